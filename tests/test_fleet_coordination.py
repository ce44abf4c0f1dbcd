"""The batched fleet QP MPC, the cap's dual-ascent coordination and the fleet's new output."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from controllers.coordination import Coordination, DualAscent, planned_aggregate_w
from controllers.fleet import CANDIDATE_OPTIONS, FleetQPMPC
from controllers.rc_mpc.osqp import QPMPC
from pinn_mpc.errors import InputError
from pinn_mpc.simulator import draw_fleet
from pinn_mpc_cli.cli import main
from scenarios.fleets.aggregator import (
    cap_account,
    cap_in_force,
    parse_cap_window,
    run_coordinated_fleet,
)
from scenarios.fleets.fleet import district_kpis
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import build_loop, prepare_run

#: A test day of winter_household with heating demand (2023-02-12, -1.7 .. 4.3 C).
COLD_SEED = 13
#: Tight OSQP tolerances: the batched and the per-building solutions then agree to round-off.
TIGHT = {"eps_abs": 1e-6, "eps_rel": 1e-6, "max_iter": 400000}


def _fleet_loop(n: int, *, warmup: int = 0):
    scenario = get_scenario("winter_household")
    fleet = draw_fleet(scenario.sim.params, n, spread=0.3, rng=np.random.default_rng(1))
    run = prepare_run(scenario, days=1, seed=COLD_SEED, warmup_steps=warmup, weather_part="test")
    return scenario, fleet, build_loop(scenario, run, seed=0, fleet=fleet)


def _observe(planner, loop):
    observations = [loop.observation(building=i) for i in range(loop.n_buildings)]
    forecast = loop.forecast()
    planner.observe(observations, forecast)
    return observations, forecast


def test_batched_qp_solves_each_buildings_qp_mpc_problem():
    scenario, fleet, loop = _fleet_loop(3)
    spec = scenario.control_spec()
    batched = FleetQPMPC(fleet, spec)
    exact = FleetQPMPC(fleet, spec, solver_options=TIGHT)  # the same problems, solved tightly
    singles = [QPMPC(p, spec) for p in fleet]  # the same OSQP settings as `batched`
    heated = 0.0
    for _ in range(4):
        observations, forecast = _observe(batched, loop)
        _observe(exact, loop)
        plan, optimum = batched.plan(), exact.plan()
        for i, (controller, obs) in enumerate(zip(singles, observations, strict=True)):
            controller.act(obs, forecast)
            assert not controller.last_stats.fallback
            # Each building's own estimate and problem: the batched plan is as good as the
            # building's own QP MPC's, both within the solver's tolerance of the optimum.
            np.testing.assert_allclose(batched_estimate(batched, i), controller.state_estimate_c)
            stage = controller.problem.stage(controller.state_estimate_c, forecast)
            best = controller.problem.objective(stage, optimum.power_w[i] / 1000.0)
            own = controller.problem.objective(stage, controller.last_plan / 1000.0)
            ours = controller.problem.objective(stage, plan.power_w[i] / 1000.0)
            assert best <= min(own, ours) + 1e-6
            assert ours == pytest.approx(best, rel=3e-2) and own == pytest.approx(best, rel=3e-2)
        heated += plan.power_w.sum()
        decision = batched.commit(plan)
        exact.commit(optimum)
        assert not decision.fallback.any()
        loop.step(decision.u_w, decision_s=np.zeros(3), fallback=decision.fallback)
    assert heated > 1e4  # the day needs heat: the plans are not trivially zero


def test_threads_share_the_blocks_and_plan_exactly_as_one_thread():
    scenario, fleet, loop = _fleet_loop(5, warmup=2)
    spec = scenario.control_spec()
    one, two = FleetQPMPC(fleet, spec, threads=1), FleetQPMPC(fleet, spec, threads=2)
    extra = np.zeros(spec.horizon_steps)
    extra[10:14] = 0.4
    for _ in range(3):
        _observe(one, loop)
        _observe(two, loop)
        for price in (None, extra):
            a, b = one.plan(price), two.plan(price)
            np.testing.assert_array_equal(a.power_w, b.power_w)
            assert a.ok.all() and b.ok.all() and a.status == b.status == "solved"
        decision = one.commit(a)
        two.commit(b)
        loop.step(decision.u_w, decision_s=np.zeros(5), fallback=decision.fallback)
    with pytest.raises(ValueError, match="threads must be a whole number >= 1"):
        FleetQPMPC(fleet, spec, threads=0)


def test_a_fast_candidate_plan_is_near_the_optimum_and_leaves_the_exact_settings_alone():
    scenario, fleet, loop = _fleet_loop(4, warmup=2)
    spec = scenario.control_spec()
    planner = FleetQPMPC(fleet, spec)
    exact = FleetQPMPC(fleet, spec, solver_options=TIGHT)
    _observe(planner, loop)
    _observe(exact, loop)
    singles = [QPMPC(p, spec) for p in fleet]
    observations = [loop.observation(building=i) for i in range(4)]
    forecast = loop.forecast()
    optimum = exact.plan()
    fast = planner.plan(fast=True)
    assert planner._solver._solvers[0].settings.eps_abs == CANDIDATE_OPTIONS["eps_abs"]
    again = planner.plan()  # the exact settings are back: the plan of a planner never run fast
    settings = planner._solver._solvers[0].settings
    assert (settings.eps_abs, settings.polishing, settings.max_iter) == (1e-3, True, 10000)
    fresh = FleetQPMPC(fleet, spec)
    _observe(fresh, loop)
    for i, (controller, obs) in enumerate(zip(singles, observations, strict=True)):
        controller.act(obs, forecast)
        stage = controller.problem.stage(batched_estimate(planner, i), forecast)
        best = controller.problem.objective(stage, optimum.power_w[i] / 1000.0)
        assert controller.problem.objective(stage, fast.power_w[i] / 1000.0) == pytest.approx(best, rel=0.1)
        assert controller.problem.objective(stage, again.power_w[i] / 1000.0) == pytest.approx(best, rel=3e-2)
    np.testing.assert_allclose(again.power_w, fresh.plan().power_w, atol=5.0)
    assert fast.iterations <= CANDIDATE_OPTIONS["max_iter"]


def test_a_block_left_unsolved_for_steps_starts_from_its_solution_shifted_as_many_steps():
    scenario, fleet, loop = _fleet_loop(2, warmup=2)
    planner = FleetQPMPC(fleet, scenario.control_spec())
    h = planner.horizon_steps
    _observe(planner, loop)
    plan = planner.plan()
    heat = planner._solver._solutions[1][0][:h].copy()  # building 1's planned heat
    skip = np.array([True, False])
    for k in range(1, 4):
        decision = planner.commit(plan)
        loop.step(decision.u_w, decision_s=np.zeros(2), fallback=decision.fallback)
        _observe(planner, loop)
        np.testing.assert_array_equal(planner._solver._solutions[1][0][: h - k], heat[k:])
        plan = planner.plan(only=skip)  # building 1 is not solved
        assert plan.ok.tolist() == [True, False]


def batched_estimate(planner: FleetQPMPC, i: int) -> np.ndarray:
    return planner.estimator.state[i]


def test_raising_the_price_never_raises_the_planned_power_in_the_priced_intervals():
    scenario, fleet, loop = _fleet_loop(6)
    planner = FleetQPMPC(fleet, scenario.control_spec(), solver_options=TIGHT)
    _observe(planner, loop)
    window = slice(20, 24)
    totals = []
    for level in (0.0, 0.05, 0.2, 0.5, 1.0, 3.0):
        extra = np.zeros(planner.horizon_steps)
        extra[window] = level
        totals.append(planned_aggregate_w(planner.plan(extra))[window].sum())
    assert totals[0] > 1000.0  # the fleet heats in that window without a price
    assert all(b <= a + 1.0 for a, b in zip(totals, totals[1:], strict=False))
    assert totals[-1] < 0.5 * totals[0]  # and the price moves it


def test_coordination_raises_the_price_while_the_plan_exceeds_the_cap_and_caps_the_first_action():
    scenario, fleet, loop = _fleet_loop(6)
    loop.reset(start=16)  # 08:00, the day band starts: every building heats now
    planner = FleetQPMPC(fleet, scenario.control_spec())
    _observe(planner, loop)
    free = planned_aggregate_w(planner.plan())
    assert free[0] > 1000.0
    cap_w = np.full(len(loop.exogenous), np.inf)
    cap_w[16:18] = 0.5 * free[0]  # the interval about to start is capped at half its plan
    coordination = Coordination(cap_w, DualAscent(iterations=3, step_eur_per_kwh=0.5))
    step = coordination.step(planner, loop.start + loop.k)
    assert step.plans == 3
    assert step.decision.u_w.sum() <= cap_w[0] + 1e-6
    assert step.price_eur_per_kwh[0] > 0 and np.all(step.price_eur_per_kwh[2:] == 0)


def test_cap_account_counts_every_interval_over_the_cap():
    aggregate = np.array([90e3, 110e3, 100e3, 130e3, 50e3])
    cap = np.array([np.inf, 100e3, 100e3, 100e3, np.inf])
    account = cap_account(aggregate, cap, dt_s=1800.0, window="17:00-18:30")
    assert account["intervals"] == 3 and account["intervals_over"] == 2
    assert account["kwh_over"] == pytest.approx((10 + 30) * 0.5)
    assert account["max_over_kw"] == pytest.approx(30.0)


def test_district_kpis_as_citylearn_defines_them():
    p_w = np.array([1.0, 3.0, 2.0, 2.0]) * 1000.0
    kpis = district_kpis(p_w, dt_s=6 * 3600.0)  # four intervals: one day
    assert kpis["peak_kw"] == 3.0 and kpis["average_daily_peak_kw"] == 3.0
    assert kpis["ramping_kw"] == pytest.approx(2.0 + 1.0 + 0.0)
    assert kpis["load_factor"] == pytest.approx(2.0 / 3.0)
    assert kpis["daily_one_minus_load_factor"] == pytest.approx(1.0 / 3.0)


def test_cap_window_parsing():
    assert parse_cap_window("17:00-19:30") == (17.0, 19.5)
    assert parse_cap_window("22:00-06:00") == (22.0, 6.0)
    for bad, says in (("17-19", "is not HH:MM-HH:MM"), ("17:00-17:00", "is empty (it starts where it ends)"),
                      ("25:00-26:00", "times must lie in 00:00..24:00"),
                      ("17:75-18:00", "with minutes < 60")):
        with pytest.raises(InputError, match=re.escape(f"cap_window '{bad}'") + ".*" + re.escape(says)) as caught:
            parse_cap_window(bad)
        assert caught.value.text({"cap_window": "--cap-window"}).startswith(f"--cap-window '{bad}'")
    hours = cap_in_force(["2023-02-12T16:30:00", "2023-02-12T17:00:00", "2023-02-12T19:00:00"],
                         {"kw": 5.0, "window": "17:00-19:00"})
    assert np.isnan(hours[0]) and hours[1] == 5.0 and np.isnan(hours[2])


@pytest.mark.slow
def test_a_feasible_cap_is_met_in_closed_loop_at_a_small_comfort_cost():
    scenario = get_scenario("winter_household")
    n, window = 12, "17:00-19:00"
    free = run_coordinated_fleet(scenario, n_buildings=n, days=1, seed=COLD_SEED)
    in_window = ~np.isnan(cap_in_force(free.times, {"kw": 1.0, "window": window}))
    cap_kw = 0.6 * free.aggregate_u_phys_w[in_window].max() / 1000.0
    capped = run_coordinated_fleet(
        scenario, n_buildings=n, days=1, seed=COLD_SEED, cap_kw=cap_kw, cap_window=window
    )
    assert capped.cap is not None and capped.cap["intervals"] == 4
    assert capped.cap["intervals_over"] == 0 and capped.cap["kwh_over"] == pytest.approx(0.0, abs=1e-6)
    assert np.all(capped.aggregate_u_phys_w[in_window] <= cap_kw * 1000.0 + 1.0)
    extra_kh = (capped.totals["discomfort_kh"] - free.totals["discomfort_kh"]) / n
    assert extra_kh < 0.5
    # Without coordination the same fleet would have broken the cap.
    assert free.aggregate_u_phys_w[in_window].max() > cap_kw * 1000.0 * 1.5


def _cli(tmp_path, *extra):
    return main([
        "closed-loop", "--scenario", "winter_household", "--controller", "qp-mpc", "--days", "1",
        "--seed", str(COLD_SEED), "--json", str(tmp_path / "k.json"), *extra,
    ])


def test_cli_capped_fleet_writes_aggregate_cap_district_and_figure(tmp_path, capsys):
    assert _cli(tmp_path, "--buildings", "4", "--cap-kw", "12", "--cap-window", "17:00-19:00") == 0
    out = capsys.readouterr().out
    assert "capped intervals over it" in out
    data = json.loads((tmp_path / "k.json").read_text())
    assert len(data["aggregate"]["time"]) == len(data["aggregate"]["power_kw"]) == 48
    assert set(data["cap"]) >= {"kw", "window", "intervals", "intervals_over", "kwh_over"}
    assert data["cap"]["kw"] == 12 and data["cap"]["window"] == "17:00-19:00"
    assert data["cap"]["intervals"] == 4
    over = [p for t, p in zip(data["aggregate"]["time"], data["aggregate"]["power_kw"], strict=True)
            if "T17:" in t or "T18:" in t]
    assert data["cap"]["intervals_over"] == sum(p > 12.001 for p in over)
    assert set(data["district"]) >= {"peak_kw", "ramping_kw", "load_factor"}
    assert data["fell_back"] == []
    assert (tmp_path / "k.fleet.png").stat().st_size > 1000


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--buildings", "3", "--cap-kw", "5", "--cap-window", "5pm-7pm"], "is not HH:MM-HH:MM"),
        (["--buildings", "3", "--cap-window", "17:00-19:00"], "--cap-window needs --cap-kw"),
        (["--cap-kw", "5"], "--cap-kw coordinates a fleet: add --buildings N"),
        (["--buildings", "3", "--cap-kw", "0"], "must be a finite number > 0, got 0"),
        # the same rule whatever the number (it once said ">= 0" of a negative one)
        (["--buildings", "3", "--cap-kw", "-5"], "must be a finite number > 0, got -5"),
        (["--buildings", "3", "--rc-candidates"], "--rc-candidates applies to the batched cem"),
    ],
)
def test_cli_cap_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    try:
        code = _cli(tmp_path, *args)
    except SystemExit as exc:  # argparse's own checks exit
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_a_fleet_partitioned_across_ray_workers_plans_as_one():
    from scenarios.fleets.partitions import partitioned
    from scenarios.running.ray_engine import ray_engine

    scenario = get_scenario("winter_household")

    def qp(fleet, spec):
        return FleetQPMPC(fleet, spec)

    whole = run_coordinated_fleet(scenario, qp, n_buildings=5, days=1, seed=COLD_SEED,
                                  cap_kw=10.0, cap_window="17:00-19:00")
    with ray_engine(None, 2):
        parts = run_coordinated_fleet(scenario, partitioned(lambda s: qp, 2, "qp-mpc"), n_buildings=5,
                                      days=1, seed=COLD_SEED, cap_kw=10.0, cap_window="17:00-19:00")
    np.testing.assert_allclose(parts.aggregate_u_phys_w, whole.aggregate_u_phys_w, atol=1e-6)
    assert parts.cap == whole.cap and parts.info["controller"] == "qp-mpc"


class _ThresholdFleet:
    """A fleet whose buildings respond like linear programs: building b plans ``demand_w``
    in an interval while its price there is under its own threshold ``tau[b]``, nothing
    above it (what makes a fixed dual step overshoot)."""

    name = "threshold"
    rc_candidates = None

    def __init__(self, tau: np.ndarray, demand_w: float, h: int = 6) -> None:
        self.tau, self.demand_w, self.h = tau, demand_w, h
        self.committed: list[np.ndarray] = []
        self.prices: list[np.ndarray] = []

    @property
    def n_buildings(self) -> int:
        return len(self.tau)

    @property
    def horizon_steps(self) -> int:
        return self.h

    @property
    def n_fallbacks(self) -> np.ndarray:
        return np.zeros(self.n_buildings, dtype=int)

    def reset(self, seed=None) -> None:
        pass

    def observe(self, observations, forecast) -> None:
        pass

    def plan(self, extra=None):
        from controllers.fleet import FleetPlan

        extra = np.zeros(self.h) if extra is None else np.asarray(extra, float)
        self.prices.append(extra.copy())
        power = np.where(extra[None, :] < self.tau[:, None], self.demand_w, 0.0)
        return FleetPlan(power, np.ones(self.n_buildings, dtype=bool), "solved", 1)

    def commit(self, plan):
        from controllers.fleet import FleetDecision

        self.committed.append(plan.power_w[:, 0].copy())
        return FleetDecision(plan.power_w[:, 0].copy(), np.zeros(self.n_buildings, dtype=bool))


def test_the_first_actions_use_the_whole_cap_where_the_plans_jump_across_it():
    rng = np.random.default_rng(0)
    tau = rng.uniform(1.0, 1.02, 40)  # EUR/kWh each building would pay to heat: alike buildings
    cap_w = np.full(12, np.inf)
    cap_w[0:6] = 0.45 * 40 * 3000.0  # 45 % of the fleet's demand, for six intervals
    big = 1.0  # EUR/kWh per unit of excess: a step that overshoots
    for settings, whole in (
        (DualAscent(step_eur_per_kwh=big), True),
        (DualAscent(step_eur_per_kwh=big, secant=False, interpolate=False), False),
    ):
        fleet = _ThresholdFleet(tau, 3000.0)
        coordination = Coordination(cap_w, settings)
        used = []
        for row in range(6):
            step = coordination.step(fleet, row)
            assert step.decision.u_w.sum() <= cap_w[row] * (1 + 1e-9)
            used.append(step.decision.u_w.sum() / cap_w[row])
        if whole:
            # Bracketed from the second step on (the prices carry over): the cap exactly, each
            # building between nothing and its demand, none scaled down.
            np.testing.assert_allclose(used[1:], 1.0, rtol=1e-9)
            assert np.all((fleet.committed[-1] >= 0) & (fleet.committed[-1] <= 3000.0))
        else:
            assert min(used) < 0.95  # the plain dual ascent overshoots and wastes the cap


def test_a_fleet_under_the_cap_at_a_price_gets_the_plan_without_it():
    tau = np.full(10, 1.0)
    fleet = _ThresholdFleet(tau, 1000.0)
    cap_w = np.full(12, np.inf)
    cap_w[0] = 20e3  # above what the fleet ever asks: the cap does not bind
    coordination = Coordination(cap_w, DualAscent(iterations=2))
    coordination._price = np.full(6, 5.0)  # a price left from before, far too high
    step = coordination.step(fleet, 0)
    assert step.decision.u_w.sum() == pytest.approx(10e3)  # the extra plan at no price wins
    assert step.plans == 3 and step.price_eur_per_kwh[0] == 0.0


def test_the_secant_price_lies_in_the_bracket_of_the_steps_plans():
    from controllers.coordination import _Point

    coordination = Coordination(np.full(4, 100.0))
    cap = np.full(4, 100.0)
    tried = [
        _Point(np.full(4, 0.5), None, np.full(4, 150.0)),  # over the cap at 0.5
        _Point(np.full(4, 1.5), None, np.full(4, 50.0)),  # under it at 1.5
    ]
    price = coordination._update(np.full(4, 1.5), np.full(4, 50.0), cap, tried)
    np.testing.assert_allclose(price, 1.0)  # the secant: halfway in power, halfway in price
    plain = Coordination(np.full(4, 100.0), DualAscent(secant=False))._update(
        np.full(4, 1.5), np.full(4, 50.0), cap, tried
    )
    np.testing.assert_allclose(plain, 1.5 - 0.2 * 0.5)
