"""The rollout interface every planner model has, and its result type.

A learned ensemble (:class:`pinn_mpc.models.LearnedModel`), the 2R2C
(:class:`pinn_mpc.models.rc.RCBatchModel`) and the ARX (:class:`pinn_mpc.models.arx.ARXModel`)
all map (history, candidate plans, exogenous forecast) to one :class:`Rollout`: predicted
end-of-interval T_r and T_m of each zone, tensors (M members, N plans, H intervals, Z zones),
and the delivered power (M, N, H). A model of one zone's one actuator (Z = 1,
:meth:`Rollout.of_one_zone`; the learned ensembles, the 2R2C, the ARX) takes plans (N, H) of
that actuator; a model of a building of several zones or actuators
(:class:`pinn_mpc.models.multizone_rc.MultiZoneRCModel`) declares its
:attr:`BatchDynamics.actuators` and takes plans (N, H, A), one power per actuator, and its
delivered power is the building's total, on which the price is paid.
Planners and the factory take :class:`BatchDynamics`, nothing more; each of those classes
declares it as its base, so the type checker holds it to the protocol, and what a planner may
exploit beyond the rollout is a declared property of the protocol, never probed.

:class:`FittedModel` is what ``train`` makes, of every family (the learned ensembles and the
ARX models, not the RC): a planner model that also says what it is and what it was fitted on,
so that the callers of :func:`pinn_mpc.fitted.fit` and :func:`pinn_mpc.fitted.load` never ask
which family they hold.

A fleet's buildings roll out through their own models' rollouts
(:class:`pinn_mpc.models.fleet.FleetModels`); models of one kind that can roll out several
buildings in one batch say so by a :attr:`BatchDynamics.stack_key` and build that batch
(:meth:`BatchDynamics.stacked`, a :class:`StackedDynamics`). Every kind rolls out alone by
default, so a new kind is a fleet's without doing anything.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import numpy as np
import torch

from pinn_mpc.errors import InternalError
from pinn_mpc.zones import ONE_ZONE, ZoneSpec

if TYPE_CHECKING:
    from pinn_mpc.actuator import ActuatorSpec
    from pinn_mpc.multizone import MultiZoneParams

__all__ = ["BatchDynamics", "Exogenous", "FittedModel", "Histories", "Rollout", "StackedDynamics"]

#: Each building's history, in the data format's names (as :meth:`BatchDynamics.rollout` takes it).
Histories = Sequence[Mapping[str, np.ndarray]]
#: A forecast's exogenous series, one array (>= H,) per name.
Exogenous = Mapping[str, np.ndarray]


class Rollout(NamedTuple):
    """Recursive predictions for M members x N plans x H intervals of a building of Z zones
    (torch tensors; a fleet's have the buildings first)."""

    t_r_c: torch.Tensor  # (M, N, H, Z) each zone's T_r at the end of each interval [C]
    u_phys_w: torch.Tensor  # (M, N, H) delivered power during each interval [W]
    t_m_c: torch.Tensor | None  # (M, N, H, Z) T_m at the start of each interval [C]; None for mlp

    @classmethod
    def of_one_zone(cls, t_r_c: torch.Tensor, u_phys_w: torch.Tensor, t_m_c: torch.Tensor | None) -> Rollout:
        """The rollout of a one-zone model from its (..., H) predictions (Z = 1)."""
        return cls(t_r_c[..., None], u_phys_w, None if t_m_c is None else t_m_c[..., None])


class BatchDynamics(Protocol):
    """What a planner needs of a model.

    ``rollout(history, u_w, exog)``: ``history`` in the data format's names (``T_r`` up to and
    including now, ``u_phys`` of past intervals, exogenous series up to now; see
    :class:`controllers.base.Observation`), ``u_w`` (N, H) demanded power [W] ((N, H, A) for a
    model that declares :attr:`actuators`), ``exog`` one
    array (H,) per name in ``exog_names`` (data-format names). The model needs ``depth + 1``
    past intervals of history. ``eta`` (heat per W of actuator power, < 0 cooling) and ``dt_s``
    (the interval it steps) must match the scenario's. ``affine_in_plan``: the horizon's T_r is
    an affine map of the plan, time-varying (the ARX, whose ``prediction_matrices`` give it),
    so a linearisation is exact only when every step is probed.
    """

    @property
    def n_members(self) -> int: ...

    @property
    def eta(self) -> float: ...

    @property
    def dt_s(self) -> float: ...

    @property
    def depth(self) -> int: ...

    @property
    def exog_names(self) -> tuple[str, ...]: ...

    @property
    def affine_in_plan(self) -> bool: ...

    def rollout(
        self, history: dict[str, np.ndarray], u_w: torch.Tensor, exog: dict[str, np.ndarray]
    ) -> Rollout: ...

    @property
    def actuators(self) -> tuple[ActuatorSpec, ...] | None:
        """The actuators of a model of a building of several zones or actuators, in the order
        of the last axis of its plans ``u_w`` (N, H, A); None, the default: a model of one
        zone's one actuator, whose plans are (N, H)."""
        return None

    @property
    def zones(self) -> tuple[ZoneSpec, ...]:
        """The zones of its predictions' last axis (Z), in order (the one zone by default)."""
        return ONE_ZONE

    @property
    def zone_params(self) -> MultiZoneParams | None:
        """The multi-zone RC building a planner over this model falls back on (the QP MPC on
        it, :class:`controllers.rc_mpc.multizone.MultiZoneMPC`); None, the default: none."""
        return None

    @property
    def stack_key(self) -> Hashable | None:
        """Models whose keys are equal (and not None) roll out in one batch when they are a
        fleet's buildings (:meth:`stacked`); None, the default: this model rolls out alone."""
        return None

    def stacked(self, models: Sequence[BatchDynamics], members: int) -> StackedDynamics:
        """``models`` (every one with this model's :attr:`stack_key`) as one batch of
        buildings, each with its first ``members`` members."""
        raise InternalError(f"{type(self).__name__} has no stack key: its buildings roll out alone")


class StackedDynamics(Protocol):
    """G buildings' models of one kind rolled out in one batch (:meth:`BatchDynamics.stacked`):
    :meth:`prepare` once per decision (the plan-free part, from each building's history as
    :meth:`BatchDynamics.rollout` takes it, ``drop_last`` intervals before its end, under the
    one forecast ``exog``), then :meth:`roll` for any number of plans (G, N, H) [W]; the
    :class:`Rollout`'s tensors are (G, M, N, H). A building's rollout is its model's, up to
    float round-off."""

    def prepare(self, histories: Histories, exog: Exogenous, h: int, *, drop_last: int = 0) -> object: ...

    def roll(self, start: object, u_w: torch.Tensor) -> Rollout: ...


class FittedModel(BatchDynamics, Protocol):
    """A model ``train`` fits (:func:`pinn_mpc.fitted.fit`), of any family: a planner model
    (:class:`BatchDynamics`) that says what it is and what it was fitted on.

    ``family``: its name in the registry (:mod:`pinn_mpc.models.registry`: a network's
    architecture, ``arx``, ``parx``). ``identified_rc``: the RC JSON object
    (:func:`pinn_mpc.physics.rc_summary` with a ``fit`` block) identified from its training
    data, which a planner over it falls back on; None where no RC could be identified.
    ``training_data``: the summary of its training data
    (:func:`pinn_mpc.training.data_summary`: columns, rows, each input's range).
    """

    @property
    def family(self) -> str: ...

    @property
    def identified_rc(self) -> dict[str, Any] | None: ...

    @property
    def training_data(self) -> dict[str, Any]: ...
