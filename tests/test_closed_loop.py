"""The closed-loop runner and the ``closed-loop`` command, on paper_household."""

import dataclasses
import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from controllers.base import Controller, Forecast, Observation, SolveStats, fallback_power
from controllers.thermostat import Thermostat
from pinn_mpc.data import read_timeseries
from pinn_mpc.errors import InternalError
from pinn_mpc_cli.cli import main
from scenarios.inputs.exogenous import ComfortSchedule, SyntheticWeather
from scenarios.inputs.scenario_file import get_scenario
from scenarios.inputs.series import ForecastErrors
from scenarios.reports.report import format_kpis
from scenarios.running.closed_loop import (
    EXTRA_COLUMNS,
    build_loop,
    counted_kpis,
    free_records,
    prepare_run,
    run_closed_loop,
)
from scenarios.running.factory import (
    CONTROLLER_NAMES,
    MODEL_CONTROLLERS,
    RC_CONTROLLERS,
    build_controller,
    make_controller,
)
from scenarios.running.kpis import KPI_KEYS

TIME_KEYS = {"decision_ms_median", "decision_ms_mean", "decision_ms_p95", "time_ratio"}


class ConstantPower:
    """Demands the same power every interval; records what it was shown."""

    name = "constant"
    knows_true_state = False
    model = None
    trust_report = None

    def __init__(self, power_w: float):
        self.power_w = power_w
        self.seen: list[tuple[Observation, Forecast]] = []

    def reset(self, seed=None):
        self.seen.clear()

    def act(self, obs, forecast):
        self.seen.append((obs, forecast))
        return self.power_w

    @property
    def last_plan(self):
        return None

    @property
    def last_stats(self):
        return SolveStats(time_s=0.0, status="ok", iterations=0, fallback=False)


class Failing(ConstantPower):
    """Raises on every ``every``-th call, returns NaN on the others when ``nan``."""

    name = "failing"

    def __init__(self, *, every=1, nan=False):
        super().__init__(0.0)
        self.every, self.nan, self.calls = every, nan, 0

    def act(self, obs, forecast):
        self.calls += 1
        if self.calls % self.every == 0:
            raise RuntimeError("solver exploded")
        return float("nan") if self.nan else 1000.0


@pytest.fixture(scope="module")
def scenario():
    return get_scenario("paper_household")


@pytest.fixture(scope="module")
def thermostat_runs(scenario):
    return [
        run_closed_loop(scenario, Thermostat(scenario.control_spec()), days=2, seed=3)
        for _ in range(2)
    ]


def test_thermostat_run_is_deterministic_and_timed(scenario, thermostat_runs):
    first, second = thermostat_runs
    steps = 2 * 48
    assert len(first.trajectory) == steps
    for key in KPI_KEYS:
        assert key in first.kpis
        if key not in TIME_KEYS:
            assert first.kpis[key] == second.kpis[key], key
    np.testing.assert_array_equal(first.trajectory["T_r"], second.trajectory["T_r"])
    assert (first.trajectory["decision_ms"] > 0).all()
    assert first.kpis["decision_ms_median"] > 0
    dt_h = scenario.sim.dt_s / 3600
    total_decision_s = first.trajectory["decision_ms"].sum() / 1000
    assert first.kpis["time_ratio"] == pytest.approx(total_decision_s / (steps * scenario.sim.dt_s))
    assert first.kpis["energy_kwh"] == pytest.approx(first.trajectory["u_phys"].sum() * dt_h / 1000)
    assert first.kpis["controller"] == "thermostat" and first.kpis["days"] == 2
    assert set(EXTRA_COLUMNS) <= set(first.trajectory.columns)
    assert first.errors == ()


def test_other_seed_gives_other_run(scenario, thermostat_runs):
    other = run_closed_loop(scenario, Thermostat(scenario.control_spec()), days=2, seed=4)
    assert not np.array_equal(other.trajectory["T_a"], thermostat_runs[0].trajectory["T_a"])


