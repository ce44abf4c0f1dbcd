"""A multi-zone RC model's response to its plan (:meth:`MultiZoneRCModel.linear_response`) and
the LP polish over it (:func:`controllers.lp_polish.solve_state_lp`): the response is the
building's impulse response written out by hand (``Ad^(j-i) Bu`` times the heat per watt),
equals the rollout's finite differences, is zero where the backup thermostat forces an
actuator, and the polish over it plans what the polish over probes plans."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from controllers.base import Forecast
from controllers.lp_polish import PlanProblem, StateQP, solve_lp, solve_state_lp
from controllers.objective import ZoneObjective
from controllers.sampling import CEM
from pinn_mpc import multizone
from pinn_mpc.models.multizone_rc import MultiZoneRCModel
from pinn_mpc.models.rollout import LinearResponse
from tests.test_multizone_planners import (
    DT_S,
    _first_history,
    _obs,
    _spec,
    _spring_day,
    _three_zones,
    _weather,
)


def _rollout64(model: MultiZoneRCModel, history: dict, plans: np.ndarray, weather: dict) -> tuple[np.ndarray, np.ndarray]:
    """(N, H, Z) rooms and (N, H) delivered power of plans (N, H, A), in float64."""
    roll = model.rollout(history, torch.tensor(plans, dtype=torch.float64), weather)
    return roll.t_r_c[0].numpy(), roll.u_phys_w[0].numpy()


def test_the_response_is_the_impulse_response_of_the_zero_order_hold():
    """Without the backup acting: d T_r(j) / d u(i, a) = [Ad^(j-i) Bu]_(room, a) x COP(i, a) for
    j >= i, 0 before; the delivered power moves 1 W per W in its own interval; the rollout at
    the plan is the model's."""
    params, actuators = _three_zones()
    model = MultiZoneRCModel(params, actuators, DT_S, backup_low_c=-50.0, backup_high_c=80.0)
    h = 12
    weather = _weather(h, 5)
    history = _first_history(params, np.array([20.0, 19.0, 21.0]), np.array([19.5, 19.0, 20.0]), weather)
    plan = np.random.default_rng(6).uniform(0.3, 0.7, (h, 4)) * [4000.0, 3000.0, 1800.0, 5000.0] + [0, 0, 200.0, 0]
    response = model.linear_response(history, plan, weather)
    jr, jp = response.jacobians()
    a, b_u, _ = multizone.discretise(params, actuators, DT_S)
    for i in (0, 5, 11):
        cop = np.array([s.efficiency.gain(weather["T_a"][i]) for s in actuators])
        for j in range(h):
            want = (np.linalg.matrix_power(a, j - i) @ b_u)[:3] * cop if j >= i else np.zeros((3, 4))
            np.testing.assert_allclose(jr[j, :, i, :], want, rtol=1e-10, atol=1e-16)
    np.testing.assert_array_equal(jp, np.eye(h)[:, :, None] * np.ones(4))
    t_r, u_phys = _rollout64(model, history, plan[None], weather)
    np.testing.assert_allclose(response.t_r_c, t_r[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(response.u_phys_w, u_phys[0], rtol=1e-12)


def test_the_response_is_the_rollouts_finite_differences_and_zero_where_the_backup_forces():
    """The backup's limits set so that it forces some actuators in some intervals: every column
    equals the rollout's central difference (a move of 1 mW switches no thermostat), a forced
    step's column is 0 and some are."""
    params, actuators = _three_zones()
    model = MultiZoneRCModel(params, actuators, DT_S, backup_low_c=(19.0, 18.0, 17.5), backup_high_c=(21.0, 22.0, 20.5))
    h = 10
    weather = _weather(h, 1)
    history = _first_history(params, np.array([20.5, 18.5, 19.0]), np.array([19.0, 19.5, 18.0]), weather)
    plan = np.random.default_rng(2).uniform(0.2, 0.8, (h, 4)) * [4000.0, 3000.0, 1800.0, 5000.0] + [0, 0, 200.0, 0]
    response = model.linear_response(history, plan, weather)
    jr, jp = response.jacobians()
    delta = 1e-3
    moved = np.repeat(plan[None], 2 * h * 4, axis=0)
    for k in range(h * 4):
        moved[2 * k].reshape(-1)[k] += delta
        moved[2 * k + 1].reshape(-1)[k] -= delta
    t_r, u_phys = _rollout64(model, history, moved, weather)
    fd_r = ((t_r[0::2] - t_r[1::2]) / (2 * delta)).reshape(h, 4, h, 3).transpose(2, 3, 0, 1)  # (H, Z, H, A)
    fd_p = ((u_phys[0::2] - u_phys[1::2]) / (2 * delta)).reshape(h, 4, h).transpose(2, 0, 1)
    np.testing.assert_allclose(jr, fd_r, rtol=0, atol=1e-9)
    np.testing.assert_allclose(jp, fd_p, rtol=0, atol=1e-6)
    forced = response.power == 0
    assert forced.any() and (~forced).any()
    assert np.all(jr[:, :, forced] == 0) and np.all(response.heat_per_w[forced] == 0)


def test_a_response_of_mismatched_shapes_is_refused_naming_the_field():
    with pytest.raises(ValueError, match=r"LinearResponse\.power has shape \(3, 1\)"):
        LinearResponse(t_r_c=np.zeros((4, 2)), u_phys_w=np.zeros(4), a=np.eye(4), b_heat=np.zeros((4, 2)),
                       heat_per_w=np.ones((4, 2)), rooms=np.arange(2), power=np.ones((3, 1)))


def test_the_state_lp_has_the_dense_lps_optimum():
    """The LP over the states (sparse) and over the dense sensitivities (the states eliminated)
    are one LP: the same plan, on a building whose backup forces some steps."""
    params, actuators = _three_zones()
    model = MultiZoneRCModel(params, actuators, DT_S, backup_low_c=(19.0, 18.0, 17.5), backup_high_c=(21.0, 22.0, 20.5))
    spec = _spec(params, actuators, horizon_steps=16)
    series = _spring_day(40)
    h = 16
    fc = Forecast(**series)
    objective = ZoneObjective.from_forecast(fc, spec, h)
    weather = fc.exogenous(model.exog_names, h)
    history = _first_history(params, np.array([20.5, 18.5, 19.0]), np.array([19.0, 19.5, 18.0]), weather)
    span = np.array([a.span_w for a in actuators])
    lower = np.array([a.lower_w for a in actuators])
    u0 = np.random.default_rng(3).uniform(0.0, 1.0, (h, 4))
    response = model.linear_response(history, lower + span * u0, weather)
    problem = PlanProblem(objective=objective, lower=0.0, upper=1.0)
    state = solve_state_lp(response, u0, span, problem, 0.5)
    jr, jp = response.jacobians()
    dense = solve_lp(response.t_r_c.reshape(1, -1), (jr * span).reshape(1, h * 3, h * 4),
                     (jp * span).reshape(1, h, h * 4), u0.reshape(-1), problem, 0.5, unit=1.0)
    assert state is not None and dense is not None
    np.testing.assert_allclose(state, dense.reshape(h, 4), rtol=0, atol=1e-6)
    assert np.abs(state - u0).max() > 0.1  # the LP moved the plan


class _Probed(MultiZoneRCModel):
    """The same model without its response: the polish probes it."""

    def linear_response(self, history, u_w, exog) -> None:  # type: ignore[override]
        return None


@pytest.mark.parametrize("limits", [(12.0, 30.0), (19.0, 21.0)], ids=["backup-idle", "backup-forcing"])
def test_cem_polished_over_the_response_plans_what_cem_polished_over_probes_plans(limits):
    """One decision of CEM (same seed) over the model and over the same model probed: the same
    plan, up to the probes' float32 differences."""
    params, actuators = _three_zones()
    spec = _spec(params, actuators, horizon_steps=24)
    series = _spring_day(40)
    plans = []
    for kind in (MultiZoneRCModel, _Probed):
        cem = CEM(kind(params, actuators, DT_S, backup_low_c=limits[0], backup_high_c=limits[1]), spec)
        cem.reset(seed=0)
        cem.act(_obs(params, np.array([19.0, 18.0, 24.5]), series), Forecast(**series))
        assert not cem.last_stats.fallback and cem.last_plan is not None
        plans.append(cem.last_plan)
    span = np.array([a.span_w for a in actuators])
    np.testing.assert_allclose(plans[0] / span, plans[1] / span, rtol=0, atol=2e-3)


def test_the_qp_of_a_large_plan_reaches_the_lps_optimum():
    """:class:`StateQP` (OSQP, without its iteration limit) on the LP of
    :func:`test_the_state_lp_has_the_dense_lps_optimum`: the linearised objective of its plan
    within 0.1 % of the LP's optimum (the regulariser and OSQP's tolerance apart); a second
    solve, warm-started, reuses the factorisation."""
    params, actuators = _three_zones()
    model = MultiZoneRCModel(params, actuators, DT_S, backup_low_c=(19.0, 18.0, 17.5), backup_high_c=(21.0, 22.0, 20.5))
    spec = _spec(params, actuators, horizon_steps=16)
    h = 16
    fc = Forecast(**_spring_day(40))
    objective = ZoneObjective.from_forecast(fc, spec, h)
    weather = fc.exogenous(model.exog_names, h)
    history = _first_history(params, np.array([20.5, 18.5, 19.0]), np.array([19.0, 19.5, 18.0]), weather)
    span = np.array([a.span_w for a in actuators])
    lower = np.array([a.lower_w for a in actuators])
    problem = PlanProblem(objective=objective, lower=0.0, upper=1.0)
    qp = StateQP({"max_iter": 100000, "eps_abs": 1e-6, "eps_rel": 1e-6}, warm_max_iter=100000)
    rng = np.random.default_rng(3)
    for _ in range(2):
        u0 = rng.uniform(0.0, 1.0, (h, 4))
        response = model.linear_response(history, lower + span * u0, weather)
        jr, jp = response.jacobians()

        def cost(plan: np.ndarray) -> float:
            du = (plan - u0) * span  # noqa: B023 (this iteration's plan)
            t_r = response.t_r_c + np.einsum("jzia,ia->jz", jr, du)  # noqa: B023
            power = np.einsum("jia,ia->j", jp, du)  # noqa: B023
            violation = np.maximum(objective.t_min_c - t_r, 0) + np.maximum(t_r - objective.t_max_c, 0)
            energy = objective.price_eur_per_kwh * objective.dt_h * power / 1000.0
            return float(energy.sum() + objective.comfort_weight_eur_per_kh * objective.dt_h * violation.sum())

        lp = solve_state_lp(response, u0, span, problem, 0.5)
        plan = qp.solve(response, u0, span, problem, 0.5)
        assert lp is not None and plan is not None and qp.last_info.status == "solved"
        assert cost(lp) < cost(u0) - 0.5  # the LP gains something
        assert cost(plan) == pytest.approx(cost(lp), rel=1e-3, abs=1e-3)
        assert np.all(plan >= 0.0) and np.all(plan <= 1.0) and np.abs(plan - u0).max() <= 0.5 + 1e-9


def test_cem_polishing_a_large_plan_by_the_qp_finds_the_optimum_of_its_model(monkeypatch):
    """test_multizone_planners' optimum test with every plan polished by the QP (the LP's
    size limit 0): the plan's cost on the model within 0.5 % of the QP MPC's optimum."""
    import controllers.zone_sampling
    from tests.test_multizone_planners import test_cem_over_zones_finds_the_optimum_of_its_model

    monkeypatch.setattr(controllers.zone_sampling, "MAX_LP_PLAN", 0)
    calls = []
    solve = StateQP.solve
    monkeypatch.setattr(StateQP, "solve", lambda self, *a: calls.append(1) or solve(self, *a))
    test_cem_over_zones_finds_the_optimum_of_its_model()
    assert calls
