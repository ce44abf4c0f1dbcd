"""Data generation: format, policies, batched buildings, thermostat behaviour."""

import numpy as np
import pandas as pd
import pytest

from controllers.base import ControlSpec, Forecast, Observation
from controllers.thermostat import Thermostat
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.data import validate_timeseries
from pinn_mpc.simulator import Simulator
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate


def test_random_policy_frame_is_valid_and_seeded():
    scenario = get_scenario("paper_household")
    frame = generate(scenario, days=4, seed=1)
    assert len(frame) == 4 * 48 and frame.attrs["dt_s"] == 1800
    assert {"time", "T_r", "T_m", "u", "u_phys", "T_a", "price", "T_min", "T_max"} == set(frame)
    validate_timeseries(frame)
    assert set(np.unique(frame["u"])) == {0.0, 5000.0}
    assert np.all((frame["u_phys"] >= 0) & (frame["u_phys"] <= 5000))
    assert frame["T_r"].iloc[0] == 17.0 and frame["T_m"].iloc[0] == 17.0
    pd.testing.assert_frame_equal(frame, generate(scenario, days=4, seed=1))


def test_on_probability_sets_the_share_of_full_power_demands():
    frame = generate(get_scenario("paper_household"), days=20, seed=2, on_probability=0.2)
    share = np.mean(frame["u"] == 5000.0)
    assert abs(share - 0.2) < 4 * np.sqrt(0.2 * 0.8 / len(frame))


def test_random_level_policy_draws_uniform_demands_over_the_range():
    scenario = get_scenario("paper_household")
    frame = generate(scenario, days=20, seed=3, policy="random-level", n_buildings=2)
    u = frame["u"].to_numpy()
    assert np.all((u >= 0) & (u <= 5000)) and len(np.unique(u)) == len(u)
    # Uniform on [0, 5000]: a fifth of the draws in each fifth of the range.
    counts = np.histogram(u, bins=5, range=(0, 5000))[0]
    expected = len(u) / 5
    assert np.all(np.abs(counts - expected) < 4 * np.sqrt(expected))
    pd.testing.assert_frame_equal(
        frame, generate(scenario, days=20, seed=3, policy="random-level", n_buildings=2)
    )


def test_batched_buildings_equal_single_simulations_of_their_demands():
    scenario = get_scenario("winter_household")
    frame = generate(scenario, days=2, seed=3, n_buildings=3)
    assert list(frame.columns[:2]) == ["building", "time"]
    assert len(frame) == 3 * 96 and list(np.unique(frame["building"])) == [0, 1, 2]
    assert {"G", "I_g"} <= set(frame)
    one = frame[frame["building"] == 1].reset_index(drop=True)
    assert not np.array_equal(one["u"], frame[frame["building"] == 0]["u"])
    sim = Simulator(scenario.sim, n_buildings=1)
    sim.reset(scenario.initial_t_r_c, scenario.initial_t_m_c)
    for k in range(len(one) - 1):
        result = sim.step(one["u"][k], one["T_a"][k], one["G"][k], one["I_g"][k])
        assert result.u_phys_w[0] == pytest.approx(one["u_phys"][k], abs=1e-9)
        assert result.t_r_c[0] == pytest.approx(one["T_r"][k + 1], abs=1e-9)
        assert result.t_m_c[0] == pytest.approx(one["T_m"][k + 1], abs=1e-9)


def test_cold_storage_stays_near_its_band_under_the_thermostat():
    frame = generate(get_scenario("cold_storage"), days=6, seed=0, policy="thermostat")
    t_r = frame["T_r"].to_numpy()[48:]  # after a day's settling
    assert 1.0 < t_r.min() and t_r.max() < 7.5
    assert np.mean((t_r >= 2.0) & (t_r <= 6.0)) > 0.85
    assert 0.1 < np.mean(frame["u"] > 0) < 0.9  # it really switches


def test_thermostat_switches_with_hysteresis_for_heating_and_cooling():
    def act(controller, t_r_c):
        band = np.full(1, 20.0), np.full(1, 24.0)
        forecast = Forecast(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), *band)
        return controller.act(Observation(k=0, t_r_c=t_r_c, history={}, t_m_true_c=0.0), forecast)

    heater = Thermostat(ControlSpec(actuators=(ActuatorSpec(upper_w=100.0),)), offset_fraction=0.25, hysteresis_k=0.5)
    # Centre 21 C: on below 20.75, off above 21.25, memory in between.
    assert [act(heater, t) for t in (21.0, 20.7, 21.0, 21.3, 21.0)] == [0, 100, 100, 0, 0]
    cooler = Thermostat(ControlSpec(actuators=(ActuatorSpec(upper_w=100.0, heats=False),)))
    assert [act(cooler, t) for t in (23.0, 23.3, 23.0, 22.7, 23.0)] == [0, 100, 100, 0, 0]
    cooler.reset()
    assert act(cooler, 23.0) == 0 and cooler.last_stats.status == "rule"
    assert cooler.last_plan is not None and cooler.last_plan.shape == (1,)


