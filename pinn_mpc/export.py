"""Export the learned 2R2C of a physics-informed model as R/C values (the ``identify`` schema)."""

from __future__ import annotations

from typing import Any

from pinn_mpc import physics
from pinn_mpc.artifacts import MODEL_DIRECTORY, load_model
from pinn_mpc.errors import InputError
from pinn_mpc.io import atomic_write_json, check_distinct, check_writable
from pinn_mpc.models import LearnedModel


def export_rc(model: LearnedModel, *, source: str) -> dict[str, Any]:
    """R/C values of the ensemble's learned coefficients (geometric mean over members).

    Keys as :func:`pinn_mpc.physics.rc_summary` (R_ra_K_per_W, R_rm_K_per_W, C_r_J_per_K,
    C_m_J_per_K, eta, gain terms, coefficients_per_s, time_constants_h, source), plus
    ``member_coefficients_per_s``, the coefficients of every member. mlp, or R/C values
    outside :data:`pinn_mpc.physics.PLAUSIBLE_RANGES` -> InputError.
    """
    coef = model.physics_coefficients()
    if coef is None:
        raise InputError(
            f"model is a plain {model.arch}: it has no physics block to export; "
            "train physreg or physnet, or use `pinn-mpc identify`"
        )
    try:
        params = physics.from_coefficients(coef, eta=model.eta)
    except InputError as exc:
        raise InputError(
            f"the model's learned 2R2C is not physical ({exc}); train it on longer, more varied "
            "data, and check the data's units"
        ) from exc
    out = physics.rc_summary(params, source=source)
    out["member_coefficients_per_s"] = model.member_coefficients()
    return out


def export_rc_to_json(*, model: str, out: str) -> str:
    """CLI ``export-rc``: load a model directory, write its RC JSON; returns a summary line."""
    check_writable(out)
    check_distinct(inputs={"--model": MODEL_DIRECTORY.paths(model)}, outputs={"--out": out})
    learned = load_model(model)
    data = export_rc(
        learned, source=f"export-rc of {learned.arch} x{learned.n_members} from {model}"
    )
    atomic_write_json(out, data)
    return (
        f"R_ra={data['R_ra_K_per_W']:.4g} K/W R_rm={data['R_rm_K_per_W']:.4g} K/W "
        f"C_r={data['C_r_J_per_K']:.4g} J/K C_m={data['C_m_J_per_K']:.4g} J/K -> {out}"
    )
