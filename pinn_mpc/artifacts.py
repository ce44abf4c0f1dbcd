"""Model directories: ``weights.safetensors`` (cannot run code on load) + ``model.json``; and
the RC files (``rc.json``) that ``identify`` and ``export-rc`` write (:func:`read_rc`).

``model.json`` holds the architecture, feature config and scaling, the learned physics
coefficients, ``eta`` (heat per W of actuator power: > 0 the model heats, < 0 it cools), the
training record and data summary, the package version, and ``weights_sha256``, the checksum
of the weights file. :func:`load_model` checks all of it and raises :class:`ModelFileError`
with one clear line for a missing directory, missing/truncated/corrupt weights (checksum
mismatch), bad JSON, implausible values (interval, eta, prior) or sizes that disagree with the
weights. Sizes are checked against the safetensors header, and against :data:`MAX_MEMBERS` and
:data:`~pinn_mpc.features.MAX_DEPTH`, before any tensor is allocated.

Older model directories are still read: without ``eta`` the model counts as a heater (eta 1,
all that ``train`` could write then); without ``weights_sha256`` it loads with a warning line
on stderr, since corruption of its weights cannot be detected (train it again to add one).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import torch
from safetensors import safe_open
from safetensors.torch import load_file, save_file

from pinn_mpc import __version__, physics
from pinn_mpc.actuator import CopCurve
from pinn_mpc.choices import ALL_ARCHS
from pinn_mpc.errors import InputError, ModelFileError, warn
from pinn_mpc.features import FeatureConfig, whole_number
from pinn_mpc.io import DirectoryLayout, atomic_directory, file_sha256
from pinn_mpc.models.learned import MAX_MEMBERS, EnsembleModule, LearnedModel, ModelRecord
from pinn_mpc.models.registry import get_architecture
from pinn_mpc.physics import read_rc_json  # torch-free: the RC MPCs read rc.json without torch

__all__ = [
    "CHECKSUM",
    "FORMAT_VERSION",
    "META",
    "MODEL_DIRECTORY",
    "WEIGHTS",
    "check_model_path",
    "load_model",
    "read_rc",
    "read_rc_json",
    "save_model",
]

WEIGHTS = "weights.safetensors"
META = "model.json"
FORMAT_VERSION = 2
#: A model directory holds these two files (weights first: they are renamed into place in this
#: order, and model.json describes them).
MODEL_DIRECTORY = DirectoryLayout(
    kind="model directory", files=(WEIGHTS, META), markers=(WEIGHTS, META)
)
_REQUIRED = ("format_version", "arch", "n_members", "features", "prior", "u_phys_range_w")
CHECKSUM = "weights_sha256"


def save_model(model: LearnedModel, path: str | os.PathLike[str], *, force: bool = False) -> str:
    """Write the model directory atomically (a failed write leaves nothing behind). An existing
    directory that is not a model directory is refused unless ``force``; then only the model's
    files in it are replaced (see :func:`pinn_mpc.io.atomic_directory`)."""
    state = {k: v.detach().contiguous().clone() for k, v in model.module.state_dict().items()}
    coef = model.physics_coefficients()
    meta: dict[str, Any] = {
        **model.meta,
        "format_version": FORMAT_VERSION,
        "package_version": __version__,
        "arch": model.arch,
        "n_members": model.n_members,
        "features": model.features.to_dict(),
        "learned_coefficients_per_s": {
            "ensemble": coef.to_dict() if coef is not None else None,
            "members": model.member_coefficients(),
        },
        "tensors": {k: list(v.shape) for k, v in state.items()},
    }
    with atomic_directory(path, MODEL_DIRECTORY, force=force) as tmp:
        save_file(state, str(tmp / WEIGHTS))
        meta[CHECKSUM] = file_sha256(tmp / WEIGHTS)
        text = json.dumps(meta, indent=2, allow_nan=False) + "\n"
        (tmp / META).write_text(text, encoding="utf-8")
        for item in (tmp / WEIGHTS, tmp / META):
            item.chmod(0o644)
    return str(path)


def _read_meta(directory: Path) -> dict[str, Any]:
    meta_path = directory / META
    if not meta_path.is_file():
        raise ModelFileError(f"model directory {directory} has no {META}; it is not a saved model")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ModelFileError(
            f"{meta_path} is not valid JSON ({exc}); retrain or restore the model"
        ) from exc
    if not isinstance(meta, dict):
        raise ModelFileError(f"{meta_path} must hold a JSON object, got {type(meta).__name__}")
    missing = [k for k in _REQUIRED if k not in meta]
    if missing:
        raise ModelFileError(f"{meta_path} lacks key(s) {missing}; retrain or restore the model")
    if meta["arch"] not in ALL_ARCHS:
        raise ModelFileError(f"{meta_path}: unknown arch {meta['arch']!r}; expected one of {ALL_ARCHS}")
    # Each architecture names the formats it reads (version 2 changed the hybrid's backup).
    if meta["format_version"] not in get_architecture(meta["arch"]).format_versions:
        raise ModelFileError(
            f"{meta_path} has format_version {meta['format_version']!r}, this package reads "
            f"{FORMAT_VERSION}; retrain the model with this version"
        )
    return meta


def _verify_checksum(directory: Path, meta: dict[str, Any]) -> None:
    """The weights must be the bytes model.json was written with (no bit flips, no swaps)."""
    weights_path = directory / WEIGHTS
    expected = meta.get(CHECKSUM)
    if expected is None:
        warn(
            f"{directory / META} has no {CHECKSUM} (a model saved before checksums): "
            "corrupted weights cannot be detected; train it again to add one"
        )
        return
    if file_sha256(weights_path) != expected:
        raise ModelFileError(
            f"{weights_path} does not match {META} (sha256 differs: the weights are corrupted "
            "or were replaced); re-train the model or restore the directory from a backup"
        )


def _corrupt(weights_path: Path, exc: Exception) -> ModelFileError:
    first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    return ModelFileError(
        f"{weights_path} is truncated or corrupt ({first}); retrain or restore the model"
    )


def _header_shapes(directory: Path) -> dict[str, tuple[int, ...]]:
    """Tensor shapes from the safetensors header; no tensor data is read."""
    weights_path = directory / WEIGHTS
    try:
        with safe_open(str(weights_path), framework="pt") as f:
            return {name: tuple(f.get_slice(name).get_shape()) for name in f.keys()}
    except Exception as exc:  # safetensors raises its own error types for bad headers/sizes
        raise _corrupt(weights_path, exc) from exc


def _check_sizes(
    directory: Path, shapes: dict[str, tuple[int, ...]], expected: dict[str, tuple[int, ...]]
) -> None:
    """Header shapes against what model.json implies; raises before anything is allocated."""
    missing = sorted(set(expected) - set(shapes))
    unexpected = sorted(set(shapes) - set(expected))
    if missing or unexpected:
        raise ModelFileError(
            f"{directory / WEIGHTS} does not match {META}: "
            f"missing {missing}, unexpected {unexpected}"
        )
    for name, shape in shapes.items():
        if shape != expected[name]:
            raise ModelFileError(
                f"{directory / WEIGHTS}: tensor {name} has shape {shape}, "
                f"{META} implies {expected[name]}; re-train or restore the model"
            )


def check_model_path(path: str | os.PathLike[str]) -> Path:
    """``path`` as a directory that exists; ModelFileError for a file or nothing there."""
    directory = Path(path)
    if directory.is_file():
        raise ModelFileError(
            f"{directory} is a file, not a model directory; give the directory that "
            "`pinn-mpc train` wrote (it holds model.json and weights.safetensors)"
        )
    if not directory.is_dir():
        raise ModelFileError(
            f"model directory {directory} does not exist; "
            "train one into it with `pinn-mpc train`"
        )
    return directory


def load_model(path: str | os.PathLike[str]) -> LearnedModel:
    """Load and validate a model directory written by :func:`save_model`."""
    directory = check_model_path(path)
    meta = _read_meta(directory)
    if not (directory / WEIGHTS).is_file():
        raise ModelFileError(f"model directory {directory} has no {WEIGHTS}; retrain or restore it")
    shapes = _header_shapes(directory)  # a truncated file fails here, with that named
    _verify_checksum(directory, meta)
    try:
        features = FeatureConfig.from_dict(meta["features"])
        prior = physics.RCParams.from_dict(meta["prior"])
        n_members = whole_number(meta["n_members"], "n_members")
        lo, hi = (float(v) for v in meta["u_phys_range_w"])
        eta = physics.check_plausible("eta", meta.get("eta", 1.0), name="eta")
        cop_curve = (
            CopCurve.from_dict(meta["cop_curve"]) if meta.get("cop_curve") is not None else None
        )
    except (KeyError, TypeError, ValueError, InputError) as exc:
        raise ModelFileError(
            f"{directory / META} has an invalid field ({exc}); retrain the model"
        ) from exc
    if prior.heating != (eta > 0):
        raise ModelFileError(
            f"{directory / META}: eta={eta:g} and prior.eta={prior.eta:g} disagree on heating "
            "vs cooling; retrain the model"
        )
    if not 1 <= n_members <= MAX_MEMBERS:
        raise ModelFileError(
            f"{directory / META}: n_members is {n_members}, must be 1 .. {MAX_MEMBERS}; "
            "retrain or restore the model"
        )
    if not 0.0 <= lo <= hi <= physics.MAX_POWER_W:
        raise ModelFileError(
            f"{directory / META}: u_phys_range_w [{lo:g}, {hi:g}] W must lie within "
            f"0 .. {physics.MAX_POWER_W:g} W with low <= high; retrain the model"
        )
    # The shapes of a one-member module (small: depth is capped) give those of n_members.
    one = EnsembleModule(
        meta["arch"],
        features=features,
        n_members=1,
        prior=prior,
        generators=[torch.Generator().manual_seed(0)],
    )
    expected = {k: (n_members, *v.shape[1:]) for k, v in one.state_dict().items()}
    # Terms added to an architecture later, which a model saved before them has without (zero).
    later = {f"net.{n}" for n in getattr(one.net, "ZERO_WHEN_ABSENT", ())} - set(shapes)
    _check_sizes(directory, shapes, {k: v for k, v in expected.items() if k not in later})
    try:
        state = load_file(str(directory / WEIGHTS))
    except Exception as exc:  # safetensors raises its own error types for bad headers/sizes
        raise _corrupt(directory / WEIGHTS, exc) from exc
    for name, tensor in state.items():
        if not torch.isfinite(tensor).all():
            raise ModelFileError(f"{directory / WEIGHTS}: tensor {name} has non-finite values")
    state.update({name: torch.zeros(expected[name]) for name in later})
    gens = [torch.Generator().manual_seed(0) for _ in range(n_members)]
    module = EnsembleModule(
        meta["arch"],
        features=features,
        n_members=n_members,
        prior=prior,
        generators=gens,
        cop_curve=cop_curve,
    )
    module.load_state_dict(state)
    return LearnedModel(
        features=features, module=module, record=ModelRecord.from_dict({**meta, "eta": eta})
    )


def read_rc(path: str | os.PathLike[str]) -> physics.RCParams:
    """RC parameters from the JSON written by ``identify`` / ``export-rc``."""
    return read_rc_json(path)[0]
