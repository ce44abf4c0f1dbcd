"""The paper-reproduction pipeline, end to end on a tiny configuration (real data, training,
evaluation, figures and report)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from pinn_mpc_cli.cli import main
from scenarios.experiments.reproduce import (
    PAPER_VALIDATION,
    ReproduceConfig,
    ReproductionResults,
    run_reproduction,
    validation_table,
)
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate

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
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, ReproductionResults]:
    out = tmp_path_factory.mktemp("repro") / "nested" / "out"  # parents are created
    results = run_reproduction(out, TINY, progress=False)
    return out, results


def _finite(values: list[float]) -> bool:
    return all(isinstance(v, float) and math.isfinite(v) for v in values)


def test_writes_every_file(tiny_run: tuple[Path, ReproductionResults]) -> None:
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


def test_results_json_is_the_typed_results(tiny_run: tuple[Path, ReproductionResults]) -> None:
    out, results = tiny_run
    on_disk = json.loads((out / "results.json").read_text())
    assert on_disk == json.loads(json.dumps(results.to_json()))
    assert on_disk["sizes"] == [2, 4]
    assert list(on_disk) == [
        "config", "hyperparameters", "sizes", "dates", "paper", "validation", "naive_t_m_mae",
        "training_size", "horizon", "persistence", "runs", "train_seconds_total",
    ]


def test_validation_numbers(tiny_run: tuple[Path, ReproductionResults]) -> None:
    _, results = tiny_run
    val = results.validation
    for arch in ("mlp", "physreg", "physnet"):
        t_r = val[arch].one_step_t_r
        assert len(t_r.members) == TINY.seeds
        assert _finite([t_r.mean, t_r.std, t_r.ensemble, *t_r.members])
        assert t_r.mean == pytest.approx(np.mean(t_r.members), rel=1e-12)
        assert t_r.std == pytest.approx(np.std(t_r.members), rel=1e-12)
        # The ensemble mean is never worse than the average member (MAE is convex).
        assert t_r.ensemble <= t_r.mean + 1e-12
    assert val["mlp"].one_step_t_m is None
    for arch in ("physreg", "physnet"):
        t_m = val[arch].one_step_t_m
        assert t_m is not None and _finite([t_m.mean, t_m.std])


def test_experiment_blocks_are_consistent(tiny_run: tuple[Path, ReproductionResults]) -> None:
    _, results = tiny_run
    runs = results.runs
    for h in (2, 4):
        block = results.training_size[h]
        assert block.x == (2, 4)
        for arch in ("mlp", "physreg", "physnet"):
            assert block.errors[arch] == tuple(runs[arch][d].horizons[h] for d in (2, 4))
        assert block.persistence == (results.persistence[h],) * 2
    for d in (2, 4):
        block = results.horizon[d]
        assert block.x == (1, 3, 6)
        # The 1-step recursive error is the one-step error.
        for arch in ("mlp", "physreg", "physnet"):
            assert block.errors[arch][0].mean == pytest.approx(
                runs[arch][d].one_step_t_r.mean, rel=1e-5
            )
        assert _finite(list(block.persistence))


def test_persistence_by_hand(tiny_run: tuple[Path, ReproductionResults]) -> None:
    """Persistence predicts T_r,i+h = T_r,i from every start i with a full depth window."""
    _, results = tiny_run
    test = generate(
        get_scenario(TINY.scenario), days=TINY.test_days, seed=TINY.test_seed, weather_part="test"
    )
    t_r = test["T_r"].to_numpy(dtype=float)
    for h in (1, 3, 6):
        starts = np.arange(TINY.depth + 1, len(t_r) - h)
        expected = np.mean(np.abs(t_r[starts + h] - t_r[starts]))
        assert results.persistence[h] == pytest.approx(expected, rel=1e-12)


def test_tables_and_report(tiny_run: tuple[Path, ReproductionResults]) -> None:
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
    for name in ("table1_validation.md", "table2_training_size.md", "table3_horizon.md"):
        assert (out / name).read_text().rstrip("\n") in report
    # Training and test days are stated and do not overlap.
    dates = json.loads((out / "results.json").read_text())["dates"]
    assert dates["training"][1] < dates["test"][0]
    assert f"{dates['training'][0]} to {dates['training'][1]}, the training part" in report
    assert f"{dates['test'][0]} to {dates['test'][1]}, the test part" in report


def _cell(stats: dict | None) -> str:
    return "n/a" if stats is None else f"{stats['mean']:.3f} ± {stats['std']:.3f}"


def test_tables_are_the_json_numbers_in_the_published_layout(
    tiny_run: tuple[Path, ReproductionResults],
) -> None:
    """The table files, rebuilt here cell by cell from results.json in the layout the tables
    have had since the first reproduction (so a refactor cannot change them unnoticed)."""
    out, _ = tiny_run
    doc = json.loads((out / "results.json").read_text())
    names = {"mlp": "MLP", "physreg": "PhysReg MLP", "physnet": "PhysNet"}
    lines = [
        "| architecture | T_r MAE [C] | T_r ens. | paper T_r | T_m MAE [C] | T_m ens. | paper T_m |",
        "|---|---|---|---|---|---|---|",
    ]
    for arch, name in names.items():
        v, paper = doc["validation"][arch], PAPER_VALIDATION[arch]
        t_m_ens = "n/a" if v["T_m"] is None else f"{v['T_m']['ensemble']:.3f}"
        lines.append(
            f"| {name} | {_cell(v['T_r'])} | {v['T_r']['ensemble']:.3f} | {paper['T_r']:.3f} | "
            f"{_cell(v['T_m'])} | {t_m_ens} | {paper['T_m']:.3f} |"
        )
    assert (out / "table1_validation.md").read_text() == "\n".join(lines) + "\n"

    def series(key: str, x_key: str, header: str, titles: dict[str, str]) -> str:
        parts = []
        for k, title in titles.items():
            block = doc[key][k]
            rows = [
                f"| {header} | MLP [C] | PhysReg MLP [C] | PhysNet [C] | persistence [C] |",
                "|---|---|---|---|---|",
            ]
            for i, x in enumerate(block[x_key]):
                cells = " | ".join(_cell(block[a][i]) for a in names)
                rows.append(f"| {x} | {cells} | {block['persistence'][i]:.3f} |")
            parts.append(f"**{title}**\n\n" + "\n".join(rows))
        return "\n\n".join(parts) + "\n"

    sizes = {"2": "2 steps (1 h)", "4": "4 steps (2 h)"}
    horizons = {"2": "2 training days", "4": "4 training days"}
    assert (out / "table2_training_size.md").read_text() == series(
        "training_size", "days", "days", sizes
    )
    assert (out / "table3_horizon.md").read_text() == series(
        "horizon", "horizons", "steps", horizons
    )


def test_text_summary_is_the_validation_table(tiny_run: tuple[Path, ReproductionResults]) -> None:
    _, results = tiny_run
    lines = validation_table(results, markdown=False).splitlines()
    assert len(lines) == 4 and lines[0].startswith("architecture")
    mlp = results.validation["mlp"].one_step_t_r
    assert lines[1].split()[:4] == ["MLP", f"{mlp.mean:.3f}", "±", f"{mlp.std:.3f}"]
    assert "n/a" in lines[1] and "1.413" in lines[1]
    # Fixed width: every column starts at the same character on every line.
    assert len({len(line) for line in lines}) == 1


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
    with pytest.raises(ValueError, match="too short"):
        ReproduceConfig(test_days=1, horizons=(1, 48))
    with pytest.raises(ValueError, match="seeds must be >= 1"):
        ReproduceConfig(seeds=0)
    with pytest.raises(ValueError, match="nowhere"):
        ReproduceConfig(also_scenarios=("nowhere",))


def test_cli_refuses_output_under_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["reproduce", "--out", str(blocker / "out"), "--quick"]) == 2
    assert "is a file" in capsys.readouterr().err


def test_cold_storage_runs_the_same_experiments(tmp_path: Path) -> None:
    config = dataclasses.replace(TINY, scenario="cold_storage", also_scenarios=())
    results = run_reproduction(tmp_path / "cold_storage", config, progress=False)
    assert results.config.scenario == "cold_storage"
    assert results.training_size[4].x == (2, 4)
    assert results.horizon[2].x == (1, 3, 6)
    report = (tmp_path / "cold_storage" / "report.md").read_text()
    assert "Scenario `cold_storage` (" in report and "household" not in report.split("\n")[2]
