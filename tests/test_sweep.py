"""``pinn-mpc sweep``: grid parsing, the statistics of the summary, and real sweeps on Ray."""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pinn_mpc.errors import InputError
from scenarios.experiments.sweep import ARCH, SweepGrid, parse_ints, parse_names
from scenarios.reports.sweep_report import mean_ci95, render_sweep_report, summarise

ROOT = Path(__file__).resolve().parents[1]


def sweep_cli(*args: str, timeout: float = 900) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, "-m", "pinn_mpc", "sweep", *args],
        capture_output=True, text=True, env=env, timeout=timeout, cwd=ROOT,
    )


def test_mean_ci95_known_t_interval():
    # 1..5: mean 3, s = sqrt(2.5), sem = sqrt(0.5); t(0.975, 4 dof) = 2.776445 (tables)
    mean, (low, high) = mean_ci95([1.0, 2.0, 3.0, 4.0, 5.0])
    half = 2.776445 * 0.5**0.5
    assert mean == 3.0
    assert low == pytest.approx(3.0 - half, abs=1e-6)
    assert high == pytest.approx(3.0 + half, abs=1e-6)
    # two values 1 and 3: sem 1, t(0.975, 1 dof) = 12.706205
    assert mean_ci95([1.0, 3.0])[1] == pytest.approx([2.0 - 12.706205, 2.0 + 12.706205], abs=1e-6)
    assert mean_ci95([1.2, 1.2, 1.2]) == (1.2, [1.2, 1.2])
    assert mean_ci95([0.7]) == (0.7, [None, None])


def _record(scenario, controller, seed, objective, train_days=None):
    return {
        "cell": {"scenario": scenario, "controller": controller, "seed": seed, "train_days": train_days},
        "kpis": {"objective": objective},
    }


def test_summarise_divides_by_the_oracle_of_the_same_seed_and_pairs_with_the_baseline():
    cells = [
        _record("s", "oracle", 0, 10.0),
        _record("s", "oracle", 1, 20.0),
        _record("s", "thermostat", 0, 15.0),  # 1.5
        _record("s", "thermostat", 1, 40.0),  # 2.0
        _record("s", "qp-mpc", 0, 11.0, 30),  # 1.1
        _record("s", "qp-mpc", 1, 21.0, 30),  # 1.05
    ]
    rows = summarise(cells, baseline="thermostat", order=["thermostat", "qp-mpc", "oracle"])
    assert [r["controller"] for r in rows] == ["thermostat", "qp-mpc", "oracle"]
    qp = rows[1]
    assert qp["n"] == 2 and qp["train_days"] == 30
    assert qp["objective_to_oracle_mean"] == pytest.approx(1.075)
    # ratios 1.1, 1.05: sem 0.025, t(0.975, 1) = 12.706205
    assert qp["objective_to_oracle_ci95"] == pytest.approx(
        [1.075 - 12.706205 * 0.025, 1.075 + 12.706205 * 0.025], abs=1e-6
    )
    # paired with the thermostat seed by seed: 1.1 - 1.5 = -0.4, 1.05 - 2.0 = -0.95
    assert qp["paired_difference_mean"] == pytest.approx(-0.675)
    assert qp["paired_difference_ci95"] == pytest.approx(
        [-0.675 - 12.706205 * 0.275, -0.675 + 12.706205 * 0.275], abs=1e-6
    )
    assert rows[2]["objective_to_oracle_ci95"] == [1.0, 1.0]


