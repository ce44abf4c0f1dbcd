"""The closed-loop engine, the estimators and the oracle built by composition."""

import cvxpy as cp
import numpy as np
import pytest

from controllers.base import ControlSpec, Forecast, Observation
from controllers.estimators import KalmanEstimator, OffsetFilter, TrueState
from controllers.objective import HorizonObjective
from controllers.rc_mpc.casadi import CasadiMPC
from controllers.rc_mpc.osqp import QPMPC
from controllers.rc_mpc.problem import DEFAULT_REGULARISATION
from controllers.rc_mpc.references import oracle_mpc
from controllers.thermostat import Thermostat
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InternalError
from pinn_mpc.models.rc import RCBatchModel
from pinn_mpc.physics import PAPER_HOUSEHOLD, discretise
from pinn_mpc.simulator import SimConfig
from scenarios.inputs.series import ExogenousSeries
from scenarios.running.engine import ClosedLoop

SPEC = ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0),))
H = SPEC.horizon_steps


def _series(n: int) -> ExogenousSeries:
    hours = (np.arange(n) * 0.5) % 24.0
    return ExogenousSeries(
        time_of_day_h=hours,
        T_a=3.0 + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0),
        G=np.where((hours > 8) & (hours < 16), 200.0, 0.0),
        I_g=np.full(n, 150.0),
        price=np.where(hours < 6, 0.12, 0.25),
        T_min=np.where((hours >= 7) & (hours < 22), 20.0, 17.0),
        T_max=np.full(n, 23.0),
    )


def _loop(n: int = 20, **kwargs) -> ClosedLoop:
    return ClosedLoop(
        SimConfig(), _series(n + H), spec=SPEC, initial_t_r_c=19.0, initial_t_m_c=18.0, **kwargs
    )


def test_observation_carries_the_last_interval_in_the_forecast_names():
    loop = _loop()
    first = loop.advance(Thermostat(SPEC))
    assert first.observation.last is None and first.k == 0
    second = loop.advance(Thermostat(SPEC))
    last = second.observation.last
    assert last is not None
    # The interval that just ended is the first decision's forecast row 0 and its plant step.
    for name in ("time_of_day_h", "T_a", "G", "I_g"):
        assert getattr(last, name) == getattr(first.forecast, name)[0]
    assert last.u == first.u_w and last.u_phys == float(first.plant.u_phys_w[0])
    assert second.observation.t_r_c == pytest.approx(float(first.plant.t_r_c[0, 0]))
    assert second.forecast.T_a[0] == second.observation.history["T_a"][-1]


def test_kalman_estimator_on_the_engine_finds_the_hidden_t_m():
    loop = _loop(n=60)
    estimator = KalmanEstimator(PAPER_HOUSEHOLD, SPEC.dt_s)
    estimator.reset()
    controller = Thermostat(SPEC)
    for _ in range(60):
        t_m_true = float(loop.true_state()[0, 1])
        estimate = estimator.update(loop.observation())
        loop.advance(controller)
    assert abs(estimate[1] - t_m_true) < 0.05
    # A step that does not follow the previous one restarts at the measurement.
    jumped = loop.observation()._replace(k=loop.k + 5)
    np.testing.assert_array_equal(estimator.update(jumped), [jumped.t_r_c, jumped.t_r_c])


def test_true_state_refuses_a_missing_t_m():
    obs = Observation.from_history(0, {"T_r": np.array([19.0])})
    with pytest.raises(ValueError, match="true thermal-mass temperature"):
        TrueState().update(obs)


