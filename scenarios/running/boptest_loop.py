"""The package's controllers and data policies on a BOPTEST test case.

A BOPTEST scenario is a scenario file with a ``[boptest]`` table (the built-in
``boptest_hydronic_heat_pump``; :mod:`scenarios.plants.boptest`). Its controllers get the
control spec of :func:`boptest_scenario`: the actuator's limit is the electrical power at the
test case's highest signal (``points.scaling.max_power_w``), the interval is the run's.

:func:`run_boptest_closed_loop` selects the plant first (BOPTEST's test period, price scenario
and warm-up), then runs the one loop engine on the plant's ``/forecast`` inputs, with no
warm-up of the package's own (BOPTEST's warm-up sets the state): every interval is counted.
The KPIs are the package's, plus ``boptest``, BOPTEST's own KPI dict from ``/kpi``, read
before the test stops. ``boptest-baseline`` runs the test case's own controller (no input
overwritten): the reference BOPTEST tables are read against. Given a test
(``test=``), the loop re-starts that test at the period's start instead of selecting one:
:func:`run_boptest_comparison` selects one test and runs every row on it.

:func:`boptest_data` records training data under the package's data policies on days of the
year disjoint from every test period and its warm-up (refused where they would overlap).
"""

from __future__ import annotations

import dataclasses
import os
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TypeAlias, cast

import numpy as np
import pandas as pd

from controllers.base import Controller
from controllers.thermostat import Thermostat
from controllers.trust import TrustSettings
from pinn_mpc.choices import ARX, AUTO, COMPARED_ARCHS, MODEL_CHOICES, PHYSICS_ARX
from pinn_mpc.errors import InputError, setting
from pinn_mpc.physics import RCParams
from scenarios.choices import MODEL_CONTROLLERS, POLICIES
from scenarios.inputs.exogenous import day_span
from scenarios.inputs.registry import Scenario, builtin_scenario, check_seed
from scenarios.inputs.series import ExogenousSeries
from scenarios.plants.boptest import (
    BUILTIN_BOPTEST,
    SECONDS_PER_DAY,
    BoptestPlant,
    BoptestRun,
    BoptestSettings,
    boptest_file,
    builtin_boptest,
    read_boptest_file,
    record_data,
)
from scenarios.plants.boptest_client import BoptestClient, BoptestTest
from scenarios.records import RunKpis
from scenarios.running.closed_loop import (
    ClosedLoopResult,
    RunInputs,
    counted_kpis,
    progress_stage,
    run_kpis,
    run_trajectory,
)
from scenarios.running.datagen import SetpointPolicy
from scenarios.running.engine import ClosedLoop
from scenarios.running.factory import FitChecks

if TYPE_CHECKING:
    from controllers.sampling import Guard
    from pinn_mpc.models.rollout import BatchDynamics, FittedModel
    from pinn_mpc.training import TrainConfig

#: What :func:`boptest_fit` returns: a fitted model of any family or an identified RC.
BoptestModel: TypeAlias = "FittedModel | RCParams"

__all__ = [
    "BASELINE",
    "CEM_FAMILIES",
    "DATA_FIRST_DAY",
    "COMPARED_KPIS",
    "RC_FIT",
    "BoptestComparison",
    "BoptestModel",
    "BoptestScenario",
    "boptest_controller",
    "boptest_guard",
    "boptest_data",
    "boptest_fit",
    "boptest_planner",
    "boptest_scenario",
    "boptest_report",
    "is_boptest_scenario",
    "run_boptest_closed_loop",
    "run_boptest_comparison",
]

#: The controller name of BOPTEST's baseline: the test case's own controller.
BASELINE = "boptest-baseline"
#: The first day of the year [d] of training data by default: the end of the earliest test
#: period of the built-in case (peak_heat_day: days 16-30), in its heating season.
DATA_FIRST_DAY = 30.0
#: The setpoints of the ``closed-loop`` data policy on BOPTEST [C]: the occupied comfort band
#: (21-24 C) widened by 3 K below and 1 K above, where controllers keep the room.
DATA_SETPOINTS_C = (18.0, 25.0)
#: The built-in scenario whose objective (comfort weight, horizon) BOPTEST scenarios share.
_OBJECTIVE_OF = "paper_household"
_POLICY_STREAM = 11