def test_summary_gives_the_mean_avoidable_and_unavoidable_discomfort_over_the_same_seeds():
    def cell(controller, seed, objective, avoidable, unavoidable):
        record = _record("s", controller, seed, objective)
        record["kpis"] |= {"discomfort_avoidable_kh": avoidable, "discomfort_unavoidable_kh": unavoidable}
        return record

    cells = [
        cell("oracle", 0, 10.0, 0.5, 8.0), cell("oracle", 1, 20.0, 1.5, 2.0),
        cell("thermostat", 0, 15.0, 3.0, 8.0), cell("thermostat", 1, 40.0, 5.0, 2.0),
        cell("thermostat", 2, 40.0, 99.0, 99.0),  # no oracle on seed 2: left out, as its ratio
        _record("s", "qp-mpc", 0, 11.0), _record("s", "qp-mpc", 1, 12.0),  # from before the split
    ]
    rows = {r["controller"]: r for r in summarise(cells, baseline="thermostat")}
    assert rows["thermostat"]["discomfort_avoidable_kh_mean"] == pytest.approx(4.0)
    assert rows["thermostat"]["discomfort_unavoidable_kh_mean"] == pytest.approx(5.0)
    assert rows["oracle"]["discomfort_unavoidable_kh_mean"] == pytest.approx(5.0)
    assert rows["qp-mpc"]["discomfort_avoidable_kh_mean"] is None
    summary = {"rows": list(rows.values()), "baseline": "thermostat", "cells_run": 7, "cells_reused": 0,
               "models_trained": 0, "models_reused": 0, "wall_time_s": 1.0, "settings": {},
               "engine": {"name": "ray", "version": "x", "resources": {}}}
    report = render_sweep_report(summary, figure_name="f.png")
    assert "| avoidable discomfort K h (mean) | unavoidable discomfort K h (mean) |" in report
    assert "| 4.000 | 5.000 |" in report and "| not computed | not computed |" in report


def test_grid_parsing_and_errors():
    assert parse_ints("0-3,8", "seeds") == (0, 1, 2, 3, 8)
    assert parse_ints("5", "seeds") == (5,)
    assert parse_names("a, b,a", "scenarios") == ("a", "b")
    with pytest.raises(InputError, match="range '5-2' is empty"):
        parse_ints("5-2", "seeds")
    with pytest.raises(InputError, match="not a whole number"):
        parse_ints("x", "seeds")
    with pytest.raises(InputError, match="unknown controller"):
        SweepGrid(scenarios=("cold_storage",), controllers=("pid",), seeds=(0,), train_days=(7,))
    grid = SweepGrid(
        scenarios=("cold_storage",), controllers=("cem", "thermostat"), seeds=(0, 1), train_days=(7, 14)
    )
    cells = grid.cells()
    # cem per seed x training size, thermostat and the (implicit) oracle once per seed
    assert len(cells) == 2 * 2 + 2 + 2
    assert {c.model for c in cells if c.controller == "cem"} == {
        c.model for c in cells if c.model is not None
    }


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--controllers", "oracle,pid", "--seeds", "0"], "unknown controller(s) pid"),
        (["--controllers", "oracle", "--seeds", "3-1"], "range '3-1' is empty"),
        (["--controllers", "oracle", "--seeds", "0", "--address", "no address"], "is not a Ray address"),
        (["--controllers", "oracle", "--seeds", "0", "--address", "127.0.0.1:1"], "no Ray head node answers"),
        (["--controllers", "oracle", "--seeds", "0", "--address", "auto", "--workers", "2"], "leave --workers out"),
        (["--controllers", "oracle", "--seeds", "0", "--test-periods", "peak_heat_day"],
         "test_periods applies to BOPTEST scenarios"),
    ],
)
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, args, message):
    out = tmp_path / "sweep"
    result = sweep_cli("--scenarios", "cold_storage", "--days", "1", "--quick", "--out", str(out), *args)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr
    assert not out.exists()


