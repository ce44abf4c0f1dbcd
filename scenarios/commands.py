"""The experiment commands of the CLI: ``simulate``, ``closed-loop``, ``compare``, ``reproduce``.

Each takes the parsed arguments, refuses outputs that cannot be written or would overwrite an
input or another output (before any work), calls the library (which returns typed results),
writes the outputs atomically and returns the summary the CLI prints. The model commands are in
:mod:`pinn_mpc.commands`; the parser is :mod:`pinn_mpc_cli.cli`.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from pinn_mpc.data import write_timeseries
from pinn_mpc.errors import InputError, warn
from pinn_mpc.io import (
    PathsArg,
    atomic_write_json,
    atomic_write_text,
    check_distinct,
    check_writable,
    file_sha256,
)
from scenarios.choices import MODEL_CONTROLLERS
from scenarios.inputs.exogenous import day_span
from scenarios.inputs.registry import Scenario
from scenarios.inputs.scenario_file import get_scenario
from scenarios.records import CompareTable, FleetInfo, FleetJson, RunKpis
from scenarios.reports.report import (
    format_fleet,
    format_kpis,
    kpi_table_text,
    prediction_table_text,
    render_report,
)
from scenarios.running.closed_loop import one_torch_thread, run_closed_loop
from scenarios.running.datagen import generate
from scenarios.running.factory import make_controller

if TYPE_CHECKING:  # compare loads torch: only the compare command imports it
    from scenarios.experiments.compare import CompareSettings, ComparisonResult
    from scenarios.fleets.fleet import FleetResult

__all__ = ["closed_loop", "compare", "reproduce", "scenario", "simulate", "sweep"]


def _scenario_inputs(name: str) -> dict[str, PathsArg]:
    """The files ``--scenario`` reads (the file and the files it names), as inputs to protect."""
    from scenarios.inputs.scenario_file import scenario_inputs

    return {
        f"--scenario {name}'s {key}" if key else "--scenario": path
        for key, path in scenario_inputs(name).items()
    }


def _scenario_label(name: str, scenario: Scenario) -> str:
    """The scenario as results name it: its name, and for a file the file too (a file may
    carry any name, a built-in's included)."""
    from scenarios.inputs.registry import is_scenario_file

    return f"{scenario.name} (file {name})" if is_scenario_file(name) else scenario.name


def simulate(a: argparse.Namespace) -> str:
    """Generate data and write it atomically to ``--out`` (never onto a file the scenario
    reads); a run that would not fit in memory is refused before it starts."""
    from scenarios.running.budget import check_simulate_memory

    sidecar = None
    if a.spread is not None:
        if a.buildings < 2:
            raise InputError("--spread draws a fleet: add --buildings N with N > 1")
        sidecar = fleet_params_path(a.out)
    elif fleet_params_path(a.out).is_file():
        stale = fleet_params_path(a.out)
        raise InputError(
            f"--out {a.out}: {stale} next to it holds the buildings of an earlier `simulate "
            f"--spread` run and would no longer describe {a.out} (train --per-building reads "
            f"it); add --spread, choose another --out, or remove {stale}"
        )
    check_writable(a.out, sidecar)
    check_distinct(inputs=_scenario_inputs(a.scenario), outputs={"--out": a.out, "fleet file": sidecar})
    chosen = get_scenario(a.scenario)
    check_simulate_memory(chosen, days=a.days, buildings=a.buildings)
    fleet = None
    if a.spread is not None:
        from pinn_mpc.simulator import draw_fleet
        from scenarios.fleets.fleet import FLEET_STREAM

        rng = np.random.default_rng([a.seed, FLEET_STREAM])
        fleet = draw_fleet(chosen.sim.params, a.buildings, spread=a.spread, rng=rng)
    policy = a.policy or chosen.data_policy
    frame = generate(
        chosen,
        days=a.days,
        seed=a.seed,
        policy=policy,
        n_buildings=a.buildings,
        weather_part=a.weather_part,
        fleet=fleet,
    )
    write_timeseries(frame, a.out)
    if sidecar is not None and fleet is not None:
        atomic_write_json(sidecar, {"spread": a.spread, "params": [dataclasses.asdict(p) for p in fleet],
                                    "data_sha256": file_sha256(a.out)})
    per_building = len(frame) // a.buildings
    overridden = float(np.mean(~np.isclose(frame["u"], frame["u_phys"])))
    first, last = day_span(frame["time"])
    also = "" if sidecar is None else f"; wrote their parameters to {sidecar}"
    return (
        f"wrote {a.out}: scenario {_scenario_label(a.scenario, chosen)}, {a.days} day(s) {first}..{last} "
        f"({a.weather_part} weather), {a.buildings} building(s), {policy} policy, "
        f"{per_building} rows per building at {chosen.sim.dt_s:g} s, T_r "
        f"{frame['T_r'].min():.1f}..{frame['T_r'].max():.1f} C, backup acted in "
        f"{100 * overridden:.0f} % of intervals{also}"
    )


def fleet_params_path(data: str | os.PathLike[str]) -> Path:
    """The file next to a fleet data set with its buildings' parameters (``simulate
    --spread``): ``fleet.csv`` -> ``fleet.fleet.json``."""
    return Path(data).with_suffix(".fleet.json")


def train(a: argparse.Namespace) -> str:
    """``train``: one ensemble (:func:`pinn_mpc.commands.train`), or with ``--per-building``
    one model per building of a fleet data set on Ray (:mod:`scenarios.fleets.training`)."""
    from pinn_mpc.commands import train as train_one

    if not a.per_building:
        for option, value in (("--address", a.address), ("--workers", a.workers)):
            if value is not None:
                raise InputError(f"{option} runs --per-building training on Ray; add --per-building")
        return train_one(a)
    import json

    from pinn_mpc.data import read_fleet_timeseries
    from pinn_mpc.physics import RCParams
    from pinn_mpc.training import TrainConfig
    from scenarios.fleets.training import train_per_building

    frames = read_fleet_timeseries(a.data, columns=a.columns)
    params = None
    sidecar = fleet_params_path(a.data)
    if sidecar.is_file():
        try:
            stored = json.loads(sidecar.read_text())
            params = [RCParams(**p) for p in stored["params"]]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise InputError(f"{sidecar}: not a fleet parameter file ({exc})") from None
        if stored.get("data_sha256") not in (None, file_sha256(a.data)):
            raise InputError(
                f"{sidecar} describes the buildings of another {a.data} (the data changed since "
                f"`simulate --spread` wrote both); simulate the fleet again, or remove {sidecar} "
                "to train without the buildings' parameters"
            )
        if len(params) != len(frames):
            raise InputError(
                f"{sidecar} holds {len(params)} buildings' parameters, {a.data} {len(frames)} "
                f"buildings; simulate the fleet again, or remove {sidecar}"
            )
    config = TrainConfig(
        depth=a.depth, n_seeds=a.seeds, first_seed=a.seed, epochs=a.epochs, lam=a.lam,
        recipe=a.recipe, eta=1.0 if a.eta is None else float(a.eta),
    )
    summary = train_per_building(
        frames, a.out, arch=a.arch, config=config, params=params, address=a.address, workers=a.workers
    )
    times = list(summary["train_seconds"].values())
    median = f", {float(np.median(times)):.1f} s per building (median)" if times else ""
    return (
        f"{len(summary['buildings'])} buildings: trained {len(summary['trained'])}, kept "
        f"{len(summary['kept'])} already there, in {summary['wall_seconds']:.0f} s{median}; "
        f"wrote {a.out}"
    )


def closed_loop(a: argparse.Namespace) -> str:
    """Run, write the KPI JSON (and CSV, plot); the summary names every file written.
    Outputs are checked before the run: writable, and none of them the same file as an input
    (``--model``'s files, ``--rc``) or as another output."""
    outputs = {"--json": a.json, "--csv": a.csv, "--plot": a.plot}
    check_writable(*outputs.values())
    inputs: dict[str, PathsArg] = {"--rc": a.rc, **_scenario_inputs(a.scenario)}
    if a.model is not None:
        from pinn_mpc.artifacts import MODEL_DIRECTORY  # torch: only when a model is given
        from scenarios.fleets.training import FLEET_FILE, fleet_model_files

        fleet_dir = (Path(a.model) / FLEET_FILE).is_file()  # per-building models
        inputs["--model"] = fleet_model_files(a.model) if fleet_dir else MODEL_DIRECTORY.paths(a.model)
    check_distinct(inputs=inputs, outputs=outputs)
    scenario = get_scenario(a.scenario)
    if a.buildings > 1:
        return _fleet_closed_loop(a, scenario, inputs)
    for option, given in (("--batched", a.batched), ("--cap-kw", a.cap_kw is not None),
                          ("--cap-window", a.cap_window is not None),
                          ("--rc-candidates", a.rc_candidates != "auto")):
        if given:
            raise InputError(f"{option} coordinates a fleet: add --buildings N with N > 1")
    if a.spread is not None:
        raise InputError("--spread draws a fleet: add --buildings N with N > 1")
    _check_controller_inputs(a)
    controller = make_controller(
        a.controller,
        scenario,
        model_dir=a.model,
        rc_path=a.rc,
        n_steps=a.days * scenario.steps_per_day,
    )
    # torch only for the planners over learned models; the others start faster without it.
    threads = one_torch_thread() if a.controller in MODEL_CONTROLLERS else contextlib.nullcontext()
    with threads:
        result = run_closed_loop(
            scenario, controller, days=a.days, seed=a.seed, weather_part=a.weather_part,
            progress=True,
        )
    if a.csv is not None:
        write_timeseries(result.trajectory, a.csv)
    if a.plot is not None:
        from scenarios.reports.plots import plot_trajectory  # matplotlib only when plotting

        plot_trajectory(result.trajectory, a.plot, title=f"{a.controller} on {a.scenario}")
    kpis = _with_scenario_file(result.kpis, a.scenario)
    atomic_write_json(a.json, kpis)
    lines = [format_kpis({**kpis, "scenario": _scenario_label(a.scenario, scenario)})]
    if a.model is not None:
        from scenarios.running.factory import weather_range_note

        note = weather_range_note(getattr(controller, "model", None), result.trajectory)
        if note is not None:
            warn(note)
    if "model_fallback_switches" in kpis:
        n_decisions = kpis["days"] * scenario.steps_per_day
        lines.append(
            f"model trusted in {n_decisions - kpis['model_fallback_steps']} of {n_decisions} "
            f"decisions; {kpis['model_fallback_switches']} switch(es) to the RC MPC fallback "
            f"{kpis['model_fallback_reasons'] or ''}".rstrip()
        )
    if result.errors:
        lines.append(f"{len(result.errors)} controller error(s), first: {result.errors[0]}")
    written = [str(p) for p in (a.json, a.csv, a.plot) if p is not None]
    return "\n".join([*lines, f"wrote {', '.join(written)}"])


def _check_controller_inputs(a: argparse.Namespace) -> None:
    """Refuse, in the user's terms, a controller without the file it plans with, a directory
    of per-building models for one building, or an RC file that is a directory (a model
    directory given to ``--rc``)."""
    if a.controller in MODEL_CONTROLLERS and a.model is None:
        raise InputError(
            f"controller {a.controller!r} plans over a trained model: add --model MODEL_DIR "
            "(make one with `pinn-mpc train --data data.csv --out MODEL_DIR`; "
            "data from `pinn-mpc simulate`)"
        )
    if a.model is not None:
        from scenarios.fleets.training import FLEET_FILE  # torch: only when a model is given

        if (Path(a.model) / FLEET_FILE).is_file():
            raise InputError(
                f"--model {a.model} holds one model per building (train --per-building), not "
                "one model: run the fleet it was trained on with --buildings N --controller "
                f"cem, or give a model directory of `pinn-mpc train` (one of {a.model}/buildings/*)"
            )
    if a.rc is not None and Path(a.rc).is_dir():
        hint = (
            " (it is a model directory: give it as --model to cem or random-shooting, or write "
            f"its RC with `pinn-mpc export-rc --model {a.rc} --out rc.json`)"
            if (Path(a.rc) / "model.json").is_file()
            else ""
        )
        raise InputError(
            f"--rc {a.rc} is a directory, not an RC JSON file{hint}; give the rc.json written "
            "by `pinn-mpc identify` or `pinn-mpc export-rc`"
        )


#: A record that names its scenario file (``scenario_file``) when ``--scenario`` is one.
_Labelled = TypeVar("_Labelled", RunKpis, FleetInfo)


def _with_scenario_file(kpis: _Labelled, name: str) -> _Labelled:
    """The KPIs with ``scenario_file`` (absolute) when ``--scenario`` is a file: its ``name``
    alone may be anything, a built-in's included."""
    from scenarios.inputs.registry import is_scenario_file

    if not is_scenario_file(name):
        return kpis
    return {**kpis, "scenario_file": os.path.abspath(name)}


_FLEET_REASONS = {
    "--model": "each building's controller plans over that building's own RC, not a shared "
    "model",
    "--rc": "each building's controller works on that building's own RC",
    "--csv": "a trajectory CSV holds one building; the KPI JSON (--json) holds every building",
    "--plot": "a trajectory figure shows one building; the KPI JSON (--json) holds every "
    "building",
}


def _fleet_closed_loop(a: argparse.Namespace, scenario: Scenario, inputs: dict[str, PathsArg]) -> str:
    """``closed-loop --buildings N``: the fleet run, its JSON (fleet, totals, step times,
    aggregate power, district KPIs, the cap's account, buildings); each building's controller
    is built on its own parameters, one after another, or the fleet is planned in one batch
    (``--batched``, ``--cap-kw``; then the fleet figure is written next to the JSON). A fleet
    that would not fit in memory is refused before anything is built."""
    from scenarios.fleets.fleet import run_fleet_closed_loop
    from scenarios.running.budget import check_fleet_memory, check_fleet_size

    batched = a.batched or a.cap_kw is not None or a.model is not None
    for option, value in (("--rc", a.rc), ("--csv", a.csv), ("--plot", a.plot)):
        if value is not None:
            raise InputError(
                f"{option} does not apply to a fleet (--buildings {a.buildings}): "
                f"{_FLEET_REASONS[option]}; leave it out, or drop --buildings for one building"
            )
    if a.cap_window is not None and a.cap_kw is None:
        raise InputError("--cap-window needs --cap-kw (the cap in that window)")
    figure = None
    if batched:
        from scenarios.fleets.aggregator import BATCHED_CONTROLLERS, parse_cap_window

        wanted = "cem" if a.model is not None else "qp-mpc"
        if a.controller != wanted:
            raise InputError(
                f"a batched fleet plans with qp-mpc (each building's RC) or, with --model DIR of "
                f"per-building models, with cem; got --controller {a.controller} "
                f"({'with' if a.model is not None else 'without'} --model); batched controllers: "
                f"{', '.join(BATCHED_CONTROLLERS)}"
            )
        if a.cap_window is not None:
            parse_cap_window(a.cap_window)
        figure = str(Path(a.json).with_suffix(".fleet.png"))
        check_writable(figure)
        check_distinct(inputs=inputs, outputs={"--json": a.json, "figure": figure})
    check_fleet_memory(scenario, a.controller, days=a.days, buildings=a.buildings)
    check_fleet_size(a.controller, buildings=a.buildings, days=a.days, large=a.large)
    spread = 0.2 if a.spread is None else a.spread
    planner: Any = a.controller
    fleet = None
    if a.model is not None:
        from scenarios.fleets.aggregator import learned_fleet_planner
        from scenarios.fleets.training import load_fleet_models

        models, fleet = load_fleet_models(a.model)
        if fleet is None:
            raise InputError(
                f"--model {a.model}: the buildings' parameters are unknown (the data was "
                "simulated without --spread); the closed loop needs the buildings the models "
                "were trained on"
            )
        if len(models) != a.buildings:
            raise InputError(f"--model {a.model} holds {len(models)} buildings, --buildings is {a.buildings}")
        if a.spread is not None:
            raise InputError("--spread does not apply with --model: the buildings are the models' own")
        _check_fleet_models_fit(a.model, models, scenario)
        candidates = a.rc_candidates == "on" or (a.rc_candidates == "auto" and a.cap_kw is not None)
        planner = learned_fleet_planner(models, rc_candidates=candidates)
    elif a.rc_candidates != "auto":
        raise InputError("--rc-candidates applies to the batched cem over learned models: add --model DIR")
    # One building's planner rolls out small tensors (one thread is fastest); a fleet's batched
    # rollout (buildings x samples x horizon) is large enough for torch's threads to pay.
    small = a.controller in MODEL_CONTROLLERS and a.model is None
    threads = one_torch_thread() if small else contextlib.nullcontext()
    with threads:
        if batched:
            from scenarios.fleets.aggregator import run_coordinated_fleet

            result = run_coordinated_fleet(
                scenario, planner, n_buildings=a.buildings, days=a.days, seed=a.seed,
                spread=spread, weather_part=a.weather_part, cap_kw=a.cap_kw,
                cap_window=a.cap_window, fleet=fleet, progress=True,
            )
        else:
            result = run_fleet_closed_loop(
                scenario, a.controller, n_buildings=a.buildings, days=a.days, seed=a.seed,
                spread=spread, weather_part=a.weather_part, progress=True,
            )
    atomic_write_json(a.json, fleet_json(result, a.scenario))
    lines = [format_fleet(result)]
    if result.cap is not None:
        c = result.cap
        lines.append(
            f"cap {c['kw']:.4g} kW ({c['window'] or 'all day'}): {c['intervals_over']} of "
            f"{c['intervals']} capped intervals over it, {c['kwh_over']:.2f} kWh over"
        )
    if result.errors:
        lines.append(f"{len(result.errors)} controller error(s), first: {result.errors[0]}")
    if figure is not None:
        from scenarios.fleets.aggregator import cap_in_force
        from scenarios.reports.plots import fleet_figure, save_figure

        cap_kw = None if result.cap is None else cap_in_force(result.times, result.cap)
        discomfort = np.array([k["discomfort_kh"] for k in result.kpis])
        title = f"{result.info['controller']} x {result.info['n_buildings']} on {result.info['scenario']}"
        save_figure(
            fleet_figure(result.times, result.aggregate_u_phys_w / 1000.0, discomfort,
                         cap_kw=cap_kw, title=title),
            figure,
        )
        lines.append(f"wrote {figure}")
    return "\n".join([*lines, f"wrote {a.json}"])


def _check_fleet_models_fit(root: str, models: list[Any], scenario: Scenario) -> None:
    """Each building's model checked against the scenario as one model is (actuator, power
    range, time constants: :func:`scenarios.running.factory.check_model_fits`): the first refusal
    names its building; the first building's warnings are shown with a count of the others."""
    from scenarios.running.factory import check_model_fits

    noted = []
    for b, model in enumerate(models):
        try:
            notes = check_model_fits(model, scenario)
        except InputError as exc:
            raise InputError(f"--model {root}, building {b}: {exc}") from None
        if notes:
            noted.append((b, notes))
    if noted:
        b, notes = noted[0]
        others = f" (and notes on {len(noted) - 1} more of the {len(models)} buildings)" if len(noted) > 1 else ""
        for note in notes:
            warn(f"--model {root}, building {b}: {note}{others}")


def fleet_json(result: FleetResult, scenario_arg: str) -> FleetJson:
    """The fleet JSON: ``fleet`` (what ran), ``totals``, ``district`` KPIs, ``aggregate``
    (``time``, ``power_kw`` per counted interval), ``cap`` (None without one), ``fell_back``
    (the buildings whose fallback or whose model's RC MPC acted at least once), ``step_time``
    and ``buildings``."""
    return {
        "fleet": _with_scenario_file(result.info, scenario_arg),
        "totals": result.totals,
        "district": result.district,
        "aggregate": {
            "time": list(result.times),
            "power_kw": [round(float(v) / 1000.0, 4) for v in result.aggregate_u_phys_w],
        },
        "cap": result.cap,
        "fell_back": [
            k["building"] for k in result.kpis
            if k["fallbacks"] > 0 or k.get("model_fallback_steps", 0) > 0
        ],
        "step_time": result.step_time,
        "buildings": [
            {**kpis, "params": dataclasses.asdict(params)}
            for kpis, params in zip(result.kpis, result.params, strict=True)
        ],
    }


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
    """Run the comparison, write the JSON table, the report and its figure (parents created)."""
    from scenarios.experiments.compare import CompareSettings, run_comparison
    from scenarios.experiments.prediction import PREDICTION_HORIZON

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
    check_distinct(inputs=_scenario_inputs(a.scenario), outputs=outputs)
    scenario = get_scenario(a.scenario)
    settings = CompareSettings.for_run(
        train_days=a.train_days, days=a.days, seed=a.seed, quick=a.quick,
        policy=a.policy or scenario.data_policy,
    )
    start = time.perf_counter()
    result = run_comparison(scenario, settings)
    total_s = time.perf_counter() - start
    settings_table = _settings_table(a.scenario, scenario, settings, result, total_s)
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
    from scenarios.reports.plots import plot_comparison  # matplotlib only when plotting

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
    from scenarios.inputs.registry import is_scenario_file
    from scenarios.reports.sweep_report import ratio
    from scenarios.running.budget import check_grid_size

    spec = read_sweep_spec(a.spec) if a.spec is not None else {}

    def given(name: str, default: Any = None) -> Any:
        value = getattr(a, name)
        return value if value is not None else spec.get(name, default)

    scenarios, controllers, seeds = given("scenarios"), given("controllers"), given("seeds")
    missing = [f"--{n}" for n, v in (("scenarios", scenarios), ("controllers", controllers), ("seeds", seeds)) if v is None]
    if missing:
        raise InputError(f"sweep needs {', '.join(missing)} (or a --spec file that gives them)")
    train_days, days = given("train_days", "30"), given("days", 3)
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
    )
    check_grid_size(
        len(grid.cells()),
        large=a.large,
        what=f"{len(grid.scenarios)} scenario(s) x {len(grid.controllers)} controller(s) and "
        f"the reference x {len(grid.seeds)} seed(s) x {len(grid.train_days)} training length(s)",
    )
    settings = SweepSettings.for_run(days=days, quick=quick, arch=given("arch", DEFAULT_ARCH))
    outcome = run_sweep(
        grid,
        settings,
        out,
        baseline=baseline or grid.controllers[0],
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
        f"{r['scenario']:<18} {r['controller']:<16} "
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


def scenario(a: argparse.Namespace) -> str:
    """``pinn-mpc scenario list | show NAME | export NAME --out FILE.toml``."""
    from scenarios.inputs.scenario_file import scenario_command

    return scenario_command(
        a.action,
        name=getattr(a, "name", None),
        out=getattr(a, "out", None),
        force=getattr(a, "force", False),
    )
