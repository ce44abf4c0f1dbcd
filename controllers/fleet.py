"""Fleet planners: every building of a fleet planned in one batch, state kept per building.

A fleet planner decides for B buildings at once. It splits a decision in three so that a
coordinator (:mod:`controllers.coordination`) can plan the fleet several times per control
step under different prices without disturbing any building's state:

- :meth:`FleetPlanner.observe` feeds every building's estimator its observation, once a step;
- :meth:`FleetPlanner.plan` plans every building under the forecast plus an extra price
  (H,) [EUR/kWh] on electrical energy (the coordination signal), without changing any
  building's estimator, warm start or counters; it may be called many times;
- :meth:`FleetPlanner.commit` applies a plan: the first action of every building that planned,
  each failed building's own :class:`controllers.base.Fallback` otherwise (counted), and the
  warm start of the next step.

:class:`FleetQPMPC` is the ``qp-mpc`` of every building as ONE sparse QP whose blocks are the
buildings: the OSQP data of :mod:`controllers.rc_mpc.qp` built vectorised and solved by
:class:`controllers.rc_mpc.osqp.QPBlocks` (``QPMPC``'s are their one-building case), in the
``BOX`` layout of its rows, on which OSQP converges in fewer iterations (``QPMPC`` keeps
``SPLIT``, the same problem), with the same OSQP settings and each building its own Kalman
observer. A new extra price changes only the linear cost, so a
coordination iteration is a warm-started OSQP solve. Per-building plans equal those of
``QPMPC`` within the solver's tolerance (tests/test_fleet_coordination.py, tests/test_rc_mpc.py).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any, NamedTuple, Protocol

import numpy as np

from controllers.base import (
    ControlSpec,
    Fallback,
    Forecast,
    Observation,
    check_heating,
    first_values,
)
from controllers.estimators import FleetKalmanEstimator
from controllers.objective import HorizonObjective
from controllers.rc_mpc.osqp import CANDIDATE_OPTIONS, OSQP_OPTIONS, QPBlocks
from controllers.rc_mpc.problem import DEFAULT_REGULARISATION
from controllers.rc_mpc.qp import BOX, qp_vectors
from pinn_mpc.errors import InternalError
from pinn_mpc.physics import RCParams, gain_schedule_index
from pinn_mpc.simulator import fleet_matrices, unmeasured_gains

__all__ = ["CANDIDATE_OPTIONS", "FleetDecision", "FleetPlan", "FleetPlanner", "FleetQPMPC"]


class FleetPlan(NamedTuple):
    """Plans of B buildings over H intervals: ``power_w`` (B, H) planned electrical power [W]
    (demanded; what the aggregate is summed from; a building of several actuators: their
    total), ``ok`` (B,) whether the building planned (False: it falls back on commit),
    ``status`` the solver's word, ``iterations``; ``actuator_w`` (B, H, A) each actuator's
    planned power [W] in a fleet of buildings of several actuators (summed over A it is
    ``power_w``; None: one actuator a building, whose plan is ``power_w``); ``plan_id`` which of
    the planner's plans of the step it is (a coordination's settled plan keeps the id of the
    plan it was made from), for a planner that keeps a state per plan (None: it keeps none)."""

    power_w: np.ndarray
    ok: np.ndarray
    status: str
    iterations: int
    actuator_w: np.ndarray | None = None
    plan_id: int | None = None


class FleetDecision(NamedTuple):
    """What :meth:`FleetPlanner.commit` applies: ``u_w`` (B,) demanded power [W] ((B, A) each
    actuator's, for buildings of several actuators), ``fallback``
    (B,) bool (the building's fallback acted: no plan, or its RC MPC decided for a distrusted
    model), ``model_fallback`` (B,) bool (a planner over learned models handed the building to
    its RC MPC; None: no such fallback)."""

    u_w: np.ndarray
    fallback: np.ndarray
    model_fallback: np.ndarray | None = None


class FleetPlanner(Protocol):
    """B buildings planned together (module docstring)."""

    name: str

    @property
    def n_buildings(self) -> int: ...

    @property
    def horizon_steps(self) -> int: ...

    def reset(self, seed: int | None = None) -> None: ...

    def observe(self, observations: Sequence[Observation], forecast: Forecast) -> None: ...

    def plan(self, extra_price_eur_per_kwh: np.ndarray | None = None) -> FleetPlan: ...

    def commit(self, plan: FleetPlan) -> FleetDecision: ...

    @property
    def n_fallbacks(self) -> np.ndarray: ...

    @property
    def rc_candidates(self) -> bool | None:
        """Whether a planner over learned models also scores the shadow RC MPC's plan among
        its samples (None: it plans over no learned model)."""
        ...


class _Stage(NamedTuple):
    """One step's data: the buildings' observations, the forecast, states and objective."""

    observations: tuple[Observation, ...]
    forecast: Forecast
    x0_c: np.ndarray  # (B, 2) (T_r, T_m) estimates [C]
    ok: np.ndarray  # (B,) the estimate is finite
    objective: HorizonObjective
    cop: np.ndarray  # (H,)
    drift_c: np.ndarray  # (B, H, 2) state drift of each step, x0's response in step 0 [C]


class FleetQPMPC:
    """``qp-mpc`` for B buildings (``fleet``: each its own parameters), planned together.

    The problem of :mod:`controllers.rc_mpc.problem` (delivered heat planned, comfort slack,
    regulariser ``regularisation_eur_per_kw2h``) for every building, variables per building
    ``(heat (H), slack (H), states (H, 2))``; ``solver_options`` update
    :data:`controllers.rc_mpc.osqp.OSQP_OPTIONS`. The states come from one Kalman observer per
    building (:meth:`KalmanEstimator.for_spec`'s, all updated in one pass by
    :class:`controllers.estimators.FleetKalmanEstimator`). A building whose estimate is not finite, or
    every building when OSQP does not report ``solved``, falls back (its previous plan, as
    ``QPMPC``), counted in :attr:`n_fallbacks`. ``threads`` share the blocks' solves (default
    the machine's CPUs, at most 2).
    """

    name = "qp-mpc"
    #: It plans on RC parameters, over no learned model (:class:`FleetPlanner`).
    rc_candidates = None

    def __init__(
        self,
        fleet: Sequence[RCParams],
        spec: ControlSpec,
        *,
        horizon_steps: int | None = None,
        regularisation_eur_per_kw2h: float = DEFAULT_REGULARISATION,
        solver_options: dict[str, Any] | None = None,
        block_size: int = 1,
        threads: int | None = None,
    ) -> None:
        if len(fleet) < 1:
            raise InternalError("FleetQPMPC needs at least one building")
        for i, params in enumerate(fleet):
            check_heating(params.eta, spec, what=f"building {i}'s RC parameters")
        h = spec.horizon_steps if horizon_steps is None else horizon_steps
        if h < 1:
            raise ValueError(f"FleetQPMPC.horizon_steps must be >= 1, got {h}")
        if not (np.isfinite(regularisation_eur_per_kw2h) and regularisation_eur_per_kw2h > 0):
            raise ValueError(
                f"regularisation_eur_per_kw2h must be > 0 (uniqueness), got {regularisation_eur_per_kw2h!r}"
            )
        self.fleet, self.spec, self._h = tuple(fleet), spec, h
        self.rho = regularisation_eur_per_kw2h
        self.solver_options = {**OSQP_OPTIONS, **(solver_options or {})}
        ad, bd = fleet_matrices(self.fleet, spec.dt_s)  # (B, 2, 2), (B, 2, 4)
        self._ad, self._bd = ad, bd
        self._schedules = unmeasured_gains(self.fleet)
        try:
            self._solver = QPBlocks(
                ad, bd[:, :, 0] * 1000.0, h, 2.0 * spec.dt_h * self.rho, BOX, self.solver_options,
                block_size=block_size, threads=min(2, os.cpu_count() or 1) if threads is None else threads,
            )
        except ValueError as exc:
            raise ValueError(f"FleetQPMPC.{exc}") from exc
        self.estimator = FleetKalmanEstimator(ad, bd, spec, schedules=self._schedules)
        self.fallbacks = [Fallback(spec, reuse_plan=True) for _ in self.fleet]
        self.reset()

    @property
    def n_buildings(self) -> int:
        return len(self.fleet)

    @property
    def horizon_steps(self) -> int:
        return self._h

    @property
    def n_fallbacks(self) -> np.ndarray:
        """(B,) fallback events of each building since ``reset``."""
        return np.array([f.n_events for f in self.fallbacks])

    def reset(self, seed: int | None = None) -> None:
        """Forget estimates, plans, counters and the solver's warm start (no randomness)."""
        self.estimator.reset()
        for f in self.fallbacks:
            f.reset()
        self._solver.reset()
        self._stage: _Stage | None = None

    def observe(self, observations: Sequence[Observation], forecast: Forecast) -> None:
        """Every building's Kalman update on its observation; the step's QP data."""
        if len(observations) != self.n_buildings:
            raise InternalError(
                f"FleetQPMPC.observe: {len(observations)} observations for {self.n_buildings} buildings"
            )
        with np.errstate(invalid="ignore", over="ignore"):
            x0 = self.estimator.update(observations)
        ok = np.all(np.isfinite(x0), axis=1)  # a failed estimate falls back for this building only
        # A failed building keeps the QP well posed from its measurement; it does not act on it.
        measured = np.array([o.t_r_c for o in observations], dtype=float)
        x0[~ok] = np.where(np.isfinite(measured[~ok]), measured[~ok], 20.0)[:, None]
        h = self._h
        exog = np.stack([first_values(a, h) for a in (forecast.T_a, forecast.G, forecast.I_g)], axis=1)
        drift = np.einsum("hc,brc->bhr", exog, self._bd[:, :, 1:])
        if self._schedules is not None:  # each building's unmeasured gains
            index = gain_schedule_index(
                first_values(forecast.time_of_day_h, h),
                None if forecast.day_of_week is None else first_values(forecast.day_of_week, h),
            )
            drift += np.einsum("bh,br->bhr", self._schedules[:, index], self._bd[:, :, 3])
        drift[:, 0] += np.einsum("brc,bc->br", self._ad, x0)
        self._stage = _Stage(
            observations=tuple(observations),
            forecast=forecast,
            x0_c=x0,
            ok=ok,
            objective=HorizonObjective.from_forecast(forecast, self.spec, h),
            cop=np.asarray(self.spec.actuator.gain(exog[:, 0]), dtype=float) * np.ones(h),
            drift_c=drift,
        )

    def _data(self, extra: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """OSQP's q, l, u (B, ...) for the step's stage and the extra price (H,)."""
        s = self._stage
        assert s is not None  # observe() comes first (an internal order, not user input)
        obj = s.objective
        heat_price = (obj.price_eur_per_kwh + extra) / s.cop
        actuator = self.spec.actuator
        # (COP x W) / 1000, the order of arithmetic the fleet's results were made in
        heat_bounds = s.cop * actuator.lower_w / 1000.0, s.cop * actuator.upper_w / 1000.0
        return qp_vectors(s.drift_c, heat_price, heat_bounds, obj, BOX)

    def plan(
        self,
        extra_price_eur_per_kwh: np.ndarray | None = None,
        *,
        only: np.ndarray | None = None,
        fast: bool = False,
    ) -> FleetPlan:
        """Every building's plan under the forecast plus ``extra_price_eur_per_kwh`` (H,)
        (default 0) on electrical energy; warm-started from the last solve. ``only`` (B,) bool:
        solve the blocks of these buildings only (the others are not ``ok``). ``fast``: solve
        to :data:`CANDIDATE_OPTIONS` (looser tolerances, no polishing, at most 200 iterations;
        for plans that are only scored as candidates, never applied as they are)."""
        if self._stage is None:
            raise InternalError("FleetQPMPC.plan: call observe() first")
        h = self._h
        extra = np.zeros(h) if extra_price_eur_per_kwh is None else np.asarray(extra_price_eur_per_kwh, float)
        if extra.shape != (h,) or not np.all(np.isfinite(extra)):
            raise InternalError(f"FleetQPMPC.plan: the extra price must be {h} finite values, got {extra!r}")
        solution = self._solver.solve(*self._data(extra), only=only, fast=fast)
        statuses = solution.statuses if only is None or only.all() else {"solved", *solution.statuses}
        x = solution.x
        p_kw = x[:, :h] / self._stage.cop
        ok = self._stage.ok & solution.solved & np.all(np.isfinite(p_kw), axis=1)
        power = self.spec.actuator.clip_kw(np.nan_to_num(p_kw)) * 1000.0
        status = "solved" if statuses == {"solved"} else ", ".join(sorted(statuses))
        return FleetPlan(power_w=power, ok=ok, status=status, iterations=solution.iterations)

    def commit(self, plan: FleetPlan, *, active: np.ndarray | None = None) -> FleetDecision:
        """Apply ``plan``: first actions of the buildings that planned, fallbacks otherwise;
        the solver's solution shifted one step is the next step's warm start. ``active`` (B,)
        bool: only these buildings act (the others get 0 W and count nothing: a shadow MPC
        acts only where its model is distrusted)."""
        s = self._stage
        if s is None:
            raise InternalError("FleetQPMPC.commit: call observe() and plan() first")
        u = np.zeros(self.n_buildings)
        for i, fallback in enumerate(self.fallbacks):
            if active is not None and not active[i]:
                continue
            if plan.ok[i]:
                fallback.planned(plan.power_w[i].copy())
                u[i] = plan.power_w[i, 0]
            else:
                u[i] = fallback.act(s.observations[i], s.forecast)
        self._solver.shift()
        self._stage = None
        failed = ~plan.ok if active is None else active & ~plan.ok
        return FleetDecision(u_w=u, fallback=failed)