def test_a_foreign_directory_is_refused_and_left_untouched(tmp_path):
    out = tmp_path / "project"
    out.mkdir()
    (out / "report.md").write_text("my thesis notes\n")
    result = sweep_cli(
        "--scenarios", "cold_storage", "--controllers", "oracle", "--seeds", "0", "--days", "1",
        "--quick", "--out", str(out),
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "not a sweep directory" in lines[0] and "--force" in lines[0]
    assert sorted(p.name for p in out.iterdir()) == ["report.md"]
    assert (out / "report.md").read_text() == "my thesis notes\n"


GRID = [
    "--scenarios", "winter_household,cold_storage",
    "--controllers", "thermostat,qp-mpc,oracle",
    "--seeds", "0-3",
    "--train-days", "7",
    "--days", "1",
    "--quick",
    "--workers", "2",
]


@pytest.mark.slow
def test_sweep_runs_then_reuses_every_cell(tmp_path, monkeypatch):
    out = tmp_path / "sweep"
    first = sweep_cli(*GRID, "--out", str(out))
    assert first.returncode == 0, first.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["cells_run"] == 24 and summary["cells_reused"] == 0
    # one identification per scenario x seed, shared by nothing else here but trained once
    assert summary["models_trained"] == 8
    assert summary["engine"]["name"] == "ray" and summary["engine"]["resources"]["CPU"] == 2
    assert len(list((out / "cells").glob("*.json"))) == 24
    rows = {(r["scenario"], r["controller"]): r for r in summary["rows"]}
    assert len(rows) == 6
    for row in rows.values():
        assert row["n"] == 4
        low, high = row["objective_to_oracle_ci95"]
        assert low <= row["objective_to_oracle_mean"] <= high
    assert rows[("cold_storage", "oracle")]["objective_to_oracle_mean"] == 1.0
    # the thermostat ignores prices and forecasts: it cannot beat the oracle on any seed
    assert all(v > 1.0 for v in rows[("winter_household", "thermostat")]["objective_to_oracle_by_seed"].values())
    report = (out / "report.md").read_text()
    assert report.count("| `winter_household` |") == report.count("| `cold_storage` |") == 3
    assert (out / "objective_to_oracle.png").stat().st_size > 0
    cell_times = {p.name: p.stat().st_mtime_ns for p in (out / "cells").glob("*.json")}

    again = sweep_cli(*GRID, "--out", str(out))
    assert again.returncode == 0, again.stderr[-3000:]
    assert "all 24 cells reused" in again.stdout
    summary2 = json.loads((out / "summary.json").read_text())
    assert summary2["cells_run"] == 0 and summary2["cells_reused"] == 24
    assert summary2["rows"] == summary["rows"]
    assert summary2["engine"] == summary["engine"]  # the engine the cells ran on
    import scenarios.experiments.sweep.engine as engine
    from pinn_mpc_cli.cli import main

    def no_ray(*_args: object) -> None:
        raise AssertionError("a sweep with every cell stored started Ray")

    monkeypatch.setattr(engine, "ray_engine", no_ray)
    assert main(["sweep", *GRID, "--out", str(out)]) == 0  # nothing to run: no engine started
    assert json.loads((out / "summary.json").read_text())["rows"] == summary["rows"]
    assert {p.name: p.stat().st_mtime_ns for p in (out / "cells").glob("*.json")} == cell_times

    other = sweep_cli(*[a if a != "1" else "2" for a in GRID], "--out", str(out))
    assert other.returncode == 2 and "other settings (test_days 1 -> 2)" in other.stderr


@pytest.mark.slow
def test_learned_controllers_share_one_trained_model(tmp_path):
    out = tmp_path / "sweep"
    result = sweep_cli(
        "--scenarios", "cold_storage", "--controllers", "cem,random-shooting", "--seeds", "0",
        "--train-days", "7", "--days", "1", "--quick", "--workers", "2", "--out", str(out),
    )
    assert result.returncode == 0, result.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["models_trained"] == 1 and summary["cells_run"] == 3
    assert [p.name for p in (out / "models").iterdir()] == [f"cold_storage--{ARCH}--seed0--train7"]


@pytest.mark.slow
def test_sigint_keeps_finished_cells_and_the_rerun_completes_the_rest(tmp_path):
    out = tmp_path / "sweep"
    grid = [
        # 16 cells of 1 day: enough left after the third that the interrupt lands mid-sweep
        "--scenarios", "cold_storage", "--controllers", "thermostat,oracle", "--seeds", "0-7",
        "--days", "1", "--quick", "--workers", "2", "--out", str(out),
    ]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "pinn_mpc", "sweep", *grid],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT,
    )
    deadline = time.monotonic() + 600
    cells = out / "cells"
    while time.monotonic() < deadline and len(list(cells.glob("*.json"))) < 3:
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr[-3000:]
    assert "interrupted" in stderr
    kept = {p.name: p.read_text() for p in cells.glob("*.json")}
    assert 3 <= len(kept) < 16, "interrupt came too late to test anything"
    for text in kept.values():
        assert json.loads(text)["kpis"]["objective"] > 0  # complete records, not half-written
    assert not list(cells.glob(".*.tmp"))
    assert not (out / "summary.json").exists()

    rerun = sweep_cli(*grid)
    assert rerun.returncode == 0, rerun.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["cells_reused"] == len(kept)
    assert summary["cells_run"] == 16 - len(kept)
    assert {p.name: p.read_text() for p in cells.glob("*.json") if p.name in kept} == kept