@dataclass(frozen=True, kw_only=True)
class BoptestScenario:
    """A BOPTEST scenario: its ``name`` (the built-in's or the file's), the ``settings`` of its
    ``[boptest]`` table and the ``path`` of its file."""

    name: str
    settings: BoptestSettings
    path: Path

    def scenario(self, dt_s: float) -> Scenario:
        """The package's scenario its controllers are built on at interval ``dt_s`` [s]: the
        actuator's limit is the test case's electrical power at its highest signal; the comfort
        weight is the ``[boptest]`` table's; the horizon is one day."""
        base = builtin_scenario(_OBJECTIVE_OF)
        sim = dataclasses.replace(
            base.sim, u_max_w=self.settings.points.scaling.max_power_w, dt_s=float(dt_s),
            substep_s=30.0,
        )
        return dataclasses.replace(
            base, name=self.name,
            description=f"BOPTEST test case {self.settings.points.testcase}",
            sim=sim, horizon_steps=int(round(86400.0 / dt_s)),
            comfort_weight_eur_per_kh=self.settings.comfort_weight_eur_per_kh,
        )

    def check_server(self) -> None:
        """Ask the scenario's server its version (:meth:`BoptestClient.probe`): a server that
        is not there or does not answer is one clear error before any work starts."""
        with closing(BoptestClient(self.settings.url, timeout_s=self.settings.timeout_s)) as client:
            client.probe()


def is_boptest_scenario(name_or_path: str) -> bool:
    """True when ``--scenario`` names a built-in BOPTEST scenario or a TOML file with a
    ``[boptest]`` table."""
    return boptest_file(name_or_path) is not None


def boptest_scenario(name_or_path: str, *, url: str | None = None) -> BoptestScenario:
    """The BOPTEST scenario ``--scenario`` names; ``url`` (if given) replaces the server of
    the file (else the file's, else ``$BOPTEST_URL``, else the local default)."""
    if name_or_path in BUILTIN_BOPTEST:
        settings, path, name = builtin_boptest(name_or_path), BUILTIN_BOPTEST[name_or_path], name_or_path
    else:
        settings, path, name = read_boptest_file(name_or_path), Path(name_or_path), Path(name_or_path).stem
    if url is not None:
        settings = dataclasses.replace(settings, url=url)
    return BoptestScenario(name=name, settings=settings, path=path)


#: How a model or RC file is checked on a BOPTEST scenario: its data may reach 1.5 x the
#: actuator's limit (the curve's top, measured at 1-2 C outdoors), since the emulator's heat
#: pump draws more at full signal on colder days and its own data exceed the limit (a margin
#: chosen, not measured: data half as large again are another building's); no time constants
#: to compare (the test case has no RC parameters).
BOPTEST_FIT_CHECKS = FitChecks(power_slack=1.5, true_building=False)


#: The trust settings of every MPC on BOPTEST: it plans inside the band by its replay error
#: (:attr:`controllers.trust.TrustSettings.margin_from_replay`); a distrusted model drives again
#: after the fixed wait only (``recover_below_rc`` off: the BOPTEST pages were measured so).
BOPTEST_TRUST = TrustSettings(margin_from_replay=True, recover_below_rc=False)


def boptest_guard(model: BatchDynamics) -> Guard:
    """The fallback of a planner over ``model`` on BOPTEST: the RC and ranges of
    :func:`scenarios.running.factory.model_guard`, and a comfort margin from the model's replay error as well as its one-step
    error (:attr:`controllers.trust.TrustSettings.margin_from_replay`): BOPTEST measures the
    zone temperature without noise, so the replayed hours' error is the model's own, and a
    plan that rides the band's edge hours ahead misses it by that much."""
    from scenarios.running.factory import model_guard

    return model_guard(model)._replace(settings=BOPTEST_TRUST)


