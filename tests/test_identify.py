"""Grey-box RC identification with T_m hidden: recovers the simulator's parameters."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.data import validate_timeseries
from pinn_mpc.errors import InputError
from pinn_mpc.identify import POOR_FIT_RMSE_C, identify_rc, simulate_rc
from pinn_mpc.physics import PAPER_HOUSEHOLD, RCParams, discretise, params_from_summary
from pinn_mpc.simulator import SimConfig, Simulator
from pinn_mpc_cli.cli import main

SOLAR = dataclasses.replace(
    PAPER_HOUSEHOLD, solar_aperture_m2=8.0, solar_to_air_fraction=0.3, gain_to_air_fraction=0.6
)


def _random_policy_frame(params: RCParams, days: int, seed: int) -> pd.DataFrame:
    """Random on/off demand, a synthetic outdoor temperature, sun and evening gains.

    Cooling data get a summer climate and a backup thermostat out of reach.
    """
    rng = np.random.default_rng(seed)
    if params.heating:
        config, t_a_mean = SimConfig(params=params), 3.0
    else:
        config, t_a_mean = SimConfig(params=params, backup_low_c=-50, backup_high_c=80), 30.0
    sim = Simulator(config, seed=seed)
    sim.reset(19.0, 18.0)
    n = days * 48
    hours = np.arange(n) * 0.5
    t_a = t_a_mean + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0) + 0.3 * np.cumsum(rng.normal(0, 0.2, n))
    cloud = rng.uniform(0.2, 1.0, days).repeat(48)
    g = 400.0 * cloud * np.clip(np.sin(2 * np.pi * (hours - 6.0) / 24.0), 0.0, None)
    i_g = 200.0 + 300.0 * ((hours % 24 > 17) & (hours % 24 < 22))
    u = np.where(rng.random(n) < 0.5, 5000.0, 0.0) * rng.uniform(0.3, 1.0, n)
    if not params.heating:
        u = u / 2.0  # a cooling machine of 2.5 kW electric
    rows = []
    for k in range(n):
        t_r, t_m = float(sim.measure()[0]), float(sim.state[0, 1])
        r = sim.step(u[k], t_a[k], g[k], i_g[k])
        rows.append((k * 1800.0, t_r, t_m, u[k], float(r.u_phys_w[0]), t_a[k], g[k], i_g[k]))
    columns = ["time", "T_r", "T_m", "u", "u_phys", "T_a", "G", "I_g"]
    return validate_timeseries(pd.DataFrame(rows, columns=columns))


def _rel(a: float, b: float) -> float:
    return abs(a / b - 1.0)


@pytest.fixture(scope="module")
def solar_frame() -> pd.DataFrame:
    return _random_policy_frame(SOLAR, days=30, seed=0)


def test_simulate_rc_matches_stepping_the_discretised_model() -> None:
    ad, bd = discretise(SOLAR, 1800.0)
    rng = np.random.default_rng(0)
    d = np.stack([rng.uniform(0, 5000, 50), rng.uniform(-5, 10, 50), rng.uniform(0, 300, 50),
                  rng.uniform(0, 500, 50)], axis=1)
    x = np.array([19.0, 17.0])
    expected = [x]
    for row in d:
        x = ad @ x + bd @ row
        expected.append(x)
    np.testing.assert_allclose(simulate_rc(ad, bd, np.array([19.0, 17.0]), d), expected, atol=1e-9)


def test_recovers_parameters_with_solar_and_gains(solar_frame: pd.DataFrame) -> None:
    result = identify_rc(solar_frame)
    p = result.params
    assert _rel(p.r_ra_k_per_w, SOLAR.r_ra_k_per_w) < 0.10
    assert _rel(p.c_r_j_per_k, SOLAR.c_r_j_per_k) < 0.10
    assert _rel(p.r_rm_k_per_w, SOLAR.r_rm_k_per_w) < 0.20
    assert _rel(p.c_m_j_per_k, SOLAR.c_m_j_per_k) < 0.20
    assert _rel(p.solar_aperture_m2, SOLAR.solar_aperture_m2) < 0.10
    assert abs(p.solar_to_air_fraction - SOLAR.solar_to_air_fraction) < 0.1
    assert abs(p.gain_to_air_fraction - SOLAR.gain_to_air_fraction) < 0.15
    assert result.identified_solar and result.identified_gains
    assert result.rmse_c < 0.1 and result.n_rows == len(solar_frame)
    assert abs(result.t_m0_c - solar_frame["T_m"].iloc[0]) < 0.5


def test_ignores_a_t_m_column(solar_frame: pd.DataFrame) -> None:
    short = validate_timeseries(solar_frame.iloc[: 7 * 48])
    garbled = short.copy()
    garbled["T_m"] = 50.0
    garbled.attrs["dt_s"] = short.attrs["dt_s"]
    assert identify_rc(garbled).params == identify_rc(short.drop(columns="T_m")).params


def test_cooling_needs_eta_and_recovers_parameters() -> None:
    cooling = dataclasses.replace(PAPER_HOUSEHOLD, eta=-3.0)
    frame = _random_policy_frame(cooling, days=12, seed=1)
    p = identify_rc(frame, eta=-3.0).params
    assert p.eta == -3.0
    assert _rel(p.r_ra_k_per_w, cooling.r_ra_k_per_w) < 0.10
    assert _rel(p.c_r_j_per_k, cooling.c_r_j_per_k) < 0.10


def test_identify_command_writes_the_rc_schema(
    tmp_path: Path, solar_frame: pd.DataFrame, capsys: pytest.CaptureFixture[str]
) -> None:
    data = tmp_path / "data.csv"
    renamed = solar_frame.iloc[: 10 * 48].rename(columns={"T_r": "T_int", "u_phys": "P_hea"})
    renamed = renamed.drop(columns=["u"])
    renamed.attrs["dt_s"] = 1800.0
    renamed.to_csv(data, index=False)
    out = tmp_path / "rc.json"
    argv = ["identify", "--data", str(data), "--columns", "T_r=T_int,u_phys=P_hea"]
    assert main([*argv, "--out", str(out)]) == 0
    summary = capsys.readouterr().out
    assert str(out) in summary and "R_ra=" in summary
    written = json.loads(out.read_text())
    params = params_from_summary(written)
    assert params.eta == 1.0
    assert _rel(params.r_ra_k_per_w, SOLAR.r_ra_k_per_w) < 0.10
    assert written["fit"]["n_rows"] == 10 * 48 and written["fit"]["rmse_c"] < 0.1
    assert written["source"].startswith("identify:")


def test_rejects_unexcited_data(solar_frame: pd.DataFrame) -> None:
    flat = solar_frame.iloc[:96].copy()
    flat["u_phys"] = 0.0
    flat.attrs["dt_s"] = 1800.0
    with pytest.raises(InputError, match="u_phys is constant"):
        identify_rc(flat)
    with pytest.raises(InputError, match="eta is 0"):
        identify_rc(solar_frame, eta=0.0)
    with pytest.raises(InputError, match="at least 48 rows"):
        identify_rc(validate_timeseries(solar_frame.iloc[:10]))
    two = pd.concat([solar_frame.iloc[:96], solar_frame.iloc[:96]], ignore_index=True)
    two.insert(0, "building", np.repeat([0, 1], 96))
    two.attrs["dt_s"] = 1800.0
    with pytest.raises(InputError, match="data holds 2 buildings"):
        identify_rc(two)


@pytest.mark.slow
def test_winter_household_sixty_days_of_random_policy() -> None:
    from scenarios.inputs.scenario_file import get_scenario
    from scenarios.running.datagen import generate

    scenario = get_scenario("winter_household")
    frame = generate(scenario, days=60, seed=0, policy="random")
    truth = scenario.sim.params
    p = identify_rc(frame, eta=truth.eta).params
    assert _rel(p.r_ra_k_per_w, truth.r_ra_k_per_w) < 0.10
    assert _rel(p.c_r_j_per_k, truth.c_r_j_per_k) < 0.10
    assert _rel(p.r_rm_k_per_w, truth.r_rm_k_per_w) < 0.20
    assert _rel(p.c_m_j_per_k, truth.c_m_j_per_k) < 0.20


def test_power_in_kilowatts_runs_into_the_plausible_edge_and_is_refused() -> None:
    """Power logged in kW needs C_r 1000 x too small (4e3 J/K < 1e4): refused, not reported."""
    frame = _random_policy_frame(PAPER_HOUSEHOLD, days=7, seed=0).drop(columns=["G", "I_g"])
    assert _rel(identify_rc(frame).params.c_r_j_per_k, PAPER_HOUSEHOLD.c_r_j_per_k) < 0.10
    kw = validate_timeseries(frame.assign(u=frame["u"] / 1000, u_phys=frame["u_phys"] / 1000))
    with pytest.raises(InputError, match="edge of the plausible range of C_r_J_per_K"):
        identify_rc(kw)


def test_a_mass_slower_than_the_data_is_kept_at_its_largest_capacity_with_a_note() -> None:
    """A thermal mass whose time constant is years (C_m at the top of its plausible range):
    over a week its temperature stays at its start, the fit wants an even larger capacity
    and stops at the edge; that edge means something physical, so the fit is kept, with a
    note, and predicts the room as well as the truth's own simulation does."""
    slow = dataclasses.replace(PAPER_HOUSEHOLD, c_m_j_per_k=1e12)
    frame = _random_policy_frame(slow, days=7, seed=0)
    result = identify_rc(frame)
    assert result.params.c_m_j_per_k > 1e11
    assert len(result.notes) == 1 and "largest plausible capacity" in result.notes[0]
    assert _rel(result.params.r_ra_k_per_w, slow.r_ra_k_per_w) < 0.10
    assert result.rmse_c < 0.05