def test_sweep_definition_files_are_read_and_checked(tmp_path):
    from scenarios.experiments.sweep import read_sweep_spec

    root = Path(__file__).resolve().parents[1]
    spec = read_sweep_spec(root / "sweeps" / "robustness.toml")
    assert spec["train_days"] == "14,30,60" and spec["seeds"] == "0-2" and spec["days"] == 3
    assert parse_ints(spec["train_days"], "training days") == (14, 30, 60)
    assert len(parse_names(spec["scenarios"], "scenarios")) == 5
    for committed in sorted((root / "sweeps").glob("*.toml")):  # every one a sweep can run
        read = read_sweep_spec(committed)
        SweepGrid(scenarios=parse_names(read["scenarios"], "scenarios"),
                  controllers=parse_names(read["controllers"], "controllers"),
                  seeds=parse_ints(read["seeds"], "seeds"),
                  train_days=parse_ints(read.get("train_days", "30"), "training days"),
                  **{k: parse_names(read[k], k) for k in ("archs", "test_periods", "price_scenarios") if k in read})
    own = tmp_path / "mine.toml"
    own.write_text('scenarios = ["my.toml", "winter_household"]\nseeds = [0, 3]\n')
    assert read_sweep_spec(own)["scenarios"] == f"{tmp_path / 'my.toml'},winter_household"
    for text, message in (
        ("scenario = ['a']", "unknown key"),
        ("days = 0", "days must be"),
        ("seeds = [true]", "seeds must be"),
        ("scenarios = [", "not a valid TOML"),
    ):
        own.write_text(text)
        with pytest.raises(InputError, match=message):
            read_sweep_spec(own)


def test_sweep_without_a_grid_or_spec_exits_2(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "pinn_mpc", "sweep", "--scenarios", "winter_household", "--out", str(tmp_path / "o")],
        capture_output=True, text=True, check=False,
    )
    assert result.returncode == 2
    assert "sweep needs --controllers, --seeds" in result.stderr
    assert not (tmp_path / "o").exists()


def test_a_sweep_logs_its_progress_when_stderr_is_not_a_terminal(tmp_path, monkeypatch, capsys):
    """Off a terminal (a log file, CI) the sweep says what it starts, each model trained, and
    a progress line every PROGRESS_EVERY_S with the cells done and the models trained."""
    import scenarios.running.closed_loop
    from pinn_mpc_cli.cli import main

    monkeypatch.setattr(scenarios.running.closed_loop, "PROGRESS_EVERY_S", 0.05)
    out = tmp_path / "sweep"
    args = ["--scenarios", "winter_household", "--controllers", "oracle,qp-mpc", "--seeds", "0-1"]
    assert main(["sweep", *args, "--days", "1", "--quick", "--out", str(out)]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("sweep: ")]
    assert re.fullmatch(r"sweep: 4 cell\(s\) to run \(0 reused\), (\d) model\(s\) to train", lines[0])
    models = int(lines[0].split(", ")[1][0])
    assert sum(bool(re.fullmatch(rf"sweep: model .* trained \(\d of {models}\)", line)) for line in lines) == models
    lines = [line for line in lines if " of 4 cells " in line]
    assert lines and "elapsed" in lines[0]
    # the count moves as cells finish (the disabled bar off a terminal counted none)
    assert any(re.match(r"sweep: [1-3] of 4 cells .* left; running or queued: .*cell\(s\)$", line) for line in lines), lines


