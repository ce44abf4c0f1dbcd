"""The model commands: ``train``, ``evaluate``, ``export-rc``, ``identify``.

Each takes the parsed arguments, refuses outputs that cannot be written, would overwrite an
input or another output, or exist already without ``--force`` (a model directory: as
:func:`pinn_mpc.io.check_output_directory` says) before any work, calls the library (which
returns typed results and never writes), writes the outputs atomically and returns the
summary the CLI prints.
Libraries are imported inside the commands, so that ``identify`` does not wait for torch.
"""

from __future__ import annotations

import argparse
import re
import time
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pinn_mpc.actuator import actuator_columns
from pinn_mpc.choices import AUTO
from pinn_mpc.data import read_timeseries
from pinn_mpc.errors import InputError, InternalError, setting, warn
from pinn_mpc.io import (
    atomic_write_json,
    check_distinct,
    check_new_files,
    check_output_directory,
    check_writable,
    output_lock,
)
from pinn_mpc.physics import rc_summary
from pinn_mpc.records import EvaluationMetrics, HorizonErrors
from pinn_mpc.zones import zones_in

if TYPE_CHECKING:
    import pandas as pd

    from pinn_mpc.model_choice import ModelChoice
    from pinn_mpc.models.arx import ARXModel
    from pinn_mpc.models.learned import LearnedModel
    from pinn_mpc.models.multizone_arx import MultiZoneARX
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid
    from pinn_mpc.models.multizone_paper import MultiZonePaperModel
    from pinn_mpc.training import TrainConfig
    from scenarios.inputs.registry import Scenario

__all__ = ["evaluate", "export_rc_json", "identify", "train"]


def train(a: argparse.Namespace) -> str:
    """``train``: one ensemble, or with ``--per-building`` one model per building of a fleet
    data set on Ray (:func:`scenarios.fleets.training.train_per_building`); ``--out`` is held
    by this run until it ends (:func:`pinn_mpc.io.output_lock`)."""
    if not a.per_building:
        for option, value in (("--address", a.address), ("--workers", a.workers)):
            if value is not None:
                raise InputError(f"{option} runs --per-building training on Ray; add --per-building")
    with output_lock(a.out):
        return _train_one(a) if not a.per_building else _train_per_building(a)


def _train_per_building(a: argparse.Namespace) -> str:
    """``train --per-building``: each building's model (``--arch``, any ``train`` takes)."""
    from pinn_mpc.data import read_fleet_params, read_fleet_timeseries
    from scenarios.fleets.training import train_per_building

    frames = read_fleet_timeseries(a.data, columns=a.columns)
    params = read_fleet_params(a.data, len(frames))
    config = _train_config(a)
    summary = train_per_building(
        frames, a.out, arch=a.arch, config=config, params=params, address=a.address, workers=a.workers
    )
    times = list(summary["train_seconds"].values())
    median = f", {float(np.median(times)):.1f} s per building (median)" if times else ""
    kinds = sorted(set(summary["chosen"].values()))
    counts = ", ".join(f"{list(summary['chosen'].values()).count(k)} {k}" for k in kinds)
    chose = f" ({counts})" if a.arch == AUTO and counts else ""
    return (
        f"{len(summary['buildings'])} buildings: trained {len(summary['trained'])}{chose}, kept "
        f"{len(summary['kept'])} already there, in {summary['wall_seconds']:.0f} s{median}; "
        f"wrote {a.out}"
    )


def _train_config(a: argparse.Namespace) -> TrainConfig:
    """The training settings of ``train``'s flags; a value :class:`TrainConfig` refuses (a
    ``--depth`` or ``--seeds`` above its limit, an implausible ``--eta``) is the user's to fix,
    named by its flag."""
    from pinn_mpc.training import TrainConfig

    try:
        return TrainConfig(
            depth=a.depth, n_seeds=a.seeds, first_seed=a.seed, epochs=a.epochs, lam=a.lam,
            recipe=a.recipe, eta=_eta(a.eta),
        )
    except ValueError as exc:
        text = exc.marked if isinstance(exc, InputError) else str(exc)
        raise InputError(re.sub(r"\bTrainConfig\.(\w+)", lambda m: setting(m[1]), text)) from None


