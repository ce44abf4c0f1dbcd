"""A controller on a scenario: the closed loop of :mod:`scenarios.running.engine`, warm-up, KPIs.

Every control interval k runs :meth:`scenarios.running.engine.ClosedLoop.advance` (observe, forecast,
decide, step, in the do-mpc order).

The KPIs split the discomfort into the part no controller could have avoided and the rest
(:mod:`scenarios.running.kpis`), from a second run of the same days with the actuator off
(:func:`free_records`).

Warm-up: learned models need a history of at least ``depth + 1`` steps and observers need
time to settle, so every run starts with ``warmup_steps`` intervals (default one day) driven by
the thermostat. They are not counted in the KPIs nor written to the trajectory; the counted
steps are the ``days`` that follow, and observations keep the whole past, warm-up included, with
``Observation.k`` counting from the start of the warm-up.

At step k the controller gets a forecast of every future row, from k to the end of the run plus
``scenario.horizon_steps`` lead rows: perfect, or with the errors of ``scenario.forecast``
(:class:`scenarios.inputs.series.ForecastErrors`, made by the engine); they depend only on ``seed``, so
every controller sees the same forecasts.
"""

from __future__ import annotations

import contextlib
import math
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO, cast

import numpy as np
import pandas as pd
from tqdm import tqdm

from controllers.base import Controller
from controllers.thermostat import Thermostat
from pinn_mpc.actuator import ActuatorSpec, actuator_columns
from pinn_mpc.data import COLUMNS, SITE_COLUMNS, write_timeseries
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.zones import zone_columns, zone_series_columns
from scenarios.inputs.exogenous import day_span
from scenarios.inputs.registry import EXOGENOUS_COLUMNS, Scenario, check_seed
from scenarios.inputs.series import ExogenousSeries
from scenarios.plants.kinds import FleetBuildings
from scenarios.records import DayKpis, Kpis, RunKpis
from scenarios.running.engine import ClosedLoop, LoopRecord
from scenarios.running.kpis import compute_kpis

__all__ = [
    "EXTRA_COLUMNS",
    "ClosedLoopResult",
    "RunInputs",
    "Stage",
    "build_loop",
    "check_plant_supports",
    "counted_kpis",
    "day_kpis",
    "free_records",
    "one_torch_thread",
    "prepare_run",
    "progress_stage",
    "progress_steps",
    "run_closed_loop",
    "run_kpis",
    "run_trajectory",
    "write_trajectory",
]

#: Columns the trajectory adds to the data format.
EXTRA_COLUMNS = ("overridden", "fallback", "decision_ms")
_FORECAST_ERROR_STREAM = 1
_EXOGENOUS = EXOGENOUS_COLUMNS[1:]  # all but time


@dataclass(frozen=True, kw_only=True)
class ClosedLoopResult:
    """One run: ``trajectory`` has one row per counted interval (data format + EXTRA_COLUMNS,
    ``attrs['dt_s']``); ``kpis`` the KPI dict (see :mod:`scenarios.running.kpis`) plus ``controller``,
    ``scenario``, ``days``, ``seed``, ``weather_part`` and the [first, last] dates of the
    ``counted_days`` and of the ``weather_days`` (warm-up and forecast lead included), and a
    planner's trust report (:class:`scenarios.records.RunKpis`); ``errors`` one line per
    controller exception."""

    trajectory: pd.DataFrame
    kpis: RunKpis
    errors: tuple[str, ...]


@dataclass(frozen=True, kw_only=True)
class RunInputs:
    """What a run is driven by: the exogenous frame (``warmup + counted`` rows plus the
    forecast lead) and its series, and the interval counts."""

    exo: pd.DataFrame
    series: ExogenousSeries
    warmup: int
    total: int  # warm-up and counted intervals

    @property
    def counted(self) -> slice:
        return slice(self.warmup, self.total)