def test_sweep_trains_on_each_scenarios_own_data_policy(tmp_path):
    """By default a sweep's models learn from the data the scenario's `data_policy` names (as
    simulate and compare use), not one policy for all; an explicit policy still applies to all."""
    from scenarios.experiments.compare import identify_scenario_rc
    from scenarios.experiments.sweep import RC_KIND, ModelKey, SweepSettings, fit_model
    from scenarios.inputs.scenario_file import get_scenario
    from scenarios.running.datagen import generate

    text = Path(_export(tmp_path)).read_text().replace(
        'data_policy = "random-level"', 'data_policy = "closed-loop"'
    )
    path = tmp_path / "closed.toml"
    path.write_text(text)
    scenario = get_scenario(str(path))
    key = ModelKey(scenario=str(path), kind=RC_KIND, seed=3, train_days=4)
    own = identify_scenario_rc(scenario, generate(scenario, days=4, seed=3, policy="closed-loop"))
    other = identify_scenario_rc(scenario, generate(scenario, days=4, seed=3, policy="random-level"))
    assert own != other
    assert SweepSettings().policy == "scenario"
    assert fit_model(key, SweepSettings()) == own
    assert fit_model(key, SweepSettings(policy="random-level")) == other
    with pytest.raises(ValueError, match="policy 'bang-bang' is unknown") as caught:
        SweepSettings(policy="bang-bang")  # a Python caller's: the command line's --policy has choices
    assert not isinstance(caught.value, InputError)


def _export(tmp_path: Path) -> str:
    out = tmp_path / "winter.toml"
    subprocess.run(
        [sys.executable, "-m", "pinn_mpc", "scenario", "export", "winter_household", "--out", str(out)],
        check=True, capture_output=True,
    )
    return str(out)


@pytest.mark.slow
def test_a_sweep_plans_over_the_architecture_it_is_given(tmp_path):
    """--arch: cem plans over the physics-informed ARX, fitted once per scenario x seed x
    training days and stored in the sweep's directory as an ARX model (numbers only); a rerun
    reuses it and another architecture is other settings."""
    from pinn_mpc.choices import PHYSICS_ARX
    from pinn_mpc.models.arx import load_arx

    out = tmp_path / "sweep"
    grid = ["--scenarios", "winter_household", "--controllers", "cem", "--seeds", "0",
            "--train-days", "7", "--days", "1", "--workers", "2", "--out", str(out)]
    result = sweep_cli(*grid, "--arch", PHYSICS_ARX.name)
    assert result.returncode == 0, result.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["models_trained"] == 1 and summary["cells_run"] == 2
    assert json.loads((out / "sweep.json").read_text())["settings"]["arch"] == PHYSICS_ARX.name
    [stored] = (out / "models").iterdir()
    assert stored.name == f"winter_household--{PHYSICS_ARX.name}--seed0--train7"
    assert load_arx(stored).interaction  # the physics-informed variant
    cem = json.loads((out / "cells" / "winter_household--cem--seed0--train7.json").read_text())
    assert cem["kpis"]["controller"] == "cem" and cem["kpis"]["objective"] > 0
    # the commit that ran it: this checkout's (git's own answer), or None outside a checkout
    root = Path(__file__).resolve().parents[1]
    head = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=root, capture_output=True, text=True)
    if (root / ".git").exists() and head.returncode == 0:
        assert cem["code"].split(" + ")[0] == head.stdout.strip()
    else:
        assert cem["code"] is None
    again = sweep_cli(*grid, "--arch", PHYSICS_ARX.name)
    assert again.returncode == 0 and "all 2 cells reused" in again.stdout
    other = sweep_cli(*grid)
    assert other.returncode == 2 and f"arch {PHYSICS_ARX.name!r} -> {ARCH!r}" in other.stderr, other.stderr


