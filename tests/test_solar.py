"""The facades' irradiance (issue 17): pvlib's plane-of-array irradiance against the analytic
value, its interval means, its way through the data, the forecasts and the ARX; the RC
scenarios without it."""

import math

import numpy as np
import pandas as pd
import pytest

from controllers.arx_mpc import ARXQPMPC
from controllers.base import ControlSpec, Forecast, Observation
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.models.arx import MEASURED_INPUTS, fit_arx, fit_physics_informed_arx
from pinn_mpc.simulator import SimConfig
from pinn_mpc.solar import FACADE_COLUMNS, facade_irradiance, interval_means
from scenarios.inputs.registry import EXOGENOUS_COLUMNS
from scenarios.inputs.scenario_file import get_scenario
from scenarios.inputs.series import ExogenousSeries, ForecastErrors
from scenarios.running.engine import ClosedLoop

HOURS = 8760
DNI, DHI, GHI, ALBEDO = 800.0, 100.0, 500.0, 0.2
#: A site on its time zone's meridian (15 deg per hour): clock time is local mean solar time.
SITE = {"latitude_deg": 40.0, "longitude_deg": -75.0, "utc_offset_h": -5.0, "altitude_m": 0.0}


def _constant_sky(**overrides):
    sky = {
        "ghi_w_per_m2": np.full(HOURS, GHI),
        "dni_w_per_m2": np.full(HOURS, DNI),
        "dhi_w_per_m2": np.full(HOURS, DHI),
        "albedo": ALBEDO,
        **SITE,
    }
    return {**sky, **overrides}


def _seconds(month: int, day: int, hour: float) -> float:
    return ((pd.Timestamp(2021, month, day) - pd.Timestamp(2021, 1, 1)).total_seconds()) + hour * 3600.0


def test_south_facade_at_solar_noon_is_the_analytic_value():
    """At the March equinox of 2021 (20 March, 09:37 UTC: declination 0) the sun at solar noon
    stands due south at 90 - 40 = 50 deg over a site at 40 deg N, so a vertical south surface
    gets DNI cos(50 deg) of beam, half the diffuse sky and half the ground's reflection; a
    north surface only the last two. The site lies on its zone's meridian (37.5 deg E, UTC +
    2.5 h), where solar noon is noon minus the equation of time (-7.5 min that day): 09:37.5
    UTC."""
    noon = _seconds(3, 20, 12.0 + 7.5 / 60.0)
    site = {"latitude_deg": 40.0, "longitude_deg": 37.5, "utc_offset_h": 2.5}
    out = facade_irradiance(np.array([noon]), **_constant_sky(**site))
    elevation = math.radians(50.0)
    sky_and_ground = DHI / 2.0 + ALBEDO * GHI / 2.0
    assert out["G_south"][0] == pytest.approx(DNI * math.cos(elevation) + sky_and_ground, rel=0.002)
    assert out["G_north"][0] == pytest.approx(sky_and_ground, rel=1e-6)
    # East and west see the beam only a little, at grazing incidence, about equally.
    assert out["G_east"][0] < sky_and_ground + 0.05 * DNI
    assert out["G_west"][0] < sky_and_ground + 0.05 * DNI


def test_the_sun_moves_from_the_east_facade_to_the_west_and_sets():
    times = np.array([_seconds(6, 21, h) for h in (8.0, 16.0, 23.0)])
    out = facade_irradiance(times, **_constant_sky())
    assert out["G_east"][0] > out["G_west"][0] + 300.0  # the morning sun
    assert out["G_west"][1] > out["G_east"][1] + 300.0  # the afternoon sun
    # At night the weather file says no irradiance: nothing on any facade.
    dark = facade_irradiance(times, **_constant_sky(
        ghi_w_per_m2=np.zeros(HOURS), dni_w_per_m2=np.zeros(HOURS), dhi_w_per_m2=np.zeros(HOURS)
    ))
    assert all(np.all(v == 0.0) for v in dark.values())


