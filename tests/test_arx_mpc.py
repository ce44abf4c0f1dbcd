"""qp-mpc over an ARX model against analytic truth: its prediction matrices are the ARX's own
recursion, on an ARX that is exactly a 2R2C it plans as the QP MPC on that 2R2C's true state
does, and a failed solve acts through the fallback and is counted."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from controllers.arx_mpc import ARXQPMPC
from controllers.base import ControlSpec, Forecast, Observation, fallback_power
from controllers.objective import HorizonObjective
from controllers.rc_mpc.references import oracle_mpc
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.features import time_of_day_h
from pinn_mpc.models.arx import ARXModel, fit_arx, fit_physics_informed_arx
from pinn_mpc.physics import PAPER_HOUSEHOLD, RCParams, discretise
from pinn_mpc.simulator import SimConfig
from scenarios.inputs.series import ExogenousSeries
from scenarios.running.engine import ClosedLoop
from tests.test_arx import _occupied_data, _rc_data

SPEC = ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0),))
#: Tight OSQP tolerances where two QPs must give the same optimum, not just a good plan.
TIGHT = {"eps_abs": 1e-9, "eps_rel": 1e-9, "max_iter": 200000}
_SCALE = {"u_phys": 1e-3, "T_a": 1.0, "G": 1e-2, "I_g": 1e-3}  # the ARX's input scales


def arx_of_rc(params: RCParams, dt_s: float) -> ARXModel:
    """The 2R2C's room temperature as the ARX of order 2 it exactly is (Cayley-Hamilton on the
    exact discretisation ``x+ = A x + B d``): ``T_r,k+1 = tr(A) T_r,k - det(A) T_r,k-1 +
    e1'B d_k + e1'(A - tr(A) I) B d_k-1``, with a zero weekly schedule."""
    ad, bd = discretise(params, dt_s)
    tr, det = float(np.trace(ad)), float(np.linalg.det(ad))
    lag = [bd[0], (ad - tr * np.eye(2))[0] @ bd]  # (4,) each: u, T_a, G, I_g
    columns = ("T_r", "u_phys", "T_a", "G", "I_g")
    coef = np.zeros(2 * len(columns) + 2 * 12)
    coef[0], coef[len(columns)] = tr, -det
    for j in range(2):
        for c, name in enumerate(columns[1:], start=1):
            coef[j * len(columns) + c] = lag[j][c - 1] / _SCALE[name]
    return ARXModel(columns=columns, lags=2, coef=coef, dt_s=dt_s, train_mae_c=0.0)


def _forecast(n: int, start: int) -> Forecast:
    """A day with weather, sun, internal gains, a price peak and a night setback (Mondays)."""
    k = np.arange(start, start + n)
    hours = (k * 0.5) % 24.0
    return Forecast(
        time_of_day_h=hours,
        T_a=3.0 + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0),
        G=np.clip(400 * np.sin((hours - 6.0) / 12.0 * np.pi), 0.0, None),
        I_g=np.where((hours >= 8) & (hours < 18), 800.0, 100.0),
        price=np.where((hours > 17) & (hours < 21), 0.45, np.where(hours < 6, 0.12, 0.25)),
        T_min=np.where((hours >= 7) & (hours < 22), 20.0, 17.0),
        T_max=np.full(n, 23.0),
        day_of_week=np.zeros(n),
    )


def _history_of(params: RCParams, x0: np.ndarray, u_w: np.ndarray, fc: Forecast) -> tuple[dict, np.ndarray]:
    """The history of the exact discrete 2R2C from ``x0`` under ``u_w`` and the forecast's
    first ``len(u_w)`` inputs; and the state at its end."""
    ad, bd = discretise(params, SPEC.dt_s)
    x, t_r = np.asarray(x0, dtype=float), [float(x0[0])]
    for k, u in enumerate(u_w):
        x = ad @ x + bd @ np.array([u, fc.T_a[k], fc.G[k], fc.I_g[k]])
        t_r.append(float(x[0]))
    n = len(u_w) + 1
    history = {
        "T_r": np.array(t_r), "u": np.array(u_w), "u_phys": np.array(u_w),
        **{name: np.asarray(getattr(fc, name))[:n] for name in ("T_a", "G", "I_g", "time_of_day_h", "day_of_week")},
    }
    return history, x


def _later(fc: Forecast, k: int) -> Forecast:
    return Forecast._make(None if a is None else np.asarray(a)[k:] for a in fc)  # no facades


@pytest.mark.parametrize("physics_informed", [False, True])
def test_prediction_matrices_are_the_arx_recursion(physics_informed: bool) -> None:
    """``free + gain @ plan`` equals the ARX's own recursion (predict_t_r on the data) of the
    same plan at every step of the horizon, to 1e-9 K; gain is lower triangular and, with the
    physics-informed ARX's schedule x (T_r - T_a) weight, changes along the horizon."""
    if physics_informed:
        model, test = fit_physics_informed_arx(_occupied_data(21, seed=0), lags=3), _occupied_data(4, seed=1)
    else:
        model, test = fit_arx(_rc_data(21, seed=0), lags=4), _rc_data(3, seed=1)
    k, h = 100, 40  # a Thursday afternoon: the horizon crosses schedule blocks
    time = pd.to_datetime(test["time"])
    history = {name: test[name].to_numpy()[: k + 1] for name in model.columns}
    history["u_phys"] = test["u_phys"].to_numpy()[:k]
    exog = {"time_of_day_h": time_of_day_h(test["time"])[k : k + h],
            "day_of_week": time.dt.day_of_week.to_numpy(dtype=float)[k : k + h],
            **{name: test[name].to_numpy()[k : k + h] for name in model.columns[2:]}}
    free, gain = model.prediction_matrices(history, exog, h)
    plan = test["u_phys"].to_numpy()[k : k + h]
    predicted = free + gain @ plan
    for step in range(1, h + 1):
        expected = model.predict_t_r(test, step, np.array([k]))[0]
        assert predicted[step - 1] == pytest.approx(expected, abs=1e-9)
    assert np.array_equal(gain, np.tril(gain)) and np.all(np.diag(gain) > 0)
    # with the interaction the response to a power depends on when it is given
    varies = not np.allclose(np.diag(gain, -1), np.diag(gain, -1)[0], rtol=1e-9, atol=0)
    assert varies == physics_informed
    with pytest.raises(InternalError, match="past values of T_r"):
        model.prediction_matrices({**history, "T_r": history["T_r"][-1:]}, exog, h)


