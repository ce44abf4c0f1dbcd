"""Online operation (:mod:`scenarios.running.online`): the schedule, champion/challenger, the
spans each refit saw, resume after Ctrl-C, nothing half-written, refits that do not hold up
decisions."""

import functools
import json
import multiprocessing
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.errors import InputError
from pinn_mpc.training import TrainConfig
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import build_loop, prepare_run
from scenarios.running.datagen import generate
from scenarios.running.online import (
    MODEL_DAYS,
    REFIT_HOUR,
    TAKEOVER_H,
    OnlineSettings,
    _held_out_error,
    _refit_pool,
    night_steps,
    run_online,
)
from tests.online_stop import stopped_then_resumed

SCENARIO = "winter_household"
TINY = OnlineSettings(
    config=TrainConfig(n_seeds=2, epochs=2), planner_options={"n_samples": 16, "n_iters": 2}
)


def test_refits_start_at_midnight_and_take_over_at_three():
    scenario = get_scenario(SCENARIO)
    run = prepare_run(scenario, days=4, seed=0, warmup_steps=None, weather_part="test")
    spd = scenario.steps_per_day
    nights = night_steps(run, steps_per_day=spd, every_days=1)
    assert nights == [run.warmup + d * spd for d in (1, 2, 3)]
    times = pd.to_datetime(run.exo["time"])
    for k in nights:
        assert times[k].hour == REFIT_HOUR and times[k].minute == 0
        takeover = k + round(TAKEOVER_H * spd / 24)
        assert times[takeover].hour == 3
    assert night_steps(run, steps_per_day=spd, every_days=2) == [run.warmup + 2 * spd]


@pytest.fixture(scope="module")
def data_3_days() -> pd.DataFrame:
    return generate(get_scenario(SCENARIO), days=MODEL_DAYS, seed=0, policy="random-level")


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory, data_3_days):
    out = tmp_path_factory.mktemp("online") / "run"
    return out, run_online(get_scenario(SCENARIO), data_3_days, days=3, seed=0, out_dir=out, settings=TINY)


def _figures(kpis):
    """The figures a rerun must reproduce (decision times are wall time)."""
    days = [{k: v for k, v in d.items()} for d in kpis["online"]["days"]]
    keep = ("objective", "cost_eur", "discomfort_kh", "energy_kwh", "own_decisions_share")
    online = kpis["online"]
    return {k: kpis[k] for k in keep}, days, online["swaps"], online["refusals"], online["guard_refusals"]


@pytest.mark.slow
def test_each_refit_sees_only_the_past_and_the_verdict_follows_the_errors(uninterrupted):
    out, result = uninterrupted
    nights = [e for e in result.log if e["verdict"] != "initial"]
    assert [e["night"] for e in nights] == [1, 2]
    times = pd.to_datetime(result.trajectory["time"])
    first = times.iloc[0]
    for e in nights:
        night_start = first + pd.Timedelta(days=e["night"])
        last_seen = pd.Timestamp(e["data_span"][1])
        assert last_seen == night_start - pd.Timedelta(minutes=30)  # up to the night, no further
        assert pd.Timestamp(e["fitted_span"][1]) < pd.Timestamp(e["held_out_day"][0])
        assert e["held_out_day"][1] == e["data_span"][1]
        better = e["challenger_error_c"] < e["champion_error_c"]
        assert e["verdict"] == ("swap" if better else "refused")
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert log == json.loads(json.dumps(list(result.log)))
    per_day = result.kpis["online"]["days"]
    assert [d["day"] for d in per_day] == [1, 2, 3]
    assert per_day[0]["model_day_ahead_error_c"] == nights[0]["champion_error_c"]
    assert not list(out.rglob("*.tmp")) and not list(out.rglob(".*"))  # nothing half-written


@pytest.mark.slow
def test_a_worse_challenger_is_refused(uninterrupted):
    """A plain network trained one epoch on one day predicts the held-out day worse than the
    running model: the measure the run judges by ranks it below (a refusal)."""
    from pinn_mpc import fitted

    out, result = uninterrupted
    frame = pd.read_csv(out / "observed.csv", parse_dates=["time"])
    data = frame
    data.attrs["dt_s"] = 1800.0
    champion = fitted.load(out / "versions" / "v000" / "model")
    cut = len(data) - 48
    one_day = data.iloc[:48].reset_index(drop=True)
    one_day.attrs["dt_s"] = 1800.0
    worse = fitted.fit(one_day, arch="mlp", config=TrainConfig(n_seeds=2, epochs=1, depth=4)).model
    assert _held_out_error(worse, data, cut) > _held_out_error(champion, data, cut)


