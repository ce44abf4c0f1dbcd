"""The fleet closed loop (scenarios.fleets.fleet): one batched plant, one controller per building."""

import dataclasses
import json

import numpy as np
import pytest

from controllers.rc_mpc.osqp import QPMPC
from controllers.thermostat import Thermostat
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc_cli.cli import main
from scenarios.fleets.fleet import FLEET_TOTAL_KEYS, run_fleet_closed_loop
from scenarios.inputs.scenario_file import get_scenario
from scenarios.inputs.series import ForecastErrors
from scenarios.running.closed_loop import (
    build_loop,
    counted_kpis,
    free_records,
    prepare_run,
    run_closed_loop,
)
from scenarios.running.factory import build_controller
from scenarios.running.kpis import KPI_KEYS

TIME_KEYS = {"decision_ms_median", "decision_ms_mean", "decision_ms_p95", "time_ratio"}
PLANT_KEYS = [k for k in KPI_KEYS if k not in TIME_KEYS]


def noisy(name: str, noise_std_c: float = 0.1):
    """A scenario with sensor noise and forecast errors, so the seeds' plumbing is exercised."""
    scenario = get_scenario(name)
    return dataclasses.replace(
        scenario,
        sim=dataclasses.replace(scenario.sim, noise_std_c=noise_std_c),
        forecast=ForecastErrors(t_a_error_std_c=1.5, g_error_rel_std=0.3, gains_known=False),
    )


def with_params(scenario, params):
    return dataclasses.replace(scenario, sim=dataclasses.replace(scenario.sim, params=params))


def assert_same_plant_kpis(got: dict, want: dict) -> None:
    for key in PLANT_KEYS:
        if key == "zones":  # each zone's figures, as the building's
            assert got[key].keys() == want[key].keys()
            for zone, figures in got[key].items():
                for name, value in figures.items():
                    assert value == pytest.approx(want[key][zone][name], rel=1e-9, abs=1e-9), (zone, name)
            continue
        assert got[key] == pytest.approx(want[key], rel=1e-9, abs=1e-9), key


@pytest.mark.parametrize(("name", "controller"), [("winter_household", "qp-mpc"), ("cold_storage", "oracle")])
def test_fleet_of_one_reproduces_the_single_building_run(name, controller):
    scenario = noisy(name)
    fleet = run_fleet_closed_loop(scenario, controller, n_buildings=1, days=1, seed=3, spread=0.0)
    assert fleet.params == (scenario.sim.params,)
    single = run_closed_loop(
        scenario,
        build_controller(controller, scenario, rc_params=scenario.sim.params, n_steps=48),
        days=1,
        seed=3,
    )
    assert_same_plant_kpis(fleet.kpis[0], single.kpis)
    np.testing.assert_allclose(
        fleet.aggregate_u_phys_w, single.trajectory["u_phys"], rtol=0, atol=1e-9
    )


def test_each_building_runs_as_it_would_alone_and_totals_add_up():
    # No sensor noise: the fleet's one noise generator would give each building other draws.
    scenario = noisy("winter_household", noise_std_c=0.0)
    fleet = run_fleet_closed_loop(scenario, "qp-mpc", n_buildings=3, days=1, seed=1, spread=0.3)
    assert len(set(fleet.params)) == 3
    for b, params in enumerate(fleet.params):
        alone = with_params(scenario, params)
        single = run_closed_loop(alone, QPMPC(params, alone.control_spec()), days=1, seed=1)
        assert fleet.kpis[b]["building"] == b
        assert_same_plant_kpis(fleet.kpis[b], single.kpis)
    totals, kpis = fleet.totals, fleet.kpis
    assert set(totals) == set(FLEET_TOTAL_KEYS)
    dt_h = scenario.sim.dt_s / 3600.0
    # The loop's aggregate power against the per-building KPIs, computed apart.
    assert totals["energy_kwh"] == pytest.approx(fleet.aggregate_u_phys_w.sum() / 1000 * dt_h, rel=1e-12)
    for key in ("cost_eur", "discomfort_kh", "discomfort_too_cold_kh", "discomfort_too_warm_kh",
                "discomfort_unavoidable_kh", "discomfort_avoidable_kh", "objective"):
        assert totals[key] == pytest.approx(sum(k[key] for k in kpis), rel=1e-12)
    # each building's unavoidable part is its own free run's, as when it runs alone (above)
    assert totals["discomfort_avoidable_kh"] + totals["discomfort_unavoidable_kh"] == pytest.approx(
        totals["discomfort_kh"], rel=1e-12
    )
    # The aggregate's peak lies between the largest building peak and the sum of the peaks.
    peaks = [k["peak_kw"] for k in kpis]
    assert max(peaks) <= totals["peak_kw"] + 1e-12 <= sum(peaks) + 2e-12
    assert totals["peak_kw"] == pytest.approx(fleet.aggregate_u_phys_w.max() / 1000, rel=1e-12)
    t = fleet.step_time
    for part in ("controllers", "plant"):
        assert 0 < t[f"{part}_ms_median"] <= t[f"{part}_ms_p95"]
    # total = controllers + plant step by step, so its order statistics are at least theirs.
    assert t["total_ms_median"] >= t["controllers_ms_median"]
    assert t["total_ms_p95"] >= t["plant_ms_p95"]


