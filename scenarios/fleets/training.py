"""One learned model per building of a fleet, trained on Ray; a fleet-pretrained alternative.

``train --data fleet.csv --per-building --out DIR`` (:func:`train_per_building`) takes a data
set with a ``building`` column (``simulate --buildings N``) and trains each building's model
(any architecture ``train`` takes, ``auto`` by default: each building's own choice) as a Ray task, locally or on a cluster (``--address``,
:func:`scenarios.running.ray_engine.ray_engine`). ``DIR`` holds ``fleet.json`` (what was trained, the
buildings' parameters when the data came with them) and one model directory per building,
``buildings/b00000`` ...; a rerun keeps every building whose model directory loads and trains
only the others (resumable, as a sweep). ``fleet.json`` is written before the first model, with
each building's data digest, the architecture and the training settings: a rerun on other data
or settings is refused (a kept model would otherwise be another building's, silently).

:func:`pretrain_and_fine_tune` is the transfer-learning alternative: one model pre-trained on
every building's data together, then each building's model started from its network (the
residual net and the learned backup thermostat; the physics block starts, as always, at the
building's own identification) and trained for a few epochs on its own data.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import shutil
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from pinn_mpc.errors import InputError, InternalError, setting
from pinn_mpc.io import atomic_write_json, setting_changes
from pinn_mpc.models.registry import AUTO, DEFAULT_ARCH, MODEL_CHOICES
from pinn_mpc.physics import RCParams
from pinn_mpc.training import TrainConfig
from scenarios.records import FleetTraining

if TYPE_CHECKING:
    from pinn_mpc.models.learned import LearnedModel
    from pinn_mpc.models.rollout import FittedModel

__all__ = [
    "FLEET_FILE",
    "building_frames",
    "building_model_dir",
    "fleet_model_files",
    "load_fleet_models",
    "pretrain_and_fine_tune",
    "train_per_building",
]

#: The file of a per-building model directory that says what it holds.
FLEET_FILE = "fleet.json"
#: State-dict entries a fine-tuned hybrid takes from the fleet's pre-trained model.
TRANSFERRED = ("net.residual_net.", "net.backup_low_c", "net.backup_high_c")


def building_frames(data: pd.DataFrame) -> dict[int, pd.DataFrame]:
    """Each building's rows of a fleet data set (a ``building`` column of whole numbers)."""
    if "building" not in data.columns:
        raise ValueError(
            "the data has no 'building' column: a fleet data set has one (`pinn-mpc simulate` "
            "writes it for several buildings)"
        )
    frames = {}
    for _, part in data.groupby("building", sort=True):
        frame = part.drop(columns="building").reset_index(drop=True)
        frame.attrs.update(data.attrs)
        frames[int(part["building"].to_numpy()[0])] = frame
    return frames


def building_model_dir(root: str | os.PathLike[str], building: int) -> Path:
    return Path(root) / "buildings" / f"b{building:05d}"


def fleet_model_files(root: str | os.PathLike[str]) -> list[Path]:
    """The files a per-building model directory holds (``fleet.json`` and each building's
    model files, of either kind): the inputs no output may replace."""
    from pinn_mpc.fitted import model_files

    files = [Path(root) / FLEET_FILE]
    for building in sorted((Path(root) / "buildings").glob("b*")):
        files.extend(model_files(building))
    return files


def _train_one(frame: pd.DataFrame, arch: str, config: TrainConfig, path: str) -> tuple[float, str]:
    """A Ray task: fit one building's model (any architecture ``train`` takes, ``auto``
    choosing) and save it; returns the seconds and the architecture fitted."""
    import torch
    from threadpoolctl import threadpool_limits

    from pinn_mpc.fitted import fit, save

    torch.set_num_threads(1)  # the task holds one CPU: one thread for torch and for BLAS
    start = time.perf_counter()
    with threadpool_limits(limits=1, user_api="blas"):
        choice = fit(frame, arch=arch, config=config, progress=False)
    save(choice.model, path)
    return time.perf_counter() - start, choice.chosen


def _stored(path: Path) -> bool:
    """A finished building: its model directory (of either kind) loads."""
    from pinn_mpc.fitted import holds_model, load

    if not holds_model(path):
        return False
    try:
        load(path)
    except (InputError, OSError, ValueError):
        return False
    return True