@pytest.mark.slow
def test_ctrl_c_and_resume_give_the_uninterrupted_figures(tmp_path, uninterrupted, data_3_days):
    _, expected = uninterrupted
    out = tmp_path / "run"
    stopped_at, resumed = stopped_then_resumed(
        lambda resume: run_online(
            get_scenario(SCENARIO), data_3_days, days=3, seed=0, out_dir=out, settings=TINY, resume=resume
        ),
        out / "state.json", 48 * 2,
    )
    assert 48 * 2 < stopped_at < 48 * 4
    assert _figures(resumed.kpis) == _figures(expected.kpis)
    assert [e["verdict"] for e in resumed.log] == [e["verdict"] for e in expected.log]


def test_a_run_folder_is_not_restarted_over(tmp_path):
    (tmp_path / "state.json").write_text("{}")

    with pytest.raises(InputError, match="already holds a run"):
        run_online(get_scenario(SCENARIO), None, days=2, seed=0, out_dir=tmp_path, settings=TINY)


@pytest.mark.parametrize(
    ("scenario", "data_of", "match"),
    [
        ("heat_pump_household", "winter_household", r"recorded with powers up to \d+ W, but scenario "
         r"'heat_pump_household''s actuator gives at most 4000 W: it was made for another building"),
        ("winter_household", "heat_pump_household", r"heat-pump data \(a cop column\), but the controllers of "
         r"scenario 'winter_household' plan without a COP"),
    ],
)
def test_data_of_another_building_are_refused_before_anything_runs(tmp_path, scenario, data_of, match):
    """Data a model of this building cannot be trained on (another actuator's, or powers beyond
    this one's) would leave the run without a model night after night: refused at once."""
    data = generate(get_scenario(data_of), days=2, seed=0, policy="random-level")
    with pytest.raises(InputError, match=match):
        run_online(get_scenario(scenario), data, days=2, seed=0, out_dir=tmp_path / "run", settings=TINY)
    assert not (tmp_path / "run").exists()


def test_data_whose_power_is_in_kw_are_refused_with_the_conversion(tmp_path):
    """The building's own data with its power in kW (a thousandth of its heater's): refused
    with the conversion, nothing written."""
    data = generate(get_scenario(SCENARIO), days=2, seed=0, policy="random-level")
    data = data.assign(u=data["u"] / 1000.0, u_phys=data["u_phys"] / 1000.0)
    with pytest.raises(InputError, match=r"the data's power was in kW; convert its power columns to W \(x 1000\) and give the data again"):
        run_online(get_scenario(SCENARIO), data, days=2, seed=0, out_dir=tmp_path / "run", settings=TINY)
    assert not (tmp_path / "run").exists()


@pytest.mark.slow
def test_decisions_go_on_while_a_refit_runs(tmp_path):
    """Without data the thermostat, then the RC's qp-mpc decide in milliseconds while each
    night's refit (the RC, then a model) runs in the worker: a refit slower than the three
    hours to its takeover is waited for there and counted, never inside a decision."""
    data = generate(get_scenario(SCENARIO), days=1, seed=0, policy="random-level")
    result = run_online(get_scenario(SCENARIO), data, days=4, seed=0, out_dir=tmp_path, settings=TINY)
    walls = result.kpis["online"]["refit_wall_s"]
    decision_s = result.trajectory["decision_ms"].to_numpy() / 1000.0
    assert np.max(decision_s) < max(walls)  # no decision took as long as the slowest refit
    late = [e for e in result.log if e.get("late")]
    assert result.kpis["online"]["late_refits"] == len(late)
    controllers = [d["controller"] for d in result.kpis["online"]["days"]]
    assert controllers[0] == "rc"  # one day at hand: the RC alone
    assert Path(tmp_path / "versions" / "v000" / "rc.json").is_file()


