"""One fit, one save, one load (:mod:`pinn_mpc.fitted`): every format a model directory has,
a directory holding no model or two refused with what it holds, and ``train`` leaving one
model in its ``--out`` whatever was there before."""

from __future__ import annotations

import pytest

from pinn_mpc.artifacts import META, WEIGHTS
from pinn_mpc.data import write_timeseries
from pinn_mpc.errors import ModelFileError
from pinn_mpc.fitted import FORMATS, fit, holds_model, load, output_layout, save
from pinn_mpc.models.arx import ARX_FILE, ARXModel
from pinn_mpc.models.learned import LearnedModel
from pinn_mpc.models.registry import AUTO, MODEL_CHOICES
from pinn_mpc.training import TrainConfig
from pinn_mpc_cli.cli import main
from tests.model_data import household_data

TINY = TrainConfig(n_seeds=1, epochs=1, depth=4)


def test_every_family_train_fits_has_one_format():
    """Each name ``train --arch`` takes is held by exactly one format of one zone's data
    (and the hybrid, the physics-informed ARX and the paper's two physics-informed networks by
    one of several zones' too), and ``auto``'s output may be any of them."""
    for arch in MODEL_CHOICES:
        assert sum(arch in fmt.families for fmt in FORMATS if not fmt.zones) == 1, arch
        assert output_layout(arch).markers
    zoned = (
        ("hybrid", "multizone.json"), ("parx", "multizone_arx.json"), ("physnet", "multizone_paper.json"),
        ("physreg", "multizone_paper.json"),
    )
    for arch, marker in zoned:
        assert [fmt.marker for fmt in FORMATS if fmt.zones and arch in fmt.families] == [marker]
        assert output_layout(arch, zones=True).markers == (marker,)
    assert output_layout(AUTO).markers == ()
    assert set(output_layout(AUTO).files) == {
        WEIGHTS, META, ARX_FILE, "multizone.json", "multizone_arx.json", "multizone_paper.json",
    }


def test_a_directory_of_no_model_or_of_two_is_refused_saying_what_it_holds(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert not holds_model(empty)
    with pytest.raises(ModelFileError, match=rf"has no {META} \(a network's\) or {ARX_FILE} \(an ARX's\) or multizone.json \(a multi-zone hybrid's\) or multizone_arx.json \(a multi-zone ARX's\) "
                       rf"or multizone_paper.json \(a multi-zone paper network's\); it is not a saved model"):
        load(empty)
    with pytest.raises(ModelFileError, match="does not exist; train one"):
        load(tmp_path / "nowhere")
    data = household_data(4, seed=0)
    arx = fit(data, arch="arx", config=TINY).model
    network = fit(data, arch="physnet", config=TINY).model
    both = tmp_path / "both"
    save(network, both)
    (both / ARX_FILE).write_text((save(arx, tmp_path / "a")[0]).read_text())
    with pytest.raises(ModelFileError, match=rf"holds two models, {META} \(a network's\) and {ARX_FILE} \(an ARX's\)"):
        load(both)
    with pytest.raises(TypeError, match="save takes a fitted model"):
        save(data, tmp_path / "frame")


def test_save_leaves_one_model_in_a_directory_that_held_the_other_family(tmp_path):
    data = household_data(4, seed=0)
    out = tmp_path / "m"
    save(fit(data, arch="arx", config=TINY).model, out)
    assert isinstance(load(out), ARXModel)
    written = save(fit(data, arch="physnet", config=TINY).model, out)
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in written) == sorted([META, WEIGHTS])
    assert isinstance(load(out), LearnedModel)


def test_train_with_force_over_a_model_of_the_other_family_replaces_it(tmp_path, capsys):
    """``train --arch X --force`` into a directory holding the other family's model leaves one
    model there, so that the commands taking ``--model`` read the one just trained."""
    data = tmp_path / "d.csv"
    write_timeseries(household_data(4, seed=0), data)
    out = tmp_path / "m"
    assert main(["train", "--data", str(data), "--arch", "arx", "--out", str(out)]) == 0
    network = ["train", "--data", str(data), "--arch", "physnet", "--seeds", "1", "--epochs", "1",
               "--out", str(out)]
    assert main(network) == 2  # another family's directory: refused without --force
    assert "--force" in capsys.readouterr().err
    assert main([*network, "--force"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted([META, WEIGHTS])
    assert main(["evaluate", "--model", str(out), "--data", str(data), "--json", str(tmp_path / "e.json")]) == 0
    assert "u_phys" in capsys.readouterr().out  # a network's metrics