def boptest_rc_mpc(name: str, scenario: Scenario, rc_params: RCParams, *, n_steps: int) -> Controller:
    """The MPC ``name`` (``qp-mpc``, ``casadi-mpc``) on ``rc_params`` for ``scenario``, planning
    inside the band by its RC's own filtered replay error, as a guarded planner's fallback
    does here (:data:`BOPTEST_TRUST`,
    :meth:`controllers.rc_mpc.problem.RCMPC.plan_with_replay_margin`): BOPTEST measures the
    zone without noise, and an MPC that rides the band's edge misses it by its RC's error."""
    from scenarios.running.factory import build_controller

    return _with_replay_margin(build_controller(name, scenario, rc_params=rc_params, n_steps=n_steps))


def _with_replay_margin(controller: Controller) -> Controller:
    """``controller``, set to plan inside the band by its RC's replay error if it is an MPC
    on an RC estimating its state (:func:`boptest_rc_mpc`)."""
    from controllers.rc_mpc.problem import RCMPC

    if isinstance(controller, RCMPC) and not controller.knows_true_state:
        controller.plan_with_replay_margin(BOPTEST_TRUST)
    return controller


def boptest_controller(
    name: str,
    chosen: BoptestScenario,
    *,
    dt_s: float,
    model_dir: str | os.PathLike[str] | None,
    rc_path: str | os.PathLike[str] | None,
    n_steps: int,
) -> Controller | None:
    """The controller ``name`` on ``chosen`` at interval ``dt_s`` [s] (as
    :func:`scenarios.running.factory.make_controller` builds it on
    :meth:`BoptestScenario.scenario`); None for :data:`BASELINE`.

    An MPC on an RC plans inside the band by its RC's replay error (:func:`boptest_rc_mpc`).

    A learned model (``model_dir``) or an RC (``rc_path``) gets the checks of the package's
    own plants (:func:`scenarios.running.factory.check_model_fits`, ``check_rc_fits``; the
    interval and the heating sign at the controller's construction) before any call to the
    server, with :data:`BOPTEST_FIT_CHECKS`: refused when made on another actuator's data or
    on powers above 1.5 x the actuator's limit, a warning when they stayed under half of it;
    the time constants are not compared (the test case has no RC parameters)."""
    if name == BASELINE:
        if model_dir is not None or rc_path is not None:
            raise InputError(
                f"{BASELINE} is the test case's own controller: it takes no "
                f"{setting('model_dir')} or {setting('rc_path')}"
            )
        return None
    from scenarios.running.factory import build_controller, make_controller

    scenario = chosen.scenario(dt_s)
    if name in MODEL_CONTROLLERS and model_dir is not None:
        from pinn_mpc.fitted import load

        model = load(model_dir)
        return build_controller(
            name, scenario, model=model, n_steps=n_steps,
            planner_options={"guard": boptest_guard(model)}, checks=BOPTEST_FIT_CHECKS,
        )
    return _with_replay_margin(make_controller(
        name, scenario, model_dir=model_dir, rc_path=rc_path, n_steps=n_steps,
        checks=BOPTEST_FIT_CHECKS,
    ))


#: What a BOPTEST run does before its first interval (its progress lines say so).
_STARTING = "selecting a test, starting its period after BOPTEST's warm-up"
_RESTARTING = "re-starting the test at its period's start after BOPTEST's warm-up"


