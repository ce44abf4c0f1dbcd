"""Running a sweep: the models and cells as Ray tasks, their progress, and the summary,
report and figure at the end (:func:`run_sweep`)."""

from __future__ import annotations

import dataclasses
import importlib.metadata
import json
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

from tqdm import tqdm

from pinn_mpc.errors import InputError
from pinn_mpc.io import atomic_write_json, atomic_write_text
from scenarios.experiments.sweep.boptest import _boptest_chosen, boptest_training_data
from scenarios.experiments.sweep.cells import run_cell
from scenarios.experiments.sweep.grid import Cell, ModelKey, SweepGrid, SweepSettings, _model_key
from scenarios.experiments.sweep.models import fit_model
from scenarios.experiments.sweep.store import (
    _cell_record_key,
    _check_out,
    _check_settings,
    _load_model,
    _read_cell,
    _settings_record,
    _store_model,
    code_revision,
)
from scenarios.plants.boptest import TEST_PERIOD_DAYS
from scenarios.plants.boptest_client import BOPTEST_URL_ENV
from scenarios.records import CellRecord, CellResult, EngineRecord, GridRecord, SweepSummary
from scenarios.reports.online_report import online_section, plot_online_days
from scenarios.reports.sweep_report import plot_sweep, render_sweep_report, summarise
from scenarios.running.ray_engine import check_engine_options, ray_engine

__all__ = ["ENERGYPLUS_CALLS_PER_WORKER", "FIGURE", "ONLINE_FIGURE", "SweepOutcome", "run_sweep"]

FIGURE = "objective_to_oracle.png"
#: The objective per day of service of the controllers run online and the baseline.
ONLINE_FIGURE = "online_days.png"
#: Tasks an engine worker runs before it is replaced when the grid has an EnergyPlus scenario.
ENERGYPLUS_CALLS_PER_WORKER = 20


