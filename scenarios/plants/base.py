"""What the closed loop steps: the plant protocol and the one result of a plant's interval.

A plant is reset to a start row, measured, stepped one control interval with the power asked,
and closed. Its step returns :class:`PlantStep`: what happened in the building over the
interval, zone by zone (each zone's room at its end and over its substeps, the power delivered,
the backup thermostat's overrides) and the interval's means of the exogenous inputs as the
plant had them (its own weather and gains, where it has them). A plant has a zone axis
(``zones``): its measurements and states are (B, Z). Every plant of
:mod:`scenarios.plants` implements :class:`LoopPlant`; none knows a scenario.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np

from pinn_mpc.simulator import StepResult
from pinn_mpc.zones import ZoneSpec

__all__ = ["LoopPlant", "PlantStep", "TrueStatePlant"]


class PlantStep(NamedTuple):
    """One control interval of any plant, for B buildings of Z zones: what happened in each
    zone (true states, not measurements) and the interval's means of the exogenous inputs as
    the plant had them."""

    t_r_c: np.ndarray  # (B, Z) room temperature at the end of the interval [C]
    t_m_c: np.ndarray  # (B, Z) thermal-mass temperature at its end [C] (NaN where none is known)
    u_phys_w: np.ndarray  # (B,) mean electrical power delivered over the interval [W]
    overridden: np.ndarray  # (B,) bool, the backup changed the demand in some substep
    t_r_sub_c: np.ndarray  # (B, S, Z) room temperature at the end of each substep [C]
    t_a_c: np.ndarray  # (B,) outdoor temperature [C]
    g_w_per_m2: np.ndarray  # (B,) global horizontal irradiance [W/m2]
    i_g_w: np.ndarray  # (B,) internal gains [W]
    # (B, A) each actuator's mean delivered electrical power [W] (u_phys_w is their sum); None:
    # the building's one actuator, whose power is u_phys_w
    u_phys_act_w: np.ndarray | None = None

    def actuator_powers_w(self) -> np.ndarray:
        """(B, A) each actuator's mean delivered electrical power over the interval [W]."""
        return self.u_phys_w[:, None] if self.u_phys_act_w is None else self.u_phys_act_w

    @classmethod
    def of_one_zone(
        cls, result: StepResult, t_a_c: np.ndarray, g_w_per_m2: np.ndarray, i_g_w: np.ndarray
    ) -> PlantStep:
        """The step of a one-zone plant from its simulator's (B,) result (Z = 1)."""
        return cls(
            t_r_c=result.t_r_c[:, None], t_m_c=result.t_m_c[:, None], u_phys_w=result.u_phys_w,
            overridden=result.overridden, t_r_sub_c=result.t_r_sub_c[:, :, None],
            t_a_c=t_a_c, g_w_per_m2=g_w_per_m2, i_g_w=i_g_w,
        )


class LoopPlant(Protocol):
    """What :class:`scenarios.running.engine.ClosedLoop` steps: B buildings of the zones
    ``zones`` (:class:`pinn_mpc.zones.ZoneSpec`), each interval in
    ``n_substeps`` substeps.

    ``reset`` starts an episode at row ``start`` of the loop's exogenous series from the state
    (T_r, T_m) (a plant that cannot set its state warms up towards T_r instead; a plant of
    several zones starts each zone there); ``measure`` is the sensors' room temperatures now,
    (B, Z); ``step`` holds the demand over the interval of row ``row`` (a number or (B,) for a
    building's one actuator, (B, A) for a plant of ``n_actuators`` > 1) and returns the step result with the interval's means of the exogenous inputs;
    ``close`` frees what it holds. ``has_true_state``: the plant is a :class:`TrueStatePlant`
    (a controller with perfect knowledge can run on it).
    """

    n_buildings: int
    n_substeps: int
    has_true_state: bool
    zones: tuple[ZoneSpec, ...]

    def reset(self, t_r_c: float, t_m_c: float, *, start: int, seed: int | None) -> None: ...

    def measure(self) -> np.ndarray: ...

    def step(self, u_w: float | np.ndarray, row: int) -> PlantStep: ...

    def close(self) -> None: ...


class TrueStatePlant(LoopPlant, Protocol):
    """A plant whose state is known exactly (the RC simulator): ``true_state`` is the true
    room and thermal-mass temperatures (B, 2) now [C], which only a controller with perfect
    knowledge (and a reference that plans on the truth) sees; ``true_zone_states`` is every
    zone's, (B, 2, Z) (the rooms, then the masses)."""

    def true_state(self) -> np.ndarray: ...

    def true_zone_states(self) -> np.ndarray: ...