def test_a_fit_a_2r2c_cannot_give_is_noted_with_what_to_do(solar_frame: pd.DataFrame) -> None:
    """The office's 1.7 C went by without a word (issue 46). A room whose temperature steps
    by 4 K every 2.5 days with nothing in the data to explain it (another sensor than the
    room's, a heater not in u_phys) is no 2R2C: noted, with what to check and what fits; the
    simulated building's own fit is not."""
    good = identify_rc(solar_frame)
    assert good.rmse_c < 0.1 and good.poor_fit_note() is None
    days = np.arange(len(solar_frame)) / 48.0
    stepped = solar_frame.assign(T_r=solar_frame["T_r"] + 2.0 * np.sign(np.sin(2 * np.pi * days / 5.0) + 1e-9))
    stepped.attrs["dt_s"] = 1800.0
    poor = identify_rc(stepped)
    warning = poor.poor_fit_note()
    assert poor.rmse_c > POOR_FIT_RMSE_C and warning is not None
    note = str(warning)  # the setting by its name; the command line names its flag
    assert "heating power delivered (columns)" in note
    assert "heating power delivered (--columns)" in warning.text({"columns": "--columns"})
    assert f"rmse of {poor.rmse_c:.2f} C, above 1 C" in note
    for advice in ("room temperature and the heating power delivered", "more days",
                   "`pinn-mpc train`", "physics-informed ARX"):
        assert advice in note


