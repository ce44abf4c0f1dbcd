"""Export the learned 2R2C of a physics-informed model as R/C values (the ``identify`` schema)."""

from __future__ import annotations

import dataclasses

from pinn_mpc import physics
from pinn_mpc.errors import InputError
from pinn_mpc.models import LearnedModel
from pinn_mpc.records import RcSummary

__all__ = ["export_rc"]


def export_rc(model: LearnedModel, *, source: str) -> RcSummary:
    """R/C values of the ensemble's learned coefficients (geometric mean over members).

    Keys as :func:`pinn_mpc.physics.rc_summary` (R_ra_K_per_W, R_rm_K_per_W, C_r_J_per_K,
    C_m_J_per_K, eta, gain terms, coefficients_per_s, time_constants_h, source), plus
    ``member_coefficients_per_s``, the coefficients of every member; with the unmeasured gains'
    schedule a hybrid or pcnn takes as its internal gains (``unmeasured_gains_W``). mlp, or R/C values
    outside :data:`pinn_mpc.physics.PLAUSIBLE_RANGES` -> InputError.
    """
    coef = model.physics_coefficients()
    if coef is None:
        raise InputError(
            f"model is a plain {model.arch}: it has no physics block to export; "
            "train physreg, physnet or hybrid, or use `pinn-mpc identify`"
        )
    try:
        params = physics.from_coefficients(coef, eta=model.eta)
    except ValueError as exc:
        raise InputError(
            f"the model's learned 2R2C is not physical ({exc}); train it on longer, more varied "
            "data, and check the data's units"
        ) from exc
    if model.features.gain_schedule_w:  # the gains its 2R2C reads where the data had none
        params = dataclasses.replace(params, unmeasured_gains_w=model.features.gain_schedule_w)
    out = physics.rc_summary(params, source=source)
    out["member_coefficients_per_s"] = model.member_coefficients()
    return out