def test_constant_power_energy_is_analytic_without_backup(scenario):
    # Backup limits far away: the demand is delivered exactly, P for 48 h -> P * 48 / 1000 kWh.
    wide = dataclasses.replace(
        scenario, sim=dataclasses.replace(scenario.sim, backup_low_c=-50.0, backup_high_c=80.0)
    )
    run = run_closed_loop(wide, ConstantPower(1500.0), days=2, seed=0)
    assert run.kpis["energy_kwh"] == pytest.approx(1500.0 * 48 / 1000, rel=1e-12)
    assert run.kpis["peak_kw"] == pytest.approx(1.5, rel=1e-12)
    assert run.kpis["backup_overrides"] == 0
    price = run.trajectory["price"].to_numpy()
    assert run.kpis["cost_eur"] == pytest.approx(float(np.sum(1.5 * 0.5 * price)), rel=1e-12)


def test_backup_overrides_are_counted(scenario):
    # Full power all the time overheats the room: the backup cuts it above 20.5 C.
    u_max = scenario.sim.u_max_w
    run = run_closed_loop(scenario, ConstantPower(u_max), days=2, seed=0)
    traj = run.trajectory
    over = traj["overridden"].to_numpy(bool)
    assert run.kpis["backup_overrides"] == int(over.sum()) > 0
    np.testing.assert_allclose(traj["u_phys"][~over], traj["u"][~over], rtol=0, atol=1e-9)
    assert (traj["u_phys"][over] < u_max).all()


def test_observation_and_forecast_contents(scenario):
    ctrl = ConstantPower(0.0)
    run_closed_loop(scenario, ctrl, days=1, seed=0, warmup_steps=10)
    horizon = scenario.horizon_steps
    assert len(ctrl.seen) == 48
    for i, (obs, forecast) in enumerate(ctrl.seen):
        k = 10 + i
        assert obs.k == k
        assert len(obs.history["T_r"]) == k + 1 and obs.history["T_r"][-1] == obs.t_r_c
        for name in ("u", "u_phys"):
            assert len(obs.history[name]) == k
        for name in ("T_a", "G", "I_g", "time_of_day_h"):
            assert len(obs.history[name]) == k + 1
        assert forecast.horizon == 10 + 48 + horizon - k
        assert forecast.T_a[0] == obs.history["T_a"][-1]
        assert math.isfinite(obs.t_m_true_c)
    # The past the controller saw is what happened: its own (zero) demand after the warm-up.
    last_obs = ctrl.seen[-1][0]
    assert (last_obs.history["u"][10:] == 0.0).all()


def test_forecast_errors_are_seeded_and_spare_the_present(scenario):
    noisy_scenario = dataclasses.replace(scenario, forecast=ForecastErrors(t_a_error_std_c=1.0))

    def forecasts(seed):
        ctrl = ConstantPower(0.0)
        run_closed_loop(noisy_scenario, ctrl, days=1, seed=seed)
        return ctrl.seen

    exact = ConstantPower(0.0)
    run_closed_loop(scenario, exact, days=1, seed=0)
    noisy, again = forecasts(0), forecasts(0)
    f_exact, f_noisy = exact.seen[0][1], noisy[0][1]
    assert f_noisy.T_a[0] == f_exact.T_a[0]
    assert not np.array_equal(f_noisy.T_a[1:], f_exact.T_a[1:])
    np.testing.assert_array_equal(f_noisy.T_a, again[0][1].T_a)
    # The plant ran on the truth: the observed past is the exact one.
    np.testing.assert_array_equal(noisy[-1][0].history["T_a"], exact.seen[-1][0].history["T_a"])


