"""A fleet closed loop: many buildings around a scenario's building, each with its own controller.

An aggregator controls many buildings under the same weather, prices and forecasts. The fleet is
drawn around the scenario's building (:func:`pinn_mpc.simulator.draw_fleet`, log-normal
``spread`` on R, C and solar aperture); the plant is the batched simulator, which advances every
building in one call per control interval (:meth:`scenarios.running.engine.ClosedLoop.advance_fleet`).
Everything else is the single-building run's (:mod:`scenarios.running.closed_loop`): the same exogenous
inputs (test part of the weather by default), thermostat warm-up, forecasts and forecast errors,
estimator and fallback of each controller, and KPIs per building (:mod:`scenarios.running.kpis`).

Each building has its own controller instance, by default the named controller built on that
building's own parameters: ``qp-mpc`` and ``casadi-mpc`` get its RC (the aggregator is assumed to
know every building's RC, e.g. from ``pinn-mpc identify`` on its data), ``cem`` and
``random-shooting`` plan over its exact RC as a batch model (:class:`RCBatchModel`), ``oracle``
and ``clairvoyant`` use its true parameters and state. A callable ``controller`` builds them
otherwise (e.g. on identified parameters with errors).

A scenario on the multi-zone RC plant (``two_zone_house``, ``shoulder_office``) draws its fleet
zone by zone and wall by wall and gives each building its zoned controller
(:mod:`scenarios.fleets.zoned`).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import pandas as pd

from controllers.base import Controller
from controllers.thermostat import Thermostat
from pinn_mpc.errors import InputError
from pinn_mpc.multizone import MultiZoneParams
from pinn_mpc.physics import RCParams
from pinn_mpc.simulator import draw_fleet
from scenarios.choices import CONTROLLER_NAMES, MODEL_CONTROLLERS, RC_CONTROLLERS
from scenarios.fleets.zoned import draw_zoned_buildings, is_zoned, zoned_controller
from scenarios.inputs.registry import Scenario, check_seed, is_scenario_file
from scenarios.records import BuildingKpis, CapAccount, FleetInfo, FleetJson, FleetTotals
from scenarios.running.closed_loop import (
    RunInputs,
    build_loop,
    counted_kpis,
    free_records,
    prepare_run,
    progress_steps,
)
from scenarios.running.engine import ClosedLoop

__all__ = [
    "FLEET_STREAM",
    "FLEET_TOTAL_KEYS",
    "FleetResult",
    "district_kpis",
    "draw_buildings",
    "fleet_controller",
    "fleet_info",
    "fleet_json",
    "fleet_result",
    "fleet_step_time",
    "fleet_totals",
    "run_fleet_closed_loop",
]

#: Keys of :attr:`FleetResult.totals`.
FLEET_TOTAL_KEYS = (
    "energy_kwh",
    "cost_eur",
    "discomfort_kh",
    "discomfort_too_cold_kh",
    "discomfort_too_warm_kh",
    "discomfort_unavoidable_kh",
    "discomfort_avoidable_kh",
    "objective",
    "peak_kw",
    "backup_overrides",
    "fallbacks",
    "buildings_with_fallbacks",
)

#: A controller for building ``index`` with parameters ``params`` (an RCParams, or a
#: MultiZoneParams in a fleet of buildings of several zones).
ControllerFactory = Callable[[int, Any], Controller]


@dataclass(frozen=True, kw_only=True)
class FleetResult:
    """A fleet run.

    - ``kpis``: one KPI dict per building (:func:`scenarios.running.kpis.compute_kpis`, plus
      ``building``, its index).
    - ``totals``: the fleet's :data:`FLEET_TOTAL_KEYS`: energy, cost, discomfort (and its
      parts), objective, overrides and fallbacks summed over the buildings; ``peak_kw`` is the peak of the
      AGGREGATE power (the interval-mean delivered power summed over the buildings), not the
      sum of the buildings' peaks.
    - ``aggregate_u_phys_w`` (K,): that aggregate power per counted interval [W].
    - ``step_time``: wall time per counted control step [ms], ``{controllers, plant,
      total}_ms_{median, p95}``: ``controllers`` is every building's observe, forecast and
      decide, ``plant`` the one batched simulator step, ``total`` both.
    - ``params``: each building's parameters; ``errors``: one line per controller exception
      (building, step), where the loop's fallback acted; ``info``: scenario, controller, days,
      seed, spread, n_buildings, weather_part.
    - ``times``: the start of each counted interval (ISO 8601), ``district``: the district
      KPIs of the aggregate (:func:`district_kpis`); ``cap``: the cap's
      account of a capped run (:func:`scenarios.fleets.aggregator.cap_account`), else None;
      ``coordination_price_eur_per_kwh`` (K,): the coordination price of each counted
      interval when it was decided (zeros without a cap; empty for a per-building run).
    """

    kpis: tuple[BuildingKpis, ...]
    totals: FleetTotals
    aggregate_u_phys_w: np.ndarray
    step_time: dict[str, float]
    params: tuple[RCParams, ...] | tuple[MultiZoneParams, ...]
    errors: tuple[str, ...]
    info: FleetInfo
    times: tuple[str, ...] = ()
    district: dict[str, float] = field(default_factory=dict)
    cap: CapAccount | None = None
    coordination_price_eur_per_kwh: np.ndarray = field(default_factory=lambda: np.zeros(0))


def draw_buildings(
    scenario: Scenario, n_buildings: int, *, spread: float, seed: int
) -> tuple[RCParams, ...] | tuple[MultiZoneParams, ...]:
    """The fleet of a run of ``seed``: ``n_buildings`` buildings around ``scenario``'s with the
    log-normal ``spread`` (:func:`pinn_mpc.simulator.draw_fleet`; a building of several zones:
    :func:`pinn_mpc.multizone.draw_zoned_fleet`), from a generator of its own stream."""
    rng = np.random.default_rng([seed, FLEET_STREAM])
    if is_zoned(scenario):
        return draw_zoned_buildings(scenario, n_buildings, spread=spread, rng=rng)
    return draw_fleet(scenario.sim.params, n_buildings, spread=spread, rng=rng)


def fleet_controller(
    name: str, scenario: Scenario, *, n_steps: int, planner_options: Mapping[str, Any] | None = None,
    rc: MultiZoneParams | None = None,
) -> ControllerFactory:
    """The factory of :func:`run_fleet_closed_loop` for controller ``name``: each building's
    controller on that building's own parameters (see the module docstring); in a fleet of
    buildings of several zones, ``rc`` (None: each its own) is the building the RC planners
    plan on (:func:`scenarios.fleets.zoned.zoned_controller`)."""
    from scenarios.running.factory import build_controller

    if name not in CONTROLLER_NAMES:
        raise InputError(f"unknown controller {name!r}; choose one of {', '.join(CONTROLLER_NAMES)}")
    if is_zoned(scenario):
        return lambda index, params: zoned_controller(
            name, scenario, params, rc=rc, n_steps=n_steps, planner_options=planner_options
        )
    if rc is not None:
        raise InputError(
            f"a multi-zone RC plans a fleet of buildings of several zones; scenario {scenario.name!r} "
            "has one zone (its fleet's controllers plan on each building's own RC)"
        )

    def make(index: int, params: RCParams) -> Controller:
        building = dataclasses.replace(scenario, sim=dataclasses.replace(scenario.sim, params=params))
        model = None
        if name in MODEL_CONTROLLERS:
            from pinn_mpc.models.rc import RCBatchModel

            sim = building.sim
            (actuator,) = sim.actuators
            model = RCBatchModel(
                params, dt_s=sim.dt_s, actuator=actuator, backup_low_c=sim.backup_low_c,
                backup_high_c=sim.backup_high_c,
            )
        return build_controller(
            name,
            building,
            model=model,
            rc_params=params if name in RC_CONTROLLERS else None,
            n_steps=n_steps,
            planner_options=planner_options,
        )

    return make


def run_fleet_closed_loop(
    scenario: Scenario,
    controller: str | ControllerFactory,
    *,
    n_buildings: int,
    days: int,
    seed: int,
    spread: float = 0.2,
    warmup_steps: int | None = None,
    weather_part: str = "test",
    planner_options: Mapping[str, Any] | None = None,
    rc: MultiZoneParams | None = None,
    progress: bool = False,
) -> FleetResult:
    """Run ``n_buildings`` buildings around ``scenario``'s building for ``days`` counted days.

    The fleet is :func:`draw_buildings` (``draw_fleet(scenario.sim.params, n_buildings,
    spread=spread)`` with a generator seeded by ``seed``; ``spread=0``: copies of the
    scenario's building; a building of several zones drawn zone by zone and wall by wall, its
    RC planners planning on ``rc`` if given, else on each building's own).
    ``controller`` is a controller name (:func:`fleet_controller`: each building's own
    controller on its own parameters; ``planner_options`` as for ``cem``) or a factory
    ``(index, params) -> Controller``. ``seed``, ``warmup_steps`` (default one day of the
    thermostat) and ``weather_part`` (default the test part) mean what they mean for
    :func:`scenarios.running.closed_loop.run_closed_loop`, which a fleet of one building reproduces.
    A controller that fails falls back (its own fallback, or the loop's on an exception) and
    is counted in that building's ``fallbacks``; the run goes on.
    """
    check_seed(seed)
    fleet = draw_buildings(scenario, n_buildings, spread=spread, seed=seed)
    run = prepare_run(
        scenario, days=days, seed=seed, warmup_steps=warmup_steps, weather_part=weather_part
    )
    n_counted = run.total - run.warmup
    factory = (
        fleet_controller(
            controller, scenario, n_steps=n_counted, planner_options=planner_options, rc=rc
        )
        if isinstance(controller, str)
        else controller
    )
    name = controller if isinstance(controller, str) else "controller"
    controllers = [
        factory(i, fleet[i])
        for i in progress_steps(len(fleet), f"building {name}s", progress, unit="building")
    ]
    spec = scenario.control_spec()
    warmup_controllers = [Thermostat(spec) for _ in fleet]
    for c in (*warmup_controllers, *controllers):
        c.reset(seed)
    loop = build_loop(scenario, run, seed=seed, fleet=fleet)
    label = f"{controllers[0].name} x {len(fleet)}"
    errors: list[str] = []
    times_s = np.zeros((n_counted, 2))  # controllers, plant
    for k in progress_steps(run.total, label, progress):
        step = loop.advance_fleet(warmup_controllers if k < run.warmup else controllers)
        errors.extend(f"building {b}, step {k}: {e}" for b, e in step.errors)
        if k >= run.warmup:
            times_s[k - run.warmup] = step.controllers_s, step.plant_s
    return fleet_result(
        scenario, run, loop, times_s, seed=seed, params=fleet, errors=tuple(errors),
        info=fleet_info(
            scenario,
            controller if isinstance(controller, str) else controllers[0].name,
            n_buildings=len(fleet), days=days, seed=seed, spread=spread, weather_part=weather_part,
        ),
    )


def fleet_info(
    scenario: Scenario, controller: str, *, n_buildings: int, days: int, seed: int,
    spread: float, weather_part: str,
) -> FleetInfo:
    """:attr:`FleetResult.info` of a run."""
    return {
        "scenario": scenario.name,
        "controller": controller,
        "n_buildings": n_buildings,
        "days": days,
        "seed": seed,
        "spread": spread,
        "weather_part": weather_part,
    }


def fleet_result(
    scenario: Scenario,
    run: RunInputs,
    loop: ClosedLoop,
    times_s: np.ndarray,
    *,
    seed: int,
    params: tuple[RCParams, ...] | tuple[MultiZoneParams, ...],
    errors: tuple[str, ...],
    info: FleetInfo,
    cap: CapAccount | None = None,
    prices: np.ndarray | None = None,
    extra_kpis: dict[str, np.ndarray] | None = None,
) -> FleetResult:
    """The :class:`FleetResult` of a fleet run on ``loop`` (every building's counted KPIs, the
    aggregate and its district KPIs) with step times ``times_s`` (K, 2) [s]; ``extra_kpis``
    adds one value (B,) per building to its KPIs. The fleet runs once more, free-running
    after the same warm-up with ``seed`` (:func:`scenarios.running.closed_loop.free_records`),
    for each building's unavoidable discomfort."""
    n = loop.n_buildings
    extra = extra_kpis or {}
    free = free_records(scenario, run, seed=seed, fleet=params)
    kpis = cast("tuple[BuildingKpis, ...]", tuple(
        {
            **counted_kpis(scenario, run, loop.record(b), free[b]),
            "building": b,
            **{name: int(values[b]) for name, values in extra.items()},
        }
        for b in range(n)
    ))
    aggregate = loop.aggregate_u_phys_w()[run.counted]
    times = pd.DatetimeIndex(run.exo["time"])[run.counted]
    return FleetResult(
        kpis=kpis,
        totals=fleet_totals(kpis, aggregate),
        aggregate_u_phys_w=aggregate,
        step_time=fleet_step_time(times_s),
        params=params,
        errors=errors,
        info=info,
        times=tuple(times.strftime("%Y-%m-%dT%H:%M:%S")),
        district=district_kpis(aggregate, dt_s=scenario.sim.dt_s),
        cap=cap,
        coordination_price_eur_per_kwh=np.zeros(0) if prices is None else prices,
    )


#: Stream of the fleet draw's generator, apart from the scenario's and the loop's.
FLEET_STREAM = 7


def fleet_totals(kpis: tuple[BuildingKpis, ...], aggregate_w: np.ndarray) -> FleetTotals:
    """:data:`FLEET_TOTAL_KEYS` of a fleet's per-building KPIs and aggregate power (K,) [W]."""
    rows: Sequence[Mapping[str, Any]] = kpis  # summed by the keys' names
    summed = {
        key: None if any(k[key] is None for k in rows) else sum(k[key] for k in rows)
        for key in FLEET_TOTAL_KEYS[: FLEET_TOTAL_KEYS.index("peak_kw")]
    }
    counts = {key: int(sum(k[key] for k in kpis)) for key in ("backup_overrides", "fallbacks")}
    return cast(FleetTotals, {
        **summed,
        "peak_kw": float(np.max(aggregate_w) / 1000.0),
        **counts,
        "buildings_with_fallbacks": sum(1 for k in kpis if k["fallbacks"] > 0),
    })


def fleet_step_time(times_s: np.ndarray) -> dict[str, float]:
    """Median and p95 [ms] of (K, 2) step times [s] (controllers, plant) and their sum."""
    columns = {"controllers": times_s[:, 0], "plant": times_s[:, 1], "total": times_s.sum(axis=1)}
    out = {}
    for name, values in columns.items():
        out[f"{name}_ms_median"] = float(np.median(values) * 1000.0)
        out[f"{name}_ms_p95"] = float(np.percentile(values, 95) * 1000.0)
    return out


def district_kpis(aggregate_w: np.ndarray, *, dt_s: float) -> dict[str, float]:
    """District KPIs of the aggregate electrical power (K,) [W] as CityLearn defines them, not
    normalised by a baseline: ``peak_kw`` (all-time peak), ``average_daily_peak_kw``,
    ``ramping_kw`` (sum of |P_t - P_t-1|), ``load_factor`` (mean / peak over the run) and
    ``daily_one_minus_load_factor`` (the mean over days of 1 - mean / peak of the day)."""
    p = np.asarray(aggregate_w, dtype=float) / 1000.0
    per_day = max(int(round(86400.0 / dt_s)), 1)
    days = [p[i : i + per_day] for i in range(0, len(p), per_day)]
    peak = float(p.max()) if len(p) else 0.0
    return {
        "peak_kw": peak,
        "average_daily_peak_kw": float(np.mean([d.max() for d in days])) if days else 0.0,
        "ramping_kw": float(np.abs(np.diff(p)).sum()),
        "load_factor": float(p.mean() / peak) if peak > 0 else 0.0,
        "daily_one_minus_load_factor": float(
            np.mean([1.0 - d.mean() / d.max() if d.max() > 0 else 0.0 for d in days])
        )
        if days
        else 0.0,
    }


def fleet_json(result: FleetResult, scenario_arg: str) -> FleetJson:
    """The fleet JSON of a run on ``scenario_arg`` (a scenario's name or file; a file is named
    absolute in ``fleet``): ``fleet`` (what ran), ``totals``, ``district`` KPIs, ``aggregate``
    (``time``, ``power_kw`` per counted interval), ``cap`` (None without one), ``fell_back``
    (the buildings whose fallback or whose model's RC MPC acted at least once), ``step_time``
    and ``buildings``."""
    buildings: Sequence[RCParams | MultiZoneParams] = result.params
    return {
        "fleet": (
            {**result.info, "scenario_file": os.path.abspath(scenario_arg)}
            if is_scenario_file(scenario_arg)
            else result.info
        ),
        "totals": result.totals,
        "district": result.district,
        "aggregate": {
            "time": list(result.times),
            "power_kw": [round(float(v) / 1000.0, 4) for v in result.aggregate_u_phys_w],
        },
        "cap": result.cap,
        "fell_back": [
            k["building"] for k in result.kpis
            if k["fallbacks"] > 0 or k.get("model_fallback_steps", 0) > 0
        ],
        "step_time": result.step_time,
        "buildings": [
            {**kpis, "params": params.to_dict() if isinstance(params, RCParams) else dataclasses.asdict(params)}
            for kpis, params in zip(result.kpis, buildings, strict=True)
        ],
    }
