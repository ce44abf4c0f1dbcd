"""The settings of an EnergyPlus plant: which building runs on which weather, and how.

``building`` is a bundled DOE reference building or an IDF/epJSON path, ``weather`` a bundled
EPW name or a path (:mod:`scenarios.plants.energyplus.files`); ``heater_w`` is its heater's
power (0: the simulation's ``u_max_w``; ``"auto"``: sized to hold the comfort band through the
weather file's coldest days, :func:`scenarios.plants.energyplus.sizing.size_heater`),
``allow_code`` lets a model that declares Python plugins or external co-simulation run them.
``zones`` says whether the conditioned zones are ``merged`` into one thermal zone or kept
``separate`` (one ideal heater per zone, the power split by floor area, T_r the
floor-area-weighted mean) or kept and ``controlled`` each on its own (a building of several
zones, below); ``radiant_fraction`` is the heater's radiant share (0: all
convective); ``gains`` says whether the building's internal gains are ``unknown`` to the
controllers (as in a real building) or ``measured``. A negative ``eta`` in the scenario's
building makes the ideal equipment a chiller (heat extracted = -eta x the power). Its R/C
parameters are unknown; the scenario's are nominal.

``zones = "controlled"``: every conditioned zone is a zone of the building
(:attr:`EnergyPlusSettings.zone_specs`, named as EnergyPlus names it, :func:`~scenarios.plants.energyplus.model.zone_names`), with
an ideal electric heater ``heat_<zone>`` and an ideal chiller ``cool_<zone>`` of its own, each
an actuator (:attr:`EnergyPlusSettings.own_actuators`, a zone's heater then its chiller, zone by
zone). ``heater_w`` and ``chiller_w`` size them: ``"auto"`` (each zone's sized on the weather
file's coldest, for a chiller hottest, days:
:func:`scenarios.plants.energyplus.sizing.size_zones`), a number (the building's total,
split by floor area) or a list (each zone's, in the zones' order); 0 (or a zone's 0) is no
heater (chiller) there, and ``chiller_w = None`` none at all. The chiller's electrical power
becomes heat removed by its ``chiller`` efficiency (:class:`pinn_mpc.actuator.Actuator`, by
default :data:`ZONE_CHILLER`: an EER that falls in hotter outdoor air; ``cop_min = cop_max``
gives a constant one).
"""

from __future__ import annotations

import calendar
import dataclasses
import datetime as dt
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal, TypedDict

import numpy as np

from pinn_mpc.actuator import Actuator, ActuatorSpec
from pinn_mpc.errors import InputError
from pinn_mpc.physics import RCParams
from pinn_mpc.zones import ONE_ZONE, ZoneSpec
from scenarios.plants.kinds import KindSettings

if TYPE_CHECKING:
    from scenarios.plants.energyplus.sizing import HeaterSizing, ZoneSizing

