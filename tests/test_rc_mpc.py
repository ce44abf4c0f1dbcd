"""RC MPCs (casadi-mpc, qp-mpc), oracle and clairvoyant against analytic truth and each other."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from controllers.base import (
    Controller,
    ControlSpec,
    Forecast,
    Observation,
    fallback_power,
)
from controllers.objective import HorizonObjective
from controllers.rc_mpc.casadi import CasadiMPC
from controllers.rc_mpc.osqp import QPMPC
from controllers.rc_mpc.problem import RCMPC, RCProblem, StageData
from controllers.rc_mpc.references import clairvoyant_mpc, oracle_mpc
from controllers.trust import TrustSettings
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.physics import PAPER_HOUSEHOLD, steady_state
from pinn_mpc.simulator import SimConfig
from scenarios.inputs.series import ExogenousSeries
from scenarios.running.engine import ClosedLoop

SPEC = ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0),))
PARAMS = PAPER_HOUSEHOLD
MPCS = (QPMPC, CasadiMPC)


def _forecast(n: int, *, start: int = 0, **constant: float) -> Forecast:
    """A day-shaped forecast of n steps from step ``start``; keywords make a field constant."""
    k = np.arange(start, start + n)
    hours = (k * 0.5) % 24.0
    fields = {
        "time_of_day_h": hours,
        "T_a": 3.0 + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0),
        "G": np.zeros(n),
        "I_g": np.zeros(n),
        "price": np.where((hours > 17) & (hours < 21), 0.45, np.where(hours < 6, 0.12, 0.25)),
        "T_min": np.where((hours >= 7) & (hours < 22), 20.0, 17.0),
        "T_max": np.full(n, 23.0),
    }
    for name, value in constant.items():
        fields[name] = np.full(n, float(value))
    return Forecast(**fields)


def _first_obs(t_r_c: float, t_m_c: float, t_a_c: float = 3.0) -> Observation:
    history = {"T_r": np.array([t_r_c]), "u": np.zeros(0), "u_phys": np.zeros(0), "T_a": np.array([t_a_c])}
    return Observation.from_history(0, history, t_m_c)


def _realised_cost(actions: np.ndarray, t_r_next_c: np.ndarray, forecast: Forecast) -> float:
    """The shared objective of what happened (the band as the planners see it)."""
    objective = HorizonObjective.from_forecast(forecast, SPEC, len(actions))
    return float(objective.cost(actions, t_r_next_c))


def _closed_loop(controller: Controller, n_steps: int, *, hidden_start_t_m_c: float = 17.0):
    """Run on the closed-loop engine (backup thermostat out of reach, so the model is exact).

    Returns (actions (n,), realised objective [EUR], final |T_m estimate - T_m| or nan).
    """
    config = SimConfig(params=PARAMS, backup_low_c=-50.0, backup_high_c=80.0)
    fc_all = _forecast(n_steps + SPEC.horizon_steps)
    loop = ClosedLoop(
        config,
        ExogenousSeries(**fc_all._asdict()),
        spec=SPEC,
        initial_t_r_c=19.0,
        initial_t_m_c=hidden_start_t_m_c,
    )
    controller.reset(seed=0)
    t_r_next, t_m_last = [], np.nan
    for _ in range(n_steps):
        t_m_last = float(loop.true_state()[0, 1])
        t_r_next.append(float(loop.advance(controller).plant.t_r_c[0, 0]))
    actions = loop.record().u_w
    error = np.nan
    if isinstance(controller, RCMPC):
        error = abs(controller.state_estimate_c[1] - t_m_last)  # estimate at k=n-1
    return actions, _realised_cost(actions, np.array(t_r_next), fc_all), error


@pytest.mark.parametrize(("t_r_c", "t_m_c"), [(18.5, 18.0), (20.5, 21.5), (17.0, 14.0)])
def test_casadi_and_qp_agree_on_first_action_and_objective(t_r_c: float, t_m_c: float) -> None:
    fc = _forecast(60)
    qp, ca = QPMPC(PARAMS, SPEC), CasadiMPC(PARAMS, SPEC)
    obs = _first_obs(t_r_c, t_m_c)
    a_qp, a_ca = qp.act(obs, fc), ca.act(obs, fc)
    assert not qp.last_stats.fallback and not ca.last_stats.fallback
    assert abs(a_qp - a_ca) <= 0.01 * SPEC.u_max_w
    stage = qp.problem.stage(qp.state_estimate_c, fc)
    assert qp.last_plan is not None and ca.last_plan is not None
    j_qp = qp.problem.objective(stage, qp.last_plan / 1000.0)
    j_ca = ca.problem.objective(stage, ca.last_plan / 1000.0)
    assert j_qp == pytest.approx(j_ca, rel=1e-3)


@pytest.mark.parametrize("cls", MPCS)
def test_plan_respects_bounds_and_matches_the_shared_objective(cls: type[RCMPC]) -> None:
    fc = _forecast(48)
    mpc = cls(PARAMS, SPEC)
    mpc.act(_first_obs(19.0, 18.0), fc)
    plan = mpc.last_plan
    assert plan is not None and plan.shape == (48,)
    assert plan.min() >= 0.0 and plan.max() <= SPEC.u_max_w
    stage = mpc.problem.stage(mpc.state_estimate_c, fc)
    t_r = mpc.problem.rollout(stage, plan / 1000.0)[:, 0]
    shared = HorizonObjective.from_forecast(fc, SPEC, 48)
    assert mpc.problem.objective(stage, plan / 1000.0) == pytest.approx(
        float(shared.cost(plan, t_r)), rel=1e-12
    )


@pytest.mark.parametrize("cls", MPCS)
def test_unreachable_comfort_band_still_solves(cls: type[RCMPC]) -> None:
    fc = _forecast(48, T_min=35.0, T_max=36.0)  # far above what 5 kW can reach
    mpc = cls(PARAMS, SPEC)
    action = mpc.act(_first_obs(19.0, 18.0), fc)
    assert not mpc.last_stats.fallback
    assert action == pytest.approx(SPEC.u_max_w, rel=1e-6)  # best effort: flat out


@pytest.mark.parametrize(
    ("cls", "options"), [(QPMPC, {"max_iter": 1}), (CasadiMPC, {"nWSR": 1})]
)
def test_injected_solver_failure_acts_through_the_fallback(cls: type, options: dict) -> None:
    fc = _forecast(48)
    obs = _first_obs(17.5, 17.0)
    mpc = cls(PARAMS, SPEC, solver_options=options)
    action = mpc.act(obs, fc)
    assert mpc.last_stats.fallback and mpc.n_fallbacks == 1
    assert action == fallback_power(obs, fc, SPEC) == SPEC.u_max_w
    assert mpc.last_plan is None


@pytest.mark.parametrize("cls", MPCS)
def test_failure_after_a_solve_uses_the_shifted_previous_plan(cls: type[RCMPC]) -> None:
    mpc = cls(PARAMS, SPEC)
    mpc.act(_first_obs(19.0, 18.0), _forecast(48))
    plan = mpc.last_plan
    assert plan is not None
    bad = _forecast(48, price=np.nan)  # a non-finite forecast: the solve fails
    history = {"T_r": np.array([19.0, 19.2]), "u": plan[:1], "u_phys": plan[:1], "T_a": np.array([3.0, 3.0])}
    action = mpc.act(Observation.from_history(1, history, 18.0), bad)
    assert mpc.last_stats.fallback and mpc.n_fallbacks == 1
    assert action == pytest.approx(plan[1])


@pytest.mark.parametrize("cls", MPCS)
def test_free_energy_and_a_band_above_the_free_run_heats_flat_out(cls: type[RCMPC]) -> None:
    fc = _forecast(48, price=0.0, T_min=22.0, T_max=30.0, T_a=5.0)
    x_free = steady_state(PARAMS, u_w=0.0, t_a_c=5.0)  # 5 C: free-running
    action = cls(PARAMS, SPEC).act(_first_obs(float(x_free[0]), float(x_free[1])), fc)
    assert action == pytest.approx(SPEC.u_max_w, rel=1e-6)


@pytest.mark.parametrize("cls", MPCS)
def test_steady_state_action_holds_the_lower_band(cls: type[RCMPC]) -> None:
    t_min, t_a = 20.0, 5.0
    u_ss = (t_min - t_a) / (PARAMS.r_ra_k_per_w * PARAMS.eta)  # 4000 W
    x = steady_state(PARAMS, u_w=u_ss, t_a_c=t_a)
    np.testing.assert_allclose(x, [t_min, t_min], atol=1e-9)
    fc = _forecast(48, price=0.25, T_min=t_min, T_max=24.0, T_a=t_a)
    action = cls(PARAMS, SPEC).act(_first_obs(t_min, t_min, t_a), fc)
    assert action == pytest.approx(u_ss, rel=0.01)


@pytest.mark.parametrize("cls", MPCS)
@pytest.mark.parametrize(("t_max", "held"), [(24.0, 20.3), (20.4, 20.2)])
def test_a_comfort_margin_holds_the_band_that_far_inside(cls: type[RCMPC], t_max: float, held: float) -> None:
    """With ``comfort_margin_k`` 0.3 K the MPC holds the room at T_min + 0.3 K (the analytic
    steady-state power there), or at the band's middle where the band is narrower than 0.6 K;
    the margin is the owner's to change between decisions."""
    t_min, t_a, margin = 20.0, 5.0, 0.3
    u_ss = (held - t_a) / (PARAMS.r_ra_k_per_w * PARAMS.eta)
    x = steady_state(PARAMS, u_w=u_ss, t_a_c=t_a)
    fc = _forecast(48, price=0.25, T_min=t_min, T_max=t_max, T_a=t_a)
    mpc = cls(PARAMS, SPEC)
    mpc.comfort_margin_k = margin
    assert mpc.act(_first_obs(float(x[0]), float(x[1]), t_a), fc) == pytest.approx(u_ss, rel=0.01)
    mpc.reset()
    mpc.comfort_margin_k = 0.0  # without it, the room is let down to T_min first
    assert mpc.act(_first_obs(float(x[0]), float(x[1]), t_a), fc) < 0.9 * u_ss