def prepare_run(
    scenario: Scenario, *, days: int, seed: int, warmup_steps: int | None, weather_part: str
) -> RunInputs:
    """The inputs of a run of ``days`` counted days after ``warmup_steps`` (default one day)."""
    if days < 1:
        raise ValueError(f"closed loop: days must be >= 1, got {days}")
    check_seed(seed)
    spd = scenario.steps_per_day
    warmup = spd if warmup_steps is None else warmup_steps
    if warmup < 0:
        raise ValueError(f"closed loop: warmup_steps must be >= 0, got {warmup}")
    total = warmup + days * spd
    horizon = scenario.horizon_steps
    exo = scenario.exogenous(
        days=days + math.ceil(warmup / spd), seed=seed, part=weather_part, lead_steps=horizon
    )
    if len(exo) < total + horizon:
        raise InternalError(
            f"scenario {scenario.name!r} gave {len(exo)} exogenous rows, need {total + horizon}"
        )
    exo = exo.iloc[: total + horizon].reset_index(drop=True)
    return RunInputs(exo=exo, series=ExogenousSeries.from_frame(exo), warmup=warmup, total=total)


def build_loop(
    scenario: Scenario, run: RunInputs, *, seed: int, fleet: FleetBuildings | None = None,
    initial_state_c: tuple[float, float] | None = None,
) -> ClosedLoop:
    """The engine of a run: sensor noise and forecast errors seeded by ``seed``; ``fleet``
    gives many buildings their own parameters (see :class:`ClosedLoop`); ``initial_state_c``
    the building's room and mass temperatures at the start [C] (default the scenario's)."""
    t_r, t_m = (scenario.initial_t_r_c, scenario.initial_t_m_c) if initial_state_c is None else initial_state_c
    return ClosedLoop(
        scenario.sim,
        run.series,
        spec=scenario.control_spec(),
        initial_t_r_c=t_r,
        initial_t_m_c=t_m,
        seed=seed,
        forecast_errors=scenario.forecast,
        forecast_seed=[seed, _FORECAST_ERROR_STREAM],
        expected_gains_w=scenario.gains.expected(pd.DatetimeIndex(run.exo["time"])),
        fleet=fleet,
        plant_settings=scenario.plant,
        measured_gains=scenario.plant.settings.measured_gains,
    )


def check_plant_supports(scenario: Scenario, controller: Controller) -> None:
    """Refuse, before anything runs, a controller with perfect knowledge (``oracle``,
    ``clairvoyant``) on a plant without a true state to know (EnergyPlus)."""
    if not scenario.plant.true_state and controller.knows_true_state:
        raise InputError(
            f"controller {controller.name!r} knows the plant's true RC model and state, which an "
            f"EnergyPlus building ({scenario.name!r}) does not have: the oracle and the "
            "clairvoyant do not apply; compare against the thermostat"
        )