def _eta(value: float | None) -> float:
    """``--eta`` not given means 1: a heater (a cooling machine gives minus its COP)."""
    return 1.0 if value is None else float(value)


def _train_one(a: argparse.Namespace) -> str:
    """Read ``--data``, fit the model ``--arch`` names (:func:`pinn_mpc.fitted.fit`: a network's
    ensemble, a least-squares ARX, or with ``auto``, the default, the hybrid, the
    physics-informed ARX or ``pcnn-parx``, whichever predicts the data's last quarter better),
    save it into the model directory ``--out``.

    ``--out`` is checked before fitting: it must be new, empty or a model directory of the kind
    ``--arch`` writes (``auto``: either), or ``--force`` given (then only model files in it are
    replaced). It ends holding one model: the other kind's files are removed.
    """
    from pinn_mpc.fitted import fit, output_layout, save
    from pinn_mpc.models.registry import BASELINES
    from pinn_mpc.training import data_warnings

    network_options = [f"--{n}" for n in ("depth", "epochs", "lam", "recipe") if getattr(a, n, None) is not None]
    unused = ", ".join(network_options).replace("--lam", "--lambda")
    if a.arch in BASELINES and network_options:
        raise InputError(
            f"train --arch {a.arch}: {unused} do(es) not apply to the least-squares ARX model; "
            "leave them out"
        )
    # Every layout lists every model file: the data must be none of them, checked before reading.
    check_distinct(inputs={"--data": a.data}, outputs={"--out": output_layout(a.arch).paths(a.out)})
    df = read_timeseries(a.data, columns=a.columns, zones=True)
    zoned = len(zones_in(df.columns)) > 1
    if zoned:
        _check_zone_training(a, network_options)
    check_output_directory(a.out, output_layout(a.arch, zones=zoned), force=a.force)
    if zoned:
        return _train_zones(a, df)
    _check_one_zone(a)
    df = read_timeseries(a.data, columns=a.columns)
    if a.arch in BASELINES and "building" in df.columns:
        raise InputError(f"{a.data}: a fleet's data (a building column); train --arch {a.arch} takes one building's")
    config = _train_config(a)
    start = time.perf_counter()
    choice = fit(df, arch=a.arch, config=config, progress=True)
    seconds = time.perf_counter() - start
    if choice.caution:
        warn(f"{a.data}: {choice.caution}")
    for message in data_warnings(df):
        warn(f"{a.data}: {message}")
    if choice.caution is None:  # the caution says it where it is given
        _warn_without_fallback(a.data, choice.model.identified_rc)
    if a.arch == AUTO and choice.chosen in BASELINES and network_options:
        warn(f"{unused} did not apply: the chosen model has no network")
    written = ", ".join(map(str, save(choice.model, a.out)))
    return f"{_fitted_line(a.arch, choice, len(df), seconds)}; wrote {written}"


def _check_zone_training(a: argparse.Namespace, network_options: list[str]) -> None:
    """Refuse in one line what ``train`` does not fit on data of several zones: another
    ``--arch`` than auto, hybrid or parx, and a network ensemble's options."""
    from pinn_mpc.models.multizone_paper import ARCHS as PAPER_ARCHS
    from pinn_mpc.models.registry import DEFAULT_ARCH, PHYSICS_ARX

    if a.arch not in (AUTO, DEFAULT_ARCH, PHYSICS_ARX.name, *PAPER_ARCHS):
        raise InputError(
            f"train --arch {a.arch}: on a building of several zones train fits the {DEFAULT_ARCH} "
            f"(each zone's RC and walls identified, a learned residual heat per zone), the {PHYSICS_ARX.name} "
            f"(a physics-informed ARX per zone) or the paper's {' or '.join(PAPER_ARCHS)} per zone (coupled "
            f"through learned walls); give --arch {AUTO}, {DEFAULT_ARCH}, {PHYSICS_ARX.name}, {', '.join(PAPER_ARCHS)}"
        )
    given = [*network_options, *(["--seeds"] if a.seeds != 20 else [])]
    if given:
        raise InputError(
            f"train: {', '.join(given).replace('--lam', '--lambda')} set a network ensemble's training; the "
            "models of several zones have their own settings: leave them out"
        )


