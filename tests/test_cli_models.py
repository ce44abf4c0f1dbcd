"""CLI ``train``, ``evaluate``, ``export-rc``: exit 0 with a summary, or 2 with one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pinn_mpc.data import write_timeseries
from pinn_mpc_cli.cli import main
from tests.model_data import household_data

REAL_COLUMNS = "T_r=T_int,u_phys=P_hea,T_a=T_ext,time=Time"


def _train(data: Path, out: Path, arch: str, *extra: str) -> int:
    return main(["train", "--data", str(data), "--arch", arch, "--out", str(out), *extra])


def _evaluate(model: Path, data: Path, out: Path, *extra: str) -> int:
    args = ["--model", str(model), "--data", str(data), "--json", str(out), *extra]
    return main(["evaluate", *args])


def _export(model: Path, out: Path) -> int:
    return main(["export-rc", "--model", str(model), "--out", str(out)])


def _error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A small physreg model trained by the CLI, and its test data."""
    root = tmp_path_factory.mktemp("cli")
    write_timeseries(household_data(4, 0), root / "train.csv")
    write_timeseries(household_data(2, 1), root / "test.csv")
    small = ("--seeds", "2", "--epochs", "2", "--depth", "4")
    assert _train(root / "train.csv", root / "model", "physreg", *small) == 0
    return root / "model", root / "test.csv"


