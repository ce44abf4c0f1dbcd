"""Sampling planners on objectives whose minimiser is known in closed form."""

import math

import pytest
import torch

from controllers.planners import CEMPlanner, RandomShootingPlanner, colored_noise, move_blocks

H = 8


def _gen(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def _quadratic(target: torch.Tensor):
    """sum_j (u_j - target_j)^2 over [0, 1]^H: minimiser clip(target, 0, 1)."""

    def objective(u: torch.Tensor) -> torch.Tensor:
        return ((u - target) ** 2).sum(dim=1)

    return objective


def _linear(weights: torch.Tensor):
    """sum_j w_j u_j over {0, 1}^H: on exactly where w_j < 0."""

    def objective(u: torch.Tensor) -> torch.Tensor:
        return (u * weights).sum(dim=1)

    return objective


TARGET = torch.tensor([0.2, 0.9, -0.5, 0.5, 1.7, 0.35, 0.0, 0.65])
WEIGHTS = torch.tensor([1.0, -2.0, 0.5, -0.1, -3.0, 0.2, 0.05, -0.4])


def test_cem_finds_the_clipped_minimiser_of_a_quadratic():
    planner = CEMPlanner(lower=0.0, upper=1.0, n_samples=200, n_iters=25, noise_beta=0.0)
    result = planner.optimize(_quadratic(TARGET), torch.full((H,), 0.5), _gen())
    expected = TARGET.clamp(0.0, 1.0)
    assert torch.max(torch.abs(result.plan - expected)) < 0.02
    assert result.cost == pytest.approx(float(_quadratic(TARGET)(result.plan[None])[0]), rel=1e-6)
    assert result.iterations == 25 and result.n_evaluated == 25 * 200


@pytest.mark.parametrize("beta", [0.0, 2.0])
def test_cem_respects_bounds_and_never_returns_worse_than_the_warm_start(beta):
    x0 = TARGET.clamp(0.0, 1.0) + 0.01  # nearly optimal warm start
    x0 = x0.clamp(0.0, 1.0)
    planner = CEMPlanner(lower=0.0, upper=1.0, n_samples=50, n_iters=2, noise_beta=beta)
    result = planner.optimize(_quadratic(TARGET), x0, _gen())
    assert float(result.plan.min()) >= 0.0 and float(result.plan.max()) <= 1.0
    assert result.cost <= float(_quadratic(TARGET)(x0[None])[0])


def test_more_cem_iterations_never_cost_more():
    # The first iterations draw the same numbers and the best-so-far is kept.
    costs = [
        CEMPlanner(lower=0.0, upper=1.0, n_samples=40, n_iters=n)
        .optimize(_quadratic(TARGET), torch.full((H,), 0.5), _gen(3))
        .cost
        for n in (1, 2, 4, 8)
    ]
    assert costs == sorted(costs, reverse=True)
    assert costs[-1] < costs[0]


def test_binary_cem_finds_the_exact_on_off_optimum():
    planner = CEMPlanner(lower=0.0, upper=1.0, n_samples=100, n_iters=10, binary=True)
    result = planner.optimize(_linear(WEIGHTS), torch.zeros(H), _gen())
    assert torch.equal(result.plan, (WEIGHTS < 0).to(torch.float32))


def test_binary_random_shooting_plans_are_on_off_and_no_worse_than_warm_start():
    planner = RandomShootingPlanner(lower=0.0, upper=5000.0, n_samples=64, binary=True)
    x0 = torch.full((H,), 4000.0)  # snapped to "on"
    result = planner.optimize(_linear(WEIGHTS), x0, _gen())
    assert set(result.plan.tolist()) <= {0.0, 5000.0}
    assert result.cost <= float((WEIGHTS * 5000.0).sum())
    assert result.iterations == 1 and result.n_evaluated == 64


def test_random_shooting_with_many_samples_approaches_the_optimum_and_stays_in_bounds():
    planner = RandomShootingPlanner(lower=0.0, upper=1.0, n_samples=4000)
    result = planner.optimize(_quadratic(TARGET), torch.full((H,), 0.5), _gen())
    optimum = float(_quadratic(TARGET)(TARGET.clamp(0, 1)[None])[0])
    x0_cost = float(_quadratic(TARGET)(torch.full((1, H), 0.5))[0])
    assert float(result.plan.min()) >= 0.0 and float(result.plan.max()) <= 1.0
    assert optimum < result.cost < x0_cost


@pytest.mark.parametrize(
    "planner",
    [
        CEMPlanner(lower=0.0, upper=1.0, n_samples=30, n_iters=3),
        CEMPlanner(lower=0.0, upper=1.0, n_samples=30, n_iters=3, binary=True),
        RandomShootingPlanner(lower=0.0, upper=1.0, n_samples=30),
    ],
)
def test_same_generator_seed_same_plan(planner):
    runs = [planner.optimize(_quadratic(TARGET), torch.full((H,), 0.5), _gen(7)) for _ in range(2)]
    assert torch.equal(runs[0].plan, runs[1].plan)
    if not planner.binary:  # (binary runs may both reach the unique on/off optimum)
        other = planner.optimize(_quadratic(TARGET), torch.full((H,), 0.5), _gen(8))
        assert not torch.equal(runs[0].plan, other.plan)


def test_non_finite_costs_rank_last():
    def objective(u: torch.Tensor) -> torch.Tensor:
        cost = ((u - 1.0) ** 2).sum(dim=1)
        return torch.where(u[:, 0] > 0.5, torch.nan, cost)  # the unconstrained optimum is NaN

    result = CEMPlanner(lower=0.0, upper=1.0, n_samples=50, n_iters=5).optimize(
        objective, torch.full((H,), 0.2), _gen()
    )
    assert float(result.plan[0]) <= 0.5 and math.isfinite(result.cost)


def test_all_non_finite_costs_give_an_infinite_result_cost():
    result = RandomShootingPlanner(lower=0.0, upper=1.0, n_samples=10).optimize(
        lambda u: torch.full((u.shape[0],), torch.nan), torch.zeros(H), _gen()
    )
    assert result.cost == math.inf


def test_colored_noise_is_unit_variance_and_correlated_in_time():
    white = colored_noise(4000, 48, 0.0, _gen(), torch.float64)
    pink = colored_noise(4000, 48, 2.0, _gen(), torch.float64)
    for noise in (white, pink):
        assert torch.allclose(noise.std(dim=0), torch.ones(48, dtype=torch.float64), atol=0.06)

    def lag1(x: torch.Tensor) -> float:
        return float(torch.corrcoef(torch.stack([x[:, 10], x[:, 11]]))[0, 1])

    assert abs(lag1(white)) < 0.05
    assert lag1(pink) > 0.8


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"lower": 1.0, "upper": 0.0}, "lower < upper"),
        ({"lower": 0.0, "upper": 1.0, "n_samples": 1}, "n_samples must be >= 2"),
        ({"lower": 0.0, "upper": 1.0, "n_iters": 0}, "n_iters must be >= 1"),
        ({"lower": 0.0, "upper": 1.0, "elite_frac": 0.0}, "elite_frac must lie in"),
        ({"lower": 0.0, "upper": 1.0, "alpha": 1.0}, "alpha must lie in"),
        ({"lower": 0.0, "upper": 1.0, "noise_beta": -1.0}, "noise_beta must be"),
    ],
)
def test_invalid_settings_are_rejected_with_a_clear_message(kwargs, message):
    with pytest.raises(ValueError, match=message):
        CEMPlanner(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"local_frac": 1.5}, "local_frac must lie in"),
        ({"local_std_fracs": ()}, "local_std_fracs must be positive"),
        ({"local_std_fracs": (0.1, -0.1)}, "local_std_fracs must be positive"),
        ({"noise_beta": 5.0}, "RandomShootingPlanner.noise_beta must be"),
    ],
)
def test_invalid_random_shooting_settings_are_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        RandomShootingPlanner(lower=0.0, upper=1.0, **kwargs)


