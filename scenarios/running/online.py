"""Online operation: one building's controller that refits its model and RC on its own data.

``closed-loop --online`` (:func:`run_online`). The controller starts from what a data set at
hand holds (the frame ``data``, its rows retimed to end just before the run's first interval):

- at least :data:`MODEL_DAYS` days: a model fitted on them (``fit``'s default, ``auto``) and
  planned over by ``settings.controller`` (cem), its RC fallback the model's own (with
  ``settings.controller`` the RC MPC, ``qp-mpc``, no model is ever fitted: the RC alone,
  refitted every night);
- at least one day but fewer: only the RC identified from them, driven by ``qp-mpc``;
- less than a day (or none): the thermostat;

and where a fit fails (data that do not yet determine the building, as ``train`` refuses them),
the next of these, the reason in the log.

It records every interval it observes. On the schedule (every ``retrain_every_days`` days of
service, at :data:`REFIT_HOUR` of the day, 00:00) a worker process (``multiprocessing``
``spawn``, one torch and one BLAS thread) refits, on every row so far (the data set's and
the run's, warm-up included), the RC (:func:`pinn_mpc.identify.identify_rc`) and, with at least
:data:`MODEL_DAYS` days besides the last, a challenger model on every row but the last day's.
The loop does not wait for it: the refit takes over :data:`TAKEOVER_H` simulated hours after it
started (03:00), whatever the wall time, so a seeded run makes the same decisions every time;
a worker not finished by then is waited for there and the wait counted (``late_refits``).

Champion/challenger: both models predict the held-out last day, from each of its starts that
leaves :data:`ERROR_HORIZON_STEPS` steps (12 h) inside it, on the measured power and weather;
the error is ``evaluate``'s, the mean |error| of the ensemble mean's T_r that many steps ahead.
The challenger replaces the champion only when its error is smaller (the first model, with no
champion, takes over the RC), and not when its guard, shown the last :data:`WARM_H` hours at
the takeover, would hand its first decision to the RC fallback while the champion's trusts the
champion (:data:`GUARD_REFUSED`): a model better over the held-out day can still be wrong
where the building is now. Such a challenger is deferred, not discarded: the next night it
predicts the new held-out day too, and the better of it and that night's challenger is the
one judged against the champion (a guard's verdict holds for the hours at the takeover, not
for the model). Each night is one JSON line of the log (``log.jsonl``): the data span seen,
the held-out day, the errors, the verdict and the version running after it.

A planner's guard (:mod:`controllers.trust`) hands its decisions back to the model at the first
decision within its limits where the model replays the recent hours within ``recover_ratio``
times its RC's error (:attr:`~controllers.trust.TrustSettings.recover_below_rc`, as everywhere but on BOPTEST and
over zones), not after a fixed wait: a model refitted every night, distrusted over a few night
hours, otherwise left the morning after them to an RC that predicted it worse.

The run's building starts where the data at hand end: its room at their last measured
temperature, its mass at their last ``T_m`` where they have one (a simulator's data), else at
the room's (an EnergyPlus building is warmed up at that room temperature). Started at the
scenario's initial state instead, the room jumped by up to 3 K between the data's last row and
the run's first, and the few rows across that jump weighed more in the refits' least squares
than all the others (on the small office, 7.0 of 11.9 K2 of a fortnight's one-step residuals).

State (``out_dir``): ``observed.csv`` (every interval so far in the data format, with the
trajectory's extra columns and ``own``), ``loop.npz`` (the exact demands, decision times and
flags, for the replay), ``versions/vNNN/`` (each refit's ``rc.json`` and ``model/``),
``log.jsonl`` and ``state.json``: written together, atomically, at every takeover. A run
interrupted (Ctrl-C during a refit or a day) resumes (``resume=True``) from the last takeover:
the plant is replayed on the recorded demands (same seed: the same states, sensor noise and
forecasts), the controller rebuilt from the recorded versions, and the run goes on as the
uninterrupted one did; a refit the interruption cut short runs again. The controller is
rebuilt (and reset with the run's seed) at every takeover, swap or not, which is what makes a
resumed run equal to an uninterrupted one, and shown the last :data:`WARM_H` hours of service
before it decides (``_Online.warm``).
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import signal
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from controllers.base import Controller, PlanningController
from controllers.thermostat import Thermostat
from pinn_mpc.data import COLUMNS, validate_timeseries, write_timeseries
from pinn_mpc.errors import InputError, InternalError, warn
from pinn_mpc.io import (
    atomic_write,
    atomic_write_json,
    atomic_write_text,
    written_at_once,
    written_together,
)
from pinn_mpc.training import TrainConfig
from scenarios.choices import MODEL_CONTROLLERS, ONLINE_CONTROLLERS
from scenarios.inputs.exogenous import day_span
from scenarios.inputs.registry import Scenario
from scenarios.records import RunKpis
from scenarios.running.closed_loop import (
    RunInputs,
    build_loop,
    counted_kpis,
    day_kpis,
    free_records,
    prepare_run,
    run_kpis,
    run_trajectory,
)
from scenarios.running.datagen import add_cop
from scenarios.running.engine import ClosedLoop, LoopRecord, decide
from scenarios.running.factory import check_data_fits

__all__ = [
    "ERROR_HORIZON_STEPS",
    "GUARD_REFUSED",
    "MODEL_DAYS",
    "REFIT_HOUR",
    "TAKEOVER_H",
    "WARM_H",
    "WORKER_START_S",
    "WORKER_STARTS",
    "OnlineResult",
    "OnlineSettings",
    "data_before_run",
    "night_steps",
    "run_online",
]

#: Days of data a model is fitted on at the least (fewer: the RC alone).
MODEL_DAYS = 3
#: The hour of the day a refit starts (the first interval of a day of service).
REFIT_HOUR = 0
#: Simulated hours after its start at which a refit takes over.
TAKEOVER_H = 3.0
#: Hours of service a controller built at a takeover is shown before it decides (``_Online.warm``).
WARM_H = 12.0
#: Seconds the refit worker process is given to start (import torch) before the run is refused.
WORKER_START_S = 120.0
#: Refit worker processes the pool may have started (each exiting as it started) before the
#: run is refused.
WORKER_STARTS = 3
#: Steps ahead of the champion/challenger error (``evaluate``'s horizon; 12 h at 30 min).
ERROR_HORIZON_STEPS = 24
#: The verdict on a challenger that predicted the held-out day better but whose guard would hand
#: its first decision over while the champion's trusts the champion (``_Online.run_verdict``).
GUARD_REFUSED = "refused by the guard"
_STATE, _LOG, _OBSERVED, _ARRAYS, _VERSIONS = "state.json", "log.jsonl", "observed.csv", "loop.npz", "versions"


@dataclass(frozen=True, kw_only=True)
class OnlineSettings:
    """How the online controller runs: ``controller`` plans over the model (cem or
    random-shooting) or, the RC MPC (qp-mpc), on the RC alone; it refits every
    ``retrain_every_days`` days of service, each fitting ``arch`` (default ``auto``) with
    ``config`` (its ``eta`` and ``u_max_w`` are the scenario's; ``first_seed`` the run's seed)."""

    controller: str = "cem"
    retrain_every_days: int = 1
    arch: str = "auto"
    config: TrainConfig = field(default_factory=TrainConfig)
    planner_options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.retrain_every_days < 1:  # the CLI's flag is a positive whole number
            raise ValueError(
                f"online: retrain_every_days must be a whole number of days >= 1, got "
                f"{self.retrain_every_days}"
            )
        if self.controller not in ONLINE_CONTROLLERS:
            raise InputError(
                f"online: controller {self.controller!r} does not run online; choose one of "
                f"{', '.join(ONLINE_CONTROLLERS)}"
            )

    @property
    def learns_model(self) -> bool:
        """Whether the controller plans over a model it refits (else it runs on the RC alone)."""
        return self.controller in MODEL_CONTROLLERS

    def record(self) -> dict[str, Any]:
        """The settings as JSON (what a resumed run must share)."""
        config = {k: v for k, v in asdict(self.config).items() if k != "prior"}
        return {"controller": self.controller, "retrain_every_days": self.retrain_every_days,
                "arch": self.arch, "config": config, "planner_options": dict(self.planner_options)}


@dataclass(frozen=True, kw_only=True)
class OnlineResult:
    """An online run: ``trajectory`` (counted intervals, as a closed loop's, plus ``own``),
    ``kpis`` (the closed loop's record plus ``online``: per day of service and per night),
    ``log`` (one dict per night)."""

    trajectory: pd.DataFrame
    kpis: RunKpis
    log: tuple[dict[str, Any], ...]


def night_steps(run: RunInputs, *, steps_per_day: int, every_days: int) -> list[int]:
    """The steps at which refits start: :data:`REFIT_HOUR` of every ``every_days``-th day of
    service after the first whose takeover lies inside the run."""
    takeover = _takeover_steps(run, steps_per_day)
    days = (run.total - run.warmup) // steps_per_day
    hour = REFIT_HOUR * steps_per_day // 24
    steps = [run.warmup + d * steps_per_day + hour for d in range(every_days, days, every_days)]
    return [k for k in steps if k + takeover < run.total]


def _takeover_steps(run: RunInputs, steps_per_day: int) -> int:
    return max(1, round(TAKEOVER_H * steps_per_day / 24))


def retimed(
    data: pd.DataFrame, first_time: pd.Timestamp, dt_s: float, *, warn_weekdays: bool = False
) -> pd.DataFrame:
    """``data``'s rows moved by whole days so that they end right before ``first_time`` (the
    run's first interval); its clock must agree with the run's. ``warn_weekdays``: warn when
    the move is not a whole number of weeks (the rows' weekdays then change)."""
    times = pd.to_datetime(data["time"])
    after = times.iloc[-1] + pd.Timedelta(seconds=dt_s)
    shift = first_time - after
    if shift % pd.Timedelta(days=1) != pd.Timedelta(0):
        raise InputError(
            f"online: the data set's last interval ends at {after.time()}, the run starts at "
            f"{first_time.time()}; give data whose rows end at the run's time of day (whole days "
            "from midnight, as `pinn-mpc simulate` writes)"
        )
    days = shift // pd.Timedelta(days=1)
    if warn_weekdays and days % 7:
        last = times.iloc[-1]
        warn(
            f"online: the data set's rows are moved by {days} days to end right before the run, "
            f"so its last day, a {last.day_name()}, is taken as a {(last + shift).day_name()}: a "
            "building whose schedules follow the week (an office) is learned on shifted weekdays "
            "until the run's own days replace them; give data that end right before the run, or "
            "a whole number of weeks before it"
        )
    out = data.copy()
    out["time"] = times + shift
    out.attrs = dict(data.attrs)
    return out


def data_before_run(
    scenario: Scenario, *, days: int, seed: int, policy: str, first_time: pd.Timestamp
) -> pd.DataFrame:
    """``days`` days of ``scenario``'s data under ``policy`` (seed ``seed``) for a run whose
    first interval starts at ``first_time``.

    On an EnergyPlus plant (a TMY3 window) whose run starts in its test part, days of the
    training part simulated by EnergyPlus on their own dates (their weather, weekdays and
    holidays): where the training part ends the day before ``first_time`` (the run starting
    on the test part's first day) its last ``days`` days, which :func:`retimed` leaves in
    place; where the run starts later, the ``days`` days of the training part that end a whole
    number of weeks before ``first_time``, which :func:`retimed` moves by those weeks, so that
    a weekday's rows stay a weekday's (an office's schedules follow the week). The run starts
    at their last room temperature (:func:`run_online`). Otherwise (the package's RC plants,
    or a training part too short) the scenario's usual draw of ``days`` days, which
    :func:`retimed` moves by whole days to end right before the run."""
    from scenarios.inputs.exogenous import TMY3Weather
    from scenarios.running.datagen import generate

    weather, spd = scenario.weather, scenario.steps_per_day
    if scenario.plant.true_state or not isinstance(weather, TMY3Weather):
        return generate(scenario, days=days, seed=seed, policy=policy)
    # A draw longer than the training part's core ends on its last day (TMY3Weather's rule).
    longer = generate(scenario, days=max(days, weather.training_core_days + 1), seed=seed, policy=policy)
    ends = pd.Timestamp(longer["time"].iloc[-1]) + pd.Timedelta(seconds=float(scenario.sim.dt_s))
    gap = first_time - ends
    back = (-(gap // pd.Timedelta(days=1))) % 7  # days before the part's end: a move of whole weeks
    stop = len(longer) - back * spd
    if gap < pd.Timedelta(0) or gap % pd.Timedelta(days=1) or stop < days * spd:
        return generate(scenario, days=days, seed=seed, policy=policy)
    last = longer.iloc[stop - days * spd : stop].reset_index(drop=True)
    last.attrs = dict(longer.attrs)
    return last


def _start_state(before: pd.DataFrame | None) -> tuple[float, float] | None:
    """Where the run's building starts, given the data at hand ``before`` (None: none, the
    scenario's initial state): its room at their last measured temperature and its mass at
    their last ``T_m`` where they have a finite one (a simulator's data), else at the room's."""
    if before is None or len(before) == 0:
        return None
    t_r = float(before["T_r"].iloc[-1])
    t_m = float(before["T_m"].iloc[-1]) if "T_m" in before.columns else float("nan")
    return t_r, t_m if np.isfinite(t_m) else t_r


def _fit_frame(frames: list[pd.DataFrame], dt_s: float) -> pd.DataFrame:
    columns = [c for c in COLUMNS if all(c in f.columns for f in frames)]
    df = pd.concat([f[columns] for f in frames], ignore_index=True)
    df.attrs["dt_s"] = dt_s
    return df


def _worker_init() -> None:
    """The refit worker: one torch thread and one BLAS/OpenMP thread (the run's decisions keep
    the other core of a 2-core machine to themselves), Ctrl-C left to the run (which ends the
    worker)."""
    import torch
    from threadpoolctl import threadpool_limits

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    torch.set_num_threads(1)
    threadpool_limits(1)


def _refit_pool(initializer: Any = None, timeout_s: float | None = None) -> Any:
    """The refit worker (a ``spawn`` pool of one process, ``initializer`` by default
    :func:`_worker_init`), once it has answered: a worker that exits as it starts (its pool
    would start it again and again, and the run would wait at its first refit for ever) is
    reported once the pool has started :data:`WORKER_STARTS` of them, and one that does not
    answer within ``timeout_s`` (default :data:`WORKER_START_S`) is reported then."""
    limit = WORKER_START_S if timeout_s is None else timeout_s
    context = multiprocessing.get_context("spawn")
    others = {child.pid for child in multiprocessing.active_children()}
    pool = context.Pool(1, initializer=_worker_init if initializer is None else initializer)
    answer, started, workers = pool.apply_async(os.getpid), time.monotonic(), set()
    try:
        while not answer.ready():
            workers |= {child.pid for child in multiprocessing.active_children()} - others
            if len(workers) >= WORKER_STARTS or time.monotonic() - started >= limit:
                break
            answer.wait(0.1)
        answer.get(0)
    except BaseException as exc:
        pool.terminate()
        pool.join()
        if isinstance(exc, multiprocessing.TimeoutError):
            how = (f"exited as it started ({len(workers)} times)" if len(workers) >= WORKER_STARTS
                   else f"did not start within {limit:g} s")
            raise InputError(
                f"online: the refit worker process {how}; a script that runs online operation "
                "must call it under `if __name__ == \"__main__\":` (the worker is started with "
                "multiprocessing's spawn, which imports the script again)"
            ) from None
        raise
    return pool


def _held_out_error(model: Any, frame: pd.DataFrame, cut: int) -> float:
    """``evaluate``'s T_r error :data:`ERROR_HORIZON_STEPS` ahead from every start in rows
    ``cut ..`` that keeps the target inside the frame (module docstring)."""
    from pinn_mpc.evaluation import t_r_ahead

    h = ERROR_HORIZON_STEPS
    pred, starts = t_r_ahead(model, frame, h, cut)
    return float(np.mean(np.abs(pred - frame["T_r"].to_numpy(dtype=float)[starts + h])))


def _refit(
    frame: pd.DataFrame, *, dt_s: float, steps_per_day: int, arch: str, config: TrainConfig,
    champion: str | None, version_dir: str, with_model: bool, hold_out: bool = True,
    deferred: str | None = None,
) -> dict[str, Any]:
    """One refit (in the worker): the RC on every row, a challenger (``with_model``) on every
    row but the last day's and the held-out errors on that day of it, the champion and the
    ``deferred`` challenger (``hold_out``; else the model on every row, unjudged: the initial
    version); written into ``version_dir`` (through a temporary sibling renamed at the end)."""
    from pinn_mpc import fitted
    from pinn_mpc.identify import identify_rc
    from pinn_mpc.physics import rc_summary

    started = time.perf_counter()
    frame.attrs["dt_s"] = dt_s
    frame = validate_timeseries(frame, source="online data")
    target = Path(version_dir)
    tmp = target.with_name(f".{target.name}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    record: dict[str, Any] = {"rows": len(frame), "data_span": [str(frame["time"].iloc[0]),
                              str(frame["time"].iloc[-1])]}
    try:
        rc = identify_rc(frame, eta=config.eta)
    except InputError as exc:
        record["rc"] = None
        record["rc_error"] = str(exc)
    else:
        summary = dict(rc_summary(rc.params, source="online refit"))
        summary["fit"] = rc.fit_statistics()
        (tmp / "rc.json").write_text(json.dumps(summary, indent=2))
        record["rc"] = "rc.json"
    record.update(model=None, family=None, challenger_error_c=None, champion_error_c=None,
                  deferred_error_c=None)
    cut = len(frame) - steps_per_day if hold_out else len(frame)  # the held-out day's first row
    fitted_on = frame.iloc[:cut].reset_index(drop=True)
    fitted_on.attrs["dt_s"] = dt_s
    choice = None
    if with_model:
        try:  # data that do not yet determine the building: no model this night, as train says
            choice = fitted.fit(fitted_on, arch=arch, config=config)
        except InputError as exc:
            record["model_error"] = str(exc)
    if choice is not None:
        fitted.save(choice.model, tmp / "model")
        record.update(model="model", family=choice.chosen)
    if choice is not None and hold_out:
        record.update(
            held_out_day=[str(frame["time"].iloc[cut]), str(frame["time"].iloc[-1])],
            fitted_span=[str(fitted_on["time"].iloc[0]), str(fitted_on["time"].iloc[-1])],
            challenger_error_c=_held_out_error(choice.model, frame, cut),
        )
        if champion is not None:
            record["champion_error_c"] = _held_out_error(fitted.load(champion), frame, cut)
        if deferred is not None:
            record["deferred_error_c"] = _held_out_error(fitted.load(deferred), frame, cut)
    record["wall_s"] = time.perf_counter() - started
    record["load_1min"] = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    shutil.rmtree(target, ignore_errors=True)
    tmp.rename(target)
    return record


class _State:
    """What ``state.json`` holds: the step of the last takeover, the versions running, the
    nights so far and the waits."""

    def __init__(self, raw: Mapping[str, Any]) -> None:
        self.step: int = int(raw["step"])
        self.champion: str | None = raw["champion"]
        self.deferred: str | None = raw.get("deferred")  # a challenger the guard refused
        self.rc: str | None = raw["rc"]
        self.version: int = int(raw["version"])
        self.late_refits: int = int(raw["late_refits"])
        self.log: list[dict[str, Any]] = list(raw["log"])
        self.identity: dict[str, Any] = dict(raw["identity"])

    def raw(self) -> dict[str, Any]:
        return {"step": self.step, "champion": self.champion, "deferred": self.deferred,
                "rc": self.rc, "version": self.version,
                "late_refits": self.late_refits, "log": self.log, "identity": self.identity}


class _Online:
    """The running state of :func:`run_online`: the loop, the controller, the recorded flags."""

    def __init__(self, scenario: Scenario, run: RunInputs, out: Path, settings: OnlineSettings,
                 seed: int, config: TrainConfig) -> None:
        self.scenario, self.run, self.out, self.settings, self.seed = scenario, run, out, settings, seed
        self.config = config
        self.spd = scenario.steps_per_day
        self.own = np.zeros(run.total, dtype=bool)
        self.mode = np.full(run.total, "", dtype=object)
        self.controller: Controller = Thermostat(scenario.control_spec())
        self.kind = "thermostat"
        self.carried_plan: np.ndarray | None = None  # the plan the running planner started from
        self.warm_s = 0.0  # wall time of the last build's warming [s]

    def path(self, version: str | None, name: str) -> str | None:
        return None if version is None else str(self.out / _VERSIONS / version / name)

    def build(self, state: _State, loop: ClosedLoop, carried: np.ndarray | None = None) -> None:
        """The controller of the versions running: a model's planner, the RC's qp-mpc, or the
        thermostat; reset with the run's seed, then shown what it would have seen over the last
        :data:`WARM_H` hours of service (:meth:`warm`). A planner goes on from the plan the
        controller it replaces made at the last step (``carried``, else that controller's, as
        :attr:`carried_plan` keeps it): a planner rebuilt at a takeover decides as one that
        had run on, where a planner started without a plan samples around half the actuator's
        range at first."""
        from scenarios.running.factory import build_controller

        if carried is None:
            carried = getattr(self.controller, "last_plan", None)

        scenario, n = self.scenario, self.run.total - self.run.warmup
        if state.champion is not None:
            from pinn_mpc import fitted

            model = fitted.load(self.path(state.champion, "model") or "")
            self.controller = build_controller(
                self.settings.controller, scenario, model=model, n_steps=n,
                planner_options=dict(self.settings.planner_options),
            )
            self.kind = "model"
        elif state.rc is not None:
            from pinn_mpc.physics import read_rc_json

            params, _ = read_rc_json(self.path(state.rc, "rc.json") or "")
            self.controller = build_controller("qp-mpc", scenario, rc_params=params, n_steps=n)
            self.kind = "rc"
        else:
            self.controller, self.kind = Thermostat(scenario.control_spec()), "thermostat"
        self.controller.reset(self.seed)
        self.warm_s = self.warm(loop)
        self.carried_plan = None
        if carried is not None and self.kind == "model" and isinstance(self.controller, PlanningController):
            self.carried_plan = np.asarray(carried, dtype=float)  # a copy already: last_plan's, or read
            self.controller.fallback.planned(self.carried_plan)  # a plan is replaced, never changed

    def warm(self, loop: ClosedLoop) -> float:
        """Show a controller just built (an MPC's observer, a planner's offset filter, shadow
        RC MPC and trust monitor) the observations and forecasts of the last :data:`WARM_H`
        hours of service, its actions discarded: it takes over with its estimates settled and
        its trust judged on the recent past, as one that had run on (built fresh, the shadow
        RC MPC's observer starts with the mass at the room's temperature, and the monitor
        judges the model on its first replay alone). The recorded past is the same on a resume,
        so a resumed run warms the same way. Returns its wall time [s]: the decision at the
        takeover waits for it."""
        started = time.perf_counter()
        if self.kind != "thermostat":
            first = max(0, loop.k - round(WARM_H * self.spd / 24.0))
            for j in range(first, loop.k):
                decide(self.controller, loop.observation(at=j), loop.forecast(at=j), loop.spec)
        return time.perf_counter() - started

    def trusted(self) -> bool:
        """Whether the controller's guard, after its warming, lets its model decide (True
        without a guard)."""
        monitor = getattr(self.controller, "monitor", None)
        return monitor is None or bool(monitor.state.trusted)

    def run_verdict(self, state: _State, loop: ClosedLoop, previous: str | None) -> None:
        """Build the controller of the versions the night's verdict (``state.log[-1]``) left
        running, ``previous`` the champion before it. A challenger that won on the held-out day
        but whose guard, shown the last :data:`WARM_H` hours (:meth:`warm`), would hand its
        first decision to the RC fallback while the champion's trusts the champion, is refused
        (:data:`GUARD_REFUSED`), deferred to the next night, and the champion runs on; where
        neither is trusted the challenger runs. Logs the wall time of the warmings (``warm_s``)
        and the version running after the verdict (``running``)."""
        carried = getattr(self.controller, "last_plan", None)
        entry = state.log[-1]
        self.build(state, loop, carried)
        warm_s = self.warm_s
        if entry["verdict"] == "swap" and previous is not None and not self.trusted():
            challenger, state.champion = state.champion, previous
            self.build(state, loop, carried)
            warm_s += self.warm_s
            if self.trusted():
                entry["verdict"] = GUARD_REFUSED
                state.deferred = challenger
            else:
                state.champion = challenger
                self.build(state, loop, carried)
                warm_s += self.warm_s
        entry["warm_s"] = warm_s
        entry["running"] = state.champion

    def advance(self, loop: ClosedLoop, k: int, warmup: Thermostat) -> None:
        if k < self.run.warmup:
            loop.advance(warmup)
            self.mode[k] = "warm-up"
            return
        monitor = getattr(self.controller, "monitor", None)
        before = monitor.state.fallback_steps if monitor is not None else 0
        decision = loop.advance(self.controller)
        after = monitor.state.fallback_steps if monitor is not None else 0
        own_kind = "model" if self.settings.learns_model else "rc"
        self.own[k] = self.kind == own_kind and after == before and not decision.fallback
        self.mode[k] = self.kind

    def observed(self, loop: ClosedLoop) -> pd.DataFrame:
        """The run's intervals so far as the data format holds them for a refit: the loop's
        trajectory, its ``I_g`` the gains the controller observed (none where it is given
        none, as :func:`~scenarios.running.datagen.generate`'s data), the heat pump's COP and
        ``own`` (the decisions the controller made itself)."""
        k = loop.k
        sofar = RunInputs(exo=self.run.exo, series=self.run.series, warmup=0, total=k)
        frame = run_trajectory(self.scenario, sofar, loop.record())
        # The gains as the controller saw them, where it sees any (a simulated data set's rule):
        # a model fitted on gains it is never given would plan without them.
        if self.scenario.gains_given:
            frame["I_g"] = loop.observed_gains_w()
        else:
            frame = frame.drop(columns="I_g", errors="ignore")
        add_cop(self.scenario, frame)  # a heat pump's: its refits fit on the delivered heat
        frame["own"] = self.own[:k].astype(int)
        return frame

    def checkpoint(self, loop: ClosedLoop, state: _State) -> None:
        """Everything so far, written together (each file atomically) and on disk when this
        returns, even inside a caller's :func:`~pinn_mpc.io.written_together` block (the
        command's outputs): a run interrupted later resumes from here."""
        rec, k = loop.record(), loop.k
        state.step = k
        with written_at_once(), written_together():
            write_timeseries(self.observed(loop), self.out / _OBSERVED)
            atomic_write(self.out / _ARRAYS, lambda tmp: _save_arrays(
                tmp, rec, self.own[:k], self.mode[:k], self.carried_plan))
            atomic_write_text(self.out / _LOG, "".join(json.dumps(e) + "\n" for e in state.log))
            atomic_write_json(self.out / _STATE, state.raw())


def _save_arrays(
    tmp: Path, rec: LoopRecord, own: np.ndarray, mode: np.ndarray, carried: np.ndarray | None
) -> None:
    with open(tmp, "wb") as f:
        np.savez(f, u_w=rec.u_w, decision_s=rec.decision_s, fallback=rec.fallback, own=own,
                 mode=mode.astype(str), carried_plan=np.array([]) if carried is None else carried)


def run_online(
    scenario: Scenario,
    data: pd.DataFrame | None,
    *,
    days: int,
    seed: int,
    out_dir: str | Path,
    settings: OnlineSettings = OnlineSettings(),
    resume: bool = False,
    weather_part: str = "test",
    warn_weekdays: bool = False,
) -> OnlineResult:
    """Run the online controller (module docstring) for ``days`` days of service after a
    one-day warm-up under the thermostat, keeping its state in ``out_dir``.

    ``data``: the validated data set at hand (None: none); ``resume``: continue the run
    ``out_dir`` holds (the same scenario, days, seed, settings and data), else ``out_dir`` must
    hold no run; ``warn_weekdays``: warn when ``data`` are moved by days that change their
    weekdays (:func:`retimed`). Raises InputError on a mismatch, and on data of another
    building (:func:`~scenarios.running.factory.check_data_fits`)."""
    zones = scenario.control_spec().zones
    if len(zones) > 1:  # what the sweep refuses too: its refits fit one zone
        raise InputError(
            f"online: runs on buildings of one zone (the RC plants or EnergyPlus merged); "
            f"{scenario.name!r} has {len(zones)} zones: run it without online operation"
        )
    if data is not None:
        check_data_fits(data, scenario)
    out = Path(out_dir)
    run = prepare_run(scenario, days=days, seed=seed, warmup_steps=None, weather_part=weather_part)
    spd, dt_s = scenario.steps_per_day, float(scenario.sim.dt_s)
    first = pd.Timestamp(run.exo["time"].iloc[0])
    before = None if data is None or len(data) == 0 else retimed(data, first, dt_s, warn_weekdays=warn_weekdays)
    config = replace(settings.config, eta=scenario.sim.params.eta, first_seed=seed,
                     u_max_w=scenario.control_spec().actuator.upper_w)
    identity = {
        "scenario": scenario.name, "days": days, "seed": seed, "weather_part": weather_part,
        "settings": settings.record(), "data_rows": 0 if before is None else len(before),
        "data_span": None if before is None else day_span(before["time"]),
    }
    online = _Online(scenario, run, out, settings, seed, config)
    nights = night_steps(run, steps_per_day=spd, every_days=settings.retrain_every_days)
    takeover = _takeover_steps(run, spd)
    state_file = out / _STATE
    if resume:
        if not state_file.is_file():
            raise InputError(f"online: {out} holds no run to resume ({_STATE} missing); start it without resume")
        state = _State(json.loads(state_file.read_text()))
        if state.identity != json.loads(json.dumps(identity)):
            raise InputError(
                f"online: {out} holds another run ({state.identity}); resume it with the same "
                "scenario, days, seed, settings and data, or give another folder"
            )
    else:
        if state_file.exists():
            raise InputError(f"online: {out} already holds a run; resume it or give another folder")
        state = _State({"step": 0, "champion": None, "rc": None, "version": 0, "late_refits": 0,
                        "log": [], "identity": identity})
    pool = _refit_pool()  # before the folder: a worker that does not start leaves nothing behind
    out.mkdir(parents=True, exist_ok=True)
    try:
        with build_loop(scenario, run, seed=seed, initial_state_c=_start_state(before)) as loop:
            carried = None
            if resume:
                carried = _replay(loop, online, out, state.step)
            elif before is not None:  # version 0: what the data at hand holds, before the run
                n_days = len(before) // spd
                entry = pool.apply(_refit, (_fit_frame([before], dt_s),), dict(
                    dt_s=dt_s, steps_per_day=spd, arch=settings.arch, config=config, champion=None,
                    version_dir=str(out / _VERSIONS / "v000"),
                    with_model=settings.learns_model and n_days >= MODEL_DAYS,
                    hold_out=False,
                )) if n_days >= 1 else None
                if entry is not None:
                    state.rc = "v000" if entry["rc"] else None
                    state.champion = "v000" if entry.get("model") else None
                    state.log.append({"night": 0, "step": 0, "version": "v000", "verdict": "initial", **entry})
                state.version = 1
            online.build(state, loop, carried)
            online.checkpoint(loop, state)
            warmup = Thermostat(scenario.control_spec())
            warmup.reset(seed)
            pending: tuple[int, Any, str] | None = None
            for k in range(state.step, run.total):
                if k in nights and pending is None:
                    version = f"v{state.version:03d}"
                    state.version += 1
                    frames = [f for f in (before, online.observed(loop)) if f is not None]
                    frame = _fit_frame(frames, dt_s)
                    with_model = settings.learns_model and len(frame) // spd - 1 >= MODEL_DAYS
                    pending = (k, pool.apply_async(_refit, (frame,), dict(
                        dt_s=dt_s, steps_per_day=spd, arch=settings.arch, config=config,
                        champion=online.path(state.champion, "model"),
                        deferred=online.path(state.deferred, "model"),
                        version_dir=str(out / _VERSIONS / version), with_model=with_model,
                    )), version)
                if pending is not None and k == pending[0] + takeover:
                    previous = state.champion
                    _take_over(pending, k, state, online)
                    pending = None
                    online.run_verdict(state, loop, previous)
                    online.checkpoint(loop, state)
                online.advance(loop, k, warmup)
            online.checkpoint(loop, state)
            rec = loop.record()
    except BaseException:  # Ctrl-C or an error: a refit under way is abandoned (rerun on resume)
        pool.terminate()
        pool.join()
        raise
    pool.close()  # every refit started was taken over: the worker is idle
    pool.join()
    return _result(scenario, run, rec, online, state, days=days, seed=seed, weather_part=weather_part,
                   initial_state_c=_start_state(before))


def _take_over(pending: tuple[int, Any, str], k: int, state: _State, online: _Online) -> None:
    """The refit started at ``pending[0]`` takes over at step ``k``: waited for if late
    (counted), the RC replaced, the challenger judged (the better on the held-out day of the
    night's and a deferred one, against the champion); one log entry."""
    started, job, version = pending
    late = not job.ready()
    state.late_refits += int(late)
    entry = job.get()
    if entry["rc"]:
        state.rc = version
    verdict = "no model"
    if entry["model"]:
        candidate, error = version, entry["challenger_error_c"]
        deferred_error = entry.get("deferred_error_c")
        if state.deferred is not None and deferred_error is not None and deferred_error < error:
            candidate, error = state.deferred, deferred_error
        champion = entry["champion_error_c"]
        if champion is None or error < champion:
            verdict = "swap"
            state.champion = candidate
        else:
            verdict = "refused"
        entry["challenger"] = candidate
    state.deferred = None  # judged this night: it runs, or another did better
    day = (started - online.run.warmup) // online.spd
    state.log.append({"night": day, "step": started, "takeover_step": k, "version": version,
                      "verdict": verdict, "late": late, **entry})


def _replay(loop: ClosedLoop, online: _Online, out: Path, steps: int) -> np.ndarray | None:
    """The plant stepped again on the recorded demands up to ``steps`` (resume); the plan the
    planner running then started from (None: none was carried over)."""
    with np.load(out / _ARRAYS) as arrays:
        u, decision_s, fallback = arrays["u_w"], arrays["decision_s"], arrays["fallback"]
        online.own[:steps], online.mode[:steps] = arrays["own"][:steps], arrays["mode"][:steps]
        carried = arrays["carried_plan"] if "carried_plan" in arrays.files else np.array([])
    if len(u) < steps:
        raise InternalError(f"online: {_ARRAYS} holds {len(u)} steps, the state says {steps}")
    for k in range(steps):
        loop.step(float(u[k]), decision_s=float(decision_s[k]), fallback=bool(fallback[k]))
    return carried if len(carried) else None


def _result(scenario: Scenario, run: RunInputs, rec: LoopRecord, online: _Online, state: _State,
            *, days: int, seed: int, weather_part: str,
            initial_state_c: tuple[float, float] | None) -> OnlineResult:
    """The closed loop's record of the run, with ``online``: per day of service its
    objective, discomfort, own decisions, the running model's error on it (judged the night
    after) and the nights' verdicts."""
    free = free_records(scenario, run, seed=seed, initial_state_c=initial_state_c)[0]
    trajectory = run_trajectory(scenario, run, rec)
    trajectory["own"] = online.own[run.counted].astype(int)
    kpis = run_kpis(
        counted_kpis(scenario, run, rec, free), None, label=f"online {online.settings.controller}",
        scenario=scenario.name, days=days, seed=seed, weather_part=weather_part,
        trajectory=trajectory, weather_times=run.exo["time"],
    )
    errors = {e["night"]: e["champion_error_c"] for e in state.log if e.get("night")}
    per_day = []
    for figures in day_kpis(scenario, run, rec):
        start = run.warmup + (figures["day"] - 1) * online.spd
        modes = list(online.mode[start : start + online.spd])
        per_day.append({
            **figures,
            "own_decisions_share": float(np.mean(online.own[start : start + online.spd])),
            "controller": max(set(modes), key=modes.count),
            "model_day_ahead_error_c": errors.get(figures["day"]),
        })
    kpis["online"] = {  # type: ignore[typeddict-unknown-key]
        "days": per_day,
        "swaps": sum(e["verdict"] == "swap" for e in state.log),
        "refusals": sum(e["verdict"] == "refused" for e in state.log),
        "guard_refusals": sum(e["verdict"] == GUARD_REFUSED for e in state.log),
        "deferred_swaps": sum(e["verdict"] == "swap" and e.get("challenger") not in (None, e["version"])
                              for e in state.log),
        "late_refits": state.late_refits,
        "own_decisions_share": float(np.mean(online.own[run.counted])),
        "refit_wall_s": [round(e["wall_s"], 3) for e in state.log if "wall_s" in e],
    }
    kpis["own_decisions_share"] = float(np.mean(online.own[run.counted]))
    return OnlineResult(trajectory=trajectory, kpis=kpis, log=tuple(state.log))