def test_generate_rejects_bad_arguments():
    scenario = get_scenario("paper_household")
    with pytest.raises(ValueError, match="unknown policy 'bangbang'; choose one of: random"):
        generate(scenario, days=1, seed=0, policy="bangbang")
    with pytest.raises(ValueError, match="on_probability"):
        generate(scenario, days=1, seed=0, on_probability=1.5)


def test_batched_thermostat_policy_makes_the_controllers_decisions():
    scenario = get_scenario("winter_household")
    frame = generate(scenario, days=2, seed=4, policy="thermostat")
    controller = Thermostat(scenario.control_spec())
    controller.reset(0)
    for row in frame.itertuples():
        band = np.array([row.T_min]), np.array([row.T_max])
        forecast = Forecast(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), *band)
        obs = Observation(k=row.Index, t_r_c=row.T_r, history={}, t_m_true_c=row.T_m)
        assert controller.act(obs, forecast) == row.u
    assert 0 < np.mean(frame["u"] > 0) < 1


def test_closed_loop_policy_tracks_random_setpoints_inside_the_backup_band():
    """Random setpoints from the comfort band widened by 1 K, tracked by a proportional
    controller with a dither: the room stays where a controller keeps it (the backup acts in
    1 % of the intervals, 44 % under random levels), the power still takes levels across its
    range, and the frame is seeded."""
    from scenarios.running.datagen import SetpointPolicy

    scenario = get_scenario("winter_household")
    frame = generate(scenario, days=14, seed=4, policy="closed-loop")
    validate_timeseries(frame)
    backup = np.mean(~np.isclose(frame["u"], frame["u_phys"]))
    levels = generate(scenario, days=14, seed=4, policy="random-level")
    assert backup < 0.03 and backup < 0.1 * np.mean(~np.isclose(levels["u"], levels["u_phys"]))
    low, high = frame["T_min"].min() - 1.0, frame["T_max"].max() + 1.0
    assert frame["T_r"].between(low - 1.0, high + 1.0).all()
    u = frame["u"].to_numpy() / scenario.sim.u_max_w
    inside = u[(u > 0) & (u < 1)]
    assert len(inside) > 0.3 * len(u)
    assert np.histogram(inside, bins=5, range=(0, 1))[0].min() > 0.03 * len(inside)
    pd.testing.assert_frame_equal(frame, generate(scenario, days=14, seed=4, policy="closed-loop"))
    policy = SetpointPolicy.for_data(ActuatorSpec(upper_w=1000.0), np.array([20.0]), np.array([22.0]), 1800.0)
    setpoints = policy.setpoints(np.random.default_rng(0).random((500, 3)))
    assert setpoints.min() >= 19.0 and setpoints.max() <= 23.0
    holds = np.diff(np.flatnonzero(np.diff(setpoints) != 0))
    assert holds.min() >= 2 and holds.max() <= 16  # 1-8 h at 30 min
    assert policy.demand(np.array([15.0, 25.0]), 21.0, np.array([0.0, 0.0, 0.5])).tolist() == [1000.0, 0.0]


def test_scenarios_say_which_policy_their_training_data_takes(tmp_path):
    """EnergyPlus scenarios train on closed-loop data by default, the RC ones on random
    levels; simulate without --policy takes the scenario's."""
    from pinn_mpc.data import read_timeseries
    from pinn_mpc_cli.cli import main

    assert get_scenario("eplus_small_office").data_policy == "closed-loop"
    assert get_scenario("eplus_midrise_apartment").data_policy == "closed-loop"
    assert get_scenario("winter_household").data_policy == "random-level"
    out = tmp_path / "d.csv"
    assert main(["simulate", "--scenario", "winter_household", "--days", "2", "--out", str(out)]) == 0
    expected = generate(get_scenario("winter_household"), days=2, seed=0, policy="random-level")
    assert np.allclose(read_timeseries(out)["u"], expected["u"])
