"""Physically wrong or damaged input through the real CLI (issue 8, cases 4-7): exit 2, one line
that names the problem, nothing written; and the right input (a cooling model) still runs."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.artifacts import META, WEIGHTS
from pinn_mpc.data import write_timeseries
from pinn_mpc.physics import PAPER_HOUSEHOLD, rc_summary
from pinn_mpc_cli.cli import main
from tests.model_data import household_data

SMALL = ("--seeds", "2", "--epochs", "2", "--depth", "4")


def _refused(capsys: pytest.CaptureFixture[str], args: list[str], *expected: str) -> str:
    """Run the CLI; it must exit 2 with one stderr line holding every expected fragment."""
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for fragment in expected:
        assert fragment in err, err
    return err


def _retime(df: pd.DataFrame, dt_s: float) -> pd.DataFrame:
    """The same rows at another interval (the values do not matter for the refusals)."""
    start = df["time"].iloc[0]
    return df.assign(time=start + pd.to_timedelta(np.arange(len(df)) * dt_s, unit="s"))


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Data, a heating model, a cooling model (on cold-storage data) and a 15-min model (all
    trained by the CLI), and the true RC of the paper's household."""
    from scenarios.inputs.scenario_file import get_scenario
    from scenarios.running.datagen import generate

    root = tmp_path_factory.mktemp("sanity")
    data = household_data(4, 0)
    write_timeseries(data, root / "d.csv")
    write_timeseries(_retime(data, 900.0), root / "d15.csv")
    # A cooling machine's model needs a cooling machine's data: train refuses an eta whose
    # sign the data contradict.
    write_timeseries(generate(get_scenario("cold_storage"), days=4, seed=0, policy="random"),
                     root / "cold.csv")
    for name, csv, extra in (
        ("heating", "d.csv", ()),
        ("cooling", "cold.csv", ("--eta", "-2.5")),
        ("quarter", "d15.csv", ()),
    ):
        args = ["train", "--data", str(root / csv), "--arch", "physnet", *SMALL, *extra]
        assert main([*args, "--out", str(root / name)]) == 0
    (root / "rc.json").write_text(json.dumps(rc_summary(PAPER_HOUSEHOLD, source="true")))
    return {
        "root": root,
        "data": root / "d.csv",
        "data15": root / "d15.csv",
        "heating": root / "heating",
        "cooling": root / "cooling",
        "quarter": root / "quarter",
        "rc": root / "rc.json",
    }


# ------------------------------------------------------- a model's heating/cooling and interval


def test_train_eta_is_recorded_and_signs_the_physics_prior(files: dict[str, Path]) -> None:
    meta = json.loads((files["cooling"] / META).read_text())
    assert meta["eta"] == -2.5 and meta["prior"]["eta"] == -2.5
    # b = eta/C_r: the learned b keeps the sign of the cooling machine in every member.
    assert all(m["b"] < 0 for m in meta["learned_coefficients_per_s"]["members"])
    heating = json.loads((files["heating"] / META).read_text())
    assert heating["eta"] == 1.0
    assert all(m["b"] > 0 for m in heating["learned_coefficients_per_s"]["members"])


@pytest.mark.parametrize(
    ("scenario", "controller", "source", "expected"),
    [
        ("cold_storage", "cem", "heating", "the model: eta=1, a heater, but the scenario's "
         "actuator is a cooling machine"),
        ("cold_storage", "random-shooting", "heating", "the model: eta=1, a heater"),
        ("cold_storage", "qp-mpc", "rc", "the RC parameters: eta=1, a heater, but the scenario's "
         "actuator is a cooling machine"),
        ("cold_storage", "casadi-mpc", "rc", "the RC parameters: eta=1, a heater"),
        ("paper_household", "cem", "cooling", "the model: eta=-2.5, a cooling machine, but the "
         "scenario's actuator is a heater"),
        ("paper_household", "cem", "quarter", "trained at 900 s (15 min) intervals but the "
         "scenario's control interval is 1800 s (30 min)"),
        ("paper_household", "random-shooting", "quarter", "900 s (15 min)"),
    ],
)
def test_model_that_does_not_fit_the_scenario_is_refused(
    files: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    scenario: str,
    controller: str,
    source: str,
    expected: str,
) -> None:
    flag = "--rc" if source == "rc" else "--model"
    args = ["closed-loop", "--scenario", scenario, "--controller", controller, flag,
            str(files[source]), "--days", "1", "--json", str(tmp_path / "k.json")]
    _refused(capsys, args, expected)
    assert list(tmp_path.iterdir()) == []