def test_an_arx_of_the_2r2c_predicts_it_exactly() -> None:
    """The analytic construction the planning tests rest on: its recursion is the 2R2C's."""
    model = arx_of_rc(PAPER_HOUSEHOLD, SPEC.dt_s)
    fc = _forecast(60, start=0)
    u = np.random.default_rng(0).uniform(0, 5000, 60)
    history, _ = _history_of(PAPER_HOUSEHOLD, np.array([19.0, 17.0]), u[:2], fc)
    truth, _ = _history_of(PAPER_HOUSEHOLD, np.array([19.0, 17.0]), u, fc)
    exog = {name: np.asarray(getattr(fc, name))[2:] for name in model.exog_names}
    free, gain = model.prediction_matrices(history, exog, 58)
    np.testing.assert_allclose(free + gain @ u[2:], truth["T_r"][3:], atol=1e-9)


@pytest.mark.parametrize(("x0", "k"), [((19.0, 17.0), 2), ((17.5, 18.5), 14), ((21.0, 20.0), 30)])
def test_plan_equals_the_rc_qp_on_the_true_state(x0: tuple[float, float], k: int) -> None:
    """On an ARX that is exactly the 2R2C, qp-mpc over the ARX (from the measured history) and
    the QP MPC on the 2R2C's true state solve the same problem: the same plan and objective."""
    fc = _forecast(k + 60, start=0)
    u_past = np.random.default_rng(k).uniform(0, 5000, k)
    history, x = _history_of(PAPER_HOUSEHOLD, np.array(x0), u_past, fc)
    obs = Observation.from_history(k, history, float(x[1]))
    ahead = _later(fc, k)
    arx_mpc = ARXQPMPC(arx_of_rc(PAPER_HOUSEHOLD, SPEC.dt_s), SPEC, offset_gain=0.0, solver_options=TIGHT)
    oracle = oracle_mpc(PAPER_HOUSEHOLD, SPEC, solver_options=TIGHT)
    a_arx, a_rc = arx_mpc.act(obs, ahead), oracle.act(obs, ahead)
    assert not arx_mpc.last_stats.fallback and not oracle.last_stats.fallback
    assert arx_mpc.last_stats.status == "solved"
    plan_arx, plan_rc = arx_mpc.last_plan, oracle.last_plan
    assert plan_arx is not None and plan_rc is not None
    np.testing.assert_allclose(plan_arx, plan_rc, atol=1e-3)  # W, of plans up to 5000 W
    assert a_arx == pytest.approx(a_rc, abs=1e-3)
    assert 0 < plan_arx.max() and plan_arx.min() < SPEC.u_max_w  # an interior, modulating plan
    stage = oracle.problem.stage(oracle.state_estimate_c, ahead)
    np.testing.assert_allclose(arx_mpc.last_prediction_c, oracle.problem.rollout(stage, plan_arx / 1000)[:, 0], atol=1e-6)
    objective = HorizonObjective.from_forecast(ahead, SPEC, SPEC.horizon_steps)
    assert float(objective.cost(plan_arx, arx_mpc.last_prediction_c)) == pytest.approx(
        oracle.problem.objective(stage, plan_rc / 1000), rel=1e-7
    )


