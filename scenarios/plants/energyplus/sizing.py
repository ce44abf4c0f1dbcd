"""The heater (or chiller) an EnergyPlus building needs: sized on its weather file's coldest
(hottest) days under an ideal thermostat; a building of zones each controlled on its own, each
zone's (:func:`size_zones`)."""

from __future__ import annotations

import datetime as dt
import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pinn_mpc.actuator import Actuator
from pinn_mpc.errors import InputError
from scenarios.plants.energyplus.files import resolve_weather
from scenarios.plants.energyplus.model import PlantKey, plant_key, prepared_from_key, zone_names
from scenarios.plants.energyplus.run import held_run, unlimited_power_w
from scenarios.plants.energyplus.settings import EnergyPlusSettings
from scenarios.plants.energyplus.zoned import held_zones_run

__all__ = ["HeaterSizing", "ZoneSizing", "extreme_window", "size_heater", "size_zones"]


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



@dataclass(frozen=True)
class ZoneSizing:
    """What :func:`size_zones` found: each zone's heater (chiller), the peaks they came from
    and where."""

    zones: tuple[str, ...]
    powers_w: tuple[float, ...]  # each zone's: its peak x margin, rounded up to 100 W
    peaks_w: tuple[float, ...]  # each zone's largest interval mean power under the thermostat
    setpoint_c: float
    start_day: int
    days: int
    margin: float
    epw: str
    cooling: bool

    @property
    def power_w(self) -> float:
        """The zones' total [W]."""
        return float(sum(self.powers_w))

    def line(self) -> str:
        """One line for the run's log."""
        first = dt.date(2001, 1, 1) + dt.timedelta(days=self.start_day - 1)
        last = first + dt.timedelta(days=self.days - 1)
        key, kind, extreme = (
            ("chiller_w", "chillers", "hottest") if self.cooling else ("heater_w", "heaters", "coldest")
        )
        each = ", ".join(
            f"{zone} {power / 1000:g} kW (peak {peak / 1000:.2f})"
            for zone, power, peak in zip(self.zones, self.powers_w, self.peaks_w, strict=True)
        )
        return (
            f"plant.{key} = \"auto\": {kind} sized {self.power_w / 1000:g} kW in all, {each}, x "
            f"{self.margin:g} to hold {self.setpoint_c:g} C in every zone on the {extreme} "
            f"{self.days} days of {Path(self.epw).name}, {first:%d %b}-{last:%d %b}"
        )


@functools.lru_cache(maxsize=16)
def _size_zones_cached(
    prepared_key: PlantKey, weather: str, setpoint_c: float, cooling: bool, efficiency: Actuator,
    margin: float, days: int, dt_s: float,
) -> ZoneSizing:
    prepared = prepared_from_key(prepared_key)
    epw = resolve_weather(weather)
    start_day = extreme_window(epw, days, hottest=cooling)
    means = held_zones_run(
        prepared, weather, setpoint_c, heats=not cooling, efficiency=efficiency, dt_s=dt_s,
        start_day=start_day, days=days, year=None,
    )
    power = np.array([m.u_phys_act_w for m in means])  # (N, Z) each zone's interval means
    peaks = power.max(axis=0)
    cop = 1.0 if efficiency.kind == "ideal" else efficiency.cop_min
    big = 1000.0 * np.asarray(prepared.zone_floor_m2) * np.asarray(prepared.multipliers) / cop
    names = zone_names(prepared.zones)
    held = [z for z, (peak, limit) in enumerate(zip(peaks, big, strict=True)) if peak >= 0.99 * limit]
    if held:
        raise InputError(
            f"sizing the {'chillers' if cooling else 'heaters'} of {prepared.source}: even 1 kW "
            f"per m2 did not hold {setpoint_c:g} C in {', '.join(names[z] for z in held)}; give "
            f"{'chiller_w' if cooling else 'heater_w'}"
        )
    return ZoneSizing(
        zones=names, powers_w=tuple(math.ceil(p * margin / 100.0) * 100.0 for p in peaks),
        peaks_w=tuple(float(p) for p in peaks), setpoint_c=setpoint_c, start_day=start_day,
        days=days, margin=margin, epw=str(epw), cooling=cooling,
    )


def size_zones(
    plant: EnergyPlusSettings,
    setpoint_c: float,
    *,
    cooling: bool = False,
    margin: float = 1.2,
    days: int = 3,
    dt_s: float = 1800.0,
) -> ZoneSizing:
    """Each zone's heater (``cooling``: chiller, of the plant's chiller efficiency) of an
    EnergyPlus plant whose zones are each controlled (``zones = "controlled"``), to hold
    ``setpoint_c`` in every zone through the weather file's coldest (hottest) ``days`` days.

    As :func:`size_heater`, zone by zone: the building runs on the extreme window of its EPW,
    warmed up at the setpoint, every zone held there by an ideal thermostat of its own
    (integral control of its heat per zone timestep; a chiller's electrical power is that
    heat over its EER at the timestep's outdoor air) with equipment no zone needs (1 kW of
    heat per m2 of its floor); each zone's largest interval mean electrical power, times
    ``margin``, rounded up to 100 W, is its heater (chiller). Computed once per process for
    the same inputs; nothing is written to disk.
    """
    if not (math.isfinite(margin) and margin >= 1.0):
        raise ValueError(f"size_zones: margin must be >= 1, got {margin!r}")
    if not plant.controlled:
        raise ValueError(f"size_zones: the plant's zones are {plant.zones!r}; each zone is sized where they are 'controlled'")
    efficiency = plant.chiller_efficiency if cooling else Actuator()
    return _size_zones_cached(
        plant_key(plant), plant.weather, float(setpoint_c), cooling, efficiency, margin, days, dt_s
    )
