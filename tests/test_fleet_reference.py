"""The centralised reference of a capped fleet (scenarios/fleets/reference.py) against analytic
truths: a cap of zero leaves the 2R2C's free response, a cap above the fleet's peak changes
nothing, a building's problem is the qp-mpc's own objective."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.estimators import TrueState
from controllers.objective import band_violation_k, planning_band
from controllers.rc_mpc.osqp import QPMPC
from controllers.rc_mpc.problem import DEFAULT_REGULARISATION
from pinn_mpc.physics import discretise
from pinn_mpc.simulator import draw_fleet, fleet_matrices
from scenarios.fleets.reference import fleet_reference, solve_fleet_reference
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import build_loop, prepare_run

COLD_SEED = 13  # winter_household's test day 2023-02-12: heating all day


def _problem(n_buildings: int, steps: int = 48):
    """A cold day's data for ``n_buildings`` of winter_household (spread 0.2), from 06:00."""
    scenario = get_scenario("winter_household")
    spec = scenario.control_spec()
    fleet = draw_fleet(scenario.sim.params, n_buildings, spread=0.2, rng=np.random.default_rng(3))
    run = prepare_run(scenario, days=1, seed=COLD_SEED, warmup_steps=12, weather_part="test")
    loop = build_loop(scenario, run, seed=0, fleet=fleet)
    loop.reset(start=12)
    forecast = loop.forecast(perfect=True)
    exog = np.column_stack([forecast.T_a[:steps], forecast.G[:steps], forecast.I_g[:steps]])
    lower, upper = planning_band(forecast, steps)
    x0 = np.tile([19.5, 20.5], (n_buildings, 1))
    data = dict(
        price_eur_per_kwh=np.asarray(forecast.price[:steps], float), t_min_c=lower, t_max_c=upper,
        actuator=spec.actuator, dt_h=spec.dt_h, comfort_weight_eur_per_kh=spec.comfort_weight_eur_per_kh,
    )
    return scenario, spec, fleet, loop, forecast, exog, x0, data


def test_a_cap_of_zero_leaves_the_free_response_of_the_2r2c():
    _, spec, fleet, _, _, exog, x0, data = _problem(1)
    ref = solve_fleet_reference(*fleet_matrices(fleet, spec.dt_s), x0, exog, cap_w=np.zeros(48), **data)
    assert np.all(ref.power_w <= 1e-3)
    # The free response, stepped with the single building's own discretisation.
    ad, bd = discretise(fleet[0], spec.dt_s)
    x, t_r = x0[0].copy(), []
    for row in exog:
        x = ad @ x + bd @ np.concatenate([[0.0], row])
        t_r.append(x[0])
    np.testing.assert_allclose(ref.t_r_c[0], t_r, atol=1e-5)
    violation = band_violation_k(np.array(t_r), data["t_min_c"], data["t_max_c"])
    assert violation.sum() > 5.0  # a cold day: the free building leaves the band
    np.testing.assert_allclose(ref.violation_k[0], violation, atol=1e-5)
    assert ref.objective_eur == pytest.approx(spec.comfort_weight_eur_per_kh * spec.dt_h * violation.sum(), rel=1e-5)
    assert ref.cap_price_eur_per_kwh.max() > 0  # the cap binds, with a price on it


def test_a_cap_above_the_fleets_peak_changes_nothing():
    _, spec, fleet, _, _, exog, x0, data = _problem(4)
    matrices = fleet_matrices(fleet, spec.dt_s)
    free = solve_fleet_reference(*matrices, x0, exog, **data)
    aggregate = free.power_w.sum(axis=0)
    cap = np.full(48, np.inf)
    cap[20:24] = 1.02 * aggregate[20:24].max()
    capped = solve_fleet_reference(*matrices, x0, exog, cap_w=cap, **data)
    assert aggregate[20:24].max() > 5000.0  # the fleet heats in the capped intervals
    np.testing.assert_allclose(capped.power_w, free.power_w, atol=5.0)
    assert capped.objective_eur == pytest.approx(free.objective_eur, rel=1e-6)
    assert np.all(capped.cap_price_eur_per_kwh < 1e-6)
    # The same cap at 60 % binds: held, at a price, for more discomfort.
    cap[20:24] = 0.6 * aggregate[20:24].max()
    tight = solve_fleet_reference(*matrices, x0, exog, cap_w=cap, **data)
    assert np.all(tight.power_w[:, 20:24].sum(axis=0) <= cap[20:24] + 1.0)
    assert tight.objective_eur > free.objective_eur + 0.01
    assert tight.cap_price_eur_per_kwh[20:24].max() > 0.05


def test_each_buildings_problem_is_the_qp_mpc_objective_and_no_worse_than_its_optimum():
    _, spec, fleet, loop, forecast, exog, x0, data = _problem(1)
    ref = solve_fleet_reference(*fleet_matrices(fleet, spec.dt_s), x0, exog, **data)
    mpc = QPMPC(fleet[0], spec, estimator=TrueState(), solver_options={"eps_abs": 1e-7, "eps_rel": 1e-7})
    stage = mpc.problem.stage(x0[0], forecast)
    p_kw = ref.power_w[0] / 1000.0
    regulariser = spec.dt_h * DEFAULT_REGULARISATION * np.sum(p_kw**2)
    assert mpc.problem.objective(stage, p_kw) == pytest.approx(ref.objective_eur - regulariser, rel=1e-5)
    observation = loop.observation(perfect=True)
    observation = observation._replace(t_r_c=x0[0, 0], t_m_true_c=x0[0, 1])
    mpc.act(observation, forecast)
    own = mpc.problem.objective(stage, mpc.last_plan / 1000.0)
    assert mpc.problem.objective(stage, p_kw) <= own + 1e-4


def test_the_reference_run_holds_the_cap_on_the_plant_and_the_cap_costs_comfort():
    scenario = get_scenario("winter_household")
    fleet = draw_fleet(scenario.sim.params, 3, spread=0.2, rng=np.random.default_rng(5))
    free = fleet_reference(scenario, fleet, days=1, seed=COLD_SEED)
    assert free.counted == 48 and free.cap is None
    window = slice(34, 38)  # 17:00-19:00
    cap_kw = 0.6 * free.aggregate_w[window].max() / 1000.0
    capped = fleet_reference(scenario, fleet, days=1, seed=COLD_SEED, cap_kw=cap_kw, cap_window="17:00-19:00")
    assert capped.cap is not None and capped.cap["intervals"] == 4 and capped.cap["intervals_over"] == 0
    np.testing.assert_allclose(capped.aggregate_w[window], cap_kw * 1000.0, rtol=1e-4)
    # The plant runs the plan: its interval-end discomfort is the model's, up to the minutes.
    assert capped.discomfort_kh.sum() > free.discomfort_kh.sum() + 0.05
    assert capped.model_discomfort_kh.sum() == pytest.approx(capped.discomfort_kh.sum(), rel=0.2)
    assert capped.energy_kwh.sum() > free.energy_kwh.sum()  # pre-heating
    # Over the day alone the plan can only do better on the day's objective (it may let the
    # mass run down for the next day, which the closed loop's last plans still see).
    day = fleet_reference(scenario, fleet, days=1, seed=COLD_SEED, cap_kw=cap_kw, cap_window="17:00-19:00", lead=False)
    assert day.plan.power_w.shape == (3, 48) and capped.plan.power_w.shape == (3, 96)
    assert sum(k["objective"] for k in day.kpis) <= sum(k["objective"] for k in capped.kpis) * 1.001
