"""Coordination of a fleet under a power cap: a price signal found by dual ascent.

An aggregator must keep the fleet's aggregate electrical power at or under a cap C_j [W] in
some intervals (a demand-response window). The cap couples the buildings; its Lagrangian
separates them again: with a price lambda_j >= 0 [EUR/kWh] on each capped interval's energy,
every building solves its own problem under ``price + lambda`` (one batched plan of the fleet,
:meth:`controllers.fleet.FleetPlanner.plan`), and the price rises where the planned aggregate
exceeds the cap (dual ascent, a projected subgradient step)::

    lambda_j <- clip(lambda_j + step x (P_j - C_j) / C_j, 0, max_price)      (capped j only)

A few iterations a control step suffice because the prices are warm-started: the last step's,
shifted by one interval, so the signal converges over the steps of a receding horizon. Raising
a price never raises the aggregate power the buildings plan in the priced intervals (each
building's problem is convex and the price enters linearly; tests check it).

The price only steers the plans. What keeps the cap in the interval about to start is the last
line: when the fleet's planned first actions still sum to more than the cap, every building's
first action is scaled down by the same factor (``curtailed``). The plant may still deliver
more than the cap (a backup thermostat forcing heat in a room below its limit): the closed loop
counts those intervals, it does not hide them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from controllers.fleet import FleetDecision, FleetPlan, FleetPlanner
from pinn_mpc.errors import InputError

__all__ = ["Coordination", "CoordinationStep", "DualAscent", "planned_aggregate_w"]


@dataclass(frozen=True, kw_only=True)
class DualAscent:
    """Settings of the price signal (module docstring): ``iterations`` batched plans per control
    step (the last one is applied), ``step_eur_per_kwh`` the price change per unit of relative
    excess of the cap, ``max_price_eur_per_kwh`` its ceiling."""

    iterations: int = 4
    step_eur_per_kwh: float = 0.2
    max_price_eur_per_kwh: float = 20.0

    def __post_init__(self) -> None:
        if not (isinstance(self.iterations, int) and 1 <= self.iterations <= 100):
            raise InputError(f"DualAscent.iterations must be an integer in 1..100, got {self.iterations!r}")
        for name in ("step_eur_per_kwh", "max_price_eur_per_kwh"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"DualAscent.{name} must be a positive number, got {value!r}")


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
            raise InputError("Coordination: the cap must be one positive value (or inf) per interval")
        self.cap_w, self.settings = cap, settings
        self.reset()

    def reset(self) -> None:
        self._price: np.ndarray | None = None  # (H,) the last step's prices

    def _update(self, price: np.ndarray, aggregate: np.ndarray, cap: np.ndarray) -> np.ndarray:
        capped = np.isfinite(cap)
        excess = np.zeros_like(price)
        excess[capped] = (aggregate[capped] - cap[capped]) / cap[capped]
        s = self.settings
        updated = np.clip(price + s.step_eur_per_kwh * excess, 0.0, s.max_price_eur_per_kwh)
        return np.where(capped, updated, 0.0)

    def step(self, planner: FleetPlanner, row: int) -> CoordinationStep:
        """Plan the fleet (already observed for this step) at row ``row`` of the series: dual
        ascent on the prices, then the cap on the first actions, then commit."""
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
        plan = planner.plan(price)
        aggregate = planned_aggregate_w(plan)
        for _ in range(iterations - 1):
            price = self._update(price, aggregate, cap)
            plan = planner.plan(price)
            aggregate = planned_aggregate_w(plan)
        applied = price
        self._price = self._update(price, aggregate, cap)
        curtailed = False
        first = float(plan.power_w[plan.ok, 0].sum())
        if math.isfinite(cap[0]) and first > cap[0]:
            power = plan.power_w.copy()
            power[:, 0] *= cap[0] / first
            plan = plan._replace(power_w=power)
            curtailed = True
        decision = planner.commit(plan)
        if math.isfinite(cap[0]) and decision.u_w.sum() > cap[0] * (1 + 1e-9):
            # Fallbacks act on their own rule; they too are held to the cap, by the same factor.
            decision = decision._replace(u_w=decision.u_w * (cap[0] / decision.u_w.sum()))
            curtailed = True
        return CoordinationStep(decision, applied, aggregate, iterations, curtailed)