@pytest.mark.parametrize(
    ("controller", "expected"),
    [(Failing(every=1), 48), (Failing(every=3), 16), (Failing(every=1000, nan=True), 48)],
    ids=["always-raises", "raises-every-third", "returns-nan"],
)
def test_failures_fall_back_and_are_counted(scenario, controller, expected):
    run = run_closed_loop(scenario, controller, days=1, seed=0)
    assert run.kpis["fallbacks"] == expected
    assert len(run.errors) == expected
    fb = run.trajectory["fallback"].to_numpy(bool)
    assert int(fb.sum()) == expected
    # Fallback steps applied the documented band rule: all or nothing.
    u_max = scenario.sim.u_max_w
    assert set(np.unique(run.trajectory["u"][fb])) <= {0.0, u_max}


def test_fallback_matches_the_documented_rule(scenario):
    spec = scenario.control_spec()
    ctrl = Failing(every=1)
    run = run_closed_loop(scenario, ctrl, days=1, seed=0)
    traj = run.trajectory
    for row in traj.itertuples():
        obs = Observation(k=0, t_r_c=row.T_r, history={}, t_m_true_c=float("nan"))
        one = np.array([row.T_min]), np.array([row.T_max])
        forecast = Forecast(*(np.zeros(1),) * 5, T_min=one[0], T_max=one[1])
        assert row.u == fallback_power(obs, forecast, spec)


# ----------------------------------------------------------------------- the CLI command


def _cli(tmp_path, *extra):
    return main(
        ["closed-loop", "--scenario", "paper_household", "--days", "1", "--seed", "1", *extra]
    )


def test_cli_writes_json_csv_png(tmp_path, capsys):
    paths = {ext: tmp_path / f"run.{ext}" for ext in ("json", "csv", "png")}
    code = _cli(tmp_path, "--controller", "thermostat", "--json", str(paths["json"]),
                "--csv", str(paths["csv"]), "--plot", str(paths["png"]))
    assert code == 0
    out = capsys.readouterr().out
    assert "energy" in out and str(paths["json"]) in out
    kpis = json.loads(paths["json"].read_text())
    assert set(KPI_KEYS) <= set(kpis)
    assert kpis["scenario"] == "paper_household" and kpis["seed"] == 1
    traj = read_timeseries(paths["csv"])
    assert len(traj) == 48
    assert traj.attrs["dt_s"] == 1800.0
    dt_h = 0.5
    assert kpis["energy_kwh"] == pytest.approx(traj["u_phys"].sum() * dt_h / 1000, rel=1e-5)
    assert paths["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.json", "run.png"]


def test_cli_without_json_prints_the_kpis_and_writes_nothing(tmp_path, capsys, monkeypatch):
    """closed-loop's --json is optional (issue 46): the KPIs are printed, as format_kpis gives
    them, the same as a run that writes the JSON; nothing is written."""
    monkeypatch.chdir(tmp_path)
    assert _cli(tmp_path, "--controller", "thermostat") == 0
    printed = capsys.readouterr().out.strip()
    assert list(tmp_path.iterdir()) == []
    assert _cli(tmp_path, "--controller", "thermostat", "--json", "k.json") == 0
    kpis = json.loads((tmp_path / "k.json").read_text())
    assert printed == format_kpis(kpis)
    assert capsys.readouterr().out.strip() == f"{printed}\nwrote k.json"
    assert _cli(tmp_path, "--controller", "qp-mpc", "--buildings", "2") == 0
    assert capsys.readouterr().out.startswith("qp-mpc x 2 buildings on paper_household, 1 d: energy")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.json"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--controller", "pid"], "unknown controller 'pid'"),
        (["--controller", "qp-mpc"], "--rc rc.json"),
        (["--controller", "casadi-mpc"], "--rc rc.json"),
        (["--controller", "cem"], "--model MODEL_DIR"),
        (["--controller", "random-shooting"], "--model MODEL_DIR"),
        (["--controller", "thermostat", "--rc", "rc.json"], "--rc is not used"),
    ],
)
def test_cli_bad_controller_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    json_path = tmp_path / "k.json"
    assert _cli(tmp_path, *args, "--json", str(json_path)) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_cli_unreadable_rc_file_exits_2(tmp_path, capsys):
    rc = tmp_path / "rc.json"
    rc.write_text('{"R_ra_K_per_W": 0.01}')
    assert _cli(tmp_path, "--controller", "qp-mpc", "--rc", str(rc),
                "--json", str(tmp_path / "k.json")) == 2
    err = capsys.readouterr().err
    assert "RC JSON lacks key(s)" in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rc.json"]


