"""The simulated plant's structure: the models' 2R2C (default) or a 3R3C with an envelope node.

``2r2c`` is :mod:`pinn_mpc.physics` exactly. ``3r3c`` splits the air-to-outdoor resistance
``R_ra`` of the same :class:`~pinn_mpc.physics.RCParams` at an envelope node of capacity
``C_e`` (the outer wall layers), ``R_ea = f R_ra`` towards the outdoor air and
``R_re = (1 - f) R_ra`` towards the room, ``f = envelope_resistance_fraction``::

    C_r dT_r/dt = (T_e - T_r)/R_re + (T_m - T_r)/R_rm + eta*g(T_a)*u + alpha*A_sol*G + beta*I_g
    C_m dT_m/dt = (T_r - T_m)/R_rm + (1-alpha)*A_sol*G + (1-beta)*I_g
    C_e dT_e/dt = (T_a - T_e)/R_ea + (T_r - T_e)/R_re

State ``(T_r, T_m, T_e)``, inputs ``(u, T_a, G, I_g)`` as the 2R2C. The steady state is the
2R2C's (``R_re + R_ea = R_ra``: same UA), and as ``C_e -> 0`` (or ``f -> 0`` or ``f -> 1``,
with C_e then lumped with the outdoor air or the room air) the 2R2C is recovered; in between the
envelope adds a third time constant ``C_e (R_re || R_ea)`` (2.6 h in ``mismatch_household``) that
no 2-state model represents: the room answers the outdoor temperature late and smoothed. The
controllers and models never see ``T_e``.

``energyplus`` is not an RC network: an EnergyPlus building model (``building``, a bundled DOE
reference building or an IDF/epJSON path) run on ``weather`` (a bundled EPW name or a path) by
:mod:`scenarios.plants.energyplus`; ``heater_w`` is its heater's power (0: the simulation's
``u_max_w``; ``"auto"``: sized to hold the comfort band through the weather file's coldest
days, :func:`scenarios.plants.energyplus.sizing.size_heater`), ``allow_code`` lets a model that declares
Python plugins or external co-simulation run them. ``zones`` says whether the conditioned zones
are ``merged`` into one thermal zone or kept ``separate`` (one ideal heater per zone, the power
split by floor area, T_r the floor-area-weighted mean); ``radiant_fraction`` is the heater's
radiant share (0: all convective); ``gains`` says whether the building's internal gains are
``unknown`` to the controllers (as in a real building) or ``measured``. A negative
``eta`` in the scenario's building makes the ideal equipment a chiller (heat extracted = -eta x
the power). Its R/C parameters are unknown; the scenario's are nominal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from pinn_mpc.errors import InputError
from pinn_mpc.physics import N_INPUTS, RCParams, check_plausible, continuous_matrices

__all__ = ["GAINS_KNOWLEDGE", "PLANT_KINDS", "ZONE_LAYOUTS", "Plant", "plant_matrices"]

PLANT_KINDS = ("2r2c", "3r3c", "energyplus")
#: ``zones`` of an EnergyPlus plant: one merged thermal zone, or the conditioned zones kept.
ZONE_LAYOUTS = ("merged", "separate")
#: ``gains`` of an EnergyPlus plant: unknown to the controllers, or measured.
GAINS_KNOWLEDGE = ("unknown", "measured")
#: Fields holding a file path, resolved relative to the scenario file that names them.
_PATH_FIELDS = ("building", "weather")


@dataclass(frozen=True, kw_only=True)
class Plant:
    """The plant's structure (module docstring); the default is the models' 2R2C."""

    kind: str = "2r2c"
    envelope_capacity_j_per_k: float = 1.0e7
    envelope_resistance_fraction: float = 0.5
    building: str = ""
    weather: str = ""
    heater_w: float | str = 0.0
    allow_code: bool = False
    zones: Literal["merged", "separate"] = "merged"
    radiant_fraction: float = 0.0
    gains: Literal["unknown", "measured"] = "unknown"
    PATH_FIELDS: ClassVar[tuple[str, ...]] = _PATH_FIELDS

    def __post_init__(self) -> None:
        if self.kind not in PLANT_KINDS:
            raise InputError(f"Plant.kind {self.kind!r} is unknown; choose one of {', '.join(PLANT_KINDS)}")
        if self.kind == "energyplus":
            if not (self.building and self.weather):
                raise InputError(
                    "plant: kind = \"energyplus\" needs building (a bundled reference building "
                    "such as small_office, or an IDF/epJSON path) and weather (a bundled EPW name "
                    "such as usa_il_chicago, or an .epw path)"
                )
            h = self.heater_w
            if h != "auto" and (
                isinstance(h, bool) or not (isinstance(h, int | float) and math.isfinite(h) and h >= 0)
            ):
                raise InputError(
                    f"Plant.heater_w = {h!r} must be a power >= 0 W (0: simulation.u_max_w) or "
                    "\"auto\" (sized for the weather file's coldest days)"
                )
            for key, allowed in (("zones", ZONE_LAYOUTS), ("gains", GAINS_KNOWLEDGE)):
                if getattr(self, key) not in allowed:
                    raise InputError(
                        f"Plant.{key} = {getattr(self, key)!r} is not one of "
                        f"{', '.join(map(repr, allowed))}"
                    )
            f = self.radiant_fraction
            if isinstance(f, bool) or not (isinstance(f, int | float) and 0.0 <= f <= 1.0):
                raise InputError(
                    f"Plant.radiant_fraction = {f!r} must lie in [0, 1] (the heater's radiant "
                    "share; 0: all convective)"
                )
        elif (
            self.building or self.weather or self.heater_w or self.allow_code
            or self.zones != "merged" or self.radiant_fraction or self.gains != "unknown"
        ):
            raise InputError(
                "plant: building, weather, heater_w, allow_code, zones, radiant_fraction and "
                f"gains belong to kind = \"energyplus\", not {self.kind!r}"
            )
        check_plausible("c_r_j_per_k", self.envelope_capacity_j_per_k, name="Plant.envelope_capacity_j_per_k")
        f = self.envelope_resistance_fraction
        if isinstance(f, bool) or not (isinstance(f, int | float) and math.isfinite(f) and 0 < f < 1):
            raise InputError(
                f"Plant.envelope_resistance_fraction = {f!r} must lie strictly between 0 and 1 "
                "(the share of R_ra between the envelope node and the outdoor air)"
            )

    @property
    def n_states(self) -> int:
        return 3 if self.kind == "3r3c" else 2

    @property
    def is_energyplus(self) -> bool:
        return self.kind == "energyplus"


def plant_matrices(params: RCParams, plant: Plant) -> tuple[np.ndarray, np.ndarray]:
    """Continuous ``A`` (n, n) [1/s] and ``B`` (n, 4) of the plant, n = ``plant.n_states``."""
    if plant.is_energyplus:
        raise InputError("an EnergyPlus plant has no RC matrices: it runs in EnergyPlus")
    a2, b2 = continuous_matrices(params)
    if plant.kind == "2r2c":
        return a2, b2
    r_ea = plant.envelope_resistance_fraction * params.r_ra_k_per_w
    r_re = params.r_ra_k_per_w - r_ea
    c_r, c_e = params.c_r_j_per_k, plant.envelope_capacity_j_per_k
    a = np.zeros((3, 3))
    b = np.zeros((3, N_INPUTS))
    a[:2, :2], b[:2] = a2, b2
    # The room now loses heat to the envelope node instead of the outdoor air.
    a[0, 0] += 1.0 / (c_r * params.r_ra_k_per_w) - 1.0 / (c_r * r_re)
    a[0, 2] = 1.0 / (c_r * r_re)
    b[0, 1] = 0.0
    a[2, 0] = 1.0 / (c_e * r_re)
    a[2, 2] = -1.0 / (c_e * r_re) - 1.0 / (c_e * r_ea)
    b[2, 1] = 1.0 / (c_e * r_ea)
    return a, b
