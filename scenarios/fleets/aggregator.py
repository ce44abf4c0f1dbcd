"""The aggregator's fleet run: every building planned in one batch, coordinated under a cap.

:func:`run_coordinated_fleet` runs the fleet of :func:`scenarios.fleets.fleet.run_fleet_closed_loop`
(the same draw, weather, warm-up, plant and KPIs) but decides with one fleet planner
(:mod:`controllers.fleet`: every building's ``qp-mpc``, data built in one pass, or
:mod:`controllers.fleet_sampling`: ``cem`` over each building's learned model in one batched
rollout)
instead of one controller per building, and, with a cap, coordinates it by the dual-ascent
price signal of :mod:`controllers.coordination`: at most ``cap_kw`` of aggregate electrical
power in the window (every day) or all day.

Beyond the fleet run's output, the result holds the aggregate power per counted interval with
its times, the cap's account (:func:`cap_account`: capped intervals, those over the cap and the
energy over it, measured on the plant's delivered power, never hidden) and the district KPIs
CityLearn reports (:func:`scenarios.fleets.fleet.district_kpis`).

A fleet of buildings of several zones is planned by its buildings' zoned controllers, any of
them (:class:`scenarios.fleets.zoned.ZoneFleetPlanner`), coordinated on each building's total
over its actuators.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import pandas as pd

from controllers.base import Controller, ControlSpec
from controllers.coordination import Coordination, DualAscent
from controllers.fleet import FleetPlanner, FleetQPMPC
from controllers.thermostat import Thermostat
from pinn_mpc.errors import InputError, InternalError, setting
from pinn_mpc.multizone import MultiZoneParams
from pinn_mpc.physics import RCParams
from scenarios.fleets.fleet import FleetResult, draw_buildings, fleet_info, fleet_result
from scenarios.fleets.zoned import ZoneFleetPlanner, is_zoned, zoned_planner_factory
from scenarios.inputs.registry import Scenario, check_seed
from scenarios.records import CapAccount, FleetInfo
from scenarios.running.closed_loop import RunInputs, build_loop, prepare_run, progress_steps
from scenarios.running.engine import ClosedLoop

if TYPE_CHECKING:
    from pinn_mpc.models.rollout import BatchDynamics

__all__ = [
    "BATCHED_CONTROLLERS",
    "DEFAULT_DUAL_ASCENT",
    "FleetPlannerFactory",
    "cap_account",
    "cap_in_force",
    "cap_series",
    "learned_fleet_planner",
    "parse_cap_window",
    "run_coordinated_fleet",
]

#: Controllers a fleet can be planned in one batch with (by name).
BATCHED_CONTROLLERS = ("qp-mpc", "cem")

#: The fleet planner for buildings ``fleet`` under ``spec`` (RCParams, or MultiZoneParams for a
#: fleet of buildings of several zones).
FleetPlannerFactory = Callable[[Any, ControlSpec], FleetPlanner]

#: The coordination's default settings.
DEFAULT_DUAL_ASCENT = DualAscent()

_WINDOW = re.compile(r"^(\d{1,2}):(\d{2})-(\d{1,2}):(\d{2})$")


def parse_cap_window(text: str) -> tuple[float, float]:
    """``"HH:MM-HH:MM"`` -> (start, end) hours since midnight; the end may be ``24:00`` and
    may come before the start (a window over midnight)."""
    match = _WINDOW.match(text.strip())
    if match is None:
        raise InputError(f"{setting('cap_window')} {text!r} is not HH:MM-HH:MM (e.g. 17:00-19:00)")
    h0, m0, h1, m1 = (int(g) for g in match.groups())
    start, end = h0 + m0 / 60.0, h1 + m1 / 60.0
    if m0 >= 60 or m1 >= 60 or start >= 24 or end > 24:
        raise InputError(f"{setting('cap_window')} {text!r}: times must lie in 00:00..24:00 with minutes < 60")
    if start == end:
        raise InputError(
            f"{setting('cap_window')} {text!r} is empty (it starts where it ends); leave "
            f"{setting('cap_window')} out to cap all day"
        )
    return start, end


def _in_window(hours: np.ndarray, window: tuple[float, float] | None) -> np.ndarray:
    if window is None:
        return np.ones(hours.shape, dtype=bool)
    start, end = window
    if start < end:
        return (hours >= start - 1e-9) & (hours < end - 1e-9)
    return (hours >= start - 1e-9) | (hours < end - 1e-9)


def cap_series(
    time_of_day_h: np.ndarray, cap_kw: float, window: tuple[float, float] | None, first_row: int
) -> np.ndarray:
    """(N,) the cap [W] on each row of a run's series: ``cap_kw`` on the rows from
    ``first_row`` on (the counted intervals and the forecast lead) whose interval starts in
    ``window`` (every day; None: all day), ``inf`` elsewhere."""
    if not (math.isfinite(cap_kw) and cap_kw > 0):
        raise ValueError(f"cap_kw must be a positive number of kW, got {cap_kw!r}")
    hours = np.asarray(time_of_day_h, dtype=float)
    capped = _in_window(hours, window)
    capped[:first_row] = False
    return np.where(capped, cap_kw * 1000.0, np.inf)


def cap_in_force(times: Sequence[str], cap: Mapping[str, Any]) -> np.ndarray:
    """(K,) the cap [kW] at each of the interval start ``times`` (ISO 8601) of a run whose cap
    account is ``cap`` (:func:`cap_account`), NaN where it does not hold."""
    stamps = pd.DatetimeIndex(pd.to_datetime(list(times)))
    hours = np.asarray(stamps.hour + stamps.minute / 60.0, dtype=float)
    window = None if cap.get("window") is None else parse_cap_window(cap["window"])
    return np.where(_in_window(hours, window), float(cap["kw"]), np.nan)


def cap_account(
    aggregate_w: np.ndarray, cap_w: np.ndarray, *, dt_s: float, window: str | None
) -> CapAccount:
    """The cap's account over the counted intervals: ``kw``, ``window`` (``HH:MM-HH:MM`` or
    None for all day), ``intervals`` capped, ``intervals_over`` (aggregate delivered power
    above the cap by more than 1 W), ``kwh_over`` (energy above the cap in them)."""
    capped = np.isfinite(cap_w)
    over = np.where(capped, aggregate_w - cap_w, 0.0)
    return {
        "kw": float(np.min(cap_w[capped]) / 1000.0) if capped.any() else None,
        "window": window,
        "intervals": int(capped.sum()),
        "intervals_over": int(np.sum(over > 1.0)),
        "kwh_over": float(np.sum(np.clip(over, 0.0, None)) * dt_s / 3.6e6),
        "max_over_kw": float(max(np.max(over, initial=0.0), 0.0) / 1000.0),
    }


def _qp_factory(fleet: Sequence[RCParams], spec: ControlSpec) -> FleetPlanner:
    return FleetQPMPC(fleet, spec)


def _planner_factory(
    planner: str | FleetPlannerFactory, scenario: Scenario, *, n_steps: int, rc: MultiZoneParams | None
) -> FleetPlannerFactory:
    """The factory of a batched fleet's planner: a given one, each building's qp-mpc, or on a
    building of several zones each building's zoned controller ``planner`` (on ``rc``, None:
    its own building)."""
    if not isinstance(planner, str):
        return planner
    if is_zoned(scenario):
        return zoned_planner_factory(planner, scenario, rc=rc, n_steps=n_steps)
    if rc is not None:
        raise InputError(
            f"a multi-zone RC plans a fleet of buildings of several zones; scenario {scenario.name!r} "
            "has one zone (its fleet's qp-mpc plans on each building's own RC)"
        )
    if planner != "qp-mpc":
        raise ValueError(
            f"a batched fleet without models plans with qp-mpc, got {planner!r}; cem needs "
            "each building's learned model (learned_fleet_planner)"
        )
    return _qp_factory


class _BatchedRun(NamedTuple):
    """What :func:`_run_batched` measured over the counted intervals."""

    times_s: np.ndarray  # (K, 2) planning and plant-step wall time of each interval [s]
    prices: np.ndarray  # (K,) the coordination price [EUR/kWh]
    curtailed: int  # intervals the cap curtailed
    plans: int  # plans made (a capped step may re-plan)
    model_fallbacks: np.ndarray  # (B,) decisions each building's RC MPC made for its model


def _run_batched(
    loop: ClosedLoop,
    run: RunInputs,
    planner: FleetPlanner,
    coordination: Coordination,
    warmup_controllers: Sequence[Controller],
    *,
    label: str,
    progress: bool,
    perfect: bool = False,
) -> _BatchedRun:
    """Every interval of ``run``: the thermostats through the warm-up, then one batched plan
    of every building a step, settled on the cap by ``coordination``; ``perfect``: the
    planner knows the truth (the observations and forecasts a true-state controller sees)."""
    n_counted, b = run.total - run.warmup, loop.n_buildings
    times_s = np.zeros((n_counted, 2))
    prices = np.zeros(n_counted)
    curtailed = plans = 0
    model_fallbacks = np.zeros(b, dtype=int)
    for k in progress_steps(run.total, label, progress):
        if k < run.warmup:
            loop.advance_fleet(warmup_controllers)
            continue
        start = time.perf_counter()
        forecast = loop.forecast(perfect=perfect)
        observations = [loop.observation(perfect=perfect, building=i) for i in range(b)]
        planner.observe(observations, forecast)
        step = coordination.step(planner, loop.start + loop.k)
        decided = time.perf_counter()
        share = np.full(b, (decided - start) / b)
        loop.step(step.decision.u_w, decision_s=share, fallback=step.decision.fallback)
        times_s[k - run.warmup] = decided - start, time.perf_counter() - decided
        prices[k - run.warmup] = step.price_eur_per_kwh[0]
        curtailed += int(step.curtailed)
        if step.decision.model_fallback is not None:
            model_fallbacks += step.decision.model_fallback
        plans += step.plans
    return _BatchedRun(times_s, prices, curtailed, plans, model_fallbacks)


def run_coordinated_fleet(
    scenario: Scenario,
    planner: str | FleetPlannerFactory = "qp-mpc",
    *,
    n_buildings: int,
    days: int,
    seed: int,
    spread: float = 0.2,
    cap_kw: float | None = None,
    cap_window: str | None = None,
    dual: DualAscent = DEFAULT_DUAL_ASCENT,
    warmup_steps: int | None = None,
    weather_part: str = "test",
    fleet: Sequence[RCParams] | None = None,
    rc: MultiZoneParams | None = None,
    progress: bool = False,
) -> FleetResult:
    """Run ``n_buildings`` buildings around ``scenario``'s under one fleet planner.

    ``planner`` is ``"qp-mpc"`` (each building's RC MPC on its own parameters, planned together) or
    a factory ``(fleet, spec) -> FleetPlanner`` (e.g. the batched sampling planner over the
    buildings' learned models). ``cap_kw`` (None: no cap, one plan a step) caps the aggregate
    electrical power in ``cap_window`` (``"HH:MM-HH:MM"``; None: all day) of every counted day,
    by ``dual`` (:class:`controllers.coordination.DualAscent`). The rest as
    :func:`scenarios.fleets.fleet.run_fleet_closed_loop`; ``kpis`` report each building's share of the
    batched decision time (the step's planning time / B) as its decision time, and
    ``model_fallback_steps`` (the decisions its RC MPC made for a distrusted model). ``fleet``
    gives the buildings (e.g. those the learned models were trained on) instead of the draw
    around the scenario's (``n_buildings`` must match).

    On a building of several zones (:mod:`scenarios.fleets.zoned`) ``planner`` may name any of
    its controllers (thermostat, oracle, qp-mpc, cem, random-shooting), each building's on its
    own building (the RC planners on ``rc`` if given); the fleet is drawn zone by zone.
    """
    check_seed(seed)
    if cap_kw is None and cap_window is not None:
        raise ValueError("cap_window needs cap_kw (the cap in that window)")
    window = parse_cap_window(cap_window) if cap_window is not None else None
    run = prepare_run(scenario, days=days, seed=seed, warmup_steps=warmup_steps, weather_part=weather_part)
    factory = _planner_factory(planner, scenario, n_steps=run.total - run.warmup, rc=rc)
    buildings: tuple[RCParams, ...] | tuple[MultiZoneParams, ...]
    if fleet is None:
        buildings = draw_buildings(scenario, n_buildings, spread=spread, seed=seed)
    elif len(fleet) != n_buildings:
        raise InternalError(f"run_coordinated_fleet: {len(fleet)} buildings given for n_buildings={n_buildings}")
    else:
        buildings = tuple(fleet)
    spec = scenario.control_spec()
    fleet_planner = factory(buildings, spec)
    fleet_planner.reset(seed)
    series = run.series
    cap = (
        cap_series(series.time_of_day_h, cap_kw, window, run.warmup)
        if cap_kw is not None
        else np.full(len(series), np.inf)
    )
    coordination = Coordination(cap, dual)
    warmup_controllers = [Thermostat(spec) for _ in buildings]
    for c in warmup_controllers:
        c.reset(seed)
    loop = build_loop(scenario, run, seed=seed, fleet=buildings)
    n_counted, b = run.total - run.warmup, len(buildings)
    label = f"{fleet_planner.name} x {b} (batched{', capped' if cap_kw is not None else ''})"
    times_s, prices, curtailed, plans, model_fallbacks = _run_batched(
        loop, run, fleet_planner, coordination, warmup_controllers, label=label, progress=progress,
        perfect=isinstance(fleet_planner, ZoneFleetPlanner) and fleet_planner.knows_true_state,
    )
    cap_info = None
    if cap_kw is not None:
        aggregate = loop.aggregate_u_phys_w()[run.counted]
        cap_info = cap_account(aggregate, cap[run.counted], dt_s=scenario.sim.dt_s, window=cap_window)
        cap_info["kw"] = float(cap_kw)
        cap_info["curtailed_steps"] = curtailed
    info: FleetInfo = {
        **fleet_info(
            scenario, fleet_planner.name, n_buildings=b, days=days, seed=seed,
            spread=spread, weather_part=weather_part,
        ),
        "batched": True,
        "plans_per_step": plans / max(n_counted, 1),
        "dual_ascent": {
            "iterations": dual.iterations,
            "step_eur_per_kwh": dual.step_eur_per_kwh,
            "max_price_eur_per_kwh": dual.max_price_eur_per_kwh,
            "secant": dual.secant,
            "interpolate": dual.interpolate,
        },
    }
    if fleet_planner.rc_candidates is not None:  # a batched cem over learned models
        info["rc_candidates"] = bool(fleet_planner.rc_candidates)
    return fleet_result(
        scenario, run, loop, times_s, seed=seed, params=buildings,
        errors=tuple(fleet_planner.errors) if isinstance(fleet_planner, ZoneFleetPlanner) else (),
        cap=cap_info,
        prices=prices,
        extra_kpis={"model_fallback_steps": model_fallbacks},
        info=info,
    )


def learned_fleet_planner(
    models: Sequence[BatchDynamics],
    *,
    plan_members: int = 1,
    n_samples: int = 32,
    n_iters: int | None = None,
    replan_iters: int = 0,
    rc_fallback: bool = True,
    rc_candidates: bool = False,
    fast_candidates: bool = True,
    rc_refresh: int = 3,
    spread_members: int | None = 5,
) -> FleetPlannerFactory:
    """The factory of a batched ``cem`` over each building's planner model (``models[b]``, any
    family ``train`` fits: hybrids roll out in one stacked batch, the others each through its
    own rollout): :class:`controllers.fleet_sampling.FleetCEM` planning with each ensemble's
    first ``plan_members`` members (the disagreement measured over the first
    ``spread_members``; None: all; not measured where a building's model has one member),
    ``n_samples`` x ``n_iters`` per plan (None: 1 with ``rc_candidates``, whose plan starts the
    CEM near the optimum, 2 without); a further plan of a step under a new coordination price
    rescores the step's samples (``replan_iters`` > 0: runs that many CEM iterations instead).
    With ``rc_fallback`` a shadow :class:`FleetQPMPC` on the RCs identified from the models'
    training data (every model must have one); ``rc_candidates`` scores that RC MPC's plan
    among the samples of a step's first plan, each building's solved every ``rc_refresh``
    steps in turn (its last one shifted otherwise), to the candidate tolerances with
    ``fast_candidates``."""
    from controllers.fleet_sampling import FleetCEM
    from controllers.planners import CEMPlanner
    from pinn_mpc.models.fleet import FleetModels
    from scenarios.running.factory import model_guard

    def make(fleet: Sequence[RCParams], spec: ControlSpec) -> FleetPlanner:
        from scenarios.running.budget import check_batched_fleet_memory

        if len(fleet) != len(models):
            raise InternalError(f"{len(models)} learned models for a fleet of {len(fleet)} buildings")
        check_batched_fleet_memory(
            buildings=len(models), members=plan_members, samples=n_samples,
            horizon_steps=spec.horizon_steps,
        )
        shadow = None
        if rc_fallback:
            rcs = [model_guard(m).rc for m in models]
            missing = [i for i, rc in enumerate(rcs) if rc is None]
            if missing:
                raise InputError(
                    f"building(s) {missing[:5]}: the model has no identified RC to fall back on; "
                    "retrain it with `train`, or plan without the RC fallback"
                )
            shadow = FleetQPMPC([rc for rc in rcs if rc is not None], spec)
        fewest = min(m.n_members for m in models)
        return FleetCEM(
            FleetModels(models, members=plan_members),
            spec,
            planner=CEMPlanner(
                lower=spec.actuator.lower_w, upper=spec.actuator.upper_w, n_samples=n_samples,
                n_iters=n_iters if n_iters is not None else (1 if rc_candidates else 2),
            ),
            shadow=shadow,
            spread_dynamics=(
                FleetModels(models, members=min(spread_members or fewest, fewest)) if fewest > 1 else None
            ),
            replan_iters=replan_iters,
            rc_candidates=rc_candidates,
            fast_candidates=fast_candidates,
            rc_refresh=rc_refresh,
        )

    return make
