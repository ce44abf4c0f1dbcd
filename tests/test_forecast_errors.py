"""Forecast errors made by the engine: growth with lead, seeding, perfect knowledge, gains."""

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from controllers.base import ControlSpec
from controllers.rc_mpc.references import oracle_mpc
from controllers.thermostat import Thermostat
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.physics import PAPER_HOUSEHOLD
from pinn_mpc.simulator import SimConfig
from scenarios.inputs.exogenous import GainsSchedule
from scenarios.inputs.series import ForecastErrors, lead_error_paths
from scenarios.running.engine import ClosedLoop
from tests.test_engine import _series  # the engine tests' day of exogenous inputs

SPEC = ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0),))
DT_S = 1800.0
LEAD_24H = 48  # intervals of 30 min


def _loop(errors: ForecastErrors, *, forecast_seed=0, n: int = 100, **kwargs) -> ClosedLoop:
    return ClosedLoop(
        SimConfig(),
        _series(n),
        spec=SPEC,
        initial_t_r_c=20.0,
        initial_t_m_c=20.0,
        forecast_errors=errors,
        forecast_seed=forecast_seed,
        **kwargs,
    )


@pytest.mark.parametrize("correlation_h", [3.0, 12.0, 48.0])
def test_lead_errors_follow_the_ar1_variance(correlation_h):
    """Std at lead h is sigma sqrt((1 - phi^2h) / (1 - phi^2(48))): 0 at lead 0, the setting at 24 h."""
    rng = np.random.default_rng(5)
    errors = lead_error_paths(
        rng, n_paths=40_000, n_leads=97, std_at_24h=2.0, correlation_h=correlation_h, dt_s=DT_S
    )
    std = errors.std(axis=0)
    phi = math.exp(-DT_S / (correlation_h * 3600.0))
    theory = 2.0 * np.sqrt((1 - phi ** (2 * np.arange(97))) / (1 - phi ** (2 * LEAD_24H)))
    assert std[0] == 0.0
    # 40 000 paths: the sample std is within 1.5 % of the truth (about 4 standard errors).
    np.testing.assert_allclose(std[1:], theory[1:], rtol=0.015)
    assert std[LEAD_24H] == pytest.approx(2.0, rel=0.015)
    assert (np.diff(theory) > 0).all()  # grows with lead


def test_engine_forecast_error_std_at_24h_matches_the_setting_over_seeds():
    truth = _series(100)
    errors = ForecastErrors(t_a_error_std_c=1.5, g_error_rel_std=0.4)
    t_a_err, g_ratio = [], []
    for seed in range(600):
        forecast = _loop(errors, forecast_seed=seed).forecast()
        assert forecast.T_a[0] == truth.T_a[0] and forecast.G[0] == truth.G[0]  # lead 0: measured
        t_a_err.append(forecast.T_a[LEAD_24H] - truth.T_a[LEAD_24H])
        g_ratio.append(forecast.G[LEAD_24H + 22] / truth.G[LEAD_24H + 22])  # a sunny interval
        assert (forecast.G >= 0).all() and (forecast.G[truth.G == 0] == 0).all()
    # 600 seeds: the std of the sample std is about 3 %; allow 4 standard errors.
    assert np.std(t_a_err) == pytest.approx(1.5, rel=0.12)
    assert abs(np.mean(t_a_err)) < 4 * 1.5 / math.sqrt(600)
    # G = truth * max(0, 1 + e): the ratio's std is that of e (clipping at 0 is 0.6 % here).
    assert np.std(g_ratio) == pytest.approx(0.4 * 1.0, rel=0.12)


def test_wind_forecast_error_is_relative_and_its_own():
    """The wind's error: wind * max(0, 1 + e), e of std 0.5 at 24 h lead, independent of G's."""
    base = _series(100)
    wind = 2.0 + 3.0 * (np.arange(100) % 7)
    truth = dataclasses.replace(base, wind=wind)
    errors = ForecastErrors(g_error_rel_std=0.4, wind_error_rel_std=0.5)
    ratio, g_ratio = [], []
    for seed in range(600):
        loop = ClosedLoop(SimConfig(), truth, spec=SPEC, initial_t_r_c=20.0, initial_t_m_c=20.0,
                          forecast_errors=errors, forecast_seed=seed)
        forecast = loop.forecast()
        assert forecast.wind is not None and forecast.wind[0] == wind[0]  # lead 0: measured
        assert (forecast.wind >= 0).all()
        ratio.append(forecast.wind[LEAD_24H] / wind[LEAD_24H])
        g_ratio.append(forecast.G[LEAD_24H + 22] / truth.G[LEAD_24H + 22])
    # Clipping at 0 (e < -1, a 2-sigma event at 0.5) narrows the ratio's spread a little.
    assert np.std(ratio) == pytest.approx(0.5, rel=0.15)
    assert abs(np.corrcoef(ratio, g_ratio)[0, 1]) < 0.15  # 600 draws: |r| < 3.7 standard errors
    # Without wind in the run the setting changes nothing, and no other series.
    plain = _loop(ForecastErrors(wind_error_rel_std=0.5)).forecast()
    assert plain.wind is None
    np.testing.assert_array_equal(plain.T_a, base.T_a)
    np.testing.assert_array_equal(plain.G, base.G)