def _below_band(mpc: RCMPC, n: int = 96) -> tuple[float, np.ndarray]:
    """Run ``mpc`` on the exact plant of PARAMS under a mild day (T_a 10 C) from inside the
    band; (K h below T_min, actions [W])."""
    config = SimConfig(params=PARAMS, backup_low_c=-50.0, backup_high_c=80.0)
    fc = _forecast(n + SPEC.horizon_steps, T_a=10.0)
    loop = ClosedLoop(config, ExogenousSeries(**fc._asdict()), spec=SPEC, initial_t_r_c=20.5, initial_t_m_c=20.0)
    mpc.reset(seed=0)
    t_r = np.array([float(loop.advance(mpc).plant.t_r_c[0, 0]) for _ in range(n)])
    below = np.maximum(fc.T_min[1 : n + 1] - t_r, 0.0).sum() * SPEC.dt_s / 3600.0
    return float(below), loop.record().u_w


@pytest.mark.parametrize(
    "wrong", [{"r_ra_k_per_w": PARAMS.r_ra_k_per_w * 1.5}, {"eta": PARAMS.eta * 1.3}], ids=["R_ra x1.5", "eta x1.3"]
)
def test_planning_with_its_replay_margin_keeps_a_misidentified_rc_in_the_band(wrong: dict[str, Any]) -> None:
    """An RC that believes the house warmer than it is (better insulated, a stronger heater)
    rides T_min and the room falls below it; planning inside the band by the RC's own filtered
    replay error (what BOPTEST's MPC does) keeps it in, with the margin that error, at most
    0.5 K. On the exact RC the replay error and the margin are 0 and nothing changes."""
    rc = dataclasses.replace(PARAMS, **wrong)
    below, _ = _below_band(QPMPC(rc, SPEC))
    guarded = QPMPC(rc, SPEC)
    guarded.plan_with_replay_margin(TrustSettings(margin_from_replay=True))
    below_guarded, _ = _below_band(guarded)
    report = guarded.replay_report
    assert below > 0.3 and below_guarded < 0.01, (below, below_guarded)
    assert report is not None and report["rc_replay_error_k"] is not None
    assert 0.05 < report["comfort_margin_k"] == pytest.approx(min(report["rc_replay_error_k"], 0.5), abs=1e-4)

    exact = QPMPC(PARAMS, SPEC)
    exact.plan_with_replay_margin(TrustSettings(margin_from_replay=True))
    _, actions = _below_band(exact)
    _, plain = _below_band(QPMPC(PARAMS, SPEC))
    assert exact.replay_report == {"rc_replay_error_k": 0.0, "comfort_margin_k": 0.0}
    np.testing.assert_allclose(actions, plain, atol=0.01 * SPEC.u_max_w)
    with pytest.raises(ValueError, match="margin_from_replay"):
        exact.plan_with_replay_margin(TrustSettings())