def _train_zones(a: argparse.Namespace, df: pd.DataFrame) -> str:
    """``train`` on data of several zones: with ``--arch auto`` the multi-zone hybrid or
    physics-informed ARX of ``--scenario``'s layout, whichever predicts the data's last quarter
    better, or the one ``--arch`` names
    (:func:`scenarios.experiments.compare.train_scenario_zones`), saved into ``--out``."""
    from pinn_mpc.fitted import save
    from pinn_mpc.models.multizone_arx import MultiZoneARX
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid
    from pinn_mpc.models.multizone_paper import MultiZonePaperModel
    from pinn_mpc.models.registry import DEFAULT_ARCH, PHYSICS_ARX
    from scenarios.experiments.compare import train_scenario_zones

    scenario = _zone_layout(a, df, "training on them")
    start = time.perf_counter()
    choice = train_scenario_zones(scenario, df, seed=a.seed, arch=a.arch)
    seconds = time.perf_counter() - start
    model = choice.model
    written = ", ".join(map(str, save(model, a.out)))
    names = ", ".join(z.name for z in model.zones)
    chose = f"chose {choice.chosen} ({choice.why}); " if a.arch == AUTO else ""
    if isinstance(model, MultiZoneARX):
        c = model.coefficients
        what = (
            f"the {PHYSICS_ARX.name} of {len(model.zones)} zones ({names}; {c.lags} lags of each room, "
            f"{c.power_lags} of each heat, settling radius {c.settling_radius():.3f})"
        )
    elif isinstance(model, MultiZoneHybrid):
        sel = model.selection
        errors = sel.get("held_out_mae_c")
        judged = (
            f"residual {'kept' if sel['kept'] else 'dropped'}: held-out {sel['horizon_steps']}-step MAE "
            f"{errors['with_residual']:.3f} C with it, {errors['rc']:.3f} C without"
            if errors else f"no residual: {sel.get('why', 'not judged')}"
        )
        walls = ", ".join(f"{x}-{y} {u:.4g} W/K" for (x, y), u in model.identified.walls.items()) or "none"
        what = f"the {DEFAULT_ARCH} of {len(model.zones)} zones ({names}; walls {walls}; {judged})"
    elif isinstance(model, MultiZonePaperModel):
        loss = model.training["final_loss"]
        walls = ", ".join(f"{x}-{y} {u:.4g} W/K" for (x, y), u in model.learned_rc().walls.items()) or "none"
        what = (
            f"the {model.family} of {len(model.zones)} zones ({names}; learned walls {walls}; final loss reg "
            f"{loss['reg']:.3g}, phys {loss['phys']:.3g})"
        )
    else:
        raise InternalError(f"train on several zones made a {type(model).__name__}")
    return f"{chose}fitted {what} on {len(df)} rows in {seconds:.1f} s; wrote {written}"


def _fitted_line(arch: str, choice: ModelChoice, rows: int, seconds: float) -> str:
    """What ``train`` fitted, on how many rows, in how long, and how well it fits them."""
    from pinn_mpc.models.arx import ARXModel
    from pinn_mpc.models.learned import LearnedModel

    model = choice.model
    if arch == AUTO:
        return f"chose {choice.chosen} ({choice.why}) on {rows} rows in {seconds:.1f} s"
    if isinstance(model, ARXModel):
        return (
            f"fitted {arch} ({model.lags} lags of {', '.join(model.columns)}, a weekly schedule) "
            f"on {rows} rows in {seconds:.2f} s (one-step MAE {model.train_mae_c:.3f} C)"
        )
    if isinstance(model, LearnedModel):
        loss = model.record.final_loss
        return (
            f"trained {arch} x{model.n_members} on {rows} rows in {model.record.train_seconds:.1f} s "
            f"(final loss reg {loss['reg']:.3g}, phys {loss['phys']:.3g})"
        )
    raise InternalError(f"train fitted a {type(model).__name__}, which it cannot describe")