def train_per_building(
    frames: Mapping[int, pd.DataFrame],
    out: str | os.PathLike[str],
    *,
    arch: str,
    config: TrainConfig,
    params: Sequence[RCParams] | None = None,
    address: str | None = None,
    workers: int | None = None,
) -> FleetTraining:
    """Train one ``arch`` model per building of ``data`` into ``out`` (module docstring) on
    Ray; buildings already there are kept. ``frames``: each building's data by its number
    (:func:`building_frames`, :func:`pinn_mpc.data.read_fleet_timeseries`); ``params``: the
    buildings' parameters, stored in ``fleet.json`` for the fleet closed loop. Returns the
    summary ``fleet.json`` holds."""
    from scenarios.running.ray_engine import check_engine_options

    if params is not None and len(params) != len(frames):
        raise InternalError(f"{len(params)} building parameters for {len(frames)} buildings in the data")
    check_engine_options(address, workers)
    root = Path(out)
    if root.exists() and not root.is_dir():
        raise InputError(f"{setting('out')} {root} is a file; give a directory")
    if root.is_dir() and any(root.iterdir()) and not (root / FLEET_FILE).is_file():
        raise InputError(
            f"{setting('out')} {root} is not empty and holds no {FLEET_FILE}; give a new or empty directory "
            "(or an earlier per-building run's, to resume it)"
        )
    digests = {str(b): frame_digest(frame) for b, frame in frames.items()}
    # as fleet.json will hold them (tuples as lists), to compare with a stored run's
    settings = json.loads(json.dumps({k: v for k, v in dataclasses.asdict(config).items() if k != "prior"}))
    if arch != AUTO and arch not in MODEL_CHOICES:
        raise ValueError(f"unknown architecture {arch!r}; choose one of {AUTO}, {', '.join(MODEL_CHOICES)}")
    previous = _read_fleet(root)
    done = [b for b in frames if _stored(building_model_dir(root, b))]
    # A run that left no model file (it failed on every building) has nothing to agree with.
    if previous is not None and any(p.is_file() for p in fleet_model_files(root)[1:]):
        _check_resumable(root, previous, arch=arch, config=settings, digests=digests)
    todo = [b for b in frames if b not in done]
    start = time.perf_counter()
    seconds: dict[int, float] = {}
    summary: FleetTraining = {
        "arch": arch,
        "config": settings,
        "buildings": sorted(frames),
        "data_sha256": digests,
        "trained": [],
        "kept": sorted(done),
        "train_seconds": {},
        "wall_seconds": 0.0,
        "params": None if params is None else [p.to_dict() for p in params],
    }
    if previous is not None and previous.get("params") and params is None:
        summary["params"] = previous["params"]
    earlier = (previous or {}).get("chosen") or {}
    chosen = {b: str(earlier[str(b)]) for b in done if str(b) in earlier}
    if todo:
        created = not root.exists()
        root.mkdir(parents=True, exist_ok=True)
        atomic_write_json(root / FLEET_FILE, summary)  # an interrupted run resumes from it
        try:
            _train_on_ray(frames, todo, root, arch, config, address, workers, seconds, chosen)
        except BaseException:
            if not any(p.is_file() for p in fleet_model_files(root)[1:]):
                _remove_empty_run(root, created)  # nothing to resume: nothing to block a rerun
            raise
    summary["chosen"] = {str(b): c for b, c in sorted(chosen.items())}
    summary["trained"] = sorted(seconds)
    summary["train_seconds"] = {str(b): round(s, 2) for b, s in sorted(seconds.items())}
    summary["wall_seconds"] = round(time.perf_counter() - start, 2)
    atomic_write_json(root / FLEET_FILE, summary)
    return summary


def _train_on_ray(
    frames: Mapping[int, pd.DataFrame], todo: list[int], root: Path, arch: str, config: TrainConfig,
    address: str | None, workers: int | None, seconds: dict[int, float], chosen: dict[int, str],
) -> None:
    """Fit the buildings ``todo`` as Ray tasks into ``root``, filling ``seconds`` and
    ``chosen`` (the architecture each building got) as they finish."""
    import ray

    from scenarios.running.ray_engine import ray_engine

    with ray_engine(address, workers):
        (root / "buildings").mkdir(parents=True, exist_ok=True)
        task = ray.remote(num_cpus=1)(_train_one)
        refs = {
            task.remote(frames[b], arch, config, str(building_model_dir(root, b))): b for b in todo
        }
        pending = list(refs)
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            try:
                took, name = ray.get(ready[0])
            except ray.exceptions.RayError as exc:
                cause = getattr(exc, "cause", None) or exc
                first = (str(cause).strip().splitlines() or [""])[0]
                # The task's own exception is a bug unless it is about input, files or
                # memory; Ray's (a worker lost) are the machine's, reported as before.
                expected = (InputError, OSError, MemoryError, ray.exceptions.RayError)
                bug = isinstance(cause, Exception) and not isinstance(cause, expected)
                raise (InternalError if bug else InputError)(
                    f"training building {refs[ready[0]]} failed: {type(cause).__name__}: {first}"
                ) from None
            seconds[refs[ready[0]]], chosen[refs[ready[0]]] = float(took), str(name)


def _remove_empty_run(root: Path, created: bool) -> None:
    """Remove what a run that kept no model wrote: ``fleet.json``, an empty ``buildings/``
    (with any half-written building directory) and ``root`` itself when this run made it."""
    (root / FLEET_FILE).unlink(missing_ok=True)
    buildings = root / "buildings"
    if buildings.is_dir():
        for part in buildings.iterdir():
            if part.is_dir() and not any(p for p in part.iterdir() if not p.name.startswith(".")):
                shutil.rmtree(part, ignore_errors=True)
        with contextlib.suppress(OSError):
            buildings.rmdir()
    if created:
        with contextlib.suppress(OSError):
            root.rmdir()