def test_regulariser_moves_the_objective_by_less_than_a_thousandth() -> None:
    fc = _forecast(48)
    obs = _first_obs(18.5, 18.0)
    regular, lp = CasadiMPC(PARAMS, SPEC), CasadiMPC(PARAMS, SPEC, regularisation_eur_per_kw2h=1e-9)
    regular.act(obs, fc)
    lp.act(obs, fc)
    stage = lp.problem.stage(lp.state_estimate_c, fc)
    assert lp.last_plan is not None and regular.last_plan is not None
    j_lp = lp.problem.objective(stage, lp.last_plan / 1000.0)
    j_reg = regular.problem.objective(stage, regular.last_plan / 1000.0)
    assert j_lp <= j_reg <= j_lp * (1 + 1e-3)


def test_closed_loop_qp_and_casadi_agree_and_the_observer_finds_t_m() -> None:
    a_qp, j_qp, err_qp = _closed_loop(QPMPC(PARAMS, SPEC), 60)
    a_ca, j_ca, err_ca = _closed_loop(CasadiMPC(PARAMS, SPEC), 60)
    assert np.max(np.abs(a_qp - a_ca)) <= 0.01 * SPEC.u_max_w
    assert j_qp == pytest.approx(j_ca, rel=1e-3)
    assert err_qp < 0.2 and err_ca < 0.2


