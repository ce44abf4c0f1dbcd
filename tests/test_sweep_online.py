"""A sweep's controllers run online (``cem-online``, ``qp-mpc-online``): the grid's labels and
checks, a cell's ``online`` and ``per_day`` blocks, the per-week table's arithmetic and the
results page."""

import importlib.util
import json
from pathlib import Path

import pytest

from pinn_mpc.errors import InputError
from scenarios.choices import ONLINE_CONTROLLERS, online_controller
from scenarios.experiments.sweep import Cell, SweepGrid, SweepSettings, read_sweep_spec, run_cell
from scenarios.reports.online_report import WEEK_DAYS, online_section, week_rows
from scenarios.reports.sweep_report import summarise

ROOT = Path(__file__).resolve().parents[1]
TINY = SweepSettings(test_days=2, n_members=2, epochs=2, quick=True)


def test_online_labels_name_the_controller_they_run_online():
    assert [online_controller(f"{c}-online") for c in ONLINE_CONTROLLERS] == list(ONLINE_CONTROLLERS)
    assert online_controller("cem") is None
    assert online_controller("oracle-online") is None  # the oracle knows the building: nothing to learn


def test_an_online_cell_starts_from_its_days_of_data():
    grid = SweepGrid(scenarios=("winter_household",), controllers=("cem-online", "cem"), seeds=(0, 1),
                     train_days=(14,), start_days=5)
    by_label = {(c.controller, c.seed): c for c in grid.cells()}
    assert by_label[("cem-online", 0)].train_days == 5  # its data at hand, not the training days
    assert by_label[("cem-online", 0)].model is None  # it fits its own
    assert by_label[("cem", 1)].train_days == 14
    assert by_label[("oracle", 1)].train_days is None


def test_online_cells_are_refused_where_they_cannot_run():
    with pytest.raises(InputError, match="unknown controller.*cem-online"):
        SweepGrid(scenarios=("winter_household",), controllers=("oracle-online",), seeds=(0,), train_days=(14,))
    with pytest.raises(InputError, match="several zones"):
        SweepGrid(scenarios=("eplus_small_office_zones",), controllers=("cem-online",), seeds=(0,), train_days=(14,))
    with pytest.raises(InputError, match="start days"):
        SweepGrid(scenarios=("winter_household",), controllers=("cem-online",), seeds=(0,), train_days=(14,),
                  start_days=-1)


def test_the_definition_file_gives_start_days(tmp_path: Path):
    spec = tmp_path / "s.toml"
    spec.write_text('controllers = ["cem-online", "cem"]\nstart_days = 4\n')
    assert read_sweep_spec(spec)["start_days"] == 4
    spec.write_text("start_days = -2\n")
    with pytest.raises(InputError, match="start_days must be a whole number >= 0"):
        read_sweep_spec(spec)
    committed = read_sweep_spec(ROOT / "sweeps" / "online_households.toml")
    assert committed["start_days"] == 3 and committed["days"] == 28


def _day(day: int, objective: float, error: float | None = None) -> dict:
    return {"day": day, "objective": objective, "discomfort_kh": objective / 10,
            "own_decisions_share": 0.5 if day == 1 else 1.0, "model_day_ahead_error_c": error}


def _record(controller: str, seed: int, days: list[dict], train_days: int | None) -> dict:
    kpis: dict = {"objective": sum(d["objective"] for d in days), "days": len(days)}
    if online_controller(controller):
        kpis["online"] = {"days": days}
    else:
        kpis["per_day"] = days
    return {"cell": {"scenario": "winter_household", "controller": controller, "seed": seed,
                     "train_days": train_days}, "kpis": kpis}


