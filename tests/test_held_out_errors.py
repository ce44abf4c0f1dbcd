"""benchmarks/held_out_errors.py: a stored model's folder name gives its building, family, seed
and training days; each model is judged on the test weather's days simulated with the next
seed, and its figure is the ARX's own h-step error there on the demanded power (as a network
is rolled out), computed here from the data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from benchmarks.held_out_errors import MODEL_DIR, main
from pinn_mpc.fitted import save
from pinn_mpc.models.arx import fit_linear
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate


def test_a_stored_models_folder_names_its_building_family_seed_and_days() -> None:
    m = MODEL_DIR.match("eplus_standalone_retail-8e17f6bd216c--pcnn-parx--seed2--train30")
    assert m is not None and (m["scenario"], m["arch"], m["seed"], m["days"]) == ("eplus_standalone_retail", "pcnn-parx", "2", "30")
    m = MODEL_DIR.match("winter_household--parx--seed0--train14")
    assert m is not None and (m["scenario"], m["arch"]) == ("winter_household", "parx")


def test_each_model_is_judged_on_the_next_seeds_test_days(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sc = get_scenario("winter_household")
    model = fit_linear("parx", generate(sc, days=6, seed=3, policy=sc.data_policy))
    save(model, tmp_path / "sweep" / "models" / "winter_household--parx--seed3--train6")
    spec = tmp_path / "spec.toml"
    spec.write_text('scenarios = ["winter_household"]\ncontrollers = ["cem"]\n')
    assert main(["--sweep", str(tmp_path / "sweep"), "--spec", str(spec), "--days", "3", "--horizon", "6"]) == 0
    held = generate(sc, days=3, seed=4, policy=sc.data_policy, weather_part="test")
    starts = np.arange(model.lags - 1, len(held) - 6)
    truth = held["T_r"].to_numpy(dtype=float)[starts + 6]
    expected = float(np.mean(np.abs(model.predict_t_r(held, 6, starts, planned=True) - truth)))
    out = capsys.readouterr().out
    assert f"winter_household--parx--seed3--train6: {expected:.3f} C" in out
    assert f"| winter_household | parx | 6 | 1 | {expected:.3f} ({expected:.3f}) | 1.000 |" in out
