"""Kalman observer: convergence to the hidden T_m, the Riccati fixed point, batch consistency."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.observer import KalmanObserver
from pinn_mpc.physics import PAPER_HOUSEHOLD, steady_state
from pinn_mpc.simulator import SimConfig, Simulator

PARAMS = dataclasses.replace(PAPER_HOUSEHOLD, solar_aperture_m2=3.0, solar_to_air_fraction=0.3)


def _simulate(n_steps: int, seed: int, noise_std_c: float = 0.0) -> dict[str, np.ndarray]:
    """Random on/off heating with a daily outdoor cycle and sun; arrays (n_steps,) or (n+1,)."""
    rng = np.random.default_rng(seed)
    sim = Simulator(SimConfig(params=PARAMS, noise_std_c=noise_std_c), seed=seed)
    sim.reset(19.0, 17.0)
    hours = np.arange(n_steps) * 0.5
    t_a = 4.0 + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0)
    g = 300.0 * np.clip(np.sin(2 * np.pi * (hours - 6.0) / 24.0), 0.0, None)
    u = np.where(rng.random(n_steps) < 0.5, 5000.0, 0.0)
    t_r, t_m, u_phys = [sim.measure()[0]], [sim.state[0, 1]], []
    for k in range(n_steps):
        r = sim.step(u[k], t_a[k], g[k], 0.0)
        t_r.append(sim.measure()[0])
        t_m.append(r.t_m_c[0])
        u_phys.append(r.u_phys_w[0])
    return {"t_r": np.array(t_r), "t_m": np.array(t_m), "u_phys": np.array(u_phys), "t_a": t_a, "g": g}


@pytest.mark.parametrize("noise_std_c", [0.0, 0.05])
def test_converges_to_hidden_thermal_mass_from_a_wrong_guess(noise_std_c: float) -> None:
    data = _simulate(96, seed=1, noise_std_c=noise_std_c)
    obs = KalmanObserver(PARAMS, 1800.0)
    obs.reset(data["t_r"][0], t_m_c=data["t_r"][0] + 4.0)  # truth is 2 K below T_r: 6 K off
    assert abs(obs.state[0, 1] - data["t_m"][0]) > 5.0  # it does start wrong
    errors = []
    for k in range(96):
        obs.predict(data["u_phys"][k], data["t_a"][k], data["g"][k], 0.0)
        est = obs.update(data["t_r"][k + 1])
        errors.append(abs(est[0, 1] - data["t_m"][k + 1]))
    assert max(errors[48:]) < 0.2  # after a day


def test_covariance_reaches_the_riccati_fixed_point() -> None:
    obs = KalmanObserver(PAPER_HOUSEHOLD, 1800.0, process_std_c=(0.05, 0.01), measurement_std_c=0.05)
    obs.reset(20.0)
    for _ in range(400):
        obs.predict(0.0, 5.0)
        obs.update(20.0)
    obs.predict(0.0, 5.0)  # the prior covariance is what the DARE describes
    h = np.array([[1.0, 0.0]])
    expected = scipy.linalg.solve_discrete_are(obs.ad.T, h.T, obs.q, np.array([[obs.r]]))
    np.testing.assert_allclose(obs.covariance, expected, rtol=1e-6, atol=1e-12)


def test_steady_state_is_a_fixed_point() -> None:
    u_w, t_a = 3000.0, 2.0
    x = steady_state(PAPER_HOUSEHOLD, u_w=u_w, t_a_c=t_a)
    obs = KalmanObserver(PAPER_HOUSEHOLD, 1800.0)
    obs.reset(x[0], t_m_c=x[1])
    for _ in range(20):
        obs.predict(u_w, t_a)
        est = obs.update(x[0])
    np.testing.assert_allclose(est[0], x, atol=1e-9)


def test_batch_equals_one_by_one() -> None:
    data = [_simulate(30, seed=s) for s in (2, 3, 4)]
    batch = KalmanObserver(PARAMS, 1800.0, n_batch=3)
    batch.reset(np.array([d["t_r"][0] for d in data]), t_m_c=np.array([15.0, 18.0, 21.0]))
    singles = [KalmanObserver(PARAMS, 1800.0) for _ in data]
    for single, d, guess in zip(singles, data, (15.0, 18.0, 21.0), strict=True):
        single.reset(d["t_r"][0], t_m_c=guess)
    for k in range(30):
        batch.predict(
            np.array([d["u_phys"][k] for d in data]),
            np.array([d["t_a"][k] for d in data]),
            np.array([d["g"][k] for d in data]),
        )
        batch.update(np.array([d["t_r"][k + 1] for d in data]))
        for single, d in zip(singles, data, strict=True):
            single.predict(d["u_phys"][k], d["t_a"][k], d["g"][k])
            single.update(d["t_r"][k + 1])
    np.testing.assert_allclose(batch.state, np.concatenate([s.state for s in singles]), atol=1e-12)


def test_rejects_zero_measurement_noise() -> None:
    with pytest.raises(ValueError, match="measurement_std_c must be > 0"):
        KalmanObserver(PAPER_HOUSEHOLD, 1800.0, measurement_std_c=0.0)


def test_rc_mpc_observer_takes_the_sensors_stated_noise_and_tracks_better_with_it() -> None:
    from controllers.base import ControlSpec, Observation
    from controllers.estimators import KalmanEstimator

    heater = (ActuatorSpec(upper_w=5000.0),)
    noisy = ControlSpec(actuators=heater, sensor_noise_std_c=0.1)
    assert KalmanEstimator.for_spec(PARAMS, noisy).observer.r == pytest.approx(0.1**2)
    clean = ControlSpec(actuators=heater)  # no stated noise: the observer's default
    assert KalmanEstimator.for_spec(PARAMS, clean).observer.r == pytest.approx(0.05**2)

    data = _simulate(480, seed=3, noise_std_c=0.1)
    true_t_r = _simulate(480, seed=3)["t_r"]  # same inputs and plant, no sensor noise
    errors = {}
    for name, spec in (("stated", noisy), ("default", clean)):
        est = KalmanEstimator.for_spec(PARAMS, spec)
        history: dict[str, list[float]] = {c: [] for c in ("T_r", "T_m", "T_a", "G", "I_g", "u", "u_phys", "time_of_day_h")}
        sq = []
        for k in range(481):
            history["T_r"].append(data["t_r"][k])
            for c, v in (("T_m", np.nan), ("time_of_day_h", 0.5 * k % 24)):
                history[c].append(v)
            row = min(k, 479)
            for c, v in (("T_a", data["t_a"][row]), ("G", data["g"][row]), ("I_g", 0.0)):
                history[c].append(v)
            obs = Observation.from_history(k, {c: np.array(v) for c, v in history.items()}, np.nan)
            if k >= 96:  # after the start-up transient
                sq.append((est.update(obs)[0] - true_t_r[k]) ** 2)
            else:
                est.update(obs)
            if k < 480:
                history["u"].append(data["u_phys"][k])
                history["u_phys"].append(data["u_phys"][k])
        errors[name] = float(np.sqrt(np.mean(sq)))
    # The Kalman filter is optimal for the noise it is told: the stated noise filters better.
    assert errors["stated"] < errors["default"] < 0.1, errors


@pytest.mark.parametrize("scenario_name", ["winter_household", "heat_pump_household"])
def test_fleet_estimator_is_each_buildings_kalman_estimator(scenario_name: str) -> None:
    """One vectorised pass equals B KalmanEstimator.for_spec building by building, restarts
    (a skipped step, no last interval) included, with the heat pump's COP."""
    from controllers.base import LastInterval, Observation
    from controllers.estimators import FleetKalmanEstimator, KalmanEstimator
    from pinn_mpc.simulator import draw_fleet, fleet_matrices
    from scenarios.inputs.scenario_file import get_scenario

    scenario = get_scenario(scenario_name)
    spec = scenario.control_spec()
    fleet = draw_fleet(scenario.sim.params, 4, spread=0.3, rng=np.random.default_rng(2))
    batched = FleetKalmanEstimator(*fleet_matrices(fleet, spec.dt_s), spec)
    singles = [KalmanEstimator.for_spec(p, spec) for p in fleet]
    rng = np.random.default_rng(0)
    ks = np.zeros(4, dtype=int)
    for step in range(30):
        observations = []
        for i in range(4):
            ks[i] += 3 if (step == 12 and i == 1) else 1  # building 1 skips steps once: restart
            last = None if (step == 20 and i == 2) else LastInterval(
                time_of_day_h=0.0, T_a=rng.uniform(-5, 5), G=rng.uniform(0, 300), I_g=100.0,
                u=0.0, u_phys=rng.uniform(0, spec.u_max_w), day_of_week=np.nan,
            )
            observations.append(Observation(int(ks[i]), rng.uniform(18, 22), {}, np.nan, last))
        got = batched.update(observations)
        want = np.array([s.update(o) for s, o in zip(singles, observations, strict=True)])
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    assert np.ptp(got[:, 1]) > 0.05  # the buildings' mass estimates differ: no mix-up passes