def test_hourly_values_are_interpolated_between_hour_middles_and_averaged_per_interval():
    """The diffuse sky is interpolated between the hours' middles (as EnergyPlus does): on a
    night sky (DNI 0) a north facade gets DHI / 2; half an hour from the middle of an hour of
    100 W/m2 and one of 300 W/m2 it is 200 / 2. Interval means are means of substeps."""
    dhi = np.zeros(HOURS)
    dhi[12], dhi[13] = 100.0, 300.0  # hours ending 13:00 and 14:00 on 1 January
    sky = _constant_sky(
        ghi_w_per_m2=np.zeros(HOURS), dni_w_per_m2=np.zeros(HOURS), dhi_w_per_m2=dhi
    )
    at = facade_irradiance(np.array([12.5, 13.0, 13.5]) * 3600.0, **sky)["G_north"]
    assert at == pytest.approx([50.0, 100.0, 150.0])
    means = interval_means(12.5 * 3600.0, 2, 1800.0, **sky)["G_north"]
    # 12:30-13:00 and 13:00-13:30, in 10-min substeps: the means of the ramp from 50 to 150
    assert means == pytest.approx([75.0, 125.0])


def test_bad_site_or_sky_is_refused():
    with pytest.raises(InputError, match="not on Earth"):
        facade_irradiance(np.zeros(1), **_constant_sky(latitude_deg=100.0))
    with pytest.raises(InputError, match="missing values"):
        facade_irradiance(np.zeros(1), **_constant_sky(dni_w_per_m2=np.full(HOURS, np.nan)))
    with pytest.raises(ValueError, match="one length"):
        facade_irradiance(np.zeros(1), **_constant_sky(dni_w_per_m2=np.zeros(10)))


def test_tmy3_weather_gives_facades_of_its_file_but_rc_scenarios_keep_their_columns():
    """The 2R2C scenarios' frames are what they were (no facade columns); the facades of a
    TMY3 weather are interval means of its own site and sky, in daylight only."""
    scenario = get_scenario("winter_household")
    frame = scenario.exogenous(days=3, seed=0, part="test")
    assert list(frame.columns) == list(EXOGENOUS_COLUMNS)
    series = ExogenousSeries.from_frame(frame)
    assert not series.has_facades and series.forecast(0).G_south is None
    facades = scenario.weather.facades(pd.DatetimeIndex(frame["time"]), dt_s=1800.0)
    assert set(facades) == set(FACADE_COLUMNS)
    # Dark: no sun in the interval's hour nor in the hours either side (interpolated from).
    dark = np.convolve(frame["G"].to_numpy(), np.ones(5), mode="same") == 0.0
    assert dark.sum() > 48
    for values in facades.values():
        assert len(values) == len(frame) and np.all(values >= 0.0)
        assert np.all(values[dark] == 0.0) and values.max() > 50.0
    # North Carolina in February: the sun is in the south; the north facade sees sky only.
    assert facades["G_south"].sum() > 1.5 * facades["G_north"].sum()


def _facade_series(n: int, *, seed: int = 0) -> ExogenousSeries:
    rng = np.random.default_rng(seed)
    hours = (np.arange(n) * 0.5) % 24.0
    day = np.clip(np.sin(np.pi * (hours - 7.0) / 10.0), 0.0, None)
    times = pd.date_range("2022-02-01", periods=n, freq="30min").to_numpy()
    return ExogenousSeries(
        time_of_day_h=hours,
        T_a=2.0 + 3.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0),
        G=300.0 * day,
        I_g=np.zeros(n),
        price=np.where(hours < 6, 0.12, 0.25),
        T_min=np.full(n, 20.0),
        T_max=np.full(n, 23.0),
        times=times,
        **{name: (500.0 - 100.0 * i) * day * rng.uniform(0.5, 1.0, n)
           for i, name in enumerate(FACADE_COLUMNS)},
    )


def test_forecasts_and_observations_carry_the_facades_with_the_error_of_g():
    spec = ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0),))
    series = _facade_series(150)
    loop = ClosedLoop(
        SimConfig(), series, spec=spec, initial_t_r_c=20.0, initial_t_m_c=20.0,
        forecast_errors=ForecastErrors(g_error_rel_std=0.3), forecast_seed=4,
    )
    for _ in range(3):
        loop.step(1000.0)
    obs, noisy, perfect = loop.observation(), loop.forecast(), loop.forecast(perfect=True)
    for name in FACADE_COLUMNS:
        assert np.array_equal(obs.history[name], getattr(series, name)[:4])
        assert getattr(obs.last, name) == getattr(series, name)[2]
        assert np.array_equal(getattr(perfect, name), getattr(series, name)[3:])
    # One relative error of the sky scales G and every facade alike.
    day = perfect.G > 0
    factor = noisy.G[day] / perfect.G[day]
    assert np.std(factor) > 0.05
    for name in FACADE_COLUMNS:
        assert getattr(noisy, name)[day] == pytest.approx(getattr(perfect, name)[day] * factor)
    with pytest.raises(InternalError, match="give all of"):
        ExogenousSeries(**{**_fields(series), "G_north": None})
    without = Forecast(*perfect[:8])
    with pytest.raises(InputError, match="no facade irradiance"):
        without.exogenous(("T_a", "G_south"), 4)


