"""One cell of a sweep: one closed loop on the test days (on BOPTEST, one test on the server)."""

from __future__ import annotations

import socket
import time
from typing import TYPE_CHECKING

from pinn_mpc.errors import InternalError
from pinn_mpc.physics import RCParams
from scenarios.choices import online_controller
from scenarios.experiments.sweep.boptest import _boptest_chosen
from scenarios.experiments.sweep.grid import (
    RC_KIND,
    Cell,
    SweepSettings,
    model_kind,
)
from scenarios.experiments.sweep.models import SweepModel, _model_family
from scenarios.inputs.scenario_file import get_scenario
from scenarios.records import CellResult

if TYPE_CHECKING:
    from scenarios.running.closed_loop import ClosedLoopResult

__all__ = ["run_cell"]


def run_cell(
    cell: Cell,
    settings: SweepSettings,
    model: SweepModel | None,
    boptest_url: str | None = None,
) -> CellResult:
    """One closed loop on the test days (seed + 1): ``{"kpis", "errors", "host", "wall_time_s"}``.

    ``model`` is what :func:`fit_model` returned for ``cell.model`` (None when it has none):
    the learned model a planner plans over, or the RC an RC MPC works on. On BOPTEST the
    cell is one test on the server (``boptest_url`` when the scenario file names none): the
    first ``test_days`` of its test period, its KPIs with BOPTEST's under ``boptest``. A
    controller run online (``cem-online``) is :func:`_run_online_cell`. On the package's own
    plants the KPIs hold ``per_day``, each test day's figures.
    """
    from scenarios.running.closed_loop import one_torch_thread, run_closed_loop
    from scenarios.running.factory import build_controller

    start = time.perf_counter()
    if cell.test_period is not None:
        return _run_boptest_cell(cell, settings, model, boptest_url, start)
    if online_controller(cell.controller) is not None:
        return _run_online_cell(cell, settings, start)
    scenario = get_scenario(cell.scenario)
    from pinn_mpc.identify_multizone import MultiZoneIdentifyResult

    kind = model_kind(cell.controller)
    zones = model if kind == RC_KIND and isinstance(model, MultiZoneIdentifyResult) else None
    learned = (
        model if kind not in (None, RC_KIND) and not isinstance(model, RCParams | MultiZoneIdentifyResult) else None
    )
    controller = build_controller(
        cell.controller.partition("/")[0],  # cem/<arch>: cem, over the model of that arch
        scenario,
        model=learned,
        rc_params=model if kind == RC_KIND and isinstance(model, RCParams) else None,
        zone_params=None if zones is None else zones.params,
        n_steps=settings.test_days * scenario.steps_per_day,
    )
    with one_torch_thread():
        result = run_closed_loop(
            scenario, controller, days=settings.test_days, seed=cell.seed + 1,
            label=cell.controller, per_day=True,
        )
    return _cell_result(result, learned, time.perf_counter() - start)


def _run_online_cell(cell: Cell, settings: SweepSettings, start: float) -> CellResult:
    """A controller run online (:func:`scenarios.running.online.run_online`): it starts from
    ``cell.train_days`` days of the scenario's data (its data policy, seed ``cell.seed``, the
    rows taken as the days right before the test days; on EnergyPlus, where they can be, the
    days simulated right before them: :func:`scenarios.running.online.data_before_run`), then
    runs ``test_days`` days (seed ``cell.seed + 1``) refitting every night with the default schedule, its ensembles of the
    settings' members, depth and epochs (None: the recipe's). The run's folder (versions,
    ``log.jsonl``) is a temporary one: its nights are the record's ``online_log``; the KPIs
    hold ``online`` and ``per_day``."""
    import tempfile

    import pandas as pd

    from pinn_mpc.training import TrainConfig
    from scenarios.running.closed_loop import one_torch_thread, prepare_run
    from scenarios.running.online import OnlineSettings, data_before_run, run_online

    name = online_controller(cell.controller)
    if name is None or cell.train_days is None:
        raise InternalError(f"sweep cell {cell.name}: not a controller run online with its days of data")
    scenario = get_scenario(cell.scenario)
    policy = scenario.data_policy if settings.policy == "scenario" else settings.policy
    run = prepare_run(scenario, days=settings.test_days, seed=cell.seed + 1, warmup_steps=None, weather_part="test")
    data = (
        data_before_run(scenario, days=cell.train_days, seed=cell.seed, policy=policy,
                        first_time=pd.Timestamp(run.exo["time"].iloc[0]))
        if cell.train_days > 0 else None
    )
    config = TrainConfig(n_seeds=settings.n_members, depth=settings.depth, epochs=settings.epochs)
    online = OnlineSettings(controller=name, config=config)
    with tempfile.TemporaryDirectory(prefix="sweep_online_") as out, one_torch_thread():
        result = run_online(scenario, data, days=settings.test_days, seed=cell.seed + 1,
                            out_dir=out, settings=online)
    result.kpis["controller"] = cell.controller
    result.kpis["per_day"] = [
        {"day": day["day"], "objective": day["objective"], "discomfort_kh": day["discomfort_kh"],
         "own_decisions_share": day["own_decisions_share"]}
        for day in result.kpis["online"]["days"]  # type: ignore[typeddict-item]
    ]
    return {
        "kpis": result.kpis,
        "errors": [],
        "host": socket.gethostname(),
        "wall_time_s": time.perf_counter() - start,
        "online_log": list(result.log),
    }


def _run_boptest_cell(
    cell: Cell,
    settings: SweepSettings,
    model: SweepModel | None,
    boptest_url: str | None,
    start: float,
) -> CellResult:
    from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
    from scenarios.plants.boptest import BoptestRun
    from scenarios.running.boptest_loop import boptest_planner, run_boptest_closed_loop
    from scenarios.running.closed_loop import one_torch_thread

    if isinstance(model, MultiZoneIdentifyResult):
        raise InternalError(f"sweep cell {cell.name}: a BOPTEST test case is one zone's, got a multi-zone RC")
    chosen = _boptest_chosen(cell.scenario, boptest_url)
    run = BoptestRun(
        time_period=cell.test_period, days=float(settings.test_days),
        price_scenario=cell.price_scenario or "dynamic",
    )
    controller = boptest_planner(
        cell.controller.partition("/")[0], chosen, model, dt_s=run.dt_s, n_steps=run.n_intervals
    )
    with one_torch_thread():
        result = run_boptest_closed_loop(chosen, cell.controller, controller, run=run, seed=cell.seed)
    wall = time.perf_counter() - start
    result.kpis["wall_s_per_day"] = wall / settings.test_days  # type: ignore[typeddict-unknown-key]
    return _cell_result(result, model, wall)


def _cell_result(result: ClosedLoopResult, model: SweepModel | None, wall_s: float) -> CellResult:
    """A cell's record of the run ``result``: its KPIs (with the family of ``model``, the
    learned model or RC it ran on, where it has one), errors, host and ``wall_s``."""
    kpis = result.kpis
    if model is not None:
        kpis["model"] = _model_family(model)  # type: ignore[typeddict-unknown-key]
    return {
        "kpis": kpis,
        "errors": list(result.errors),
        "host": socket.gethostname(),
        "wall_time_s": wall_s,
    }


