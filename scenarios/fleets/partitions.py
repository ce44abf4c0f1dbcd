"""A fleet planner split into partitions across Ray workers (or nodes).

:class:`PartitionedPlanner` is a :class:`controllers.fleet.FleetPlanner` whose buildings are
cut into P contiguous partitions, each held by a Ray actor with its own fleet planner (batched
over its buildings, with their estimators, warm starts and fallbacks). The closed loop and the
coordination (:mod:`controllers.coordination`) stay in the driver: each step the driver sends
every partition its buildings' observations and the forecast, then per coordination iteration
only the price (H floats) and gets back that partition's plans; the driver sums the aggregate,
updates the price and finally sends each partition its part of the plan to commit. Planning is
deterministic per building for ``qp-mpc``, so a partitioned fleet plans exactly as an
unpartitioned one (tests); a sampling planner seeds its buildings by their index within the
partition.

Run it inside :func:`scenarios.running.ray_engine.ray_engine` (a local instance or ``--address``); the
factory and the buildings' models travel to the workers by pickling.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from controllers.base import ControlSpec, Forecast, Observation
from controllers.fleet import FleetDecision, FleetPlan, FleetPlanner
from pinn_mpc.errors import InternalError
from pinn_mpc.physics import RCParams

__all__ = ["PartFactory", "PartitionedPlanner", "partitioned"]

#: The fleet planner of some buildings under ``spec``.
Factory = Callable[[Sequence[RCParams], ControlSpec], FleetPlanner]
#: The factory of the buildings in a slice of the fleet (e.g. with those buildings' models).
PartFactory = Callable[[slice], Factory]


class _Partition:
    """A Ray actor's state: one partition's fleet planner."""

    def __init__(self, factory: Factory, fleet: Sequence[RCParams], spec: ControlSpec) -> None:
        import torch

        torch.set_num_threads(1)
        self.planner = factory(fleet, spec)

    def reset(self, seed: int | None) -> None:
        self.planner.reset(seed)

    def observe(self, observations: Sequence[Observation], forecast: Forecast) -> None:
        self.planner.observe(observations, forecast)

    def plan(self, extra: np.ndarray | None) -> FleetPlan:
        return self.planner.plan(extra)

    def commit(self, plan: FleetPlan) -> FleetDecision:
        return self.planner.commit(plan)

    def n_fallbacks(self) -> np.ndarray:
        return self.planner.n_fallbacks


class PartitionedPlanner:
    """``factory_of``'s planners over ``fleet`` in ``partitions`` Ray actors (module
    docstring): the actor of buildings ``s`` (a slice) plans with ``factory_of(s)``."""

    def __init__(
        self, factory_of: PartFactory, fleet: Sequence[RCParams], spec: ControlSpec, *, partitions: int
    ) -> None:
        import ray

        if not 1 <= partitions <= len(fleet):
            raise ValueError(f"partitions must lie in 1..{len(fleet)} (the buildings), got {partitions}")
        if not ray.is_initialized():
            raise InternalError("PartitionedPlanner runs on Ray: start it first (scenarios.running.ray_engine.ray_engine)")
        self._ray = ray
        cuts = np.array_split(np.arange(len(fleet)), partitions)
        self.slices = [slice(int(c[0]), int(c[-1]) + 1) for c in cuts]
        actor = ray.remote(num_cpus=1)(_Partition)
        self.actors = [actor.remote(factory_of(s), list(fleet[s]), spec) for s in self.slices]
        self._n, self._h = len(fleet), spec.horizon_steps
        self.name = "partitioned"

    @property
    def n_buildings(self) -> int:
        return self._n

    @property
    def rc_candidates(self) -> bool | None:
        """None: the planners run in the partitions' actors, whose settings a run's record
        does not report."""
        return None

    @property
    def horizon_steps(self) -> int:
        return self._h

    def _all(self, method: str, *per_partition: Sequence[Any]) -> list[Any]:
        refs = [
            getattr(actor, method).remote(*(args[i] for args in per_partition))
            for i, actor in enumerate(self.actors)
        ]
        return list(self._ray.get(refs))

    def reset(self, seed: int | None = None) -> None:
        self._all("reset", [seed] * len(self.actors))

    def observe(self, observations: Sequence[Observation], forecast: Forecast) -> None:
        self._all("observe", [list(observations[s]) for s in self.slices], [forecast] * len(self.actors))

    def plan(self, extra_price_eur_per_kwh: np.ndarray | None = None) -> FleetPlan:
        parts: list[FleetPlan] = self._all("plan", [extra_price_eur_per_kwh] * len(self.actors))
        statuses = {p.status for p in parts}
        return FleetPlan(
            power_w=np.concatenate([p.power_w for p in parts]),
            ok=np.concatenate([p.ok for p in parts]),
            status=statuses.pop() if len(statuses) == 1 else ", ".join(sorted(statuses)),
            iterations=max(p.iterations for p in parts),
        )

    def commit(self, plan: FleetPlan) -> FleetDecision:
        pieces = [
            FleetPlan(plan.power_w[s], plan.ok[s], plan.status, plan.iterations) for s in self.slices
        ]
        parts: list[FleetDecision] = self._all("commit", pieces)
        model = [p.model_fallback for p in parts if p.model_fallback is not None]
        return FleetDecision(
            u_w=np.concatenate([p.u_w for p in parts]),
            fallback=np.concatenate([p.fallback for p in parts]),
            model_fallback=np.concatenate(model) if len(model) == len(parts) else None,
        )

    @property
    def n_fallbacks(self) -> np.ndarray:
        return np.concatenate(self._all("n_fallbacks"))


def partitioned(factory_of: PartFactory, partitions: int, name: str) -> Factory:
    """A factory of :class:`PartitionedPlanner` over ``factory_of`` (``name``: the planner's)."""

    def make(fleet: Sequence[RCParams], spec: ControlSpec) -> FleetPlanner:
        planner = PartitionedPlanner(factory_of, fleet, spec, partitions=partitions)
        planner.name = name
        return planner

    return make