def test_data_that_do_not_determine_the_building_start_the_thermostat(tmp_path, data_3_days):
    """Three days with the heater never on identify no RC and fit no model (as `train` refuses
    them): the run starts with the thermostat, logs why, and refits later nights as data come."""
    idle = data_3_days.assign(u=0.0, u_phys=0.0)
    result = run_online(get_scenario(SCENARIO), idle, days=3, seed=0, out_dir=tmp_path / "run", settings=TINY)
    first = result.log[0]
    assert first["verdict"] == "initial" and first["rc"] is None and first["model"] is None
    assert "identify" in first["rc_error"] and "model_error" in first
    days = result.kpis["online"]["days"]
    assert days[0]["controller"] == "thermostat"
    # the run's data (the thermostat heating once the room, started at the data's last 23.5 C,
    # cools into the band) identify one on a later night
    assert any(e["rc"] == "rc.json" for e in result.log[1:]), result.log


@pytest.mark.slow
def test_a_heat_pumps_refits_see_its_cop_and_qp_mpc_runs_on_the_rc_alone(tmp_path):
    """A heat pump's observed intervals keep the COP the plant applied at their outdoor
    temperature (its actuator's law), so each night's RC is identified on the delivered heat as
    the data at hand's was; qp-mpc online fits no model and its own decisions are the RC's."""
    scenario = get_scenario("heat_pump_household")
    data = generate(scenario, days=1, seed=0, policy="random-level")
    result = run_online(scenario, data, days=2, seed=1, out_dir=tmp_path, settings=OnlineSettings(controller="qp-mpc"))
    observed = pd.read_csv(tmp_path / "observed.csv")
    (pump,) = scenario.sim.actuators
    assert not pump.is_ideal
    np.testing.assert_allclose(observed["cop"], pump.gain(observed["T_a"].to_numpy()), rtol=1e-6)
    assert all(e["model"] is None for e in result.log) and result.log[1]["rc"] == "rc.json"
    days = result.kpis["online"]["days"]
    assert [d["controller"] for d in days] == ["rc", "rc"]
    fallback = result.trajectory["fallback"].to_numpy()
    assert days[0]["own_decisions_share"] == pytest.approx(1.0 - fallback[: scenario.steps_per_day].mean())


def test_data_moved_by_days_that_change_their_weekdays_are_warned_about():
    """``retimed`` moves the data at hand to end right before the run by whole days; where the
    move is not a whole number of weeks, a Friday's rows become another day's, and the command
    line (``warn_weekdays``) says which; a move by whole weeks keeps every weekday and says
    nothing."""
    import warnings

    from pinn_mpc.errors import PinnMpcWarning
    from scenarios.running.online import retimed

    data = pd.DataFrame({"time": pd.date_range("2023-01-04", periods=3 * 48, freq="30min")})  # Wed-Fri
    monday = pd.Timestamp("2023-01-09")  # the run's first interval
    with pytest.warns(PinnMpcWarning, match="moved by 2 days .* a Friday, is taken as a Sunday"):
        moved = retimed(data, monday, 1800.0, warn_weekdays=True)
    assert moved["time"].iloc[-1] + pd.Timedelta(minutes=30) == monday
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        retimed(data, monday, 1800.0)  # the library's callers (a sweep's cell) are not told
        weeks = retimed(data, pd.Timestamp("2023-01-14"), 1800.0, warn_weekdays=True)  # 7 days
    assert (weeks["time"].dt.day_name() == data["time"].dt.day_name()).all()


@pytest.mark.slow
def test_ctrl_c_of_the_command_leaves_its_state_and_resume_gives_the_uninterrupted_figures(tmp_path, data_3_days):
    """`closed-loop --online` through the command line: its state goes to DIR night by night
    (the command's written-together outputs used to hold it back until the end, so a Ctrl-C
    left nothing to resume); interrupted after two nights and resumed, its KPI JSON is an
    uninterrupted command's, and no temporary file is left in DIR."""
    import _thread
    import threading
    import time

    from pinn_mpc.data import write_timeseries
    from pinn_mpc_cli.cli import INTERRUPT_EXIT, main

    data = tmp_path / "d.csv"
    write_timeseries(data_3_days, data)
    args = ["closed-loop", "--scenario", SCENARIO, "--controller", "cem", "--data", str(data), "--days", "3",
            "--seed", "0", "--online-seeds", "2", "--online-epochs", "2", "--json"]
    assert main([*args, str(tmp_path / "whole.json"), "--online", str(tmp_path / "whole")]) == 0
    run, state = [*args, str(tmp_path / "run.json"), "--online", str(tmp_path / "run")], tmp_path / "run" / "state.json"
    running = threading.Event()
    running.set()

    def interrupt_after_two_nights() -> None:  # only while the command runs
        while running.is_set():
            if state.is_file() and json.loads(state.read_text())["step"] > 48 * 2:
                _thread.interrupt_main()
                return
            time.sleep(0.01)

    watcher = threading.Thread(target=interrupt_after_two_nights, daemon=True)
    watcher.start()
    try:
        status = main(run)
        running.clear()
        watcher.join()
    except KeyboardInterrupt:  # one that came after the command had ended: it never stopped
        status = 0
    assert status == INTERRUPT_EXIT, "the command ran to its end: its state was not on disk mid-run"
    assert 48 * 2 < json.loads(state.read_text())["step"] < 48 * 4
    assert not (tmp_path / "run.json").exists() and not list((tmp_path / "run").glob(".*.tmp"))
    assert main([*run, "--resume"]) == 0
    whole, resumed = (json.loads((tmp_path / name).read_text()) for name in ("whole.json", "run.json"))
    assert _figures(resumed) == _figures(whole)
    assert not list((tmp_path / "run").glob(".*.tmp"))


