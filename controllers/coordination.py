"""Coordination of a fleet under a power cap: a price signal found by dual ascent.

An aggregator must keep the fleet's aggregate electrical power at or under a cap C_j [W] in
some intervals (a demand-response window). The cap couples the buildings; its Lagrangian
separates them again: with a price lambda_j >= 0 [EUR/kWh] on each capped interval's energy,
every building solves its own problem under ``price + lambda`` (one batched plan of the fleet,
:meth:`controllers.fleet.FleetPlanner.plan`), and the price rises where the planned aggregate
exceeds the cap (dual ascent, a projected subgradient step)::

    lambda_j <- clip(lambda_j + step x (P_j - C_j) / C_j, 0, max_price)      (capped j only)

The prices are warm-started: the last step's, shifted by one interval, so the signal converges
over the steps of a receding horizon. Raising a price never raises the aggregate power the
buildings plan in the priced intervals (each building's problem is convex and the price enters
linearly; tests check it).

Each control step's plans are a few points of every capped interval's response P_j(lambda_j).
Once a step has planned the interval both over and under its cap, its next price is the secant
between the closest such pair (kept inside the bracket), not a subgradient step: the plans of a
near-linear program respond in jumps, and a fixed step overshoots (the fleet then stays far
under the cap where comfort needs the power). ``DualAscent(secant=False)`` keeps the plain
subgradient.

The price only steers the plans. The interval about to start is settled from the step's plans
(primal recovery): with a plan over the cap and one under it, every building's first action is
the same convex combination of its two actions that puts the aggregate exactly on the cap
(``interpolate``; each action is then one its own constraints allow, and the buildings that
respond to the price get the headroom, as at the optimum). When all plans are under the cap at
a positive price, one more plan without the price on that interval closes the bracket. When
all are over, every building's first action is scaled down by the same factor (``curtailed``).
A fleet of buildings of several actuators (zones, a heater and a cooler) is coordinated on each
building's total, the sum over its actuators: the price is on the building's electrical energy,
the aggregate sums the totals, and the settled first actions are each actuator's, combined or
scaled by the building's factor (:attr:`controllers.fleet.FleetPlan.actuator_w`), so every
actuator stays within its own bounds.

The plant may still deliver more than the cap (a backup thermostat forcing heat in a room below
its limit): the closed loop counts those intervals, it does not hide them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from controllers.fleet import FleetDecision, FleetPlan, FleetPlanner
from pinn_mpc.errors import InternalError

__all__ = ["Coordination", "CoordinationStep", "DualAscent", "planned_aggregate_w"]


@dataclass(frozen=True, kw_only=True)
class DualAscent:
    """Settings of the price signal (module docstring): ``iterations`` batched plans per control
    step (the last price's plan is not necessarily the one applied), ``step_eur_per_kwh`` the
    price change per unit of relative excess of the cap, ``max_price_eur_per_kwh`` its
    ceiling; ``secant`` the secant price within a step's bracket, ``interpolate`` the first
    actions settled on the cap between a plan over it and one under it (both False: the plain
    dual ascent, the last plan scaled down when over)."""

    iterations: int = 4
    step_eur_per_kwh: float = 0.2
    max_price_eur_per_kwh: float = 20.0
    secant: bool = True
    interpolate: bool = True

    def __post_init__(self) -> None:
        if not (isinstance(self.iterations, int) and 1 <= self.iterations <= 100):
            raise ValueError(f"DualAscent.iterations must be an integer in 1..100, got {self.iterations!r}")
        for name in ("step_eur_per_kwh", "max_price_eur_per_kwh"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"DualAscent.{name} must be a positive number, got {value!r}")


class CoordinationStep(NamedTuple):
    """One control step: the decision applied, the prices (H,) [EUR/kWh] it was planned under,
    the planned aggregate (H,) [W] of the last plan, the plans made, whether the first actions
    were scaled down to the cap."""

    decision: FleetDecision
    price_eur_per_kwh: np.ndarray
    planned_aggregate_w: np.ndarray
    plans: int
    curtailed: bool


def planned_aggregate_w(plan: FleetPlan) -> np.ndarray:
    """(H,) the fleet's planned electrical power [W], summed over the buildings that planned."""
    return plan.power_w[plan.ok].sum(axis=0)


class Coordination:
    """Dual ascent over a fleet planner under a cap ``cap_w`` (N,) [W] per row of the run's
    exogenous series (``inf`` where there is no cap)."""

    def __init__(self, cap_w: np.ndarray, settings: DualAscent = DualAscent()) -> None:
        cap = np.asarray(cap_w, dtype=float)
        if cap.ndim != 1 or np.any(np.isnan(cap)) or np.any(cap <= 0):
            raise InternalError("Coordination: the cap must be one positive value (or inf) per interval")
        self.cap_w, self.settings = cap, settings
        self.reset()

    def reset(self) -> None:
        self._price: np.ndarray | None = None  # (H,) the last step's prices

    def _update(
        self, price: np.ndarray, aggregate: np.ndarray, cap: np.ndarray, tried: list[_Point] | None = None
    ) -> np.ndarray:
        """The next prices: a subgradient step, or within a bracket of this step's plans
        (``tried``) the secant (module docstring)."""
        capped = np.isfinite(cap)
        excess = np.zeros_like(price)
        excess[capped] = (aggregate[capped] - cap[capped]) / cap[capped]
        s = self.settings
        updated = price + s.step_eur_per_kwh * excess
        if s.secant and tried:
            prices = np.array([t.price for t in tried])  # (T, H)
            totals = np.array([t.aggregate for t in tried])
            over = totals > cap  # (T, H); False where uncapped
            under = capped & ~over
            for j in np.flatnonzero(capped & over.any(axis=0) & under.any(axis=0)):
                # The highest price still over the cap and the lowest one under it.
                lo = int(np.flatnonzero(over[:, j])[np.argmax(prices[over[:, j], j])])
                hi = int(np.flatnonzero(under[:, j])[np.argmin(prices[under[:, j], j])])
                p_lo, p_hi = prices[lo, j], prices[hi, j]
                if p_hi <= p_lo:  # not monotone (other prices moved, or sampling noise)
                    continue
                share = (totals[lo, j] - cap[j]) / max(totals[lo, j] - totals[hi, j], 1e-9)
                updated[j] = p_lo + float(np.clip(share, 0.1, 0.9)) * (p_hi - p_lo)
        updated = np.clip(updated, 0.0, s.max_price_eur_per_kwh)
        return np.where(capped, updated, 0.0)

    def step(self, planner: FleetPlanner, row: int) -> CoordinationStep:
        """Plan the fleet (already observed for this step) at row ``row`` of the series: dual
        ascent on the prices, then the first actions settled on the cap, then commit."""
        h = planner.horizon_steps
        cap = np.full(h, np.inf)
        window = self.cap_w[row : row + h]
        cap[: len(window)] = window
        price = np.zeros(h)
        if self._price is not None:  # the last step's prices, shifted one interval
            price[:-1] = self._price[1:]
            price[-1] = self._price[-1]
        price = np.where(np.isfinite(cap), price, 0.0)
        uncapped = not np.any(np.isfinite(cap))
        iterations = 1 if uncapped else self.settings.iterations
        tried: list[_Point] = []
        for i in range(iterations):
            if i:
                price = self._update(price, tried[-1].aggregate, cap, tried)
            plan = planner.plan(price)
            tried.append(_Point(price, plan, planned_aggregate_w(plan)))
        self._price = self._update(price, tried[-1].aggregate, cap, tried)
        if math.isfinite(cap[0]) and self.settings.interpolate:
            first = np.array([t.aggregate[0] for t in tried])
            if np.all(first <= cap[0]) and price[0] > 0 and first.max() < cap[0] * 0.98:
                # Under the cap at a price: the plan without it on this interval closes the bracket.
                free = price.copy()
                free[0] = 0.0
                plan = planner.plan(free)
                tried.append(_Point(free, plan, planned_aggregate_w(plan)))
        applied, plan, curtailed = self._settle(tried, cap[0])
        decision = planner.commit(plan)
        if math.isfinite(cap[0]) and decision.u_w.sum() > cap[0] * (1 + 1e-9):
            # Fallbacks act on their own rule; they too are held to the cap, by the same factor
            # (every actuator of every building: u_w (B,) or (B, A)).
            decision = decision._replace(u_w=decision.u_w * (cap[0] / decision.u_w.sum()))
            curtailed = True
        return CoordinationStep(decision, applied, tried[-1].aggregate, len(tried), curtailed)

    def _settle(self, tried: list[_Point], cap0: float) -> tuple[np.ndarray, FleetPlan, bool]:
        """The plan applied (its price, the plan, whether its first actions were scaled down)
        from the step's plans ``tried`` (module docstring)."""
        last = tried[-1]
        if not math.isfinite(cap0):
            return last.price, last.plan, False
        first = np.array([t.aggregate[0] for t in tried])
        if self.settings.interpolate:
            under = np.flatnonzero(first <= cap0)
            over = np.flatnonzero(first > cap0)
            if len(under) and len(over):
                a = tried[int(under[np.argmax(first[under])])]  # the closest under the cap
                b = tried[int(over[np.argmin(first[over])])]  # the closest over it
                share = (cap0 - a.aggregate[0]) / (b.aggregate[0] - a.aggregate[0])
                ok = a.plan.ok & b.plan.ok
                power = np.where(ok[:, None], a.plan.power_w, 0.0)
                power[:, 0] += share * np.where(ok, b.plan.power_w[:, 0] - a.plan.power_w[:, 0], 0.0)
                actuators = None
                if a.plan.actuator_w is not None and b.plan.actuator_w is not None:  # (B, H, A)
                    actuators = np.where(ok[:, None, None], a.plan.actuator_w, 0.0)
                    step = b.plan.actuator_w[:, 0] - a.plan.actuator_w[:, 0]
                    actuators[:, 0] += share * np.where(ok[:, None], step, 0.0)
                return a.price, a.plan._replace(power_w=power, ok=ok, actuator_w=actuators), False
            if len(under):
                best = tried[int(under[np.argmax(first[under])])]
                return best.price, best.plan, False
            last = tried[int(np.argmin(first))]
        plan = last.plan
        total = float(plan.power_w[plan.ok, 0].sum())
        if total <= cap0:
            return last.price, plan, False
        power = plan.power_w.copy()
        power[:, 0] *= cap0 / total
        actuators = None if plan.actuator_w is None else plan.actuator_w.copy()
        if actuators is not None:
            actuators[:, 0] *= cap0 / total
        return last.price, plan._replace(power_w=power, actuator_w=actuators), True


class _Point(NamedTuple):
    """One plan of a control step: the prices (H,) it was made under, the plan, its aggregate
    (H,) [W]."""

    price: np.ndarray
    plan: FleetPlan
    aggregate: np.ndarray