def test_reset_makes_runs_reproducible() -> None:
    mpc = QPMPC(PARAMS, SPEC)
    first, _, _ = _closed_loop(mpc, 12)
    second, _, _ = _closed_loop(mpc, 12)
    np.testing.assert_array_equal(first, second)


def test_oracle_uses_the_true_state() -> None:
    oracle = oracle_mpc(PARAMS, SPEC)
    oracle.act(_first_obs(19.0, 15.0), _forecast(48))
    np.testing.assert_array_equal(oracle.state_estimate_c, [19.0, 15.0])
    assert oracle.name == "oracle"


def test_clairvoyant_is_a_lower_bound_and_realises_its_plan() -> None:
    n = 48
    clair = clairvoyant_mpc(PARAMS, SPEC, n)
    _, j_oracle, _ = _closed_loop(oracle_mpc(PARAMS, SPEC), n)
    actions, j_clair, _ = _closed_loop(clair, n)
    assert j_clair <= j_oracle * (1 + 1e-4)
    # With an exact model the whole-run plan of step 0 is what happens.
    fresh = clairvoyant_mpc(PARAMS, SPEC, n)
    fresh.act(_first_obs(19.0, 17.0), _forecast(n + SPEC.horizon_steps))
    assert fresh.last_plan is not None
    np.testing.assert_allclose(actions, fresh.last_plan, atol=0.01 * SPEC.u_max_w)
    assert clair.name == "clairvoyant"


def test_forecast_longer_or_shorter_than_the_horizon() -> None:
    spec = dataclasses.replace(SPEC, horizon_steps=12)
    mpc = QPMPC(PARAMS, spec)
    long_action = mpc.act(_first_obs(19.0, 18.0), _forecast(100))
    short = QPMPC(PARAMS, spec).act(_first_obs(19.0, 18.0), _forecast(12))
    assert long_action == pytest.approx(short, abs=1.0)
    assert mpc.last_plan is not None and mpc.last_plan.shape == (12,)
    padded = QPMPC(PARAMS, spec)
    padded.act(_first_obs(19.0, 18.0), _forecast(5))  # the last value is repeated
    assert not padded.last_stats.fallback


