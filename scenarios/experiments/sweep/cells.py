"""One cell of a sweep: one closed loop on the test days (on BOPTEST, one test on the server)."""

from __future__ import annotations

import socket
import time
from typing import TYPE_CHECKING

from pinn_mpc.errors import InternalError
from pinn_mpc.physics import RCParams
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
    first ``test_days`` of its test period, its KPIs with BOPTEST's under ``boptest``.
    """
    from scenarios.running.closed_loop import one_torch_thread, run_closed_loop
    from scenarios.running.factory import build_controller

    start = time.perf_counter()
    if cell.test_period is not None:
        return _run_boptest_cell(cell, settings, model, boptest_url, start)
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
            label=cell.controller,
        )
    return _cell_result(result, learned, time.perf_counter() - start)


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