def run_trajectory(scenario: Scenario, run: RunInputs, rec: LoopRecord) -> pd.DataFrame:
    """The counted intervals of a run in the data format, with the plant's own inputs (the
    series' rows on the RC plant, EnergyPlus's otherwise), the backup thermostat's overrides,
    the fallbacks and the decision times; no ``T_m`` where the plant has none. Each zone's
    ``T_r`` and ``T_m`` are its columns (:func:`pinn_mpc.zones.zone_column`: ``T_r`` for the
    one-zone building)."""
    series, counted, exo = run.series, run.counted, run.exo
    # The inputs the plant had: the series' rows on the RC plant, EnergyPlus's own otherwise.
    # The facades' irradiance and the wind, where the run has them, are the weather file's.
    given = {
        *_EXOGENOUS, *(c for c in SITE_COLUMNS if getattr(series, c) is not None),
        *(("holiday",) if series.holiday is not None else ()),
    }
    exogenous = tuple(c for c in COLUMNS if c in given)  # in the data format's order
    cols = {c: getattr(series, c) for c in exogenous}
    cols.update(T_a=rec.t_a_c, G=rec.g_w_per_m2, I_g=rec.i_g_w)
    trajectory = pd.DataFrame(
        {
            "time": exo["time"].iloc[counted].reset_index(drop=True),
            **zone_series_columns("T_r", rec.t_r_c[counted], rec.zones),
            **zone_series_columns("T_m", rec.t_m_c[counted], rec.zones),
            "u": rec.u_w[counted],
            "u_phys": rec.u_phys_w[counted],
            **_actuator_series(rec, counted),
            **{
                column: values
                for c in exogenous
                for column, values in zone_series_columns(c, cols[c][counted], rec.zones).items()
            },
            "overridden": rec.overridden[counted].astype(int),
            "fallback": rec.fallback[counted].astype(int),
            "decision_ms": rec.decision_s[counted] * 1000.0,
        }
    )
    if not scenario.plant.true_state:  # no true mass temperature
        trajectory = trajectory.drop(columns=list(zone_columns("T_m", rec.zones)))
    trajectory.attrs["dt_s"] = float(scenario.sim.dt_s)
    return trajectory


def _actuator_series(rec: LoopRecord, counted: slice) -> dict[str, np.ndarray]:
    """Each actuator's demanded and delivered power as its columns ``u[<name>]`` and
    ``u_phys[<name>]`` in a building of several (one actuator's are ``u`` and ``u_phys``)."""
    if len(rec.actuators) < 2 or rec.u_act_w is None or rec.u_phys_act_w is None:
        return {}
    return {
        **dict(zip(actuator_columns("u", rec.actuators), rec.u_act_w[counted].T, strict=True)),
        **dict(zip(actuator_columns("u_phys", rec.actuators), rec.u_phys_act_w[counted].T, strict=True)),
    }


def free_records(
    scenario: Scenario, run: RunInputs, *, seed: int, fleet: FleetBuildings | None = None,
    initial_state_c: tuple[float, float] | None = None,
) -> tuple[LoopRecord, ...]:
    """Each building's record of ``run`` with its actuator asked for nothing after the warm-up.

    The engine of every run (:func:`build_loop`: the same plant, weather, gains, sensor noise
    and forecast errors of ``seed``) runs the warm-up under the thermostat exactly as
    :func:`run_closed_loop` (a ``fleet``: as the fleet runs) does, so the counted days start
    from the same state, then steps every interval with the actuator off (its lower bound,
    0 W): the building free-running, its backup thermostat still acting. Its too-warm discomfort (a cooling machine: too cold) is
    the part no controller could avoid (:func:`scenarios.running.kpis.compute_kpis`);
    ``initial_state_c``: the run's start (:func:`build_loop`)."""
    spec = scenario.control_spec()
    n = 1 if fleet is None else len(fleet)
    thermostats = [Thermostat(spec) for _ in range(n)]
    for thermostat in thermostats:
        thermostat.reset(seed)
    off = np.array([a.lower_w for a in spec.actuators]) if spec.n_actuators > 1 else spec.actuator.on_off(False)
    with build_loop(scenario, run, seed=seed, fleet=fleet, initial_state_c=initial_state_c) as loop:
        for k in range(run.total):
            if k >= run.warmup:
                loop.step(off if fleet is None else np.full((n, *np.shape(off)), off))
            elif fleet is None:
                loop.advance(thermostats[0])
            else:
                loop.advance_fleet(thermostats)
        return tuple(loop.record(b) for b in range(n))