def test_clairvoyant_counts_its_run_from_the_first_decision() -> None:
    """A warm-up driven by another controller advances obs.k but is not part of the run."""
    n, fc = 24, _forecast(24 + SPEC.horizon_steps)
    at_zero, after_warmup = clairvoyant_mpc(PARAMS, SPEC, n), clairvoyant_mpc(PARAMS, SPEC, n)
    at_zero.act(_first_obs(19.0, 17.0), fc)
    late = _first_obs(19.0, 17.0)._replace(k=48)
    after_warmup.act(late, fc)
    assert at_zero.last_plan is not None and after_warmup.last_plan is not None
    np.testing.assert_allclose(after_warmup.last_plan, at_zero.last_plan, atol=1e-6)
    assert at_zero.last_plan.shape == (n,) and at_zero.last_plan.max() > 100.0
    plan = at_zero.last_plan
    history = {"T_r": np.array([19.0, 19.5]), "u": plan[:1], "u_phys": plan[:1], "T_a": fc.T_a[:2]}
    second = Observation.from_history(1, history, 17.1)
    at_zero.act(second, Forecast._make(None if a is None else np.asarray(a)[1:] for a in fc))
    assert at_zero.last_plan is not None
    assert at_zero.last_plan[-1] < 1.0  # the last step is after the run end: nothing planned


def _cvxpy_problem(problem: RCProblem, stage: StageData):
    """The QP of controllers/rc_mpc/problem.py stated in cvxpy, the states as variables: the
    independent statement the hand-built OSQP data are checked against."""
    import cvxpy as cp

    h, dt_h = problem.horizon_steps, problem.spec.dt_h
    ad, _ = problem.matrices
    drift = stage.free_c.T.copy()
    drift[:, 0] += ad @ stage.x0_c
    heat = cp.Variable(h)
    slack = cp.Variable(h)
    x = cp.Variable((2, h))
    previous = cp.hstack([np.zeros((2, 1)), x[:, :-1]]) if h > 1 else np.zeros((2, 1))
    b_u = problem.b_u_c_per_kw.reshape(2, 1)
    constraints = [
        x == ad @ previous + b_u @ cp.reshape(heat, (1, h), order="C") + drift,
        x[0, :] + slack >= stage.objective.t_min_c,
        x[0, :] - slack <= stage.objective.t_max_c,
        heat >= problem.spec.actuator.lower_kw * stage.cop,
        heat <= problem.spec.actuator.upper_kw * stage.cop,
        slack >= 0.0,
    ]
    objective = dt_h * (
        stage.heat_price_eur_per_kwh @ heat
        + problem.spec.comfort_weight_eur_per_kh * cp.sum(slack)
        + problem.regularisation_eur_per_kw2h * cp.sum_squares(heat)
    )
    return cp.Problem(cp.Minimize(objective), constraints)