def _warn_without_fallback(data: str, identified_rc: object) -> None:
    """Say so when no RC could be identified from the training data: cem and random-shooting
    over the model then have no RC MPC to hand their decisions to."""
    if identified_rc is None:
        warn(
            f"{data}: no RC could be identified from the data (`pinn-mpc identify` says why), so "
            "cem and random-shooting over this model have no RC MPC to fall back on"
        )


def _arx_metrics(model: ARXModel, df: pd.DataFrame, a: argparse.Namespace) -> EvaluationMetrics:
    """An ARX model's errors on ``df``: T_r MAE one step and ``--horizons`` ahead."""
    horizons: dict[str, HorizonErrors] = {}
    for h in sorted(set(a.horizons) | {1}):
        mae = model.horizon_mae(df, h)
        if mae is not None:
            horizons[str(h)] = {"T_r_mae": mae}
    if "1" not in horizons:
        raise InputError(f"{a.data}: too few rows for the ARX model's {model.lags} lags")
    return {"one_step": {"T_r_mae": horizons["1"]["T_r_mae"]}, "horizons": horizons}


def _network_metrics(learned: LearnedModel, df: pd.DataFrame, a: argparse.Namespace) -> EvaluationMetrics:
    """A network's errors on ``df`` (:func:`pinn_mpc.evaluation.evaluate_model`), after a
    warning when the data and the training data disagree on a heat pump (a ``cop`` column)."""
    from pinn_mpc.evaluation import evaluate_model

    trained_on = learned.meta.get("training_data", {}).get("columns", [])
    if ("cop" in df.columns) != ("cop" in trained_on):
        has, lacks = ("the data", "the model's training data") if "cop" in df.columns else ("the model's training data", "the data")
        warn(
            f"{has} has a cop column (a heat pump) and {lacks} has none: "
            "the model may be evaluated on another actuator than it was made for"
        )
    return evaluate_model(learned, df, a.horizons)


def evaluate(a: argparse.Namespace) -> str:
    """Load ``--model`` (any model directory, :func:`pinn_mpc.fitted.load`) and ``--data``,
    write the metrics JSON ``--json``: a network's one-step errors of T_r, u_phys and T_m and
    its ``--horizons``-step T_r errors against persistence; an ARX's T_r errors."""
    from pinn_mpc.fitted import load, model_files
    from pinn_mpc.models.arx import ARXModel
    from pinn_mpc.models.learned import LearnedModel
    from pinn_mpc.models.multizone_arx import MultiZoneARX
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid
    from pinn_mpc.models.multizone_paper import MultiZonePaperModel

    check_writable(a.json)
    _refuse_fleet_directory(a.model, "evaluate", "--data BUILDING.csv --json metrics.json")
    check_distinct(inputs={"--model": model_files(a.model), "--data": a.data}, outputs={"--json": a.json})
    check_new_files({"json": a.json}, force=a.force)
    model = load(a.model)
    if isinstance(model, MultiZoneHybrid | MultiZoneARX | MultiZonePaperModel):
        return _evaluate_zones(model, a)
    df = read_timeseries(a.data, columns=a.columns)
    if isinstance(model, ARXModel):
        metrics = _arx_metrics(model, df, a)
    elif isinstance(model, LearnedModel):
        metrics = _network_metrics(model, df, a)
    else:
        raise InternalError(f"evaluate cannot evaluate a {type(model).__name__}")
    atomic_write_json(a.json, metrics)
    one = metrics["one_step"]
    last = max(int(h) for h in metrics["horizons"])
    last_mae = metrics["horizons"][str(last)]["T_r_mae"]
    if "persistence" not in metrics:
        return (
            f"one-step MAE: T_r {one['T_r_mae']:.3f} C; {last}-step T_r MAE {last_mae:.3f} C "
            f"-> {a.json}"
        )
    t_m = f", T_m {one['T_m_mae']:.3f} C" if one["T_m_mae"] is not None else ""
    return (
        f"one-step MAE: T_r {one['T_r_mae']:.3f} C, u_phys {one['u_phys_mae']:.0f} W{t_m}; "
        f"{last}-step T_r MAE {last_mae:.3f} C "
        f"(persistence {metrics['persistence']['horizons'][str(last)]['T_r_mae']:.3f} C) "
        f"-> {a.json}"
    )