def test_offset_filter_of_an_exact_model_stays_zero_and_follows_a_bias():
    loop = _loop(n=12)
    model = RCBatchModel(PAPER_HOUSEHOLD, dt_s=SPEC.dt_s, actuator=SPEC.actuator)
    exact, biased = OffsetFilter(model, 0.5), OffsetFilter(model, 0.5)
    thermostat = Thermostat(SPEC)
    for _ in range(12):
        obs = loop.observation()
        history = {**obs.history, "T_m": np.full(len(obs.history["T_r"]), np.nan)}
        if obs.k >= 1:  # the true T_m one step ago, so the model's one-step prediction is exact
            history["T_m"][-2] = loop.record().t_m_c[-1, 0]
        exact.update(obs._replace(history=history))
        shifted = obs._replace(history=history, t_r_c=obs.t_r_c + 0.2)
        biased.update(shifted)
        loop.advance(thermostat)
    # Ten updates (from k=2, the first with a one-step prediction); float32 rollouts.
    assert exact.offset_k == pytest.approx(0.0, abs=1e-5)
    assert biased.offset_k == pytest.approx(0.2 * (1 - 0.5**10), abs=1e-5)


def _independent_qp_first_action(x0: np.ndarray, forecast: Forecast) -> float:
    """The oracle's problem written out again in cvxpy: the shared objective plus the
    regulariser, exact ZOH dynamics from the true state."""
    ad, bd = discretise(PAPER_HOUSEHOLD, SPEC.dt_s)
    objective = HorizonObjective.from_forecast(forecast, SPEC, H)
    p = cp.Variable(H)  # kW
    x = cp.Variable((H + 1, 2))
    s = cp.Variable(H, nonneg=True)
    d = np.stack([forecast.T_a[:H], forecast.G[:H], forecast.I_g[:H]], axis=1)
    cons = [x[0] == x0, p >= 0, p <= SPEC.u_max_w / 1000.0]
    cons += [x[j + 1] == ad @ x[j] + bd[:, 0] * 1000.0 * p[j] + bd[:, 1:] @ d[j] for j in range(H)]
    cons += [s >= objective.t_min_c - x[1:, 0], s >= x[1:, 0] - objective.t_max_c]
    cost = SPEC.dt_h * (
        objective.price_eur_per_kwh @ p
        + SPEC.comfort_weight_eur_per_kh * cp.sum(s)
        + DEFAULT_REGULARISATION * cp.sum_squares(p)
    )
    cp.Problem(cp.Minimize(cost), cons).solve(solver=cp.CLARABEL)
    assert p.value is not None
    return float(p.value[0]) * 1000.0


@pytest.mark.parametrize(("t_r_c", "t_m_c"), [(18.5, 17.0), (20.5, 21.0)])
def test_oracle_by_composition_is_the_true_state_qp(t_r_c, t_m_c):
    loop = ClosedLoop(
        SimConfig(), _series(2 * H), spec=SPEC, initial_t_r_c=t_r_c, initial_t_m_c=t_m_c
    )
    obs, forecast = loop.observation(), loop.forecast()
    oracle = oracle_mpc(PAPER_HOUSEHOLD, SPEC)
    casadi = CasadiMPC(PAPER_HOUSEHOLD, SPEC, estimator=TrueState())
    action = oracle.act(obs, forecast)
    assert oracle.name == "oracle" and isinstance(oracle, QPMPC)
    np.testing.assert_array_equal(oracle.state_estimate_c, [t_r_c, t_m_c])
    reference = _independent_qp_first_action(np.array([t_r_c, t_m_c]), forecast)
    assert action == pytest.approx(reference, abs=0.002 * SPEC.u_max_w)
    assert casadi.act(obs, forecast) == pytest.approx(reference, abs=0.002 * SPEC.u_max_w)


def test_engine_validates_its_inputs():
    bad = _series(10)
    with pytest.raises(ValueError, match="non-finite"):
        ClosedLoop(
            SimConfig(),
            ExogenousSeries(**{**bad.__dict__, "T_a": np.full(10, np.nan)}),
            spec=SPEC,
            initial_t_r_c=19.0,
            initial_t_m_c=18.0,
        )
    with pytest.raises(InternalError, match="one length"):
        ExogenousSeries(**{**bad.__dict__, "G": np.zeros(3)})
    loop = _loop(n=1)
    for _ in range(1 + H):
        loop.step(0.0)
    with pytest.raises(InternalError, match="exhausted"):
        loop.step(0.0)