__all__ = [
    "DATA_POLICY",
    "GAINS_KNOWLEDGE",
    "NOMINAL_BUILDING",
    "SEASONS",
    "WEATHER_WINDOW",
    "ZONE_CHILLER",
    "ZONE_LAYOUTS",
    "WeatherWindow",
    "EnergyPlusSettings",
    "check_settings",
    "season_window",
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
#: The seasons an EnergyPlus scenario's weather may be given by (``[weather] season``): the
#: months, each tested on, trained on the month before it (:func:`season_window`).
SEASONS = tuple(name.lower() for name in calendar.month_name[1:])


def season_window(season: str) -> WeatherWindow:
    """The weather window of ``season`` (a month's name, :data:`SEASONS`): that month tested,
    the month before it trained on (a longer training run reaches back further)."""
    if season not in SEASONS:
        raise InputError(f"weather.season = {season!r} is not a month; choose one of {', '.join(SEASONS)}")
    month = SEASONS.index(season) + 1
    first = dt.date(2001, month, 1)  # a non-leap year, as the typical year
    before = (first - dt.timedelta(days=1)).replace(day=1)
    days = calendar.monthrange(2001, month)[1]
    return WeatherWindow(
        window_start=f"{before:%m-%d}", window_days=(first - before).days + days,
        test_start=f"{first:%m-%d}", test_days=days,
    )


#: ``zones`` of an EnergyPlus plant: one merged thermal zone, or the conditioned zones kept
#: (as one building, or each controlled on its own).
ZONE_LAYOUTS = ("merged", "separate", "controlled")
#: The chiller of each zone of ``zones = "controlled"`` unless ``chiller`` gives another: a
#: 12 C supply at 30 % of the Carnot EER, clipped to 1..6 (4.8 at 30 C outdoor air, 3.8 at
#: 35 C, 6 below 24 C), as the package's multi-zone office's.
ZONE_CHILLER = Actuator(kind="chiller", supply_temp_c=12.0, carnot_efficiency=0.3, cop_min=1.0, cop_max=6.0)
#: ``gains`` of an EnergyPlus plant: unknown to the controllers, or measured.
GAINS_KNOWLEDGE = ("unknown", "measured")


def _is_power(value: object) -> bool:
    """A finite power >= 0 [W] (a number, not a bool)."""
    return (
        not isinstance(value, bool) and isinstance(value, int | float)
        and math.isfinite(value) and value >= 0
    )


def _check_zone_powers(key: str, value: object, owner: str) -> None:
    """``value`` of ``key`` (heater_w, chiller_w) of zones kept and controlled: "auto", a
    power >= 0 W (the building's, split by floor area) or a list of them, one per zone."""
    ok = value == "auto" or _is_power(value) or (
        isinstance(value, tuple) and len(value) > 0 and all(_is_power(v) for v in value)
    )
    if not ok:
        raise InputError(
            f"{owner}.{key} = {value!r} must be \"auto\" (each zone's sized), a power >= 0 W "
            "(the building's, split by floor area) or a list of them, one per zone"
        )


def check_settings(
    *, building: str, weather: str, heater_w: float | str | tuple[float, ...], zones: str, gains: str,
    radiant_fraction: float, owner: str, chiller_w: object = None, chiller: object = None,
) -> None:
    """Raise InputError on settings an EnergyPlus plant cannot run with; ``owner`` is the class
    whose fields the message names (``owner.heater_w = ...``)."""
    if not (building and weather):
        raise InputError(
            "plant: kind = \"energyplus\" needs building (a bundled reference building "
            "such as small_office, or an IDF/epJSON path) and weather (a bundled EPW name "
            "such as usa_il_chicago, or an .epw path)"
        )
    for key, value, allowed in (("zones", zones, ZONE_LAYOUTS), ("gains", gains, GAINS_KNOWLEDGE)):
        if value not in allowed:
            raise InputError(f"{owner}.{key} = {value!r} is not one of {', '.join(map(repr, allowed))}")
    h = heater_w
    if zones == "controlled":
        _check_controlled(heater_w=h, chiller_w=chiller_w, chiller=chiller, owner=owner)
    elif h != "auto" and not _is_power(h):
        raise InputError(
            f"{owner}.heater_w = {h!r} must be a power >= 0 W (0: simulation.u_max_w) or "
            "\"auto\" (sized for the weather file's coldest days)"
            + ("; a list, one per zone, needs zones = \"controlled\"" if isinstance(h, tuple) else "")
        )
    elif chiller_w is not None or chiller is not None:
        key = "chiller_w" if chiller_w is not None else "chiller"
        raise InputError(
            f"{owner}.{key} is the zones' own chillers of zones = \"controlled\", not of "
            f"zones = {zones!r}; leave it out (a merged building is cooled with [building] eta < 0)"
        )
    f = radiant_fraction
    if isinstance(f, bool) or not (isinstance(f, int | float) and 0.0 <= f <= 1.0):
        raise InputError(
            f"{owner}.radiant_fraction = {f!r} must lie in [0, 1] (the heater's radiant "
            "share; 0: all convective)"
        )


def _check_controlled(*, heater_w: object, chiller_w: object, chiller: object, owner: str) -> None:
    """The actuators of zones kept and controlled (module docstring): their powers, at least
    one actuator, an ideal chiller."""
    _check_zone_powers("heater_w", heater_w, owner)
    if chiller_w is not None:
        _check_zone_powers("chiller_w", chiller_w, owner)

    def none(value: object) -> bool:
        return value is None or value == 0 or (isinstance(value, tuple) and not any(value))

    if none(heater_w) and none(chiller_w):
        raise InputError(
            f"{owner}: zones = \"controlled\" has no actuator: give heater_w or chiller_w "
            "(\"auto\", a power in W, or one per zone)"
        )
    if chiller is not None:
        if not isinstance(chiller, Actuator) or chiller.kind == "heat_pump":
            raise InputError(
                f"{owner}.chiller = {chiller!r} must be a chiller's efficiency (an Actuator of "
                "kind \"chiller\", or \"ideal\": 1 W of heat removed per W)"
            )
        if chiller.min_modulation:
            raise InputError(
                f"{owner}.chiller.min_modulation = {chiller.min_modulation:g}: the zones' ideal "
                "chillers run at any power; give 0"
            )


@dataclass(frozen=True, kw_only=True)
class EnergyPlusSettings(KindSettings):
    """An EnergyPlus plant's building, weather and heater (module docstring): the settings of
    the kind ``energyplus``, which brings its weather file, its holiday calendar and (with
    ``gains = "measured"``) the gains its schedules deliver."""

    building: str
    weather: str
    heater_w: float | str | tuple[float, ...] = 0.0
    allow_code: bool = False
    zones: Literal["merged", "separate", "controlled"] = "merged"
    radiant_fraction: float = 0.0
    gains: Literal["unknown", "measured"] = "unknown"
    #: The zones' chillers (``zones = "controlled"``; None: none): "auto", the building's
    #: electrical power [W] split by floor area, or each zone's.
    chiller_w: float | str | tuple[float, ...] | None = None
    #: The zones' chillers' efficiency (None: :data:`ZONE_CHILLER`).
    chiller: Actuator | None = None
    #: Fields holding a file path, resolved relative to the scenario file that names them.
    PATH_FIELDS: ClassVar[tuple[str, ...]] = ("building", "weather")

    def __post_init__(self) -> None:
        for key in ("heater_w", "chiller_w"):  # a list read from a file, or given as one
            if isinstance(getattr(self, key), list):
                object.__setattr__(self, key, tuple(getattr(self, key)))
        check_settings(
            building=self.building, weather=self.weather, heater_w=self.heater_w, zones=self.zones,
            gains=self.gains, radiant_fraction=self.radiant_fraction, owner=type(self).__name__,
            chiller_w=self.chiller_w, chiller=self.chiller,
        )

    @property
    def controlled(self) -> bool:
        """Whether the zones are kept and each controlled on its own (a building of several zones)."""
        return self.zones == "controlled"

    @property
    def chiller_efficiency(self) -> Actuator:
        """The zones' chillers' efficiency: ``chiller``, or :data:`ZONE_CHILLER`."""
        return ZONE_CHILLER if self.chiller is None else self.chiller

    @property
    def zone_specs(self) -> tuple[ZoneSpec, ...]:
        """The building's zones: each conditioned zone where they are controlled, else one."""
        if not self.controlled:
            return ONE_ZONE
        from scenarios.plants.energyplus.model import zone_layout

        return tuple(ZoneSpec(name) for name in zone_layout(self)[0])

    @property
    def zone_adjacency(self) -> np.ndarray | None:
        """Where the zones are controlled, (Z, Z) True where two zones share a surface in the
        model (:func:`scenarios.plants.energyplus.model.zone_adjacency`); None otherwise."""
        if not self.controlled:
            return None
        from scenarios.plants.energyplus.model import zone_adjacency

        return np.array(zone_adjacency(self), dtype=bool)

    @property
    def rc_errs_hours_ahead(self) -> bool:
        """True: EnergyPlus's building (its envelope's layers, ventilation and schedules) is no
        2R2C, and the RC identified from its data errs hours ahead by that."""
        return True

    @property
    def zone_solar_inputs(self) -> tuple[str | None, ...] | None:
        """Where the zones are controlled, the facade each zone's windows face (``G`` for
        skylights or none, :func:`scenarios.plants.energyplus.model.zone_window_facades`);
        None otherwise."""
        if not self.controlled:
            return None
        from scenarios.plants.energyplus.model import zone_window_facades

        return zone_window_facades(self)

    @property
    def zone_shares(self) -> tuple[float, ...]:
        """Where the zones are controlled, each zone's share of the floor area (zone multipliers
        counted, :func:`scenarios.plants.energyplus.model.zone_layout`); else (1.0,)."""
        if not self.controlled:
            return (1.0,)
        from scenarios.plants.energyplus.model import zone_layout

        return tuple(zone_layout(self)[1])

    @property
    def own_actuators(self) -> tuple[ActuatorSpec, ...] | None:
        """Where the zones are controlled, each zone's heater ``heat_<zone>`` then its chiller
        ``cool_<zone>`` (those of power > 0), zone by zone; None otherwise (the scenario's one
        actuator). InputError while a power is still ``"auto"`` (sized when the scenario is
        read, :func:`scenarios.inputs.registry.with_sized_heater`)."""
        if not self.controlled:
            return None
        from scenarios.plants.energyplus.model import zone_layout

        names, weights = zone_layout(self)
        heaters = self._zone_powers("heater_w", self.heater_w, names, weights)
        chillers = self._zone_powers("chiller_w", self.chiller_w or 0.0, names, weights)
        actuators = []
        for z, name in enumerate(names):
            if heaters[z] > 0:
                actuators.append(ActuatorSpec(upper_w=heaters[z], zone=z, name=f"heat_{name}"))
            if chillers[z] > 0:
                actuators.append(ActuatorSpec(
                    upper_w=chillers[z], zone=z, heats=False, efficiency=self.chiller_efficiency,
                    name=f"cool_{name}",
                ))
        return tuple(actuators)

    def _zone_powers(
        self, key: str, value: Any, names: tuple[str, ...], weights: tuple[float, ...]
    ) -> tuple[float, ...]:
        """Each zone's power [W] of ``key``: a list as given, a number split by floor area."""
        if value == "auto":
            raise InputError(
                f"{type(self).__name__}.{key} = \"auto\" is sized when a scenario is read; "
                "read it through get_scenario (or with_sized_heater), or give the powers"
            )
        if isinstance(value, tuple):
            if len(value) != len(names):
                raise InputError(
                    f"{type(self).__name__}.{key} gives {len(value)} power(s), but the building has "
                    f"{len(names)} zones ({', '.join(names)}): give one per zone, in that order"
                )
            return tuple(float(v) for v in value)
        return tuple(float(value) * w for w in weights)

    @property
    def sizes_own_actuators(self) -> bool:
        return self.controlled

    def size_own_actuators(
        self, *, heating_c: float, cooling_c: float, dt_s: float
    ) -> tuple[EnergyPlusSettings, tuple[ZoneSizing, ...]]:
        """These settings with each ``"auto"`` of ``heater_w`` (``chiller_w``) the zones' heaters
        (chillers) :func:`scenarios.plants.energyplus.sizing.size_zones` finds to hold
        ``heating_c`` (``cooling_c``) through the weather file's coldest (hottest) days, and
        what was sized."""
        from scenarios.plants.energyplus.sizing import size_zones

        sized, sizings = self, []
        if self.heater_w == "auto":
            sizings.append(size_zones(self, heating_c, dt_s=dt_s))
            sized = dataclasses.replace(sized, heater_w=sizings[-1].powers_w)
        if self.chiller_w == "auto":
            sizings.append(size_zones(self, cooling_c, cooling=True, dt_s=dt_s))
            sized = dataclasses.replace(sized, chiller_w=sizings[-1].powers_w)
        return sized, tuple(sizings)

    @property
    def weather_file(self) -> str:
        return self.weather

    @property
    def measured_gains(self) -> bool:
        return self.gains == "measured"

    @property
    def own_gains(self) -> bool:
        return True

    @property
    def sized_when_read(self) -> bool:
        return self.heater_w == "auto" or self.chiller_w == "auto"

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
