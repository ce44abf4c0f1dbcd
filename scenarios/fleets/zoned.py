"""Fleets of buildings of several zones: each building's zoned controller, coordinated under a cap.

A fleet of a scenario on the multi-zone RC plant (``two_zone_house``, ``shoulder_office``) is
drawn around the scenario's building zone by zone and wall by wall
(:func:`pinn_mpc.multizone.draw_zoned_fleet`) and stepped in one batch by the plant. Each
building has its own controller, any the zoned building has (:func:`zoned_controller`): the
thermostat of each zone, the ``oracle`` (the QP MPC over zones x actuators on the building's true
RC and state), ``qp-mpc`` (the same with a Kalman observer), ``cem`` and ``random-shooting``
(sampling over the building's RC as a batch model). They plan on the building's own RC, as a
one-zone fleet's controllers do (the aggregator is assumed to know every building's), or all on
one given building (``rc``: e.g. the RC ``identify`` found on the scenario's data).

Under a cap on the fleet's aggregate electrical power the coordination is the one-zone
fleet's (:class:`controllers.coordination.Coordination`), on each building's total over its
actuators: :class:`ZoneFleetPlanner` is a :class:`controllers.fleet.FleetPlanner` over the
buildings' controllers. An MPC (``oracle``, ``qp-mpc``) plans under the coordination's price on
the building's electrical energy (:meth:`controllers.rc_mpc.multizone.MultiZoneMPC.plan`), so
the price moves its plan. A sampler (``cem``, ``random-shooting``) plans each price on a copy of
itself, with the price added to its forecast's, and the copy whose plan is applied carries on
(a plan costs one decision). The thermostat has no price: it decides once a step, and its fleet
is held on the cap by the coordination's curtailment, every building's actuators scaled down by
the one factor that puts the aggregate on the cap.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from controllers.base import Controller, ControlSpec, Forecast, Observation, PlanningController
from controllers.fleet import FleetDecision, FleetPlan
from controllers.rc_mpc.multizone import MultiZoneMPC, ZonePlan
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.multizone import MultiZoneParams, draw_zoned_fleet
from scenarios.choices import ZONE_CONTROLLERS
from scenarios.inputs.registry import Scenario
from scenarios.plants.multizone import MultiZoneSettings
from scenarios.running.engine import decide

__all__ = [
    "ZoneFleetPlanner",
    "draw_zoned_buildings",
    "is_zoned",
    "with_building",
    "zoned_controller",
    "zoned_planner_factory",
]


def is_zoned(scenario: Scenario) -> bool:
    """Whether ``scenario``'s plant is a building of several zones with a true RC (its
    fleets are drawn and controlled here)."""
    return isinstance(scenario.plant.settings, MultiZoneSettings)


def _settings(scenario: Scenario) -> MultiZoneSettings:
    settings = scenario.plant.settings
    if not isinstance(settings, MultiZoneSettings):
        raise InternalError(f"scenario {scenario.name!r} is not on the multi-zone RC plant")
    return settings


def draw_zoned_buildings(
    scenario: Scenario, n_buildings: int, *, spread: float, rng: np.random.Generator
) -> tuple[MultiZoneParams, ...]:
    """``n_buildings`` buildings around ``scenario``'s (:func:`pinn_mpc.multizone.draw_zoned_fleet`)."""
    return draw_zoned_fleet(_settings(scenario).building, n_buildings, spread=spread, rng=rng)


def with_building(scenario: Scenario, params: MultiZoneParams) -> Scenario:
    """``scenario`` with ``params`` as its building (its zones, in order); the nominal
    one-zone view is that building's zones merged, as the built-ins have it."""
    settings = _settings(scenario)
    if params.zone_specs != settings.building.zone_specs:
        raise ValueError(
            f"with_building: the building's zones ({', '.join(z.name for z in params.zone_specs)}) "
            f"are not scenario {scenario.name!r}'s ({', '.join(z.name for z in settings.building.zone_specs)})"
        )
    plant = dataclasses.replace(scenario.plant, settings=dataclasses.replace(settings, building=params))
    sim = dataclasses.replace(scenario.sim, params=params.lumped())
    return dataclasses.replace(scenario, plant=plant, sim=sim)


def zoned_controller(
    name: str,
    scenario: Scenario,
    params: MultiZoneParams,
    *,
    rc: MultiZoneParams | None = None,
    n_steps: int,
    planner_options: Mapping[str, Any] | None = None,
) -> Controller:
    """The controller ``name`` (one of :data:`scenarios.choices.ZONE_CONTROLLERS`) of the
    fleet's building ``params``: the oracle on its true building and state; ``qp-mpc``,
    ``cem`` and ``random-shooting`` on ``rc`` (None: its own building)."""
    from scenarios.running.factory import build_controller

    if name not in ZONE_CONTROLLERS:
        raise InputError(
            f"controller {name!r} plans one zone with one actuator; a fleet of scenario "
            f"{scenario.name!r} (several zones) runs {', '.join(ZONE_CONTROLLERS)}"
        )
    building = with_building(scenario, params)
    planned_on = None if name in ("thermostat", "oracle") else (params if rc is None else rc)
    return build_controller(
        name, building, zone_params=planned_on, n_steps=n_steps, planner_options=planner_options
    )


