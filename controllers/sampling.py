"""Random shooting and CEM controllers over batched dynamics models (learned or physical).

Every ``act`` builds an objective over candidate demand sequences (N, H) [W] and hands it to a
planner of :mod:`controllers.planners`. The objective rolls all candidates and all ensemble
members out in one :meth:`pinn_mpc.models.rollout.BatchDynamics.rollout` call under ``torch.no_grad`` and scores them
with :class:`controllers.objective.HorizonObjective` (evaluated in torch): price x delivered energy + comfort weight x band
violation x dt_h, where *delivered* is the model's predicted ``u_phys`` (so the planner knows
the backup thermostat will override it) and the temperature is the predicted ``T_r`` at the end
of each interval. On a building of several zones or actuators (a spec that is not
:attr:`controllers.base.ControlSpec.single`) plans are (N, H, A) over a model of the building's
zones and actuators, and ``act`` returns (A,): :mod:`controllers.zone_sampling`; what follows
is the one-zone path.

Four defaults matter in closed loop (their measured effect, and what was tried instead, is in
``CHANGELOG.md`` and ``docs/results/measured.md``):

- ``ensemble="mean"``: the members' mean prediction is scored (a seed ensemble as one point
  predictor). ``"members"`` scores each member and averages the costs, plus ``risk_weight`` x
  their std: it plans for every member, so the members' spread (a few tenths of a kelvin)
  becomes a comfort margin paid for in energy.
- ``offset_gain=0.5``: offset-free MPC. The controller's estimator component,
  :class:`controllers.estimators.OffsetFilter`, filters the error of the model's one-step
  prediction of the interval that just ended into an offset added to every predicted ``T_r``.
  It removes the slowly varying bias a learned model has in closed-loop operating points.
- CEM polishes its plan with one LP on the linearised model (:mod:`controllers.lp_polish`),
  which takes a plan the last few percent to the optimum of the model; random shooting does
  not by default (``polish_iters``), so it shows what sampling alone does.
- CEM and random shooting plan against the comfort band narrowed by ``comfort_margin_k`` (None:
  :data:`ONE_ZONE_COMFORT_MARGIN_K`, 0.01 K; over several zones
  :func:`controllers.zone_sampling.zone_comfort_margin_k`) on each side (constraint tightening,
  :meth:`controllers.objective.HorizonObjective.tightened`): a plan that rides a band edge
  exactly (the optimum does) and a model a few millikelvin off in closed loop would overshoot
  it at most intervals.
- Random shooting samples room-temperature setpoint schedules (``space="setpoint"``): offsets
  from the band edge, turned into powers by tracking them through the model linearised around
  the warm start (:mod:`controllers.setpoint_space`; the probes come out of the same budget of
  128 rollouts). In power space the search plateaus above the optimum because the optimum
  rides the band edge; in setpoint space that plan is one sample.

The plan is warm-started from the previous plan shifted by one step (its last action
repeated); the first plan starts from half power.

Fallback (never an exception out of ``act``): with a :class:`Guard`'s RC, the MPC on that RC
decides whenever the model does not (distrusted by :mod:`controllers.trust`, a non-finite
prediction or any other failure, too short a history: fewer than ``depth + 1`` past
intervals); without one, the controller acts through :class:`controllers.base.Fallback` (the
band-keeping rule on the measured room temperature). Either way ``last_stats.fallback`` is True
with the reason in ``status`` (so the KPIs' ``fallbacks`` count every decision the model did not
make), and a failure clears ``last_plan`` and restarts the next warm start from scratch.

Speed: a rollout is a few small tensor ops per horizon step for the whole batch, so its time
is mostly fixed per horizon step and an iteration costs about as much as many more candidates
(``benchmarks/bench_planners.py`` times it). On a shared 2-core machine one intra-op thread is
fastest (``torch.set_num_threads(1)`` in the caller).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import torch

from controllers.base import (
    EXOGENOUS_NAMES,
    ControlSpec,
    Fallback,
    Forecast,
    Observation,
    PlanningController,
    SolveStats,
    check_heating,
)
from controllers.estimators import OffsetFilter
from controllers.lp_polish import PiggybackPolish, PlanProblem, PolishSettings, RolloutFn
from controllers.objective import HorizonObjective
from controllers.planners import CEMPlanner, Planner, PlanResult, RandomShootingPlanner
from controllers.setpoint_space import SetpointSpace
from controllers.trust import RCReplay, TrustMonitor, TrustSettings
from controllers.zone_sampling import ZoneGuard, ZoneSampling, zone_comfort_margin_k
from pinn_mpc.errors import InternalError
from pinn_mpc.features import check_interval
from pinn_mpc.models.rollout import BatchDynamics
from pinn_mpc.physics import RCParams
from pinn_mpc.records import TrustReport

__all__ = ["CEM", "ENSEMBLE_MODES", "Guard", "RandomShooting"]

#: How ensemble members enter the objective: "mean" scores the members' average prediction (a
#: seed ensemble as one point predictor); "members" averages the members' costs (plus
#: ``risk_weight`` x their std), which plans for every member and so hedges against their spread.
ENSEMBLE_MODES = ("mean", "members")

#: The comfort margin [K] a planner of one zone plans with by default (module docstring; over
#: several zones :func:`controllers.zone_sampling.zone_comfort_margin_k`).
ONE_ZONE_COMFORT_MARGIN_K = 0.01

#: What random shooting samples: demanded powers, or room-temperature setpoint schedules tracked
#: through the model (:mod:`controllers.setpoint_space`).
PLAN_SPACES = ("power", "setpoint")


class _Options(NamedTuple):
    """How a sampling controller scores and refines plans (see the module docstring); on/off
    actions are never polished (the LP plan is continuous)."""

    risk_weight: float
    ensemble: str
    offset_gain: float
    polish_iters: int
    comfort_margin_k: float | None


class _NonFiniteModelOutput(Exception):
    pass


class Guard(NamedTuple):
    """What a sampling controller falls back on when its model is not to be trusted
    (:mod:`controllers.trust`): the RC identified from the model's training data (None: no
    fallback, the model always drives), the monitor's limits, and the training data's input
    ranges (``{"T_a": (lo, hi), "G": (lo, hi)}``, empty when unknown)."""

    rc: RCParams | None = None
    settings: TrustSettings = TrustSettings()
    training_ranges: dict[str, tuple[float, float]] = {}


#: No RC fallback: the model always drives (its errors are still monitored and counted).
NO_GUARD = Guard()


class _SamplingController(ZoneSampling, PlanningController):
    """Shared ``reset``/``act`` of the sampling controllers (see the module docstring; over a
    building of several zones or actuators, :mod:`controllers.zone_sampling`)."""

    name = "sampling"

    def __init__(
        self,
        model: BatchDynamics,
        spec: ControlSpec,
        planner: Planner,
        options: _Options,
        guard: Guard | ZoneGuard,
    ):
        risk_weight, ensemble = options.risk_weight, options.ensemble
        if spec.single:
            if model.actuators is not None:
                raise ValueError(
                    f"{type(self).__name__}: the model plans {len(model.actuators)} actuator(s) "
                    "of a building of zones, but the scenario has one zone with one actuator; "
                    "give a model of one zone (a trained model, or pinn_mpc.models.rc.RCBatchModel)"
                )
            check_heating(model.eta, spec, what="the model")
        check_interval(model.dt_s, spec.dt_s, what="the scenario's control interval is")
        for name in model.exog_names:
            if name not in EXOGENOUS_NAMES:
                raise ValueError(
                    f"{type(self).__name__}: model exogenous input {name!r} has no forecast; "
                    f"known inputs are {sorted(EXOGENOUS_NAMES)}"
                )
        if not (risk_weight >= 0 and np.isfinite(risk_weight)):
            raise ValueError(f"{type(self).__name__}.risk_weight must be >= 0, got {risk_weight}")
        self.model, self.spec, self.planner, self.risk_weight = model, spec, planner, risk_weight
        # A model whose horizon is affine in the plan (the ARX) but time-varying (its schedule)
        # is linearised exactly only when every step is probed.
        self.polish = PolishSettings(iters=options.polish_iters, probe_stride=1 if model.affine_in_plan else 4)
        if ensemble not in ENSEMBLE_MODES:
            raise ValueError(
                f"{type(self).__name__}.ensemble must be one of {', '.join(ENSEMBLE_MODES)}, "
                f"got {ensemble!r}"
            )
        self.ensemble = ensemble
        margin = options.comfort_margin_k
        if margin is None:  # the default: one zone's, or the zones' by the model's kind
            margin = ONE_ZONE_COMFORT_MARGIN_K if spec.single else zone_comfort_margin_k(model)
        if not (0 <= margin < 1 and np.isfinite(margin)):
            raise ValueError(
                f"{type(self).__name__}.comfort_margin_k must lie in [0, 1) K (or None: the "
                f"default), got {margin}"
            )
        self.comfort_margin_k = margin
        if risk_weight > 0 and ensemble != "members":
            raise ValueError(
                f"{type(self).__name__}.risk_weight needs ensemble='members' (the spread of the "
                f"members' costs); got risk_weight={risk_weight} with ensemble={ensemble!r}"
            )
        self.last_cost_eur = float("nan")  # planned objective of the last plan [EUR]
        if not spec.single:  # a building of several zones or actuators
            if isinstance(guard, Guard) and guard != NO_GUARD:
                raise ValueError(
                    f"{type(self).__name__}.guard: a planner of several actuators falls back on "
                    "the QP MPC of its model's zone_params, not a guard's one-zone RC; leave guard "
                    "out or give a controllers.zone_sampling.ZoneGuard"
                )
            self._init_zones(options.offset_gain, guard if isinstance(guard, ZoneGuard) else ZoneGuard())
            self.reset()
            return
        if isinstance(guard, ZoneGuard):
            raise ValueError(
                f"{type(self).__name__}.guard: a ZoneGuard watches a model of several zones; this "
                "scenario has one zone: give a controllers.sampling.Guard or leave guard out"
            )
        try:
            self.estimator = OffsetFilter(model, options.offset_gain)
        except ValueError as exc:
            raise ValueError(f"{type(self).__name__}.{exc}") from exc
        self.fallback = Fallback(spec, reuse_plan=False)
        self.monitor = TrustMonitor(guard.settings, spec.actuator.span_w)
        self.training_ranges = dict(guard.training_ranges)
        self.shadow = None
        self.replay: RCReplay | None = None  # the shadow's estimates, replayed
        if guard.rc is not None:
            from controllers.rc_mpc.osqp import QPMPC

            check_heating(guard.rc.eta, spec, what="the model's fallback RC")
            self.shadow = QPMPC(guard.rc, spec)
            self.replay = RCReplay(guard.rc, spec, guard.settings.replay_steps)
        self.setpoint_stride: int | None = None  # probe stride when planning in setpoint space
        self.reset()

    @property
    def offset_gain(self) -> float:
        """The offset filter's gain (over several zones, each zone's filter's)."""
        return self.estimator.gain if self.spec.single else self._zone_offset.gain

    def reset(self, seed: int | None = None) -> None:
        """Forget the warm start; reseed the sampling generator (entropy when ``seed`` is None)."""
        self._generator = torch.Generator()
        if seed is None:
            self._generator.seed()
        else:
            self._generator.manual_seed(seed)
        self._stats = SolveStats(time_s=0.0, status="reset", iterations=0, fallback=False)
        if not self.spec.single:
            self._reset_zones()
            return
        self.fallback.reset()
        self.estimator.reset()
        self.monitor.reset()
        if self.shadow is not None and self.replay is not None:
            self.shadow.reset(seed)
            self.replay.reset()

    @property
    def trust_report(self) -> TrustReport | None:
        """The trust monitor's counts since ``reset`` (the KPIs report them; over several
        zones the building's, with the worst zone's errors)."""
        if not self.spec.single:
            return self._zone_trust_report()
        s = self.monitor.state
        return {
            "model_fallback": self.shadow is not None,
            "model_fallback_switches": s.switches,
            "model_fallback_steps": s.fallback_steps,
            "model_fallback_reasons": dict(s.reasons),
            "out_of_training_range_steps": s.out_of_range_steps,
            "model_error_k": round(s.error_k, 4),
            "model_replay_error_k": round(s.replay_k, 4) if math.isfinite(s.replay_k) else None,
            "rc_replay_error_k": round(s.replay_rc_k, 4) if math.isfinite(s.replay_rc_k) else None,
        }

    def act(self, obs: Observation, forecast: Forecast) -> float | np.ndarray:
        """Demanded power for the coming interval [W], within the actuator's bounds: the model's plan,
        or the fallback RC MPC's action while the model is not to be trusted (over several
        actuators, (A,): :mod:`controllers.zone_sampling`)."""
        if not self.spec.single:
            return self._act_zones(obs, forecast)
        start = time.perf_counter()
        shadow_u = None
        try:
            if self.shadow is not None:  # every step, so that its observer stays current
                self.shadow.comfort_margin_k = self.monitor.fallback_margin_k(self._colder(forecast))
                shadow_u = self.shadow.act(obs, forecast)
                if self.replay is not None:
                    self.replay.record(obs.k, self.shadow.state_estimate_c)
            if len(obs.history["u_phys"]) < self.model.depth + 1:
                if shadow_u is not None:  # the model cannot predict yet: not a verdict on it
                    self.monitor.stand_in("short history")
                    return self._rc_decides(shadow_u, start, "short history", 0)
                return self._fallback(obs, forecast, start, "short history")
            plan, cost, iterations, spread = self._solve(obs, forecast)
        except _NonFiniteModelOutput:
            return self._model_failed(obs, forecast, start, shadow_u, "non-finite model output", "")
        except Exception as exc:  # a failed solve must not stop a closed-loop run
            detail = f": {type(exc).__name__}: {exc}"
            return self._model_failed(obs, forecast, start, shadow_u, "model error", detail)
        self.fallback.planned(plan)
        self.last_cost_eur = cost
        reason = self.monitor.reason(spread)
        if shadow_u is not None and not self.monitor.decide(reason):
            return self._rc_decides(shadow_u, start, reason or "recovering", iterations)
        self._stats = SolveStats(
            time_s=time.perf_counter() - start, status="ok", iterations=iterations, fallback=False
        )
        return float(self.spec.actuator.clip(plan[0]))

    def _replay_errors(self, obs: Observation) -> tuple[float, float]:
        """Measured minus replayed T_r now [K], of the model and of the fallback RC, over the
        last ``replay_steps`` intervals (fewer, down to 2, early in a run) under the delivered
        power (NaN where there is too little history, or no settled RC estimate)."""
        # The longest replay from a settled RC estimate (2 .. replay_steps intervals), else the
        # longest the history allows, for the model alone.
        hist = obs.history
        longest = min(self.monitor.settings.replay_steps, len(hist["u_phys"]) - self.model.depth - 1)
        r = longest if self.replay is None else self.replay.longest(obs.k, longest)
        if r < 2:
            return math.nan, math.nan
        u_phys = np.asarray(hist["u_phys"], dtype=float)[-r:]
        past = {name: np.asarray(values)[:-r] for name, values in hist.items()}
        exog = {name: np.asarray(hist[name], dtype=float)[-r - 1 : -1] for name in self.model.exog_names}
        with torch.no_grad():
            roll = self.model.rollout(past, torch.tensor(u_phys[None], dtype=torch.float32), exog)
        learned = float(roll.t_r_c[:, 0, -1, 0].mean())  # the planned zone
        rc = math.nan if self.replay is None else self.replay.error_k(obs.k, obs.t_r_c, hist, r)
        return obs.t_r_c - learned, rc

    def _colder(self, forecast: Forecast) -> bool:
        """Whether the forecast's outdoor temperature over the horizon falls below the lowest
        of the training data (False where that is unknown)."""
        lo = self.training_ranges.get("T_a", (math.nan, math.nan))[0]
        t_a = np.asarray(forecast.T_a, dtype=float)[: self.spec.horizon_steps]
        return math.isfinite(lo) and t_a.size > 0 and float(np.nanmin(t_a)) < lo

    def _out_of_range(self, exog: dict[str, np.ndarray]) -> None:
        """Count a forecast that leaves the training data's input ranges."""
        excess = 0.0
        for name, (lo, hi) in self.training_ranges.items():
            if name in exog and len(exog[name]):
                v = np.asarray(exog[name], dtype=float)
                excess = max(excess, float(v.max()) - hi, lo - float(v.min()))
        if excess > 0:
            self.monitor.state.out_of_range_steps += 1

    def _rc_decides(self, shadow_u: float, start: float, reason: str, iterations: int) -> float:
        """The fallback RC MPC's action ``shadow_u`` [W] for this decision (the monitor has
        counted it), with stats that say the controller's fallback acted."""
        self._stats = SolveStats(
            time_s=time.perf_counter() - start,
            status=f"rc-mpc fallback: {reason}",
            iterations=iterations,
            fallback=True,
        )
        return float(self.spec.actuator.clip(shadow_u))

    def _model_failed(
        self,
        obs: Observation,
        forecast: Forecast,
        start: float,
        shadow_u: float | None,
        reason: str,
        detail: str,
    ) -> float:
        """A model whose planning failed (``reason``, ``detail`` for the status): its fallback RC
        MPC decides and the model is distrusted (a switch, counted), or without one the
        band-keeping rule acts; the warm start restarts from scratch either way."""
        if shadow_u is None:
            return self._fallback(obs, forecast, start, f"{reason}{detail}")
        self.fallback.plan_w = None
        self.last_cost_eur = float("nan")
        self.monitor.decide(reason)
        return self._rc_decides(shadow_u, start, f"{reason}{detail}", 0)

    def _fallback(self, obs: Observation, forecast: Forecast, start: float, reason: str) -> float:
        self.last_cost_eur = float("nan")
        action = self.fallback.act(obs, forecast)
        self._stats = SolveStats(
            time_s=time.perf_counter() - start,
            status=f"fallback: {reason}",
            iterations=0,
            fallback=True,
        )
        return action

    def _warm_start(self, h: int) -> torch.Tensor:
        plan = self.fallback.plan_w
        if plan is None:
            x0 = np.full(h, self.spec.actuator.at_fraction(0.5))
        else:
            shifted = np.append(plan[1:], plan[-1])
            x0 = np.pad(shifted, (0, max(h - len(shifted), 0)), mode="edge")[:h]
        return torch.as_tensor(x0, dtype=torch.float32)

    def _solve(
        self, obs: Observation, forecast: Forecast
    ) -> tuple[np.ndarray, float, int, float]:
        """(plan [W], its planned cost [EUR], iterations, the members' largest std of T_r
        along it [K])."""
        h = min(self.spec.horizon_steps, forecast.horizon)
        if h < 1:
            raise InternalError("the forecast is empty")
        offset = self.estimator.update(obs)
        self.monitor.observe(
            self.estimator.innovation_k, self.estimator.power_error_w, *self._replay_errors(obs)
        )
        objective = HorizonObjective.from_forecast(forecast, self.spec, h).tightened(
            self.monitor.margin_k(self.comfort_margin_k)
        )
        exog = forecast.exogenous(self.model.exog_names, h)
        self._out_of_range(exog)
        rollout, score = self._scorer(obs.history, exog, objective, offset)
        actuator = self.spec.actuator
        problem = PlanProblem(objective=objective, lower=actuator.lower_w, upper=actuator.upper_w)

        x0 = self._warm_start(h)
        polisher = PiggybackPolish(rollout, score, problem, self.polish, x0)
        if self.setpoint_stride is None:
            result = self.planner.optimize(polisher.objective, x0, self._generator)
            plan, cost = result.plan, result.cost
        else:
            plan, cost, result = self._optimize_setpoints(
                rollout, score, objective, polisher, x0, self.setpoint_stride
            )
        polished = polisher.finish()
        if polished is not None and polished[1] < cost:
            plan, cost = polished
        if not np.isfinite(cost):
            raise _NonFiniteModelOutput
        with torch.no_grad():
            members = self.model.rollout(obs.history, plan[None].float(), exog).t_r_c[:, 0, :, 0]
        spread = float(members.std(0, correction=0).max()) if members.shape[0] > 1 else 0.0
        return plan.numpy().astype(float), cost, result.iterations + polisher.lps, spread

    def _optimize_setpoints(
        self,
        rollout: RolloutFn,
        score: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
        objective: HorizonObjective,
        polisher: PiggybackPolish,
        x0: torch.Tensor,
        stride: int,
    ) -> tuple[torch.Tensor, float, PlanResult]:
        """Sample offset schedules from the band edge, tracked through the model linearised
        around ``x0`` (:mod:`controllers.setpoint_space`); the probes are candidates too."""
        actuator = self.spec.actuator
        edge = objective.t_min_c if actuator.heats else objective.t_max_c
        space, batch, predictions = SetpointSpace.probe(
            rollout, x0, torch.as_tensor(edge), actuator=actuator, stride=stride,
        )
        probe_costs = score(*predictions).double()
        result = self.planner.optimize(
            lambda offsets: polisher.objective(space.powers(offsets)),
            space.offsets_of_warm_start(),
            self._generator,
        )
        plan, cost = space.powers(result.plan[None])[0], result.cost
        best = int(torch.argmin(probe_costs))
        if float(probe_costs[best]) < cost:
            plan, cost = batch[best].clone(), float(probe_costs[best])
        return plan, cost, result

    def _scorer(
        self,
        history: dict[str, np.ndarray],
        exog: dict[str, np.ndarray],
        objective: HorizonObjective,
        offset: float,
    ) -> tuple[RolloutFn, Callable[[torch.Tensor, torch.Tensor], torch.Tensor]]:
        """The model's rollout (with the offset, members merged per ``ensemble``) and the
        objective of its predictions, aggregated over members (mean, plus risk x std)."""
        dtype = torch.float32

        def rollout(u_w: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
            with torch.no_grad():
                roll = self.model.rollout(history, u_w, exog)
                # The one zone it plans (the LP polish and the setpoint space are one zone's).
                t_r, u_phys = roll.t_r_c[..., 0].to(dtype), roll.u_phys_w.to(dtype)
            if not (bool(torch.isfinite(t_r).all()) and bool(torch.isfinite(u_phys).all())):
                raise _NonFiniteModelOutput
            if self.ensemble == "mean":
                return t_r.mean(0, keepdim=True) + offset, u_phys.mean(0, keepdim=True)
            return t_r + offset, u_phys

        def score(t_r: torch.Tensor, u_phys: torch.Tensor) -> torch.Tensor:
            cost = objective.cost_torch(u_phys, t_r)  # (M, N)
            if self.risk_weight > 0 and cost.shape[0] > 1:
                return cost.mean(0) + self.risk_weight * cost.std(0, correction=0)
            return cost.mean(0)

        return rollout, score


_RS = RandomShootingPlanner(lower=0.0, upper=1.0)  # the defaults, defined once in the planners
_CEM = CEMPlanner(lower=0.0, upper=1.0)


def _plan_box(spec: ControlSpec, binary: bool, name: str) -> tuple[float, float]:
    """The planner's box: the one actuator's bounds [W], or each actuator's fraction of its
    range, [0, 1], over several (:mod:`controllers.zone_sampling`)."""
    if spec.single:
        return spec.actuator.lower_w, spec.actuator.upper_w
    if binary:
        raise ValueError(
            f"{name}.binary: on/off plans are one actuator's; this building has "
            f"{spec.n_actuators} actuators: leave binary=False"
        )
    return 0.0, 1.0


class RandomShooting(_SamplingController):
    """Random shooting over a model: ``n_samples`` sequences scored once, the best one applied
    (sampled around the warm start and in a move-blocked plan space, see
    :class:`controllers.planners.RandomShootingPlanner`). By default the samples are setpoint
    offsets [K] in ``[0, setpoint_span_k]`` from the band edge, tracked through the model (the
    linearising probes, every ``probe_stride``-th step, count against ``n_samples``);
    ``space="power"`` samples demanded powers (and on/off plans always do, and so does a plan of
    several actuators, whatever ``space``: :mod:`controllers.zone_sampling`)."""

    name = "random-shooting"

    def __init__(
        self,
        model: BatchDynamics,
        spec: ControlSpec,
        *,
        n_samples: int = _RS.n_samples,
        local_frac: float = _RS.local_frac,
        binary: bool = False,
        risk_weight: float = 0.0,
        polish_iters: int = 0,
        ensemble: str = "mean",
        offset_gain: float = 0.5,
        comfort_margin_k: float | None = None,
        space: str = "setpoint",
        setpoint_span_k: float = 1.0,
        probe_stride: int = 4,
        guard: Guard | ZoneGuard = NO_GUARD,
    ):
        if space not in PLAN_SPACES:
            raise ValueError(
                f"RandomShooting.space must be one of {', '.join(PLAN_SPACES)}, got {space!r}"
            )
        lower, upper = _plan_box(spec, binary, "RandomShooting")
        setpoints = space == "setpoint" and not binary and spec.single
        if setpoints:
            if not (0 < setpoint_span_k < 10):
                raise ValueError(
                    f"RandomShooting.setpoint_span_k must lie in (0, 10) K, got {setpoint_span_k}"
                )
            if probe_stride < 1:
                raise ValueError(f"RandomShooting.probe_stride must be >= 1, got {probe_stride}")
            # The probes that linearise the model come out of the same budget of rollouts.
            n_probes = 1 + -(-spec.horizon_steps // probe_stride)
            if n_samples - n_probes < 2:
                raise ValueError(
                    f"RandomShooting.n_samples={n_samples} leaves fewer than 2 samples after the "
                    f"{n_probes} probes of setpoint space; use more samples or a larger probe_stride"
                )
            planner = RandomShootingPlanner(
                lower=0.0, upper=setpoint_span_k, n_samples=n_samples - n_probes, local_frac=local_frac
            )
        else:
            planner = RandomShootingPlanner(
                lower=lower, upper=upper, n_samples=n_samples, local_frac=local_frac, binary=binary,
            )
        options = _Options(
            risk_weight, ensemble, offset_gain, 0 if binary else polish_iters, comfort_margin_k
        )
        super().__init__(model, spec, planner, options, guard)
        if setpoints:
            self.setpoint_stride = probe_stride


class CEM(_SamplingController):
    """Cross-entropy method over a model (see :class:`controllers.planners.CEMPlanner`).

    The defaults (those of :class:`controllers.planners.CEMPlanner`, coloured noise, one LP
    polish) are set by decision time: a learned model's rollout costs mostly a fixed time per
    horizon step, so iterations are expensive and samples cheap, and the polish rides along in
    the same batches (``benchmarks/bench_planners.py`` times it). The sampling finds the shape
    of the plan, the polish its last percent (see :mod:`controllers.lp_polish`).
    """

    name = "cem"

    def __init__(
        self,
        model: BatchDynamics,
        spec: ControlSpec,
        *,
        n_samples: int = _CEM.n_samples,
        n_iters: int = _CEM.n_iters,
        elite_frac: float = _CEM.elite_frac,
        alpha: float = _CEM.alpha,
        init_std_frac: float = _CEM.init_std_frac,
        noise_beta: float = _CEM.noise_beta,
        binary: bool = False,
        risk_weight: float = 0.0,
        polish_iters: int = 1,
        ensemble: str = "mean",
        offset_gain: float = 0.5,
        comfort_margin_k: float | None = None,
        guard: Guard | ZoneGuard = NO_GUARD,
    ):
        lower, upper = _plan_box(spec, binary, "CEM")
        planner = CEMPlanner(
            lower=lower,
            upper=upper,
            n_samples=n_samples,
            n_iters=n_iters,
            elite_frac=elite_frac,
            alpha=alpha,
            init_std_frac=init_std_frac,
            noise_beta=noise_beta,
            binary=binary,
        )
        options = _Options(
            risk_weight, ensemble, offset_gain, 0 if binary else polish_iters, comfort_margin_k
        )
        super().__init__(model, spec, planner, options, guard)