@pytest.mark.parametrize(
    ("h", "dt_s", "weight", "rho", "lower_w"),
    [(48, 1800.0, 1.0, 1e-4, 0.0), (7, 900.0, 3.7, 2.3e-4, 800.0), (1, 3600.0, 0.3, 1e-3, 0.0)],
)
def test_qp_data_are_cvxpys_canonical_form_value_for_value(h, dt_s, weight, rho, lower_w) -> None:
    """qp-mpc's OSQP data (the one-building case of the fleet's, controllers/rc_mpc/qp.py, in
    the SPLIT layout) are exactly what cvxpy makes of the problem: same layout, signs and values
    (the heat's bounds the actuator's, a floor above zero included), so OSQP takes the same
    iterates either way."""
    import cvxpy as cp
    import scipy.sparse as sp

    from controllers.rc_mpc.qp import SPLIT, qp_matrices, qp_vectors
    from pinn_mpc.actuator import Actuator

    heat_pump = ActuatorSpec(lower_w=lower_w, upper_w=5000.0, efficiency=Actuator(kind="heat_pump"))
    spec = ControlSpec(actuators=(heat_pump,), horizon_steps=h, dt_s=dt_s, comfort_weight_eur_per_kh=weight)
    problem = RCProblem(params=PARAMS, spec=spec, horizon_steps=h, regularisation_eur_per_kw2h=rho)
    stage = problem.stage(np.array([19.3, 18.1]), _forecast(h, start=5))
    assert np.ptp(stage.cop) > 0 or h == 1  # a COP that varies over the horizon
    data, _, _ = _cvxpy_problem(problem, stage).get_problem_data(cp.OSQP)
    ad, _ = problem.matrices
    p_upper, a = qp_matrices(ad[None], problem.b_u_c_per_kw[None], h, 2.0 * spec.dt_h * rho, SPLIT)
    drift = stage.free_c.copy()
    drift[0] += ad @ stage.x0_c
    q, lower, upper = (v[0] for v in qp_vectors(
        drift[None], stage.heat_price_eur_per_kwh, stage.heat_bounds_kw(spec.actuator), stage.objective, SPLIT
    ))
    want_a = sp.csc_matrix(sp.vstack([data["A"], data["F"]], format="csc"))
    want_p = sp.csc_matrix(sp.triu(data["P"], format="csc"))
    for got, want in ((a, want_a), (p_upper, want_p)):
        assert got.shape == want.shape
        np.testing.assert_array_equal(got.indptr, want.indptr)
        np.testing.assert_array_equal(got.indices, want.indices)
        np.testing.assert_array_equal(got.data, want.data)
    n_eq = len(data["b"])
    np.testing.assert_array_equal(q, data["q"])
    np.testing.assert_array_equal(upper, np.concatenate([data["b"], data["G"]]))
    np.testing.assert_array_equal(lower[:n_eq], data["b"])
    assert np.all(np.isneginf(lower[n_eq:]))


def test_both_layouts_state_one_problem_and_a_fleet_of_one_plans_as_qp_mpc() -> None:
    """The SPLIT rows (qp-mpc's) and the BOX rows (the fleet's) are one QP: solved tightly
    they give the same plan; a one-building FleetQPMPC and QPMPC on the same stage plan alike
    to the solver's tolerance."""
    import osqp

    from controllers.fleet import FleetQPMPC
    from controllers.rc_mpc.qp import BOX, SPLIT, qp_matrices, qp_vectors

    forecast = _forecast(SPEC.horizon_steps)
    single = QPMPC(PARAMS, SPEC)
    stage = single.problem.stage(np.array([19.0, 18.0]), forecast)
    ad, _ = single.problem.matrices
    drift = stage.free_c.copy()
    drift[0] += ad @ stage.x0_c
    plans = {}
    for layout in (SPLIT, BOX):
        p_upper, a = qp_matrices(ad[None], single.problem.b_u_c_per_kw[None], SPEC.horizon_steps, 2e-4, layout)
        q, lower, upper = (v[0] for v in qp_vectors(
            drift[None], stage.heat_price_eur_per_kwh, stage.heat_bounds_kw(SPEC.actuator), stage.objective, layout
        ))
        solver = osqp.OSQP()
        solver.setup(P=p_upper, q=q, A=a, l=lower, u=upper, eps_abs=1e-8, eps_rel=1e-8, max_iter=10**6,
                     polishing=True, verbose=False)
        result = solver.solve(raise_error=False)
        assert str(result.info.status) == "solved"
        plans[layout.name] = result.x[: SPEC.horizon_steps]
    np.testing.assert_allclose(plans["box"], plans["split"], atol=1e-5)
    fleet = FleetQPMPC([PARAMS], SPEC)
    fleet.observe([_first_obs(19.0, 18.0)], forecast)
    assert fleet._stage is not None
    stage = single.problem.stage(fleet._stage.x0_c[0], forecast)
    own = single.problem.objective(stage, single._solve(stage).p_kw)
    planned = single.problem.objective(stage, fleet.plan().power_w[0] / 1000.0)
    assert planned == pytest.approx(own, rel=1e-3)