def test_cli_unwritable_json_leaves_nothing(tmp_path, capsys):
    csv_path = tmp_path / "traj.csv"
    code = _cli(tmp_path, "--controller", "thermostat",
                "--json", str(tmp_path / "missing" / "k.json"), "--csv", str(csv_path))
    assert code == 2
    err = capsys.readouterr().err
    assert "does not exist" in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------- the factory


@pytest.fixture(scope="module")
def files(tmp_path_factory, scenario):
    """A tiny trained model directory and the true RC parameters as an RC JSON."""
    from pinn_mpc.artifacts import save_model
    from pinn_mpc.physics import rc_summary
    from pinn_mpc.training import TrainConfig, train_model
    from scenarios.running.datagen import generate

    root = tmp_path_factory.mktemp("factory")
    data = generate(scenario, days=3, seed=0, policy="random")
    model = train_model(
        data, arch="physnet", config=TrainConfig(depth=4, n_seeds=1, epochs=1), progress=False
    )
    save_model(model, root / "model")
    (root / "rc.json").write_text(json.dumps(rc_summary(scenario.sim.params, source="true")))
    return {"model_dir": str(root / "model"), "rc_path": str(root / "rc.json")}


@pytest.mark.parametrize("name", CONTROLLER_NAMES)
def test_factory_builds_every_controller_by_its_cli_name(scenario, files, name):
    kwargs = {}
    if name in MODEL_CONTROLLERS:
        kwargs["model_dir"] = files["model_dir"]
    if name in RC_CONTROLLERS:
        kwargs["rc_path"] = files["rc_path"]
    controller = make_controller(name, scenario, n_steps=48, **kwargs)
    assert isinstance(controller, Controller)
    assert controller.name == name


def test_qp_mpc_on_true_rc_in_closed_loop_beats_the_thermostat(tmp_path, files, scenario):
    json_path = tmp_path / "k.json"
    assert _cli(tmp_path, "--controller", "qp-mpc", "--rc", files["rc_path"],
                "--json", str(json_path)) == 0
    kpis = json.loads(json_path.read_text())
    thermostat = run_closed_loop(scenario, Thermostat(scenario.control_spec()), days=1, seed=1)
    assert kpis["objective"] < thermostat.kpis["objective"]


# ---- the discomfort no controller could avoid (free_records, the KPIs' split) ----


def _hot_day(t0_c: float) -> object:
    """paper_household with a constant 30 C outside, no sun, no gains, a 18-22 C band, the
    room and the mass at ``t0_c`` at the start and a backup thermostat out of the way."""
    base = get_scenario("paper_household")
    return dataclasses.replace(
        base,
        sim=dataclasses.replace(base.sim, backup_low_c=5.0, backup_high_c=45.0),
        weather=SyntheticWeather(
            mean_c=30.0, daily_amplitude_c=0.0, slow_amplitude_c=0.0, noise_std_c=0.0,
            peak_irradiance_w_per_m2=0.0,
        ),
        comfort=ComfortSchedule(day_min_c=18.0, day_max_c=22.0, night_min_c=18.0, night_max_c=22.0),
        initial_t_r_c=t0_c,
        initial_t_m_c=t0_c,
    )