def _evaluate_zones(model: MultiZoneHybrid | MultiZoneARX | MultiZonePaperModel, a: argparse.Namespace) -> str:
    """``evaluate`` of a model of several zones (:func:`pinn_mpc.evaluation.evaluate_zone_model`)
    on ``--data`` of its building: each zone's errors, written to ``--json``."""
    from pinn_mpc.evaluation import evaluate_zone_model

    df = read_timeseries(a.data, columns=a.columns, zones=True)
    metrics = evaluate_zone_model(model, df, a.horizons)
    atomic_write_json(a.json, metrics)
    last = str(max(int(h) for h in metrics["horizons"]))
    ahead, still = metrics["horizons"][last], metrics["persistence"]["horizons"][last]
    per_zone = ", ".join(f"{name} {mae:.3f}" for name, mae in ahead.get("zones", {}).items())
    return (
        f"one-step MAE of the rooms: {metrics['one_step']['T_r_mae']:.3f} C; {last}-step {ahead['T_r_mae']:.3f} C "
        f"(persistence {still['T_r_mae']:.3f} C; by zone {per_zone}) -> {a.json}"
    )


def _refuse_fleet_directory(model: str, command: str, rest: str) -> None:
    """A per-building directory (``train --per-building``) holds one model per building: say
    which to give instead."""
    from scenarios.fleets.training import FLEET_FILE, building_model_dir

    if (Path(model) / FLEET_FILE).is_file():
        raise InputError(
            f"--model {model} holds one model per building (train --per-building), not one "
            f"model: {command} each building's, e.g. `pinn-mpc {command} --model "
            f"{building_model_dir(model, 0)} {rest}`"
        )


def export_rc_json(a: argparse.Namespace) -> str:
    """``export-rc``: load ``--model`` (any model directory, :func:`pinn_mpc.fitted.load`),
    write its RC JSON ``--out``: a physics-informed network's learned R/C values, or the RC an
    ARX model carries (identified from its training data by ``train``); of a model of several
    zones, its multi-zone RC file (each zone's R and C, each wall's conductance), which qp-mpc
    takes with ``--rc``."""
    from pinn_mpc.export import export_rc
    from pinn_mpc.fitted import load, model_files
    from pinn_mpc.models.arx import ARXModel
    from pinn_mpc.models.learned import LearnedModel
    from pinn_mpc.models.multizone_arx import MultiZoneARX
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid
    from pinn_mpc.models.multizone_paper import MultiZonePaperModel

    check_writable(a.out)
    _refuse_fleet_directory(a.model, "export-rc", "--out rc.json")
    check_distinct(inputs={"--model": model_files(a.model)}, outputs={"--out": a.out})
    check_new_files({"out": a.out}, force=a.force)
    model = load(a.model)
    if isinstance(model, MultiZoneHybrid | MultiZoneARX | MultiZonePaperModel):
        # The RC it carries; the paper's networks' learned one (its R, C and walls trained).
        rc = model.learned_rc() if isinstance(model, MultiZonePaperModel) else model.identified
        what = "the learned RC of" if isinstance(model, MultiZonePaperModel) else "export-rc of"
        atomic_write_json(a.out, {**rc.to_json(), "source": f"{what} the {model.family} of several zones from {a.model}"})
        zones = "; ".join(
            f"{z.zone.name} R_ra={z.rc.r_ra_k_per_w:.4g} K/W R_rm={z.rc.r_rm_k_per_w:.4g} K/W "
            f"C_r={z.rc.c_r_j_per_k:.4g} J/K C_m={z.rc.c_m_j_per_k:.4g} J/K"
            for z in rc.params.zones
        )
        walls = ", ".join(f"{x}-{y} U={u:.4g} W/K" for (x, y), u in rc.walls.items()) or "no walls"
        return f"{zones}; {walls} -> {a.out}"
    own = isinstance(model, LearnedModel) and model.physics_coefficients() is not None
    if isinstance(model, ARXModel):
        data = _identified_rc(model.identified_rc, model.training_data, a.model, "an ARX model")
    elif isinstance(model, LearnedModel) and not own:
        data = _identified_rc(
            model.record.identified_rc, model.record.training_data, a.model, f"the {model.arch} model"
        )
    elif isinstance(model, LearnedModel):
        data = dict(export_rc(
            model, source=f"export-rc of {model.arch} x{model.n_members} from {a.model}"
        ))
        data["power_range_w"] = [float(v) for v in model.record.u_phys_range_w]
        data["heat_pump_data"] = "cop" in model.record.training_data.get("columns", [])
    else:
        raise InternalError(f"export-rc cannot export a {type(model).__name__}")
    atomic_write_json(a.out, data)
    return (
        ("" if own else "the RC identified from its training data (the model has no R or C of its own): ")
        + f"R_ra={data['R_ra_K_per_W']:.4g} K/W R_rm={data['R_rm_K_per_W']:.4g} K/W "
        f"C_r={data['C_r_J_per_K']:.4g} J/K C_m={data['C_m_J_per_K']:.4g} J/K -> {a.out}"
    )


