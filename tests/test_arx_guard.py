"""The trust guard over the ARX models: an ARX from ``train`` carries the RC identified from the
same data, a planner over it hands a wrong ARX's decisions to the MPC on that RC and counts
them, and a good ARX keeps control."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np
import pytest

from pinn_mpc.choices import ARX, PHYSICS_ARX
from pinn_mpc.errors import InputError
from pinn_mpc.models.arx import fit_linear, load_arx, save_arx
from pinn_mpc.physics import params_from_summary
from scenarios.inputs.registry import Scenario
from scenarios.inputs.scenario_file import get_scenario
from scenarios.records import RunKpis
from scenarios.reports.report import kpi_table_text
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.datagen import generate
from scenarios.running.factory import build_controller, model_guard


@pytest.fixture(scope="module")
def winter_parx():
    scenario = get_scenario("winter_household")
    data = generate(scenario, days=14, seed=3, policy="random-level")
    return scenario, fit_linear(PHYSICS_ARX.name, data, eta=scenario.sim.params.eta)


def test_a_fitted_arx_carries_the_rc_identified_from_its_data(winter_parx, tmp_path) -> None:
    scenario, parx = winter_parx
    guard = model_guard(parx)
    assert guard.rc is not None
    assert guard.rc.c_m_j_per_k == pytest.approx(scenario.sim.params.c_m_j_per_k, rel=0.2)
    lo, hi = guard.training_ranges["T_a"]
    assert lo < hi
    save_arx(parx, tmp_path)
    loaded = load_arx(tmp_path)
    assert loaded.identified_rc == parx.identified_rc
    assert model_guard(loaded).rc == guard.rc
    assert model_guard(dataclasses.replace(parx, identified_rc=None)).rc is None


def test_a_tampered_fallback_rc_in_an_arx_file_is_refused(winter_parx, tmp_path) -> None:
    _, parx = winter_parx
    save_arx(parx, tmp_path)
    stored = json.loads((tmp_path / "arx.json").read_text())
    rc = {**stored["identified_rc"], "C_m_J_per_K": -1.0}
    (tmp_path / "arx.json").write_text(json.dumps({**stored, "identified_rc": rc}))
    with pytest.raises(InputError, match="identified_rc: .*C_m_J_per_K"):
        load_arx(tmp_path)


def _run(scenario: Scenario, **kwargs: Any) -> RunKpis:
    controller = build_controller("cem", scenario, n_steps=scenario.steps_per_day, **kwargs)
    return run_closed_loop(scenario, controller, days=1, seed=5).kpis


def test_a_good_arx_keeps_nearly_all_decisions(winter_parx) -> None:
    scenario, parx = winter_parx
    kpis = _run(scenario, model=parx)
    assert kpis["model_fallback"] is True and kpis["rc_replay_error_k"] is not None
    assert kpis["own_decisions_share"] >= 0.95
    assert kpis["fallbacks"] == kpis["model_fallback_steps"]


@pytest.mark.parametrize(
    ("coefficient", "reason"),
    [(0, "non-finite model output"), (1, "prediction error")],
    ids=["room-lag", "power"],
)
def test_an_arx_with_a_wrong_coefficient_is_handed_to_the_rc_mpc_and_counted(
    winter_parx, coefficient, reason
) -> None:
    """A coefficient edited to 1e6 (the room's own lag: predictions overflow; the power's: a
    heater 1e6 times too strong, which the replays expose): the MPC on the RC identified from
    the same data makes the decisions, every one of them counted in ``fallbacks`` and
    ``model_fallback_steps``, and the run ends at that MPC's objective; without the fallback
    the same ARX drives the building far past it."""
    scenario, parx = winter_parx
    coef = parx.coef.copy()
    coef[coefficient] = 1e6
    broken = dataclasses.replace(parx, coef=coef)
    kpis = _run(scenario, model=broken)
    alone = _run(scenario, model=broken, planner_options={"guard": model_guard(broken)._replace(rc=None)})
    rc = params_from_summary(parx.identified_rc or {})
    qp = run_closed_loop(
        scenario, build_controller("qp-mpc", scenario, rc_params=rc, n_steps=48), days=1, seed=5
    ).kpis
    n = scenario.steps_per_day
    assert kpis["model_fallback_switches"] >= 1
    assert any(key.startswith(reason) for key in kpis["model_fallback_reasons"])
    assert kpis["model_fallback_steps"] >= 0.8 * n
    assert kpis["fallbacks"] == kpis["model_fallback_steps"]
    assert kpis["own_decisions_share"] == pytest.approx(1 - kpis["fallbacks"] / n)
    assert kpis["objective"] <= 1.02 * qp["objective"]
    assert alone["model_fallback_steps"] == 0
    assert alone["objective"] > 1.2 * qp["objective"]


def test_the_kpi_table_says_who_decided(winter_parx) -> None:
    """The compare table's share of own decisions sits next to the objective, and its
    ``fallbacks`` counts the decisions the RC MPC made for the model."""
    scenario, parx = winter_parx
    coef = parx.coef.copy()
    coef[1] = 1e6
    rows: list[RunKpis] = [
        {**_run(scenario, model=parx), "controller": "cem-parx"},
        {**_run(scenario, model=dataclasses.replace(parx, coef=coef)), "controller": "cem-broken"},
    ]
    lines = kpi_table_text(rows).splitlines()
    headers = lines[0].split("  ")
    headers = [h.strip() for h in headers if h.strip()]
    assert headers[1:4] == ["objective EUR", "/ oracle", "own decisions"]
    assert headers[-1] == "fallbacks"
    good, broken = (line.split() for line in lines[1:])
    assert int(broken[-1]) == rows[1]["model_fallback_steps"] >= 0.8 * 48
    assert broken[3] == f"{rows[1]['own_decisions_share']:.0%}"
    assert good[3] == f"{rows[0]['own_decisions_share']:.0%}"


def test_train_writes_the_fallback_rc_into_the_arx_file(tmp_path) -> None:
    from pinn_mpc.data import write_timeseries
    from pinn_mpc_cli.cli import main

    scenario = get_scenario("winter_household")
    data = tmp_path / "d.csv"
    write_timeseries(generate(scenario, days=14, seed=1, policy="random-level"), data)
    for arch in (ARX.name, PHYSICS_ARX.name):
        out = tmp_path / arch
        assert main(["train", "--data", str(data), "--arch", arch, "--out", str(out)]) == 0
        stored = json.loads((out / "arx.json").read_text())
        assert stored["identified_rc"]["source"] == "identify (training data)"
        assert stored["training_data"]["n_rows"] == 14 * 48
        assert np.isfinite(params_from_summary(stored["identified_rc"]).c_m_j_per_k)


def test_trains_caution_promises_the_fallback_only_where_the_model_has_one(winter_parx) -> None:
    from pinn_mpc.model_choice import ModelChoice

    _, parx = winter_parx
    rough: dict[str, Any] = {"held_out_mae_c": {PHYSICS_ARX.name: 0.8}, "horizon_steps": 24, "why": ""}
    guarded = ModelChoice(chosen=PHYSICS_ARX.name, model=parx, **rough).caution
    bare = ModelChoice(
        chosen=PHYSICS_ARX.name, model=dataclasses.replace(parx, identified_rc=None), **rough
    ).caution
    assert guarded is not None and "hand more decisions to the MPC on the RC" in guarded
    assert bare is not None and "no RC MPC to fall back on" in bare
    assert ModelChoice(chosen=PHYSICS_ARX.name, model=parx, **{**rough, "held_out_mae_c": {PHYSICS_ARX.name: 0.2}}).caution is None