def test_forecast_is_deterministic_per_seed_and_row():
    errors = ForecastErrors(t_a_error_std_c=2.0)
    a, b, c = _loop(errors, forecast_seed=3), _loop(errors, forecast_seed=3), _loop(errors, forecast_seed=4)
    first = a.forecast()
    np.testing.assert_array_equal(first.T_a, a.forecast().T_a)  # asking twice changes nothing
    np.testing.assert_array_equal(first.T_a, b.forecast().T_a)
    assert not np.array_equal(first.T_a, c.forecast().T_a)
    a.step(0.0)
    b.step(5000.0)  # another controller's action: the next forecast is the same
    np.testing.assert_array_equal(a.forecast().T_a, b.forecast().T_a)


def test_perfect_knowledge_controllers_see_the_truth():
    truth = _series(100)
    errors = ForecastErrors(t_a_error_std_c=2.0, g_error_rel_std=0.5, gains_known=False)
    loop = _loop(errors, expected_gains_w=np.full(100, 250.0))
    oracle = oracle_mpc(PAPER_HOUSEHOLD, SPEC)
    oracle.reset(0)
    seen = loop.advance(oracle)
    for name in ("T_a", "G", "I_g"):
        np.testing.assert_array_equal(getattr(seen.forecast, name), getattr(truth, name))
    np.testing.assert_array_equal(seen.observation.history["I_g"], truth.I_g[:1])
    other = loop.advance(Thermostat(SPEC))
    assert not np.array_equal(other.forecast.T_a, truth.T_a[1:])


def test_unknown_gains_are_the_schedules_expectation_in_forecast_and_past():
    schedule = GainsSchedule(base_w=100.0, scheduled_w=400.0, periods_h=((17.0, 23.0),),
                             event_w=1000.0, event_probability=0.25)
    times = pd.date_range("2022-02-01", periods=100, freq="30min")
    expected = schedule.expected(times)
    hours = times.hour + times.minute / 60.0
    inside = (hours >= 17) & (hours < 23)
    np.testing.assert_allclose(expected, np.where(inside, 100.0 + 400.0 + 0.25 * 1000.0, 100.0))
    # The mean of many draws is the expectation.
    draws = np.mean([schedule.sample(times, rng=np.random.default_rng(s)) for s in range(4000)], axis=0)
    np.testing.assert_allclose(draws, expected, atol=4 * 1000.0 * math.sqrt(0.25 * 0.75 / 4000))

    loop = _loop(ForecastErrors(gains_known=False), expected_gains_w=expected)
    decision = loop.advance(Thermostat(SPEC))
    np.testing.assert_array_equal(decision.forecast.I_g, expected)
    np.testing.assert_array_equal(decision.observation.history["I_g"], expected[:1])
    with pytest.raises(InternalError, match="expected_gains_w"):
        _loop(ForecastErrors(gains_known=False))


def test_the_gains_a_controller_observed_are_the_expected_ones_where_it_is_not_given_the_plants():
    """What a refit learns from holds the gains as the controller saw them: the expectation
    where the gains are unknown, though the plant had others (its record keeps those)."""
    truth = _series(100)
    expected = np.full(100, 250.0)
    loop = _loop(ForecastErrors(gains_known=False), expected_gains_w=expected)
    for _ in range(3):
        seen = loop.advance(Thermostat(SPEC))
    np.testing.assert_array_equal(loop.observed_gains_w(), expected[:3])
    np.testing.assert_array_equal(loop.observed_gains_w()[:2], seen.observation.history["I_g"][:2])
    np.testing.assert_array_equal(loop.record().i_g_w, truth.I_g[:3])
    assert not np.array_equal(loop.record().i_g_w, expected[:3])
    known = _loop(ForecastErrors())
    known.step(0.0)
    np.testing.assert_array_equal(known.observed_gains_w(), truth.I_g[:1])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"t_a_error_std_c": -1.0}, "t_a_error_std_c must be a number >= 0"),
        ({"g_error_rel_std": float("nan")}, "g_error_rel_std"),
        ({"wind_error_rel_std": -0.1}, "wind_error_rel_std must be a number >= 0"),
        ({"error_correlation_h": 0.0}, "error_correlation_h must be > 0"),
        ({"gains_known": 1}, "gains_known must be true or false"),
    ],
)
def test_forecast_errors_are_validated(kwargs, match):
    """A Python caller's misuse is a ValueError (a scenario file's [forecast] table is the
    file's InputError, naming the key: the reader converts it)."""
    with pytest.raises(ValueError, match=match) as caught:
        ForecastErrors(**kwargs)
    assert not isinstance(caught.value, InputError)
