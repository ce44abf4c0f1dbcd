"""The settings of an EnergyPlus plant: which building runs on which weather, and how.

``building`` is a bundled DOE reference building or an IDF/epJSON path, ``weather`` a bundled
EPW name or a path (:mod:`scenarios.plants.energyplus.files`); ``heater_w`` is its heater's
power (0: the simulation's ``u_max_w``; ``"auto"``: sized to hold the comfort band through the
weather file's coldest days, :func:`scenarios.plants.energyplus.sizing.size_heater`),
``allow_code`` lets a model that declares Python plugins or external co-simulation run them.
``zones`` says whether the conditioned zones are ``merged`` into one thermal zone or kept
``separate`` (one ideal heater per zone, the power split by floor area, T_r the
floor-area-weighted mean); ``radiant_fraction`` is the heater's radiant share (0: all
convective); ``gains`` says whether the building's internal gains are ``unknown`` to the
controllers (as in a real building) or ``measured``. A negative ``eta`` in the scenario's
building makes the ideal equipment a chiller (heat extracted = -eta x the power). Its R/C
parameters are unknown; the scenario's are nominal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Literal, TypedDict

import numpy as np

from pinn_mpc.errors import InputError
from pinn_mpc.physics import RCParams
from scenarios.plants.kinds import KindSettings

if TYPE_CHECKING:
    from scenarios.plants.energyplus.sizing import HeaterSizing

__all__ = [
    "DATA_POLICY",
    "GAINS_KNOWLEDGE",
    "NOMINAL_BUILDING",
    "WEATHER_WINDOW",
    "ZONE_LAYOUTS",
    "WeatherWindow",
    "EnergyPlusSettings",
    "check_settings",
]

#: What the controllers' side of a scenario assumes of an EnergyPlus building (eta = 1: an
#: electric heater; a solar aperture, so data carry G): nominal values of the order identify
#: finds for DOE's small office (so a model of it is recognised as this building's), not the
#: plant's, which has no R/C parameters. Models and RC MPCs learn their own.
NOMINAL_BUILDING = RCParams(
    r_ra_k_per_w=1.0 / 800.0,
    r_rm_k_per_w=1.0 / 5000.0,
    c_r_j_per_k=3.0e6,
    c_m_j_per_k=6.0e8,
    eta=1.0,
    solar_aperture_m2=10.0,
    solar_to_air_fraction=0.3,
    gain_to_air_fraction=0.5,
)
#: The training data's policy on an EnergyPlus building: random setpoints tracked (random
#: levels overheat the room into the backup thermostat, which then cuts the heat inside
#: intervals).
DATA_POLICY: Literal["closed-loop"] = "closed-loop"
#: The weather window of an EnergyPlus scenario on its plant's EPW: January and February,
#: trained on January (a longer training run reaches back into December), tested on February.
class WeatherWindow(TypedDict):
    """A part of a weather file's year (``[weather]`` of a scenario file, month-day strings)."""

    window_start: str
    window_days: int
    test_start: str
    test_days: int


WEATHER_WINDOW = WeatherWindow(window_start="01-01", window_days=59, test_start="02-01", test_days=28)

#: ``zones`` of an EnergyPlus plant: one merged thermal zone, or the conditioned zones kept.
ZONE_LAYOUTS = ("merged", "separate")
#: ``gains`` of an EnergyPlus plant: unknown to the controllers, or measured.
GAINS_KNOWLEDGE = ("unknown", "measured")


def check_settings(
    *, building: str, weather: str, heater_w: float | str, zones: str, gains: str,
    radiant_fraction: float, owner: str,
) -> None:
    """Raise InputError on settings an EnergyPlus plant cannot run with; ``owner`` is the class
    whose fields the message names (``owner.heater_w = ...``)."""
    if not (building and weather):
        raise InputError(
            "plant: kind = \"energyplus\" needs building (a bundled reference building "
            "such as small_office, or an IDF/epJSON path) and weather (a bundled EPW name "
            "such as usa_il_chicago, or an .epw path)"
        )
    h = heater_w
    if h != "auto" and (
        isinstance(h, bool) or not (isinstance(h, int | float) and math.isfinite(h) and h >= 0)
    ):
        raise InputError(
            f"{owner}.heater_w = {h!r} must be a power >= 0 W (0: simulation.u_max_w) or "
            "\"auto\" (sized for the weather file's coldest days)"
        )
    for key, value, allowed in (("zones", zones, ZONE_LAYOUTS), ("gains", gains, GAINS_KNOWLEDGE)):
        if value not in allowed:
            raise InputError(f"{owner}.{key} = {value!r} is not one of {', '.join(map(repr, allowed))}")
    f = radiant_fraction
    if isinstance(f, bool) or not (isinstance(f, int | float) and 0.0 <= f <= 1.0):
        raise InputError(
            f"{owner}.radiant_fraction = {f!r} must lie in [0, 1] (the heater's radiant "
            "share; 0: all convective)"
        )


@dataclass(frozen=True, kw_only=True)
class EnergyPlusSettings(KindSettings):
    """An EnergyPlus plant's building, weather and heater (module docstring): the settings of
    the kind ``energyplus``, which brings its weather file, its holiday calendar and (with
    ``gains = "measured"``) the gains its schedules deliver."""

    building: str
    weather: str
    heater_w: float | str = 0.0
    allow_code: bool = False
    zones: Literal["merged", "separate"] = "merged"
    radiant_fraction: float = 0.0
    gains: Literal["unknown", "measured"] = "unknown"
    #: Fields holding a file path, resolved relative to the scenario file that names them.
    PATH_FIELDS: ClassVar[tuple[str, ...]] = ("building", "weather")

    def __post_init__(self) -> None:
        check_settings(
            building=self.building, weather=self.weather, heater_w=self.heater_w, zones=self.zones,
            gains=self.gains, radiant_fraction=self.radiant_fraction, owner=type(self).__name__,
        )

    @property
    def weather_file(self) -> str:
        return self.weather

    @property
    def measured_gains(self) -> bool:
        return self.gains == "measured"

    @property
    def sized_when_read(self) -> bool:
        return self.heater_w == "auto"

    def size_actuator(self, setpoint_c: float, *, heat_per_w: float, dt_s: float) -> HeaterSizing:
        """The heater (a chiller, ``heat_per_w < 0``) that holds ``setpoint_c`` through the
        weather file's coldest (hottest) days (:func:`scenarios.plants.energyplus.sizing.size_heater`)."""
        from scenarios.plants.energyplus.sizing import size_heater

        return size_heater(self, setpoint_c, heat_per_w=heat_per_w, dt_s=dt_s)

    def holidays(self, times: np.ndarray) -> np.ndarray:
        """(N,) 1.0 on the building's holidays (:func:`scenarios.plants.energyplus.schedules.holidays`)."""
        from scenarios.plants.energyplus.schedules import holidays

        return holidays(self, times)

    def scheduled_gains(
        self, times: np.ndarray, *, setpoint_c: float, dt_s: float, heat_per_w: float
    ) -> np.ndarray | None:
        """The gains the building's schedules deliver
        (:func:`scenarios.plants.energyplus.schedules.schedule_gains`) where they are measured."""
        if not self.measured_gains:
            return None
        from scenarios.plants.energyplus.schedules import schedule_gains

        return schedule_gains(self, times, setpoint_c=setpoint_c, dt_s=dt_s, heat_per_w=heat_per_w)
