"""The RC simulator as a plant: the minute-level 2R2C or 3R3C of :mod:`pinn_mpc.simulator`, with
its backup thermostat, one building or a fleet stepped in one batch."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pinn_mpc.physics import RCParams
from pinn_mpc.simulator import SimConfig, Simulator
from scenarios.plants.base import PlantStep

__all__ = ["RCPlant"]


class RCPlant:
    """The RC simulator (:class:`pinn_mpc.simulator.Simulator`) as a
    :class:`~scenarios.plants.base.LoopPlant`, driven by the rows of the outdoor temperature
    ``t_a_c`` [C], irradiance ``g_w_per_m2`` [W/m2] and internal gains ``i_g_w`` [W], (N,)
    each, so the interval means are those rows."""

    has_true_state = True

    def __init__(
        self, config: SimConfig, *, t_a_c: np.ndarray, g_w_per_m2: np.ndarray, i_g_w: np.ndarray,
        seed: int | None, fleet: Sequence[RCParams] | None,
    ) -> None:
        self.sim = Simulator(config, seed=seed, fleet=fleet)
        self.t_a_c, self.g_w_per_m2, self.i_g_w = t_a_c, g_w_per_m2, i_g_w
        self.n_buildings = self.sim.n_buildings
        self.n_substeps = config.n_substeps

    def reset(self, t_r_c: float, t_m_c: float, *, start: int, seed: int | None) -> None:
        self.sim.reset(t_r_c, t_m_c, seed=seed)

    def measure(self) -> np.ndarray:
        return self.sim.measure()

    def hidden_t_m(self) -> np.ndarray:
        return self.sim.state[:, 1]

    def step(self, u_w: float | np.ndarray, row: int) -> PlantStep:
        t_a, g, i_g = self.t_a_c[row], self.g_w_per_m2[row], self.i_g_w[row]
        result = self.sim.step(u_w, t_a, g, i_g)
        shape = (self.n_buildings,)
        return PlantStep(result, np.full(shape, t_a), np.full(shape, g), np.full(shape, i_g))

    def close(self) -> None:
        """Nothing to free."""