@pytest.mark.slow
def test_a_planner_rebuilt_at_a_takeover_goes_on_from_the_running_plan(uninterrupted):
    """At a takeover the rebuilt planner starts from the plan the planner it replaces made at
    the step before (as one that had run on would), not from half the actuator's range; the run's
    arrays keep that plan for a resume; a thermostat carries nothing."""
    from controllers.thermostat import Thermostat
    from scenarios.running.online import _Online, _State

    out, result = uninterrupted
    with np.load(out / "loop.npz") as arrays:
        assert len(arrays["carried_plan"]) > 0  # the last takeover carried the running plan
    scenario = get_scenario(SCENARIO)
    run = prepare_run(scenario, days=3, seed=0, warmup_steps=None, weather_part="test")
    online = _Online(scenario, run, out, TINY, 0, TINY.config)
    state = _State(json.loads((out / "state.json").read_text()))
    assert state.champion is not None
    with build_loop(scenario, run, seed=0) as loop:
        online.build(state, loop)  # from the thermostat: no plan to go on from
        assert online.carried_plan is None and online.controller.last_plan is None
        plan = np.linspace(0.0, 3000.0, 48)
        online.controller.fallback.planned(plan)
        online.build(state, loop)
        assert np.array_equal(online.controller.last_plan, plan) and np.array_equal(online.carried_plan, plan)
        online.build(state, loop, carried=plan[::-1])  # a resume gives the plan its arrays kept
        assert np.array_equal(online.controller.last_plan, plan[::-1])
        online.controller = Thermostat(scenario.control_spec())
        state.champion = None
        online.build(state, loop)
        assert online.carried_plan is None


@pytest.mark.slow
def test_a_controller_built_at_a_takeover_has_seen_the_recent_past(uninterrupted):
    """A planner built at a takeover is shown the last WARM_H hours before it decides: its
    shadow RC MPC's observer and its trust monitor stand where a planner that had run on would
    (the observer at the last step, the replay errors judged), and the plant is not touched;
    at the run's first step there is nothing to show."""
    from controllers.thermostat import Thermostat
    from scenarios.running.online import WARM_H, _Online, _State

    out, result = uninterrupted
    assert all(e["warm_s"] > 0 for e in result.log if e["verdict"] != "initial")  # each takeover's
    scenario = get_scenario(SCENARIO)
    run = prepare_run(scenario, days=3, seed=0, warmup_steps=None, weather_part="test")
    online = _Online(scenario, run, out, TINY, 0, TINY.config)
    state = _State(json.loads((out / "state.json").read_text()))
    spd = scenario.steps_per_day
    with build_loop(scenario, run, seed=0) as loop:
        online.build(state, loop)
        assert online.controller.monitor.settings.recover_below_rc  # back once better than the RC
        fresh = online.controller.monitor.state
        assert not np.isfinite(fresh.replay_k) and not np.isfinite(fresh.replay_rc_k)
        thermostat = Thermostat(scenario.control_spec())
        thermostat.reset(0)
        while loop.k < run.warmup + spd // 2:
            loop.advance(thermostat)
        before = loop.record()
        online.build(state, loop)
        after = loop.record()
        assert loop.k == run.warmup + spd // 2 and np.array_equal(before.u_w, after.u_w)
        shown = online.controller
        assert shown.shadow.estimator._k_seen == loop.k - 1  # its observer is at the last step
        assert np.isfinite(shown.monitor.state.replay_k) and np.isfinite(shown.monitor.state.replay_rc_k)
        assert WARM_H * spd / 24 <= loop.k