def test_cooling_model_runs_on_the_cooling_scenario(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from scenarios.inputs.scenario_file import get_scenario
    from scenarios.running.datagen import generate

    write_timeseries(generate(get_scenario("cold_storage"), days=3, seed=0, policy="random"),
                     tmp_path / "cold.csv")
    train = ["train", "--data", str(tmp_path / "cold.csv"), "--arch", "physnet", *SMALL]
    assert main([*train, "--eta", "-2.5", "--out", str(tmp_path / "m")]) == 0
    run = ["closed-loop", "--scenario", "cold_storage", "--controller", "cem", "--model",
           str(tmp_path / "m"), "--days", "1", "--json", str(tmp_path / "k.json")]
    assert main(run) == 0
    assert json.loads((tmp_path / "k.json").read_text())["controller"] == "cem"


def test_evaluate_on_data_at_another_interval_is_refused(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["evaluate", "--model", str(files["heating"]), "--data", str(files["data15"]),
            "--json", str(tmp_path / "m.json")]
    _refused(capsys, args, "trained at 1800 s (30 min) intervals but the evaluation data has "
             "900 s (15 min)")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------- data for a model


def _set_row(column: str, value: float) -> Callable[[pd.DataFrame], pd.DataFrame]:
    def mutate(df: pd.DataFrame) -> pd.DataFrame:
        out = df.copy()
        out.loc[10, column] = value
        return out

    return mutate


DATA_CASES = [
    (_set_row("u_phys", -500.0), ["'u_phys' row 11 is -500 W, negative"]),
    (_set_row("u_phys", 1e12), ["'u_phys' row 11 is 1e+12 W", "plausible range is 0 .. 1e+07 W"]),
    (lambda df: df.assign(time=np.arange(len(df))),
     ["time step is 1 s, outside the plausible 60 .. 21600 s", "ISO 8601"]),
    (lambda df: df.iloc[::-1], ["'time' goes backwards at row 2 (", " then ", "sort the rows by time"]),
    (lambda df: pd.concat([df.iloc[:20], df.iloc[19:]]),
     ["duplicate timestamp at row 21", "as in row 20"]),
]


@pytest.mark.parametrize("command", ["train", "identify"])
@pytest.mark.parametrize(("mutate", "expected"), DATA_CASES)
def test_physically_wrong_data_is_refused(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    command: str,
    mutate: Callable[[pd.DataFrame], pd.DataFrame],
    expected: list[str],
) -> None:
    data = tmp_path / "bad.csv"
    mutate(household_data(2, 0)).to_csv(data, index=False)
    extra = ["--arch", "physnet", *SMALL] if command == "train" else []
    _refused(capsys, [command, "--data", str(data), *extra, "--out", str(tmp_path / "out")],
             *expected)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


def test_train_eta_zero_is_refused(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["train", "--data", str(files["data"]), "--arch", "physnet", *SMALL, "--eta", "0",
            "--out", str(tmp_path / "m")]
    _refused(capsys, args, "error: --eta is 0: the actuator would do nothing")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------ damaged model directories


def _flip_a_weight_bit(model: Path) -> None:
    raw = bytearray((model / WEIGHTS).read_bytes())
    header_len = int.from_bytes(raw[:8], "little")
    raw[8 + header_len + 100] ^= 0x40
    (model / WEIGHTS).write_bytes(bytes(raw))


def _edit(**changes: object) -> Callable[[Path], None]:
    """Change model.json fields; ``features_<name>`` changes ``features.<name>``."""

    def edit(model: Path) -> None:
        meta = json.loads((model / META).read_text())
        for key, value in changes.items():
            if key.startswith("features_"):
                meta["features"][key.removeprefix("features_")] = value
            else:
                meta[key] = value
        (model / META).write_text(json.dumps(meta))

    return edit


@pytest.mark.parametrize(
    ("damage", "expected"),
    [
        (_flip_a_weight_bit, f"{WEIGHTS} does not match {META}"),
        (_edit(n_members=1e9), "n_members is 1000000000, must be 1 .. 1000"),
        (_edit(features_depth=1e8), "depth must be 1 .. 1008 intervals"),
        (_edit(features_dt_s=0), "dt_s must be a control interval of 60 .. 21600 s, got 0"),
        (_edit(features_dt_s=900), "trained at 900 s (15 min) intervals but the evaluation data "
         "has 1800 s (30 min)"),
        (_edit(eta=0), "eta is 0"),
    ],
)
def test_damaged_model_directory_is_refused(
    files: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    damage: Callable[[Path], None],
    expected: str,
) -> None:
    model = tmp_path / "model"
    shutil.copytree(files["heating"], model)
    damage(model)
    args = ["evaluate", "--model", str(model), "--data", str(files["data"]),
            "--json", str(tmp_path / "m.json")]
    _refused(capsys, args, expected)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model"]


# ---------------------------------------------------------------------------------- rc.json


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"C_m_J_per_K": 1e30}, "C_m_J_per_K = 1e+30 J/K is outside the plausible range "
         "10000 .. 1e+12 J/K"),
        ({"R_ra_K_per_W": -0.004}, "R_ra_K_per_W is negative (-0.004 K/W)"),
        ({"R_rm_K_per_W": "small"}, "R_rm_K_per_W is 'small', not a number"),
    ],
)
def test_implausible_rc_json_is_refused_by_its_key(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
    change: dict[str, object], expected: str,
) -> None:
    rc = tmp_path / "rc.json"
    rc.write_text(json.dumps(json.loads(files["rc"].read_text()) | change))
    args = ["closed-loop", "--scenario", "paper_household", "--controller", "qp-mpc", "--rc",
            str(rc), "--days", "1", "--json", str(tmp_path / "k.json")]
    _refused(capsys, args, expected)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rc.json"]


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"cop": -1.0}, ("column 'cop'", "plausible 0.5 .. 10")),
        ({"cop": 100.0}, ("column 'cop'", "plausible 0.5 .. 10")),
        ({"building": "two"}, ("holds 2 buildings", "column 'building'")),
    ],
)
def test_heat_pump_and_fleet_columns_are_checked(tmp_path, capsys, change, expected):
    df = household_data(days=3, seed=0)
    if change.get("building") == "two":
        df = pd.concat([df.assign(building=0), df.assign(building=1)], ignore_index=True)
    else:
        df = df.assign(cop=3.0)
        df.loc[5, "cop"] = change["cop"]
    write_timeseries(df, tmp_path / "d.csv")
    for command in (["train", "--out", str(tmp_path / "m"), *SMALL], ["identify", "--out", str(tmp_path / "rc.json")]):
        _refused(capsys, [command[0], "--data", str(tmp_path / "d.csv"), *command[1:]], *expected)
    assert not (tmp_path / "m").exists() and not (tmp_path / "rc.json").exists()


def test_output_into_a_closed_pipe_ends_quietly() -> None:
    """``pinn-mpc scenario show NAME | head -1``: the reader leaves early; no traceback."""
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "pinn_mpc", "scenario", "show", "winter_household"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader is gone before the command prints (as after head's line)
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 0
    assert "Traceback" not in err and "BrokenPipe" not in err
