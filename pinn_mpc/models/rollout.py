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
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import numpy as np
import torch

from pinn_mpc.errors import InternalError
from pinn_mpc.zones import ONE_ZONE, ZoneSpec

if TYPE_CHECKING:
    from pinn_mpc.actuator import ActuatorSpec
    from pinn_mpc.multizone import MultiZoneParams

__all__ = [
    "BatchDynamics",
    "Exogenous",
    "FittedModel",
    "Histories",
    "LinearResponse",
    "Rollout",
    "StackedDynamics",
]

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


@dataclass(frozen=True, kw_only=True)
class LinearResponse:
    """A model's rollout of one plan (H, A) of a building of Z zones and A actuators and its
    exact response to a change of that plan, as an affine state-space system (what
    :meth:`BatchDynamics.linear_response` gives): the state's change after interval j is
    ``dx_j = a dx_(j-1) + b_heat (heat_per_w[j] * du_j)`` (``dx_(-1) = 0``), each zone's room
    change ``dx_j[rooms]``, the delivered power's change ``power[j] * du_j``, for ``du_j`` (A,)
    the change of each actuator's demand in interval j [W]. Exact while the change switches no
    rule the rollout applies to the state (a backup thermostat): the derivative of the rollout
    where it is affine in the plan."""

    t_r_c: np.ndarray  # (H, Z) each zone's room at the end of each interval, at the plan [C]
    u_phys_w: np.ndarray  # (H,) the building's delivered power in each interval, at the plan [W]
    a: np.ndarray  # (S, S) the state's transition over one interval
    b_heat: np.ndarray  # (S, A) the state's change per W of each actuator's heat (its sign in it) [K/W]
    heat_per_w: np.ndarray  # (H, A) each actuator's heat per W of demand in interval j (0: it does not follow)
    rooms: np.ndarray  # (Z,) the rooms' indices in the state
    power: np.ndarray  # (H, A) the delivered power's change per W of demand [W/W]

    def __post_init__(self) -> None:
        h, z_n = self.t_r_c.shape
        s_n, a_n = self.b_heat.shape
        shapes = {
            "u_phys_w": (self.u_phys_w.shape, (h,)), "a": (self.a.shape, (s_n, s_n)),
            "heat_per_w": (self.heat_per_w.shape, (h, a_n)), "rooms": (self.rooms.shape, (z_n,)),
            "power": (self.power.shape, (h, a_n)),
        }
        for name, (got, want) in shapes.items():
            if got != want:
                raise ValueError(
                    f"LinearResponse.{name} has shape {got}, but t_r_c {self.t_r_c.shape} and b_heat "
                    f"{self.b_heat.shape} make it {want}; give arrays of one horizon, state and plan"
                )

    @property
    def b(self) -> np.ndarray:
        """(H, S, A) the state's change per W of each actuator's demand in interval j [K/W]."""
        return self.b_heat[None] * self.heat_per_w[:, None, :]

    def jacobians(self) -> tuple[np.ndarray, np.ndarray]:
        """The rollout's derivatives, dense: ``jr`` (H, Z, H, A), d(room z at the end of
        interval j) / d(demand of actuator a in interval i) [K/W] (the impulse response
        ``a^(j-i) b[i]`` of the rooms, 0 for i > j), and ``jp`` (H, H, A), d(delivered power
        in interval j) / d(demand in interval i) [W/W]."""
        h, z_n = self.t_r_c.shape
        a_n = self.b_heat.shape[1]
        b = self.b
        reach = np.empty((h, z_n, self.a.shape[0]))  # (L, Z, S) the rooms' rows of a^L
        reach[0] = np.eye(self.a.shape[0])[self.rooms]
        for lag in range(1, h):
            reach[lag] = reach[lag - 1] @ self.a
        jr = np.zeros((h, z_n, h, a_n))
        for i in range(h):
            jr[i:, :, i, :] = reach[: h - i] @ b[i]
        jp = np.zeros((h, h, a_n))
        jp[np.arange(h), np.arange(h)] = self.power
        return jr, jp


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
    def estimates_state(self) -> bool:
        """Whether each rollout starts from a state a filter re-estimates from every measured
        room (:class:`pinn_mpc.models.multizone_rc.MultiZoneRCModel`'s Kalman filter): its
        one-step errors are then the filter's innovations, noise that a planner's offset filter
        would only pass on. False, the default: the planner's offset filter corrects it."""
        return False

    def linear_response(
        self, history: Mapping[str, np.ndarray], u_w: np.ndarray, exog: Exogenous
    ) -> LinearResponse | None:
        """The rollout of one plan ``u_w`` (H, A) [W] of a model of several actuators and its
        exact response to a change of the plan (:class:`LinearResponse`), which a planner's LP
        polish uses instead of probing every step of every actuator; None, the default: the
        model does not give it (the polish probes)."""
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
