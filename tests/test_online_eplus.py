"""Online operation on an EnergyPlus plant (:mod:`scenarios.running.online`): a resume re-runs
EnergyPlus from its start on the recorded demands and reaches the uninterrupted run's states
and figures; the data at hand are the days simulated right before the run; the sweep's online
cells run on EnergyPlus of one zone."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.training import TrainConfig
from scenarios.experiments.sweep.grid import SweepGrid
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate
from scenarios.running.online import (
    MODEL_DAYS,
    OnlineSettings,
    data_before_run,
    retimed,
    run_online,
)
from tests.online_stop import stopped_then_resumed

SCENARIO = "eplus_small_office"
JANUARY = str(Path(__file__).resolve().parents[1] / "sweeps" / "buildings" / "eplus_small_office_january.toml")
DAYS = 4
TINY = OnlineSettings(
    config=TrainConfig(n_seeds=2, epochs=2), planner_options={"n_samples": 16, "n_iters": 2}
)


def test_online_cells_run_on_energyplus_of_one_zone():
    grid = SweepGrid(scenarios=(SCENARIO,), controllers=("cem-online", "qp-mpc-online"), seeds=(0,),
                     train_days=(14,))
    assert {c.controller for c in grid.cells()} >= {"cem-online", "qp-mpc-online"}


def test_the_data_at_hand_are_the_days_simulated_right_before_the_run():
    """The small office tested in January from the test part's first day (1 January): its 3
    days of data are 29-31 December, on their own dates (so the office's weekday schedules and
    the weather are those days'), the last 3 of a longer draw of the same seed; a run starting
    later in its test part (2 January) gets the training part's days a week before it (23-25
    December, moved by 7 days: a weekday's rows stay a weekday's)."""
    scenario = get_scenario(JANUARY)
    spd = scenario.steps_per_day
    first = pd.Timestamp("2023-01-01 00:00")
    data = data_before_run(scenario, days=MODEL_DAYS, seed=0, policy=scenario.data_policy, first_time=first)
    times = pd.to_datetime(data["time"])
    assert times.iloc[0] == pd.Timestamp("2022-12-29 00:00") and len(data) == MODEL_DAYS * spd
    assert times.iloc[-1] + pd.Timedelta(minutes=30) == first
    assert retimed(data, first, 1800.0)["time"].equals(data["time"])  # nothing moved
    longer = generate(scenario, days=32, seed=0, policy=scenario.data_policy)
    np.testing.assert_array_equal(data["T_r"].to_numpy(), longer["T_r"].to_numpy()[-MODEL_DAYS * spd :])
    later = data_before_run(scenario, days=MODEL_DAYS, seed=0, policy=scenario.data_policy,
                            first_time=pd.Timestamp("2023-01-02 00:00"))
    later_times = pd.to_datetime(later["time"])
    assert later_times.iloc[0] == pd.Timestamp("2022-12-23 00:00") and len(later) == MODEL_DAYS * spd
    np.testing.assert_array_equal(
        later["T_r"].to_numpy(), longer["T_r"].to_numpy()[-(MODEL_DAYS + 6) * spd : -6 * spd]
    )
    moved = pd.to_datetime(retimed(later, pd.Timestamp("2023-01-02 00:00"), 1800.0)["time"])
    assert (moved - later_times).eq(pd.Timedelta(days=7)).all()
    assert moved.iloc[-1] + pd.Timedelta(minutes=30) == pd.Timestamp("2023-01-02 00:00")


@pytest.mark.slow
def test_a_resumed_energyplus_run_is_the_uninterrupted_one(tmp_path):
    """Ctrl-C after the first night's takeover, then resume: EnergyPlus is run again from its
    start on the recorded demands (the same weather, schedules and sensor noise), so the room
    temperatures up to the stop, the decisions after it and the figures are the uninterrupted
    run's, to the last bit."""
    scenario = get_scenario(SCENARIO)
    data = generate(scenario, days=MODEL_DAYS, seed=0, policy=scenario.data_policy)
    spd = scenario.steps_per_day
    expected = run_online(scenario, data, days=DAYS, seed=1, out_dir=tmp_path / "whole", settings=TINY)
    assert any(e["model"] for e in expected.log[1:])  # the resume rebuilds a refitted model

    out = tmp_path / "cut"
    stopped_at, resumed = stopped_then_resumed(
        lambda resume: run_online(scenario, data, days=DAYS, seed=1, out_dir=out, settings=TINY, resume=resume),
        out / "state.json", 2 * spd,
    )
    assert 2 * spd < stopped_at < (DAYS + 1) * spd

    whole, again = expected.trajectory, resumed.trajectory
    for column in ("T_r", "u", "u_phys", "overridden", "fallback", "own"):
        np.testing.assert_array_equal(again[column].to_numpy(), whole[column].to_numpy(), err_msg=column)
    keep = ("objective", "cost_eur", "discomfort_kh", "energy_kwh", "own_decisions_share")
    assert {k: resumed.kpis[k] for k in keep} == {k: expected.kpis[k] for k in keep}
    assert resumed.kpis["online"]["days"] == expected.kpis["online"]["days"]
    assert [e["verdict"] for e in resumed.log] == [e["verdict"] for e in expected.log]
    observed = pd.read_csv(out / "observed.csv")
    assert len(observed) == (DAYS + 1) * spd  # warm-up and every day, each interval once
    # The office's gains are unmeasured: the controllers are never given them, so the data the
    # refits learn from hold none (EnergyPlus's own would be an input the planner never has).
    assert "I_g" not in observed.columns and "I_g" in whole.columns