def test_a_sweep_definition_names_a_known_architecture(tmp_path):
    from scenarios.experiments.sweep import SweepSettings, read_sweep_spec

    good, bad = tmp_path / "good.toml", tmp_path / "bad.toml"
    good.write_text(f"arch = \"{SweepSettings().arch}\"\n")
    bad.write_text('arch = "transformer"\n')
    assert read_sweep_spec(good) == {"arch": SweepSettings().arch}
    with pytest.raises(InputError, match="arch must be one of"):
        read_sweep_spec(bad)
    with pytest.raises(ValueError, match="arch 'transformer' is unknown") as caught:
        SweepSettings(arch="transformer")  # a Python caller's: the file's arch is checked above
    assert not isinstance(caught.value, InputError)


def test_boptest_grid_cells_labels_and_refusals():
    """sweeps/boptest.toml's grid: every test period x price x controller (cem once per arch)
    x training length, the baseline once per period and price; BOPTEST's keys and controllers
    are checked with one clear error each."""
    from scenarios.experiments.sweep import read_sweep_spec

    def grid_of(name: str) -> SweepGrid:
        spec = read_sweep_spec(ROOT / "sweeps" / name)
        return SweepGrid(
            scenarios=parse_names(spec["scenarios"], "scenarios"),
            controllers=parse_names(spec["controllers"], "controllers"),
            seeds=parse_ints(spec["seeds"], "seeds"), train_days=parse_ints(spec["train_days"], "t"),
            archs=parse_names(spec["archs"], "archs"),
            test_periods=parse_names(spec["test_periods"], "test_periods"),
            price_scenarios=parse_names(spec["price_scenarios"], "price_scenarios"),
        )

    grid = grid_of("boptest.toml")
    assert grid.is_boptest and grid.references == {"boptest_hydronic_heat_pump": "boptest-baseline"}
    assert grid.labels == ("boptest-baseline", "thermostat", "qp-mpc", "cem/auto")
    cells = grid.cells()
    # 4 places x (baseline + thermostat + (qp-mpc + cem) x 2 training lengths)
    assert len(cells) == 4 * (2 + 2 * 2) == len({c.name for c in cells})
    # models are shared by the prices of a test period: one per kind x training length x period
    assert len({c.model for c in cells if c.model is not None}) == 2 * 2 * 2
    families = grid_of("boptest_families.toml")
    assert families.labels == ("boptest-baseline", "cem/hybrid", "cem/physnet", "cem/physreg",
                               "cem/mlp", "cem/arx", "cem/parx")
    cells = families.cells()
    assert len(cells) == 4 * (1 + 6 * 2) == len({c.name for c in cells})
    cem = next(c for c in cells if c.controller == "cem/parx" and c.train_days == 28
               and c.test_period == "typical_heat_day" and c.price_scenario == "highly_dynamic")
    assert cem.name == "boptest_hydronic_heat_pump--typical_heat_day--highly_dynamic--cem-parx--seed0--train28"
    assert cem.model is not None and cem.model.kind == "parx"
    assert cem.model.name == "boptest_hydronic_heat_pump--parx--seed0--train28--near-typical_heat_day"
    base = dict(scenarios=("boptest_hydronic_heat_pump",), seeds=(0,), train_days=(14,))
    for kwargs, message in (
        (dict(controllers=("oracle",)), r"controller\(s\) oracle do not run on BOPTEST"),
        (dict(controllers=("cem",), test_periods=("summer",)), r"test period\(s\) summer are not"),
        (dict(controllers=("cem",), price_scenarios=("cheap",)), r"price scenario\(s\) cheap are not BOPTEST's"),
        (dict(controllers=("cem",), archs=("lstm",)), r"unknown architecture\(s\) lstm"),
        (dict(controllers=("cem",), scenarios=("boptest_hydronic_heat_pump", "cold_storage")), "sweep them separately"),
    ):
        with pytest.raises(InputError, match=message):
            SweepGrid(**{**base, **kwargs})
    with pytest.raises(InputError, match="price_scenarios applies to BOPTEST scenarios"):
        SweepGrid(scenarios=("cold_storage",), controllers=("cem",), seeds=(0,), train_days=(7,),
                  price_scenarios=("dynamic",))
    # archs on the package's own scenarios: cem/<arch> labels, one model each
    own = SweepGrid(scenarios=("cold_storage",), controllers=("cem", "thermostat"), seeds=(0,),
                    train_days=(7,), archs=("hybrid", "parx"))
    assert own.labels == ("cem/hybrid", "cem/parx", "thermostat")
    assert {c.model.kind for c in own.cells() if c.model is not None} == {"hybrid", "parx"}
    assert all(c.test_period is None for c in own.cells())


