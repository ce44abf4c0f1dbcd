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

A plant that is not an RC network (EnergyPlus, BOPTEST) runs outside this package's simulator;
its kind and settings live with it in ``scenarios.plants``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.physics import N_INPUTS, RCParams, check_plausible, continuous_matrices

__all__ = ["RC_KINDS", "Plant", "plant_matrices"]

#: The structures the simulator integrates.
RC_KINDS = ("2r2c", "3r3c")


@dataclass(frozen=True, kw_only=True)
class Plant:
    """The simulated plant's structure (module docstring); the default is the models' 2R2C."""

    kind: str = "2r2c"
    envelope_capacity_j_per_k: float = 1.0e7
    envelope_resistance_fraction: float = 0.5

    def __post_init__(self) -> None:
        if self.kind not in RC_KINDS:
            raise InputError(f"Plant.kind {self.kind!r} is unknown; choose one of {', '.join(RC_KINDS)}")
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


def plant_matrices(params: RCParams, plant: Plant) -> tuple[np.ndarray, np.ndarray]:
    """Continuous ``A`` (n, n) [1/s] and ``B`` (n, 4) of the plant, n = ``plant.n_states``."""
    a2, b2 = continuous_matrices(params)
    if plant.kind == "2r2c":
        return a2, b2
    if plant.kind != "3r3c":
        raise InternalError(f"plant_matrices: no matrices for kind {plant.kind!r}")
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
