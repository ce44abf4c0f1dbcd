"""A fleet of learned hybrids planned in one batch: the batched rollout and CEM against the
per-building ones, and the batched CEM in closed loop (with and without a cap)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from controllers.planners import CEMPlanner
from pinn_mpc import TrainConfig, train_model
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.models.fleet import FEW_PLANS, FleetHybrid
from pinn_mpc.simulator import draw_fleet
from scenarios.fleets.aggregator import cap_in_force, learned_fleet_planner, run_coordinated_fleet
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import build_loop, prepare_run
from scenarios.running.datagen import generate

COLD_SEED = 13  # winter_household's test day 2023-02-12: heating all day


@pytest.fixture(scope="module")
def fleet_models():
    """Two buildings of a spread fleet, each with a small hybrid from 5 days of its own data."""
    scenario = get_scenario("winter_household")
    fleet = draw_fleet(scenario.sim.params, 2, spread=0.2, rng=np.random.default_rng(0))
    data = generate(scenario, days=5, seed=0, policy="random-level", n_buildings=2, fleet=fleet)
    config = TrainConfig(n_seeds=3, epochs=8, eta=scenario.sim.params.eta, u_max_w=scenario.sim.u_max_w)
    models = [
        train_model(part.drop(columns="building").reset_index(drop=True), arch="hybrid",
                    config=config, progress=False)
        for _, part in data.groupby("building")
    ]
    return scenario, fleet, models


def _observations(scenario, fleet, steps=20):
    run = prepare_run(scenario, days=1, seed=COLD_SEED, warmup_steps=steps, weather_part="test")
    loop = build_loop(scenario, run, seed=0, fleet=fleet)
    rng = np.random.default_rng(0)
    for _ in range(steps):  # a history with every power level
        loop.step(rng.uniform(0, scenario.sim.u_max_w, len(fleet)), decision_s=np.zeros(len(fleet)),
                  fallback=np.zeros(len(fleet), dtype=bool))
    return [loop.observation(building=i) for i in range(len(fleet))], loop.forecast()


def test_batched_rollout_equals_each_models_rollout(fleet_models):
    scenario, fleet, models = fleet_models
    observations, forecast = _observations(scenario, fleet)
    h = 48
    exog = forecast.exogenous(models[0].exog_names, h)
    u = torch.rand((2, 9, h), generator=torch.Generator().manual_seed(0)) * scenario.sim.u_max_w
    batched = FleetHybrid(models).rollout([o.history for o in observations], u, exog)
    first = FleetHybrid(models, members=1).rollout([o.history for o in observations], u, exog)
    for i, model in enumerate(models):
        own = model.rollout(observations[i].history, u[i], exog)
        assert batched.t_r_c[i].shape == own.t_r_c.shape == (3, 9, h)
        # One recursion (roll_states) for both: only the preparation's round-off differs.
        torch.testing.assert_close(batched.t_r_c[i], own.t_r_c, atol=1e-4, rtol=0)
        torch.testing.assert_close(batched.u_phys_w[i], own.u_phys_w, atol=0.05, rtol=0)
        torch.testing.assert_close(batched.t_m_c[i], own.t_m_c, atol=1e-4, rtol=0)
        torch.testing.assert_close(first.t_r_c[i], own.t_r_c[:1], atol=1e-4, rtol=0)
    # A rollout of a few plans (FEW_PLANS: the first layer row by row) is the same rollout.
    for n in (1, FEW_PLANS):
        few = FleetHybrid(models).rollout([o.history for o in observations], u[:, :n], exog)
        torch.testing.assert_close(few.t_r_c, batched.t_r_c[:, :, :n], atol=1e-4, rtol=0)
        torch.testing.assert_close(few.u_phys_w, batched.u_phys_w[:, :, :n], atol=0.05, rtol=0)
    # The two buildings' models differ: a mixed-up batch would not pass the comparison.
    assert (batched.t_r_c[0] - batched.t_r_c[1]).abs().max() > 0.05


def test_batched_cem_equals_the_cem_planner_building_by_building(fleet_models):
    from controllers.fleet_sampling import optimize_fleet

    scenario, fleet, models = fleet_models
    observations, forecast = _observations(scenario, fleet)
    h = 24
    exog = forecast.exogenous(models[0].exog_names, h)
    planner = CEMPlanner(lower=0.0, upper=scenario.sim.u_max_w, n_samples=16, n_iters=3)
    target = torch.linspace(20.0, 21.5, h)

    def cost(i: int, u: torch.Tensor) -> torch.Tensor:  # (N, H) -> (N,)
        roll = models[i].rollout(observations[i].history, u, exog)
        return (roll.t_r_c.mean(0) - target).abs().sum(-1) + 1e-4 * roll.u_phys_w.mean(0).sum(-1)

    x0 = torch.full((2, h), 3000.0)
    seeds = (5, 7)
    plans, costs = optimize_fleet(
        planner, lambda u: torch.stack([cost(i, u[i]) for i in range(2)]), x0,
        [torch.Generator().manual_seed(s) for s in seeds],
    )
    for i, s in enumerate(seeds):
        alone = planner.optimize(lambda u, i=i: cost(i, u), x0[i], torch.Generator().manual_seed(s))
        torch.testing.assert_close(plans[i], alone.plan, atol=1e-3, rtol=0)
        assert float(costs[i]) == pytest.approx(alone.cost, rel=1e-6)


def test_a_candidate_plan_is_scored_and_kept_unless_a_sample_beats_it():
    from controllers.fleet_sampling import optimize_fleet

    planner = CEMPlanner(lower=0.0, upper=10.0, n_samples=8, n_iters=2)
    h = 6
    target = torch.tensor([[1.0, 9.0, 2.0, 8.0, 3.0, 7.0], [5.0, 5.0, 0.0, 0.0, 10.0, 10.0]])

    def cost(u: torch.Tensor) -> torch.Tensor:  # (B, N, H) -> (B, N)
        return (u - target[:, None]).abs().sum(-1)

    x0 = torch.full((2, h), 5.0)
    generators = lambda: [torch.Generator().manual_seed(s) for s in (1, 2)]  # noqa: E731
    without, _ = optimize_fleet(planner, cost, x0, generators())
    assert float(cost(without[:, None]).max()) > 1.0  # two iterations of 8 samples do not find it
    plans, costs = optimize_fleet(planner, cost, x0, generators(), candidates=target[:, None])
    torch.testing.assert_close(plans, target)
    assert float(costs.max()) == 0.0
    with pytest.raises(InternalError, match="candidates must be"):
        optimize_fleet(planner, cost, x0, generators(), candidates=torch.zeros(2, 7, h))


def test_more_members_than_the_ensembles_have_are_refused(fleet_models):
    _, _, models = fleet_models
    with pytest.raises(InputError, match="members must lie in 1..3"):
        FleetHybrid(models, members=4)


@pytest.mark.slow
def test_batched_cem_over_learned_models_keeps_comfort_and_a_cap(fleet_models):
    scenario, fleet, models = fleet_models
    free = run_coordinated_fleet(
        scenario, learned_fleet_planner(models), n_buildings=2, days=1, seed=COLD_SEED, fleet=fleet
    )
    assert free.info["controller"] == "cem" and free.totals["fallbacks"] == 0
    assert free.totals["discomfort_kh"] / 2 < 1.0
    assert all("model_fallback_steps" in k for k in free.kpis)
    window = "17:00-19:00"
    in_window = ~np.isnan(cap_in_force(free.times, {"kw": 1.0, "window": window}))
    cap_kw = 0.6 * free.aggregate_u_phys_w[in_window].max() / 1000.0
    capped = run_coordinated_fleet(
        scenario, learned_fleet_planner(models), n_buildings=2, days=1, seed=COLD_SEED,
        fleet=fleet, cap_kw=cap_kw, cap_window=window,
    )
    assert capped.cap is not None and capped.cap["intervals"] == 4
    assert capped.cap["intervals_over"] == 0
    assert np.all(capped.aggregate_u_phys_w[in_window] <= cap_kw * 1000.0 + 1.0)


def test_a_batched_rollout_that_would_not_fit_is_refused_before_it_starts():
    from scenarios.running.budget import check_batched_fleet_memory

    check_batched_fleet_memory(buildings=1000, members=1, samples=32, horizon_steps=48,
                               available=8_000_000_000)
    with pytest.raises(InputError, match="use at most .* buildings, or fewer samples"):
        check_batched_fleet_memory(buildings=100_000, members=5, samples=64, horizon_steps=48,
                                   available=8_000_000_000)


def _counting_candidates(planner):
    """Record the ``only`` mask of every candidate solve of ``planner``'s shadow RC MPC (None:
    every building); commit's solves for the distrusted are not candidates."""
    shadow, real_plan, solves = planner.shadow, planner.shadow.plan, []

    def counted(*args, **kwargs):
        if "fast" in kwargs:
            solves.append(kwargs.get("only"))
        return real_plan(*args, **kwargs)

    shadow.plan = counted
    return solves, real_plan