def _office_gains_w(times: pd.DatetimeIndex) -> np.ndarray:
    """An office's unmeasured gains [W]: 900 W on workdays 08-18 h, 150 W otherwise."""
    hours = times.hour + times.minute / 60.0
    return np.where((times.day_of_week < 5) & (hours >= 8) & (hours < 18), 900.0, 150.0)


@pytest.fixture(scope="module")
def office_frame() -> pd.DataFrame:
    """28 days from a Monday of a 2R2C with office gains that the data do not hold (no I_g)."""
    rng = np.random.default_rng(3)
    n = 28 * 48
    times = pd.date_range("2024-01-01", periods=n, freq="30min")
    hours = np.arange(n) * 0.5
    t_a = 2.0 + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0) + 0.3 * np.cumsum(rng.normal(0, 0.2, n))
    cloud = rng.uniform(0.2, 1.0, 28).repeat(48)
    g = 400.0 * cloud * np.clip(np.sin(2 * np.pi * (hours - 6.0) / 24.0), 0.0, None)
    u = np.where(rng.random(n) < 0.5, 5000.0, 0.0) * rng.uniform(0.3, 1.0, n)
    gains = _office_gains_w(times)
    ad, bd = discretise(SOLAR, 1800.0)
    x = simulate_rc(ad, bd, np.array([19.0, 18.0]), np.stack([u, t_a, g, gains], axis=1)[:-1])
    frame = pd.DataFrame({"time": times, "T_r": x[:, 0], "u_phys": u, "T_a": t_a, "G": g})
    return validate_timeseries(frame)