def test_each_buildings_unavoidable_discomfort_is_its_own_free_run_alone():
    """11-12 March (seed 0) hold a warm spell: every building of a fleet, batched, gets the
    too-warm discomfort of its own free run, as if it ran alone."""
    scenario = get_scenario("winter_household")
    fleet = run_fleet_closed_loop(scenario, "thermostat", n_buildings=2, days=2, seed=0, spread=0.3)
    for b, params in enumerate(fleet.params):
        alone = with_params(scenario, params)
        run = prepare_run(alone, days=2, seed=0, warmup_steps=None, weather_part="test")
        free = counted_kpis(alone, run, free_records(alone, run, seed=0)[0])
        assert fleet.kpis[b]["discomfort_unavoidable_kh"] == pytest.approx(
            free["discomfort_too_warm_kh"], rel=1e-9
        )
        assert free["discomfort_too_warm_kh"] > 1.0


def test_a_building_whose_solver_fails_falls_back_and_is_counted():
    scenario = get_scenario("winter_household")

    def controllers(index, params):
        # OSQP stopped after one iteration: a real non-optimal status (QPMPC's documented option).
        options = {"max_iter": 1} if index == 1 else None
        return QPMPC(params, scenario.control_spec(), solver_options=options)

    fleet = run_fleet_closed_loop(scenario, controllers, n_buildings=3, days=1, seed=0)
    assert [k["fallbacks"] for k in fleet.kpis] == [0, 48, 0]
    assert fleet.totals["fallbacks"] == 48
    assert fleet.totals["buildings_with_fallbacks"] == 1
    assert fleet.errors == ()  # the controller's own fallback acted, nothing raised


def test_fleet_input_errors_are_one_clear_line():
    scenario = get_scenario("paper_household")
    with pytest.raises(ValueError, match="n_buildings must be") as caught:  # a Python caller's
        run_fleet_closed_loop(scenario, "thermostat", n_buildings=0, days=1, seed=0)
    assert not isinstance(caught.value, InputError)
    with pytest.raises(InputError, match="unknown controller 'pid'"):
        run_fleet_closed_loop(scenario, "pid", n_buildings=2, days=1, seed=0)
    with pytest.raises(ValueError, match="days must be >= 1") as caught:  # a Python caller's
        run_fleet_closed_loop(scenario, "thermostat", n_buildings=2, days=0, seed=0)
    assert not isinstance(caught.value, InputError)
    run = prepare_run(scenario, days=1, seed=0, warmup_steps=0, weather_part="test")
    loop = build_loop(scenario, run, seed=0, fleet=(scenario.sim.params,) * 2)
    with pytest.raises(InternalError, match="use advance_fleet"):
        loop.advance(Thermostat(scenario.control_spec()))
    with pytest.raises(InternalError, match="1 controllers for 2 buildings"):
        loop.advance_fleet([Thermostat(scenario.control_spec())])
    with pytest.raises(InternalError, match=r"building=2 must lie in \[0, 1\]"):
        loop.record(2)


def _cli(*extra):
    return main(["closed-loop", "--scenario", "paper_household", "--days", "1", "--seed", "2", *extra])


def test_cli_fleet_writes_totals_step_times_and_every_building(tmp_path, capsys):
    path = tmp_path / "fleet.json"
    assert _cli("--controller", "qp-mpc", "--buildings", "3", "--spread", "0.1", "--json", str(path)) == 0
    out = capsys.readouterr().out
    assert "qp-mpc x 3 buildings" in out and "time per control step" in out and str(path) in out
    data = json.loads(path.read_text())
    assert data["fleet"]["n_buildings"] == 3 and data["fleet"]["spread"] == 0.1
    assert set(data["totals"]) == set(FLEET_TOTAL_KEYS)
    assert [b["building"] for b in data["buildings"]] == [0, 1, 2]
    # The JSON's parameters are the fleet's: the same draw through the library.
    again = run_fleet_closed_loop(
        get_scenario("paper_household"), "qp-mpc", n_buildings=3, days=1, seed=2, spread=0.1
    )
    assert [b["params"] for b in data["buildings"]] == [p.to_dict() for p in again.params]
    assert data["totals"]["energy_kwh"] == pytest.approx(again.totals["energy_kwh"], rel=1e-9)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet.json"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--buildings", "2", "--rc", "rc.json"], "--rc does not apply to a fleet"),
        (["--buildings", "2", "--csv", "t.csv"], "--csv does not apply to a fleet"),
        (["--spread", "0.3"], "--spread draws a fleet: add --buildings N"),
        (["--buildings", "2", "--spread", "1.5"], "spread must lie in [0, 1]"),
    ],
)
def test_cli_fleet_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    assert _cli("--controller", "qp-mpc", *args, "--json", str(tmp_path / "k.json")) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []
