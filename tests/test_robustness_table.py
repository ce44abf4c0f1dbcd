"""benchmarks/robustness_table.py: the robustness sweep's per-cell table, read from a sweep's
cells as the sweep writes them (``sweeps/robustness.toml`` plans over the default model, so its
planners' cells are named ``cem/auto`` and ``random-shooting/auto``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks.robustness_table import load_cells, main


def _cell(directory: Path, controller: str, objective: float, train_days: int | None, fallbacks: int = 0) -> None:
    cell = {"scenario": "winter_household", "controller": controller, "seed": 0, "train_days": train_days}
    kpis = {"objective": objective, "days": 3, "model_fallback_steps": fallbacks}
    name = f"{controller.replace('/', '-')}--{train_days}.json"
    (directory / "cells" / name).write_text(json.dumps({"cell": cell, "kpis": kpis}), encoding="utf-8")


def test_the_default_model_s_planners_are_read_and_tabled(tmp_path, monkeypatch, capsys):
    (tmp_path / "cells").mkdir()
    _cell(tmp_path, "oracle", 100.0, None)
    _cell(tmp_path, "cem/auto", 110.0, 14, fallbacks=3)
    _cell(tmp_path, "random-shooting/auto", 120.0, 14, fallbacks=5)
    _cell(tmp_path, "qp-mpc", 105.0, 14)
    assert {c for _, c, _, _ in load_cells(tmp_path)} == {"oracle", "cem", "random-shooting", "qp-mpc"}
    monkeypatch.setattr("sys.argv", ["robustness_table.py", str(tmp_path)])
    main()
    out = capsys.readouterr().out
    assert "| winter_household | 14 | 0 | 1.100 | 1.200 | 1.050 | 1.048 | 3, 5 of 144 |" in out
    assert "cem: median 1.100, worst 1.100 (winter_household 14 d seed 0)" in out


def test_a_directory_without_cem_over_the_default_model_is_refused(tmp_path):
    (tmp_path / "cells").mkdir()
    _cell(tmp_path, "oracle", 100.0, None)
    _cell(tmp_path, "cem/hybrid", 110.0, 14)
    with pytest.raises(SystemExit, match="no cells of cem over the default model"):
        load_cells(tmp_path)
