"""The typed records against what their producers really write.

Each record of :mod:`scenarios.records` and :mod:`pinn_mpc.records` must have every required
key of its TypedDict and no key it does not declare (nested records, lists and dicts of them
checked alike, leaf values by their declared type), on short real runs: a producer that adds,
drops or renames a key fails here. Records built as TypedDict literals are checked by mypy too;
those built from dynamic keys (the RC summary, a fleet's KPIs and totals, the sweep's settings
and rows) only here.
"""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from typing import Any, Union

import pytest

from pinn_mpc.records import EvaluationMetrics, RcSummary, ReplayMarginReport, TrustReport
from pinn_mpc_cli.cli import main
from scenarios.inputs.scenario_file import get_scenario
from scenarios.records import (
    BuildingKpis,
    CapAccount,
    CellRecord,
    CellResult,
    CompareRow,
    FleetInfo,
    FleetJson,
    FleetTotals,
    Kpis,
    PredictionRow,
    RunKpis,
    SweepRow,
    SweepSettingsRecord,
)

_LEAVES: dict[Any, tuple[type, ...]] = {
    float: (float, int), int: (int,), str: (str,), bool: (bool,), type(None): (type(None),),
    Any: (object,), object: (object,),
}


def assert_record(value: Any, record: Any, where: str = "record") -> None:
    """``value`` has every required key of the TypedDict ``record`` and no other than its
    optional ones; each value matches its declared type (nested TypedDicts alike)."""
    assert isinstance(value, dict), f"{where}: {type(value).__name__}, not a dict"
    keys = set(value)
    missing = sorted(record.__required_keys__ - keys)
    undeclared = sorted(keys - record.__required_keys__ - record.__optional_keys__)
    assert not missing and not undeclared, (
        f"{where} ({record.__name__}): missing {missing}, undeclared {undeclared}"
    )
    hints = typing.get_type_hints(record)
    for key in keys:
        _assert_type(value[key], hints[key], f"{where}.{key}")


def _assert_type(value: Any, tp: Any, where: str) -> None:
    if typing.is_typeddict(tp):
        assert_record(value, tp, where)
        return
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (Union, types.UnionType):
        errors = []
        for option in args:
            try:
                _assert_type(value, option, where)
                return
            except AssertionError as exc:
                errors.append(str(exc))
        raise AssertionError(f"{where}: {value!r} matches none of {tp}: {errors}")
    if origin is list:
        assert isinstance(value, list), f"{where}: {type(value).__name__}, not a list"
        for i, item in enumerate(value):
            _assert_type(item, args[0], f"{where}[{i}]")
    elif origin is dict:
        assert isinstance(value, dict), f"{where}: {type(value).__name__}, not a dict"
        for k, item in value.items():
            assert isinstance(k, args[0]), f"{where}: key {k!r} not {args[0]}"
            _assert_type(item, args[1], f"{where}[{k!r}]")
    else:
        allowed = _LEAVES[tp]
        ok = isinstance(value, allowed) and not (isinstance(value, bool) and tp in (int, float))
        assert ok, f"{where}: {value!r} ({type(value).__name__}) is not {tp}"


def test_the_check_refuses_an_undeclared_a_missing_and_a_mistyped_key():
    kpis = dict.fromkeys(Kpis.__annotations__, 0.0) | {"backup_overrides": 0, "fallbacks": 0, "zones": {}}
    assert_record(kpis, Kpis)
    with pytest.raises(AssertionError, match="undeclared \\['new_kpi'\\]"):
        assert_record({**kpis, "new_kpi": 1.0}, Kpis)
    with pytest.raises(AssertionError, match="missing \\['peak_kw'\\]"):
        assert_record({k: v for k, v in kpis.items() if k != "peak_kw"}, Kpis)
    with pytest.raises(AssertionError, match="fallbacks"):
        assert_record({**kpis, "fallbacks": 1.5}, Kpis)


def test_kpi_and_fleet_total_keys_are_the_records_in_order():
    from scenarios.fleets.fleet import FLEET_TOTAL_KEYS
    from scenarios.running.kpis import KPI_KEYS

    assert tuple(Kpis.__annotations__) == KPI_KEYS
    assert tuple(FleetTotals.__annotations__) == FLEET_TOTAL_KEYS
    # CompareRow adds what ran and the ratio to the reference, nothing else
    assert set(CompareRow.__annotations__) - set(RunKpis.__annotations__) == {
        "name", "model", "objective_to_oracle", "objective_to_thermostat",
    }