def _observed_candidate_planner(fleet_models, **options):
    """The batched cem with RC candidates (``options`` for ``learned_fleet_planner``) reset
    and observing a step, its candidate solves counted (:func:`_counting_candidates`)."""
    scenario, fleet, models = fleet_models
    planner = learned_fleet_planner(models, rc_candidates=True, **options)(fleet, scenario.control_spec())
    planner.reset(0)
    solves, real_plan = _counting_candidates(planner)
    observations, forecast = _observations(scenario, fleet)
    planner.observe(observations, forecast)
    return planner, solves, real_plan, observations, forecast


def test_rc_candidates_are_scored_in_the_first_plan_and_the_re_plans_rescore_the_pool(fleet_models):
    """The RC MPC's plan is a candidate of a step's first plan (kept unless a sample beats it
    on the model); a re-plan under a new coordination price picks each building's best of
    the step's scored plans under the new prices, without a rollout or a solve."""
    planner, solves, real_plan, observations, forecast = _observed_candidate_planner(fleet_models, rc_refresh=1)
    h = planner.horizon_steps
    first = planner.plan()
    assert solves == [None]
    rc = real_plan()
    step = planner._step
    pool = [kwh for _, kwh, _ in planner._pool]
    cost = lambda u: planner._costs(step, np.zeros(h), torch.as_tensor(u, dtype=torch.float32)[:, None])[:, 0]  # noqa: E731
    assert torch.all(cost(first.power_w) <= cost(rc.power_w) + 1e-4)
    planner._pool = planner._pool[: len(pool)]  # the scoring above is not a sample of the step
    np.testing.assert_array_equal(planner.plan().power_w, first.power_w)  # same prices, same plans
    extra = np.zeros(h)
    extra[:8] = 2.0
    pricey = planner.plan(extra)
    assert len(solves) == 1
    plans = torch.cat([u for u, _, _ in planner._pool], dim=1)
    kwh = torch.cat(pool, dim=1)
    for b in range(2):
        row = int(np.flatnonzero(np.all(plans[b].numpy() == pricey.power_w[b].astype(np.float32), axis=1))[0])
        first_row = int(np.flatnonzero(np.all(plans[b].numpy() == first.power_w[b].astype(np.float32), axis=1))[0])
        # A price on the first 8 intervals never raises the energy the model delivers there.
        assert kwh[b, row, :8].sum() <= kwh[b, first_row, :8].sum() + 1e-6
    planner.commit(pricey)
    planner.observe(observations, forecast)
    planner.plan()
    assert solves == [None, None]


def test_cem_re_plans_solve_the_rc_candidates_under_each_price(fleet_models):
    planner, solves, *_ = _observed_candidate_planner(fleet_models, replan_iters=2, rc_refresh=1)
    planner.plan()
    planner.plan(np.full(planner.horizon_steps, 0.5))
    assert solves == [None, None] and planner._pool == []


def test_rc_candidates_refreshed_in_turn_keep_each_buildings_last_plan_shifted(fleet_models):
    planner, solves, _, observations, forecast = _observed_candidate_planner(fleet_models, rc_refresh=2)
    plan = planner.plan()
    assert [m.tolist() for m in solves] == [[True, False]]
    assert planner._rc_valid.tolist() == [True, False]
    kept = planner._rc_plans[0].copy()
    planner.commit(plan)
    planner.observe(observations, forecast)
    planner.plan()
    assert [m.tolist() for m in solves] == [[True, False], [False, True]]
    np.testing.assert_array_equal(planner._rc_plans[0, :-1], kept[1:])  # building 0's, shifted
    assert planner._rc_valid.all()
    with pytest.raises(InputError, match="rc_refresh must be a whole number >= 1"):
        _observed_candidate_planner(fleet_models, rc_refresh=0)
