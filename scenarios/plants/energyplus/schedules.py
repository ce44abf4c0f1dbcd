"""What an EnergyPlus building's calendar and schedules say, known before it runs: its holidays
(the days it runs its Sunday-or-holiday schedules) and the internal gains its schedules deliver."""

from __future__ import annotations

import calendar
import datetime as dt
import functools
from typing import Any

import numpy as np

from pinn_mpc.errors import InputError
from scenarios.plants.energyplus.files import WEEKDAYS
from scenarios.plants.energyplus.model import PlantKey, plant_key, prepared_from_key
from scenarios.plants.energyplus.run import held_run
from scenarios.plants.energyplus.settings import EnergyPlusSettings

__all__ = ["holiday_dates", "holidays", "schedule_gains", "special_day_date"]

_MONTHS = {name.lower(): i for i, name in enumerate(calendar.month_name) if name} | {
    name.lower(): i for i, name in enumerate(calendar.month_abbr) if name
}
_ORDINALS = {"1st": 1, "2nd": 2, "3rd": 3, "4th": 4, "5th": 5, "last": -1}


def special_day_date(text: str, year: int) -> dt.date:
    """The date in ``year`` of a ``RunPeriodControl:SpecialDays`` start date, in any form
    EnergyPlus reads: ``1/15`` (month/day), ``January 15`` or ``15 January``, ``3rd Monday in
    January``, ``Last Monday in May``. InputError on anything else."""
    words = str(text).strip().lower().replace(",", " ").split()
    try:
        if len(words) == 1 and "/" in words[0]:
            month, day = (int(x) for x in words[0].split("/"))
            return dt.date(year, month, day)
        if len(words) == 2:
            month_word, day_word = words if words[0] in _MONTHS else words[::-1]
            return dt.date(year, _MONTHS[month_word], int(day_word))
        if len(words) == 4 and words[2] == "in":
            nth, weekday, month = _ORDINALS[words[0]], WEEKDAYS.index(words[1]), _MONTHS[words[3]]
            days = [
                d for d in range(1, calendar.monthrange(year, month)[1] + 1)
                if dt.date(year, month, d).weekday() == weekday
            ]
            return dt.date(year, month, days[nth if nth < 0 else nth - 1])
    except (KeyError, ValueError, IndexError):
        pass
    raise InputError(
        f"RunPeriodControl:SpecialDays start date {text!r} is not a date EnergyPlus reads "
        "(e.g. 1/15, January 15, 3rd Monday in January, Last Monday in May)"
    )


def holiday_dates(model: dict[str, Any], year: int) -> frozenset[dt.date]:
    """The days of ``year`` on which the building (an epJSON model) runs its holiday schedules:
    its ``RunPeriodControl:SpecialDays`` of type Holiday, each for its duration."""
    out: set[dt.date] = set()
    for obj in model.get("RunPeriodControl:SpecialDays", {}).values():
        if str(obj.get("special_day_type", "Holiday")).lower() != "holiday":
            continue
        first = special_day_date(obj.get("start_date", ""), year)
        out.update(first + dt.timedelta(days=i) for i in range(int(obj.get("duration", 1))))
    return frozenset(d for d in out if d.year == year)


@functools.lru_cache(maxsize=16)
def _holiday_dates_cached(prepared_key: PlantKey, year: int) -> frozenset[dt.date]:
    return holiday_dates(prepared_from_key(prepared_key).model, year)


def holidays(plant: EnergyPlusSettings, times: np.ndarray) -> np.ndarray:
    """(N,) 1.0 where the interval starting at ``times`` falls on one of the building's
    holidays (:func:`holiday_dates`: the days it runs its Sunday-or-holiday schedules), else 0.0.
    A building's holiday calendar is known in advance, like its gains schedules."""
    days = np.asarray(times, dtype="datetime64[D]")
    years = days.astype("datetime64[Y]").astype(int) + 1970
    found: set[np.datetime64] = set()
    for year in np.unique(years):
        found.update(np.datetime64(d, "D") for d in _holiday_dates_cached(plant_key(plant), int(year)))
    return np.isin(days, np.array(sorted(found), dtype="datetime64[D]")).astype(float)


@functools.lru_cache(maxsize=16)
def _schedule_gains_cached(
    prepared_key: PlantKey, weather: str, setpoint_c: float, heat_per_w: float,
    dt_s: float, start_day: int, days: int, year: int,
) -> np.ndarray:
    prepared = prepared_from_key(prepared_key)
    means = held_run(prepared, weather, setpoint_c, heat_per_w, dt_s, start_day, days, year)
    gains = np.array([m.i_g_w for m in means])
    gains.flags.writeable = False
    return gains


def schedule_gains(
    plant: EnergyPlusSettings, times: np.ndarray, *, setpoint_c: float, dt_s: float, heat_per_w: float = 1.0
) -> np.ndarray:
    """(N,) the internal gains [W] (the heater's excluded) the building's own schedules
    deliver in the intervals starting at ``times``, as interval means.

    A building's gains schedules (occupancy, lighting, equipment) are known in advance; the
    gains that happen are not quite them (EnergyPlus's people give off less sensible heat in
    a warmer room). So these come from a run of their own over the same dates with the room
    held at ``setpoint_c`` by an ideal thermostat: what the schedules give at that
    temperature, known before the plant runs. Computed once per process for the same inputs.
    """
    times = np.asarray(times, dtype="datetime64[s]")
    days = times.astype("datetime64[D]")
    year = int(days[0].astype("datetime64[Y]").astype(int)) + 1970
    start_day = int((days[0] - days[0].astype("datetime64[Y]")).astype(int)) + 1
    n_days = int((days[-1] - days[0]).astype(int)) + 1
    gains = _schedule_gains_cached(
        plant_key(plant), plant.weather, float(setpoint_c), float(heat_per_w), float(dt_s),
        start_day, n_days, year,
    )
    rows = ((times - days[0].astype("datetime64[s]")).astype(int) // int(dt_s)).astype(int)
    return np.array(gains[rows])
