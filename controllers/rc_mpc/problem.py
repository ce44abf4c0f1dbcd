"""The linear MPC problem on RC parameters, and the controller shell its solvers share.

Over H control intervals j = 0..H-1, with decision power ``p_j`` [kW] within the actuator's
bounds ``[p_min, p_max]`` (``spec.actuator``) and comfort slack ``s_j >= 0`` [K]::

    minimise   sum_j  price_j dt_h p_j  +  comfort_weight dt_h s_j  +  rho dt_h p_j^2
    subject to x[j+1] = Ad x[j] + Bd (1000 p_j, T_a,j, G_j, I_g,j)      (exact ZOH, physics.discretise)
               T_min,j - s_j <= T_r[j+1] <= T_max,j + s_j

``p_j`` is electrical. With a heat pump (``spec.actuator``) the building receives
``COP(T_a,j) p_j``: the COP is evaluated on the forecast outdoor temperature, so the problem is
still linear, ``B_u,j = COP(T_a,j) b`` (exact for the plant's COP curve; only the forecast's
T_a error enters). The solvers plan the delivered heat ``q_j = COP_j p_j`` instead, so that
their matrices stay fixed: the price of heat is ``price_j / COP_j``, its bounds ``COP_j p_min``
and ``COP_j p_max``, and the regulariser acts on ``q`` (a tie-breaker either way). For the ideal
heater ``COP_j = 1`` and nothing changes.

The first two terms are :class:`controllers.objective.HorizonObjective` with ``s`` as the band
violation: its price and band arrays are the QP data. The third, ``rho =
regularisation_eur_per_kw2h`` (default :data:`DEFAULT_REGULARISATION`), only makes the optimum
unique (the LP is often degenerate, e.g. under a flat price). The backup thermostat of the
simulator is not modelled: the MPC plans as if its demand is always delivered.

Forecast arrays may be longer than H (the first H are used) or shorter (the last value is
repeated). With ``run_steps`` (the clairvoyant) the steps after the run end have zero price and
a band that never binds (:meth:`HorizonObjective.until`), so the regulariser turns the heater
off there.

:class:`RCMPC` is the controller shell both solvers share: a state estimator component (a
Kalman observer on the same parameters unless another is given), timing, status checks and the
fallback (:class:`controllers.base.Fallback`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from controllers.base import (
    ControlSpec,
    Fallback,
    Forecast,
    Observation,
    PlanningController,
    SolveStats,
    check_heating,
    first_values,
)
from controllers.estimators import KalmanEstimator, StateEstimator, TrueState
from controllers.objective import HorizonObjective, narrowed
from controllers.trust import RCReplay, TrustMonitor, TrustSettings
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.physics import RCParams, discretise
from pinn_mpc.records import ReplayMarginReport

__all__ = ["DEFAULT_REGULARISATION", "RCMPC", "RCProblem", "SolveResult", "StageData"]

DEFAULT_REGULARISATION = 1e-4


class StageData(NamedTuple):
    """Numeric data of one solve: the initial state, the drift and the objective (QP data)."""

    x0_c: np.ndarray  # (2,) initial (T_r, T_m) [C]
    free_c: np.ndarray  # (H, 2) state drift per step from exogenous inputs [C]
    objective: HorizonObjective
    cop: np.ndarray  # (H,) heat per electrical watt of each step (1 for the ideal heater)

    @property
    def heat_price_eur_per_kwh(self) -> np.ndarray:
        """(H,) price per kWh of delivered heat: the solvers' linear cost."""
        return self.objective.price_eur_per_kwh / self.cop

    def heat_bounds_kw(self, actuator: ActuatorSpec) -> tuple[np.ndarray, np.ndarray]:
        """(H,) the least and the most heat ``actuator`` delivers in each step [kW]."""
        return actuator.lower_kw * self.cop, actuator.upper_kw * self.cop

    def electrical_kw(self, heat_kw: np.ndarray) -> np.ndarray:
        """Electrical power [kW] of a heat plan (H,)."""
        return np.asarray(heat_kw, dtype=float) / self.cop