def _too_warm_kh_closed_form(params, *, t0_c, t_a_c, heat_w, t_max_c, dt_sub_s, n_sub):
    """The 2R2C from T_r = T_m = t0_c under constant outdoor temperature and heating, no sun or
    gains, in closed form: it relaxes to T_r = T_m = t_a_c + eta heat_w R_ra along two
    exponentials (the eigenvalues of the 2x2 system); the too-warm K h as the KPI takes it,
    the temperature at the end of each of n_sub substeps held over it (the room above t_max_c
    throughout)."""
    c_r, c_m = params.c_r_j_per_k, params.c_m_j_per_k
    r_ra, r_rm = params.r_ra_k_per_w, params.r_rm_k_per_w
    a = np.array([[-1 / (c_r * r_ra) - 1 / (c_r * r_rm), 1 / (c_r * r_rm)],
                  [1 / (c_m * r_rm), -1 / (c_m * r_rm)]])
    trace, det = a[0, 0] + a[1, 1], a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    lam = trace / 2 + np.array([1.0, -1.0]) * math.sqrt(trace**2 / 4 - det)
    v = np.array([[a[0, 1], a[0, 1]], lam - a[0, 0]])  # eigenvectors as columns
    t_ss = t_a_c + params.eta * heat_w * r_ra
    alpha = np.linalg.solve(v, np.full(2, t0_c - t_ss))
    q = np.exp(lam * dt_sub_s)  # per-substep decay of each mode
    # sum over j = 1..n of T_r(j h) - t_max = (t_ss - t_max) n + sum_i a01 alpha_i q_i (1 - q_i^n) / (1 - q_i)
    modes = a[0, 1] * alpha * q * (1 - q**n_sub) / (1 - q)
    return ((t_ss - t_max_c) * n_sub + modes.sum()) * dt_sub_s / 3600.0


@pytest.mark.parametrize("heat_w", [0.0, 1500.0])
def test_unavoidable_discomfort_of_a_hot_day_is_the_closed_form_relaxation(heat_w):
    """A day at 30 C outside, the room starting at 23 C above its 22 C top: free-running it
    relaxes towards 30 C, and its too-warm K h is the closed form's; a heater held at 1.5 kW
    adds the closed form's extra K h, which is all avoidable."""
    scenario = _hot_day(23.0)
    result = run_closed_loop(scenario, ConstantPower(heat_w), days=1, seed=0, warmup_steps=0)
    k, sim = result.kpis, scenario.sim
    n_sub, dt_sub_s = 48 * sim.n_substeps, sim.dt_s / sim.n_substeps
    form = dict(t0_c=23.0, t_a_c=30.0, t_max_c=22.0, dt_sub_s=dt_sub_s, n_sub=n_sub)
    free_kh = _too_warm_kh_closed_form(sim.params, heat_w=0.0, **form)
    own_kh = _too_warm_kh_closed_form(sim.params, heat_w=heat_w, **form)
    assert free_kh > 48.0  # more than a kelvin above the top all day
    assert k["discomfort_unavoidable_kh"] == pytest.approx(free_kh, rel=1e-9)
    assert k["discomfort_too_warm_kh"] == k["discomfort_kh"] == pytest.approx(own_kh, rel=1e-9)
    assert k["discomfort_avoidable_kh"] == pytest.approx(own_kh - free_kh, rel=1e-7, abs=1e-9)
    assert k["discomfort_too_cold_kh"] == 0.0


@pytest.fixture(scope="module")
def free_days():
    """Two test days (seed 0: 11-12 March for the households, up to 29 C outside) of each
    scenario free-running after the thermostat's warm-up."""
    out = {}
    for name in ("winter_household", "heat_pump_household", "mismatch_household", "cold_storage"):
        scenario = get_scenario(name)
        run = prepare_run(scenario, days=2, seed=0, warmup_steps=None, weather_part="test")
        free = free_records(scenario, run, seed=0)[0]
        out[name] = scenario, run, free, counted_kpis(scenario, run, free)
    return out


