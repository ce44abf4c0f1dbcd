"""Build any controller by its CLI name for a scenario.

``thermostat`` needs nothing; ``random-shooting`` and ``cem`` plan over a trained model
(``--model``); ``casadi-mpc`` and ``qp-mpc`` work on an RC parameter set (``--rc``, from
``pinn-mpc identify`` or ``pinn-mpc export-rc``); ``oracle`` and ``clairvoyant`` use the
scenario's true parameters (and the true T_m), as references: the QP MPC composed with the
true-state estimator (:mod:`controllers.rc_mpc.references`). On a plant of higher order than
the models (``SimConfig.plant`` 3r3c, :mod:`pinn_mpc.plant`) no 2-state QP has the true model:
they then plan on the plant's R/C without its envelope node (the 2R2C it reduces to as C_e ->
0, same steady state) with the true T_r and T_m, so they are strong references there, not
bounds. With a heat pump they plan on its COP curve at the forecast T_a (exact).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from controllers.base import Controller
from pinn_mpc.errors import InputError
from pinn_mpc.physics import RCParams, params_from_summary
from scenarios.choices import (
    CONTROLLER_NAMES,
    MODEL_CONTROLLERS,
    RC_CONTROLLERS,
    TRUTH_CONTROLLERS,
)
from scenarios.registry import Scenario

__all__ = [
    "CONTROLLER_NAMES",
    "MODEL_CONTROLLERS",
    "RC_CONTROLLERS",
    "TRUTH_CONTROLLERS",
    "build_controller",
    "make_controller",
    "read_rc",
]



def _unknown(name: str) -> InputError:
    return InputError(f"unknown controller {name!r}; choose one of {', '.join(CONTROLLER_NAMES)}")


def read_rc(path: str | os.PathLike[str]) -> RCParams:
    """RC parameters from the JSON written by ``identify`` / ``export-rc``."""
    source = Path(path)
    if not source.is_file():
        raise InputError(
            f"{source}: no such RC file; write one with `pinn-mpc identify` or `pinn-mpc export-rc`"
        )
    try:
        data = json.loads(source.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(
            f"{source}: not valid JSON ({exc}); expected the RC JSON of identify or export-rc"
        ) from exc
    if not isinstance(data, dict):
        raise InputError(
            f"{source}: expected a JSON object of RC parameters, got {type(data).__name__}"
        )
    try:
        return params_from_summary(data)
    except InputError as exc:
        raise InputError(f"{source}: {exc}") from exc


def build_controller(
    name: str,
    scenario: Scenario,
    *,
    model: Any = None,
    rc_params: RCParams | None = None,
    n_steps: int,
    planner_options: Mapping[str, Any] | None = None,
) -> Controller:
    """A controller from objects already in memory (a LearnedModel, RCParams).

    ``n_steps`` is the number of counted intervals of the run (used by ``clairvoyant``);
    ``planner_options`` are keyword arguments of ``random-shooting`` / ``cem`` (e.g. samples).
    """
    spec = scenario.control_spec()
    options = dict(planner_options or {})
    if name == "thermostat":
        from controllers.thermostat import Thermostat

        return Thermostat(spec)
    if name in MODEL_CONTROLLERS:
        if model is None:
            raise InputError(
                f"controller {name!r} plans over a trained model: add --model MODEL_DIR "
                "(make one with `pinn-mpc train --data data.csv --arch physnet --out MODEL_DIR`)"
            )
        from controllers.sampling import CEM, RandomShooting

        planner = RandomShooting if name == "random-shooting" else CEM
        return planner(model, spec, **options)
    if name in RC_CONTROLLERS:
        if rc_params is None:
            raise InputError(
                f"controller {name!r} needs RC parameters: add --rc rc.json "
                "(write one with `pinn-mpc identify --data data.csv --out rc.json`)"
            )
        if name == "casadi-mpc":
            from controllers.rc_mpc.casadi import CasadiMPC

            return CasadiMPC(rc_params, spec)
        from controllers.rc_mpc.osqp import QPMPC

        return QPMPC(rc_params, spec)
    if name == "oracle":
        from controllers.rc_mpc.references import oracle_mpc

        return oracle_mpc(scenario.sim.params, spec)
    if name == "clairvoyant":
        from controllers.rc_mpc.references import clairvoyant_mpc

        return clairvoyant_mpc(scenario.sim.params, spec, n_steps)
    raise _unknown(name)


def make_controller(
    name: str,
    scenario: Scenario,
    *,
    model_dir: str | os.PathLike[str] | None = None,
    rc_path: str | os.PathLike[str] | None = None,
    n_steps: int,
) -> Controller:
    """The controller ``name`` (see :data:`CONTROLLER_NAMES`), reading ``--model`` / ``--rc``.

    A model or RC file given to a controller that does not use it is an error, not ignored.
    """
    if name not in CONTROLLER_NAMES:
        raise _unknown(name)
    if model_dir is not None and name not in MODEL_CONTROLLERS:
        raise InputError(
            f"--model is not used by controller {name!r}; "
            f"only {', '.join(MODEL_CONTROLLERS)} take it"
        )
    if rc_path is not None and name not in RC_CONTROLLERS:
        raise InputError(
            f"--rc is not used by controller {name!r}; only {', '.join(RC_CONTROLLERS)} take it"
        )
    model = None
    if model_dir is not None:
        from pinn_mpc.artifacts import load_model

        model = load_model(model_dir)
    rc_params = read_rc(rc_path) if rc_path is not None else None
    return build_controller(name, scenario, model=model, rc_params=rc_params, n_steps=n_steps)
