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
from typing import ClassVar, Literal

from pinn_mpc.errors import InputError

__all__ = ["GAINS_KNOWLEDGE", "ZONE_LAYOUTS", "EnergyPlusSettings", "check_settings"]

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
class EnergyPlusSettings:
    """An EnergyPlus plant's building, weather and heater (module docstring)."""

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
