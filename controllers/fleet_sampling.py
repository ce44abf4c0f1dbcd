"""CEM over every building's planner model in one batched rollout (a fleet planner).

:class:`FleetCEM` is the ``cem`` controller of :mod:`controllers.sampling` for B buildings at
once, behind :class:`controllers.fleet.FleetPlanner`: each CEM iteration rolls all buildings x
samples x horizon out in ONE call of a fleet model (:class:`pinn_mpc.models.fleet.FleetModels`
over any model family: hybrids in one stacked batch, an ARX or PhysNet building through its own
rollout), scores them with the objective (price plus the coordination price, band violation;
the members' mean prediction plus the building's offset, as ``ensemble="mean"``) and refits
each building's sampling distribution (:meth:`controllers.planners.CEMPlanner.optimize_batch`,
whose one-building case the single controller runs, each building drawing from its own
generator).

Kept per building, in the single controller's arithmetic (so a fleet of one building decides
as the single controller does without polish and RC fallback): the warm start (its last plan
shifted), the offset filter (offset-free MPC, one batched replay of the interval that just
ended), the comfort margin from its filtered error, its :class:`controllers.trust.TrustMonitor`
(delivered power error, ensemble disagreement along the chosen plan, rolled out over all
members) and its fallbacks: the band-keeping rule when the history is short or the model's
output not finite (counted as fallbacks), and the shadow RC MPC on the RC identified from its
training data while the model is not trusted (a :class:`controllers.fleet.FleetQPMPC` whose
Kalman observers follow every step and which solves only for the distrusted buildings; counted
per building, and as fallbacks too: a decision the model did not make).

Not batched, so not done here: the single controller's multi-step replay of the model against
the RC (the monitor sees the one-step innovation and power error instead), the LP polish and
random shooting's setpoint space.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import NamedTuple, cast

import numpy as np
import torch

from controllers.base import ControlSpec, Fallback, Forecast, Observation, check_heating
from controllers.estimators import FleetOffsetFilter
from controllers.fleet import FleetDecision, FleetPlan, FleetQPMPC
from controllers.objective import (
    HorizonObjective,
    comfort_cost_torch,
    energy_cost_eur,
    narrowed_band,
)
from controllers.planners import CEMPlanner
from controllers.trust import TrustMonitor, TrustSettings
from pinn_mpc.errors import InternalError
from pinn_mpc.models.fleet import FleetModels, FleetStart

__all__ = ["FleetCEM"]


#: Plans a step has scored (B, N, H) [W], their predicted delivered power (B, N, H) [W] and
#: comfort cost (B, N) [EUR].
PoolEntry = tuple[torch.Tensor, torch.Tensor, torch.Tensor]


class _Step(NamedTuple):
    observations: tuple[Observation, ...]
    forecast: Forecast
    start: FleetStart | None  # None: the history is too short for the models
    spread_start: FleetStart | None  # the same for the disagreement's members (None: not measured)
    price: np.ndarray  # (H,)
    t_min: torch.Tensor  # (B, 1, H) tightened band
    t_max: torch.Tensor
    offset: torch.Tensor  # (B, 1, 1) [K]
    x0: torch.Tensor  # (B, H) warm starts


class FleetCEM:
    """CEM over B buildings' planner models, planned in one batch (module docstring).

    ``dynamics`` plans (e.g. ``FleetModels(models, members=1)``: fewer members, a cheaper
    rollout); ``spread_dynamics`` (e.g. a few members) measures the members' disagreement along
    the chosen plans (None: not measured); ``shadow`` is the fallback RC MPC of every building
    (None: the models always drive). ``planner`` holds the CEM settings (bounds are the
    actuator's). A re-plan within a step (the next coordination price) picks each building's
    best of the plans the step has scored (the price enters the objective linearly: each plan's
    rollout is kept with its energy per interval and comfort cost, no rollout is repeated);
    ``replan_iters`` > 0 runs that many CEM iterations from the step's last plans instead.

    With ``rc_candidates`` a step's first plan also scores the shadow RC MPC's plan as one of
    its first samples, so the CEM starts from the RC's optimum where its own samples do not
    beat it, e.g. when a coordination price comes or goes and the warm start is far off. Each
    building's RC plan is solved every ``rc_refresh`` steps, the buildings in turn (its last
    plan shifted one interval stands in between; before its first, the warm start), to
    :data:`controllers.fleet.CANDIDATE_OPTIONS` with ``fast_candidates``; with CEM re-plans
    every re-plan solves them all under its prices.
    """

    name = "cem"

    def __init__(
        self,
        dynamics: FleetModels,
        spec: ControlSpec,
        *,
        planner: CEMPlanner | None = None,
        offset_gain: float = 0.5,
        comfort_margin_k: float = 0.01,
        trust: TrustSettings | None = None,
        shadow: FleetQPMPC | None = None,
        spread_dynamics: FleetModels | None = None,
        replan_iters: int = 2,
        rc_candidates: bool = False,
        fast_candidates: bool = False,
        rc_refresh: int = 1,
    ) -> None:
        check_heating(dynamics.eta, spec, what="the fleet's models")
        if not (0 <= comfort_margin_k < 1):
            raise ValueError(f"FleetCEM.comfort_margin_k must lie in [0, 1) K, got {comfort_margin_k}")
        if shadow is not None and shadow.n_buildings != dynamics.n_buildings:
            raise InternalError("FleetCEM: the shadow RC MPC must have one building per model")
        self.dynamics, self.spec = dynamics, spec
        actuator = spec.actuator
        self.planner = (
            planner if planner is not None
            else CEMPlanner(lower=actuator.lower_w, upper=actuator.upper_w, n_samples=32)
        )
        if replan_iters < 0:
            raise ValueError(f"FleetCEM.replan_iters must be >= 0, got {replan_iters}")
        if not (isinstance(rc_refresh, int) and rc_refresh >= 1):
            raise ValueError(f"FleetCEM.rc_refresh must be a whole number >= 1, got {rc_refresh!r}")
        self.fast_candidates, self.rc_refresh = fast_candidates, rc_refresh
        self._pool: list[PoolEntry] = []
        try:
            self.offsets = FleetOffsetFilter(dynamics, offset_gain)
        except ValueError as exc:
            raise ValueError(f"FleetCEM.{exc}") from exc
        self.comfort_margin_k = comfort_margin_k
        self.replan_iters = replan_iters
        if rc_candidates and shadow is None:
            raise InternalError("FleetCEM.rc_candidates needs the shadow RC MPC")
        self.rc_candidates = rc_candidates
        self.shadow, self.spread_dynamics = shadow, spread_dynamics
        b = dynamics.n_buildings
        self.fallbacks = [Fallback(spec, reuse_plan=False) for _ in range(b)]
        settings = TrustSettings() if trust is None else trust
        self.monitors = [TrustMonitor(settings, actuator.span_w) for _ in range(b)]
        self.reset()

    @property
    def n_buildings(self) -> int:
        return self.dynamics.n_buildings

    @property
    def horizon_steps(self) -> int:
        return self.spec.horizon_steps

    @property
    def n_fallbacks(self) -> np.ndarray:
        return np.array([f.n_events for f in self.fallbacks])

    def reset(self, seed: int | None = None) -> None:
        """Forget warm starts, offsets, trust and counters; building b's sampling generator is
        seeded by (seed, b) (entropy when ``seed`` is None)."""
        self.generators = []
        for i in range(self.n_buildings):
            g = torch.Generator()
            if seed is None:
                g.seed()
            else:
                g.manual_seed(int(np.random.SeedSequence([seed, i]).generate_state(1, np.uint64)[0] >> 1))
            self.generators.append(g)
        for f, mon in zip(self.fallbacks, self.monitors, strict=True):
            f.reset()
            mon.reset()
        self.offsets.reset()
        self._plans = torch.zeros(self.n_buildings, self.horizon_steps)  # the last plans (B, H)
        self._has_plan = torch.zeros(self.n_buildings, dtype=torch.bool)
        if self.shadow is not None:
            self.shadow.reset(seed)
        self._step: _Step | None = None
        self._best: torch.Tensor | None = None
        self._steps = 0
        self._rc_plans = np.zeros((self.n_buildings, self.horizon_steps))
        self._rc_valid = np.zeros(self.n_buildings, dtype=bool)

    def observe(self, observations: Sequence[Observation], forecast: Forecast) -> None:
        """Offsets and trust from the interval that just ended (one batched replay), the
        step's objective and rollout start."""
        b, h = self.n_buildings, self.horizon_steps
        if len(observations) != b:
            raise InternalError(f"FleetCEM.observe: {len(observations)} observations for {b} buildings")
        if self.shadow is not None:
            self.shadow.observe(observations, forecast)
        histories = [o.history for o in observations]
        n_past = min(len(hist["u_phys"]) for hist in histories)
        offsets = self.offsets.update(observations)
        for mon, inn, pe in zip(self.monitors, self.offsets.innovation_k, self.offsets.power_error_w, strict=True):
            mon.observe(float(inn), float(pe))
        objective = HorizonObjective.from_forecast(forecast, self.spec, h)
        margins = np.array([m.margin_k(self.comfort_margin_k) for m in self.monitors])[:, None]
        t_min, t_max = narrowed_band(objective.t_min_c[None], objective.t_max_c[None], margins)
        start = spread_start = None
        if n_past >= self.dynamics.depth + 1:
            exog = forecast.exogenous(self.dynamics.exog_names, h)
            start = self.dynamics.prepare(histories, exog, h)
            if self.spread_dynamics is not None:
                spread_start = self.spread_dynamics.prepare(histories, exog, h)
        self._step = _Step(
            observations=tuple(observations),
            forecast=forecast,
            start=start,
            spread_start=spread_start,
            price=np.asarray(objective.price_eur_per_kwh, dtype=float),
            t_min=torch.as_tensor(t_min, dtype=torch.float32)[:, None],
            t_max=torch.as_tensor(t_max, dtype=torch.float32)[:, None],
            offset=torch.as_tensor(offsets, dtype=torch.float32)[:, None, None],
            x0=self._warm_starts(h),
        )
        self._best = None

    def _warm_starts(self, h: int) -> torch.Tensor:
        """(B, H) each building's last plan shifted one interval (its last value repeated), or
        half power where it has none (before its first plan, after a fallback)."""
        x0 = torch.full((self.n_buildings, h), self.spec.actuator.at_fraction(0.5))
        if self._has_plan.any():
            shifted = torch.cat([self._plans[:, 1:], self._plans[:, -1:]], dim=1)
            x0[self._has_plan] = shifted[self._has_plan]
        return x0

    def _costs(self, step: _Step, extra: np.ndarray, u_w: torch.Tensor) -> torch.Tensor:
        """(B, N) objective of plans (B, N, H) under the members' mean prediction + offset,
        as the single controller scores them; the plans, their delivered power and comfort
        cost join the step's pool."""
        assert step.start is not None
        dtype = torch.float32
        roll = self.dynamics.roll(step.start, u_w)
        t_r = roll.t_r_c[..., 0].to(dtype).mean(1) + step.offset  # each building's one zone
        u_phys = roll.u_phys_w.to(dtype).mean(1)  # (B, N, H)
        spec = self.spec
        comfort = comfort_cost_torch(t_r, step.t_min, step.t_max, spec.dt_h, spec.comfort_weight_eur_per_kh)
        price = torch.as_tensor(step.price + extra, dtype=dtype)
        if self.replan_iters == 0:
            self._pool.append((u_w, u_phys, comfort.sum(-1)))
        cost = energy_cost_eur(u_phys, price, spec.dt_h)
        cost += comfort
        return cost.sum(-1)

    def _pool_costs(self, step: _Step, extra: np.ndarray, u_phys: torch.Tensor, comfort: torch.Tensor) -> torch.Tensor:
        """(B, N) objective of plans whose delivered power (B, N, H) [W] and comfort cost
        (B, N) are known, under the step's prices plus ``extra`` (H,)."""
        price = torch.as_tensor(step.price + extra, dtype=torch.float32)
        return energy_cost_eur(u_phys, price, self.spec.dt_h).sum(-1) + comfort

    def plan(self, extra_price_eur_per_kwh: np.ndarray | None = None) -> FleetPlan:
        """Every building's CEM plan under the forecast plus the extra price (H,); a second
        plan of the same step starts from the first one's plans."""
        step = self._step
        if step is None:
            raise InternalError("FleetCEM.plan: call observe() first")
        h, b = self.horizon_steps, self.n_buildings
        extra = np.zeros(h) if extra_price_eur_per_kwh is None else np.asarray(extra_price_eur_per_kwh, float)
        if extra.shape != (h,) or not np.all(np.isfinite(extra)):
            raise InternalError(f"FleetCEM.plan: the extra price must be {h} finite values")
        if step.start is None:
            return FleetPlan(np.zeros((b, h)), np.zeros(b, dtype=bool), "short history", 0)
        if self._best is None:
            x0, planner = step.x0, self.planner
            self._pool = []
        else:  # a re-plan of the step (a new coordination price): from the last plans
            x0 = self._best
            planner = dataclasses.replace(self.planner, n_iters=max(self.replan_iters, 1))
        rescore = self._best is not None and self.replan_iters == 0
        if self.rc_candidates and self.shadow is not None and not rescore:
            # The first plan of a step solves the buildings due (all of them every rc_refresh
            # steps, in turn); a CEM re-plan under a new price solves them all.
            due = (np.arange(b) + self._steps) % self.rc_refresh == 0 if self._best is None else np.ones(b, bool)
            rc = self.shadow.plan(extra, only=None if due.all() else due, fast=self.fast_candidates)
            fresh = rc.ok & due
            self._rc_plans[fresh] = rc.power_w[fresh]
            self._rc_valid |= fresh
        if rescore:
            plans, costs = self._rescore(step, extra)
        else:
            candidates = None
            if self.rc_candidates and self._rc_valid.any():
                # Where the RC has no plan, the warm start stands in (a sample like any other).
                candidates = torch.as_tensor(
                    np.where(self._rc_valid[:, None], self._rc_plans, x0.numpy()), dtype=x0.dtype
                )[:, None]
            plans, costs = planner.optimize_batch(
                lambda u: self._costs(step, extra, u), x0, self.generators, candidates
            )
        self._best = plans
        ok = torch.isfinite(costs).numpy()
        return FleetPlan(plans.double().numpy(), ok, "ok", 0 if rescore else planner.n_iters)

    def _rescore(self, step: _Step, extra: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        """Every building's best plan of the step's pool under the prices plus ``extra``."""
        if len(self._pool) > 1:  # joined once: a step's further re-plans read it as it is
            self._pool = [cast(PoolEntry, tuple(torch.cat(parts, dim=1) for parts in zip(*self._pool, strict=True)))]
        plans, u_phys, comfort = self._pool[0]
        costs = self._pool_costs(step, extra, u_phys, comfort).double()
        costs = torch.where(torch.isfinite(costs), costs, torch.full_like(costs, math.inf))
        best = costs.argmin(dim=1)
        rows = torch.arange(plans.shape[0])
        return plans[rows, best], costs[rows, best]

    def commit(self, plan: FleetPlan) -> FleetDecision:
        """Apply ``plan``: each trusted building's first action, the shadow RC MPC's for the
        distrusted ones, the band-keeping fallback where there is no plan."""
        step = self._step
        if step is None:
            raise InternalError("FleetCEM.commit: call observe() and plan() first")
        b = self.n_buildings
        spread = np.zeros(b)
        if self.spread_dynamics is not None and step.spread_start is not None and plan.ok.any():
            members = self.spread_dynamics.roll(
                step.spread_start, torch.as_tensor(plan.power_w[:, None], dtype=torch.float32)
            ).t_r_c[:, :, 0, :, 0]  # (B, M, H)
            if members.shape[1] > 1:
                spread = members.std(1, correction=0).amax(-1).double().numpy()
        u = np.where(plan.ok, plan.power_w[:, 0], 0.0)
        ok = torch.as_tensor(plan.ok)
        self._plans[ok] = torch.as_tensor(plan.power_w, dtype=torch.float32)[ok]
        self._has_plan = ok.clone()  # a fallback forgets the plan: the next warm start is fresh
        distrusted = np.zeros(b, dtype=bool)
        for i in np.flatnonzero(~plan.ok):
            u[i] = self.fallbacks[i].act(step.observations[i], step.forecast)
        if self.shadow is not None:
            for i in np.flatnonzero(plan.ok):
                distrusted[i] = not self.monitors[i].decide(self.monitors[i].reason(float(spread[i])))
            rc_plan = self.shadow.plan(only=distrusted)
            u[distrusted] = rc_plan.power_w[distrusted, 0]
            self.shadow.commit(rc_plan, active=distrusted)
        self._step = None
        self._steps += 1
        self._rc_plans = np.concatenate([self._rc_plans[:, 1:], self._rc_plans[:, -1:]], axis=1)
        return FleetDecision(u_w=self.spec.actuator.clip(u), fallback=~plan.ok | distrusted, model_fallback=distrusted)

    @property
    def model_fallback_steps(self) -> np.ndarray:
        """(B,) decisions each building's shadow RC MPC made since ``reset``."""
        return np.array([m.state.fallback_steps for m in self.monitors])