def test_closed_loop_cost_equals_the_oracles() -> None:
    """Closed loop on the 2R2C plant (backup thermostat out of reach, so the 2R2C is exact),
    after two thermostat intervals that give the ARX its history: qp-mpc over the exact ARX
    with default options (offset filter on) realises the oracle's actions and objective."""
    from controllers.thermostat import Thermostat

    n, h, warm = 48, SPEC.horizon_steps, 2
    fc = _forecast(warm + n + h, start=0)

    def run(controller) -> tuple[np.ndarray, float]:
        loop = ClosedLoop(
            SimConfig(params=PAPER_HOUSEHOLD, backup_low_c=-50.0, backup_high_c=80.0),
            ExogenousSeries(**fc._asdict()), spec=SPEC, initial_t_r_c=19.0, initial_t_m_c=17.0,
        )
        controller.reset(seed=0)
        for _ in range(warm):
            loop.advance(Thermostat(SPEC))
        t_r = []
        for _ in range(n):
            decision = loop.advance(controller)
            assert decision.error is None and not decision.fallback
            t_r.append(float(decision.plant.t_r_c[0, 0]))
        u = loop.record().u_w[warm:]
        return u, float(HorizonObjective.from_forecast(_later(fc, warm), SPEC, n).cost(u, np.array(t_r)))

    arx_mpc = ARXQPMPC(arx_of_rc(PAPER_HOUSEHOLD, SPEC.dt_s), SPEC)
    u_arx, j_arx = run(arx_mpc)
    u_rc, j_rc = run(oracle_mpc(PAPER_HOUSEHOLD, SPEC))
    assert arx_mpc.n_fallbacks == 0
    assert 0 < u_rc.max() and u_rc.min() < SPEC.u_max_w
    np.testing.assert_allclose(u_arx, u_rc, atol=2.0)  # W
    assert j_arx == pytest.approx(j_rc, rel=1e-3)
    assert abs(arx_mpc.estimator.offset_k) < 1e-6  # the model is exact: nothing to offset


def test_solver_failure_and_bad_data_fall_back_and_are_counted() -> None:
    """A solver stopped before convergence acts as QPMPC's does (the band-keeping rule, no plan
    kept); a non-finite forecast after a solve uses the shifted previous plan; both counted."""
    fc = _forecast(80, start=0)
    history, x = _history_of(PAPER_HOUSEHOLD, np.array([17.5, 17.0]), np.full(4, 1000.0), fc)
    obs = Observation.from_history(4, history, float(x[1]))
    model = arx_of_rc(PAPER_HOUSEHOLD, SPEC.dt_s)
    stopped = ARXQPMPC(model, SPEC, solver_options={"max_iter": 1})
    action = stopped.act(obs, _later(fc, 4))
    assert stopped.last_stats.fallback and stopped.n_fallbacks == 1
    assert "maximum iterations" in stopped.last_stats.status
    assert action == fallback_power(obs, _later(fc, 4), SPEC) and stopped.last_plan is None

    mpc = ARXQPMPC(model, SPEC)
    mpc.act(obs, _later(fc, 4))
    plan = mpc.last_plan
    assert plan is not None and not mpc.last_stats.fallback and mpc.n_fallbacks == 0
    history, x = _history_of(PAPER_HOUSEHOLD, np.array([17.5, 17.0]), np.append(np.full(4, 1000.0), plan[0]), fc)
    bad = _later(fc, 5)._replace(price=np.full(75, np.nan))
    action = mpc.act(Observation.from_history(5, history, float(x[1])), bad)
    assert mpc.last_stats.fallback and mpc.n_fallbacks == 1 and "non-finite" in mpc.last_stats.status
    assert action == pytest.approx(plan[1])
    no_dates = ARXQPMPC(model, SPEC)
    no_dates.act(obs, _later(fc, 4)._replace(day_of_week=None))
    assert no_dates.n_fallbacks == 1 and "calendar" in no_dates.last_stats.status