@pytest.mark.parametrize(("x0_value", "p_on"), [(0.0, 0.25), (0.5, 0.5), (1.0, 0.75)])
def test_binary_cem_starts_between_a_fair_coin_and_the_warm_start(x0_value, p_on) -> None:
    seen: list[torch.Tensor] = []

    def objective(u: torch.Tensor) -> torch.Tensor:
        seen.append(u.clone())
        return torch.zeros(u.shape[0])

    planner = CEMPlanner(lower=0.0, upper=1.0, n_samples=2000, n_iters=1, binary=True)
    planner.optimize(objective, torch.full((H,), x0_value), _gen())
    drawn = seen[0][1:]  # row 0 is the (snapped) warm start itself
    assert float(drawn.mean()) == pytest.approx(p_on, abs=0.02)  # 16000 draws: 4 sigma


def test_move_blocks_double_every_two_blocks_and_cover_the_horizon():
    assert move_blocks(48).tolist() == [
        0, 1, *[2] * 2, *[3] * 2, *[4] * 4, *[5] * 4, *[6] * 8, *[7] * 8, *[8] * 16, *[9] * 2
    ]
    assert move_blocks(1).tolist() == [0]


def test_random_shooting_samples_stay_in_bounds_and_centre_on_the_warm_start():
    seen = []

    def objective(u):
        seen.append(u.clone())
        return (u - 0.7).pow(2).sum(1)

    x0 = torch.full((24,), 0.9)
    planner = RandomShootingPlanner(lower=0.0, upper=1.0, n_samples=101, local_frac=0.5)
    result = planner.optimize(objective, x0, torch.Generator().manual_seed(0))
    (batch,) = seen
    assert batch.shape == (101, 24) and bool(((batch >= 0) & (batch <= 1)).all())
    torch.testing.assert_close(batch[0], x0)
    local, blocked = batch[1:51], batch[51:]
    # The smallest scale (1 % of the range) stays next to the warm start; the blocked samples
    # are constant over each block.
    assert float((local[:17] - x0).abs().max()) < 0.1
    blocks = move_blocks(24)
    for b in range(int(blocks[-1]) + 1):
        cols = blocked[:, blocks == b]
        torch.testing.assert_close(cols, cols[:, :1].expand_as(cols))
    assert result.cost == pytest.approx(float(objective(result.plan[None])[0]))
    assert result.cost <= float((x0 - 0.7).pow(2).sum())