@pytest.mark.parametrize("layout_name", ["split", "box"])
def test_the_fleets_qp_is_the_buildings_qps_block_by_block(layout_name: str) -> None:
    """B buildings' OSQP data are the one-building data of each, on the block diagonal."""
    import scipy.sparse as sp

    from controllers.rc_mpc.qp import BOX, SPLIT, qp_matrices, qp_vectors

    layout = SPLIT if layout_name == "split" else BOX
    from pinn_mpc.simulator import draw_fleet, fleet_matrices

    h = 6
    fleet = draw_fleet(PARAMS, 3, spread=0.3, rng=np.random.default_rng(2))
    ad, bd = fleet_matrices(fleet, SPEC.dt_s)
    b_u = bd[:, :, 0] * 1000.0
    p_upper, a = qp_matrices(ad, b_u, h, 1e-4, layout)
    ones = [qp_matrices(ad[i : i + 1], b_u[i : i + 1], h, 1e-4, layout) for i in range(3)]
    for got, want in ((p_upper, sp.block_diag([o[0] for o in ones], format="csc")),
                      (a, sp.block_diag([o[1] for o in ones], format="csc"))):
        assert (got != want).nnz == 0
    objective = HorizonObjective.from_forecast(_forecast(h), SPEC, h)
    drift = np.random.default_rng(0).normal(size=(3, h, 2))
    price = np.random.default_rng(1).uniform(0.1, 0.4, size=(3, h))
    bounds = np.zeros(h), np.full(h, 5.0)
    stacked = qp_vectors(drift, price, bounds, objective, layout)
    for i in range(3):
        one = qp_vectors(drift[i : i + 1], price[i], bounds, objective, layout)
        for got, want in zip(stacked, one, strict=True):
            np.testing.assert_array_equal(got[i], want[0])


def test_an_rcs_unmeasured_gains_act_as_the_same_gains_measured() -> None:
    """An RC with an unmeasured-gain schedule plans, observes and predicts as the RC without
    one to which the forecast and the history give those gains as ``I_g``: qp-mpc's free
    response, the fleet's drift and the observer's estimate agree to rounding."""
    from controllers.estimators import KalmanEstimator
    from controllers.fleet import FleetQPMPC
    from pinn_mpc.physics import gain_schedule_index

    schedule = tuple(float(v) for v in np.linspace(0.0, 2300.0, 24))
    scheduled = dataclasses.replace(PARAMS, gain_to_air_fraction=0.7, unmeasured_gains_w=schedule)
    plain = dataclasses.replace(scheduled, unmeasured_gains_w=())
    h = SPEC.horizon_steps
    days = np.repeat([4.0, 5.0], [20, h - 20])
    base = _forecast(h, start=30)._replace(day_of_week=days)
    gains = np.asarray(schedule)[gain_schedule_index(base.time_of_day_h, base.day_of_week)]
    assert np.ptp(gains) > 1000.0  # the forecast spans blocks of both day kinds
    measured = base._replace(I_g=gains)
    x0 = np.array([19.0, 18.0])
    np.testing.assert_allclose(
        RCProblem(params=scheduled, spec=SPEC, horizon_steps=h).stage(x0, base).free_c,
        RCProblem(params=plain, spec=SPEC, horizon_steps=h).stage(x0, measured).free_c,
        atol=1e-12,
    )
    drifts = []
    for params, forecast in ((scheduled, base), (plain, measured)):
        fleet = FleetQPMPC([params], SPEC)
        fleet.observe([_first_obs(19.0, 18.0)], forecast)
        assert fleet._stage is not None
        drifts.append(fleet._stage.drift_c)
    np.testing.assert_allclose(drifts[0], drifts[1], atol=1e-12)
    estimates = []
    for params, i_g in ((scheduled, np.zeros(4)), (plain, gains[:4])):
        estimator = KalmanEstimator.for_spec(params, SPEC)
        history = {
            "T_r": np.array([19.0, 19.4, 19.9, 20.1]), "u_phys": np.array([3000.0, 2000.0, 0.0]),
            "T_a": np.full(4, 2.0), "G": np.zeros(4), "I_g": i_g,
            "time_of_day_h": base.time_of_day_h[:4], "day_of_week": days[:4],
        }
        for k in range(4):
            cut = {name: values[: k + 1] if name != "u_phys" else values[:k] for name, values in history.items()}
            estimate = estimator.update(Observation.from_history(k, cut))
        estimates.append(estimate)
    np.testing.assert_allclose(estimates[0], estimates[1], atol=1e-12)