def test_identifies_the_unmeasured_gain_schedule(office_frame: pd.DataFrame) -> None:
    from pinn_mpc.physics import gain_schedule_index

    result = identify_rc(office_frame)
    p = result.params
    assert len(p.unmeasured_gains_w) == 24 and result.fit_statistics()["unmeasured_gains"]
    # every block against the true gains (the 08-18 h blocks of a workday are whole blocks)
    hours = np.arange(0, 24, 2.0) + 1.0
    truth = np.concatenate([_office_gains_w(pd.DatetimeIndex(pd.Timestamp("2024-01-01") + pd.to_timedelta(hours, "h"))),
                            _office_gains_w(pd.DatetimeIndex(pd.Timestamp("2024-01-06") + pd.to_timedelta(hours, "h")))])
    index = gain_schedule_index(np.concatenate([hours, hours]), np.repeat([0.0, 5.0], 12))
    np.testing.assert_allclose(np.asarray(p.unmeasured_gains_w)[index], truth, atol=60.0)
    assert _rel(p.r_ra_k_per_w, SOLAR.r_ra_k_per_w) < 0.05
    assert _rel(p.c_r_j_per_k, SOLAR.c_r_j_per_k) < 0.10
    assert _rel(p.solar_aperture_m2, SOLAR.solar_aperture_m2) < 0.10
    assert abs(p.gain_to_air_fraction - SOLAR.gain_to_air_fraction) < 0.1
    assert result.rmse_c < 0.05
    # without the schedule the same data fit far worse and read the office's gains as sun
    plain = identify_rc(office_frame, unmeasured_gains=False)
    assert plain.params.unmeasured_gains_w == () and plain.rmse_c > 5 * result.rmse_c


def test_a_building_without_unmeasured_gains_gets_no_schedule() -> None:
    """The same office without its gains: a schedule would fit noise only, so none is kept,
    and the fit is the one without a schedule, to the bit."""
    n = 14 * 48
    rng = np.random.default_rng(4)
    times = pd.date_range("2024-01-01", periods=n, freq="30min")
    hours = np.arange(n) * 0.5
    t_a = 2.0 + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0)
    u = np.where(rng.random(n) < 0.5, 5000.0, 0.0) * rng.uniform(0.3, 1.0, n)
    ad, bd = discretise(PAPER_HOUSEHOLD, 1800.0)
    x = simulate_rc(ad, bd, np.array([19.0, 18.0]), np.stack([u, t_a, 0 * u, 0 * u], axis=1)[:-1])
    t_r = x[:, 0] + rng.normal(0.0, 0.02, n)  # a sensor's noise, which a schedule could chase
    frame = validate_timeseries(pd.DataFrame({"time": times, "T_r": t_r, "u_phys": u, "T_a": t_a}))
    for days in (3, 14):  # 3 days of noise would buy a schedule by its RMSE alone
        part = validate_timeseries(frame.iloc[: days * 48])
        result = identify_rc(part)
        assert result.params.unmeasured_gains_w == ()
        assert result == identify_rc(part, unmeasured_gains=False)


def test_gain_schedule_needs_days_of_both_kinds_and_no_measured_gains(
    office_frame: pd.DataFrame, solar_frame: pd.DataFrame
) -> None:
    from pinn_mpc.identify import MIN_SCHEDULE_DAYS, gain_schedule_applies

    assert gain_schedule_applies(office_frame)
    short = validate_timeseries(office_frame.iloc[: (MIN_SCHEDULE_DAYS - 1) * 48])
    assert not gain_schedule_applies(short) and identify_rc(short).params.unmeasured_gains_w == ()
    assert gain_schedule_applies(validate_timeseries(office_frame.iloc[: 12 * 48]))  # one weekend
    holidays = office_frame.iloc[: 12 * 48].assign(holiday=1.0)  # every day a holiday: no workday
    assert not gain_schedule_applies(validate_timeseries(holidays))
    assert not gain_schedule_applies(solar_frame)  # measured I_g and no calendar


def test_rc_json_keeps_the_gain_schedule(office_frame: pd.DataFrame, tmp_path: Path) -> None:
    from pinn_mpc.physics import rc_summary, read_rc_json

    params = identify_rc(office_frame).params
    path = tmp_path / "rc.json"
    path.write_text(json.dumps(rc_summary(params, source="test")))
    assert read_rc_json(path)[0] == params
    bad = {**rc_summary(params, source="test"), "unmeasured_gains_W": [1.0, 2.0]}
    path.write_text(json.dumps(bad))
    with pytest.raises(InputError, match="unmeasured_gains_w: expected 24 gains"):
        read_rc_json(path)