def run_boptest_closed_loop(
    chosen: BoptestScenario,
    controller_name: str,
    controller: Controller | None,
    *,
    run: BoptestRun,
    seed: int = 0,
    progress: bool = False,
    test: BoptestTest | None = None,
) -> ClosedLoopResult:
    """Run ``controller`` (None for :data:`BASELINE`; reset with ``seed``, which fixes a
    sampling planner's draws) over ``run`` on the BOPTEST server.

    The run selects a test of its own, stopped on the server however the run ends (an error
    reply or Ctrl-C included), or, given ``test``, borrows that one (:class:`BoptestPlant`):
    re-started at the period's start (BOPTEST re-initialises it and its KPIs), left for its
    owner to stop. Nothing is returned from a run that did not finish. The KPIs are the
    package's over every interval, with ``boptest`` (BOPTEST's ``/kpi``), ``test_period``,
    ``price_scenario`` and ``boptest_testcase``. A run of its own asks the server first
    (:meth:`BoptestScenario.check_server`). With ``progress``, a line as the run starts and
    one a minute on stderr (:func:`scenarios.running.closed_loop.progress_stage`).
    """
    if run.time_period is None:
        raise ValueError("a closed loop on BOPTEST runs a test period (run.time_period)")
    baseline = controller is None
    scenario = chosen.scenario(run.dt_s)
    spec = scenario.control_spec()
    acting = Thermostat(spec) if controller is None else controller
    check_seed(seed)
    acting.reset(seed)
    n = run.n_intervals
    if test is None:  # no server: one line, before the run says it starts
        chosen.check_server()
    label = (
        f"{controller_name} on BOPTEST: {run.time_period}, {run.days:g} day(s), "
        f"{run.price_scenario} price"
    )
    with progress_stage(label, progress) as stage:
        stage.detail = _STARTING if test is None else _RESTARTING
        with BoptestPlant(
            chosen.settings, run, baseline=baseline, lead_intervals=scenario.horizon_steps,
            test=test,
        ) as plant:
            frame = plant.exogenous_frame()
            t_r0 = float(plant.measure()[0, 0])
            with ClosedLoop(
                scenario.sim, ExogenousSeries.from_frame(frame), spec=spec, initial_t_r_c=t_r0,
                initial_t_m_c=t_r0, seed=0, plant=plant,
            ) as loop:
                errors: list[str] = []
                for k in stage.steps(n, "interval"):
                    decision = loop.advance(acting)
                    if decision.error is not None:
                        errors.append(f"step {k}: {decision.error}")
                rec = loop.record()
                boptest = plant.kpis()
                version = plant.client.server_version
    inputs = RunInputs(exo=frame, series=ExogenousSeries.from_frame(frame), warmup=0, total=n)
    trajectory = run_trajectory(scenario, inputs, rec).drop(columns="T_m")
    if baseline:  # the test case's own controller decided; the demand column is not its
        trajectory["u"] = np.nan
    kpis = run_kpis(
        counted_kpis(scenario, inputs, rec), controller, label=controller_name,
        scenario=chosen.name, days=int(round(run.days)), seed=seed, weather_part="test",
        trajectory=trajectory, weather_times=frame["time"],  # the forecast lead included
        boptest=boptest, boptest_testcase=chosen.settings.points.testcase,
        boptest_version=version, test_period=run.time_period, price_scenario=run.price_scenario,
    )
    return ClosedLoopResult(trajectory=trajectory, kpis=kpis, errors=tuple(errors))


