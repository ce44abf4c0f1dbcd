"""Scenario registry and exogenous inputs: real TMY3 values, resampling, schedules, seeds."""

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.errors import InputError
from pinn_mpc.physics import steady_state
from scenarios.inputs.exogenous import (
    HOURS_PER_TYPICAL_YEAR,
    PriceProfile,
    load_tmy3,
    resample_typical_year,
    time_of_day_h,
)
from scenarios.inputs.registry import EXOGENOUS_COLUMNS, scenario_names
from scenarios.inputs.scenario_file import get_scenario

NAMES = ("paper_household", "winter_household", "cold_storage")


def test_registry_lists_the_three_scenarios_and_rejects_unknown_names():
    assert set(NAMES) <= set(scenario_names())
    with pytest.raises(InputError, match="unknown scenario 'nope'.*cold_storage.*paper_household"):
        get_scenario("nope")


@pytest.mark.parametrize("part", ["train", "test", "whole"])
@pytest.mark.parametrize("name", NAMES)
def test_exogenous_shape_determinism_and_lead_rows(name, part):
    scenario = get_scenario(name)
    frame = scenario.exogenous(days=2, seed=5, part=part, lead_steps=10)
    assert list(frame.columns) == list(EXOGENOUS_COLUMNS)
    assert len(frame) == 2 * 48 + 10
    steps = np.diff(frame["time"].to_numpy()).astype("timedelta64[s]").astype(int)
    assert np.all(steps == 1800)
    assert np.all(np.isfinite(frame.drop(columns="time").to_numpy()))
    assert np.all(frame["G"] >= 0) and np.all(frame["I_g"] >= 0) and np.all(frame["price"] > 0)
    assert np.all(frame["T_min"] < frame["T_max"])
    pd.testing.assert_frame_equal(frame, scenario.exogenous(days=2, seed=5, part=part, lead_steps=10))
    if part == "whole":  # in a part, the lead rows must fit in it too and may move the start
        # The forecast lead never changes the simulated rows.
        pd.testing.assert_frame_equal(frame.iloc[:96], scenario.exogenous(days=2, seed=5, part=part))
    other = scenario.exogenous(days=2, seed=6, part=part, lead_steps=10)
    assert not np.allclose(other["T_a"], frame["T_a"])


def test_exogenous_rejects_bad_arguments():
    scenario = get_scenario("paper_household")
    with pytest.raises(ValueError, match="days must be >= 1"):
        scenario.exogenous(days=0, seed=0, part="train")
    with pytest.raises(ValueError, match="seed must be a non-negative"):
        scenario.exogenous(days=1, seed=-1, part="train")
    with pytest.raises(ValueError, match="unknown weather part 'all'; choose one of: train, test, whole"):
        scenario.exogenous(days=1, seed=0, part="all")


def test_paper_weather_range_and_irradiance_cycle():
    frame = get_scenario("paper_household").exogenous(days=120, seed=0, part="train")
    assert 2.0 < frame["T_a"].min() < 10.0 and 20.0 < frame["T_a"].max() < 27.0
    hour = time_of_day_h(frame["time"])
    night = (hour < 6.0) | (hour >= 20.0)
    assert np.all(frame["G"][night] == 0.0)
    assert frame["G"].max() > 300.0
    # No solar or internal gains in the paper's simulation.
    scenario = get_scenario("paper_household")
    assert scenario.sim.params.solar_aperture_m2 == 0 and not scenario.gains.active


def test_tmy3_values_are_real_greensboro_data():
    t_a, ghi, station = load_tmy3("723170TYA.CSV")
    assert "GREENSBORO" in station
    assert t_a.shape == ghi.shape == (HOURS_PER_TYPICAL_YEAR,)
    january, july = t_a[: 31 * 24].mean(), t_a[181 * 24 : 212 * 24].mean()
    assert -3.0 < january < 8.0  # Greensboro's January normal is about 3 C
    assert 22.0 < july < 29.0
    assert ghi.min() >= 0 and 900 < ghi.max() < 1200
    assert np.all(ghi[: 24 * 10].reshape(10, 24)[:, [0, 1, 2, 3, 22, 23]] == 0)  # dark at night


@pytest.mark.parametrize("dt_s", [900.0, 1800.0, 3600.0])
def test_resampling_preserves_daily_means(dt_s):
    t_a, ghi, _ = load_tmy3("723170TYA.CSV")
    per_day = round(86400 / dt_s)
    t_res, g_res = resample_typical_year(t_a, ghi, start_s=0.0, n=365 * per_day, dt_s=dt_s)
    daily_t = t_res.reshape(365, per_day).mean(axis=1)
    daily_g = g_res.reshape(365, per_day).mean(axis=1)
    np.testing.assert_allclose(daily_g, ghi.reshape(365, 24).mean(axis=1), rtol=0, atol=1e-9)
    # Linear interpolation of instants: the daily mean moves by at most the boundary term.
    np.testing.assert_allclose(daily_t, t_a.reshape(365, 24).mean(axis=1), atol=0.35)
    assert abs(daily_t.mean() - t_a.mean()) < 1e-6


