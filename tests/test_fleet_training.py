"""One model per building: the fleet data set, per-building training on Ray (resumable), the
fleet-pretrained fine-tuning, and the CLI around them."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import torch

from pinn_mpc.data import read_fleet_timeseries, write_fleet_params, write_timeseries
from pinn_mpc.errors import InputError
from pinn_mpc.io import atomic_write_json
from pinn_mpc.physics import params_from_summary
from pinn_mpc.simulator import draw_fleet
from pinn_mpc.training import TrainConfig, train_model
from pinn_mpc_cli.cli import main
from scenarios.fleets.training import (
    TRANSFERRED,
    building_frames,
    building_model_dir,
    load_fleet_models,
    pretrain_and_fine_tune,
    train_per_building,
)
from scenarios.inputs.scenario_file import get_scenario
from scenarios.records import FleetTraining
from scenarios.running.datagen import generate
from tests.test_records import assert_record

TINY = TrainConfig(n_seeds=2, epochs=2, u_max_w=10000.0)


def _fleet_data(n=2, days=3):
    scenario = get_scenario("winter_household")
    fleet = draw_fleet(scenario.sim.params, n, spread=0.2, rng=np.random.default_rng(3))
    return generate(scenario, days=days, seed=0, policy="random-level", n_buildings=n, fleet=fleet), fleet


def test_a_fleet_data_set_is_read_building_by_building(tmp_path):
    data, _ = _fleet_data()
    path = tmp_path / "fleet.csv"
    write_timeseries(data, path)
    frames = read_fleet_timeseries(path)
    assert sorted(frames) == [0, 1]
    for b, frame in frames.items():
        mine = data[data["building"] == b]
        np.testing.assert_allclose(frame["T_r"], mine["T_r"], atol=1e-3)
        assert frame.attrs["dt_s"] == 1800.0
    bad = data.astype({"building": float})
    bad.loc[5, "building"] = 0.5
    bad.to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(InputError, match="row 7: 'building' must be a whole number"):
        read_fleet_timeseries(tmp_path / "bad.csv")


def test_init_weights_start_the_training_and_must_fit():
    data, _ = _fleet_data()
    frame = building_frames(data)[0]
    donor = train_model(frame, arch="hybrid", config=TINY, progress=False)
    weights = {k: v for k, v in donor.module.state_dict().items() if k.startswith(TRANSFERRED)}
    assert weights and all("physics" not in k for k in weights)
    bad = {"net.residual_net.0.weight": torch.zeros(3, 3)}
    with pytest.raises(ValueError, match="does not fit the model"):
        train_model(frame, arch="hybrid", config=TINY, progress=False, init_weights=bad)


def test_fleet_pretraining_then_fine_tuning_gives_one_model_per_building():
    data, _ = _fleet_data()
    frames = building_frames(data)
    models, seconds = pretrain_and_fine_tune(list(frames.values()), config=TINY, fine_tune_epochs=1)
    assert len(models) == 2 and set(seconds) == {"pretrain", "fine_tune"}
    assert all(m.arch == "hybrid" and m.n_members == 2 for m in models)
    # Each fine-tuned model's physics starts at its own building's identification.
    rcs = [params_from_summary(m.record.identified_rc).r_ra_k_per_w for m in models]
    assert rcs[0] != rcs[1]


@pytest.mark.slow
def test_per_building_training_on_ray_is_resumable(tmp_path):
    data, fleet = _fleet_data()
    frames = building_frames(data)
    out = tmp_path / "models"
    first = train_per_building(frames, out, arch="hybrid", config=TINY, params=fleet, workers=1)
    assert first["trained"] == [0, 1] and first["kept"] == []
    models, params = load_fleet_models(out)
    assert len(models) == 2 and params == list(fleet)
    shutil.rmtree(building_model_dir(out, 1))  # an interrupted run lost one building
    again = train_per_building(frames, out, arch="hybrid", config=TINY, workers=1)
    assert again["trained"] == [1] and again["kept"] == [0]
    stored = json.loads((out / "fleet.json").read_text())
    assert stored["params"] is not None  # kept
    assert_record(stored, FleetTraining)
    assert [m.family for m in load_fleet_models(out)[0]] == ["hybrid", "hybrid"]


def test_cli_per_building_input_errors_are_one_line(tmp_path, capsys):
    data, _ = _fleet_data()
    write_timeseries(data, tmp_path / "fleet.csv")
    cases = [
        (["train", "--data", str(tmp_path / "fleet.csv"), "--out", str(tmp_path / "m"),
          "--address", "127.0.0.1:1"], "--address runs --per-building training on Ray"),
        (["closed-loop", "--scenario", "winter_household", "--controller", "qp-mpc", "--days", "1",
          "--buildings", "2", "--model", str(tmp_path), "--json", str(tmp_path / "k.json")],
         "with --model DIR of per-building models, with cem"),
        (["closed-loop", "--scenario", "winter_household", "--controller", "cem", "--days", "1",
          "--buildings", "2", "--model", str(tmp_path), "--json", str(tmp_path / "k.json")],
         "no fleet.json"),
    ]
    for args, message in cases:
        assert main(args) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet.csv"]


def test_cli_learned_fleet_scores_rc_candidates_by_default_only_under_a_cap(tmp_path):
    data, fleet = _fleet_data()
    out = tmp_path / "models"
    train_per_building(building_frames(data), out, arch="hybrid", config=TINY, params=fleet, workers=1)
    base = ["closed-loop", "--scenario", "winter_household", "--controller", "cem", "--days", "1",
            "--buildings", "2", "--model", str(out), "--batched", "--seed", "1"]
    cases = {"free": ([], False), "capped": (["--cap-kw", "8"], True),
             "capped-off": (["--cap-kw", "8", "--rc-candidates", "off"], False),
             "free-on": (["--rc-candidates"], True)}
    for name, (extra, expected) in cases.items():
        path = tmp_path / f"{name}.json"
        assert main([*base, *extra, "--json", str(path)]) == 0
        assert json.loads(path.read_text())["fleet"]["rc_candidates"] is expected, name


@pytest.mark.slow
def test_documented_fleet_commands_run_as_written(tmp_path, capsys, monkeypatch):
    """docs/sweeps-and-fleets.md's three commands at the smallest sizes, with the default
    architecture (auto) and without --spread (every building the scenario's): the parameters
    file is written, each building's model chosen and the fleet closed loop runs over them."""
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--scenario", "winter_household", "--buildings", "2", "--days", "6",
                 "--seed", "0", "--out", "fleet.csv"]) == 0
    params = json.loads((tmp_path / "fleet.fleet.json").read_text())
    assert params["spread"] == 0.0 and len(params["params"]) == 2
    assert main(["train", "--data", "fleet.csv", "--per-building", "--seeds", "2", "--workers", "1",
                 "--out", "fleet_models"]) == 0
    assert "trained 2 (2 hybrid)" in capsys.readouterr().out
    stored = json.loads((tmp_path / "fleet_models" / "fleet.json").read_text())
    assert stored["arch"] == "auto" and stored["chosen"] == {"0": "hybrid", "1": "hybrid"}
    assert main(["closed-loop", "--scenario", "winter_household", "--controller", "cem", "--model",
                 "fleet_models", "--buildings", "2", "--batched", "--cap-kw", "8", "--days", "1",
                 "--json", "learned.json"]) == 0
    assert json.loads((tmp_path / "learned.json").read_text())["fleet"]["n_buildings"] == 2