def boptest_data(
    chosen: BoptestScenario,
    *,
    days: int,
    seed: int,
    policy: str = "closed-loop",
    first_day: float = DATA_FIRST_DAY,
    dt_s: float = 1800.0,
    price_scenario: str = "dynamic",
    progress: bool = False,
) -> pd.DataFrame:
    """Training data from the emulator: ``days`` days from day ``first_day`` of the year
    (after BOPTEST's 7-day warm-up), refused where they overlap a test period or its warm-up,
    under a data policy of :mod:`scenarios.running.datagen` (``random``, ``random-level``,
    ``thermostat``, ``closed-loop``: random setpoints in :data:`DATA_SETPOINTS_C` tracked),
    seeded by ``seed``. The data format's columns (:func:`scenarios.plants.boptest.record_data`).
    The server is asked first (:meth:`BoptestScenario.check_server`). With ``progress``, a
    line as the recording starts and one a minute on stderr."""
    if policy not in POLICIES:
        raise ValueError(f"unknown policy {policy!r}; choose one of: {', '.join(POLICIES)}")
    check_seed(seed)
    run = BoptestRun(time_period=None, first_day=first_day, days=float(days),
                     price_scenario=price_scenario, dt_s=dt_s)
    chosen.settings.points.check_disjoint(first_day, float(days))
    spec = chosen.scenario(dt_s).control_spec()
    n = run.n_intervals
    draws = np.random.default_rng([seed, _POLICY_STREAM]).random((n, 3))
    low, high = DATA_SETPOINTS_C
    actuator = spec.actuator
    tracking = SetpointPolicy(
        actuator=actuator, low_c=low, high_c=high,
        hold_steps=(max(1, round(3600.0 / dt_s)), max(1, round(8 * 3600.0 / dt_s))),
    )
    setpoints = tracking.setpoints(draws)
    thermostat = Thermostat(spec)
    on = np.zeros(1, dtype=bool)

    def demand(k: int, t_r_c: float, row: pd.Series) -> float:
        nonlocal on
        if policy == "random":
            return actuator.on_off(draws[k, 0] < 0.5)
        if policy == "random-level":
            return float(actuator.at_fraction(draws[k, 0]))
        if policy == "closed-loop":
            return float(tracking.demand(np.array([t_r_c]), setpoints[k], draws[k])[0])
        on = thermostat.switch(np.array([t_r_c]), on, float(row["T_min"]), float(row["T_max"]))
        return actuator.on_off(on[0])

    chosen.check_server()  # no server: one line, before the recording says it starts
    label = (
        f"training data on BOPTEST: {days} day(s) from day {first_day:g} of the year, "
        f"{policy} policy"
    )
    with progress_stage(label, progress) as stage:
        stage.detail = f"selecting a test, simulating its {run.warmup_days:g}-day warm-up"
        return record_data(chosen.settings, run, demand, intervals=lambda n: stage.steps(n, "interval"))


#: BOPTEST's KPIs a comparison shows: (key in ``/kpi``, column heading).
COMPARED_KPIS = (
    ("tdis_tot", "tdis K h/zone (total)"),
    ("ener_tot", "energy kWh/m2"),
    ("cost_tot", "cost EUR/m2"),
    ("emis_tot", "emissions kg/m2"),
    ("time_rat", "time ratio"),
)


#: The model families ``cem`` plans over in a BOPTEST comparison, as in ``compare``: the
#: compared network architectures, then the linear ARX and the physics-informed ARX.
CEM_FAMILIES = (*COMPARED_ARCHS, ARX.name, PHYSICS_ARX.name)
#: What a BOPTEST sweep or comparison fits for qp-mpc: the RC identified from the data.
RC_FIT = "rc"


def boptest_fit(
    kind: str, data: pd.DataFrame, config: TrainConfig, *, progress: bool = False
) -> tuple[BoptestModel, str]:
    """Fit ``kind`` on the emulator's ``data``: :data:`RC_FIT` (the grey-box RC, the actuator's
    gain 1: BOPTEST's power is the heat pump's electrical power, its COP learned into the
    gain), ``auto`` (``train``'s default, :func:`pinn_mpc.model_choice.choose_model` with
    ``config``) or a model ``train --arch`` takes by name (``config`` for the networks).
    Returns the model and the name of what was fitted (for ``auto``, the family it chose);
    ``progress``: the training's bars on a terminal."""
    from pinn_mpc.fitted import fit
    from pinn_mpc.identify import identify_rc

    if kind == RC_FIT:
        return identify_rc(data, eta=1.0).params, RC_FIT
    if kind not in (AUTO, *MODEL_CHOICES):
        raise ValueError(f"unknown model {kind!r}; choose {RC_FIT}, {AUTO} or one of {', '.join(MODEL_CHOICES)}")
    choice = fit(data, arch=kind, config=config, progress=progress)
    return choice.model, choice.chosen