def test_it_refuses_a_model_of_another_interval_or_a_cooling_model() -> None:
    model = arx_of_rc(PAPER_HOUSEHOLD, 900.0)
    with pytest.raises(InputError, match="intervals"):
        ARXQPMPC(model, SPEC)
    cooling = ARXModel(columns=model.columns, lags=model.lags, coef=-model.coef, dt_s=SPEC.dt_s, train_mae_c=0.0)
    with pytest.raises(InputError, match="cooling machine"):
        ARXQPMPC(cooling, SPEC)


def test_closed_loop_qp_mpc_plans_on_an_arx_directory_and_refuses_a_network(tmp_path, capsys) -> None:
    """The user's path: ``closed-loop --controller qp-mpc --model ARX_DIR`` plans on the ARX
    (every decision a solve, none a fallback after the warm-up); a learned network's directory,
    or an ARX with --rc too, is refused with one line and exit status 2."""
    import json

    from pinn_mpc.artifacts import save_model
    from pinn_mpc.data import write_timeseries
    from pinn_mpc.training import TrainConfig, train_model
    from pinn_mpc_cli.cli import main
    from tests.model_data import household_data

    data = tmp_path / "d.csv"
    write_timeseries(household_data(14, 0), data)
    arx = tmp_path / "arx"
    assert main(["train", "--data", str(data), "--arch", "arx", "--out", str(arx)]) == 0
    kpis, csv = tmp_path / "k.json", tmp_path / "k.csv"
    args = ["closed-loop", "--scenario", "winter_household", "--controller", "qp-mpc", "--days", "1"]
    assert main([*args, "--model", str(arx), "--json", str(kpis), "--csv", str(csv)]) == 0
    record = json.loads(kpis.read_text())
    assert record["controller"] == "qp-mpc" and record["objective"] > 0
    assert record["fallbacks"] == 0
    assert "fallback" in pd.read_csv(csv).columns
    network = tmp_path / "net"
    save_model(train_model(household_data(3, 0), arch="physnet",
                           config=TrainConfig(n_seeds=1, epochs=1, depth=4), progress=False), network)
    capsys.readouterr()
    for extra, message in (
        (["--model", str(network)], "this --model is a learned network"),
        (["--model", str(arx), "--rc", str(tmp_path / "rc.json")], "not both"),
    ):
        assert main([*args, *extra, "--json", str(tmp_path / "x.json")]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err, err


def test_a_comfort_margin_keeps_the_plan_that_far_inside_the_band() -> None:
    """With ``comfort_margin_k`` the plan keeps its predicted T_r that far inside the band where
    the band is reachable, at a higher energy cost than without."""
    fc = _forecast(80, start=0)._replace(T_min=np.full(80, 20.0))  # a band 5 kW can hold
    history, x = _history_of(PAPER_HOUSEHOLD, np.array([21.0, 21.0]), np.full(12, 4500.0), fc)
    obs, ahead = Observation.from_history(12, history, float(x[1])), _later(fc, 12)
    model = arx_of_rc(PAPER_HOUSEHOLD, SPEC.dt_s)
    spec = ControlSpec(actuators=SPEC.actuators, comfort_weight_eur_per_kh=50.0)  # comfort first
    plain, margin = ARXQPMPC(model, spec), ARXQPMPC(model, spec, comfort_margin_k=0.3)
    plain.act(obs, ahead)
    margin.act(obs, ahead)
    band = HorizonObjective.from_forecast(ahead, spec, spec.horizon_steps)
    held = margin.last_prediction_c - band.t_min_c
    assert np.min(plain.last_prediction_c - band.t_min_c) == pytest.approx(0.0, abs=2e-3)  # rides it
    assert np.min(held) == pytest.approx(0.3, abs=5e-3)  # OSQP tolerances
    assert margin.last_plan is not None and plain.last_plan is not None
    assert margin.last_plan.sum() > plain.last_plan.sum()
    with pytest.raises(ValueError, match="comfort_margin_k"):
        ARXQPMPC(model, SPEC, comfort_margin_k=-0.1)
