"""The paper-reproduction pipeline, end to end on a tiny configuration (real data, training,
evaluation, figures and report)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from pinn_mpc.cli import main
from pinn_mpc.errors import InputError
from scenarios.datagen import generate
from scenarios.registry import get_scenario
from scenarios.reproduce import (
    PAPER_VALIDATION,
    ReproduceConfig,
    run_reproduction,
    validation_table,
)

TINY = ReproduceConfig(
    seeds=2,
    epochs=3,
    validation_days=4,
    train_days=(2, 4),
    size_horizons=(2, 4),
    horizon_days=(2, 4),
    horizons=(1, 3, 6),
    test_days=1,
)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("repro") / "nested" / "out"  # parents are created
    results = run_reproduction(out, TINY, progress=False)
    return out, results


def _finite(values: list[float]) -> bool:
    return all(isinstance(v, float) and math.isfinite(v) for v in values)


def test_writes_every_file(tiny_run: tuple[Path, dict]) -> None:
    out, _ = tiny_run
    names = {p.name for p in out.iterdir()}
    assert names == {
        "results.json",
        "report.md",
        "table1_validation.md",
        "table2_training_size.md",
        "table3_horizon.md",
        "fig1_validation.png",
        "fig2_training_size.png",
        "fig3_horizon.png",
    }
    for png in out.glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.glob(".*")), "temporary files left behind"


def test_results_json_matches_returned_results(tiny_run: tuple[Path, dict]) -> None:
    out, results = tiny_run
    on_disk = json.loads((out / "results.json").read_text())
    assert on_disk["validation"] == json.loads(json.dumps(results["validation"]))
    assert on_disk["sizes"] == [2, 4]


def test_validation_numbers(tiny_run: tuple[Path, dict]) -> None:
    _, results = tiny_run
    val = results["validation"]
    for arch in ("mlp", "physreg", "physnet"):
        t_r = val[arch]["T_r"]
        assert len(t_r["members"]) == TINY.seeds
        assert _finite([t_r["mean"], t_r["std"], t_r["ensemble"], *t_r["members"]])
        assert t_r["mean"] == pytest.approx(np.mean(t_r["members"]), rel=1e-12)
        # The ensemble mean is never worse than the average member (MAE is convex).
        assert t_r["ensemble"] <= t_r["mean"] + 1e-12
    assert val["mlp"]["T_m"] is None
    for arch in ("physreg", "physnet"):
        assert _finite([val[arch]["T_m"]["mean"], val[arch]["T_m"]["std"]])


def test_experiment_blocks_are_consistent(tiny_run: tuple[Path, dict]) -> None:
    _, results = tiny_run
    runs = results["runs"]
    for h in ("2", "4"):
        block = results["training_size"][h]
        assert block["days"] == [2, 4]
        for arch in ("mlp", "physreg", "physnet"):
            assert [s["mean"] for s in block[arch]] == [
                runs[arch][d]["horizons"][h]["mean"] for d in ("2", "4")
            ]
        assert block["persistence"] == [results["persistence"][h]] * 2
    for d in ("2", "4"):
        block = results["horizon"][d]
        assert block["horizons"] == [1, 3, 6]
        # The 1-step recursive error is the one-step error.
        for arch in ("mlp", "physreg", "physnet"):
            assert block[arch][0]["mean"] == pytest.approx(
                runs[arch][d]["one_step"]["T_r_mae"]["mean"], rel=1e-5
            )
        assert _finite(block["persistence"])

def test_persistence_by_hand(tiny_run: tuple[Path, dict]) -> None:
    """Persistence predicts T_r,i+h = T_r,i from every start i with a full depth window."""
    _, results = tiny_run
    test = generate(get_scenario(TINY.scenario), days=TINY.test_days, seed=TINY.test_seed)
    t_r = test["T_r"].to_numpy(dtype=float)
    for h in (1, 3, 6):
        starts = np.arange(TINY.depth + 1, len(t_r) - h)
        expected = np.mean(np.abs(t_r[starts + h] - t_r[starts]))
        assert results["persistence"][str(h)] == pytest.approx(expected, rel=1e-12)


def test_tables_and_report(tiny_run: tuple[Path, dict]) -> None:
    out, _ = tiny_run
    table = (out / "table1_validation.md").read_text()
    for label, arch in (("MLP", "mlp"), ("PhysReg MLP", "physreg"), ("PhysNet", "physnet")):
        row = next(line for line in table.splitlines() if line.startswith(f"| {label} |"))
        assert f"{PAPER_VALIDATION[arch]['T_r']:.3f}" in row
        assert "nan" not in row
    sizes = (out / "table2_training_size.md").read_text()
    assert sizes.count("| 2 |") == 2 and sizes.count("| 4 |") == 2
    horizons = (out / "table3_horizon.md").read_text()
    assert horizons.count("| 6 |") == 2
    report = (out / "report.md").read_text()
    for needle in ("fig1_validation.png", "fig2_training_size.png", "fig3_horizon.png",
                   "cold-storage", "reduced run"):
        assert needle in report


def test_text_summary_is_the_validation_table(tiny_run: tuple[Path, dict]) -> None:
    _, results = tiny_run
    lines = validation_table(results, markdown=False).splitlines()
    assert len(lines) == 4 and lines[0].startswith("architecture")
    mlp = results["validation"]["mlp"]["T_r"]
    assert lines[1].split()[:4] == ["MLP", f"{mlp['mean']:.3f}", "±", f"{mlp['std']:.3f}"]
    assert "n/a" in lines[1] and "1.413" in lines[1]


def test_quick_and_default_configurations() -> None:
    quick = ReproduceConfig.quick()
    assert quick.seeds == 3 and quick.epochs is not None
    assert quick.sizes() == [15, 60, 120]
    assert ReproduceConfig.quick(7).seeds == 7
    full = ReproduceConfig()
    assert full.seeds == 20 and full.epochs is None
    assert full.sizes() == [15, 30, 45, 60, 90, 120]
    assert full.eval_horizons() == [1, 6, 12, 24, 36, 48]
    # Experiments 2-3 also run on the paper's own setting, a (simulated) cold store.
    assert full.also_scenarios == ("cold_storage",) == quick.also_scenarios


def test_bad_configuration_is_refused() -> None:
    with pytest.raises(InputError, match="too short"):
        ReproduceConfig(test_days=1, horizons=(1, 48))
    with pytest.raises(InputError, match="seeds must be >= 1"):
        ReproduceConfig(seeds=0)
    with pytest.raises(InputError, match="nowhere"):
        ReproduceConfig(also_scenarios=("nowhere",))


def test_cli_refuses_output_under_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["reproduce", "--out", str(blocker / "out"), "--quick"]) == 2
    assert "is a file" in capsys.readouterr().err


def test_cold_storage_runs_the_same_experiments(tmp_path: Path) -> None:
    config = dataclasses.replace(TINY, scenario="cold_storage", also_scenarios=())
    results = run_reproduction(tmp_path / "cold_storage", config, progress=False)
    assert results["config"]["scenario"] == "cold_storage"
    assert results["training_size"]["4"]["days"] == [2, 4]
    assert results["horizon"]["2"]["horizons"] == [1, 3, 6]
    report = (tmp_path / "cold_storage" / "report.md").read_text()
    assert "Scenario `cold_storage` (" in report and "household" not in report.split("\n")[2]
