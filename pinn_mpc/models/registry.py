"""The registry of architectures: the one place their names appear.

Each entry is an :class:`ArchSpec`: the architecture's name, the module and class that implement
it (:class:`pinn_mpc.models.base.Architecture`), and the settings that give it its best
accuracy (history depth, training recipe, the data policy it wants). The entries are light (no
torch), so the CLI lists them and their defaults in its help without loading the library;
:func:`get_architecture` imports an implementation when it is first asked for. Adding an
architecture means one module with its :class:`~pinn_mpc.models.base.Architecture` subclass and
one entry here.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pinn_mpc.models.base import Architecture

__all__ = [
    "ALL_ARCHS",
    "AUTO",
    "ARCHITECTURES",
    "ARCHS",
    "ARX",
    "BASELINES",
    "PHYSICS_ARX",
    "COMPARED_ARCHS",
    "CONSISTENT_ARCHS",
    "CONSISTENT_ARX",
    "DEFAULT_ARCH",
    "MODEL_CHOICES",
    "TRAIN_CHOICES",
    "ArchSpec",
    "BaselineSpec",
    "get_architecture",
    "get_spec",
]


@dataclass(frozen=True, kw_only=True)
class ArchSpec:
    """An architecture as the registry lists it.

    ``implementation`` is ``"module:Class"`` of its :class:`~pinn_mpc.models.base.Architecture`;
    ``label`` its name in tables; ``paper`` whether it is one of the paper's networks.
    ``depth`` (history steps), ``recipe`` (:data:`pinn_mpc.choices.RECIPES`) and ``policy``
    (the ``simulate --policy`` of the data it was tuned on) are its defaults; ``summary``
    says in a line what it is; ``consistent`` whether every temperature it predicts is
    non-decreasing in each heating power and outdoor temperature by construction.
    """

    name: str
    implementation: str
    label: str
    paper: bool
    depth: int
    recipe: str
    policy: str
    summary: str
    consistent: bool = False


ARCHITECTURES: dict[str, ArchSpec] = {
    spec.name: spec
    for spec in (
        ArchSpec(
            name="mlp",
            implementation="pinn_mpc.models.mlp:MLP",
            label="MLP",
            paper=True,
            depth=8,
            recipe="converged",
            policy="random",
            summary="the paper's plain network (no physics)",
        ),
        ArchSpec(
            name="physreg",
            implementation="pinn_mpc.models.physreg:PhysReg",
            label="PhysReg MLP",
            paper=True,
            depth=8,
            recipe="long",
            policy="random-level",
            summary="the paper's network with a T_m head and a physics loss",
        ),
        ArchSpec(
            name="physnet",
            implementation="pinn_mpc.models.physnet:PhysNet",
            label="PhysNet",
            paper=True,
            depth=8,
            recipe="long",
            policy="random-level",
            summary="the paper's encoder (T_m) and dynamics networks with a physics loss",
        ),
        ArchSpec(
            name="hybrid",
            implementation="pinn_mpc.models.hybrid:Hybrid",
            label="Hybrid",
            paper=False,
            depth=16,
            recipe="converged",
            policy="random-level",
            summary="the identified 2R2C with learned corrections (recommended for control)",
        ),
        ArchSpec(
            name="pcnn",
            implementation="pinn_mpc.models.pcnn:Pcnn",
            label="PCNN",
            paper=False,
            depth=8,
            recipe="long",
            policy="random-level",
            summary="the physically consistent PhysNet: T_m encoded from the history, power and "
            "outdoor temperature through a positive 2R2C, a network for the unforced heat",
            consistent=True,
        ),
        ArchSpec(
            name="pcnn-parx",
            implementation="pinn_mpc.models.pcnn_parx:PcnnParx",
            label="PCNN-PARX",
            paper=False,
            depth=8,
            recipe="long",
            policy="random-level",
            summary="the physics-informed ARX fitted as a positive system, with a network for "
            "the unforced heat",
            consistent=True,
        ),
    )
}
#: The paper's learned-model architectures.
ARCHS = tuple(name for name, spec in ARCHITECTURES.items() if spec.paper)
#: Every architecture.
ALL_ARCHS = tuple(ARCHITECTURES)
DEFAULT_ARCH = next(name for name, spec in ARCHITECTURES.items() if not spec.paper)
#: The physically consistent architectures (Di Natale et al., 2022).
CONSISTENT_ARCHS = tuple(name for name, spec in ARCHITECTURES.items() if spec.consistent)
#: The consistent network on the physics-informed ARX's structure: ``train``'s default
#: (:mod:`pinn_mpc.model_choice`) weighs it against the ARX where the ARX beats the hybrid.
CONSISTENT_ARX = "pcnn-parx"

#: The architectures ``compare`` trains, in its order: the default, then the paper's
#: networks from the most physical (PhysNet) to the plain MLP.
COMPARED_ARCHS = (DEFAULT_ARCH, *reversed(ARCHS))


@dataclass(frozen=True, kw_only=True)
class BaselineSpec:
    """A model without a network that ``train --arch`` also fits: ``label`` its name in
    tables, ``summary`` what it is (none of the networks' training settings apply to it)."""

    name: str
    label: str
    summary: str


#: The linear ARX baseline (:mod:`pinn_mpc.models.arx`).
ARX = BaselineSpec(
    name="arx",
    label="ARX",
    summary="the linear ARX baseline (least squares on 8 lags and a weekly schedule, no "
    "network)",
)
#: The physics-informed ARX (:func:`pinn_mpc.models.arx.fit_physics_informed_arx`): the ARX with a
#: workday / Saturday / Sunday schedule whose blocks also weigh the indoor-outdoor difference
#: (occupancy-driven ventilation), its heating effect required positive.
PHYSICS_ARX = BaselineSpec(
    name="parx",
    label="Physics-informed ARX",
    summary="the physics-informed linear ARX (the ARX with workday, Saturday and Sunday "
    "schedules, each block also weighing T_r - T_a, heating required to warm; no network)",
)
#: Models ``train`` fits that are not architectures of networks.
BASELINES: dict[str, BaselineSpec] = {ARX.name: ARX, PHYSICS_ARX.name: PHYSICS_ARX}
#: Every model ``train --arch`` fits by name.
MODEL_CHOICES = (*ALL_ARCHS, *BASELINES)
#: The ``train --arch`` choice that picks the model (its default, :mod:`pinn_mpc.model_choice`).
AUTO = "auto"
#: What ``train --arch`` takes: :data:`AUTO`, then every model by name.
TRAIN_CHOICES = (AUTO, *MODEL_CHOICES)


def get_spec(name: str) -> ArchSpec:
    """The registry's entry for ``name``; ValueError naming the choices if there is none."""
    if name not in ARCHITECTURES:
        raise ValueError(f"unknown architecture {name!r}; choose one of {', '.join(ALL_ARCHS)}")
    return ARCHITECTURES[name]


@cache
def get_architecture(name: str) -> Architecture:
    """The implementation of architecture ``name`` (imported on first use, then kept)."""
    spec = get_spec(name)
    module, cls = spec.implementation.split(":")
    architecture: Architecture = getattr(importlib.import_module(module), cls)(spec)
    return architecture