def boptest_planner(
    name: str, chosen: BoptestScenario, model: BoptestModel | None, *, dt_s: float, n_steps: int
) -> Controller | None:
    """The controller ``name`` (:data:`BASELINE`, ``thermostat``, ``qp-mpc`` on an RC,
    ``cem`` over a learned model or an ARX, with its RC fallback) on ``chosen`` at interval
    ``dt_s`` [s] for ``n_steps`` intervals, from a fitted ``model`` (:func:`boptest_fit`);
    None for :data:`BASELINE`."""
    from controllers.sampling import CEM

    scenario = chosen.scenario(dt_s)
    spec = scenario.control_spec()
    if name == BASELINE:
        return None
    if name == "thermostat":
        return Thermostat(spec)
    if name == "qp-mpc" and isinstance(model, RCParams):
        return boptest_rc_mpc("qp-mpc", scenario, model, n_steps=n_steps)
    if name == "cem" and model is not None and not isinstance(model, RCParams):
        return CEM(model, spec, guard=boptest_guard(model))
    raise InputError(
        f"controller {name!r} on BOPTEST takes {BASELINE}, thermostat, qp-mpc (on an identified "
        "RC) or cem (over a learned model or an ARX)"
    )


@dataclass(frozen=True, kw_only=True)
class BoptestComparison:
    """A comparison on one BOPTEST test: ``rows`` (one KPI dict of
    :func:`run_boptest_closed_loop` per controller, with ``wall_s_per_day``, the wall time
    per simulated day through the API, the warm-up included, and ``model``, what cem planned
    over), the ``rc`` identified from the training data (:func:`pinn_mpc.physics.rc_summary`),
    the ``model`` the default ``train`` chose, the training data's ``data_days`` and the
    ``wall_time_s`` of each stage (``select test``: selecting the test the rows share)."""

    rows: list[RunKpis]
    rc: dict[str, float]
    model: str
    data_days: list[str]
    wall_time_s: dict[str, float]


def run_boptest_comparison(
    chosen: BoptestScenario,
    *,
    train_days: int,
    days: int,
    seed: int,
    run: BoptestRun,
    config: TrainConfig,
    policy: str = "closed-loop",
    families: tuple[str, ...] = CEM_FAMILIES,
    progress: bool = False,
) -> BoptestComparison:
    """Training data from the emulator (:func:`boptest_data`, ``train_days`` days nearest the
    test period, :meth:`~scenarios.plants.boptest.BoptestPoints.data_first_day`), the RC
    identified from it, the default model ``train`` would choose on it
    (:func:`pinn_mpc.model_choice.choose_model`) and each model family of ``families``, all
    trained once with ``config``; then ``boptest-baseline``, the thermostat, ``qp-mpc`` on the
    identified RC, ``cem`` over the default model (row ``cem / default (<family>)``) and
    ``cem`` over each other family (``cem / <family>``; the default's own family is not run
    twice: its model is the same) on the test ``run``.

    The rows run one after another on one test, selected once after the training (the
    training data records on a test of its own: the server ends a test left idle, as it is
    while the models train) and re-started at the period's start for each row (BOPTEST
    re-initialises the test and its KPIs); the test is stopped however the rows end, an
    error or Ctrl-C included. With ``progress``, each stage (the recording, each fit, the
    select, each row) says on stderr as it starts what it does, and a line a minute while it
    runs."""
    import time

    from pinn_mpc.physics import rc_summary
    from scenarios.running.closed_loop import one_torch_thread

    wall: dict[str, float] = {}
    start = time.perf_counter()
    if run.time_period is None:
        raise ValueError("a comparison on BOPTEST runs a test period (run.time_period)")
    first_day = chosen.settings.points.data_first_day(run.time_period, float(train_days))
    data = boptest_data(
        chosen, days=train_days, seed=seed, policy=policy, dt_s=run.dt_s, first_day=first_day,
        progress=progress,
    )
    wall["training data"] = time.perf_counter() - start
    fitted: dict[str, tuple[BoptestModel, str]] = {}
    with one_torch_thread():
        for kind in (RC_FIT, AUTO, *families):
            start = time.perf_counter()
            stage = "identify RC" if kind == RC_FIT else f"train {kind}"
            with progress_stage(f"compare on BOPTEST: {stage} on {train_days} day(s) of data", progress):
                fitted[kind] = boptest_fit(kind, data, config, progress=progress)
            wall[stage] = time.perf_counter() - start
    default = fitted[AUTO][1]
    n_steps = int(round(days * SECONDS_PER_DAY / run.dt_s))
    plan: list[tuple[str, str, str, BoptestModel | None]] = [
        (BASELINE, BASELINE, "-", None),
        ("thermostat", "thermostat", "-", None),
        ("qp-mpc", "qp-mpc", "identified RC", fitted[RC_FIT][0]),
        ("cem", f"cem / default ({default})", default, fitted[AUTO][0]),
        *(("cem", f"cem / {kind}", kind, fitted[kind][0]) for kind in families if kind != default),
    ]
    test_run = dataclasses.replace(run, days=float(days))
    rows: list[RunKpis] = []
    settings = chosen.settings
    start = time.perf_counter()
    with closing(BoptestClient(settings.url, timeout_s=settings.timeout_s)) as client:
        with progress_stage("compare on BOPTEST: selecting the test the rows share", progress):
            test = client.select(settings.points.testcase)
        wall["select test"] = time.perf_counter() - start
        with test:  # stopped however the rows end (before the block, by the client's close)
            for name, label, model_name, model in plan:
                start = time.perf_counter()
                controller = boptest_planner(name, chosen, model, dt_s=run.dt_s, n_steps=n_steps)
                with one_torch_thread():
                    result = run_boptest_closed_loop(
                        chosen, label, controller, run=test_run, seed=seed, progress=progress,
                        test=test,
                    )
                wall[label] = time.perf_counter() - start
                kpis = result.kpis
                kpis["wall_s_per_day"] = wall[label] / days  # type: ignore[typeddict-unknown-key]
                kpis["model"] = model_name  # type: ignore[typeddict-unknown-key]
                rows.append(kpis)
    rc = cast(RCParams, fitted[RC_FIT][0])  # what boptest_fit identifies for RC_FIT
    return BoptestComparison(
        rows=rows, rc=dict(rc_summary(rc, source="identify (training data)")),  # type: ignore[arg-type]
        model=default, data_days=day_span(data["time"]), wall_time_s=wall,
    )


