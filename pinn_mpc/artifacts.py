"""Model directories: ``weights.safetensors`` (cannot run code on load) + ``model.json``.

``model.json`` holds the architecture, feature config and scaling, the learned physics
coefficients, the training record and data summary, and the package version.
:func:`load_model` checks all of it and raises :class:`ModelFileError` with one clear line
for a missing directory, missing/truncated/corrupt weights, bad JSON or a shape mismatch.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import torch
from safetensors.torch import load_file, save_file

from pinn_mpc import __version__, physics
from pinn_mpc.errors import InputError, ModelFileError
from pinn_mpc.features import FeatureConfig
from pinn_mpc.io import atomic_directory
from pinn_mpc.models import ALL_ARCHS, EnsembleModule, LearnedModel

WEIGHTS = "weights.safetensors"
META = "model.json"
FORMAT_VERSION = 1
_REQUIRED = ("format_version", "arch", "n_members", "features", "prior", "eta", "u_phys_range_w")


def save_model(model: LearnedModel, path: str | os.PathLike[str]) -> str:
    """Write the model directory atomically (a failed write leaves nothing behind)."""
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
    text = json.dumps(meta, indent=2, allow_nan=False) + "\n"
    with atomic_directory(path) as tmp:
        save_file(state, str(tmp / WEIGHTS))
        (tmp / META).write_text(text, encoding="utf-8")
        for item in (tmp / WEIGHTS, tmp / META):
            item.chmod(0o644)
        tmp.chmod(0o755)  # mkdtemp makes it private
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
    if meta["format_version"] != FORMAT_VERSION:
        raise ModelFileError(
            f"{meta_path} has format_version {meta['format_version']!r}, this package reads "
            f"{FORMAT_VERSION}; retrain the model with this version"
        )
    if meta["arch"] not in ALL_ARCHS:
        raise ModelFileError(f"{meta_path}: unknown arch {meta['arch']!r}; expected one of {ALL_ARCHS}")
    return meta


def _read_weights(directory: Path) -> dict[str, torch.Tensor]:
    weights_path = directory / WEIGHTS
    if not weights_path.is_file():
        raise ModelFileError(f"model directory {directory} has no {WEIGHTS}; retrain or restore it")
    try:
        return load_file(str(weights_path))
    except Exception as exc:  # safetensors raises its own error types for bad headers/sizes
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise ModelFileError(
            f"{weights_path} is truncated or corrupt ({first}); retrain or restore the model"
        ) from exc


def load_model(path: str | os.PathLike[str]) -> LearnedModel:
    """Load and validate a model directory written by :func:`save_model`."""
    directory = Path(path)
    if not directory.is_dir():
        raise ModelFileError(
            f"model directory {directory} does not exist; "
            f"train one with `pinn-mpc train --out {directory}`"
        )
    meta = _read_meta(directory)
    state = _read_weights(directory)
    try:
        features = FeatureConfig.from_dict(meta["features"])
        prior = physics.RCParams.from_dict(meta["prior"])
        n_members = int(meta["n_members"])
        lo, hi = (float(v) for v in meta["u_phys_range_w"])
        float(meta["eta"])
    except (KeyError, TypeError, ValueError, InputError) as exc:
        raise ModelFileError(
            f"{directory / META} has an invalid field ({exc}); retrain the model"
        ) from exc
    if n_members < 1 or not lo <= hi:
        raise ModelFileError(f"{directory / META}: invalid n_members={n_members} or u_phys range")
    gens = [torch.Generator().manual_seed(0) for _ in range(n_members)]
    module = EnsembleModule(
        meta["arch"], features=features, n_members=n_members, prior=prior, generators=gens
    )
    expected = module.state_dict()
    missing = sorted(set(expected) - set(state))
    unexpected = sorted(set(state) - set(expected))
    if missing or unexpected:
        raise ModelFileError(
            f"{directory / WEIGHTS} does not match {META}: "
            f"missing {missing}, unexpected {unexpected}"
        )
    for name, tensor in state.items():
        if tuple(tensor.shape) != tuple(expected[name].shape):
            raise ModelFileError(
                f"{directory / WEIGHTS}: tensor {name} has shape {tuple(tensor.shape)}, "
                f"{META} implies {tuple(expected[name].shape)}"
            )
        if not torch.isfinite(tensor).all():
            raise ModelFileError(f"{directory / WEIGHTS}: tensor {name} has non-finite values")
    module.load_state_dict(state)
    return LearnedModel(arch=meta["arch"], features=features, module=module, meta=meta)