@pytest.mark.slow
def test_per_building_arx_models_and_a_failed_run_that_leaves_nothing_behind(tmp_path, capsys, monkeypatch):
    """--arch parx per building writes each building's arx.json, and the batched fleet cem
    plans over them; a run whose every building fails leaves no fleet.json, and an earlier
    such run's fleet.json without models blocks no rerun."""
    monkeypatch.chdir(tmp_path)
    data, fleet = _fleet_data(days=6)
    write_timeseries(data, tmp_path / "fleet.csv")
    write_fleet_params(tmp_path / "fleet.csv", fleet, spread=0.2)  # for the closed loop below
    base = ["train", "--data", "fleet.csv", "--per-building", "--workers", "1"]
    # A cooling actuator on heated data: the physics-informed ARX cannot fit it.
    assert main([*base, "--arch", "parx", "--eta", "-3", "--out", "m"]) == 2
    assert "training building" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet.csv", "fleet.fleet.json"]
    (tmp_path / "m" / "buildings").mkdir(parents=True)  # as such a run left it before
    atomic_write_json(tmp_path / "m" / "fleet.json", {"arch": "auto", "config": {}, "buildings": [0, 1],
                                                      "data_sha256": {"0": "x", "1": "y"}})
    assert main([*base, "--arch", "parx", "--out", "m"]) == 0
    for b in (0, 1):
        assert sorted(p.name for p in building_model_dir(tmp_path / "m", b).iterdir()) == ["arx.json"]
    models, _ = load_fleet_models(tmp_path / "m")
    assert [type(m).__name__ for m in models] == ["ARXModel", "ARXModel"]
    capsys.readouterr()
    assert main(["closed-loop", "--scenario", "winter_household", "--controller", "cem", "--model", "m",
                 "--buildings", "2", "--days", "1", "--json", "k.json"]) == 0
    fleet = json.loads((tmp_path / "k.json").read_text())
    assert fleet["fleet"]["controller"] == "cem" and fleet["fleet"]["n_buildings"] == 2
