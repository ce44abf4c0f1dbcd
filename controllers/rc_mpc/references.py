"""Reference controllers with perfect knowledge, by composition: ``oracle`` and ``clairvoyant``.

Both are :class:`controllers.rc_mpc.osqp.QPMPC` with the true-state estimator
(:class:`controllers.estimators.TrueState`) in place of the Kalman observer, and are meant to get
the true parameters and perfect forecasts.

- ``oracle``: the receding-horizon MPC (horizon ``spec.horizon_steps``) with perfect knowledge;
  the reference a controller is judged by.
- ``clairvoyant``: the whole run as one problem. The run is the ``n_steps`` intervals from the
  first ``act`` after ``reset`` (so a warm-up driven by another controller, which advances
  ``obs.k``, does not count). At the i-th decision it solves over the remaining ``n_steps - i``
  intervals (shrinking horizon to the run end; the QP is built once with ``n_steps`` steps and
  the steps after the end get zero price and an open band). With a perfect model this
  reproduces the single whole-run optimum, so its objective is the lower bound for the run (up
  to the backup thermostat, which no controller models). The forecast must hold the rest of the
  run (the last value is repeated if it is shorter).
- ``oracle_multizone``: the oracle of a multi-zone building
  (:class:`controllers.rc_mpc.multizone.MultiZoneMPC` on the true state).
"""

from __future__ import annotations

from typing import Any

from controllers.base import ControlSpec
from controllers.estimators import TrueState
from controllers.rc_mpc.multizone import MultiZoneMPC
from controllers.rc_mpc.osqp import QPMPC
from pinn_mpc.multizone import MultiZoneParams
from pinn_mpc.physics import RCParams

__all__ = ["clairvoyant_mpc", "oracle_mpc", "oracle_multizone"]


def oracle_mpc(params: RCParams, spec: ControlSpec, **options: Any) -> QPMPC:
    """Receding-horizon QP MPC on the true state; ``options`` as for :class:`QPMPC`."""
    return QPMPC(params, spec, estimator=TrueState(), name="oracle", **options)


def clairvoyant_mpc(params: RCParams, spec: ControlSpec, n_steps: int, **options: Any) -> QPMPC:
    """The whole run of ``n_steps`` intervals as one shrinking-horizon QP on the true state."""
    if n_steps < 1:
        raise ValueError(f"clairvoyant: n_steps must be >= 1 (the run length), got {n_steps}")
    return QPMPC(
        params,
        spec,
        estimator=TrueState(),
        name="clairvoyant",
        horizon_steps=n_steps,
        run_steps=n_steps,
        **options,
    )


def oracle_multizone(params: MultiZoneParams, spec: ControlSpec, **options: Any) -> MultiZoneMPC:
    """The receding-horizon QP MPC of a multi-zone building on its true state; ``options`` as
    for :class:`~controllers.rc_mpc.multizone.MultiZoneMPC`."""
    return MultiZoneMPC(params, spec, estimator="true", name="oracle", **options)
