"""The BOPTEST plant and its web-API client against a real BOPTEST server.

The session's server is :func:`tests.boptest_server.boptest_server`. A select costs seconds and
a test period's warm-up more: the tests share selected tests where they can.
"""

from __future__ import annotations

import argparse
import math
from contextlib import closing
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from controllers.base import ControlSpec, Forecast, Observation, SolveStats
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InputError
from pinn_mpc.simulator import SimConfig
from scenarios.inputs.series import ExogenousSeries
from scenarios.plants.boptest import (
    BoptestPlant,
    BoptestRun,
    BoptestSettings,
    SignalScaling,
    boptest_settings_from_dict,
    read_boptest_file,
)
from scenarios.plants.boptest_client import (
    BoptestClient,
    BoptestError,
    BoptestTest,
)
from scenarios.running.closed_loop import ClosedLoopResult
from scenarios.running.engine import ClosedLoop
from scenarios.running.kpis import compute_kpis
from tests.boptest_server import Server, free_port

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "plants" / "boptest_hydronic_heat_pump.toml"
TESTCASE = "bestest_hydronic_heat_pump"


@pytest.fixture(scope="session")
def server(boptest_server: Server) -> Server:
    return boptest_server


@pytest.fixture(scope="session")
def settings(server: Server) -> BoptestSettings:
    points = read_boptest_file(str(SCENARIO)).points
    return BoptestSettings(points=points, url=server.url)


class Constant:
    """A controller that asks for the same electrical power every interval."""

    name = "constant"
    knows_true_state = False
    model = None
    trust_report = None

    def __init__(self, u_w: float) -> None:
        self.u_w = u_w

    @property
    def last_plan(self) -> np.ndarray | None:
        return None

    @property
    def last_stats(self) -> SolveStats:
        return SolveStats(time_s=0.0, status="constant", iterations=0, fallback=False)

    def reset(self, seed: int | None = None) -> None:
        """Nothing to reset."""

    def act(self, obs: Observation, forecast: Forecast) -> float:
        return self.u_w


# --- without a server --------------------------------------------------------------------------


def test_server_url_comes_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("BOPTEST_URL", raising=False)
    assert BoptestClient().url == "http://127.0.0.1:8000"
    monkeypatch.setenv("BOPTEST_URL", "http://example.invalid:5000/")
    assert BoptestClient().url == "http://example.invalid:5000"
    assert BoptestClient("http://10.0.0.1:80").url == "http://10.0.0.1:80"
    with pytest.raises(InputError, match="not an http"):
        BoptestClient("localhost:8000")


def test_signal_scaling_follows_the_curve_and_switches_off_below_half_the_lowest_power() -> None:
    scaling = SignalScaling(signal=(0.1, 1.0), power_w=(1000.0, 3000.0))
    assert scaling.to_signal(2000.0) == pytest.approx(0.55)
    assert scaling.to_signal(9000.0) == 1.0  # clipped to the last knot
    assert scaling.to_signal(600.0) == 0.1 and scaling.to_signal(400.0) == 0.0
    for u in (1000.0, 1700.0, 3000.0):
        assert scaling.to_power_w(scaling.to_signal(u)) == pytest.approx(u)
    assert scaling.max_power_w == 3000.0 and scaling.to_power_w(0.0) == 0.0
    with pytest.raises(InputError, match="increase strictly"):
        SignalScaling(signal=(0.5, 0.2), power_w=(1.0, 2.0))
    with pytest.raises(InputError, match="same number"):
        SignalScaling(signal=(0.1, 1.0), power_w=(1.0,))


def test_scenario_file_is_checked_key_by_key(tmp_path: Path) -> None:
    import tomllib

    data = tomllib.loads(SCENARIO.read_text())["boptest"]
    settings = boptest_settings_from_dict(data)
    assert settings.points.consumed_power == ("reaPHeaPum_y", "reaPFan_y", "reaPPumEmi_y")
    assert settings.points.scaling.max_power_w == 3715.0
    bad = {**data, "points": {**data["points"], "room_temp": "x"}}
    with pytest.raises(InputError, match=r"boptest.points: unknown key\(s\) \['room_temp'\]"):
        boptest_settings_from_dict(bad)
    no_price = {**data, "prices": {"constant": "PriceElectricPowerConstant"}}
    with pytest.raises(InputError, match="a forecast point for each price scenario"):
        boptest_settings_from_dict(no_price)
    broken = tmp_path / "broken.toml"
    broken.write_text("[boptest\n")
    with pytest.raises(InputError, match="not valid TOML"):
        read_boptest_file(str(broken))


