"""What the closed loop steps: the plant protocol and the one result of a plant's interval.

A plant is reset to a start row, measured, stepped one control interval with the power asked,
and closed. Its step returns :class:`PlantStep`: what happened in the building over the
interval (:class:`~pinn_mpc.simulator.StepResult`: the room at its end, the power delivered,
the backup thermostat's overrides) and the interval's means of the exogenous inputs as the
plant had them (its own weather and gains, where it has them). Every plant of
:mod:`scenarios.plants` implements :class:`LoopPlant`; none knows a scenario.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np

from pinn_mpc.simulator import StepResult

__all__ = ["LoopPlant", "PlantStep", "TrueStatePlant"]


class PlantStep(NamedTuple):
    """One control interval of any plant: the step result and the interval's means of the
    exogenous inputs as the plant had them, (B,) each."""

    result: StepResult
    t_a_c: np.ndarray  # outdoor temperature [C]
    g_w_per_m2: np.ndarray  # global horizontal irradiance [W/m2]
    i_g_w: np.ndarray  # internal gains [W]


class LoopPlant(Protocol):
    """What :class:`scenarios.running.engine.ClosedLoop` steps: B buildings, each interval in
    ``n_substeps`` substeps.

    ``reset`` starts an episode at row ``start`` of the loop's exogenous series from the state
    (T_r, T_m) (a plant that cannot set its state warms up towards T_r instead); ``measure``
    is the sensor's room temperature now; ``step`` holds the demand over the interval of row
    ``row`` and returns the step result with the interval's means of the exogenous inputs;
    ``close`` frees what it holds. ``has_true_state``: the plant is a :class:`TrueStatePlant`
    (a controller with perfect knowledge can run on it).
    """

    n_buildings: int
    n_substeps: int
    has_true_state: bool

    def reset(self, t_r_c: float, t_m_c: float, *, start: int, seed: int | None) -> None: ...

    def measure(self) -> np.ndarray: ...

    def step(self, u_w: float | np.ndarray, row: int) -> PlantStep: ...

    def close(self) -> None: ...


class TrueStatePlant(LoopPlant, Protocol):
    """A plant whose state is known exactly (the RC simulator): ``true_state`` is the true
    room and thermal-mass temperatures (B, 2) now [C], which only a controller with perfect
    knowledge (and a reference that plans on the truth) sees."""

    def true_state(self) -> np.ndarray: ...