def _fields(series: ExogenousSeries) -> dict:
    import dataclasses

    return {f.name: getattr(series, f.name) for f in dataclasses.fields(series)}


def _sunlit_room(days: int, seed: int, *, through_facades: bool) -> pd.DataFrame:
    """A first-order room heated by its power and by the sun through its windows, which see
    the south facade's irradiance (``through_facades``) or the horizontal one's; the data
    carry both, and noise besides."""
    rng = np.random.default_rng(seed)
    n = days * 48
    series = _facade_series(n, seed=seed)
    sun = series.G_south if through_facades else series.G
    assert sun is not None and series.times is not None
    u = rng.uniform(0, 3000, n)
    t_r = np.empty(n)
    t_r[0] = 20.0
    for k in range(n - 1):
        t_r[k + 1] = (t_r[k] - 0.05 * (t_r[k] - series.T_a[k]) + 0.001 * u[k] + 0.004 * sun[k]
                      + rng.normal(0, 0.02))
    df = pd.DataFrame({
        "time": pd.DatetimeIndex(series.times), "T_r": t_r, "u": u, "u_phys": u,
        "T_a": series.T_a, "G": series.G, **{c: getattr(series, c) for c in FACADE_COLUMNS},
    })
    df.attrs["dt_s"] = 1800.0
    return df


@pytest.mark.parametrize("through_facades", [True, False])
def test_physics_informed_arx_takes_the_facades_only_where_they_predict_better(through_facades):
    """Chosen on a held-out last quarter of the training data: taken where the sun reaches
    the room through the south facade, left out where it is the horizontal irradiance (and
    the facades' four more inputs only add variance). The plain ARX keeps the measured ones."""
    train = _sunlit_room(28, seed=0, through_facades=through_facades)
    model = fit_physics_informed_arx(train, lags=2)
    assert set(FACADE_COLUMNS) <= set(model.columns) if through_facades else (
        not set(FACADE_COLUMNS) & set(model.columns)
    )
    assert fit_arx(train).columns[3:] == tuple(c for c in MEASURED_INPUTS if c in train)
    if through_facades:  # and the facades make the prediction
        test = _sunlit_room(7, seed=1, through_facades=True)
        starts = np.arange(1, len(test) - 24)
        truth = test["T_r"].to_numpy()[starts + 24]
        without = fit_physics_informed_arx(train.drop(columns=list(FACADE_COLUMNS)), lags=2)
        err = [np.mean(np.abs(m.predict_t_r(test, 24, starts) - truth)) for m in (model, without)]
        assert err[0] < 0.5 * err[1]


def test_qp_mpc_over_an_arx_with_facades_plans_on_their_forecast():
    """The ARX's history and forecast of the facades come from the loop: it plans every step,
    and its prediction changes with the facades' forecast."""
    train = _sunlit_room(21, seed=0, through_facades=True)
    model = fit_physics_informed_arx(train, lags=2)
    spec = ControlSpec(actuators=(ActuatorSpec(upper_w=3000.0),), horizon_steps=12)
    controller = ARXQPMPC(model, spec)
    loop = ClosedLoop(SimConfig(), _facade_series(60), spec=spec, initial_t_r_c=20.0, initial_t_m_c=20.0)
    for k in range(20):
        decision = loop.advance(controller)
        assert decision.error is None and decision.fallback == (k < model.lags - 1)
    obs, forecast = loop.observation(), loop.forecast()
    free, _ = controller.prediction(obs, forecast)
    brighter = forecast._replace(G_south=forecast.G_south + 200.0)
    free_bright, _ = controller.prediction(obs, brighter)
    assert np.all(free_bright[1:] > free[1:] + 0.1)
    assert isinstance(obs, Observation)
