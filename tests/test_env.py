"""The Gymnasium environment: API checker, reward = minus the shared objective, seeding."""

import warnings

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from pinn_mpc.simulator import Simulator
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.gym_env import OBSERVATION_NAMES, BuildingEnv


def make_env(episode_steps=48, name="winter_household"):
    scenario = get_scenario(name)
    return scenario, BuildingEnv(
        scenario.sim,
        scenario.exogenous(days=2, seed=0, part="train"),
        comfort_weight_eur_per_kh=scenario.comfort_weight_eur_per_kh,
        episode_steps=episode_steps,
        initial_t_r_c=scenario.initial_t_r_c,
        initial_t_m_c=scenario.initial_t_m_c,
    )


def test_passes_the_gymnasium_checker():
    _, env = make_env()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    # [0, u_max] W is the physical action range; only the normalisation hint may be raised.
    others = [str(w.message) for w in caught if "symmetric and normalized" not in str(w.message)]
    assert others == []
    assert env.observation_space.shape == (len(OBSERVATION_NAMES),)


def test_reward_is_minus_cost_plus_weighted_discomfort_and_matches_the_simulator():
    scenario, env = make_env()
    obs, info = env.reset(seed=1, options={"start": 10})
    exo = scenario.exogenous(days=2, seed=0, part="train")
    sim = Simulator(scenario.sim, n_buildings=1)
    sim.reset(scenario.initial_t_r_c, scenario.initial_t_m_c)
    assert obs[1] == pytest.approx(exo["T_a"][10], abs=1e-5)
    actions = np.random.default_rng(0).uniform(0, scenario.sim.u_max_w, size=48)
    for k, u in enumerate(actions):
        row = exo.iloc[10 + k]
        obs, reward, terminated, truncated, info = env.step(np.array([u], dtype=np.float32))
        ref = sim.step(float(np.float32(u)), row["T_a"], row["G"], row["I_g"])
        t_r = ref.t_r_c[0]
        assert info["T_r"] == pytest.approx(t_r) and info["T_m"] == pytest.approx(ref.t_m_c[0])
        assert info["u_phys"] == pytest.approx(ref.u_phys_w[0])
        violation = max(row["T_min"] - t_r, 0) + max(t_r - row["T_max"], 0)
        expected = -(row["price"] * ref.u_phys_w[0] / 1000 * 0.5 + 5.0 * violation * 0.5)
        assert reward == pytest.approx(expected, rel=1e-9, abs=1e-12)
        assert not terminated and truncated == (k == 47)
    with pytest.raises(ValueError, match="episode is over"):
        env.step(np.array([0.0], dtype=np.float32))


def test_seeded_reset_is_reproducible_and_draws_the_start():
    _, env = make_env(episode_steps=12)
    first, _ = env.reset(seed=7)
    again, _ = env.reset(seed=7)
    np.testing.assert_array_equal(first, again)
    clocks = {tuple(env.reset(seed=s)[0][-2:]) for s in range(10)}
    assert len(clocks) > 3


def test_actions_are_clipped_and_bad_input_rejected():
    scenario, env = make_env(name="cold_storage")
    env.reset(seed=0, options={"start": 0, "t_r_c": 5.0, "t_m_c": 5.0})
    *_, info = env.step(np.array([1e9], dtype=np.float32))
    assert info["u_phys"] <= scenario.sim.u_max_w
    with pytest.raises(ValueError, match="unknown option"):
        env.reset(options={"temperature": 3})
    with pytest.raises(ValueError, match="lacks column"):
        BuildingEnv(scenario.sim, scenario.exogenous(days=1, seed=0, part="train").drop(columns="price"),
                    comfort_weight_eur_per_kh=1.0)
    with pytest.raises(ValueError, match="episode_steps=100"):
        BuildingEnv(scenario.sim, scenario.exogenous(days=1, seed=0, part="train"), comfort_weight_eur_per_kh=1.0,
                    episode_steps=100)


@pytest.mark.parametrize(
    ("action", "match"),
    [
        (np.array([1000.0, 0.0, 0.0], dtype=np.float32), "has 3 elements"),
        (np.array([], dtype=np.float32), "has 0 elements"),
        (np.array([np.nan], dtype=np.float32), "not finite"),
        ("warm", "not a number"),
    ],
)
def test_a_malformed_action_is_refused_naming_the_action_space(action, match):
    _, env = make_env(episode_steps=4)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)


@pytest.mark.parametrize("value", [float("nan"), 500.0, -100.0, float("inf")])
def test_an_implausible_start_temperature_is_refused(value):
    _, env = make_env(episode_steps=4)
    with pytest.raises(ValueError, match=r"t_r_c=.* must be a finite temperature in \[-60, 90\] C"):
        env.reset(seed=0, options={"t_r_c": value})
    scenario = get_scenario("winter_household")
    with pytest.raises(ValueError, match=r"initial_t_m_c=.* must be a finite temperature"):
        BuildingEnv(scenario.sim, scenario.exogenous(days=1, seed=0, part="train"),
                    comfort_weight_eur_per_kh=1.0, initial_t_m_c=value)


@pytest.mark.parametrize("start", [2.5, 3.0, "4", True])
def test_a_start_row_must_be_a_whole_number(start):
    _, env = make_env(episode_steps=4)
    with pytest.raises(ValueError, match="must be a whole row number"):
        env.reset(seed=0, options={"start": start})
    observation, _ = env.reset(seed=0, options={"start": np.int64(3)})
    assert env._loop.start == 3 and np.all(np.isfinite(observation))
