"""The heater (or chiller) an EnergyPlus building needs: sized on its weather file's coldest
(hottest) days under an ideal thermostat."""

from __future__ import annotations

import datetime as dt
import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pinn_mpc.errors import InputError
from scenarios.plants.energyplus.files import resolve_weather
from scenarios.plants.energyplus.model import PlantKey, plant_key, prepared_from_key
from scenarios.plants.energyplus.run import held_run, unlimited_power_w
from scenarios.plants.energyplus.settings import EnergyPlusSettings

__all__ = ["HeaterSizing", "extreme_window", "size_heater"]


def _daily_mean_dry_bulb(epw: Path) -> np.ndarray:
    """(365,) the EPW's daily mean dry-bulb temperature [C] (column 7 of its hourly rows)."""
    import pvlib

    try:
        dry_bulb = pvlib.iotools.read_epw(epw)[0]["temp_air"].to_numpy(dtype=float)
    except Exception:  # pvlib raises many kinds on a malformed file; one line for the user
        raise InputError(f"{epw}: not a readable EPW weather file (no dry-bulb column)") from None
    if len(dry_bulb) < 365 * 24:
        raise InputError(f"{epw}: {len(dry_bulb)} hourly rows; sizing needs a whole year (8760)")
    return dry_bulb[: 365 * 24].reshape(365, 24).mean(axis=1)


def extreme_window(epw: Path, days: int = 3, *, hottest: bool = False) -> int:
    """The first day of the year (1 = 1 January) of the coldest (``hottest``: the hottest)
    ``days`` consecutive days of the weather file, by their daily mean dry-bulb."""
    daily = _daily_mean_dry_bulb(epw)
    window = np.convolve(daily, np.ones(days) / days, mode="valid")
    return int(np.argmax(window) if hottest else np.argmin(window)) + 1


@dataclass(frozen=True)
class HeaterSizing:
    """What :func:`size_heater` found: the power, the peak it came from and where."""

    power_w: float  # the heater's (chiller's) power: peak x margin, rounded up to 1 kW
    peak_w: float  # the largest interval mean power the ideal thermostat needed
    setpoint_c: float  # the temperature held
    start_day: int  # first day of the year of the window
    days: int
    margin: float
    epw: str
    cooling: bool = False

    def line(self) -> str:
        """One line for the run's log."""
        first = dt.date(2001, 1, 1) + dt.timedelta(days=self.start_day - 1)
        last = first + dt.timedelta(days=self.days - 1)
        kind, extreme = ("chiller", "hottest") if self.cooling else ("heater", "coldest")
        return (
            f"plant.heater_w = \"auto\": {kind} sized {self.power_w / 1000:g} kW (peak "
            f"{self.peak_w / 1000:.1f} kW x {self.margin:g} to hold {self.setpoint_c:g} C on the "
            f"{extreme} {self.days} days of {Path(self.epw).name}, {first:%d %b}-{last:%d %b})"
        )


@functools.lru_cache(maxsize=16)
def _size_heater_cached(
    prepared_key: PlantKey, weather: str, setpoint_c: float, heat_per_w: float,
    margin: float, days: int, dt_s: float,
) -> HeaterSizing:
    prepared = prepared_from_key(prepared_key)
    epw = resolve_weather(weather)
    cooling = heat_per_w < 0
    start_day = extreme_window(epw, days, hottest=cooling)
    big_w = unlimited_power_w(prepared, heat_per_w)
    means = held_run(prepared, weather, setpoint_c, heat_per_w, dt_s, start_day, days, None)
    peak = max(m.u_phys_w for m in means)
    if peak >= 0.99 * big_w:
        raise InputError(
            f"sizing the {'chiller' if cooling else 'heater'} of {prepared.source}: even "
            f"{big_w / 1000:g} kW did not hold {setpoint_c:g} C; give heater_w"
        )
    power = math.ceil(peak * margin / 1000.0) * 1000.0
    return HeaterSizing(
        power_w=power, peak_w=peak, setpoint_c=setpoint_c, start_day=start_day, days=days,
        margin=margin, epw=str(epw), cooling=cooling,
    )


def size_heater(
    plant: EnergyPlusSettings,
    setpoint_c: float,
    *,
    heat_per_w: float = 1.0,
    margin: float = 1.2,
    days: int = 3,
    dt_s: float = 1800.0,
) -> HeaterSizing:
    """The heater an EnergyPlus :class:`~scenarios.plants.energyplus.settings.EnergyPlusSettings` needs to hold ``setpoint_c``
    (the comfort band's lower bound) through the weather file's coldest ``days`` days.

    The building (as the plant prepares it: zones, radiant fraction) runs on the coldest
    window of its EPW (:func:`extreme_window`, by daily mean dry-bulb), warmed up at the
    setpoint, under an ideal thermostat (integral control per zone timestep) with a heater
    no building needs (1 kW per m2 of floor); the largest interval mean power it used, times
    ``margin``, rounded up to a whole kW, is the heater. For a chiller (``heat_per_w < 0``) the
    same on the hottest days, ``setpoint_c`` the band's upper bound, in electrical power.
    Computed once per process for the same inputs; nothing is written to disk.
    """
    if not (math.isfinite(margin) and margin >= 1.0):
        raise ValueError(f"size_heater: margin must be >= 1, got {margin!r}")
    return _size_heater_cached(plant_key(plant), plant.weather, float(setpoint_c), float(heat_per_w), margin, days, dt_s)