def boptest_report(comparison: BoptestComparison, *, scenario: str, run: BoptestRun, days: int) -> str:
    """The markdown report of :func:`run_boptest_comparison`: BOPTEST's KPIs per controller,
    the share of its own decisions, the wall time per simulated day and the decision times."""
    heads = [h for _, h in COMPARED_KPIS]
    lines = [
        f"# {scenario} on BOPTEST: {run.time_period}, {run.price_scenario} price",
        "",
        f"{days} day(s) of the test period at {run.dt_s:g} s; training data "
        f"{comparison.data_days[0]}..{comparison.data_days[1]}; cem over the default model "
        f"({comparison.model}, which `train` chooses) and over each other model family, each "
        "trained once on the same data; qp-mpc on the RC identified from them. BOPTEST's own "
        "KPIs (per m2 of floor, per zone).",
        "",
        "| controller | " + " | ".join(heads) + " | own decisions | wall s / day | decision ms (median / p95) |",
        "|---" * (len(heads) + 4) + "|",
    ]
    for row in comparison.rows:
        b = row.get("boptest", {})
        values = [f"{b[k]:.4g}" if isinstance(b.get(k), float | int) else "-" for k, _ in COMPARED_KPIS]
        extra = dict(row)
        lines.append(
            f"| {row['controller']} | " + " | ".join(values)
            + f" | {100 * row['own_decisions_share']:.0f} % | {extra.get('wall_s_per_day', float('nan')):.1f}"
            + f" | {row['decision_ms_median']:.1f} / {row['decision_ms_p95']:.1f} |"
        )
    lines += ["", "Wall time per stage: " + ", ".join(
        f"{stage} {sec:.0f} s" for stage, sec in comparison.wall_time_s.items()
    ), ""]
    return "\n".join(lines)