def counted_kpis(
    scenario: Scenario, run: RunInputs, rec: LoopRecord, free: LoopRecord | None = None
) -> Kpis:
    """The KPIs (:func:`scenarios.running.kpis.compute_kpis`) of one building's counted
    intervals; ``free`` is the building's record of the same run free-running
    (:func:`free_records`), whose warm-up must be ``rec``'s, None: the unavoidable
    discomfort is not computed."""
    counted, series = run.counted, run.series
    if free is not None and not np.array_equal(
        free.t_r_sub_c[: run.warmup], rec.t_r_sub_c[: run.warmup]
    ):
        raise InternalError(
            "counted_kpis: the free-running run's warm-up differs from the run's, so its "
            "discomfort bounds nothing; both must be one engine's warm-up under the thermostat "
            "with the same seed"
        )
    return compute_kpis(
        u_phys_w=rec.u_phys_w[counted],
        price_eur_per_kwh=series.price[counted],
        t_r_sub_c=rec.t_r_sub_c[counted],
        t_min_c=series.T_min[counted],
        t_max_c=series.T_max[counted],
        decision_s=rec.decision_s[counted],
        overridden=rec.overridden[counted],
        fallback=rec.fallback[counted],
        dt_s=scenario.sim.dt_s,
        comfort_weight_eur_per_kh=scenario.comfort_weight_eur_per_kh,
        free_t_r_sub_c=None if free is None else free.t_r_sub_c[counted],
        heating=_heating(rec.actuators) if rec.actuators else scenario.sim.params.heating,
        zones=rec.zones,
        u_phys_act_w=None if rec.u_phys_act_w is None else rec.u_phys_act_w[counted],
        actuator_zones=tuple(a.zone for a in rec.actuators) if rec.actuators else (0,),
    )