def test_the_run_starts_where_the_data_at_hand_end(uninterrupted, data_3_days):
    """The run's building starts at the data's last state (the simulator's data: room and mass),
    not at the scenario's initial one: no jump between the data's last row and the run's first."""
    from scenarios.running.online import _start_state

    out, _ = uninterrupted
    scenario = get_scenario(SCENARIO)
    last = data_3_days.iloc[-1]
    assert _start_state(data_3_days) == (last["T_r"], last["T_m"])
    assert _start_state(data_3_days.drop(columns=["T_m"])) == (last["T_r"], last["T_r"])
    assert _start_state(None) is None
    run = prepare_run(scenario, days=3, seed=0, warmup_steps=None, weather_part="test")
    with build_loop(scenario, run, seed=0, initial_state_c=_start_state(data_3_days)) as loop:
        assert np.array_equal(loop.true_state()[0], [last["T_r"], last["T_m"]])
    first = pd.read_csv(out / "observed.csv").iloc[0]
    noise = scenario.sim.noise_std_c
    assert abs(first["T_r"] - last["T_r"]) <= 5 * noise + 1e-6  # observed.csv keeps 6 decimals
    assert abs(scenario.initial_t_r_c - last["T_r"]) > 0.5  # the scenario's own start is elsewhere


@pytest.mark.slow
def test_a_challenger_its_guard_would_hand_over_at_once_is_refused(uninterrupted, tmp_path):
    """At a takeover, a challenger that won on the held-out day but whose guard, shown the last
    hours, would hand its first decision to the RC fallback does not replace a champion its
    guard trusts; a challenger that predicts as well is swapped in as before."""
    import shutil

    from controllers.thermostat import Thermostat
    from pinn_mpc import fitted
    from scenarios.running.online import GUARD_REFUSED, _Online, _State

    out, _ = uninterrupted
    run_dir = tmp_path / "run"
    shutil.copytree(out, run_dir)
    scenario = get_scenario(SCENARIO)
    data = generate(scenario, days=14, seed=1, policy="random-level")
    parx = fitted.fit(data, arch="parx", config=replace(TINY.config, eta=scenario.sim.params.eta)).model
    for version, power_scale in (("v900", 1.0), ("v901", 3.0)):  # v901: the outdoor air weighs 3 times
        fitted.save(parx, run_dir / "versions" / version / "model")
        path = run_dir / "versions" / version / "model" / "arx.json"
        saved = json.loads(path.read_text())
        n_col = len(saved["columns"])
        for j in range(saved["lags"]):
            saved["coef"][j * n_col + saved["columns"].index("T_a")] *= power_scale
        path.write_text(json.dumps(saved))
    run = prepare_run(scenario, days=3, seed=0, warmup_steps=None, weather_part="test")
    online = _Online(scenario, run, run_dir, TINY, 0, TINY.config)
    state = _State(json.loads((run_dir / "state.json").read_text()))
    champion = "v900"
    thermostat = Thermostat(scenario.control_spec())
    thermostat.reset(0)
    with build_loop(scenario, run, seed=0) as loop:
        while loop.k < run.warmup + scenario.steps_per_day:
            loop.advance(thermostat)
        verdicts = []
        for challenger in ("v901", "v900"):
            state.champion = challenger
            state.log.append({"verdict": "swap", "version": challenger})
            online.run_verdict(state, loop, champion)
            verdicts.append((state.log[-1]["verdict"], state.champion, state.deferred, online.trusted()))
            state.deferred = None
    assert verdicts == [(GUARD_REFUSED, "v900", "v901", True), ("swap", "v900", None, True)]
    assert state.log[-1]["running"] == "v900"


class _Done:
    """A refit already finished (what ``_take_over`` reads of a worker's job)."""

    def __init__(self, entry):
        self.entry = entry

    def ready(self):
        return True

    def get(self):
        return dict(self.entry)


