"""benchmarks/held_out_errors.py: a stored model's folder name gives its building, family, seed
and training days; each model is judged on the test weather's days simulated with the next
seed, and its figure is the ARX's own h-step error there on the demanded power (as a network
is rolled out), computed here from the data."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import torch

from benchmarks.held_out_errors import MODEL_DIR, main, zero_unforced
from pinn_mpc.fitted import save
from pinn_mpc.models.arx import fit_linear
from pinn_mpc.models.pcnn_parx import PcnnParxNet
from pinn_mpc.training import TrainConfig, train_model
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate
from tests.model_data import net_of


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


def test_a_consistent_model_is_judged_also_with_its_unforced_network_zeroed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A ``pcnn-parx`` of a sweep's models is judged as trained and as its positive ARX alone
    (``pcnn-parx-net0``): zeroed, its unforced network adds nothing for any input, and the
    two figures differ (the trained network added heat); a model with no unforced network is
    judged once."""
    sc = get_scenario("winter_household")
    data = generate(sc, days=6, seed=3, policy=sc.data_policy)
    config = TrainConfig(n_seeds=2, epochs=3, eta=sc.sim.params.eta, u_max_w=sc.sim.u_max_w)
    model = train_model(data, arch="pcnn-parx", config=config, progress=False)
    (tmp_path / "sweep" / "models").mkdir(parents=True)
    save(model, tmp_path / "sweep" / "models" / "winter_household--pcnn-parx--seed3--train6")
    save(fit_linear("parx", data), tmp_path / "sweep" / "models" / "winter_household--parx--seed3--train6")
    spec = tmp_path / "spec.toml"
    spec.write_text('scenarios = ["winter_household"]\ncontrollers = ["cem"]\n')
    assert main(["--sweep", str(tmp_path / "sweep"), "--spec", str(spec), "--days", "3", "--horizon", "6"]) == 0
    out = capsys.readouterr().out
    trained = float(re.search(r"pcnn-parx--seed3--train6: (\S+) C", out)[1])  # type: ignore[index]
    zeroed = float(re.search(r"pcnn-parx--seed3--train6, its unforced network zeroed: (\S+) C", out)[1])  # type: ignore[index]
    assert trained != zeroed
    assert "| winter_household | pcnn-parx-net0 | 6 | 1 |" in out
    assert "winter_household--parx--seed3--train6, its unforced network zeroed" not in out
    assert zero_unforced(model)
    unforced = net_of(model, PcnnParxNet).unforced
    e_seq = torch.randn(1, 5, len(model.features.exog_series), model.features.depth + 4)
    tod = torch.rand(1, 5, 4, unforced.n_clock)
    assert torch.count_nonzero(unforced(e_seq, tod)) == 0
    assert not zero_unforced(train_model(data, arch="hybrid", config=config, progress=False))