def _identified_rc(
    identified: Mapping[str, Any] | None, training_data: Mapping[str, Any], model_dir: str, what: str
) -> dict[str, Any]:
    """The RC JSON of a model from ``model_dir`` that has no R or C of its own (``what``: an
    ARX, a network without a physics block such as the mlp or pcnn-parx): the 2R2C ``train``
    identified from the same data (``identified``, which its guard falls back on; its data's
    summary ``training_data``), the source saying so; refused where there is none."""
    if identified is None:
        raise InputError(
            f"--model {model_dir} is {what}, which has no R or C of its own, and no RC "
            "could be identified from its training data; run `pinn-mpc identify --data DATA.csv "
            "--out rc.json` on that data to see why"
        )
    data = dict(identified)
    data["source"] = (
        f"export-rc of {what} from {model_dir}, which has no R or C of its own: the RC identified "
        "from its training data"
    )
    power = training_data.get("u_phys_range")
    if power is not None:
        data["power_range_w"] = [float(v) for v in power]
    data["heat_pump_data"] = "cop" in training_data.get("columns", [])
    return data


def _check_one_zone(a: argparse.Namespace) -> None:
    """Refuse ``--scenario`` with data of one zone: it only gives the layout of data of several
    zones (a scenario of one zone, e.g. an EnergyPlus building's merged zones, has none to give)."""
    if a.layout is not None:
        raise InputError(
            f"--scenario {a.layout}: only data of several zones need a layout; {a.data} holds one "
            "zone (T_r): leave --scenario out"
        )