def _one_backup_substep_k(scenario) -> float:
    """The most one substep at full power can change the room [K]: what the backup thermostat's
    floor, applied substep by substep, can put between two runs near it."""
    sim = scenario.sim
    gain = sim.actuator.cop_max if sim.actuator.kind == "heat_pump" else 1.0
    return sim.u_max_w * abs(sim.params.eta) * gain / sim.params.c_r_j_per_k * sim.dt_s / sim.n_substeps


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    name=st.sampled_from(["winter_household", "heat_pump_household", "mismatch_household", "cold_storage"]),
    levels=st.lists(st.floats(0.0, 1.0), min_size=96, max_size=96),
)
def test_no_plan_beats_the_free_run_on_the_side_its_actuator_cannot_help(free_days, name, levels):
    """Any plan of the actuator (random levels of its power after the same warm-up) leaves the
    room at least as warm as the free run (a cooling machine: as cold), but for one substep of
    the backup floor, and its too-warm (too-cold) K h at least the free run's."""
    scenario, run, free, free_kpis = free_days[name]
    spec = scenario.control_spec()
    thermostat = Thermostat(spec)
    thermostat.reset(0)
    with build_loop(scenario, run, seed=0) as loop:
        for k in range(run.total):
            if k < run.warmup:
                loop.advance(thermostat)
            else:
                loop.step(levels[k - run.warmup] * spec.u_max_w)
        rec = loop.record()
    sign = 1.0 if spec.heating else -1.0
    gap = sign * (rec.t_r_sub_c[run.counted] - free.t_r_sub_c[run.counted])
    assert gap.min() >= -_one_backup_substep_k(scenario)
    kpis = counted_kpis(scenario, run, rec, free)
    side = "discomfort_too_warm_kh" if spec.heating else "discomfort_too_cold_kh"
    assert kpis[side] >= free_kpis[side]
    assert kpis["discomfort_unavoidable_kh"] == free_kpis[side]
    assert kpis["discomfort_avoidable_kh"] >= 0.0


def test_free_days_have_unavoidable_discomfort(free_days):
    """The monotonicity test above means something: the heated scenarios' test days hold
    discomfort no heating could avoid (the warm spell of 11-12 March)."""
    for name in ("winter_household", "heat_pump_household", "mismatch_household"):
        assert free_days[name][3]["discomfort_too_warm_kh"] > 5.0, name


def _noisy(name: str):
    scenario = get_scenario(name)
    return dataclasses.replace(
        scenario,
        sim=dataclasses.replace(scenario.sim, noise_std_c=0.3),
        forecast=ForecastErrors(t_a_error_std_c=2.0, g_error_rel_std=0.3),
    )


def test_sensor_noise_and_forecast_errors_leave_the_bound_the_same_for_every_controller():
    """With sensor noise and forecast errors the warm-up (the thermostat reading the same noisy
    sensor) and the free run are the same for every controller of a seed, so they share the
    unavoidable part; misled controllers only add avoidable discomfort."""
    scenario = _noisy("winter_household")
    runs = [
        run_closed_loop(scenario, build_controller(name, scenario, rc_params=scenario.sim.params,
                                                   n_steps=96), days=2, seed=0)
        for name in ("thermostat", "qp-mpc", "oracle")
    ]
    run = prepare_run(scenario, days=2, seed=0, warmup_steps=None, weather_part="test")
    free = counted_kpis(scenario, run, free_records(scenario, run, seed=0)[0])
    for r in runs:
        assert r.kpis["discomfort_unavoidable_kh"] == free["discomfort_too_warm_kh"] > 5.0
        assert r.kpis["discomfort_too_warm_kh"] >= free["discomfort_too_warm_kh"]


def test_a_free_run_from_another_warm_up_is_refused():
    scenario = _noisy("winter_household")
    run = prepare_run(scenario, days=1, seed=0, warmup_steps=None, weather_part="test")
    ours, other = free_records(scenario, run, seed=0)[0], free_records(scenario, run, seed=1)[0]
    itself = counted_kpis(scenario, run, ours, ours)
    assert itself["discomfort_avoidable_kh"] == pytest.approx(itself["discomfort_too_cold_kh"], rel=1e-12)
    with pytest.raises(InternalError, match="warm-up differs"):
        counted_kpis(scenario, run, ours, other)