def test_the_weeks_sum_the_days_and_divide_by_the_baselines_same_weeks():
    """9 days: week 1 is days 1-7, week 2 days 8-9; the sums, means over seeds, worst seeds and
    ratios written out by hand."""
    online = {0: [_day(d, 2.0, 0.2) for d in range(1, 10)], 1: [_day(d, 4.0, 0.4) for d in range(1, 10)]}
    pretrained = {0: [_day(d, 1.0) for d in range(1, 10)], 1: [_day(d, 5.0) for d in range(1, 10)]}
    records = [_record("cem-online", s, days, 3) for s, days in online.items()]
    records += [_record("cem", s, days, 14) for s, days in pretrained.items()]
    rows = {(r.controller, r.week): r for r in week_rows(records, baseline="cem")}
    assert WEEK_DAYS == 7
    week1, week2 = rows[("cem-online", 1)], rows[("cem-online", 2)]
    assert (week1.first_day, week1.last_day, week2.first_day, week2.last_day) == (1, 7, 8, 9)
    assert week1.objective_mean == pytest.approx((14.0 + 28.0) / 2)
    assert (week1.objective_worst, week1.objective_worst_seed) == (pytest.approx(28.0), 1)
    assert week1.to_baseline_mean == pytest.approx(21.0 / ((7.0 + 35.0) / 2))
    # seed 0: 14 / 7 = 2.0, seed 1: 28 / 35 = 0.8; the worst seed is by its ratio
    assert (week1.to_baseline_worst, week1.to_baseline_worst_seed) == (pytest.approx(2.0), 0)
    assert week2.objective_mean == pytest.approx((4.0 + 8.0) / 2)
    assert week1.discomfort_kh_mean == pytest.approx(2.1)
    assert week1.own_share_mean == pytest.approx((0.5 + 6) / 7)
    assert week2.own_share_mean == 1.0
    assert week1.day_ahead_error_c_mean == pytest.approx(0.3)
    assert rows[("cem", 1)].day_ahead_error_c_mean is None
    assert week_rows([r for r in records if r["cell"]["controller"] == "cem"], baseline="cem") == []


@pytest.fixture(scope="module")
def online_records() -> list[dict]:
    """Two days of cem and qp-mpc run online on winter_household from 3 days of data (tiny
    ensembles): the sweep's cells as ``run_cell`` returns them."""
    records = []
    for controller in ("cem-online", "qp-mpc-online"):
        cell = Cell(scenario="winter_household", controller=controller, seed=0, train_days=3)
        result = run_cell(cell, TINY, None)
        records.append({"cell": {"scenario": cell.scenario, "controller": controller, "seed": 0,
                                 "train_days": 3}, **result})
    return records


@pytest.mark.slow
def test_an_online_cell_keeps_its_days_and_its_nights(online_records):
    cem, qp = online_records
    for record in online_records:
        kpis = record["kpis"]
        days = kpis["online"]["days"]
        assert [d["day"] for d in days] == [1, 2] and [d["day"] for d in kpis["per_day"]] == [1, 2]
        # the days partition the run: cost and discomfort add up
        assert sum(d["objective"] for d in days) == pytest.approx(kpis["objective"], rel=1e-9)
        assert sum(d["discomfort_kh"] for d in days) == pytest.approx(kpis["discomfort_kh"], abs=1e-9)
        assert [e["verdict"] for e in record["online_log"]] == ["initial", record["online_log"][1]["verdict"]]
    assert cem["kpis"]["controller"] == "cem-online"
    assert cem["online_log"][0]["model"] == "model"  # 3 days: a model from the start
    assert all(e["model"] is None for e in qp["online_log"])  # qp-mpc refits the RC alone
    assert [d["controller"] for d in qp["kpis"]["online"]["days"]] == ["rc", "rc"]
    assert qp["kpis"]["online"]["days"][1]["model_day_ahead_error_c"] is None


@pytest.mark.slow
def test_the_results_page_has_the_weeks_of_the_online_cells(online_records, tmp_path: Path):
    spec = importlib.util.spec_from_file_location("gen_results", ROOT / "docs" / "gen_results.py")
    assert spec and spec.loader
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    baseline = _record("cem", 0, [_day(1, 5.0), _day(2, 5.0)], 14)
    oracle = _record("oracle", 0, [_day(1, 4.0), _day(2, 4.0)], None)
    records = [*online_records, baseline, oracle]
    sweep = tmp_path / "sweep"
    (sweep / "cells").mkdir(parents=True)
    for i, record in enumerate(records):
        (sweep / "cells" / f"{i}.json").write_text(json.dumps(record))
    summary = {"rows": summarise(records, baseline="cem", order=["cem-online", "cem", "qp-mpc-online"]),
               "baseline": "cem", "cells_run": 4, "cells_reused": 0, "models_trained": 0, "settings": {}}
    (sweep / "summary.json").write_text(json.dumps(summary))
    page_path = tmp_path / "online.md"
    figure = gen.days_figure(sweep, page_path)
    assert figure == "online_days.png" and (tmp_path / figure).stat().st_size > 0
    text = gen.page(ROOT / "sweeps" / "online_households.toml", sweep, "cmd", None, "abc", figure)
    week = online_records[0]["kpis"]["objective"]  # two days: one (short) week
    assert f"| winter_household | cem-online | 3 | 1 (1-2) | 1 | {week:.2f} |" in text
    assert f"| {week / 10.0:.3f} |" in text  # / cem's 10 EUR
    assert "![objective per day of service, mean over seeds](online_days.png)" in text
    assert online_section([baseline, oracle], baseline="cem", figure_name=None) == []