def test_an_arch_cell_runs_on_the_packages_own_plants() -> None:
    """A ``cem/<arch>`` cell (``archs`` in a sweep) on a non-BOPTEST scenario runs cem over
    the model of that architecture, labelled with the cell's name and the model it planned
    over (it failed as "unknown controller 'cem/parx'" before)."""
    from scenarios.experiments.sweep import Cell, SweepSettings, fit_model, run_cell

    grid = SweepGrid(scenarios=("winter_household",), controllers=("cem",), seeds=(0,),
                     train_days=(7,), archs=("parx",))
    [cell] = [c for c in grid.cells() if c.controller.startswith("cem")]  # and the oracle
    assert cell == Cell(scenario="winter_household", controller="cem/parx", seed=0, train_days=7)
    settings = SweepSettings(test_days=1)
    assert cell.model is not None
    model = fit_model(cell.model, settings)
    result = run_cell(cell, settings, model)
    assert result["errors"] == []
    kpis = result["kpis"]
    assert kpis["controller"] == "cem/parx" and kpis["model"] == "parx"  # type: ignore[typeddict-item]
    assert kpis["objective"] > 0 and kpis["own_decisions_share"] > 0.9


def test_a_sweep_of_a_zoned_building_plans_over_its_trained_model_and_identified_rc(tmp_path):
    """On a building of several zones, cem plans over the hybrid of every zone ``train``
    fits and qp-mpc over the multi-zone RC identified, both on the cell's training data (one
    of each per seed, stored as the model directory and the multi-zone RC file and read back
    on reuse)."""
    out = tmp_path / "zones"
    args = ["--scenarios", "two_zone_house", "--controllers", "cem,qp-mpc", "--seeds", "0",
            "--train-days", "7", "--days", "1", "--quick", "--out", str(out)]
    first = sweep_cli(*args)
    assert first.returncode == 0, first.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["models_trained"] == 2 and summary["cells_run"] == 3
    stored = json.loads(next((out / "models").glob("*--rc--*.json")).read_text())
    assert [z["name"] for z in stored["zones"]] == ["south", "north"]
    model = json.loads(next((out / "models").glob("*--hybrid--*/multizone.json")).read_text())
    assert model["zones"] == ["south", "north"] and model["family"] == "hybrid"
    rows = {r["controller"]: r for r in summary["rows"]}
    for controller in ("cem", "qp-mpc"):
        assert rows[controller]["objective_to_oracle_mean"] < 1.05, rows[controller]
    again = sweep_cli(*args)
    assert again.returncode == 0 and "all 3 cells reused" in again.stdout