def frame_digest(frame: pd.DataFrame) -> str:
    """The sha256 of one building's data (its column names and values, row by row)."""
    digest = hashlib.sha256(",".join(map(str, frame.columns)).encode("utf-8"))
    digest.update(pd.util.hash_pandas_object(frame, index=False).to_numpy().tobytes())
    return digest.hexdigest()


def _check_resumable(
    root: Path, previous: dict[str, Any], *, arch: str, config: dict[str, Any], digests: dict[str, str]
) -> None:
    """Refuse to resume ``root`` on other data or settings: its models would be kept as this
    data's (each building's digest, the architecture and the training settings must match)."""
    fix = f"give a new {setting('out')} directory, or the same {setting('data')} and options to resume this one"
    stored = previous.get("data_sha256")
    if not isinstance(stored, dict):
        raise InputError(
            f"{setting('out')} {root}: its {FLEET_FILE} records no data digests, so its models cannot be "
            f"told to be this data's; {fix}"
        )
    other = [b for b, d in digests.items() if b in stored and stored[b] != d]
    if other:
        raise InputError(
            f"{setting('out')} {root} holds models trained on other data (building {other[0]}'s rows "
            f"differ{f', and {len(other) - 1} more' if len(other) > 1 else ''}); {fix}"
        )
    was = {"arch": previous.get("arch"), **(previous.get("config") or {})}
    now = {"arch": arch, **config}
    changed = setting_changes(was, now)
    if changed:
        raise InputError(f"{setting('out')} {root} holds models trained otherwise ({changed}); {fix}")


def _read_fleet(root: Path) -> dict[str, Any] | None:
    path = root / FLEET_FILE
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: not a readable fleet file ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("buildings"), list):
        raise InputError(f"{path}: not a fleet file (no list of buildings)")
    return data


#: A directory of per-building models, as a message names it.
_MODELS = setting("model_dir", python="directory")


def load_fleet_models(root: str | os.PathLike[str]) -> tuple[list[FittedModel], list[RCParams] | None]:
    """The per-building models of ``root`` in building order (of any family,
    :func:`pinn_mpc.fitted.load`), and the buildings' parameters when ``fleet.json`` has them."""
    from pinn_mpc.fitted import holds_model, load

    fleet = _read_fleet(Path(root))
    if fleet is None:
        raise InputError(
            f"{_MODELS} {root}: no {FLEET_FILE}; train its buildings' models first (the "
            "per-building training of `pinn-mpc train`)"
        )
    models = []
    for b in fleet["buildings"]:
        path = building_model_dir(root, int(b))
        if not holds_model(path):
            raise InputError(
                f"{_MODELS} {root}: building {b} has no model (an interrupted run?); rerun the "
                "per-building training into it to finish it"
            )
        models.append(load(path))
    params = None
    if fleet.get("params"):
        params = [RCParams(**p) for p in fleet["params"]]
    return models, params


def pretrain_and_fine_tune(
    frames: Sequence[pd.DataFrame],
    *,
    config: TrainConfig,
    fine_tune_epochs: int,
    arch: str = DEFAULT_ARCH,
) -> tuple[list[LearnedModel], dict[str, float]]:
    """Pre-train one ``arch`` model on all ``frames`` (each building's data, concatenated
    building after building), then fine-tune one model per building for ``fine_tune_epochs``
    from its transferred weights (:data:`TRANSFERRED`). Returns the fine-tuned models and the
    seconds spent (``pretrain``, ``fine_tune`` summed over the buildings)."""
    from pinn_mpc.training import train_model

    if fine_tune_epochs < 1:
        raise ValueError(f"fine_tune_epochs must be >= 1, got {fine_tune_epochs}")
    start = time.perf_counter()
    pooled = _pool(frames)
    fleet_model = train_model(pooled, arch=arch, config=config, progress=False)
    pretrain_s = time.perf_counter() - start
    weights = {
        k: v.clone() for k, v in fleet_model.module.state_dict().items() if k.startswith(TRANSFERRED)
    }
    tuned = dataclasses.replace(config, epochs=fine_tune_epochs)
    start = time.perf_counter()
    models = [
        train_model(frame, arch=arch, config=tuned, progress=False, init_weights=weights)
        for frame in frames
    ]
    return models, {"pretrain": pretrain_s, "fine_tune": time.perf_counter() - start}


def _pool(frames: Sequence[pd.DataFrame]) -> pd.DataFrame:
    """The buildings' data one after another, each on its own days: the time column carries
    on from the last building's end, so the feature windows never straddle two buildings
    except at the joins (a few windows of ``depth`` rows in thousands)."""
    parts = []
    offset = pd.Timedelta(0)
    for frame in frames:
        part = frame.copy()
        times = pd.to_datetime(part["time"])
        part["time"] = times + offset
        offset += times.iloc[-1] - times.iloc[0] + (times.iloc[1] - times.iloc[0])
        parts.append(part)
    pooled = pd.concat(parts, ignore_index=True)
    pooled.attrs.update(frames[0].attrs)
    return pooled