def test_copying_or_pickling_a_planners_generator_keeps_nones_reference_count() -> None:
    """torch's ``Generator.__reduce__`` takes a reference from ``None`` each call
    (pytorch/pytorch#188032): a capped fleet that copies its controllers every step aborted
    at exit with ``none_dealloc``. With :mod:`pinn_mpc.torch_generator` registered (the
    planners import it), 2000 copies and pickles leave ``None``'s count where it was, and
    every copy draws what the original draws."""
    import copy
    import gc
    import pickle
    import sys

    generator = torch.Generator().manual_seed(123)
    torch.rand(5, generator=generator)  # a state past the seed
    gc.collect()
    before = sys.getrefcount(None)
    for _ in range(1000):
        copied = copy.deepcopy(generator)
        unpickled = pickle.loads(pickle.dumps(generator))
        del copied, unpickled
    gc.collect()
    assert abs(sys.getrefcount(None) - before) < 100  # the bug: 2000 fewer

    copied, unpickled = copy.deepcopy(generator), pickle.loads(pickle.dumps(generator))
    assert copied.initial_seed() == unpickled.initial_seed() == 123
    expected = torch.rand(8, generator=generator)
    assert torch.equal(torch.rand(8, generator=copied), expected)
    assert torch.equal(torch.rand(8, generator=unpickled), expected)