def day_kpis(scenario: Scenario, run: RunInputs, rec: LoopRecord) -> list[DayKpis]:
    """Per counted day of ``run`` (midnight to midnight after the warm-up): its ``objective``
    [EUR], ``discomfort_kh`` [K h] and ``own_decisions_share`` (decisions not handed to a
    fallback), each day's :func:`counted_kpis` alone."""
    spd = scenario.steps_per_day
    out: list[DayKpis] = []
    for d in range((run.total - run.warmup) // spd):
        start = run.warmup + d * spd
        day = RunInputs(exo=run.exo, series=run.series, warmup=start, total=start + spd)
        figures = counted_kpis(scenario, day, rec)
        out.append({
            "day": d + 1,
            "objective": figures["objective"],
            "discomfort_kh": figures["discomfort_kh"],
            "own_decisions_share": figures["own_decisions_share"],
        })
    return out


def _heating(actuators: Sequence[ActuatorSpec]) -> bool | None:
    """Whether a building's actuators all heat (True) or all cool (False); None: some each."""
    heats = {a.heats for a in actuators}
    return heats.pop() if len(heats) == 1 else None


def run_closed_loop(
    scenario: Scenario,
    controller: Controller,
    *,
    days: int,
    seed: int,
    warmup_steps: int | None = None,
    label: str | None = None,
    weather_part: str = "test",
    progress: bool = False,
    per_day: bool = False,
) -> ClosedLoopResult:
    """Run ``controller`` on ``scenario`` for ``days`` counted days after the warm-up.

    A thermostat drives the warm-up (not counted); then ``controller`` decides every interval.
    The same days run once more with the actuator off after the same warm-up
    (:func:`free_records`) for the discomfort no controller could have avoided
    (``discomfort_unavoidable_kh``): a few milliseconds on the RC plants, a second simulation
    on EnergyPlus (about half a second per day of the small office).

    Parameters
    ----------
    scenario
        The building, weather, price and comfort band (:func:`scenarios.get_scenario`).
    controller
        Any :class:`controllers.Controller`, e.g. from :func:`scenarios.build_controller`.
    days
        Counted days after the warm-up.
    seed
        Fixes the weather/price draw of the scenario, the sensor noise and the forecast errors,
        so two runs with the same seed see the same disturbances.
    warmup_steps
        Warm-up intervals; default one day.
    label
        Names the controller in the KPIs; default its ``name``.
    weather_part
        The part of the scenario's weather the run is drawn from: ``"test"`` (default),
        ``"train"`` or ``"whole"`` (see :mod:`scenarios.inputs.exogenous`).
    progress
        Show progress on stderr (:func:`progress_steps`).
    per_day
        Add ``per_day`` to the KPIs: each counted day's objective, discomfort and own
        decisions (:func:`day_kpis`).

    Returns
    -------
    ClosedLoopResult
        ``kpis`` (the dict of :func:`scenarios.compute_kpis` and the run's labels) and
        ``trajectory`` (one row per counted interval).
    """
    check_plant_supports(scenario, controller)
    run = prepare_run(
        scenario, days=days, seed=seed, warmup_steps=warmup_steps, weather_part=weather_part
    )
    warmup_controller = Thermostat(scenario.control_spec())
    warmup_controller.reset(seed)
    controller.reset(seed)
    errors: list[str] = []
    with build_loop(scenario, run, seed=seed) as loop:
        for k in progress_steps(run.total, label or controller.name, progress):
            decision = loop.advance(warmup_controller if k < run.warmup else controller)
            if decision.error is not None:
                errors.append(f"step {k}: {decision.error}")
        rec = loop.record()
    # The same days free-running: the discomfort no controller could have avoided.
    free = free_records(scenario, run, seed=seed)[0]
    trajectory = run_trajectory(scenario, run, rec)
    kpis = run_kpis(
        counted_kpis(scenario, run, rec, free), controller, label=label or controller.name,
        scenario=scenario.name, days=days, seed=seed, weather_part=weather_part,
        trajectory=trajectory, weather_times=run.exo["time"],
    )
    if per_day:
        kpis["per_day"] = day_kpis(scenario, run, rec)
    return ClosedLoopResult(trajectory=trajectory, kpis=kpis, errors=tuple(errors))


def run_kpis(
    kpis: Kpis,
    controller: Controller | None,
    *,
    label: str,
    scenario: str,
    days: int,
    seed: int,
    weather_part: str,
    trajectory: pd.DataFrame,
    weather_times: pd.Series,
    **extra: object,
) -> RunKpis:
    """The one record of a closed-loop run (:class:`scenarios.records.RunKpis`), of every
    plant: its counted ``kpis``, the run's labels, the [first, last] dates of the
    ``trajectory``'s counted intervals and of the weather (``weather_times``: warm-up and
    forecast lead included), ``extra`` keys of the plant's (BOPTEST's own KPIs, its period),
    then what the controller reports of its run: a planner over a learned model how often it
    fell back (``trust_report``), an RC MPC planning inside the band by its replay error how
    far (``replay_report``)."""
    record = {
        **kpis,
        "controller": label,
        "scenario": scenario,
        "days": days,
        "seed": seed,
        "weather_part": weather_part,
        "counted_days": day_span(trajectory["time"]),
        "weather_days": day_span(weather_times),
        **extra,
    }
    for name in ("trust_report", "replay_report"):
        report = getattr(controller, name, None)
        if isinstance(report, dict):
            record.update(report)
    return cast(RunKpis, record)


#: Seconds between two progress lines when stderr is not a terminal (a log file, a pipe).
PROGRESS_EVERY_S = 60.0


def progress_steps(
    total: int,
    label: str,
    progress: bool,
    *,
    unit: str = "step",
    stream: TextIO | None = None,
    clock: Callable[[], float] = time.monotonic,
    every_s: float = PROGRESS_EVERY_S,
) -> Iterable[int]:
    """``range(total)``, with progress on ``stream`` (default stderr) when ``progress``: a bar
    after a second on a terminal; otherwise (a log file, a pipe) one line every ``every_s``
    seconds of ``clock`` with the steps done and an estimate of the time left."""
    out = sys.stderr if stream is None else stream
    if not progress:
        return range(total)
    if out.isatty():
        return tqdm(range(total), desc=label, unit=unit, delay=1.0, leave=False, file=out)
    return _progress_lines(total, label, unit, out, clock, every_s)


def duration_text(seconds: float) -> str:
    """``seconds`` as ``45 s``, ``12 min`` or ``3 h 05 min``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    minutes = round(seconds / 60)
    return f"{minutes} min" if minutes < 90 else f"{minutes // 60} h {minutes % 60:02d} min"


def _progress_lines(
    total: int, label: str, unit: str, out: TextIO, clock: Callable[[], float], every_s: float
) -> Iterator[int]:
    start = last = clock()
    for k in range(total):
        yield k
        now = clock()
        if now - last >= every_s and k + 1 < total:
            last = now
            done = k + 1
            left = (now - start) / done * (total - done)
            print(
                f"{label}: {done:,} of {total:,} {unit}s ({100 * done / total:.0f} %), "
                f"{duration_text(now - start)} elapsed, about {duration_text(left)} left",
                file=out,
                flush=True,
            )


class Stage:
    """A long stage of work (:func:`progress_stage`): ``label`` says what it is, ``detail``
    what it is at now (set by the work, read by the stage's lines)."""

    def __init__(self, label: str, out: TextIO | None, clock: Callable[[], float]) -> None:
        self.label, self.detail = label, ""
        self._out, self._clock = out, clock
        self._started = clock()

    def line(self) -> str:
        """The stage's progress line now: its label, detail and the time since it started."""
        elapsed = f"{duration_text(self._clock() - self._started)} elapsed"
        return f"{self.label}: {self.detail}, {elapsed}" if self.detail else f"{self.label}: {elapsed}"

    def steps(self, total: int, unit: str) -> Iterator[int]:
        """``range(total)``, the steps done and an estimate of the time left kept in
        ``detail``; on a terminal a bar besides (as :func:`progress_steps`)."""
        steps: Iterable[int] = range(total)
        if self._out is not None and self._out.isatty():
            steps = tqdm(steps, desc=self.label, unit=unit, delay=1.0, leave=False, file=self._out)
        start = self._clock()
        for k in steps:
            if k:
                left = (self._clock() - start) / k * (total - k)
                self.detail = (
                    f"{k:,} of {total:,} {unit}s ({100 * k / total:.0f} %), about "
                    f"{duration_text(left)} left"
                )
            else:
                self.detail = f"0 of {total:,} {unit}s"
            yield k


@contextlib.contextmanager
def progress_stage(
    label: str,
    progress: bool,
    *,
    stream: TextIO | None = None,
    clock: Callable[[], float] = time.monotonic,
    every_s: float = PROGRESS_EVERY_S,
) -> Iterator[Stage]:
    """A long stage's progress on ``stream`` (default stderr) when ``progress``: ``label`` as
    it starts, then :meth:`Stage.line` every ``every_s`` seconds until it ends, from a thread
    of its own, so that a stage held up in one call (a server's warm-up, a network's
    training) is heard from too. Lines go through tqdm, which keeps a terminal's bars intact.
    Nothing is written without ``progress``."""
    if not progress:
        yield Stage(label, None, clock)
        return
    out = sys.stderr if stream is None else stream
    stage = Stage(label, out, clock)

    def write(line: str) -> None:
        tqdm.write(line, file=out)
        out.flush()

    write(label)
    ended = threading.Event()

    def beat() -> None:
        while not ended.wait(every_s):
            write(stage.line())

    beating = threading.Thread(target=beat, name=f"progress: {label}", daemon=True)
    beating.start()
    try:
        yield stage
    finally:
        ended.set()
        beating.join()


@contextlib.contextmanager
def one_torch_thread() -> Iterator[None]:
    """Planners roll out small tensors: one intra-op thread is fastest on a shared machine."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def write_trajectory(result: ClosedLoopResult, path: str | Path) -> Path:
    """The trajectory CSV: the data format's columns, then :data:`EXTRA_COLUMNS`."""
    return write_timeseries(result.trajectory, path)
