"""The prediction-error table of ``compare``: the RC path against the plant that made the data."""

import dataclasses

import numpy as np
import pytest

from pinn_mpc.actuator import Actuator
from scenarios.experiments.prediction import prediction_errors, rc_recursive_t_r
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate


def _data(name: str, **sim_changes):
    scenario = get_scenario(name)
    # Backup limits out of reach: the interval-mean power is then the power held over it.
    sim = dataclasses.replace(scenario.sim, backup_low_c=-40.0, backup_high_c=60.0, **sim_changes)
    scenario = dataclasses.replace(scenario, sim=sim)
    return scenario, generate(scenario, days=4, seed=5, policy="random-level", weather_part="test")


@pytest.mark.parametrize("name", ["winter_household", "heat_pump_household"])
def test_the_true_rc_predicts_its_own_noise_free_data(name: str):
    # without the minimum modulation (its cycling is what a 2R2C on interval means cannot follow)
    actuator = dataclasses.replace(get_scenario(name).sim.actuator, min_modulation=0.0)
    scenario, df = _data(name, actuator=actuator)
    starts = np.arange(48, len(df) - 24)  # after a day of the Kalman estimate settling
    pred = rc_recursive_t_r(scenario.sim.params, df, 24, starts, scenario.sim.actuator)
    truth = df["T_r"].to_numpy()[starts + 24]
    assert np.abs(pred - truth).max() < 0.02
    # the same RC without the heat pump's COP is far off: the COP path is exercised
    if name == "heat_pump_household":
        ideal = rc_recursive_t_r(scenario.sim.params, df, 24, starts, Actuator())
        assert np.abs(ideal - truth).mean() > 1.0


def test_on_the_3r3c_plant_the_2r2c_has_a_structural_error():
    scenario, df = _data("mismatch_household")
    rows = prediction_errors(df, learned={}, rc={"true RC": scenario.sim.params}, actuator=Actuator())
    assert [r["model"] for r in rows] == ["true RC"] and rows[0]["n_starts"] == len(df) - 25
    assert rows[0]["T_r_mae_c"] > 0.05
    _, exact = _data("winter_household")
    exact_rows = prediction_errors(exact, learned={}, rc={"true RC": scenario.sim.params}, actuator=Actuator())
    assert exact_rows[0]["T_r_mae_c"] < rows[0]["T_r_mae_c"] / 3
