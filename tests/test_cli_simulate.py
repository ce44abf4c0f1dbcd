"""The real ``simulate`` command: format, determinism, exact 2R2C agreement, errors."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.physics import PAPER_HOUSEHOLD, discretise
from pinn_mpc_cli.cli import main
from scenarios.inputs.registry import scenario_names

ARGS = ["simulate", "--scenario", "paper_household", "--days", "6"]


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pinn_mpc", *args], cwd=cwd, capture_output=True, text=True, timeout=300
    )


@pytest.fixture(scope="module")
def paper_csv(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sim")
    result = run_cli(*ARGS, "--seed", "0", "--out", "d.csv", cwd=folder)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("wrote d.csv: scenario paper_household") and not result.stderr
    return folder / "d.csv"


def test_paper_csv_format(paper_csv):
    df = pd.read_csv(paper_csv)
    assert len(df) == 288
    assert {"time", "T_r", "T_m", "u", "u_phys", "T_a"} <= set(df.columns)
    assert set(df.columns) <= {"time", "T_r", "T_m", "u", "u_phys", "T_a", "G", "I_g", "price",
                               "T_min", "T_max"}
    steps = np.diff(pd.to_datetime(df["time"]).to_numpy()).astype("timedelta64[s]").astype(int)
    assert np.all(steps == 1800)


def test_same_seed_is_byte_identical_and_another_seed_differs(paper_csv, tmp_path, capsys):
    assert main([*ARGS, "--seed", "0", "--out", str(tmp_path / "again.csv")]) == 0
    assert (tmp_path / "again.csv").read_bytes() == paper_csv.read_bytes()
    assert main([*ARGS, "--seed", "1", "--out", str(tmp_path / "other.csv")]) == 0
    other = pd.read_csv(tmp_path / "other.csv")
    assert not np.allclose(other["T_a"], pd.read_csv(paper_csv)["T_a"])
    assert "288 rows per building" in capsys.readouterr().out


def test_rows_without_backup_action_follow_the_exact_2r2c_solution(paper_csv):
    df = pd.read_csv(paper_csv)
    ad, bd = discretise(PAPER_HOUSEHOLD, 1800.0)
    x = df[["T_r", "T_m"]].to_numpy()
    d = np.column_stack([df["u"], df["T_a"], np.zeros(len(df)), np.zeros(len(df))])
    predicted = x[:-1] @ ad.T + d[:-1] @ bd.T
    free = np.isclose(df["u"], df["u_phys"], rtol=0, atol=1e-6)[:-1]
    assert free.sum() > 100
    error = np.abs(predicted[free] - x[1:][free])
    assert np.median(error) < 0.01 and error.max() < 0.05


def test_backup_acts_and_caps_the_room_temperature(paper_csv):
    df = pd.read_csv(paper_csv)
    acted = ~np.isclose(df["u"], df["u_phys"], rtol=0, atol=1e-6)
    assert 5 <= acted.sum() <= len(df) - 100
    assert df["T_r"].max() <= 20.5 + 0.3
    assert df["T_r"].iloc[48:].min() >= 17.0 - 0.3


@pytest.mark.parametrize(
    ("scenario", "policy", "band"),
    [
        ("winter_household", "random", None),
        ("winter_household", "random-level", None),
        ("cold_storage", "thermostat", (1.0, 7.5)),
    ],
)
def test_other_scenarios_simulate(scenario, policy, band, tmp_path, capsys):
    out = tmp_path / "s.csv"
    argv = ["simulate", "--scenario", scenario, "--days", "3", "--seed", "2", "--policy", policy]
    assert main([*argv, "--buildings", "2", "--out", str(out)]) == 0
    df = pd.read_csv(out)
    assert len(df) == 2 * 144 and set(df["building"]) == {0, 1}
    assert {"G", "I_g"} <= set(df.columns) or scenario == "cold_storage"
    if band is not None:
        assert band[0] < df["T_r"].iloc[48:].min() and df["T_r"].iloc[48:].max() < band[1]
    levels = df["u"].nunique()
    assert levels == len(df) if policy == "random-level" else levels <= 2
    assert "2 building(s)" in capsys.readouterr().out


def _assert_clean_failure(result_code: int, err: str, folder: Path) -> None:
    assert result_code == 2
    assert 0 < len(err.strip().splitlines()) <= 5 and "Traceback" not in err
    leftovers = [p for p in folder.rglob("*") if p.is_file()]
    assert leftovers == []


def test_days_zero_is_rejected(tmp_path):
    result = run_cli("simulate", "--scenario", "paper_household", "--days", "0", "--out", "d.csv",
                     cwd=tmp_path)
    _assert_clean_failure(result.returncode, result.stderr, tmp_path)
    assert "--days: must be at least 1" in result.stderr


def test_unknown_scenario_lists_the_valid_names(tmp_path):
    result = run_cli("simulate", "--scenario", "mars_base", "--days", "1", "--out", "d.csv",
                     cwd=tmp_path)
    _assert_clean_failure(result.returncode, result.stderr, tmp_path)
    assert ", ".join(scenario_names()) in result.stderr
    assert "paper_household" in scenario_names()


def test_out_inside_a_missing_directory(tmp_path, capsys):
    code = main([*ARGS, "--out", str(tmp_path / "missing" / "d.csv")])
    _assert_clean_failure(code, capsys.readouterr().err, tmp_path)


@pytest.mark.skipif(os.name != "posix", reason="POSIX permissions")
def test_out_in_a_read_only_directory(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        if os.access(locked, os.W_OK):  # root ignores permissions: use a directory nobody can write
            target = Path("/proc/pinn_mpc_test.csv")
        else:
            target = locked / "d.csv"
        code = main([*ARGS, "--days", "1", "--out", str(target)])
        _assert_clean_failure(code, capsys.readouterr().err, tmp_path)
        assert not target.exists()
    finally:
        locked.chmod(0o755)