@pytest.mark.parametrize("day", ["400", "10", "359", "23.5", "-1"])
def test_test_periods_are_checked_where_the_scenario_file_is_read(
    day: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A period centred on ``day`` and its warm-up must lie in the year (14 <= day <= 358,
    whole days): one line naming the key and the value, when the file is read (before a day
    of data could be placed by it)."""
    from pinn_mpc_cli.cli import main

    mine = tmp_path / "mine.toml"
    mine.write_text(SCENARIO.read_text().replace("peak_heat_day = 23", f"peak_heat_day = {day}"))
    key = f"boptest.test_periods.peak_heat_day = {day}"
    with pytest.raises(InputError, match=f"{mine}: {key}: .*a whole day from 14 to 358"):
        read_boptest_file(str(mine))
    out = tmp_path / "d.csv"
    code = main(["simulate", "--scenario", str(mine), "--days", "3", "--first-day", "16", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and key in err
    assert not out.exists()
    for edge in ("14", "358"):  # the first and last day whose period and warm-up fit
        mine.write_text(SCENARIO.read_text().replace("peak_heat_day = 23", f"peak_heat_day = {edge}"))
        assert read_boptest_file(str(mine)).points.period_days("peak_heat_day")[0] == float(edge) - 7


def test_runs_are_checked_and_data_days_stay_off_the_test_periods() -> None:
    points = read_boptest_file(str(SCENARIO)).points
    with pytest.raises(ValueError, match="price scenario 'spot'"):
        BoptestRun(price_scenario="spot")
    with pytest.raises(ValueError, match="not both"):
        BoptestRun(time_period="peak_heat_day", first_day=40)
    with pytest.raises(ValueError, match="a BOPTEST test period has 14 days, 15 were asked for peak_heat_day; give at most 14"):
        BoptestRun(days=15)
    with pytest.raises(InputError, match="days 360-370 of the year run past its end"):
        BoptestRun(time_period=None, first_day=360.0, days=10.0)
    assert points.period_days("peak_heat_day") == (16.0, 30.0)
    assert points.period_days("typical_heat_day") == (108.0, 122.0)
    points.check_disjoint(30.0, 71.0)  # days 30-101: between the periods and their warm-ups
    points.check_disjoint(0.0, 9.0)
    with pytest.raises(InputError, match="overlap BOPTEST's test period peak_heat_day"):
        points.check_disjoint(25.0, 10.0)
    with pytest.raises(InputError, match="typical_heat_day with its warm-up \\(days 101-122\\)"):
        points.check_disjoint(95.0, 7.0)
    with pytest.raises(InputError, match="test period 'cold_day' is not one of"):
        points.period_days("cold_day")


def test_training_days_nearest_a_test_period() -> None:
    """Right before the period's warm-up where the data and their own 7-day warm-up fit after
    1 January and off every period; else right after the period's end."""
    points = read_boptest_file(str(SCENARIO)).points
    # typical_heat_day: warm-up days 101-108, test days 108-122
    assert points.data_first_day("typical_heat_day", 14) == 87.0
    assert points.data_first_day("typical_heat_day", 28) == 73.0
    # 80 days before day 101 would start before the data's own warm-up: after the period
    assert points.data_first_day("typical_heat_day", 80) == 122.0
    # peak_heat_day: warm-up from day 9, so nothing fits before it
    assert points.data_first_day("peak_heat_day", 14) == 30.0
    assert points.data_first_day("peak_heat_day", 28) == 30.0
    # 72 days after peak_heat_day would reach typical_heat_day's warm-up
    with pytest.raises(InputError, match="no 72 days of training data fit beside test period peak_heat_day"):
        points.data_first_day("peak_heat_day", 72)


# --- the client against the server's routes ----------------------------------------------------


def test_the_test_case_through_the_client_on_the_server(settings: BoptestSettings) -> None:
    points = settings.points
    client = BoptestClient(settings.url)
    assert client.version()
    assert TESTCASE in client.testcases()
    with client.select(TESTCASE) as test:
        assert test.name() == TESTCASE
        inputs, measurements = test.inputs(), test.measurements()
        assert {points.actuator, points.activate} <= inputs.keys()
        assert inputs[points.actuator]["Minimum"] == 0 and inputs[points.actuator]["Maximum"] == 1
        assert {points.room_temperature, *points.consumed_power} <= measurements.keys()
        assert measurements[points.room_temperature]["Unit"] == "K"
        assert {points.comfort_lower, *points.prices.values()} <= test.forecast_points().keys()
        # the scenario: BOPTEST starts the test period 7 days before its day, after a warm-up
        start = test.set_scenario(time_period="peak_heat_day", electricity_price="dynamic")
        assert start["time_period"]["time"] == (23 - 7) * 86400.0
        assert start["electricity_price"] == "dynamic"
        assert test.scenario()["time_period"] == "peak_heat_day"
        test.set_step(900.0)
        assert test.step_s() == 900.0
        fc = test.forecast(["TDryBul", "LowerSetp[1]"], horizon_s=3600.0, interval_s=900.0)
        assert list(fc["time"]) == [16 * 86400.0 + i * 900.0 for i in range(5)]
        assert np.all((fc["TDryBul"] > 243.15) & (fc["TDryBul"] < 303.15))
        state = test.advance({points.actuator: 0.5, points.activate: 1})
        assert state["time"] == 16 * 86400.0 + 900.0
        assert state[points.actuator] == 0.5  # the input as applied
        res = test.results([points.room_temperature], start_time_s=16 * 86400.0, final_time_s=state["time"])
        assert res[points.room_temperature][-1] == pytest.approx(state[points.room_temperature])
        kpi = test.kpi()
        assert {"tdis_tot", "ener_tot", "cost_tot", "emis_tot", "time_rat"} <= kpi.keys()
        assert kpi["ener_tot"] is not None and kpi["ener_tot"] > 0
        # an error reply carries BOPTEST's message
        with pytest.raises(BoptestError, match=r"status 400\): Unexpected input variable: oveNope_u"):
            test.advance({"oveNope_u": 1.0})
        with pytest.raises(BoptestError, match=r"Invalid point name\(s\) \['Nope'\]"):
            test.forecast(["Nope"], horizon_s=3600.0, interval_s=900.0)
    # the client's own part (routes, payloads, errors, a stopped or ended test):
    # tests/test_boptest_client.py against a stand-in


def test_plant_refuses_points_the_test_case_lacks_and_stops_its_test(
    settings: BoptestSettings, monkeypatch: pytest.MonkeyPatch
) -> None:
    import dataclasses

    selected: list[BoptestTest] = []
    select = BoptestClient.select

    def recording_select(self: BoptestClient, testcase: str) -> BoptestTest:
        selected.append(select(self, testcase))
        return selected[-1]

    monkeypatch.setattr(BoptestClient, "select", recording_select)
    points = dataclasses.replace(settings.points, room_temperature="reaTRoom_y")
    with pytest.raises(InputError, match="has no measurement reaTRoom_y"):
        BoptestPlant(dataclasses.replace(settings, points=points), BoptestRun(days=1))
    assert len(selected) == 1 and selected[0].stopped
    status = BoptestClient(settings.url).call("GET", f"status/{selected[0].testid}")
    assert status == "Stopped"


# --- the plant in the closed loop --------------------------------------------------------------


@pytest.mark.slow
def test_a_day_at_a_constant_power_through_the_loop_matches_boptest(settings: BoptestSettings) -> None:
    run = BoptestRun(time_period="peak_heat_day", days=1.0, price_scenario="dynamic", dt_s=1800.0)
    u_w = 2500.0
    with BoptestPlant(settings, run) as plant:
        frame = plant.exogenous_frame()
        assert len(frame) == 48 and str(frame["time"].iloc[0]) == "2018-01-17 00:00:00"
        assert frame["T_min"].min() == pytest.approx(15.0) and frame["T_min"].max() == pytest.approx(21.0)
        u_max = settings.points.scaling.max_power_w
        config = SimConfig(u_max_w=u_max, dt_s=run.dt_s)
        spec = ControlSpec(actuators=config.actuators, dt_s=run.dt_s)
        t_r0 = float(plant.measure()[0])
        with ClosedLoop(
            config, ExogenousSeries.from_frame(frame), spec=spec, initial_t_r_c=t_r0,
            initial_t_m_c=t_r0, plant=plant,
        ) as loop:
            for _ in range(run.n_intervals):
                loop.advance(Constant(u_w))
            record = loop.record()
            kpis = plant.kpis()
            history = plant.history()
            # the plant's room temperature is the server's own measurement
            end = plant.test.results(
                [settings.points.room_temperature], start_time_s=16 * 86400.0, final_time_s=17 * 86400.0
            )
            assert loop.measure() == pytest.approx(end[settings.points.room_temperature][-1] - 273.15, abs=1e-9)
            assert record.t_r_c[0] == pytest.approx(t_r0)
        assert plant.test.stopped  # closing the loop stopped the test
    # physically plausible: a mild January night-and-day in a heated house
    assert np.all((record.t_r_sub_c > 15.0) & (record.t_r_sub_c < 30.0))
    assert np.all(np.abs(np.diff(record.t_r_sub_c.ravel())) < 0.2)  # per 30 s
    assert np.all((record.t_a_c > -15.0) & (record.t_a_c < 15.0))
    # the curve maps watts to the signal: the heat pump draws the power asked within 3 %
    assert np.all(np.abs(record.u_phys_w / u_w - 1.0) < 0.03)
    cop = history["heat_w"] / history["u_phys"]
    assert np.all((cop > 1.5) & (cop < 5.0))  # heat delivered per electrical watt
    # the package's KPIs of the loop are BOPTEST's (per m2 of floor)
    area = settings.points.floor_area_m2
    ours = compute_kpis(
        u_phys_w=record.u_phys_w, price_eur_per_kwh=frame["price"].to_numpy(),
        t_r_sub_c=record.t_r_sub_c, t_min_c=frame["T_min"].to_numpy(), t_max_c=frame["T_max"].to_numpy(),
        decision_s=record.decision_s, overridden=record.overridden, fallback=record.fallback,
        dt_s=run.dt_s, comfort_weight_eur_per_kh=1.0,
    )
    assert kpis["ener_tot"] is not None and kpis["cost_tot"] is not None and kpis["tdis_tot"] is not None
    assert ours["energy_kwh"] / area == pytest.approx(kpis["ener_tot"], rel=1e-4)
    assert ours["cost_eur"] / area == pytest.approx(kpis["cost_tot"], rel=1e-3)
    assert ours["discomfort_kh"] == pytest.approx(kpis["tdis_tot"], rel=0.02, abs=0.01)


@pytest.mark.slow
def test_baseline_kpis_of_a_short_run(settings: BoptestSettings) -> None:
    run = BoptestRun(time_period="peak_heat_day", days=1.0, price_scenario="highly_dynamic", dt_s=3600.0)
    with BoptestPlant(settings, run, baseline=True) as plant:
        frame = plant.exogenous_frame()
        # half the intervals as the loop steps a baseline plant (the demand ignored), half directly
        steps = [plant.step(0.0, k) if k % 2 else plant.step_baseline(k) for k in range(run.n_intervals)]
        kpis = plant.kpis()
        history = plant.history()
    # no input overwritten: the test case's own controller modulated the heat pump
    assert history["signal_mean"].max() > 0.05 and history["signal_mean"].std() > 0.01
    assert not any(bool(s.overridden[0]) for s in steps)
    u_phys = np.array([s.u_phys_w[0] for s in steps])
    sub = np.vstack([s.t_r_sub_c[:, :, 0] for s in steps])
    area = settings.points.floor_area_m2
    energy = float(np.sum(u_phys) * run.dt_s / 3.6e6)
    assert energy / area == pytest.approx(kpis["ener_tot"], rel=1e-4)
    price = frame["price"].to_numpy()
    assert float(np.sum(price * u_phys) * run.dt_s / 3.6e6) / area == pytest.approx(kpis["cost_tot"], rel=1e-3)
    low = np.maximum(frame["T_min"].to_numpy()[:, None] - sub, 0.0)
    high = np.maximum(sub - frame["T_max"].to_numpy()[:, None], 0.0)
    tdis = float(np.sum(low + high) * run.dt_s / sub.shape[1] / 3600.0)
    assert tdis == pytest.approx(kpis["tdis_tot"], rel=0.02, abs=0.01)
    assert kpis["time_rat"] is not None and math.isfinite(kpis["time_rat"])


def test_builtin_scenario_by_name() -> None:
    from scenarios.plants.boptest import BUILTIN_BOPTEST, builtin_boptest

    assert builtin_boptest("boptest_hydronic_heat_pump").points.testcase == TESTCASE
    with pytest.raises(ValueError, match="no built-in BOPTEST scenario 'bestest'"):
        builtin_boptest("bestest")
    assert all(path.is_file() for path in BUILTIN_BOPTEST.values())


@pytest.mark.slow
def test_training_data_from_the_emulator_stays_off_the_test_periods(settings: BoptestSettings) -> None:
    from scenarios.plants.boptest import record_data

    with pytest.raises(InputError, match="overlap BOPTEST's test period peak_heat_day"):
        record_data(settings, BoptestRun(time_period=None, first_day=20.0, days=1.0), lambda k, t, row: 0.0)
    with pytest.raises(InputError, match="never on a test period"):
        record_data(settings, BoptestRun(days=1.0), lambda k, t, row: 0.0)
    rng = np.random.default_rng(0)
    levels = rng.uniform(0.0, settings.points.scaling.max_power_w, size=24)
    run = BoptestRun(time_period=None, first_day=40.0, days=0.5, warmup_days=1.0, dt_s=1800.0)
    data = record_data(settings, run, lambda k, t, row: float(levels[k]))
    assert len(data) == 24 and str(data["time"].iloc[0]) == "2018-02-10 00:00:00"
    assert list(data.columns[:4]) == ["time", "T_r", "u", "u_phys"]
    off = data["u"] < 0.5 * settings.points.scaling.min_power_w
    # below half the lowest power: off (the 30-s samples of BOPTEST's trajectory, which its
    # energy KPI integrates too, carry the last interval's power into the first 15 s)
    assert np.all(data.loc[off, "u_phys"] < 0.02 * settings.points.scaling.min_power_w)
    on = data["u"] >= settings.points.scaling.min_power_w
    assert np.all(np.abs(data.loc[on, "u_phys"] / data.loc[on, "u"] - 1.0) < 0.06)
    assert np.all((data["T_r"] > 10.0) & (data["T_r"] < 30.0))


class Interrupted(Constant):
    """A controller whose third decision is interrupted, as Ctrl-C would."""

    def __init__(self) -> None:
        super().__init__(2000.0)
        self.calls = 0

    def act(self, obs: Observation, forecast: Forecast) -> float:
        self.calls += 1
        if self.calls == 3:
            raise KeyboardInterrupt
        return self.u_w


def test_ctrl_c_in_the_loop_stops_the_test_on_the_server(settings: BoptestSettings) -> None:
    # a period of its own with no warm-up: the cheapest start
    run = BoptestRun(time_period=None, first_day=45.0, days=0.25, warmup_days=0.0, dt_s=1800.0)
    u_max = settings.points.scaling.max_power_w
    plant = BoptestPlant(settings, run)
    frame = plant.exogenous_frame()
    t_r0 = float(plant.measure()[0])
    controller = Interrupted()
    with pytest.raises(KeyboardInterrupt):
        with ClosedLoop(
            SimConfig(u_max_w=u_max, dt_s=run.dt_s), ExogenousSeries.from_frame(frame),
            spec=ControlSpec(actuators=(ActuatorSpec(upper_w=u_max),), dt_s=run.dt_s), initial_t_r_c=t_r0,
            initial_t_m_c=t_r0, plant=plant,
        ) as loop:
            for _ in range(run.n_intervals):
                loop.advance(controller)
    assert controller.calls == 3 and loop.k == 2
    assert plant.test.stopped
    status = BoptestClient(settings.url).call("GET", f"status/{plant.test.testid}")
    assert status == "Stopped"


# --- one test for several runs ----------------------------------------------------------------

#: What a run measures in wall time, not of the building: left out where two runs are compared.
WALL_CLOCK_KPIS = {"decision_ms_median", "decision_ms_mean", "decision_ms_p95", "time_ratio"}


def _assert_same_run(result: ClosedLoopResult, reference: ClosedLoopResult) -> None:
    """``result`` is ``reference``'s run: its KPIs (BOPTEST's and the package's) and trajectory
    to 1e-9 relative, but for the wall-clock figures (:data:`WALL_CLOCK_KPIS`, BOPTEST's
    ``time_rat``, the decision times)."""
    got, want = dict(result.kpis), dict(reference.kpis)
    assert got.keys() == want.keys()
    for key in want.keys() - WALL_CLOCK_KPIS - {"boptest"}:
        if isinstance(want[key], float):
            assert got[key] == pytest.approx(want[key], rel=1e-9), key
        else:
            assert got[key] == want[key], key
    ours, theirs = result.kpis["boptest"], reference.kpis["boptest"]
    assert ours.keys() == theirs.keys() and ours["time_rat"] is not None
    for key in theirs.keys() - {"time_rat"}:
        if theirs[key] is None:
            assert ours[key] is None, key
        else:
            assert ours[key] == pytest.approx(theirs[key], rel=1e-9), key
    pd.testing.assert_frame_equal(
        result.trajectory.drop(columns="decision_ms"), reference.trajectory.drop(columns="decision_ms"),
        check_exact=False, rtol=1e-9,
    )
    assert result.errors == reference.errors


@pytest.mark.slow
def test_a_loop_on_a_borrowed_test_is_the_loop_on_a_fresh_test(server: Server) -> None:
    """BOPTEST re-initialises a test and its KPIs as a run re-starts it (``PUT /scenario``):
    the thermostat's half day on a test, after the baseline's on it, has the KPIs
    (BOPTEST's and the package's) and trajectory of the same day on a fresh test; KPIs
    carried over from an earlier run would add to them. The plants leave the test running."""
    from controllers.thermostat import Thermostat
    from scenarios.running.boptest_loop import BASELINE, boptest_scenario, run_boptest_closed_loop

    chosen = boptest_scenario("boptest_hydronic_heat_pump", url=server.url)
    run = BoptestRun(time_period="peak_heat_day", days=0.5, dt_s=3600.0)
    spec = chosen.scenario(run.dt_s).control_spec()

    def thermostat(test: BoptestTest | None) -> ClosedLoopResult:
        return run_boptest_closed_loop(chosen, "thermostat", Thermostat(spec), run=run, test=test)

    fresh = thermostat(None)
    with closing(BoptestClient(server.url)) as client, client.select(TESTCASE) as test:
        before = run_boptest_closed_loop(chosen, BASELINE, None, run=run, test=test)
        reused = thermostat(test)
        assert not test.stopped and client.call("GET", f"status/{test.testid}") == "Running"
    assert test.stopped
    assert BoptestClient(server.url).call("GET", f"status/{test.testid}") == "Stopped"
    # the baseline's run left energy behind to carry over, and differs from the thermostat's
    b, t = before.kpis["boptest"], fresh.kpis["boptest"]
    assert b["ener_tot"] is not None and t["ener_tot"] is not None and b["ener_tot"] > 0
    assert b["ener_tot"] != pytest.approx(t["ener_tot"], rel=1e-3)
    _assert_same_run(reused, fresh)


def test_a_plant_refuses_a_borrowed_test_of_another_test_case() -> None:
    points = read_boptest_file(str(SCENARIO)).points
    test = BoptestTest(BoptestClient(f"http://127.0.0.1:{free_port()}"), "no-id", "bestest_air")
    with pytest.raises(ValueError, match="test case bestest_air, the scenario's is bestest_hydronic_heat_pump"):
        BoptestPlant(BoptestSettings(points=points), BoptestRun(days=1), test=test)
    assert not test.stopped


def test_a_plant_on_a_borrowed_test_leaves_stopping_it_to_its_owner(settings: BoptestSettings) -> None:
    import dataclasses

    run = BoptestRun(time_period=None, first_day=45.0, days=0.25, warmup_days=0.0, dt_s=1800.0)
    wrong = dataclasses.replace(settings.points, room_temperature="reaTRoom_y")
    with closing(BoptestClient(settings.url)) as client, client.select(TESTCASE) as test:
        with pytest.raises(InputError, match="has no measurement reaTRoom_y"):
            BoptestPlant(dataclasses.replace(settings, points=wrong), run, test=test)
        assert not test.stopped
        with BoptestPlant(settings, run, test=test) as plant:
            first = plant.step(2000.0, 0).t_r_c[0, 0]
        assert plant.test is test and not test.stopped
        assert client.call("GET", f"status/{test.testid}") == "Running"
        with BoptestPlant(settings, run, test=test) as again:  # re-started: the same interval
            assert again.start_time_s == plant.start_time_s
            assert again.step(2000.0, 0).t_r_c[0, 0] == pytest.approx(first, rel=1e-12)
    assert test.stopped
    assert BoptestClient(settings.url).call("GET", f"status/{test.testid}") == "Stopped"


# --- the command line on BOPTEST ---------------------------------------------------------------


def test_cli_without_a_server_exits_2_with_one_line_naming_the_url(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from pinn_mpc_cli.cli import main

    url = f"http://127.0.0.1:{free_port()}"
    monkeypatch.setenv("BOPTEST_URL", url)
    out = tmp_path / "k.json"
    code = main(["closed-loop", "--scenario", "boptest_hydronic_heat_pump", "--controller",
                 "thermostat", "--days", "1", "--json", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err
    assert url in err and "docker compose up" in err and "BOPTEST_URL" in err
    assert not out.exists()


def test_cli_closed_loop_days_on_boptest_default_to_the_test_period(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Without --days a BOPTEST closed loop goes on to the server (its test period's 14
    days); --days 15 is one line in the user's terms; the package's own scenarios still
    need --days."""
    from pinn_mpc_cli.cli import main
    from pinn_mpc_cli.parser import build_parser

    url = f"http://127.0.0.1:{free_port()}"
    monkeypatch.setenv("BOPTEST_URL", url)
    out = ["--json", str(tmp_path / "k.json")]
    boptest = ["closed-loop", "--scenario", "boptest_hydronic_heat_pump", "--controller", "thermostat"]
    assert main([*boptest, *out]) == 2
    assert f"no BOPTEST server answers at {url}" in capsys.readouterr().err
    assert main([*boptest, "--days", "15", *out]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("error: --days 15: a BOPTEST test period has 14 days; give at most 14, or leave --days out for the whole period")
    assert "BoptestRun" not in err
    assert main(["closed-loop", "--scenario", "paper_household", "--controller", "thermostat", *out]) == 2
    assert "closed-loop needs --days N" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    help_text = " ".join(commands.choices["closed-loop"].format_help().split())
    assert "on a BOPTEST scenario the days of its test period, after BOPTEST's warm-up, default the whole period: 14" in help_text


def test_models_and_rc_files_get_the_plants_checks_on_boptest(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """identify / train on winter_household data (its 10 kW heater): refused on BOPTEST's
    3715 W heat pump as on heat_pump_household's 4000 W, before any server call; an RC of
    data within the emulator's margin (:data:`BOPTEST_FIT_CHECKS`) is taken."""
    import json

    from pinn_mpc.data import write_timeseries
    from pinn_mpc_cli.cli import main
    from scenarios.inputs.scenario_file import get_scenario
    from scenarios.running.boptest_loop import (
        BOPTEST_FIT_CHECKS,
        boptest_controller,
        boptest_scenario,
    )
    from scenarios.running.datagen import generate

    monkeypatch.setenv("BOPTEST_URL", f"http://127.0.0.1:{free_port()}")  # no server: a call fails
    data = generate(get_scenario("winter_household"), days=3, seed=0, policy="random-level", weather_part="train")
    top = float(data["u_phys"].max())
    assert top > 1.5 * 3715.0  # another building's heater
    write_timeseries(data, tmp_path / "wh.csv")
    rc = tmp_path / "rc_base.json"
    assert main(["identify", "--data", str(tmp_path / "wh.csv"), "--out", str(rc)]) == 0
    assert main(["train", "--data", str(tmp_path / "wh.csv"), "--arch", "arx", "--out", str(tmp_path / "arx")]) == 0
    capsys.readouterr()
    out = ["--days", "1", "--json", str(tmp_path / "k.json")]
    runs = {
        "rc": (["--controller", "qp-mpc", "--rc", str(rc)], f"the RC of rc_base.json was identified on powers up to {top:.0f} W"),
        "cem": (["--controller", "cem", "--model", str(tmp_path / "arx")], f"the model was trained on powers up to {top:.0f} W"),
        "qp-mpc over the ARX": (["--controller", "qp-mpc", "--model", str(tmp_path / "arx")], f"the model was trained on powers up to {top:.0f} W"),
    }
    for what, (args, refusal) in runs.items():
        for scenario, limit in (("heat_pump_household", 4000), ("boptest_hydronic_heat_pump", 3715)):
            assert main(["closed-loop", "--scenario", scenario, *args, *out]) == 2, (what, scenario)
            err = capsys.readouterr().err.strip()
            assert "\n" not in err and refusal in err and f"at most {limit} W" in err, (what, err)
    assert not (tmp_path / "k.json").exists()
    # an RC of data up to the margin is the emulator's own: taken, no server asked
    chosen = boptest_scenario("boptest_hydronic_heat_pump")
    record = json.loads(rc.read_text())
    slack = BOPTEST_FIT_CHECKS.power_slack
    for power_w, taken in ((0.99 * slack * 3715.0, True), (1.01 * slack * 3715.0, False)):
        record["power_range_w"] = [0.0, power_w]
        rc.write_text(json.dumps(record))
        if taken:
            controller = boptest_controller("qp-mpc", chosen, dt_s=1800.0, model_dir=None, rc_path=rc, n_steps=48)
            assert controller is not None and controller.name == "qp-mpc"
        else:
            with pytest.raises(InputError, match="identified on powers up to"):
                boptest_controller("qp-mpc", chosen, dt_s=1800.0, model_dir=None, rc_path=rc, n_steps=48)


def test_cli_simulate_refuses_days_on_a_test_period(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from pinn_mpc_cli.cli import main

    out = tmp_path / "d.csv"
    # peak_heat_day's test period is days 16-30 of the year after its warm-up from day 9
    code = main(["simulate", "--scenario", "boptest_hydronic_heat_pump", "--days", "3",
                 "--first-day", "28", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "peak_heat_day" in err and "days 9-30" in err
    assert not out.exists()
    # --test-period is BOPTEST's: refused on the package's own scenarios
    code = main(["closed-loop", "--scenario", "paper_household", "--controller", "thermostat",
                 "--days", "1", "--test-period", "peak_heat_day", "--json", str(tmp_path / "k.json")])
    assert code == 2 and "BOPTEST scenarios" in capsys.readouterr().err


# The CLI's simulate -> identify -> train -> closed loops and compare on BOPTEST, with BOPTEST's
# KPIs in the JSON agreeing with the package's: tests/test_docs.py runs docs/boptest.md as written.


def test_cli_compare_options_on_and_off_boptest(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from pinn_mpc_cli.cli import main

    out = ["--json", str(tmp_path / "t.json"), "--report", str(tmp_path / "r.md")]
    assert main(["compare", "--scenario", "boptest_hydronic_heat_pump", "--days", "15", *out]) == 2
    assert "14 days" in capsys.readouterr().err
    assert main(["compare", "--scenario", "paper_household", "--price-scenario", "dynamic", *out]) == 2
    assert "BOPTEST scenarios" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


@pytest.mark.slow
def test_a_sweep_runs_boptest_tests_as_cells_and_reuses_them(
    server: Server, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Two cells (BOPTEST's baseline and qp-mpc on the RC identified from two days of the
    emulator's data), one day of peak_heat_day each, run at once on the server: each cell's
    record carries BOPTEST's KPIs; a rerun reuses both; the results page shows them."""
    import importlib.util
    import json

    from scenarios.experiments.sweep import SweepGrid, SweepSettings, run_sweep

    monkeypatch.setenv("BOPTEST_URL", server.url)
    grid = SweepGrid(scenarios=("boptest_hydronic_heat_pump",), controllers=("qp-mpc",),
                     seeds=(0,), train_days=(2,))
    settings = SweepSettings(test_days=1)
    out = tmp_path / "sweep"
    first = run_sweep(grid, settings, out, baseline="boptest-baseline", workers=2)
    assert first.summary["cells_run"] == 2 and first.summary["models_trained"] == 1
    cells = {p.name: json.loads(p.read_text()) for p in (out / "cells").glob("*.json")}
    assert set(cells) == {
        "boptest_hydronic_heat_pump--peak_heat_day--dynamic--boptest-baseline--seed0.json",
        "boptest_hydronic_heat_pump--peak_heat_day--dynamic--qp-mpc--seed0--train2.json",
    }
    area = read_boptest_file(str(SCENARIO)).points.floor_area_m2
    for record in cells.values():
        kpis = record["kpis"]
        assert record["cell"]["test_period"] == "peak_heat_day"
        assert kpis["counted_days"] == ["2018-01-17", "2018-01-17"]
        assert kpis["energy_kwh"] / area == pytest.approx(kpis["boptest"]["ener_tot"], rel=1e-3)
        assert kpis["wall_s_per_day"] == pytest.approx(record["wall_time_s"])
    assert cells["boptest_hydronic_heat_pump--peak_heat_day--dynamic--qp-mpc--seed0--train2.json"]["kpis"]["model"] == "rc"
    row = next(r for r in first.summary["rows"] if r["controller"] == "qp-mpc")
    assert row["test_period"] == "peak_heat_day" and row["reference"] == "boptest-baseline"
    again = run_sweep(grid, settings, out, baseline="boptest-baseline", workers=1)
    assert again.summary["cells_run"] == 0 and again.summary["cells_reused"] == 2
    spec = importlib.util.spec_from_file_location("gen_results", ROOT / "docs" / "gen_results.py")
    assert spec is not None and spec.loader is not None
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    text = gen.page(ROOT / "sweeps" / "boptest.toml", out, "python docs/gen_results.py", None, "abc")
    tdis = cells["boptest_hydronic_heat_pump--peak_heat_day--dynamic--qp-mpc--seed0--train2.json"]["kpis"]["boptest"]["tdis_tot"]
    assert f"| peak_heat_day | dynamic | qp-mpc | 2 | 0 | rc | {tdis:.4g} |" in text
    assert "| peak_heat_day | highly_dynamic | 8.381 | 3.478 | 0.9088 |" in text


def test_scenario_command_shows_lists_and_exports_the_boptest_scenario(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from pinn_mpc_cli.cli import main
    from scenarios.inputs.scenario_file import get_scenario

    assert main(["scenario", "show", "boptest_hydronic_heat_pump"]) == 0
    assert capsys.readouterr().out.strip() == SCENARIO.read_text().strip()
    assert main(["scenario", "list"]) == 0
    listed = capsys.readouterr().out
    assert "\nboptest_hydronic_heat_pump: BOPTEST's test case bestest_hydronic_heat_pump" in listed
    out = tmp_path / "mine.toml"
    assert main(["scenario", "export", "boptest_hydronic_heat_pump", "--out", str(out)]) == 0
    assert read_boptest_file(str(out)) == read_boptest_file(str(SCENARIO))
    capsys.readouterr()
    assert main(["scenario", "show", str(out)]) == 0
    assert "[boptest.test_periods]" in capsys.readouterr().out
    # where one of the package's own scenarios is needed, the name is refused saying why
    with pytest.raises(InputError, match="is a BOPTEST scenario: it runs on a BOPTEST server"):
        get_scenario("boptest_hydronic_heat_pump")


def test_cli_sweep_on_boptest_without_a_server_exits_2_before_any_work(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from pinn_mpc_cli.cli import main

    url = f"http://127.0.0.1:{free_port()}"
    monkeypatch.setenv("BOPTEST_URL", url)
    out = tmp_path / "sweep"
    code = main(["sweep", "--scenarios", "boptest_hydronic_heat_pump", "--controllers", "thermostat",
                 "--seeds", "0", "--days", "1", "--test-periods", "typical_heat_day", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and url in err
    assert not out.exists()


def test_boptest_planners_from_fitted_models_and_their_refusals() -> None:
    from controllers.thermostat import Thermostat
    from pinn_mpc.physics import PAPER_HOUSEHOLD
    from pinn_mpc.training import TrainConfig
    from scenarios.running.boptest_loop import (
        BASELINE,
        boptest_fit,
        boptest_planner,
        boptest_scenario,
    )

    chosen = boptest_scenario("boptest_hydronic_heat_pump")
    assert boptest_planner(BASELINE, chosen, None, dt_s=1800.0, n_steps=48) is None
    assert isinstance(boptest_planner("thermostat", chosen, None, dt_s=1800.0, n_steps=48), Thermostat)
    qp = boptest_planner("qp-mpc", chosen, PAPER_HOUSEHOLD, dt_s=1800.0, n_steps=48)
    assert qp is not None and qp.name == "qp-mpc"
    for name, model in (("oracle", None), ("cem", None), ("cem", PAPER_HOUSEHOLD), ("qp-mpc", None)):
        with pytest.raises(InputError, match="on BOPTEST takes boptest-baseline, thermostat, qp-mpc"):
            boptest_planner(name, chosen, model, dt_s=1800.0, n_steps=48)
    with pytest.raises(ValueError, match="unknown model 'lstm'"):
        boptest_fit("lstm", None, TrainConfig())  # type: ignore[arg-type]