def _zone_layout(a: argparse.Namespace, df: pd.DataFrame, doing: str) -> Scenario:
    """The scenario of ``--scenario`` that gives the layout of ``df``'s building of several
    zones, checked against the data (its zones, each actuator's power column, its step);
    ``doing`` names the command's work in the messages ("identifying them")."""
    from scenarios.inputs.scenario_file import get_scenario

    zones = zones_in(df.columns)
    names = ", ".join(z.name for z in zones)
    if a.layout is None:
        raise InputError(
            f"{a.data}: holds {len(zones)} zones ({names}); {doing} needs the building's "
            "layout (which actuator acts on which zone, which facade each zone's windows face): "
            "add --scenario NAME or a scenario file of that building"
        )
    if a.eta is not None:
        raise InputError("--eta is a one-zone building's; a building of several zones has each actuator's efficiency in its scenario")
    scenario = get_scenario(a.layout)
    spec = scenario.control_spec()
    if spec.zones != zones:
        raise InputError(
            f"--scenario {a.layout}: its zones ({', '.join(z.name for z in spec.zones)}) are not "
            f"the data's ({names}); give the scenario of the building the data were measured in"
        )
    columns = actuator_columns("u_phys", spec.actuators)
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise InputError(
            f"{a.data}: no column {', '.join(missing)}; data of a building of several actuators give "
            "each one's delivered power, u_phys[<actuator>]"
        )
    if float(df.attrs["dt_s"]) != scenario.sim.dt_s:
        raise InputError(
            f"{a.data}: its step is {df.attrs['dt_s']:g} s, the scenario's control interval "
            f"{scenario.sim.dt_s:g} s; give data at the scenario's interval"
        )
    return scenario


def _identify_zones(a: argparse.Namespace, df: pd.DataFrame) -> str:
    """``identify`` of data of several zones: the building of ``--scenario``'s layout
    (:func:`pinn_mpc.identify_multizone.identify_multizone`), its multi-zone RC file."""
    from scenarios.experiments.compare import identify_scenario_zones

    scenario = _zone_layout(a, df, "identifying them")
    zones = scenario.control_spec().zones
    names = ", ".join(z.name for z in zones)
    result = identify_scenario_zones(scenario, df)
    atomic_write_json(a.out, {**result.to_json(), "source": f"identify:{a.data}"})
    walls = ", ".join(f"{x}-{y} {u:.4g} W/K" for (x, y), u in result.walls.items()) or "none"
    rmse = ", ".join(f"{z.name} {r:.3f} C" for z, r in zip(zones, result.rmse_c, strict=True))
    return f"identified {len(zones)} zones ({names}), walls {walls} (rmse {rmse} over {result.n_rows} rows) -> {a.out}"


def identify(a: argparse.Namespace) -> str:
    """Read ``--data``, identify, write the RC JSON ``--out``:
    :func:`pinn_mpc.physics.rc_summary` plus a ``fit`` block
    (:meth:`~pinn_mpc.identify.IdentifyResult.fit_statistics`)."""
    from pinn_mpc.identify import identify_rc

    check_writable(a.out)
    check_distinct(inputs={"--data": a.data}, outputs={"--out": a.out})
    check_new_files({"out": a.out}, force=a.force)
    df = read_timeseries(a.data, columns=a.columns, zones=True)
    if len(zones_in(df.columns)) > 1:
        return _identify_zones(a, df)
    _check_one_zone(a)
    df = read_timeseries(a.data, columns=a.columns)
    result = identify_rc(df, eta=_eta(a.eta))
    summary = rc_summary(result.params, source=f"identify:{a.data}")
    summary["fit"] = result.fit_statistics()
    power = df["u_phys"].to_numpy(dtype=float)
    summary["power_range_w"] = [float(power.min()), float(power.max())]
    summary["heat_pump_data"] = "cop" in df.columns
    for note in (*result.notes, result.poor_fit_note()):
        if note is not None:
            warn(note)
    atomic_write_json(a.out, summary)
    p = result.params
    gains = ""
    if p.unmeasured_gains_w:
        half = len(p.unmeasured_gains_w) // 2
        gains = (
            f"; unmeasured gains up to {max(p.unmeasured_gains_w[:half]) / 1000:.3g} kW on a "
            f"workday, {max(p.unmeasured_gains_w[half:]) / 1000:.3g} kW on a weekend day"
        )
    return (
        f"identified R_ra={p.r_ra_k_per_w:.4g} K/W R_rm={p.r_rm_k_per_w:.4g} K/W "
        f"C_r={p.c_r_j_per_k:.4g} J/K C_m={p.c_m_j_per_k:.4g} J/K{gains} "
        f"(rmse {result.rmse_c:.3f} C over {result.n_rows} rows) -> {a.out}"
    )