def _one_blas_thread(function: Callable[..., Any], *args: Any) -> Any:
    """A Ray task body: each task holds one CPU, so its linear algebra gets one thread."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return function(*args)


def _task_failure(what: str, exc: Exception) -> InputError:
    cause = getattr(exc, "cause", None) or exc
    first = (str(cause).strip().splitlines() or [""])[0]
    return InputError(f"sweep: {what} failed: {type(cause).__name__}: {first}")


@dataclass(frozen=True, kw_only=True)
class SweepOutcome:
    summary: SweepSummary
    summary_path: Path
    report_path: Path
    figure_path: Path


def _start_line(cells: int, reused: int, models: int, recordings: int) -> str:
    """What the sweep starts: its cells, its models and (BOPTEST) their training data."""
    data = f", on {recordings} recording(s) of BOPTEST training data first" if recordings else ""
    return f"sweep: {cells} cell(s) to run ({reused} reused), {models} model(s) to train{data}"


def _progress_line(
    done: int, total: int, reused: int, trained: int, elapsed_s: float, *, waiting: Mapping[str, int]
) -> str:
    """The sweep's progress: cells done of ``total``, models trained, time left, and the
    tasks still running or queued (``waiting``: their kind -> how many)."""
    from scenarios.running.closed_loop import duration_text

    run_now = done - reused
    left = (
        f"about {duration_text(elapsed_s / run_now * (total - done))} left"
        if run_now
        else "no cell finished yet"
    )
    busy = ", ".join(f"{n} {kind}(s)" for kind, n in waiting.items() if n)
    return (
        f"sweep: {done} of {total} cells ({reused} reused), {trained} model(s) "
        f"trained, {duration_text(elapsed_s)} elapsed, {left}"
        + (f"; running or queued: {busy}" if busy else "")
    )


def _submit(
    root: Path, grid: SweepGrid, settings: SweepSettings, keys: Sequence[ModelKey], missing: Sequence[Cell]
) -> tuple[dict[Any, tuple[str, Any]], int]:
    """Submit the models ``keys`` not stored under ``root`` (those stored are put into Ray's
    object store) and the ``missing`` cells as Ray tasks, each cell given its model's reference;
    the pending tasks (reference -> ``("model", key)`` or ``("cell", cell)``) and the number of
    BOPTEST recordings of training data among them."""
    import ray

    # EnergyPlus leaks ~0.55 MB per run inside the engine: its workers are recycled.
    max_calls = ENERGYPLUS_CALLS_PER_WORKER if grid.has_energyplus else 0  # 0: never
    task = ray.remote(num_cpus=1, max_calls=max_calls)(_one_blas_thread)
    pending: dict[Any, tuple[str, Any]] = {}
    model_refs: dict[ModelKey, Any] = {}
    # BOPTEST: the emulator's data, recorded once per scenario x seed x training days x period
    data_refs: dict[ModelKey, Any] = {}
    url = os.environ.get(BOPTEST_URL_ENV)
    for key in keys:
        stored = _load_model(root, key)
        if stored is not None:
            model_refs[key] = ray.put(stored)
            continue
        data = None
        if grid.is_boptest:
            source = dataclasses.replace(key, kind="data")
            if source not in data_refs:
                data_refs[source] = task.remote(boptest_training_data, source, url)
            data = data_refs[source]
        model_refs[key] = task.remote(fit_model, key, settings, data)
        pending[model_refs[key]] = ("model", key)
    for cell in missing:
        needed = _model_key(cell, settings)
        ref = task.remote(run_cell, cell, settings, model_refs.get(needed) if needed else None, url)
        pending[ref] = ("cell", cell)
    return pending, len(data_refs)


def _run_on_ray(
    root: Path,
    grid: SweepGrid,
    settings: SweepSettings,
    *,
    keys: Sequence[ModelKey],
    missing: Sequence[Cell],
    records: dict[Cell, CellRecord | None],
    total: int,
    reused: int,
) -> int:
    """Train the models ``keys`` (those stored under ``root`` are reused) and run the
    ``missing`` cells (of ``total``, ``reused`` of them read back) as Ray tasks, writing each model and cell the moment it arrives and
    entering each cell's record in ``records``; the number of models trained."""
    import ray

    from scenarios.running.closed_loop import PROGRESS_EVERY_S

    trained = 0
    code = code_revision()  # the checkout whose tasks run now, in every cell's record
    pending, recordings = _submit(root, grid, settings, keys, missing)

    to_train = sum(kind == "model" for kind, _ in pending.values())

    def say(line: str) -> None:  # through tqdm: a terminal's bar stays intact
        tqdm.write(line, file=sys.stderr)
        sys.stderr.flush()

    say(_start_line(len(missing), reused, to_train, recordings))
    began = last = time.monotonic()
    done = reused  # counted here: off a terminal the bar is disabled and does not count
    with tqdm(total=total, initial=reused, desc="sweep", unit="cell", disable=None) as bar:
        while pending:
            now = time.monotonic()
            if now - last >= PROGRESS_EVERY_S:  # a line a minute, a cell finished or not
                last = now
                waiting = {kind: sum(k == kind for k, _ in pending.values()) for kind in ("model", "cell")}
                say(_progress_line(done, total, reused, trained, now - began, waiting=waiting))
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=PROGRESS_EVERY_S)
            if not ready:  # nothing finished within a minute: report progress, wait again
                continue
            kind, what = pending.pop(ready[0])
            try:
                value = ray.get(ready[0])
            except ray.exceptions.RayError as exc:
                raise _task_failure(f"{kind} {what.name}", exc) from None
            if kind == "model":
                _store_model(root, what, value)
                trained += 1
                say(f"sweep: model {what.name} trained ({trained} of {to_train})")
                continue
            record: CellRecord = {
                **_cell_record_key(what),
                "settings": _settings_record(settings),
                "code": code,
                **cast(CellResult, value),
            }
            atomic_write_json(root / "cells" / f"{what.name}.json", record)
            records[what] = record
            done += 1
            bar.update()
    return trained


def _grid_record(grid: SweepGrid) -> GridRecord:
    record: GridRecord = {
        "scenarios": list(grid.scenarios),
        "controllers": list(grid.controllers),
        "seeds": list(grid.seeds),
        "train_days": list(grid.train_days),
    }
    if grid.archs:
        record["archs"] = list(grid.archs)
    if grid.is_boptest:
        record["test_periods"] = list(grid.boptest_periods)
        record["price_scenarios"] = list(grid.boptest_prices)
    return record


