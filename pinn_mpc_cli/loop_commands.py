"""The closed-loop commands: ``simulate`` (data from a scenario) and ``closed-loop`` (one
controller on one building, or a fleet of them).

Each takes the parsed arguments, refuses outputs that cannot be written, would overwrite an
input or another output, or exist already without ``--force`` (before any work), calls the library (which returns typed results),
writes the outputs atomically and returns the summary the CLI prints.
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pinn_mpc.data import fleet_params_path, write_fleet_params, write_timeseries
from pinn_mpc.errors import InputError, warn
from pinn_mpc.io import (
    PathsArg,
    atomic_write_json,
    check_distinct,
    check_new_files,
    check_writable,
    written_together,
)
from pinn_mpc.zones import zone_columns, zones_in
from pinn_mpc_cli.scenario_args import (
    refuse_boptest_options,
    scenario_inputs,
    scenario_label,
    with_scenario_file,
)
from scenarios.choices import MODEL_CONTROLLERS, ZONE_CONTROLLERS, ZONE_RC_CONTROLLERS
from scenarios.inputs.exogenous import day_span
from scenarios.inputs.registry import Scenario
from scenarios.inputs.scenario_file import get_scenario
from scenarios.reports.report import format_fleet, format_kpis
from scenarios.running.closed_loop import one_torch_thread, run_closed_loop
from scenarios.running.datagen import generate
from scenarios.running.factory import make_controller

if TYPE_CHECKING:
    from pinn_mpc.models.rollout import FittedModel

__all__ = ["closed_loop", "simulate"]


def simulate(a: argparse.Namespace) -> str:
    """Generate data and write it atomically to ``--out`` (never onto a file the scenario
    reads), a fleet's with its parameters file, together or not at all
    (:func:`pinn_mpc.io.written_together`); a run that would not fit in memory is refused
    before it starts."""
    from scenarios.running.boptest_loop import is_boptest_scenario
    from scenarios.running.budget import check_simulate_memory

    if is_boptest_scenario(a.scenario):
        return _boptest_simulate(a)
    refuse_boptest_options(
        {o: getattr(a, o) for o in ("first_day", "test_period")}, a.scenario,
        does="places data on a BOPTEST scenario",
    )
    if a.spread is not None and a.buildings < 2:
        raise InputError("--spread draws a fleet: add --buildings N with N > 1")
    sidecar = None
    if a.buildings > 1:  # the fleet closed loop over per-building models reads it
        sidecar = fleet_params_path(a.out)
    elif fleet_params_path(a.out).is_file():
        stale = fleet_params_path(a.out)
        raise InputError(
            f"--out {a.out}: {stale} next to it holds the buildings of an earlier `simulate "
            f"--buildings N` run and would no longer describe {a.out} (train --per-building reads "
            f"it); add --buildings N, choose another --out, or remove {stale}"
        )
    check_writable(a.out, sidecar)
    check_distinct(inputs=scenario_inputs(a.scenario), outputs={"--out": a.out, "fleet file": sidecar})
    check_new_files({"out": [a.out] if sidecar is None else [a.out, sidecar]}, force=a.force)
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
    with written_together():  # the data and its fleet file, or neither
        write_timeseries(frame, a.out)
        if sidecar is not None:  # without --spread every building is the scenario's
            write_fleet_params(
                a.out, fleet or [chosen.sim.params] * a.buildings,
                spread=0.0 if a.spread is None else a.spread,
            )
    per_building = len(frame) // a.buildings
    rooms = frame[list(zone_columns("T_r", zones_in(frame.columns)))].to_numpy()  # every zone's
    overridden = float(np.mean(~np.isclose(frame["u"], frame["u_phys"])))
    first, last = day_span(frame["time"])
    also = "" if sidecar is None else f"; wrote their parameters to {sidecar}"
    return (
        f"wrote {a.out}: scenario {scenario_label(a.scenario, chosen)}, {a.days} day(s) {first}..{last} "
        f"({a.weather_part} weather), {a.buildings} building(s), {policy} policy, "
        f"{per_building} rows per building at {chosen.sim.dt_s:g} s, T_r "
        f"{rooms.min():.1f}..{rooms.max():.1f} C, backup acted in "
        f"{100 * overridden:.0f} % of intervals{also}"
    )


def closed_loop(a: argparse.Namespace) -> str:
    """Run, write the KPI JSON (and CSV, plot) together or not at all
    (:func:`pinn_mpc.io.written_together`); the summary names every file written.
    Outputs are checked before the run: writable, none of them the same file as an input
    (``--model``'s files, ``--rc``) or as another output, and none existing without ``--force``."""
    with written_together():
        return _closed_loop(a)


def _closed_loop(a: argparse.Namespace) -> str:
    from scenarios.running.boptest_loop import is_boptest_scenario

    outputs = {"--json": a.json, "--csv": a.csv, "--plot": a.plot}
    check_writable(*outputs.values())
    if is_boptest_scenario(a.scenario):
        return _boptest_closed_loop(a, outputs)
    refuse_boptest_options({o: getattr(a, o) for o in ("test_period", "price_scenario")}, a.scenario)
    if a.days is None:  # only a BOPTEST scenario's test period has a length of its own
        raise InputError(
            f"closed-loop needs --days N (the counted days after a one-day warm-up) on "
            f"scenario {a.scenario}"
        )
    if a.online is not None:
        return _online_closed_loop(a)
    for option, given in (("--data", a.data is not None), ("--resume", a.resume),
                          ("--retrain-every", a.retrain_every != 1),
                          ("--online-seeds", a.online_seeds is not None),
                          ("--online-epochs", a.online_epochs is not None)):
        if given:
            raise InputError(f"{option} belongs to online operation: add --online DIR")
    inputs: dict[str, PathsArg] = {"--rc": a.rc, **scenario_inputs(a.scenario)}
    if a.model is not None:
        from pinn_mpc.fitted import model_files  # torch: only when a model is given
        from scenarios.fleets.training import FLEET_FILE, fleet_model_files

        fleet_dir = (Path(a.model) / FLEET_FILE).is_file()  # per-building models
        inputs["--model"] = fleet_model_files(a.model) if fleet_dir else model_files(a.model)
    check_distinct(inputs=inputs, outputs=outputs)
    _check_new_outputs(a)
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
    _check_controller_inputs(a, zones=not scenario.control_spec().single)
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
        from scenarios.reports.plots import plot_trajectory

        plot_trajectory(result.trajectory, a.plot, title=f"{a.controller} on {a.scenario}")
    kpis = with_scenario_file(result.kpis, a.scenario)
    if a.json is not None:
        atomic_write_json(a.json, kpis)
    lines = [format_kpis({**kpis, "scenario": scenario_label(a.scenario, scenario)})]
    if a.model is not None:
        from scenarios.running.factory import weather_range_note

        note = weather_range_note(controller.model, result.trajectory)
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
    return "\n".join([*lines, *_wrote(a.json, a.csv, a.plot)])


def _online_closed_loop(a: argparse.Namespace) -> str:
    """``closed-loop --online DIR``: :func:`scenarios.running.online.run_online`."""
    from pinn_mpc.data import read_timeseries
    from pinn_mpc.training import TrainConfig
    from scenarios.running.online import OnlineSettings, run_online

    for option, given in (("--model", a.model is not None), ("--rc", a.rc is not None),
                          ("--buildings", a.buildings != 1)):
        if given:
            raise InputError(f"{option} does not apply to --online: the controller fits its own from --data")
    _check_new_outputs(a)  # the files it writes beside DIR
    config = TrainConfig(
        **({} if a.online_seeds is None else {"n_seeds": a.online_seeds}),
        **({} if a.online_epochs is None else {"epochs": a.online_epochs}),
    )
    settings = OnlineSettings(controller=a.controller, retrain_every_days=a.retrain_every, config=config)
    data = None if a.data is None else read_timeseries(a.data)
    scenario = get_scenario(a.scenario)
    with one_torch_thread():
        result = run_online(
            scenario, data, days=a.days, seed=a.seed, out_dir=a.online, settings=settings,
            resume=a.resume, weather_part=a.weather_part, warn_weekdays=True,
        )
    if a.csv is not None:
        write_timeseries(result.trajectory, a.csv)
    kpis = with_scenario_file(result.kpis, a.scenario)
    if a.json is not None:
        atomic_write_json(a.json, kpis)
    if a.plot is not None:  # after the figures: a figure that fails loses none of them
        from scenarios.reports.plots import plot_trajectory

        plot_trajectory(result.trajectory, a.plot, title=f"{a.controller} online on {a.scenario}")
    online = result.kpis["online"]  # type: ignore[typeddict-item]
    lines = [
        format_kpis({**kpis, "scenario": scenario_label(a.scenario, scenario)}),
        f"online: {online['swaps']} swap(s), {online['refusals']} refusal(s) on the held-out day, "
        f"{online['guard_refusals']} by the guard ({online['deferred_swaps']} ran a night later), "
        f"{online['late_refits']} late refit(s); own decisions {100 * online['own_decisions_share']:.0f} %"
        f"{_without_model(result.log) if settings.learns_model else ''}; state in {a.online}",
    ]
    return "\n".join([*lines, *_wrote(a.json, a.csv, a.plot)])


def _without_model(log: Sequence[Mapping[str, Any]]) -> str:
    """``; N night(s) without a model (why the first)`` for the nights of an online run's
    ``log`` whose refit gave no model (the initial one included), or nothing."""
    from scenarios.running.online import MODEL_DAYS

    nights = [e for e in log if not e.get("model")]
    if not nights:
        return ""
    first = nights[0]
    held_out = "" if first["verdict"] == "initial" else " besides the held-out day"
    why = first.get("model_error") or f"fewer than {MODEL_DAYS} days of data{held_out}"
    return f"; {len(nights)} night(s) without a model (night {first['night']}: {why})"


def _check_new_outputs(a: argparse.Namespace) -> None:
    """Refuse, before the run, a ``--json``, ``--csv`` or ``--plot`` file that exists, unless
    ``--force``."""
    check_new_files({"json": a.json, "csv": a.csv, "plot": a.plot}, force=a.force)


def _wrote(*paths: str | None) -> list[str]:
    """The summary's last line naming the files written (none without any: the KPIs are
    printed only, as ``closed-loop`` without ``--json`` does)."""
    written = [str(p) for p in paths if p is not None]
    return [f"wrote {', '.join(written)}"] if written else []


def _check_controller_inputs(a: argparse.Namespace, *, zones: bool = False) -> None:
    """Refuse, in the user's terms, a controller without the file it plans with, a directory
    of per-building models for one building, or an RC file that is a directory (a model
    directory given to ``--rc``). On a building of several zones (``zones``) the planners
    plan on a multi-zone RC file, which the factory checks."""
    if a.controller in MODEL_CONTROLLERS and a.model is None and not zones:
        rc = "" if a.rc is None else " in place of --rc (a multi-zone RC file plans only a scenario of several zones)"
        raise InputError(
            f"controller {a.controller!r} plans over a trained model: add --model MODEL_DIR{rc} "
            "(make one with `pinn-mpc train --data data.csv --out MODEL_DIR`; "
            "data from `pinn-mpc simulate`)"
        )
    if a.model is not None:
        from scenarios.fleets.training import FLEET_FILE

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
    from scenarios.fleets.fleet import fleet_json, run_fleet_closed_loop
    from scenarios.fleets.zoned import is_zoned
    from scenarios.running.budget import check_fleet_memory, check_fleet_size

    batched = a.batched or a.cap_kw is not None or a.model is not None
    zoned = is_zoned(scenario)
    figure = _check_fleet_options(a, inputs, batched=batched, zoned=zoned)
    check_fleet_memory(scenario, a.controller, days=a.days, buildings=a.buildings)
    check_fleet_size(a.controller, buildings=a.buildings, days=a.days, large=a.large)
    spread = 0.2 if a.spread is None else a.spread
    planner: Any = a.controller
    fleet = None
    zone_rc = None
    if zoned and a.rc is not None:  # every building's RC planners plan on the identified building
        from scenarios.running.factory import read_zone_rc

        if a.controller not in ZONE_RC_CONTROLLERS:
            raise InputError(
                f"--rc is not used by controller {a.controller!r}; only "
                f"{', '.join(ZONE_RC_CONTROLLERS)} take it (a multi-zone RC file)"
            )
        zone_rc = read_zone_rc(a.rc, scenario.control_spec(), scenario.name)
    if a.model is not None:
        from scenarios.fleets.aggregator import learned_fleet_planner
        from scenarios.fleets.training import load_fleet_models

        models, fleet = load_fleet_models(a.model)
        if fleet is None:
            raise InputError(
                f"--model {a.model}: the buildings' parameters are unknown (the training data "
                "had no parameters file beside it, as `simulate --buildings N` writes one); the "
                "closed loop needs the buildings the models were trained on"
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
                cap_window=a.cap_window, fleet=fleet, rc=zone_rc, progress=True,
            )
        else:
            result = run_fleet_closed_loop(
                scenario, a.controller, n_buildings=a.buildings, days=a.days, seed=a.seed,
                spread=spread, weather_part=a.weather_part, rc=zone_rc, progress=True,
            )
    if a.json is not None:
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
    return "\n".join([*lines, *_wrote(a.json)])


def _check_fleet_options(
    a: argparse.Namespace, inputs: dict[str, PathsArg], *, batched: bool, zoned: bool = False
) -> str | None:
    """Refuse the options a fleet does not take, and a batched fleet's wrong controller or cap
    window; the fleet figure's path (written next to ``--json``) when the fleet is batched
    and ``--json`` is given. A fleet of buildings of several zones (``zoned``) takes a
    multi-zone RC file (``--rc``, the building its RC planners plan on), no trained model, and
    batches any zoned controller."""
    if zoned and a.model is not None:
        raise InputError(
            f"--model does not apply to a fleet of scenario {a.scenario} (several zones): its planners "
            "plan on each building's own RC, or all on --rc rc.json; run a trained model on one building"
        )
    for option, value in (("--rc", None if zoned else a.rc), ("--csv", a.csv), ("--plot", a.plot)):
        if value is not None:
            raise InputError(
                f"{option} does not apply to a fleet (--buildings {a.buildings}): "
                f"{_FLEET_REASONS[option]}; leave it out, or drop --buildings for one building"
            )
    if a.cap_window is not None and a.cap_kw is None:
        raise InputError("--cap-window needs --cap-kw (the cap in that window)")
    if not batched:
        return None
    from scenarios.fleets.aggregator import BATCHED_CONTROLLERS, parse_cap_window

    wanted = "cem" if a.model is not None else "qp-mpc"
    if zoned and a.controller not in ZONE_CONTROLLERS:
        raise InputError(
            f"controller {a.controller!r} plans one zone with one actuator; scenario {a.scenario} has "
            f"several zones: choose one of {', '.join(ZONE_CONTROLLERS)}"
        )
    if not zoned and a.controller != wanted:
        raise InputError(
            f"a batched fleet plans with qp-mpc (each building's RC) or, with --model DIR of "
            f"per-building models, with cem; got --controller {a.controller} "
            f"({'with' if a.model is not None else 'without'} --model); batched controllers: "
            f"{', '.join(BATCHED_CONTROLLERS)}"
        )
    if a.cap_window is not None:
        parse_cap_window(a.cap_window)
    if a.json is None:
        return None
    figure = str(Path(a.json).with_suffix(".fleet.png"))
    check_writable(figure)
    check_distinct(inputs=inputs, outputs={"--json": a.json, "figure": figure})
    check_new_files({"json": [a.json, figure]}, force=a.force)
    return figure


def _check_fleet_models_fit(root: str, models: Sequence[FittedModel], scenario: Scenario) -> None:
    """Each building's model checked against the scenario as one model is (actuator, power
    range, time constants: :func:`scenarios.running.factory.check_model_fits`): the first refusal
    names its building; the first building's warnings are shown with a count of the others."""
    from scenarios.running.factory import check_model_fits

    noted = []
    for b, model in enumerate(models):
        try:
            notes = check_model_fits(model, scenario)
        except InputError as exc:
            raise InputError(f"--model {root}, building {b}: {exc.marked}") from None
        if notes:
            noted.append((b, notes))
    if noted:
        b, notes = noted[0]
        others = f" (and notes on {len(noted) - 1} more of the {len(models)} buildings)" if len(noted) > 1 else ""
        for note in notes:
            warn(f"--model {root}, building {b}: {note}{others}")


def _boptest_simulate(a: argparse.Namespace) -> str:
    """``simulate`` on a BOPTEST scenario: the emulator's days off its test periods."""
    from scenarios.running.boptest_loop import DATA_FIRST_DAY, boptest_data, boptest_scenario

    for option, value in (("--buildings", a.buildings != 1), ("--spread", a.spread is not None),
                          ("--weather-part", a.weather_part != "train")):
        if value:
            raise InputError(f"{option} does not apply to a BOPTEST scenario (one emulated building, its own weather)")
    chosen = boptest_scenario(a.scenario)
    check_writable(a.out)
    check_distinct(inputs={"--scenario": str(chosen.path)}, outputs={"--out": a.out})
    check_new_files({"out": a.out}, force=a.force)
    if a.test_period is not None and a.first_day is not None:
        raise InputError("give --test-period (the days nearest it) or --first-day, not both")
    if a.test_period is not None:
        first_day = chosen.settings.points.data_first_day(a.test_period, float(a.days))
    else:
        first_day = DATA_FIRST_DAY if a.first_day is None else a.first_day
    policy = a.policy or "closed-loop"
    frame = boptest_data(
        chosen, days=a.days, seed=a.seed, policy=policy, first_day=first_day, progress=True
    )
    write_timeseries(frame, a.out)
    first, last = day_span(frame["time"])
    return (
        f"wrote {a.out}: BOPTEST scenario {chosen.name} ({chosen.settings.points.testcase}), "
        f"{a.days} day(s) {first}..{last}, {policy} policy, {len(frame)} rows at "
        f"{frame.attrs['dt_s']:g} s, T_r {frame['T_r'].min():.1f}..{frame['T_r'].max():.1f} C"
    )


def _boptest_closed_loop(a: argparse.Namespace, outputs: dict[str, str | None]) -> str:
    """``closed-loop`` on a BOPTEST scenario: one test period on the server; the KPI JSON
    carries BOPTEST's KPIs under ``boptest``."""
    from scenarios.plants.boptest import TEST_PERIOD_DAYS, BoptestRun
    from scenarios.running.boptest_loop import (
        BASELINE,
        boptest_controller,
        boptest_scenario,
        run_boptest_closed_loop,
    )

    for option, given in (("--buildings", a.buildings != 1), ("--spread", a.spread is not None),
                          ("--batched", a.batched), ("--cap-kw", a.cap_kw is not None),
                          ("--weather-part", a.weather_part != "test")):
        if given:
            raise InputError(f"{option} does not apply to a BOPTEST scenario (one emulated test case)")
    chosen = boptest_scenario(a.scenario)
    inputs: dict[str, PathsArg] = {"--rc": a.rc, "--scenario": str(chosen.path)}
    if a.model is not None:
        from pinn_mpc.fitted import model_files

        inputs["--model"] = model_files(a.model)
    check_distinct(inputs=inputs, outputs=outputs)
    _check_new_outputs(a)
    if a.days is not None and a.days > TEST_PERIOD_DAYS:
        raise InputError(
            f"--days {a.days}: a BOPTEST test period has {TEST_PERIOD_DAYS:g} days; give at most "
            f"{TEST_PERIOD_DAYS:g}, or leave --days out for the whole period"
        )
    run = BoptestRun(
        time_period=a.test_period or "peak_heat_day",
        days=TEST_PERIOD_DAYS if a.days is None else float(a.days),
        price_scenario=a.price_scenario or "dynamic", dt_s=1800.0,
    )
    if a.controller != BASELINE:
        _check_controller_inputs(a)
    controller = boptest_controller(
        a.controller, chosen, dt_s=run.dt_s, model_dir=a.model, rc_path=a.rc,
        n_steps=run.n_intervals,
    )
    threads = one_torch_thread() if a.controller in MODEL_CONTROLLERS else contextlib.nullcontext()
    with threads:
        result = run_boptest_closed_loop(
            chosen, a.controller, controller, run=run, seed=a.seed, progress=True
        )
    if a.csv is not None:
        write_timeseries(result.trajectory, a.csv)
    if a.plot is not None:
        from scenarios.reports.plots import plot_trajectory

        plot_trajectory(result.trajectory, a.plot, title=f"{a.controller} on {chosen.name}")
    if a.json is not None:
        atomic_write_json(a.json, result.kpis)
    b = result.kpis.get("boptest", {})
    lines = [
        format_kpis({**result.kpis, "scenario": chosen.name}),
        f"BOPTEST ({run.time_period}, {run.price_scenario} price): " + ", ".join(
            f"{key} {_number_text(b.get(key))}" for key in ("tdis_tot", "ener_tot", "cost_tot", "emis_tot", "time_rat")
        ),
    ]
    if result.errors:
        lines.append(f"{len(result.errors)} controller error(s), first: {result.errors[0]}")
    return "\n".join([*lines, *_wrote(a.json, a.csv, a.plot)])


def _number_text(value: object) -> str:
    """A KPI as the summary shows it: four significant digits, or ``-`` where BOPTEST gave none."""
    return f"{value:.4g}" if isinstance(value, int | float) else "-"
