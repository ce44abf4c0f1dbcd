"""The model commands: ``train``, ``evaluate``, ``export-rc``, ``identify``.

Each takes the parsed arguments, refuses outputs that cannot be written or would overwrite an
input or another output (before any work), calls the library (which returns typed results and
never writes), writes the outputs atomically and returns the summary the CLI prints.
Libraries are imported inside the commands, so that ``identify`` does not wait for torch.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

from pinn_mpc.choices import ARX, AUTO, PHYSICS_ARX
from pinn_mpc.data import read_timeseries
from pinn_mpc.errors import InputError, warn
from pinn_mpc.io import (
    PathsArg,
    atomic_write_json,
    check_distinct,
    check_output_directory,
    check_writable,
    output_lock,
)
from pinn_mpc.physics import rc_summary
from pinn_mpc.records import EvaluationMetrics, HorizonErrors

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
    from pinn_mpc.training import TrainConfig
    from scenarios.fleets.training import train_per_building

    frames = read_fleet_timeseries(a.data, columns=a.columns)
    params = read_fleet_params(a.data, len(frames))
    config = TrainConfig(
        depth=a.depth, n_seeds=a.seeds, first_seed=a.seed, epochs=a.epochs, lam=a.lam,
        recipe=a.recipe, eta=_eta(a.eta),
    )
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


def _eta(value: float | None) -> float:
    """``--eta`` not given means 1: a heater (a cooling machine gives minus its COP)."""
    return 1.0 if value is None else float(value)


def _train_one(a: argparse.Namespace) -> str:
    """Read ``--data``, train the ensemble, save the model directory ``--out``.

    ``--out`` is checked before training: it must be new, empty or a model directory, or
    ``--force`` given (then only the model's files in it are replaced).
    """
    from pinn_mpc.artifacts import MODEL_DIRECTORY, save_model
    from pinn_mpc.training import TrainConfig, train_model

    if a.arch in (ARX.name, PHYSICS_ARX.name):
        return _train_arx(a)
    if a.arch == AUTO:
        return _train_auto(a)
    check_output_directory(a.out, MODEL_DIRECTORY, force=a.force)
    files = MODEL_DIRECTORY.paths(a.out)
    check_distinct(inputs={"--data": a.data}, outputs={"--out": files})
    df = read_timeseries(a.data, columns=a.columns)
    config = TrainConfig(
        depth=a.depth, n_seeds=a.seeds, first_seed=a.seed, epochs=a.epochs, lam=a.lam,
        recipe=a.recipe, eta=_eta(a.eta),
    )
    model = train_model(df, arch=a.arch, config=config)
    for message in model.record.data_warnings:
        warn(f"{a.data}: {message}")
    _warn_without_fallback(a.data, model.record.identified_rc)
    save_model(model, a.out, force=a.force)
    loss = model.record.final_loss
    return (
        f"trained {a.arch} x{a.seeds} on {len(df)} rows in {model.record.train_seconds:.1f} s "
        f"(final loss reg {loss['reg']:.3g}, phys {loss['phys']:.3g}); "
        f"wrote {', '.join(map(str, files))}"
    )


def _warn_without_fallback(data: str, identified_rc: object) -> None:
    """Say so when no RC could be identified from the training data: cem and random-shooting
    over the model then have no RC MPC to hand their decisions to."""
    if identified_rc is None:
        warn(
            f"{data}: no RC could be identified from the data (`pinn-mpc identify` says why), so "
            "cem and random-shooting over this model have no RC MPC to fall back on"
        )


def _train_auto(a: argparse.Namespace) -> str:
    """``train --arch auto`` (the default): the hybrid or the physics-informed ARX, whichever
    predicts the data's last quarter better (:mod:`pinn_mpc.model_choice`), into ``--out``.
    ``--out`` may hold a model of either kind; the one not chosen is removed from it."""
    from pinn_mpc.artifacts import MODEL_DIRECTORY, save_model
    from pinn_mpc.io import DirectoryLayout
    from pinn_mpc.model_choice import choose_model, fallback_rc
    from pinn_mpc.models.arx import ARX_DIRECTORY, ARXModel, save_arx
    from pinn_mpc.training import TrainConfig, data_warnings

    either = DirectoryLayout(
        kind="model directory", files=(*MODEL_DIRECTORY.files, *ARX_DIRECTORY.files), markers=()
    )
    check_output_directory(a.out, either, force=a.force)
    check_distinct(inputs={"--data": a.data}, outputs={"--out": either.paths(a.out)})
    df = read_timeseries(a.data, columns=a.columns)
    config = TrainConfig(
        depth=a.depth, n_seeds=a.seeds, first_seed=a.seed, epochs=a.epochs, lam=a.lam,
        recipe=a.recipe, eta=_eta(a.eta),
    )
    start = time.perf_counter()
    choice = choose_model(df, config, progress=True)
    if choice.caution:
        warn(f"{a.data}: {choice.caution}")
    # The other kind's files would make the directory ambiguous to load: they go.
    stale = ARX_DIRECTORY if choice.chosen != PHYSICS_ARX.name else MODEL_DIRECTORY
    for message in data_warnings(df):
        warn(f"{a.data}: {message}")
    if choice.caution is None:  # the caution says it where it is given
        _warn_without_fallback(a.data, fallback_rc(choice.model))
    if isinstance(choice.model, ARXModel):
        unused = [f"--{n}" for n in ("depth", "epochs", "lam", "recipe") if getattr(a, n, None) is not None]
        if unused:
            warn(f"{', '.join(unused).replace('--lam', '--lambda')} did not apply: the chosen model has no network")
        written = [str(save_arx(choice.model, a.out))]
    else:
        written = [str(p) for p in MODEL_DIRECTORY.paths(a.out)]
        save_model(choice.model, a.out, force=True)  # --out was checked above
    for path in stale.paths(a.out):
        path.unlink(missing_ok=True)
    return (
        f"chose {choice.chosen} ({choice.why}) on {len(df)} rows in "
        f"{time.perf_counter() - start:.1f} s; wrote {', '.join(written)}"
    )


def _train_arx(a: argparse.Namespace) -> str:
    """``train --arch arx`` (the least-squares ARX baseline, :mod:`pinn_mpc.models.arx`) or its
    physics-informed variant into ``--out``."""
    from pinn_mpc.models.arx import ARX_DIRECTORY, fit_linear, save_arx
    from pinn_mpc.training import data_warnings

    given = [f"--{n}" for n in ("depth", "epochs", "lam", "recipe") if getattr(a, n, None) is not None]
    if given:
        raise InputError(
            f"train --arch {a.arch}: {', '.join(given).replace('--lam', '--lambda')} do(es) not apply to "
            "the least-squares ARX model; leave them out"
        )
    check_output_directory(a.out, ARX_DIRECTORY, force=a.force)
    files = ARX_DIRECTORY.paths(a.out)
    check_distinct(inputs={"--data": a.data}, outputs={"--out": files})
    df = read_timeseries(a.data, columns=a.columns)
    if "building" in df.columns:
        raise InputError(f"{a.data}: a fleet's data (a building column); train --arch {a.arch} takes one building's")
    start = time.perf_counter()
    model = fit_linear(a.arch, df, eta=_eta(a.eta))
    for message in data_warnings(df):
        warn(f"{a.data}: {message}")
    _warn_without_fallback(a.data, model.identified_rc)
    written = save_arx(model, a.out)
    return (
        f"fitted {a.arch} ({model.lags} lags of {', '.join(model.columns)}, a weekly schedule) on "
        f"{len(df)} rows in {time.perf_counter() - start:.2f} s (one-step MAE "
        f"{model.train_mae_c:.3f} C); wrote {written}"
    )


def _evaluate_arx(a: argparse.Namespace) -> str:
    """``evaluate`` of an ARX model directory: T_r MAE one step and ``--horizons`` ahead."""
    from pinn_mpc.models.arx import load_arx

    model = load_arx(a.model)
    df = read_timeseries(a.data, columns=a.columns)
    t_r = df["T_r"].to_numpy(dtype=float)
    horizons: dict[str, HorizonErrors] = {}
    for h in sorted(set(a.horizons) | {1}):
        starts = np.arange(model.lags - 1, len(df) - h)
        if starts.size:
            pred = model.predict_t_r(df, h, starts)
            horizons[str(h)] = {"T_r_mae": float(np.mean(np.abs(pred - t_r[starts + h])))}
    if "1" not in horizons:
        raise InputError(f"{a.data}: too few rows for the ARX model's {model.lags} lags")
    metrics: EvaluationMetrics = {"one_step": {"T_r_mae": horizons["1"]["T_r_mae"]}, "horizons": horizons}
    atomic_write_json(a.json, metrics)
    last = max(int(h) for h in horizons)
    return (
        f"one-step MAE: T_r {horizons['1']['T_r_mae']:.3f} C; {last}-step T_r MAE "
        f"{horizons[str(last)]['T_r_mae']:.3f} C -> {a.json}"
    )


def evaluate(a: argparse.Namespace) -> str:
    """Load ``--model`` and ``--data``, write the metrics JSON ``--json``."""
    from pinn_mpc.artifacts import MODEL_DIRECTORY, load_model
    from pinn_mpc.evaluation import evaluate_model
    from pinn_mpc.models.arx import ARX_DIRECTORY, is_arx_directory

    check_writable(a.json)
    _refuse_fleet_directory(a.model, "evaluate", "--data BUILDING.csv --json metrics.json")
    if is_arx_directory(a.model):
        check_distinct(
            inputs={"--model": ARX_DIRECTORY.paths(a.model), "--data": a.data},
            outputs={"--json": a.json},
        )
        return _evaluate_arx(a)
    inputs: dict[str, PathsArg] = {"--model": MODEL_DIRECTORY.paths(a.model), "--data": a.data}
    check_distinct(inputs=inputs, outputs={"--json": a.json})
    learned = load_model(a.model)
    df = read_timeseries(a.data, columns=a.columns)
    trained_on = learned.meta.get("training_data", {}).get("columns", [])
    if ("cop" in df.columns) != ("cop" in trained_on):
        has, lacks = ("the data", "the model's training data") if "cop" in df.columns else ("the model's training data", "the data")
        warn(
            f"{has} has a cop column (a heat pump) and {lacks} has none: "
            "the model may be evaluated on another actuator than it was made for"
        )
    metrics = evaluate_model(learned, df, a.horizons)
    atomic_write_json(a.json, metrics)
    one = metrics["one_step"]
    last = max(int(h) for h in metrics["horizons"])
    t_m = f", T_m {one['T_m_mae']:.3f} C" if one["T_m_mae"] is not None else ""
    return (
        f"one-step MAE: T_r {one['T_r_mae']:.3f} C, u_phys {one['u_phys_mae']:.0f} W{t_m}; "
        f"{last}-step T_r MAE {metrics['horizons'][str(last)]['T_r_mae']:.3f} C "
        f"(persistence {metrics['persistence']['horizons'][str(last)]['T_r_mae']:.3f} C) "
        f"-> {a.json}"
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
    """``export-rc``: load ``--model``, write its RC JSON ``--out``: a physics-informed
    network's learned R/C values, or the RC an ARX model carries (identified from its training
    data by ``train``)."""
    from pinn_mpc.artifacts import MODEL_DIRECTORY, load_model
    from pinn_mpc.export import export_rc
    from pinn_mpc.models.arx import ARX_DIRECTORY, is_arx_directory

    check_writable(a.out)
    _refuse_fleet_directory(a.model, "export-rc", "--out rc.json")
    if is_arx_directory(a.model):
        check_distinct(inputs={"--model": ARX_DIRECTORY.paths(a.model)}, outputs={"--out": a.out})
        data = _arx_rc(a.model)
    else:
        check_distinct(inputs={"--model": MODEL_DIRECTORY.paths(a.model)}, outputs={"--out": a.out})
        learned = load_model(a.model)
        data = dict(export_rc(
            learned, source=f"export-rc of {learned.arch} x{learned.n_members} from {a.model}"
        ))
        data["power_range_w"] = [float(v) for v in learned.record.u_phys_range_w]
        data["heat_pump_data"] = "cop" in learned.record.training_data.get("columns", [])
    atomic_write_json(a.out, data)
    return (
        f"R_ra={data['R_ra_K_per_W']:.4g} K/W R_rm={data['R_rm_K_per_W']:.4g} K/W "
        f"C_r={data['C_r_J_per_K']:.4g} J/K C_m={data['C_m_J_per_K']:.4g} J/K -> {a.out}"
    )


def _arx_rc(model_dir: str) -> dict[str, Any]:
    """The RC JSON of the ARX model in ``model_dir``: the 2R2C ``train`` identified from the
    same data (an ARX has no R or C of its own); refused where there is none."""
    from pinn_mpc.models.arx import load_arx

    model = load_arx(model_dir)
    if model.identified_rc is None:
        raise InputError(
            f"--model {model_dir} is an ARX model, which has no R or C of its own, and no RC "
            "could be identified from its training data; run `pinn-mpc identify --data DATA.csv "
            "--out rc.json` on that data to see why"
        )
    data = dict(model.identified_rc)
    data["source"] = f"export-rc of an ARX model from {model_dir}: the RC identified from its training data"
    power = model.training_data.get("u_phys_range")
    if power is not None:
        data["power_range_w"] = [float(v) for v in power]
    data["heat_pump_data"] = "cop" in model.training_data.get("columns", [])
    return data


def identify(a: argparse.Namespace) -> str:
    """Read ``--data``, identify, write the RC JSON ``--out``:
    :func:`pinn_mpc.physics.rc_summary` plus a ``fit`` block
    (:meth:`~pinn_mpc.identify.IdentifyResult.fit_statistics`)."""
    from pinn_mpc.identify import identify_rc

    check_writable(a.out)
    check_distinct(inputs={"--data": a.data}, outputs={"--out": a.out})
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
    return (
        f"identified R_ra={p.r_ra_k_per_w:.4g} K/W R_rm={p.r_rm_k_per_w:.4g} K/W "
        f"C_r={p.c_r_j_per_k:.4g} J/K C_m={p.c_m_j_per_k:.4g} J/K "
        f"(rmse {result.rmse_c:.3f} C over {result.n_rows} rows) -> {a.out}"
    )