def test_train_evaluate_export(
    trained: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model, test = trained
    capsys.readouterr()
    assert _evaluate(model, test, tmp_path / "m.json", "--horizons", "1,6") == 0
    assert "one-step MAE" in capsys.readouterr().out
    metrics = json.loads((tmp_path / "m.json").read_text())
    assert set(metrics["one_step"]) == {"T_r_mae", "u_phys_mae", "T_m_mae"}
    assert set(metrics["horizons"]) == {"1", "6"}
    assert set(metrics["horizons"]["6"]) == {"T_r_mae", "T_r_mae_std"}
    assert set(metrics["persistence"]["horizons"]["6"]) == {"T_r_mae"}
    assert _export(model, tmp_path / "rc.json") == 0
    rc = json.loads((tmp_path / "rc.json").read_text())
    assert {"R_ra_K_per_W", "R_rm_K_per_W", "C_r_J_per_K", "C_m_J_per_K", "source"} <= set(rc)


def test_train_on_data_with_nan_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    df = household_data(2, 0)
    df.loc[30, "T_r"] = np.nan
    df.to_csv(tmp_path / "bad.csv", index=False)
    assert _train(tmp_path / "bad.csv", tmp_path / "model", "physnet", "--seeds", "2") == 2
    assert "column 'T_r' row 31" in _error_line(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


def test_evaluate_missing_model_dir(
    trained: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, test = trained
    capsys.readouterr()
    assert _evaluate(tmp_path / "none", test, tmp_path / "m.json") == 2
    assert "does not exist" in _error_line(capsys)
    assert list(tmp_path.iterdir()) == []


def test_evaluate_truncated_weights(
    trained: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model, test = trained
    broken = tmp_path / "broken"
    broken.mkdir()
    for item in model.iterdir():
        data = item.read_bytes()
        cut = len(data) // 2 if item.suffix == ".safetensors" else len(data)
        (broken / item.name).write_bytes(data[:cut])
    capsys.readouterr()
    assert _evaluate(broken, test, tmp_path / "m.json") == 2
    assert "truncated or corrupt" in _error_line(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken"]


def _real_world_csv(path: Path, days: int) -> None:
    """Columns as a monitoring system names them: Time, T_ext, P_hea, I_sol, T_int."""
    df = household_data(days, 4)
    out = df.rename(columns={"time": "Time", "T_a": "T_ext", "u_phys": "P_hea", "T_r": "T_int"})
    out["I_sol"] = 0.0
    out = out[["Time", "T_ext", "P_hea", "I_sol", "T_int"]]
    out["Time"] = out["Time"].dt.strftime("%Y-%m-%d %H:%M:%S")
    out.to_csv(path, index=False)


def test_real_world_columns(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data, model = tmp_path / "real.csv", tmp_path / "model"
    _real_world_csv(data, 3)
    small = ("--seeds", "2", "--epochs", "2", "--columns", REAL_COLUMNS)
    assert _train(data, model, "physnet", *small) == 0
    assert "trained physnet x2 on 144 rows" in capsys.readouterr().out
    extra = ("--columns", REAL_COLUMNS, "--horizons", "1,12")
    assert _evaluate(model, data, tmp_path / "m.json", *extra) == 0
    metrics = json.loads((tmp_path / "m.json").read_text())
    assert metrics["one_step"]["T_m_mae"] is None
    assert np.isfinite(metrics["horizons"]["12"]["T_r_mae"])


def test_real_world_data_too_short(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _real_world_csv(tmp_path / "real.csv", 1)
    short = tmp_path / "short.csv"
    short.write_text("\n".join((tmp_path / "real.csv").read_text().splitlines()[:31]) + "\n")
    assert _train(short, tmp_path / "model", "physreg", "--columns", REAL_COLUMNS) == 2
    assert "has 30 rows, but depth 8 needs at least 42 rows" in _error_line(capsys)  # physreg
    assert not (tmp_path / "model").exists()


def test_export_rc_of_an_mlp_is_the_rc_identified_from_its_data(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A network without R or C of its own (the mlp; pcnn-parx likewise) exports, as an ARX
    does, the RC ``train`` identified from its training data, which its guard falls back on:
    the household's true one here, the source and the printed line saying whose it is;
    without one it is refused with the reason."""
    from pinn_mpc.physics import params_from_summary
    from scenarios.inputs.registry import builtin_scenario

    write_timeseries(household_data(6, 0), tmp_path / "d.csv")
    assert _train(tmp_path / "d.csv", tmp_path / "mlp", "mlp", "--seeds", "1", "--epochs", "1") == 0
    capsys.readouterr()
    assert _export(tmp_path / "mlp", tmp_path / "rc.json") == 0
    assert capsys.readouterr().out.startswith("the RC identified from its training data (the model has no R or C")
    rc = json.loads((tmp_path / "rc.json").read_text())
    assert "the mlp model" in rc["source"] and "identified from its training data" in rc["source"]
    got, true = params_from_summary(rc), builtin_scenario("winter_household").sim.params
    assert got.r_ra_k_per_w == pytest.approx(true.r_ra_k_per_w, rel=0.05)
    record = json.loads((tmp_path / "mlp" / "model.json").read_text())
    del record["identified_rc"]
    (tmp_path / "mlp" / "model.json").write_text(json.dumps(record))
    assert _export(tmp_path / "mlp", tmp_path / "rc2.json") == 2
    assert "the mlp model, which has no R or C of its own" in _error_line(capsys)
    assert not (tmp_path / "rc2.json").exists()


def test_export_rc_of_an_arx_model_is_the_rc_identified_from_its_data(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A model directory ``train`` writes for the physics-informed ARX (arx.json) works with
    export-rc: the RC identified from its training data, the household's true one here."""
    from pinn_mpc.physics import params_from_summary
    from scenarios.inputs.registry import builtin_scenario

    write_timeseries(household_data(6, 0), tmp_path / "train.csv")
    assert _train(tmp_path / "train.csv", tmp_path / "m", "parx") == 0
    assert _export(tmp_path / "m", tmp_path / "rc.json") == 0, capsys.readouterr().err
    rc = json.loads((tmp_path / "rc.json").read_text())
    assert "ARX" in rc["source"] and rc["power_range_w"][1] > 0
    got, true = params_from_summary(rc), builtin_scenario("winter_household").sim.params
    assert got.r_ra_k_per_w == pytest.approx(true.r_ra_k_per_w, rel=0.05)
    assert got.c_r_j_per_k == pytest.approx(true.c_r_j_per_k, rel=0.05)
    # Without an identified RC, the refusal says why and what to use.
    record = json.loads((tmp_path / "m" / "arx.json").read_text())
    del record["identified_rc"]
    (tmp_path / "m" / "arx.json").write_text(json.dumps(record))
    capsys.readouterr()
    assert _export(tmp_path / "m", tmp_path / "rc2.json") == 2
    err = _error_line(capsys)
    assert "has no R or C of its own" in err and "pinn-mpc identify" in err
    assert not (tmp_path / "rc2.json").exists()


@pytest.mark.parametrize("command", ["evaluate", "export-rc"])
def test_a_per_building_directory_is_named_as_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    (tmp_path / "fleet" / "buildings" / "b00000").mkdir(parents=True)
    (tmp_path / "fleet" / "fleet.json").write_text('{"buildings": [0]}')
    write_timeseries(household_data(2, 0), tmp_path / "d.csv")
    out = ["--out", str(tmp_path / "o.json")] if command == "export-rc" else [
        "--data", str(tmp_path / "d.csv"), "--json", str(tmp_path / "o.json")]
    assert main([command, "--model", str(tmp_path / "fleet"), *out]) == 2
    err = _error_line(capsys)
    assert "holds one model per building" in err and f"{command} --model " in err
    assert "buildings/b00000" in err and not (tmp_path / "o.json").exists()