def test_resampling_wraps_around_the_typical_year():
    t_a, ghi, _ = load_tmy3("723170TYA.CSV")
    year_s = HOURS_PER_TYPICAL_YEAR * 3600.0
    wrapped = resample_typical_year(t_a, ghi, start_s=year_s - 86400.0, n=96, dt_s=1800.0)
    direct_end = resample_typical_year(t_a, ghi, start_s=year_s - 86400.0, n=48, dt_s=1800.0)
    direct_start = resample_typical_year(t_a, ghi, start_s=0.0, n=48, dt_s=1800.0)
    for w, end, start in zip(wrapped, direct_end, direct_start, strict=True):
        np.testing.assert_allclose(w[:48], end)
        np.testing.assert_allclose(w[48:], start)


def test_winter_window_and_seeded_start_day():
    scenario = get_scenario("winter_household")
    starts = set()
    for seed in range(6):
        frame = scenario.exogenous(days=5, seed=seed, part="whole")
        months = set(frame["time"].dt.month)
        assert months <= {11, 12, 1, 2, 3}
        starts.add(frame["time"].iloc[0])
        assert frame["T_a"].min() > -20 and frame["T_a"].max() < 30
    assert len(starts) >= 4


def test_price_profiles():
    times = pd.date_range("2021-01-01", periods=48 * 30, freq="30min")
    rng = np.random.default_rng(0)
    constant = PriceProfile(kind="constant", level_eur_per_kwh=0.2).sample(times, dt_s=1800, rng=rng)
    assert np.all(constant == 0.2)
    day_night = PriceProfile(kind="day_night", level_eur_per_kwh=0.3, night_eur_per_kwh=0.1)
    prices = day_night.sample(times, dt_s=1800, rng=rng)
    hour = time_of_day_h(times)
    assert np.all(prices[(hour >= 7) & (hour < 22)] == 0.3) and np.all(prices[hour < 7] == 0.1)
    dynamic = PriceProfile(kind="dynamic").sample(times, dt_s=1800, rng=rng)
    assert dynamic.min() >= 0.01
    evening, night = dynamic[(hour >= 18) & (hour < 20)].mean(), dynamic[hour < 4].mean()
    assert evening > night + 0.08
    with pytest.raises(ValueError, match="PriceProfile.kind 'spot' is unknown"):
        PriceProfile(kind="spot")


def test_comfort_and_gains_schedules():
    winter = get_scenario("winter_household").exogenous(days=3, seed=0, part="test")
    hour = time_of_day_h(winter["time"])
    day = (hour >= 7) & (hour < 22)
    assert np.all(winter["T_min"][day] == 20) and np.all(winter["T_min"][~day] == 17)
    assert np.all(winter["T_max"] == 22)
    cold = get_scenario("cold_storage").exogenous(days=10, seed=0, part="train")
    hour = time_of_day_h(cold["time"])
    open_hours = (hour >= 7) & (hour < 19)
    assert np.all(cold["I_g"][~open_hours] == 150.0)
    doors = cold["I_g"][open_hours] > 150.0
    assert 0.2 < doors.mean() < 0.4  # event probability 0.3


def test_actuators_can_hold_the_bands_in_the_worst_weather():
    winter = get_scenario("winter_household")
    t_a, _, _ = load_tmy3("723170TYA.CSV")
    coldest = min(t_a[: 90 * 24].min(), t_a[304 * 24 :].min())
    t_r, _ = steady_state(winter.sim.params, u_w=winter.sim.u_max_w, t_a_c=coldest)
    assert t_r > 20.0
    cold = get_scenario("cold_storage")
    hottest = t_a[151 * 24 : 243 * 24].max()
    t_r, _ = steady_state(cold.sim.params, u_w=cold.sim.u_max_w, t_a_c=hottest, i_g_w=2650.0)
    assert t_r < 2.0
    assert not cold.sim.params.heating and not cold.control_spec().heating


def test_control_spec_matches_the_scenario():
    scenario = get_scenario("winter_household")
    spec = scenario.control_spec()
    assert spec.u_max_w == scenario.sim.u_max_w and spec.dt_s == 1800
    assert spec.horizon_steps == 48 and spec.comfort_weight_eur_per_kh == 5.0 and spec.heating
