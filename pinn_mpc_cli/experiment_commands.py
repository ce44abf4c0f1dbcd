"""The experiment commands: ``compare`` (every controller on one scenario), ``reproduce`` (the
paper's experiments) and ``sweep`` (a grid of closed loops on Ray).

Each takes the parsed arguments, refuses outputs that cannot be written or would overwrite an
input or another output (before any work), calls the library (which returns typed results),
writes the outputs atomically and returns the summary the CLI prints.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pinn_mpc.errors import InputError, warn
from pinn_mpc.io import (
    PathsArg,
    atomic_write_json,
    atomic_write_text,
    check_distinct,
    check_writable,
    output_lock,
    written_together,
)
from pinn_mpc_cli.scenario_args import refuse_boptest_options, scenario_inputs
from scenarios.inputs.registry import Scenario
from scenarios.inputs.scenario_file import get_scenario
from scenarios.records import CompareTable
from scenarios.reports.report import kpi_table_text, prediction_table_text, render_report

if TYPE_CHECKING:  # compare loads torch: only the compare command imports it
    from scenarios.experiments.compare import CompareSettings, ComparisonResult

__all__ = ["compare", "reproduce", "sweep"]


def _dates_text(settings: CompareSettings, days: dict[str, list[str]]) -> str:
    """One sentence: when the training data and the test days are."""
    (train_first, train_last), (first, last) = days["training"], days["test"]
    return (
        f"Training data: {settings.train_days} days, {train_first} to {train_last}, from the "
        f"training part of the weather (seed {settings.seed}). Test: {settings.test_days} days, "
        f"{first} to {last}, from the test part (seed {settings.test_seed}); with the warm-up "
        f"day and the forecast lead the test weather spans {days['test weather'][0]} to "
        f"{days['test weather'][1]}."
    )


def _settings_table(
    name: str,
    scenario: Scenario,
    settings: CompareSettings,
    result: ComparisonResult,
    total_s: float,
) -> dict[str, Any]:
    """What the comparison depended on, for the report and the JSON table (``name``: the
    ``--scenario`` given, a built-in name or a file)."""
    from scenarios.inputs.registry import is_scenario_file

    return {
        **dataclasses.asdict(settings),
        "test_seed": settings.test_seed,
        "training_dates": result.days["training"],
        "test_dates": result.days["test"],
        "training_epochs": settings.training_epochs,
        "scenario": scenario.name,
        **({"scenario_file": os.path.abspath(name)} if is_scenario_file(name) else {}),
        "comfort_weight_eur_per_kh": scenario.comfort_weight_eur_per_kh,
        "horizon_steps": scenario.horizon_steps,
        "dt_s": scenario.sim.dt_s,
        "u_max_w": scenario.sim.u_max_w,
        "wall_time_s": round(total_s, 1),
        "cpu_count": os.cpu_count(),
    }


def compare(a: argparse.Namespace) -> str:
    """Run the comparison, write the JSON table, the report and its figure (parents created)
    together or not at all; the report is held by this run until it ends."""
    check_writable(a.json, a.report, create_parents=True)
    with output_lock(a.report, option="report", create_parents=True), written_together():
        return _compare(a)


def _compare(a: argparse.Namespace) -> str:
    from scenarios.experiments.compare import CompareSettings, run_comparison
    from scenarios.experiments.prediction import PREDICTION_HORIZON
    from scenarios.running.boptest_loop import is_boptest_scenario

    if is_boptest_scenario(a.scenario):
        return _boptest_compare(a)
    refuse_boptest_options({o: getattr(a, o) for o in ("test_period", "price_scenario")}, a.scenario)
    check_writable(a.json, a.report, create_parents=True)
    report = Path(a.report)
    figure = report.with_suffix(".png")
    if figure == report:
        raise InputError(
            f"--report {a.report}: the report is markdown and its figure is written next to "
            f"it as {figure.name}; give --report a name ending in .md"
        )
    check_writable(figure, create_parents=True)
    outputs: dict[str, PathsArg] = {
        "--json": a.json,
        "--report": a.report,
        "--report's figure": figure,
    }
    check_distinct(inputs=scenario_inputs(a.scenario), outputs=outputs)
    scenario = get_scenario(a.scenario)
    zoned = not scenario.control_spec().single
    settings = CompareSettings.for_run(
        train_days=a.train_days, days=a.days, seed=a.seed, quick=a.quick,
        policy=a.policy or scenario.data_policy,
    )
    start = time.perf_counter()
    if zoned:
        from scenarios.experiments.compare_zones import paper_training, run_zone_comparison

        result = run_zone_comparison(scenario, settings)
    else:
        result = run_comparison(scenario, settings)
    total_s = time.perf_counter() - start
    settings_table = _settings_table(a.scenario, scenario, settings, result, total_s)
    if zoned:  # the paper's networks of every zone train for the multi-zone fit's epochs
        settings_table["training_epochs"] = paper_training(settings).epochs
        settings_table["default_model"] = result.default_model
    notes = [
        f"`{label}`: {len(errs)} controller error(s), the fallback acted; first: {errs[0]}"
        for label, errs in result.errors.items()
    ]
    for note in result.notes:
        warn(note)
    notes += list(result.notes)
    notes += [f"wall time of {stage}: {sec:.1f} s" for stage, sec in result.wall_time_s.items()]
    for path in (Path(a.json), report, figure):
        path.parent.mkdir(parents=True, exist_ok=True)
    from scenarios.reports.plots import plot_comparison

    first, last = result.days["test"]
    title = f"{scenario.name}: test days {first} to {last}, seed {settings.test_seed}"
    plot_comparison(result.trajectories, figure, title=title, reference=scenario.reference)
    atomic_write_text(
        report,
        render_report(
            scenario=scenario.name,
            description=scenario.description,
            rows=result.rows,
            rc=result.rc,
            settings=settings_table,
            figure_name=figure.name,
            notes=notes,
            dates=_dates_text(settings, result.days),
            prediction=result.prediction,
            prediction_horizon=PREDICTION_HORIZON,
            zone_rc=result.zone_rc if zoned else None,
        ),
    )
    table: CompareTable = {
        "scenario": scenario.name,
        "training_dates": result.days["training"],
        "test_dates": result.days["test"],
        "settings": settings_table,
        "rows": result.rows,
        "rc": result.rc,
        "prediction": result.prediction,
        **({"zone_rc": result.zone_rc} if zoned else {}),  # type: ignore[typeddict-item]
    }
    atomic_write_json(a.json, table)
    written = f"wrote {a.json}, {a.report}, {figure} ({total_s:.0f} s)"
    prediction = prediction_table_text(result.prediction)
    return f"{kpi_table_text(result.rows)}\n{prediction}\n{written}"


def reproduce(a: argparse.Namespace) -> str:
    """Run the paper's experiments into ``--out``; the summary is the validation table and
    the files written."""
    from scenarios.experiments.reproduce import ReproduceConfig, run_reproduction, validation_table
    from scenarios.experiments.reproduce.render import OUTPUT

    config = ReproduceConfig.quick(a.seeds) if a.quick else ReproduceConfig(seeds=a.seeds or 20)
    started = time.perf_counter()
    with output_lock(a.out):
        results = run_reproduction(a.out, config, force=a.force)
        for name in config.also_scenarios:
            run_reproduction(
                Path(a.out) / name,
                dataclasses.replace(config, scenario=name, also_scenarios=()),
                force=a.force,
            )
    elapsed = time.perf_counter() - started
    return (
        f"one-step MAE on {config.test_days} test days after {config.validation_days} training "
        "days, "
        f"mean ± std over {config.seeds} seeds (ens. = ensemble mean):\n"
        + validation_table(results, markdown=False)
        + f"\nwrote {Path(a.out)}/: {', '.join(OUTPUT.files)}"
        + "".join(f"; the same in {Path(a.out) / name}/" for name in config.also_scenarios)
        + f" in {elapsed:.0f} s"
    )


def sweep(a: argparse.Namespace) -> str:
    """Parse the grid, run it on Ray (:func:`scenarios.experiments.sweep.run_sweep`), return what was run
    and written."""
    from pinn_mpc.choices import DEFAULT_ARCH
    from scenarios.experiments.sweep import (
        SweepGrid,
        SweepSettings,
        parse_ints,
        parse_names,
        read_sweep_spec,
        run_sweep,
    )
    from scenarios.experiments.sweep.grid import START_DAYS
    from scenarios.inputs.registry import is_scenario_file
    from scenarios.reports.sweep_report import place_label, ratio
    from scenarios.running.budget import check_grid_size

    spec = read_sweep_spec(a.spec) if a.spec is not None else {}

    def given(name: str, default: Any = None) -> Any:
        value = getattr(a, name)
        return value if value is not None else spec.get(name, default)

    scenarios, controllers, seeds = given("scenarios"), given("controllers"), given("seeds")
    missing = [f"--{n}" for n, v in (("scenarios", scenarios), ("controllers", controllers), ("seeds", seeds)) if v is None]
    if missing:
        raise InputError(f"sweep needs {', '.join(missing)} (or a --spec file that gives them)")
    train_days, days = given("train_days", "30"), given("days")
    out, quick, address, workers = a.out, a.quick, a.address, a.workers
    baseline, force = given("baseline"), a.force
    grid = SweepGrid(
        # Absolute: Ray workers resolve scenario files wherever they run.
        scenarios=tuple(
            os.path.abspath(n) if is_scenario_file(n) else n
            for n in parse_names(scenarios, "scenarios")
        ),
        controllers=parse_names(controllers, "controllers"),
        seeds=parse_ints(seeds, "seeds"),
        train_days=parse_ints(train_days, "training days"),
        start_days=given("start_days", START_DAYS),
        **{
            key: parse_names(value, key.replace("_", " "))
            for key in ("archs", "test_periods", "price_scenarios")
            if (value := given(key)) is not None
        },
    )
    places = len(grid.periods) * len(grid.prices)
    check_grid_size(
        len(grid.cells()),
        large=a.large,
        what=f"{len(grid.scenarios)} scenario(s) x {len(grid.labels)} controller(s) and "
        f"the reference x {len(grid.seeds)} seed(s) x {len(grid.train_days)} training length(s)"
        + (f" x {places} test period(s) and price(s)" if grid.is_boptest else ""),
    )
    settings = SweepSettings.for_run(days=days, quick=quick, arch=given("arch", DEFAULT_ARCH))
    with output_lock(out):
        outcome = run_sweep(
            grid,
            settings,
            out,
            baseline=baseline or grid.labels[0],
            address=address,
            workers=workers,
            force=force,
        )
    s = outcome.summary
    total = s["cells_run"] + s["cells_reused"]
    reuse = (
        f"all {total} cells reused from {out}, none run"
        if s["cells_run"] == 0
        else f"{s['cells_run']} of {total} cells run now, {s['cells_reused']} reused"
    )
    lines = [
        f"{place_label(r):<18} {r['controller']:<16} "
        f"{'' if r.get('train_days') is None else str(r['train_days']) + ' d':<5} n={r['n']:<3} "
        f"objective/{r['reference']} {ratio(r, 'mean'):.3f} (worst {max(ratio(r, 'by_seed').values()):.3f})"
        for r in s["rows"]
    ]
    lines.append(
        f"sweep: {reuse}; models {s['models_trained']} trained, {s['models_reused']} reused; "
        f"wrote {outcome.summary_path}, {outcome.report_path}, {outcome.figure_path} "
        f"({s['wall_time_s']:.0f} s)"
    )
    return "\n".join(lines)


def _boptest_compare(a: argparse.Namespace) -> str:
    """``compare`` on a BOPTEST scenario: training data from the emulator, the identified RC,
    the default model and every model family (compare's training; ``--quick`` its small
    ensembles and short training), then boptest-baseline, the thermostat, qp-mpc and cem over
    each model on one test period; the JSON table and the report show BOPTEST's KPIs."""
    from scenarios.plants.boptest import TEST_PERIOD_DAYS, BoptestRun
    from scenarios.running.boptest_loop import (
        boptest_report,
        boptest_scenario,
        run_boptest_comparison,
    )

    if a.days is None:  # BOPTEST's KPIs are published for the whole test period
        a.days = int(TEST_PERIOD_DAYS)
    if a.days > TEST_PERIOD_DAYS:
        raise InputError(f"--days {a.days}: a BOPTEST test period has {TEST_PERIOD_DAYS:g} days")
    check_writable(a.json, a.report, create_parents=True)
    chosen = boptest_scenario(a.scenario)
    check_distinct(inputs={"--scenario": str(chosen.path)}, outputs={"--json": a.json, "--report": a.report})
    run = BoptestRun(
        time_period=a.test_period or "peak_heat_day", days=float(a.days),
        price_scenario=a.price_scenario or "dynamic",
    )
    from scenarios.experiments.compare import CompareSettings

    # compare's training (with --quick its small ensembles and short training); the power
    # limit is not imposed on the data: the emulator's heat pump draws more on cold days
    settings = CompareSettings.for_run(train_days=a.train_days, days=a.days, seed=a.seed, quick=a.quick)
    result = run_boptest_comparison(
        chosen, train_days=a.train_days, days=a.days, seed=a.seed, run=run,
        config=settings.train_config(eta=1.0, u_max_w=None),
        policy=a.policy or "closed-loop", progress=True,
    )
    text = boptest_report(result, scenario=chosen.name, run=run, days=a.days)
    for path in (Path(a.json), Path(a.report)):
        path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(a.json, {
        "scenario": chosen.name, "test_period": run.time_period,
        "price_scenario": run.price_scenario, "train_days": a.train_days, "days": a.days,
        "seed": a.seed, "quick": a.quick, "n_members": settings.n_seeds,
        "training_epochs": settings.training_epochs, "model": result.model, "rc": result.rc,
        "data_days": result.data_days,
        "wall_time_s": result.wall_time_s, "rows": result.rows,
    })
    atomic_write_text(Path(a.report), text)
    table = [ln for ln in text.splitlines() if ln.startswith("|")]
    return "\n".join([*table, f"wrote {a.json}, {a.report}"])