@pytest.mark.parametrize(("errors", "verdict", "champion"), [
    ((0.5, 0.2, 0.3), "swap", "v004"),     # the deferred one predicts the new day best: it runs
    ((0.1, 0.2, 0.3), "swap", "v007"),     # the night's challenger does better still
    ((0.5, 0.4, 0.3), "refused", "v002"),  # neither beats the champion: the deferred one is dropped
])
def test_a_challenger_the_guard_refused_is_judged_again_the_next_night(errors, verdict, champion) -> None:
    """A challenger refused by the guard is deferred, not discarded: the next night the better
    on the held-out day of it and the night's challenger is judged against the champion, and
    whatever the verdict the deferred one is not judged again (the guard may defer it anew)."""
    from types import SimpleNamespace

    from scenarios.running.online import _State, _take_over

    challenger, deferred, running = errors
    state = _State({"step": 0, "champion": "v002", "deferred": "v004", "rc": "v002", "version": 8,
                    "late_refits": 0, "log": [], "identity": {}})
    entry = {"rc": "rc.json", "model": "model", "challenger_error_c": challenger,
             "deferred_error_c": deferred, "champion_error_c": running}
    online = SimpleNamespace(run=SimpleNamespace(warmup=48), spd=48)
    _take_over((48 + 6 * 48, _Done(entry), "v007"), 48 + 6 * 48 + 6, state, online)  # type: ignore[arg-type]
    assert (state.log[-1]["verdict"], state.champion, state.deferred, state.rc) == (verdict, champion, None, "v007")
    deferred_swap = state.log[-1].get("challenger") not in (None, "v007") and verdict == "swap"
    assert deferred_swap == (errors == (0.5, 0.2, 0.3))


def test_a_refit_worker_that_does_not_start_is_reported_not_waited_for():
    """A worker that exits as it starts (its initializer here; a script that calls online
    operation without a main guard, imported again by spawn, does the same) would be started
    again for ever and the run would wait at its first refit: the pool is refused once it has
    started a few, long before its timeout (whose own message would differ), with one line
    that says what to do."""
    before = {child.pid for child in multiprocessing.active_children()}
    with pytest.raises(InputError, match=r"exited as it started \(3 times\); a script .*__main__") as caught:
        _refit_pool(initializer=sys.exit, timeout_s=600)
    assert "\n" not in str(caught.value)
    assert {child.pid for child in multiprocessing.active_children()} <= before


def test_a_refit_worker_that_hangs_is_reported_after_its_timeout():
    """A worker that starts but never answers (its initializer sleeps) is refused after the
    timeout and ended."""
    before = {child.pid for child in multiprocessing.active_children()}
    with pytest.raises(InputError, match=r"did not start within 2 s; a script .*__main__"):
        _refit_pool(initializer=functools.partial(time.sleep, 60), timeout_s=2)
    assert {child.pid for child in multiprocessing.active_children()} <= before


def test_a_run_whose_worker_does_not_start_leaves_no_folder(tmp_path, monkeypatch):
    """The run is refused before its output folder is made: no empty folder is left behind."""
    import scenarios.running.online as online

    monkeypatch.setattr(online, "_refit_pool", functools.partial(_refit_pool, initializer=sys.exit, timeout_s=2))
    out = tmp_path / "run"
    with pytest.raises(InputError, match="the refit worker process (exited as it started|did not start)"):
        run_online(get_scenario(SCENARIO), None, days=1, seed=0, out_dir=out, settings=TINY)
    assert not out.exists()


def test_the_command_says_how_many_nights_ran_without_a_model_and_why():
    """The summary line names the nights whose refit gave no model and the first one's reason
    (too few days, or the fit's own message); nothing where every night had one."""
    from pinn_mpc_cli.loop_commands import _without_model

    assert _without_model([{"night": 0, "verdict": "initial", "model": "model"}]) == ""
    few = [{"night": 0, "verdict": "initial", "model": None}, {"night": 1, "verdict": "no model", "model": None},
           {"night": 2, "verdict": "swap", "model": "model"}]
    assert _without_model(few) == f"; 2 night(s) without a model (night 0: fewer than {MODEL_DAYS} days of data)"
    later = [{"night": 3, "verdict": "no model", "model": None}]
    assert _without_model(later).endswith(f"(night 3: fewer than {MODEL_DAYS} days of data besides the held-out day)")
    failed = [{"night": 4, "verdict": "no model", "model": None, "model_error": "identify: u_phys is constant"}]
    assert _without_model(failed) == "; 1 night(s) without a model (night 4: identify: u_phys is constant)"
