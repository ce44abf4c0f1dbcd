"""A fleet of learned hybrids planned in one batch: the batched rollout and CEM against the
per-building ones, and the batched CEM in closed loop (with and without a cap)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from controllers.planners import CEMPlanner
from pinn_mpc import TrainConfig, train_model
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.models.fleet import FEW_PLANS, FleetModels
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
    batched = FleetModels(models).rollout([o.history for o in observations], u, exog)
    first = FleetModels(models, members=1).rollout([o.history for o in observations], u, exog)
    for i, model in enumerate(models):
        own = model.rollout(observations[i].history, u[i], exog)
        assert batched.t_r_c[i].shape == own.t_r_c.shape == (3, 9, h, 1)
        # One recursion (roll_states) for both: only the preparation's round-off differs.
        torch.testing.assert_close(batched.t_r_c[i], own.t_r_c, atol=1e-4, rtol=0)
        torch.testing.assert_close(batched.u_phys_w[i], own.u_phys_w, atol=0.05, rtol=0)
        torch.testing.assert_close(batched.t_m_c[i], own.t_m_c, atol=1e-4, rtol=0)
        torch.testing.assert_close(first.t_r_c[i], own.t_r_c[:1], atol=1e-4, rtol=0)
    # A rollout of a few plans (FEW_PLANS: the first layer row by row) is the same rollout.
    for n in (1, FEW_PLANS):
        few = FleetModels(models).rollout([o.history for o in observations], u[:, :n], exog)
        torch.testing.assert_close(few.t_r_c, batched.t_r_c[:, :, :n], atol=1e-4, rtol=0)
        torch.testing.assert_close(few.u_phys_w, batched.u_phys_w[:, :, :n], atol=0.05, rtol=0)
    # The two buildings' models differ: a mixed-up batch would not pass the comparison.
    assert (batched.t_r_c[0] - batched.t_r_c[1]).abs().max() > 0.05


def test_batched_cem_equals_the_cem_planner_building_by_building(fleet_models):
    scenario, fleet, models = fleet_models
    observations, forecast = _observations(scenario, fleet)
    h = 24
    exog = forecast.exogenous(models[0].exog_names, h)
    planner = CEMPlanner(lower=0.0, upper=scenario.sim.u_max_w, n_samples=16, n_iters=3)
    target = torch.linspace(20.0, 21.5, h)

    def cost(i: int, u: torch.Tensor) -> torch.Tensor:  # (N, H) -> (N,)
        roll = models[i].rollout(observations[i].history, u, exog)
        return (roll.t_r_c[..., 0].mean(0) - target).abs().sum(-1) + 1e-4 * roll.u_phys_w.mean(0).sum(-1)

    x0 = torch.full((2, h), 3000.0)
    seeds = (5, 7)
    plans, costs = planner.optimize_batch(
        lambda u: torch.stack([cost(i, u[i]) for i in range(2)]), x0,
        [torch.Generator().manual_seed(s) for s in seeds],
    )
    for i, s in enumerate(seeds):  # one building's plan is the single planner's, bit for bit
        alone = planner.optimize(lambda u, i=i: cost(i, u), x0[i], torch.Generator().manual_seed(s))
        assert torch.equal(plans[i], alone.plan)
        assert float(costs[i]) == alone.cost


def test_a_candidate_plan_is_scored_and_kept_unless_a_sample_beats_it():
    planner = CEMPlanner(lower=0.0, upper=10.0, n_samples=8, n_iters=2)
    h = 6
    target = torch.tensor([[1.0, 9.0, 2.0, 8.0, 3.0, 7.0], [5.0, 5.0, 0.0, 0.0, 10.0, 10.0]])

    def cost(u: torch.Tensor) -> torch.Tensor:  # (B, N, H) -> (B, N)
        return (u - target[:, None]).abs().sum(-1)

    x0 = torch.full((2, h), 5.0)
    generators = lambda: [torch.Generator().manual_seed(s) for s in (1, 2)]  # noqa: E731
    without, _ = planner.optimize_batch(cost, x0, generators())
    assert float(cost(without[:, None]).max()) > 1.0  # two iterations of 8 samples do not find it
    plans, costs = planner.optimize_batch(cost, x0, generators(), candidates=target[:, None])
    torch.testing.assert_close(plans, target)
    assert float(costs.max()) == 0.0
    with pytest.raises(InternalError, match="candidates must be"):
        planner.optimize_batch(cost, x0, generators(), candidates=torch.zeros(2, 7, h))


def test_more_members_than_the_ensembles_have_are_refused(fleet_models):
    _, _, models = fleet_models
    with pytest.raises(ValueError, match="members must lie in 1..3"):
        FleetModels(models, members=4)


def _keeps_comfort_and_a_cap(scenario, fleet, models, discomfort_kh: float, **options) -> None:
    """The batched cem over ``models`` (one per building of ``fleet``; ``options`` of
    ``learned_fleet_planner``) free and under a cap of 60 % of its free peak in an evening
    window: comfort within ``discomfort_kh`` per building a day, no fallback, and the cap held."""
    free = run_coordinated_fleet(
        scenario, learned_fleet_planner(models, **options), n_buildings=len(fleet), days=1,
        seed=COLD_SEED, fleet=fleet,
    )
    assert free.info["controller"] == "cem" and free.totals["fallbacks"] == 0
    assert free.totals["discomfort_kh"] / len(fleet) < discomfort_kh
    assert all("model_fallback_steps" in k for k in free.kpis)
    window = "17:00-19:00"
    in_window = ~np.isnan(cap_in_force(free.times, {"kw": 1.0, "window": window}))
    cap_kw = 0.6 * free.aggregate_u_phys_w[in_window].max() / 1000.0
    capped = run_coordinated_fleet(
        scenario, learned_fleet_planner(models, **options), n_buildings=len(fleet), days=1,
        seed=COLD_SEED, fleet=fleet, cap_kw=cap_kw, cap_window=window,
    )
    assert capped.cap is not None and capped.cap["intervals"] == 4
    assert capped.cap["intervals_over"] == 0
    assert np.all(capped.aggregate_u_phys_w[in_window] <= cap_kw * 1000.0 + 1.0)


@pytest.mark.slow
def test_batched_cem_over_learned_models_keeps_comfort_and_a_cap(fleet_models):
    _keeps_comfort_and_a_cap(*fleet_models, discomfort_kh=1.0)


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
    with pytest.raises(ValueError, match="rc_refresh must be a whole number >= 1"):
        _observed_candidate_planner(fleet_models, rc_refresh=0)


@pytest.fixture(scope="module")
def other_families():
    """Two buildings of a spread fleet, each with a physics-informed ARX and with a small
    PhysNet from 5 days of its own data."""
    from pinn_mpc.models.arx import fit_linear

    scenario = get_scenario("winter_household")
    fleet = draw_fleet(scenario.sim.params, 2, spread=0.2, rng=np.random.default_rng(0))
    data = generate(scenario, days=5, seed=0, policy="random-level", n_buildings=2, fleet=fleet)
    frames = [part.drop(columns=["building", "T_m"]).reset_index(drop=True) for _, part in data.groupby("building")]
    config = TrainConfig(n_seeds=2, epochs=8, eta=scenario.sim.params.eta, u_max_w=scenario.sim.u_max_w)
    return scenario, fleet, {
        "parx": [fit_linear("parx", frame) for frame in frames],
        "physnet": [train_model(frame, arch="physnet", config=config, progress=False) for frame in frames],
    }


@pytest.mark.parametrize("family", ["parx", "physnet"])
def test_a_fleet_of_any_family_rolls_out_as_each_building_model(other_families, family):
    """Buildings whose models do not stack roll out through their own models' rollouts, so
    each building's rollout is its model's exactly; a mixed fleet keeps the building order."""
    scenario, fleet, families = other_families
    models = families[family]
    observations, forecast = _observations(scenario, fleet)
    h = 24
    fleet_models = FleetModels([*models, families["physnet" if family == "parx" else "parx"][0]], members=1)
    exog = forecast.exogenous(fleet_models.exog_names, h)
    u = torch.rand((3, 5, h), generator=torch.Generator().manual_seed(0)) * scenario.sim.u_max_w
    histories = [o.history for o in observations]
    roll = fleet_models.rollout([*histories, histories[0]], u, exog)
    assert roll.t_r_c.shape == (3, 1, 5, h, 1)
    for i, model in enumerate([*models, fleet_models.models[2]]):
        own = model.rollout(histories[i % 2], u[i], {n: exog[n] for n in model.exog_names})
        assert torch.equal(roll.t_r_c[i], own.t_r_c[:1].to(roll.t_r_c.dtype))
        assert torch.equal(roll.u_phys_w[i], own.u_phys_w[:1].to(roll.u_phys_w.dtype))


@pytest.mark.parametrize("family", ["hybrid", "parx", "physnet"])
def test_a_one_building_fleet_decides_as_the_single_cem(fleet_models, other_families, family):
    """The batched cem of one building (no polish, no RC fallback: what the fleet does not
    batch) makes the single cem's decisions, step for step in closed loop: one planner
    (:meth:`CEMPlanner.optimize_batch`), one rollout (a fleet of one building is its model),
    one offset filter and objective."""
    from controllers.fleet_sampling import FleetCEM
    from controllers.sampling import CEM

    scenario, fleet, families = other_families
    model = fleet_models[2][0] if family == "hybrid" else families[family][0]
    spec = scenario.control_spec()
    single = CEM(model, spec, n_samples=24, n_iters=2, polish_iters=0)
    batched = FleetCEM(FleetModels([model]), spec, planner=single.planner)
    single.reset(3)
    batched.reset(3)
    batched.generators[0].manual_seed(3)
    run = prepare_run(scenario, days=1, seed=COLD_SEED, warmup_steps=12, weather_part="test")
    loop = build_loop(scenario, run, seed=0, fleet=fleet[:1])
    rng = np.random.default_rng(1)
    decisions = []
    for k in range(30):
        obs, forecast = loop.observation(building=0), loop.forecast()
        u = single.act(obs, forecast)
        batched.observe([obs], forecast)
        decision = batched.commit(batched.plan())
        decisions.append((u, float(decision.u_w[0]), single.last_stats.fallback, bool(decision.fallback[0])))
        applied = rng.uniform(0, spec.u_max_w) if k < 12 else u  # a varied history first
        loop.step(np.array([applied]), decision_s=np.zeros(1), fallback=np.zeros(1, dtype=bool))
    assert sum(not fell for *_, fell, _ in decisions) >= 8  # the model planned most steps
    for u_single, u_fleet, fell_single, fell_fleet in decisions:
        assert (u_fleet, fell_fleet) == (u_single, fell_single)


@pytest.mark.slow
@pytest.mark.parametrize("family", ["parx", "physnet"])
def test_a_fleet_of_physics_informed_arx_or_physnet_buildings_keeps_a_cap(other_families, family):
    """A fleet of the other families runs as a fleet of hybrids does, free and under a cap. The
    models drive: a PhysNet of a few epochs on 5 days is rightly distrusted by its guard (its
    two members disagree by more than the limit), whose RC MPC would decide every step, so
    the PhysNet fleet plans without the RC fallback."""
    scenario, fleet, families = other_families
    options = {"rc_fallback": family != "physnet"}
    _keeps_comfort_and_a_cap(scenario, fleet, families[family], discomfort_kh=1.0, **options)
