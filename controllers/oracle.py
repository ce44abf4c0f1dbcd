"""Reference controllers with perfect knowledge: ``oracle`` and ``clairvoyant``.

Both are :class:`controllers.qp_mpc.QPMPC` with the observer replaced by the simulator's true
state (``obs.t_m_true_c``) and are meant to get the true parameters and perfect forecasts.

- ``oracle``: the receding-horizon MPC (horizon ``spec.horizon_steps``) with perfect knowledge;
  the reference a controller is judged by.
- ``clairvoyant``: the whole run as one problem. The run is the ``n_steps`` intervals from
  the first ``act`` after ``reset`` (so a warm-up driven by another controller, which advances
  ``obs.k``, does not count). At the i-th decision it solves over the remaining ``n_steps - i``
  intervals (shrinking horizon to the run end; the QP is built once with
  ``n_steps`` steps and the steps after the end get zero price and an open band). With a
  perfect model this reproduces the single whole-run optimum, so its objective is the lower
  bound for the run (up to the backup thermostat, which no controller models). The forecast
  must hold the rest of the run (the last value is repeated if it is shorter).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from controllers.base import ControlSpec, Observation
from controllers.qp_mpc import QPMPC
from controllers.rc_problem import DEFAULT_REGULARISATION
from pinn_mpc.errors import InputError
from pinn_mpc.physics import RCParams


class Oracle(QPMPC):
    """Receding-horizon MPC with the true state (T_r, T_m) instead of an observer."""

    name = "oracle"

    def _estimate_state(self, obs: Observation) -> np.ndarray:
        if not math.isfinite(obs.t_m_true_c):
            raise InputError(
                f"{self.name} needs the true thermal-mass temperature, got obs.t_m_true_c="
                f"{obs.t_m_true_c}; use it only against the simulator"
            )
        return np.array([obs.t_r_c, obs.t_m_true_c], dtype=float)


class Clairvoyant(Oracle):
    """The whole run of ``n_steps`` intervals solved as one (shrinking-horizon) problem."""

    name = "clairvoyant"

    def __init__(
        self,
        params: RCParams,
        spec: ControlSpec,
        n_steps: int,
        *,
        regularisation_eur_per_kw2h: float = DEFAULT_REGULARISATION,
        solver_options: dict[str, Any] | None = None,
    ) -> None:
        if n_steps < 1:
            raise InputError(f"Clairvoyant.n_steps must be >= 1 (the run length), got {n_steps}")
        self.n_steps = n_steps
        super().__init__(
            params,
            spec,
            horizon_steps=n_steps,
            regularisation_eur_per_kw2h=regularisation_eur_per_kw2h,
            solver_options=solver_options,
        )

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._k_start: int | None = None

    def _n_active(self, obs: Observation) -> int:
        if self._k_start is None:
            self._k_start = obs.k
        return max(self.n_steps - (obs.k - self._k_start), 1)