def test_a_closed_loop_writes_run_kpis(tmp_path):
    from controllers.thermostat import Thermostat
    from scenarios.running.closed_loop import run_closed_loop

    scenario = get_scenario("winter_household")
    result = run_closed_loop(scenario, Thermostat(scenario.control_spec()), days=1, seed=0, warmup_steps=4)
    assert_record(result.kpis, RunKpis)
    assert not RunKpis.__optional_keys__ & set(result.kpis)  # no trust report, no file
    assert_record({k: result.kpis[k] for k in Kpis.__annotations__}, Kpis)
    # the CLI's JSON, with a scenario file: scenario_file added
    toml = tmp_path / "mine.toml"
    assert main(["scenario", "export", "winter_household", "--out", str(toml)]) == 0
    out = tmp_path / "kpis.json"
    assert main(["closed-loop", "--scenario", str(toml), "--controller", "thermostat",
                 "--days", "1", "--json", str(out)]) == 0
    written = json.loads(out.read_text())
    assert_record(written, RunKpis)
    assert "scenario_file" in written


def test_a_planner_over_a_learned_model_adds_its_trust_report():
    from pinn_mpc.models.rc import RCBatchModel
    from scenarios.running.closed_loop import run_closed_loop
    from scenarios.running.factory import build_controller

    scenario = get_scenario("winter_household")
    sim = scenario.sim
    model = RCBatchModel(sim.params, dt_s=sim.dt_s, actuator=sim.actuators[0], backup_low_c=sim.backup_low_c,
                         backup_high_c=sim.backup_high_c)
    controller = build_controller("cem", scenario, model=model, n_steps=48,
                                  planner_options={"n_samples": 16, "n_iters": 1})
    assert_record(controller.trust_report, TrustReport)
    result = run_closed_loop(scenario, controller, days=1, seed=0, warmup_steps=4)
    assert_record(result.kpis, RunKpis)
    assert set(TrustReport.__annotations__) <= set(result.kpis)
    # the trust keys a run may have are exactly the trust report's and an RC MPC's replay
    # margin's (the rest: a scenario file's name, the per-day figures a sweep asks for and a
    # BOPTEST run's own)
    boptest = {"boptest", "boptest_testcase", "boptest_version", "test_period", "price_scenario"}
    assert set(RunKpis.__optional_keys__) - {"scenario_file", "per_day"} - boptest == set(
        TrustReport.__annotations__
    ) | set(ReplayMarginReport.__annotations__)


def test_an_rc_mpc_planning_with_its_replay_margin_reports_it():
    from controllers.rc_mpc.osqp import QPMPC
    from controllers.trust import TrustSettings
    from scenarios.running.closed_loop import run_closed_loop

    scenario = get_scenario("winter_household")
    mpc = QPMPC(scenario.sim.params, scenario.control_spec())
    assert mpc.replay_report is None
    mpc.plan_with_replay_margin(TrustSettings(margin_from_replay=True))
    run_closed_loop(scenario, mpc, days=1, seed=0, warmup_steps=4)
    assert_record(mpc.replay_report, ReplayMarginReport)


def test_prediction_rows_and_rc_summaries():
    from pinn_mpc.models.arx import fit_arx
    from pinn_mpc.physics import rc_summary
    from scenarios.experiments.prediction import prediction_errors
    from scenarios.running.datagen import generate

    scenario = get_scenario("winter_household")
    data = generate(scenario, days=3, seed=0, policy="random-level")
    rows = prediction_errors(
        data, learned={}, linear={"ARX": fit_arx(data)}, rc={"true RC": scenario.sim.params},
        actuator=scenario.sim.actuator,
    )
    assert len(rows) == 2
    for row in rows:
        assert_record(row, PredictionRow)
    summary = rc_summary(scenario.sim.params, source="test")
    assert_record(summary, RcSummary)
    assert not RcSummary.__optional_keys__ & set(summary)