def _start_directory(root: Path, settings: SweepSettings) -> None:
    """Make the sweep directory ``root`` (its ``models/`` and ``cells/``) and write its
    ``sweep.json`` (the settings its cells are kept under)."""
    (root / "models").mkdir(parents=True, exist_ok=True)
    (root / "cells").mkdir(exist_ok=True)
    atomic_write_json(root / "sweep.json", {"settings": _settings_record(settings)})


def _stored_engine(root: Path) -> EngineRecord:
    """The engine the stored cells of ``root`` ran on: its ``summary.json``'s, or (no summary,
    or one without it) Ray's name and version with no resources."""
    try:
        engine = json.loads((root / "summary.json").read_text(encoding="utf-8"))["engine"]
    except (OSError, ValueError, KeyError, TypeError):
        engine = None
    if isinstance(engine, dict) and set(engine) == {"name", "version", "resources"}:
        return cast(EngineRecord, engine)
    return {"name": "ray", "version": importlib.metadata.version("ray"), "resources": {}}


def run_sweep(
    grid: SweepGrid,
    settings: SweepSettings,
    out: str | os.PathLike[str],
    *,
    baseline: str,
    address: str | None = None,
    workers: int | None = None,
    force: bool = False,
) -> SweepOutcome:
    """Run the missing cells of ``grid`` on Ray, then write the summary, report and figure
    (none missing: Ray is not started, and the summary keeps the engine the cells ran on).

    ``out`` must be new, empty or an earlier sweep's directory (it holds ``sweep.json``); any
    other directory needs ``force`` (then the sweep's files are added and nothing else in it is
    touched, but a ``summary.json`` or ``report.md`` of the user's would be replaced)."""

    if baseline not in (*grid.labels, *grid.references.values()):
        raise InputError(
            f"sweep: baseline {baseline!r} is not among the controllers ({', '.join(grid.labels)})"
        )
    if grid.is_boptest and settings.test_days > TEST_PERIOD_DAYS:
        raise InputError(
            f"sweep: days {settings.test_days}: a BOPTEST test period has {TEST_PERIOD_DAYS:g} days"
        )
    check_engine_options(address, workers)
    if grid.is_boptest:  # no server: one line now, not a failed cell after Ray has started
        for scenario in grid.scenarios:
            _boptest_chosen(scenario, None).check_server()
    start = time.perf_counter()
    root = Path(out)
    _check_out(root, force=force)
    _check_settings(root, settings)
    cells = grid.cells()
    records = {c: _read_cell(root / "cells" / f"{c.name}.json", c) for c in cells}
    missing = [c for c in cells if records[c] is None]
    reused = len(cells) - len(missing)
    keys = sorted({k for c in missing if (k := _model_key(c, settings)) is not None})
    if missing:
        with ray_engine(address, workers) as engine:
            # Only now that the engine runs: a refused address leaves no directory behind.
            _start_directory(root, settings)
            trained = _run_on_ray(
                root, grid, settings, keys=keys, missing=missing, records=records,
                total=len(cells), reused=reused,
            )
    else:  # every cell stored: nothing to run, no engine to start
        engine = _stored_engine(root)
        _start_directory(root, settings)
        trained = 0
    done = [r for r in records.values() if r is not None]
    rows = summarise(
        done,
        baseline=baseline,
        order=[*grid.labels, *dict.fromkeys(grid.references.values())],
        references=grid.references,
    )
    summary: SweepSummary = {
        "rows": rows,
        "baseline": baseline,
        "engine": engine,
        "cells_run": len(missing),
        "cells_reused": reused,
        "models_trained": trained,
        "models_reused": len(keys) - trained,
        "grid": _grid_record(grid),
        "settings": _settings_record(settings),
        "wall_time_s": time.perf_counter() - start,
    }
    summary_path = atomic_write_json(root / "summary.json", summary)
    figure_path = plot_sweep(rows, root / FIGURE)
    online_figure = plot_online_days(done, root / ONLINE_FIGURE, baseline=baseline)
    online = online_section(
        done, baseline=baseline, figure_name=None if online_figure is None else ONLINE_FIGURE
    )
    report_path = atomic_write_text(
        root / "report.md",
        render_sweep_report(summary, figure_name=FIGURE) + "".join(f"\n{line}" for line in online),
    )
    return SweepOutcome(
        summary=summary, summary_path=summary_path, report_path=report_path, figure_path=figure_path
    )