@dataclass(frozen=True, kw_only=True)
class RCProblem:
    """Problem data for horizon ``horizon_steps``; the matrices come from physics.discretise."""

    params: RCParams
    spec: ControlSpec
    horizon_steps: int
    regularisation_eur_per_kw2h: float = DEFAULT_REGULARISATION

    def __post_init__(self) -> None:
        if self.horizon_steps < 1:
            raise ValueError(f"RCProblem.horizon_steps must be >= 1, got {self.horizon_steps}")
        rho = self.regularisation_eur_per_kw2h
        if not (math.isfinite(rho) and rho > 0):
            raise ValueError(f"regularisation_eur_per_kw2h must be > 0 (uniqueness), got {rho!r}")
        check_heating(self.params.eta, self.spec, what="the RC parameters")

    @cached_property
    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """``Ad`` (2, 2) and ``Bd`` (2, 4) of the control interval."""
        return discretise(self.params, self.spec.dt_s)

    @cached_property
    def b_u_c_per_kw(self) -> np.ndarray:
        """(2,) state change per kW held over one interval [K/kW]."""
        return self.matrices[1][:, 0] * 1000.0

    def stage(self, x0_c: np.ndarray, forecast: Forecast, *, n_active: int | None = None) -> StageData:
        """Numeric data for a solve from state x0 (2,) and the forecast."""
        h = self.horizon_steps
        _, bd = self.matrices
        exog = np.stack([first_values(a, h) for a in (forecast.T_a, forecast.G, forecast.I_g)], axis=1)
        exog[:, 2] = self.params.gains_w(
            exog[:, 2], first_values(forecast.time_of_day_h, h),
            None if forecast.day_of_week is None else first_values(forecast.day_of_week, h),
        )
        cop = self.spec.actuator.gain(exog[:, 0])
        objective = HorizonObjective.from_forecast(forecast, self.spec, h)
        if n_active is not None:
            objective = objective.until(n_active)
        x0 = np.asarray(x0_c, dtype=float).reshape(2)
        if not np.all(np.isfinite(x0)):
            raise FloatingPointError(f"state estimate is not finite: {x0}")
        return StageData(x0_c=x0, free_c=exog @ bd[:, 1:].T, objective=objective, cop=cop)

    def rollout(self, stage: StageData, p_kw: np.ndarray) -> np.ndarray:
        """States at the end of each interval (H, 2) [C] for electrical plan p (H,) [kW]."""
        ad, _ = self.matrices
        b_u = self.b_u_c_per_kw
        x = stage.x0_c
        out = np.empty((len(p_kw), 2))
        for j, p in enumerate(p_kw):
            x = ad @ x + b_u * (stage.cop[j] * p) + stage.free_c[j]
            out[j] = x
        return out

    def objective(self, stage: StageData, p_kw: np.ndarray) -> float:
        """Objective of electrical plan p (H,) [kW] without the regulariser [EUR]."""
        p_kw = np.asarray(p_kw, dtype=float)
        return float(stage.objective.cost(p_kw * 1000.0, self.rollout(stage, p_kw)[:, 0]))


class SolveResult(NamedTuple):
    p_kw: np.ndarray  # (H,) planned electrical power [kW]
    status: str
    iterations: int
    optimal: bool