def test_identify_evaluate_and_export_write_their_records(tmp_path):
    from pinn_mpc.evaluation import evaluate_model
    from pinn_mpc.export import export_rc
    from pinn_mpc.training import TrainConfig, train_model
    from tests.model_data import household_data

    data, test = tmp_path / "data.csv", tmp_path / "test.csv"
    household_data(4, 0).to_csv(data, index=False)
    household_data(2, 1).to_csv(test, index=False)
    rc = tmp_path / "rc.json"
    assert main(["identify", "--data", str(data), "--out", str(rc)]) == 0
    identified = json.loads(rc.read_text())
    assert_record(identified, RcSummary)
    assert "fit" in identified
    arx, metrics = tmp_path / "arx", tmp_path / "arx.json"
    assert main(["train", "--data", str(data), "--arch", "arx", "--out", str(arx)]) == 0
    assert main(["evaluate", "--model", str(arx), "--data", str(test), "--horizons", "1,3",
                 "--json", str(metrics)]) == 0
    assert_record(json.loads(metrics.read_text()), EvaluationMetrics)
    model = train_model(household_data(4, 0), arch="physreg",
                        config=TrainConfig(n_seeds=2, epochs=1, depth=4), progress=False)
    full = evaluate_model(model, household_data(2, 1), [1, 3])
    assert_record(full, EvaluationMetrics)
    assert set(full["one_step"]) == {"T_r_mae", "u_phys_mae", "T_m_mae"} and "persistence" in full
    exported = export_rc(model, source="test")
    assert_record(exported, RcSummary)
    assert "member_coefficients_per_s" in exported


def test_a_fleet_writes_its_records():
    from scenarios.fleets.fleet import fleet_json, run_fleet_closed_loop

    scenario = get_scenario("winter_household")
    result = run_fleet_closed_loop(scenario, "thermostat", n_buildings=2, days=1, seed=0, warmup_steps=4)
    for kpis in result.kpis:
        assert_record(kpis, BuildingKpis)
    assert_record(result.totals, FleetTotals)
    assert_record(result.info, FleetInfo)
    assert result.cap is None
    assert_record(json.loads(json.dumps(fleet_json(result, "winter_household"))), FleetJson)


def test_a_capped_batched_fleet_writes_its_records():
    from scenarios.fleets.aggregator import run_coordinated_fleet
    from scenarios.fleets.fleet import fleet_json

    scenario = get_scenario("winter_household")
    result = run_coordinated_fleet(scenario, "qp-mpc", n_buildings=2, days=1, seed=0, cap_kw=3.0,
                                   cap_window="06:00-09:00", warmup_steps=4)
    for kpis in result.kpis:
        assert_record(kpis, BuildingKpis)
        assert "model_fallback_steps" in kpis
    assert_record(result.totals, FleetTotals)
    assert_record(result.info, FleetInfo)
    assert {"batched", "plans_per_step", "dual_ascent"} <= set(result.info)
    assert_record(result.cap, CapAccount)
    assert "curtailed_steps" in (result.cap or {})
    assert_record(json.loads(json.dumps(fleet_json(result, "winter_household"))), FleetJson)


def test_a_sweep_cell_its_record_and_the_summary_rows(tmp_path):
    from scenarios.experiments.sweep import Cell, SweepSettings, run_cell
    from scenarios.experiments.sweep.store import _cell_record_key, _read_cell, _settings_record
    from scenarios.reports.sweep_report import summarise

    settings = SweepSettings(test_days=1)
    record_settings = _settings_record(settings)
    assert_record(record_settings, SweepSettingsRecord)
    assert list(record_settings) == [*(f.name for f in dataclasses.fields(SweepSettings)), "package_version"]
    records = []
    for controller in ("oracle", "thermostat"):
        cell = Cell(scenario="winter_household", controller=controller, seed=0, train_days=None)
        result = run_cell(cell, settings, None)
        assert_record(result, CellResult)
        record = {**_cell_record_key(cell), "settings": record_settings, **result}
        assert_record(record, CellRecord)
        path = tmp_path / f"{cell.name}.json"
        path.write_text(json.dumps(record))
        records.append(_read_cell(path, cell))
    rows = summarise(records, baseline="thermostat", order=["thermostat", "oracle"])
    assert len(rows) == 2
    for row in rows:
        assert_record(row, SweepRow)
        assert "objective_to_oracle_mean" in row
    # on a plant without an oracle the ratio keys are the thermostat's
    eplus = summarise(records, baseline="thermostat", references={"winter_household": "thermostat"})
    for row in eplus:
        assert_record(row, SweepRow)
        assert "objective_to_thermostat_by_seed" in row

