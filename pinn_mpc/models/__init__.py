"""Learned models as plug-ins: one module per architecture behind one protocol.

- :mod:`~pinn_mpc.models.rollout`: the rollout interface planners use (:class:`BatchDynamics`)
  and its result (:class:`Rollout`).
- :mod:`~pinn_mpc.models.registry`: the architectures by name, with their defaults (light:
  no torch).
- :mod:`~pinn_mpc.models.base`: the :class:`Architecture` protocol (network, loss terms,
  rollout, record fields) and what training hands it.
- :mod:`~pinn_mpc.models.mlp`, :mod:`~pinn_mpc.models.physreg`,
  :mod:`~pinn_mpc.models.physnet` (the paper's, sharing :mod:`~pinn_mpc.models.paper`) and
  :mod:`~pinn_mpc.models.hybrid` (the recommended model for control).
- :mod:`~pinn_mpc.models.layers` (ensemble layers), :mod:`~pinn_mpc.models.physics_block`
  (learnable 2R2C, physics residuals), :mod:`~pinn_mpc.models.learned` (:class:`LearnedModel`,
  :class:`ModelRecord`).
- The other planner models, each declaring :class:`BatchDynamics` as :class:`LearnedModel`
  does: :mod:`~pinn_mpc.models.rc` (the 2R2C), :mod:`~pinn_mpc.models.arx` (the linear ARX
  baseline); and :mod:`~pinn_mpc.models.fleet` (many buildings' models of any kind rolled out
  together, :class:`~pinn_mpc.models.fleet.FleetModels`).

Every layer holds the weights of all M members and applies them in one batched product, so an
ensemble trains and rolls out as one model. Names are imported on first use
(:mod:`pinn_mpc.lazy`), so the registry can be read without loading torch.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pinn_mpc.lazy import lazy_exports

if TYPE_CHECKING:
    from pinn_mpc.models.base import Architecture as Architecture
    from pinn_mpc.models.hybrid import RESIDUAL_BOUND_FACTOR as RESIDUAL_BOUND_FACTOR
    from pinn_mpc.models.hybrid import RESIDUAL_UNBOUNDED_K as RESIDUAL_UNBOUNDED_K
    from pinn_mpc.models.hybrid import HybridConstants as HybridConstants
    from pinn_mpc.models.hybrid import HybridInputs as HybridInputs
    from pinn_mpc.models.hybrid import HybridNet as HybridNet
    from pinn_mpc.models.layers import EnsembleLinear as EnsembleLinear
    from pinn_mpc.models.learned import MAX_MEMBERS as MAX_MEMBERS
    from pinn_mpc.models.learned import EnsembleModule as EnsembleModule
    from pinn_mpc.models.learned import LearnedModel as LearnedModel
    from pinn_mpc.models.learned import ModelRecord as ModelRecord
    from pinn_mpc.models.physics_block import Physics as Physics
    from pinn_mpc.models.physics_block import discretise_torch as discretise_torch
    from pinn_mpc.models.physics_block import interp_clamped as interp_clamped
    from pinn_mpc.models.physics_block import residual_exact as residual_exact
    from pinn_mpc.models.physics_block import (
        residual_finite_difference as residual_finite_difference,
    )
    from pinn_mpc.models.registry import ALL_ARCHS as ALL_ARCHS
    from pinn_mpc.models.registry import ARCHS as ARCHS
    from pinn_mpc.models.registry import DEFAULT_ARCH as DEFAULT_ARCH
    from pinn_mpc.models.registry import get_architecture as get_architecture
    from pinn_mpc.models.rollout import BatchDynamics as BatchDynamics
    from pinn_mpc.models.rollout import Rollout as Rollout

_EXPORTS = {
    "pinn_mpc.models.base": ("Architecture",),
    "pinn_mpc.models.hybrid": (
        "RESIDUAL_BOUND_FACTOR", "RESIDUAL_UNBOUNDED_K", "HybridConstants", "HybridInputs",
        "HybridNet",
    ),
    "pinn_mpc.models.layers": ("EnsembleLinear",),
    "pinn_mpc.models.learned": ("MAX_MEMBERS", "EnsembleModule", "LearnedModel", "ModelRecord"),
    "pinn_mpc.models.physics_block": (
        "Physics", "discretise_torch", "interp_clamped", "residual_exact",
        "residual_finite_difference",
    ),
    "pinn_mpc.models.registry": ("ALL_ARCHS", "ARCHS", "DEFAULT_ARCH", "get_architecture"),
    "pinn_mpc.models.rollout": ("BatchDynamics", "Rollout"),
}
__all__ = [name for names in _EXPORTS.values() for name in names]
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