class ZoneFleetPlanner:
    """A :class:`controllers.fleet.FleetPlanner` over one zoned controller per building
    (module docstring), for :class:`controllers.coordination.Coordination`.

    A :class:`~controllers.rc_mpc.multizone.MultiZoneMPC` observes once a step and plans under
    each extra price asked; another planning controller (a sampler) decides on a copy of itself
    per extra price (:func:`scenarios.running.engine.decide`, the price added to its forecast's;
    a failure falls back), and the copy of the plan applied replaces it on :meth:`commit`; a
    controller without a plan (the thermostat) decides once a step, on :meth:`observe`, and
    plans that decision whatever the price. A plan's ``power_w`` is each building's total over
    its actuators, ``actuator_w`` each actuator's (B, H, A); :meth:`commit` applies each
    building's settled first row. Uncapped (one plan a step, no price), every building decides exactly as its
    controller's ``act`` would. :attr:`errors` holds one line per controller exception (its
    building and the planner's step), where the loop's fallback acted."""

    #: It plans on RC parameters, over no learned model (:class:`FleetPlanner`).
    rc_candidates = None

    def __init__(self, controllers: Sequence[Controller], spec: ControlSpec) -> None:
        if not controllers:
            raise InternalError("ZoneFleetPlanner needs at least one building's controller")
        self.controllers, self.spec = list(controllers), spec
        self.name = self.controllers[0].name
        self._mpc = np.array([isinstance(c, MultiZoneMPC) for c in self.controllers])
        self._copied = np.array(
            [isinstance(c, PlanningController) and not isinstance(c, MultiZoneMPC) for c in self.controllers]
        )
        self.reset()

    @property
    def n_buildings(self) -> int:
        return len(self.controllers)

    @property
    def horizon_steps(self) -> int:
        return self.spec.horizon_steps

    @property
    def knows_true_state(self) -> bool:
        """Whether the buildings' controllers plan on the plant's true state (the oracle's
        fleet: it then sees the truth, forecasts included)."""
        return all(c.knows_true_state for c in self.controllers)

    @property
    def n_fallbacks(self) -> np.ndarray:
        """(B,) fallback events of each building since ``reset``."""
        return self._fallbacks.copy()

    def reset(self, seed: int | None = None) -> None:
        for c in self.controllers:
            c.reset(seed)
        b, a = self.n_buildings, self.spec.n_actuators
        self._fallbacks = np.zeros(b, dtype=int)
        self._decided_w = np.zeros((b, a))  # (B, A) the once-a-step decisions
        self._decided_fallback = np.zeros(b, dtype=bool)
        self._status = ["not run"] * b
        self.errors: list[str] = []
        self._steps = 0
        self._seen: list[tuple[Observation, Forecast]] = []  # the samplers' step inputs
        self._copies: list[dict[int, tuple[Controller, bool, str | None]]] = []  # per plan: building -> copy
        self._iterations = np.zeros(b, dtype=int)
        self._observed = False

    def observe(self, observations: Sequence[Observation], forecast: Forecast) -> None:
        """Every building's observation, with its own copy of ``forecast``: the MPCs
        estimate, the thermostats decide, the samplers keep them for :meth:`plan`."""
        if len(observations) != self.n_buildings:
            raise InternalError(
                f"ZoneFleetPlanner.observe: {len(observations)} observations for {self.n_buildings} buildings"
            )
        self._seen, self._copies = [], []
        for i, (controller, obs) in enumerate(zip(self.controllers, observations, strict=True)):
            own = _copied(forecast)
            self._seen.append((obs, own))
            if isinstance(controller, MultiZoneMPC):
                controller.observe(obs, own)
                continue
            if self._copied[i]:
                continue
            u, _, fell_back, error = decide(controller, obs, own, self.spec)
            self._decided_w[i] = u
            self._decided_fallback[i] = fell_back
            if error is not None:
                self.errors.append(f"building {i}, step {self._steps}: {error}")
        self._observed = True
        self._steps += 1

    def plan(self, extra_price_eur_per_kwh: np.ndarray | None = None) -> FleetPlan:
        """Every building's plan under the forecast plus ``extra_price_eur_per_kwh`` (H,) on
        electrical energy (the MPCs'; the others' decisions held over the horizon)."""
        if not self._observed:
            raise InternalError("ZoneFleetPlanner.plan: call observe() first")
        b, h, a = self.n_buildings, self.horizon_steps, self.spec.n_actuators
        actuators = np.broadcast_to(self._decided_w[:, None, :], (b, h, a)).copy()  # (B, H, A)
        ok = np.ones(b, dtype=bool)
        iterations = 0
        copies: dict[int, tuple[Controller, bool, str | None]] = {}
        for i in np.flatnonzero(self._copied):
            obs, forecast = self._seen[i]
            priced = _copied(forecast)
            if extra_price_eur_per_kwh is not None:
                extra = np.asarray(extra_price_eur_per_kwh, dtype=float)[: len(priced.price)]
                priced.price[: len(extra)] += extra
            planner = copy.deepcopy(self.controllers[i])  # it may keep or change what it is given
            u, _, fell_back, error = decide(planner, copy.deepcopy(obs), priced, self.spec)
            copies[int(i)] = (planner, fell_back, error)
            plan_w = planner.last_plan if isinstance(planner, PlanningController) else None
            if not fell_back and plan_w is not None and np.shape(plan_w) == (h, a):
                actuators[i] = plan_w
                actuators[i, 0] = u
            else:  # no plan over the horizon: its decision held
                actuators[i] = u
        self._copies.append(copies)
        for i in np.flatnonzero(self._mpc):
            controller = self.controllers[i]
            assert isinstance(controller, MultiZoneMPC)
            zone_plan = controller.plan(extra_price_eur_per_kwh)
            self._status[i], self._iterations[i] = zone_plan.status, zone_plan.iterations
            iterations = max(iterations, zone_plan.iterations)
            if zone_plan.power_w is None:
                ok[i], actuators[i] = False, 0.0
            else:
                actuators[i] = zone_plan.power_w
        statuses = {s for s, m in zip(self._status, self._mpc, strict=True) if m} or {"decided"}
        return FleetPlan(
            power_w=actuators.sum(axis=2), ok=ok, status=", ".join(sorted(statuses)),
            iterations=iterations, actuator_w=actuators, plan_id=len(self._copies) - 1,
        )

    def commit(self, plan: FleetPlan) -> FleetDecision:
        """Apply ``plan`` (settled on the cap): each building's first row of ``actuator_w``; a
        building whose MPC did not plan falls back (counted)."""
        if not self._observed or plan.actuator_w is None:
            raise InternalError("ZoneFleetPlanner.commit: call observe() and plan() first")
        u = np.zeros((self.n_buildings, self.spec.n_actuators))
        fallback = self._decided_fallback.copy()
        if self._copied.any():  # the copies of the plan applied carry on
            if plan.plan_id is None or not 0 <= plan.plan_id < len(self._copies):
                raise InternalError(f"ZoneFleetPlanner.commit: plan_id {plan.plan_id} is not one of this step's plans")
            for i, (planner, fell_back, error) in self._copies[plan.plan_id].items():
                self.controllers[i] = planner
                fallback[i] = fell_back
                if error is not None:
                    self.errors.append(f"building {i}, step {self._steps - 1}: {error}")
        for i, controller in enumerate(self.controllers):
            if isinstance(controller, MultiZoneMPC):
                planned = plan.actuator_w[i] if plan.ok[i] else None
                step = ZonePlan(power_w=planned, status=self._status[i], iterations=int(self._iterations[i]))
                u[i] = controller.commit(step)
                fallback[i] = planned is None
            else:
                u[i] = plan.actuator_w[i, 0]
        self._fallbacks += fallback
        self._observed = False
        self._seen, self._copies = [], []
        # A building of one actuator takes (B,) demands, as the loop steps it.
        return FleetDecision(u_w=u[:, 0] if self.spec.n_actuators == 1 else u, fallback=fallback)


def _copied(forecast: Forecast) -> Forecast:
    """A copy of ``forecast`` (its arrays too) for one controller to keep or change."""
    return forecast._replace(**{n: np.array(v) for n, v in forecast._asdict().items() if v is not None})


def zoned_planner_factory(
    name: str,
    scenario: Scenario,
    *,
    rc: MultiZoneParams | None = None,
    n_steps: int,
    planner_options: Mapping[str, Any] | None = None,
) -> Callable[[Sequence[MultiZoneParams], ControlSpec], ZoneFleetPlanner]:
    """The factory ``(fleet, spec) -> ZoneFleetPlanner`` of :func:`zoned_controller` ``name``
    on every building of the fleet."""

    def make(fleet: Sequence[MultiZoneParams], spec: ControlSpec) -> ZoneFleetPlanner:
        controllers = [
            zoned_controller(name, scenario, p, rc=rc, n_steps=n_steps, planner_options=planner_options)
            for p in fleet
        ]
        return ZoneFleetPlanner(controllers, spec)

    return make
