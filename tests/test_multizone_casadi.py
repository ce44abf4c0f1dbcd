"""casadi-mpc over zones x actuators (controllers.rc_mpc.multizone_casadi) against an equivalent
known solution: qp-mpc's plan of the same problem (itself checked against cvxpy in
test_multizone_mpc), the one-zone casadi-mpc
(qpOASES on the condensed form) on a building of one zone, a closed loop of the two-zone house,
the fallback on a capped solver, and the CLI."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from controllers.base import ControlSpec, fallback_powers
from controllers.estimators import TrueState
from controllers.rc_mpc.casadi import CasadiMPC
from controllers.rc_mpc.multizone import MultiZoneMPC
from controllers.rc_mpc.multizone_casadi import MultiZoneCasadiMPC, ZonesCasadi
from controllers.rc_mpc.references import oracle_multizone
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InputError
from pinn_mpc.multizone import MultiZoneParams, ZoneRC
from pinn_mpc.physics import PAPER_HOUSEHOLD
from pinn_mpc.zones import ONE_ZONE
from pinn_mpc_cli.cli import main
from scenarios import get_scenario, run_closed_loop
from scenarios.running.factory import build_controller
from tests.test_multizone_mpc import (
    HEAT_PUMP,
    LIGHT,
    TIGHT,
    _day,
    _forecast,
    _house,
    _obs,
    _spec,
    _three_zones,
    _two_zone_house,
    _zone,
)
from tests.test_multizone_planners import _rc_file

#: CasADi's OSQP run as tightly as qp-mpc's TIGHT, so that the two agree to the optimum.
CASADI_TIGHT = {"osqp": {"eps_abs": 1e-8, "eps_rel": 1e-8, "max_iter": 400000}}


def _two_heated_zones() -> tuple[MultiZoneParams, ControlSpec]:
    """The two_zone_house-like building: two zones, a heater each, a wall between them."""
    south = dataclasses.replace(LIGHT, solar_aperture_m2=3.0, solar_to_air_fraction=0.4)
    params = _house((_zone("south", south, 0.6, "G_south"), _zone("north", PAPER_HOUSEHOLD, 0.4)), 120.0)
    return params, _spec(
        params,
        ActuatorSpec(upper_w=4000.0, zone=0, name="heat_south"),
        ActuatorSpec(upper_w=5000.0, zone=1, name="heat_north", efficiency=HEAT_PUMP),
    )


#: Each case: the building, its weather (:func:`_day`'s keywords), the rooms and the masses [C].
CASES: dict[str, tuple[Callable[[], tuple[MultiZoneParams, ControlSpec]], dict[str, Any], tuple[float, ...], tuple[float, ...]]] = {
    "two-heated-zones": (_two_heated_zones, dict(t_a_mean=4.0), (19.5, 20.5), (19.0, 20.0)),
    "heat-and-cool-in-a-zone": (
        _two_zone_house, dict(t_a_mean=12.0, swing=9.0, sun=700.0), (20.5, 21.5), (20.0, 21.0)
    ),
    "three-zones": (_three_zones, dict(t_a_mean=9.0, swing=7.0, sun=450.0), (21.5, 19.0, 18.0), (21.0, 19.5, 18.5)),
}


@pytest.mark.parametrize("case", list(CASES))
def test_first_action_is_qp_mpcs_on_the_same_problem(case: str) -> None:
    make, weather, t_r, t_m = CASES[case]
    params, spec = make()
    fc = _forecast(_day(60, **weather), T_min=np.full(60, 20.0), T_max=np.full(60, 22.0))
    obs = _obs(params, np.array(t_r), np.array(t_m), weather["t_a_mean"])
    qp = oracle_multizone(params, spec, solver_options=TIGHT)
    ca = MultiZoneCasadiMPC(params, spec, estimator="true", solver_options=CASADI_TIGHT)
    u_qp, u_ca = np.atleast_1d(qp.act(obs, fc)), np.atleast_1d(ca.act(obs, fc))
    assert not qp.last_stats.fallback and not ca.last_stats.fallback and ca.last_stats.status == "solved"
    assert np.allclose(u_ca, u_qp, rtol=1e-3, atol=1.0), (u_ca, u_qp)
    # The comparison is not between bounds: some actuator works within the horizon and the
    # plan's objective is qp-mpc's.
    assert qp.last_plan is not None and ca.last_plan is not None and qp.last_plan.max() > 500.0
    stage = qp.problem.stage(qp.state_estimate_c, fc)
    j_qp = qp.problem.objective(stage, qp.last_plan / 1000.0)
    assert ca.problem.objective(stage, ca.last_plan / 1000.0) == pytest.approx(j_qp, rel=1e-4)
    # The CasADi solution's states are its plan simulated on the exact ZOH.
    assert np.allclose(ca.qp.predicted_states_c(), ca.problem.rollout(stage, ca.last_plan / 1000.0), atol=1e-4)


def test_heat_and_cool_in_a_zone_both_work_within_the_horizon() -> None:
    """The heating-and-cooling case above compares plans that use both machines of a zone."""
    params, spec = _two_zone_house()
    fc = _forecast(_day(60, t_a_mean=12.0, swing=9.0, sun=700.0), T_min=np.full(60, 20.0), T_max=np.full(60, 22.0))
    ca = MultiZoneCasadiMPC(params, spec, estimator="true")
    ca.act(_obs(params, np.array([20.5, 21.5]), np.array([20.0, 21.0]), 12.0), fc)
    plan = ca.last_plan
    assert plan is not None and plan[:, 0].max() > 500.0 and plan[:, 1].max() > 500.0


@pytest.mark.parametrize(("t_a_mean", "t_r_c", "t_m_c"), [(3.0, 20.5, 20.0), (8.0, 19.5, 20.0)])
def test_one_zone_one_heater_is_the_one_zone_casadi_mpc(t_a_mean: float, t_r_c: float, t_m_c: float) -> None:
    rc = dataclasses.replace(PAPER_HOUSEHOLD, solar_aperture_m2=4.0, solar_to_air_fraction=0.3, gain_to_air_fraction=0.6)
    params = MultiZoneParams(zones=(ZoneRC(zone=ONE_ZONE[0], rc=rc, gain_share=1.0, solar_input="G"),),
                             wall_conductance_w_per_k=((0.0,),))
    spec = ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0, efficiency=HEAT_PUMP),))
    fc = _forecast(_day(60, t_a_mean=t_a_mean))
    obs = _obs(params, np.array([t_r_c]), np.array([t_m_c]), t_a_mean)
    one = CasadiMPC(rc, spec, estimator=TrueState())
    zones = MultiZoneCasadiMPC(params, spec, estimator="true", solver_options=CASADI_TIGHT)
    u_one, u_zones = one.act(obs, fc), zones.act(obs, fc)
    assert isinstance(u_zones, float) and not one.last_stats.fallback and not zones.last_stats.fallback
    assert abs(u_zones - u_one) <= 1e-3 * max(abs(u_one), 1.0)
    assert one.last_plan is not None and zones.last_plan is not None
    assert np.allclose(zones.last_plan[:, 0], one.last_plan, rtol=1e-3, atol=1.0)


def test_a_capped_solver_falls_back_then_a_failed_estimate_uses_the_shifted_plan() -> None:
    params, spec = _three_zones()
    fc = _forecast(_day(30))
    obs = _obs(params, np.array([19.0, 20.5, 21.0]), np.array([19.0, 20.0, 21.0]))
    capped = MultiZoneCasadiMPC(params, spec, estimator="true", solver_options={"osqp": {"max_iter": 1}})
    first = capped.act(obs, fc)
    assert capped.last_stats.fallback and capped.n_fallbacks == 1 and capped.last_plan is None
    assert capped.last_stats.status != "solved"
    assert np.array_equal(first, fallback_powers(obs, fc, spec))
    good = MultiZoneCasadiMPC(params, spec, estimator="true")
    good.act(obs, fc)
    plan = good.last_plan
    assert plan is not None and good.n_fallbacks == 0
    # The next decision fails (non-finite masses): the plan made a step ago, one step on.
    assert np.array_equal(good.act(obs._replace(k=1, t_m_true_zones_c=np.full(3, np.nan)), fc), plan[1])
    assert good.n_fallbacks == 1
    good.reset()
    assert good.n_fallbacks == 0 and good.last_plan is None


def test_it_is_qp_mpc_with_another_solver() -> None:
    params, spec = _two_heated_zones()
    mpc = MultiZoneCasadiMPC(params, spec)
    assert isinstance(mpc, MultiZoneMPC) and isinstance(mpc.qp, ZonesCasadi) and mpc.name == "casadi-mpc"
    with pytest.raises(ValueError, match=r"MultiZoneMPC.estimator = 'exact' is unknown; choose 'true'"):
        MultiZoneCasadiMPC(params, spec, estimator="exact")


def test_closed_loop_of_the_two_zone_house_costs_what_qp_mpcs_does() -> None:
    scenario = get_scenario("two_zone_house")
    building = scenario.plant.settings.building  # type: ignore[attr-defined]
    kpis = {}
    for name in ("qp-mpc", "casadi-mpc"):
        controller = build_controller(name, scenario, zone_params=building, n_steps=scenario.steps_per_day)
        assert controller.name == name
        kpis[name] = run_closed_loop(scenario, controller, days=1, seed=1).kpis
        assert kpis[name]["fallbacks"] == 0
    assert isinstance(controller, MultiZoneCasadiMPC)
    assert kpis["casadi-mpc"]["objective"] == pytest.approx(kpis["qp-mpc"]["objective"], rel=0.01)


def test_cli_closed_loop_plans_the_house_on_a_multizone_rc_file(tmp_path, capsys) -> None:
    from scenarios.inputs.zoned import TWO_ZONE_HOUSE

    rc = _rc_file(tmp_path / "rc.json", TWO_ZONE_HOUSE)
    out = tmp_path / "casadi.json"
    argv = ["closed-loop", "--scenario", "two_zone_house", "--controller", "casadi-mpc", "--rc", str(rc),
            "--days", "1", "--json", str(out)]
    assert main(argv) == 0, capsys.readouterr().err
    kpis = json.loads(out.read_text(encoding="utf-8"))
    assert kpis["controller"] == "casadi-mpc" and kpis["fallbacks"] == 0 and set(kpis["zones"]) == {"south", "north"}
    # With a model instead of an RC file: refused in one line.
    argv = ["closed-loop", "--scenario", "two_zone_house", "--controller", "casadi-mpc", "--model", str(tmp_path / "m"),
            "--days", "1"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--model is not used by controller 'casadi-mpc'" in err and len(err.strip().splitlines()) == 1, err


def test_without_an_rc_file_the_zoned_casadi_mpc_asks_for_one() -> None:
    with pytest.raises(InputError, match=r"controller 'casadi-mpc' on a building of several zones plans on a multi-zone RC file"):
        build_controller("casadi-mpc", get_scenario("two_zone_house"), n_steps=48)


def test_a_sweep_cell_plans_the_house_on_its_identified_multizone_rc() -> None:
    from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
    from scenarios.experiments.sweep import Cell, SweepSettings, fit_model, run_cell

    cell = Cell(scenario="two_zone_house", controller="casadi-mpc", seed=0, train_days=7)
    settings = SweepSettings(test_days=1, quick=True)
    assert cell.model is not None
    model = fit_model(cell.model, settings)
    assert isinstance(model, MultiZoneIdentifyResult)
    result = run_cell(cell, settings, model)
    assert result["errors"] == []
    kpis = result["kpis"]
    assert kpis["controller"] == "casadi-mpc" and kpis["fallbacks"] == 0 and set(kpis["zones"]) == {"south", "north"}
