"""One fit, one save and one load for every model ``train`` makes.

Every family's fitted model is a :class:`~pinn_mpc.models.rollout.FittedModel`: the learned
ensembles of every architecture (:class:`~pinn_mpc.models.learned.LearnedModel`) and the ARX
and physics-informed ARX (:class:`~pinn_mpc.models.arx.ARXModel`). :func:`fit` fits any of them
by its registry name (``train --arch``'s choices, ``auto`` included), :func:`save` writes one
into a model directory and :func:`load` reads any model directory back, checked, without
running code from its files (safetensors and JSON numbers). Callers (the command line, the
controller factory, BOPTEST, sweeps, fleets) use these three and never ask which family they
hold.

How each family is kept on disk is :data:`FORMATS`, the one place that knows the formats: the
networks' ``model.json`` with ``weights.safetensors`` (:mod:`pinn_mpc.artifacts`), the ARX's
``arx.json`` (:mod:`pinn_mpc.models.arx`), the hybrid of a building of several zones'
``multizone.json`` (:mod:`pinn_mpc.models.multizone_hybrid`), the physics-informed ARX of
such a building's ``multizone_arx.json`` (:mod:`pinn_mpc.models.multizone_arx`) and the paper's
networks of such a building's ``multizone_paper.json`` (:mod:`pinn_mpc.models.multizone_paper`), all fitted with
the building's layout by :func:`scenarios.experiments.compare.train_scenario_zones`. A new network architecture (a registry entry,
:mod:`pinn_mpc.models.registry`) saves and loads as the networks do; a family with files of
its own adds its format here. A directory holds one model: :func:`save` removes the other
formats' files, and :func:`load` refuses a directory holding two.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from pinn_mpc.artifacts import META, MODEL_DIRECTORY, check_model_path, load_model, save_model
from pinn_mpc.errors import InternalError, ModelFileError
from pinn_mpc.io import DirectoryLayout
from pinn_mpc.model_choice import ModelChoice, choose_model
from pinn_mpc.models.arx import ARX_DIRECTORY, ARX_FILE, ARXModel, fit_linear, load_arx, save_arx
from pinn_mpc.models.learned import LearnedModel
from pinn_mpc.models.multizone_arx import (
    MULTIZONE_ARX_DIRECTORY,
    MULTIZONE_ARX_FILE,
    MultiZoneARX,
    load_multizone_arx,
    save_multizone_arx,
)
from pinn_mpc.models.multizone_hybrid import (
    MULTIZONE_DIRECTORY,
    MULTIZONE_FILE,
    MultiZoneHybrid,
    load_multizone,
    save_multizone,
)
from pinn_mpc.models.multizone_paper import ARCHS as PAPER_ZONE_ARCHS
from pinn_mpc.models.multizone_paper import (
    MULTIZONE_PAPER_DIRECTORY,
    MULTIZONE_PAPER_FILE,
    MultiZonePaperModel,
    load_multizone_paper,
    save_multizone_paper,
)
from pinn_mpc.models.registry import (
    ALL_ARCHS,
    AUTO,
    BASELINES,
    DEFAULT_ARCH,
    MODEL_CHOICES,
    PHYSICS_ARX,
)
from pinn_mpc.models.rollout import FittedModel
from pinn_mpc.training import TrainConfig, train_model

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "FORMATS",
    "FittedModel",
    "ModelFormat",
    "fit",
    "holds_model",
    "load",
    "model_files",
    "output_layout",
    "save",
]


@dataclass(frozen=True, kw_only=True)
class ModelFormat:
    """How the models of some families are kept in a directory: its ``layout`` (the files it
    writes), its ``marker`` (the file that says a directory holds this format: it describes
    the rest), ``what`` (the format in a message: "a network's"), the ``families`` it holds
    (registry names) and whether of buildings of several ``zones``, the ``model_type`` of its
    models, and how to ``write`` one (returning the files written) and ``read`` one (checked,
    raising InputError naming the file)."""

    layout: DirectoryLayout
    marker: str
    what: str
    families: tuple[str, ...]
    model_type: type
    write: Callable[[FittedModel, Path], list[Path]]
    read: Callable[[Path], FittedModel]
    zones: bool = False


def _write_network(model: FittedModel, path: Path) -> list[Path]:
    if not isinstance(model, LearnedModel):  # save() picks the format by the model's type
        raise InternalError(f"a network's model directory given a {type(model).__name__}")
    save_model(model, path, force=True)  # the caller checked the directory
    return MODEL_DIRECTORY.paths(path)


def _write_arx(model: FittedModel, path: Path) -> list[Path]:
    if not isinstance(model, ARXModel):
        raise InternalError(f"an ARX model directory given a {type(model).__name__}")
    return [save_arx(model, path)]


def _write_multizone(model: FittedModel, path: Path) -> list[Path]:
    if not isinstance(model, MultiZoneHybrid):
        raise InternalError(f"a multi-zone model directory given a {type(model).__name__}")
    return [save_multizone(model, path)]


def _write_multizone_arx(model: FittedModel, path: Path) -> list[Path]:
    if not isinstance(model, MultiZoneARX):
        raise InternalError(f"a multi-zone ARX model directory given a {type(model).__name__}")
    return [save_multizone_arx(model, path)]


def _write_multizone_paper(model: FittedModel, path: Path) -> list[Path]:
    if not isinstance(model, MultiZonePaperModel):
        raise InternalError(f"a multi-zone paper network directory given a {type(model).__name__}")
    return [save_multizone_paper(model, path)]


#: The model directory formats, one per kind of fitted model.
FORMATS: tuple[ModelFormat, ...] = (
    ModelFormat(
        layout=MODEL_DIRECTORY, marker=META, what="a network's", families=ALL_ARCHS,
        model_type=LearnedModel, write=_write_network, read=load_model,
    ),
    ModelFormat(
        layout=ARX_DIRECTORY, marker=ARX_FILE, what="an ARX's", families=tuple(BASELINES),
        model_type=ARXModel, write=_write_arx, read=load_arx,
    ),
    ModelFormat(
        layout=MULTIZONE_DIRECTORY, marker=MULTIZONE_FILE, what="a multi-zone hybrid's", families=(DEFAULT_ARCH,),
        model_type=MultiZoneHybrid, write=_write_multizone, read=load_multizone, zones=True,
    ),
    ModelFormat(
        layout=MULTIZONE_ARX_DIRECTORY, marker=MULTIZONE_ARX_FILE, what="a multi-zone ARX's",
        families=(PHYSICS_ARX.name,), model_type=MultiZoneARX, write=_write_multizone_arx, read=load_multizone_arx,
        zones=True,
    ),
    ModelFormat(
        layout=MULTIZONE_PAPER_DIRECTORY, marker=MULTIZONE_PAPER_FILE, what="a multi-zone paper network's",
        families=PAPER_ZONE_ARCHS, model_type=MultiZonePaperModel, write=_write_multizone_paper,
        read=load_multizone_paper, zones=True,
    ),
)


def fit(
    df: pd.DataFrame, *, arch: str = AUTO, config: TrainConfig | None = None, progress: bool = False
) -> ModelChoice:
    """Any model ``train --arch`` takes, fitted on ``df``: ``auto``
    (:func:`pinn_mpc.model_choice.choose_model`, the default), a network architecture
    (:func:`pinn_mpc.training.train_model` with ``config``) or a least-squares ARX (``arx``,
    ``parx``; ``config.eta`` the actuator's sign). ``progress``: the training's bars on stderr.
    The fitted model is the result's ``model``; ``chosen`` names its family."""
    config = TrainConfig() if config is None else config
    if arch == AUTO:
        return choose_model(df, config, progress=progress)
    if arch not in MODEL_CHOICES:
        raise ValueError(f"unknown architecture {arch!r}; choose one of {AUTO}, {', '.join(MODEL_CHOICES)}")
    model: FittedModel
    if arch in BASELINES:
        model = fit_linear(arch, df, eta=config.eta)
    else:
        model = train_model(df, arch=arch, config=config, progress=progress)
    return ModelChoice(chosen=arch, model=model, held_out_mae_c={}, horizon_steps=0, why="as asked")


def _format_of(model: FittedModel) -> ModelFormat:
    for fmt in FORMATS:
        if isinstance(model, fmt.model_type):
            return fmt
    known = ", ".join(f.model_type.__name__ for f in FORMATS)
    raise TypeError(f"save takes a fitted model ({known}), got {type(model).__name__}")


def save(model: FittedModel, path: str | os.PathLike[str]) -> list[Path]:
    """Write ``model`` into the model directory ``path`` (created; its files replaced, the
    other formats' removed, so that the directory holds one model); the files written. The
    caller checks ``path`` first (:func:`pinn_mpc.io.check_output_directory` with
    :func:`output_layout`)."""
    fmt = _format_of(model)
    written = fmt.write(model, Path(path))
    for other in FORMATS:
        if other is not fmt:
            for old in other.layout.paths(path):
                old.unlink(missing_ok=True)
    return written


def _formats_in(directory: Path) -> list[ModelFormat]:
    return [fmt for fmt in FORMATS if (directory / fmt.marker).is_file()]


def holds_model(path: str | os.PathLike[str]) -> bool:
    """Whether the directory ``path`` holds a model of some format (its marker file is there;
    whether it loads is :func:`load`'s to say)."""
    return bool(_formats_in(Path(path)))


def load(path: str | os.PathLike[str]) -> FittedModel:
    """The model in the directory ``path`` (``train --out``), of whichever family: checked
    as its format reads it (ModelFileError or InputError with one line naming the file);
    a directory that holds no model, or two, is refused saying which files it lacks or has."""
    directory = check_model_path(path)
    found = _formats_in(directory)
    if len(found) > 1:
        held = " and ".join(f"{f.marker} ({f.what})" for f in found)
        raise ModelFileError(
            f"model directory {directory} holds two models, {held}; move away the files of the "
            "one you do not mean"
        )
    if not found:
        wanted = " or ".join(f"{f.marker} ({f.what})" for f in FORMATS)
        raise ModelFileError(f"model directory {directory} has no {wanted}; it is not a saved model")
    return found[0].read(directory)


def model_files(path: str | os.PathLike[str]) -> list[Path]:
    """Every file a model directory ``path`` may hold, of any format (what no output may
    replace)."""
    return [file for fmt in FORMATS for file in fmt.layout.paths(path)]


def output_layout(arch: str, *, zones: bool = False) -> DirectoryLayout:
    """What ``train --arch arch --out DIR`` writes (on data of several ``zones`` or one), for
    checking ``DIR`` first: any model's files (the other formats' are removed, :func:`save`); a
    directory is already this kind of output when it holds the format's ``arch`` writes
    (``auto``: any)."""
    files = tuple(file for fmt in FORMATS for file in fmt.layout.files)
    if arch == AUTO:
        return DirectoryLayout(kind="model directory", files=files, markers=())
    fmt = next((f for f in FORMATS if arch in f.families and f.zones == zones), None)
    if fmt is None:
        raise ValueError(f"unknown architecture {arch!r}; choose one of {AUTO}, {', '.join(MODEL_CHOICES)}")
    return DirectoryLayout(kind=fmt.layout.kind, files=files, markers=fmt.layout.markers)
