"""The protocol every architecture implements, and what training hands it.

An :class:`Architecture` builds its network for M members, chooses the physics block's start,
gives the training loop its loss terms for a mini-batch, finishes its network after training,
adds its own fields to the model record and rolls its network out recursively. The training
loop (:func:`pinn_mpc.training.train_model`) and :class:`pinn_mpc.models.LearnedModel` only
talk to this protocol; the registry (:mod:`pinn_mpc.models.registry`) names the
implementations.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import pandas as pd
import torch
from torch import nn

from pinn_mpc import physics
from pinn_mpc.actuator import CopCurve
from pinn_mpc.errors import InternalError
from pinn_mpc.features import FeatureConfig
from pinn_mpc.models.physics_block import Physics
from pinn_mpc.models.registry import ArchSpec
from pinn_mpc.models.rollout import Rollout, StackedDynamics

if TYPE_CHECKING:
    from pinn_mpc.identify import IdentifyResult
    from pinn_mpc.models.learned import EnsembleModule, LearnedModel
    from pinn_mpc.training import TrainConfig

__all__ = [
    "HOLD_TOLERANCE_W",
    "Architecture",
    "Batch",
    "LossFn",
    "LossTerms",
    "NetParts",
    "RolloutInputs",
    "TrainingSet",
    "regression_loss",
]

#: |u - u_phys| [W] below which an interval counts as held at constant power.
HOLD_TOLERANCE_W = 1.0


@dataclass(frozen=True, kw_only=True)
class TrainingSet:
    """The training samples as tensors, S samples of consecutive rows.

    ``x`` (S, F) scaled features; ``y`` (S, 2) scaled targets (T_r increment, u_phys);
    ``t_r`` (S+1,) measured T_r of the rows [C]; ``inputs`` (S, 4) u_phys [W], T_a, G, I_g of
    each row; ``held`` (S,) 1 where the delivered power was held constant over the interval;
    ``df`` the validated frame, ``features`` its feature configuration; ``chunk`` the
    consecutive samples per mini-batch chunk.
    """

    x: torch.Tensor
    y: torch.Tensor
    t_r: torch.Tensor
    inputs: torch.Tensor
    held: torch.Tensor
    df: pd.DataFrame
    features: FeatureConfig
    chunk: int


class NetParts(NamedTuple):
    """What a network is built from: the feature configuration, the number of members and
    their generators (initial weights), the module's physics block (None without one), the
    physics' start and the data's COP curve (None without a ``cop`` column)."""

    features: FeatureConfig
    n_members: int
    generators: Sequence[torch.Generator]
    physics_block: Physics | None
    prior: physics.RCParams
    cop_curve: CopCurve | None


class RolloutInputs(NamedTuple):
    """A rollout's inputs in scaled units, N plans (or starts) of H steps: ``t_win``, ``p_win``
    (N0, k+1) T_r,i-k..T_r,i and u_phys,i-k-1..u_phys,i-1; ``e_seq`` (N0, n_series, k+H)
    exogenous series from i-k to i+H-1; ``u_s`` (N, H) demand; ``tod`` (N0, H, 2 + c) encoded
    time of day, then the calendar's c columns where the features have it
    (:meth:`pinn_mpc.features.FeatureConfig.encode_clock`). N0 is 1 or N."""

    t_win: torch.Tensor
    p_win: torch.Tensor
    e_seq: torch.Tensor
    u_s: torch.Tensor
    tod: torch.Tensor


class Batch(NamedTuple):
    """A mini-batch of C chunks of L consecutive samples per member.

    ``first`` (M, C) each chunk's first sample, ``idx`` (M, C, L) its samples, ``flat``
    (M, C*L) the same flattened.
    """

    first: torch.Tensor
    idx: torch.Tensor
    flat: torch.Tensor


class LossTerms(NamedTuple):
    """A mini-batch's loss: the ``total`` that is minimised, its regression part ``reg`` and
    its physics part ``phys`` (both reported in the training record)."""

    total: torch.Tensor
    reg: torch.Tensor
    phys: torch.Tensor


#: A prepared loss: a mini-batch -> its loss terms.
LossFn = Callable[[Batch], LossTerms]


def regression_loss(obs: torch.Tensor, data: TrainingSet, batch: Batch) -> torch.Tensor:
    """Mean squared error of the scaled (T_r increment, u_phys) predictions ``obs``."""
    return torch.mean((obs - data.y[batch.flat]) ** 2)


class Architecture(ABC):
    """One learned-model architecture: its network, loss terms, rollout and defaults.

    ``spec`` is its registry entry (name, depth, recipe, data policy); ``has_physics`` whether
    it owns a learnable 2R2C block (then the model has physical coefficients);
    ``physics_lr_factor`` the block's default learning-rate factor; ``format_versions`` the
    model-directory formats its saved models can be read from; ``calendar`` and
    ``optional_exog`` the inputs beyond the paper's its features hold.
    """

    has_physics = True
    physics_lr_factor = 10.0
    format_versions: tuple[int, ...] = (1, 2)
    #: Whether its features carry the calendar, and the optional exogenous inputs it reads
    #: where the data has them (:mod:`pinn_mpc.features`).
    calendar = False
    optional_exog: tuple[str, ...] = ()
    #: Whether it takes the unmeasured gains' schedule of the RC identified from its data as
    #: its internal gains (``I_g``) where the data has none (:attr:`pinn_mpc.features.
    #: FeatureConfig.gain_schedule_w`).
    gain_schedule = False

    def __init__(self, spec: ArchSpec):
        self.spec = spec

    @property
    def name(self) -> str:
        """The registry name."""
        return self.spec.name

    @abstractmethod
    def build_net(self, parts: NetParts) -> nn.Module:
        """The network of ``parts.n_members`` members; ``forward(x (M, B, F))`` returns ``(obs
        (M, B, 2) scaled (T_r increment, u_phys), z (M, B) scaled T_m or None)``."""

    @abstractmethod
    def training_prior(
        self, config: TrainConfig, df: pd.DataFrame, identified: IdentifyResult | None
    ) -> physics.RCParams:
        """The physics block's start for training on ``df``."""

    def physics_weight(self, lam: float) -> float:
        """The weight of the physics residual in the loss, given the recipe's ``lam``."""
        return 0.0

    def chunk_length(self, lam: float, linked: int) -> int:
        """Consecutive samples per mini-batch chunk: ``linked`` where a physics residual links
        neighbours (``lam`` > 0), else 1; an architecture trained on a multi-step rollout
        loss returns the rollout's length."""
        return linked if lam > 0 else 1

    @abstractmethod
    def loss_fn(
        self, module: EnsembleModule, data: TrainingSet, config: TrainConfig, lam: float
    ) -> LossFn:
        """Prepare the loss of ``module`` on ``data``: a function of a mini-batch."""

    def after_training(self, module: EnsembleModule, data: TrainingSet) -> None:  # noqa: B027
        """Set what depends on the trained weights (nothing unless an architecture needs it)."""

    def record_fields(self, config: TrainConfig, cop_curve: CopCurve | None) -> dict[str, Any]:
        """The architecture's own fields of the model record: ``residual_weight``,
        ``anchor_weight`` and ``cop_curve`` where it uses them."""
        return {}

    def rollout_constants(self, net: nn.Module) -> Any:
        """What a rollout needs of the weights, computed once while they stay the same; None
        when a rollout reads the weights directly."""
        return None

    @abstractmethod
    def rollout_scaled(self, model: LearnedModel, inputs: RolloutInputs) -> Rollout:
        """Batched recursive rollout of ``model`` in scaled units (see
        :meth:`pinn_mpc.models.LearnedModel.rollout_scaled`)."""

    def stack_key(self, model: LearnedModel) -> Hashable | None:
        """What models of this architecture must share to roll out several buildings in one
        batch (:attr:`pinn_mpc.models.rollout.BatchDynamics.stack_key`); None, the default:
        each building's model rolls out alone."""
        return None

    def stacked(self, models: Sequence[LearnedModel], members: int) -> StackedDynamics:
        """``models`` (of one :meth:`stack_key`) as one batch of buildings
        (:meth:`pinn_mpc.models.rollout.BatchDynamics.stacked`)."""
        raise InternalError(f"the {self.name} architecture has no stacked rollout")