class RCMPC(PlanningController):
    """Shared controller shell: estimator, timing, checks, fallback.

    Subclasses give ``_build`` (called once at the end of ``__init__``) and ``_solve``;
    ``solver_options`` are handed to the solver (their meaning is the subclass's).
    ``estimator`` defaults to a :class:`~controllers.estimators.KalmanEstimator` on ``params``;
    ``run_steps`` makes the horizon shrink to the end of a run of that many intervals, counted
    from the first ``act`` after ``reset`` (the clairvoyant); ``name`` overrides the class name.
    ``comfort_margin_k`` [K] (0 unless set; an owner may change it between decisions) narrows
    the forecast's comfort band on each side before each solve, to its middle where the band
    is narrower than twice the margin: a guarded planner sets it on its fallback RC MPC from
    the RC's realised error (:class:`controllers.sampling.CEM`); after
    :meth:`plan_with_replay_margin` the MPC sets it itself by the same rule.

    Fallback (on an exception in the estimate or solve, a non-optimal status or a non-finite
    plan): :class:`controllers.base.Fallback` with the previous plan. ``last_stats.fallback`` is
    then True and ``n_fallbacks`` counts the events since ``reset``.
    """

    name = "rc-mpc"

    def __init__(
        self,
        params: RCParams,
        spec: ControlSpec,
        *,
        estimator: StateEstimator | None = None,
        horizon_steps: int | None = None,
        run_steps: int | None = None,
        regularisation_eur_per_kw2h: float = DEFAULT_REGULARISATION,
        solver_options: dict[str, Any] | None = None,
        name: str | None = None,
    ) -> None:
        if run_steps is not None and run_steps < 1:
            raise ValueError(f"{type(self).__name__}.run_steps must be >= 1 (the run length), got {run_steps}")
        self.params = params
        self.spec = spec
        if name is not None:
            self.name = name
        self.run_steps = run_steps
        self.solver_options = dict(solver_options or {})
        self.problem = RCProblem(
            params=params,
            spec=spec,
            horizon_steps=spec.horizon_steps if horizon_steps is None else horizon_steps,
            regularisation_eur_per_kw2h=regularisation_eur_per_kw2h,
        )
        self.estimator = (
            KalmanEstimator.for_spec(params, spec) if estimator is None else estimator
        )
        self.fallback = Fallback(spec, reuse_plan=True)
        self.comfort_margin_k = 0.0
        self._replay: tuple[RCReplay, TrustMonitor] | None = None
        self.reset()
        self._build()

    def plan_with_replay_margin(self, settings: TrustSettings) -> None:
        """From the next decision on, plan against the band narrowed by this RC's own filtered
        replay error (:class:`controllers.trust.RCReplay`), by the rule a guarded planner's
        fallback follows (:meth:`controllers.trust.TrustMonitor.fallback_margin_k` with
        ``settings``, which must have ``margin_from_replay``): on a plant measured without
        noise (BOPTEST) an MPC that rides the band's edge misses it by the error its RC makes
        over the hours it plans. 0 until the first replay."""
        if not settings.margin_from_replay:
            raise ValueError("plan_with_replay_margin needs TrustSettings(margin_from_replay=True)")
        self._replay = (
            RCReplay(self.params, self.spec, settings.replay_steps),
            TrustMonitor(settings, self.spec.actuator.span_w),
        )
        self.comfort_margin_k = 0.0

    @property
    def replay_report(self) -> ReplayMarginReport | None:
        """After :meth:`plan_with_replay_margin`: the RC's filtered replay error [K] (None
        before the first replay) and the margin it plans with now [K]; else None."""
        if self._replay is None:
            return None
        error = self._replay[1].state.replay_rc_k
        return {
            "rc_replay_error_k": round(error, 4) if math.isfinite(error) else None,
            "comfort_margin_k": round(self.comfort_margin_k, 4),
        }

    #: It plans on RC parameters, over no learned or ARX model (:class:`controllers.base.Controller`).
    model = None

    # -- protocol -------------------------------------------------------------------------
    @property
    def knows_true_state(self) -> bool:
        """Whether its estimator is the plant's true state (the oracle, the clairvoyant)."""
        return isinstance(self.estimator, TrueState)

    def reset(self, seed: int | None = None) -> None:
        """Forget the estimator state, the previous plan and the counters (no randomness used)."""
        self.estimator.reset()
        self.fallback.reset()
        self._k_start: int | None = None
        self._stats = SolveStats(time_s=0.0, status="not run", iterations=0, fallback=False)
        self.state_estimate_c = np.full(2, np.nan)
        if self._replay is not None:
            self._replay[0].reset()
            self._replay[1].reset()
            self.comfort_margin_k = 0.0

    def act(self, obs: Observation, forecast: Forecast) -> float:
        start = time.perf_counter()
        status, iterations = "error", 0
        try:
            self.state_estimate_c = np.full(2, np.nan)
            self.state_estimate_c = self.estimator.update(obs)
            if self._replay is not None:
                self._replayed(obs, *self._replay)
            if self.comfort_margin_k > 0:
                forecast = narrowed(forecast, self.comfort_margin_k)
            stage = self.problem.stage(self.state_estimate_c, forecast, n_active=self._n_active(obs))
            result = self._solve(stage)
            status, iterations = result.status, result.iterations
            p = np.asarray(result.p_kw, dtype=float)
            if not result.optimal or p.shape != (self.problem.horizon_steps,):
                raise RuntimeError(f"solver status {status!r}")
            if not np.all(np.isfinite(p)):
                raise FloatingPointError("solver returned a non-finite plan")
        except Exception as exc:  # any solver failure acts through the fallback, never raises
            return self._failed(obs, forecast, start, f"{status}: {type(exc).__name__}: {exc}", iterations)
        plan_w = self.spec.actuator.clip_kw(p) * 1000.0
        return self._succeeded(plan_w, start, status, iterations)

    def _replayed(self, obs: Observation, replay: RCReplay, monitor: TrustMonitor) -> None:
        """Replay the RC over the last intervals from its earlier estimate, filter its error,
        record this step's estimate and set the margin from the filtered error."""
        hist = obs.history
        r = replay.longest(obs.k, min(replay.replay_steps, len(hist["u_phys"]) - 1))
        if r >= 2:
            monitor.observe(math.nan, math.nan, replay_rc_k=replay.error_k(obs.k, obs.t_r_c, hist, r))
        replay.record(obs.k, self.state_estimate_c)
        self.comfort_margin_k = monitor.fallback_margin_k()

    # -- hooks ----------------------------------------------------------------------------
    def _build(self) -> None:
        """Build the solver once (``self.problem``, ``self.solver_options`` are set)."""
        raise NotImplementedError

    def _solve(self, stage: StageData) -> SolveResult:
        raise NotImplementedError

    def _n_active(self, obs: Observation) -> int | None:
        """Steps left in the run (``run_steps``), else None (receding horizon)."""
        if self.run_steps is None:
            return None
        if self._k_start is None:
            self._k_start = obs.k
        return max(self.run_steps - (obs.k - self._k_start), 1)
