"""Batched 2R2C simulator with the paper's backup thermostat (Eq. backup).

Each control interval (``dt_s``, default 30 min) is integrated in substeps (default 1 min)
with the exact zero-order-hold discretisation of :mod:`pinn_mpc.physics`; the backup
thermostat is re-evaluated at the start of every substep, so the power actually delivered
(``u_phys``, the interval mean) can differ from the demand ``u``. All buildings share one
parameter set and step together as arrays of shape (B,).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from pinn_mpc.errors import InputError
from pinn_mpc.physics import PAPER_HOUSEHOLD, RCParams, discretise

__all__ = ["SimConfig", "Simulator", "StepResult", "backup_power"]


@dataclass(frozen=True, kw_only=True)
class SimConfig:
    """Building, actuator and backup-thermostat settings of a simulation."""

    params: RCParams = field(default_factory=lambda: PAPER_HOUSEHOLD)
    u_max_w: float = 5000.0
    dt_s: float = 1800.0
    substep_s: float = 60.0
    backup_low_c: float = 17.0
    backup_high_c: float = 20.5
    noise_std_c: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.u_max_w) and self.u_max_w > 0):
            raise InputError(f"SimConfig.u_max_w must be positive, got {self.u_max_w!r}")
        if not (self.substep_s > 0 and self.dt_s > 0):
            raise InputError(
                f"SimConfig dt_s and substep_s must be positive, got {self.dt_s}, {self.substep_s}"
            )
        ratio = self.dt_s / self.substep_s
        if abs(ratio - round(ratio)) > 1e-9:
            raise InputError(
                f"SimConfig.dt_s={self.dt_s} must be a whole multiple of substep_s={self.substep_s}"
            )
        if not self.backup_low_c < self.backup_high_c:
            raise InputError(
                f"backup limits must satisfy low < high, got {self.backup_low_c} / {self.backup_high_c}"
            )
        if not (math.isfinite(self.noise_std_c) and self.noise_std_c >= 0):
            raise InputError(f"SimConfig.noise_std_c must be >= 0, got {self.noise_std_c!r}")

    @property
    def n_substeps(self) -> int:
        return round(self.dt_s / self.substep_s)


class StepResult(NamedTuple):
    """Outcome of one control interval for B buildings (true states, not measurements)."""

    t_r_c: np.ndarray  # (B,) room temperature at the end of the interval [C]
    t_m_c: np.ndarray  # (B,) thermal-mass temperature at the end of the interval [C]
    u_phys_w: np.ndarray  # (B,) mean power delivered over the interval [W]
    overridden: np.ndarray  # (B,) bool, the backup changed the demand in some substep
    t_r_sub_c: np.ndarray  # (B, n_substeps) room temperature at the end of each substep [C]


def backup_power(t_r_c: np.ndarray, u_w: np.ndarray, config: SimConfig) -> np.ndarray:
    """Paper Eq. backup, for a heater (or, mirrored, a cooling machine): (B,) -> (B,) [W]."""
    too_cold = t_r_c < config.backup_low_c
    too_warm = t_r_c > config.backup_high_c
    force_on, force_off = (too_cold, too_warm) if config.params.heating else (too_warm, too_cold)
    return np.where(force_on, config.u_max_w, np.where(force_off, 0.0, u_w))


class Simulator:
    """B buildings stepping together; seeded and deterministic.

    ``reset`` sets the state; ``step`` advances one control interval; ``measure`` returns
    the room temperature as a sensor sees it (with noise when ``noise_std_c > 0``).
    """

    def __init__(self, config: SimConfig, *, n_buildings: int = 1, seed: int | None = 0):
        if n_buildings < 1:
            raise InputError(f"n_buildings must be >= 1, got {n_buildings}")
        self.config = config
        self.n_buildings = n_buildings
        self._ad, self._bd = discretise(config.params, config.substep_s)
        self._rng = np.random.default_rng(seed)
        self._x = np.zeros((n_buildings, 2))

    def reset(
        self, t_r_c: float | np.ndarray, t_m_c: float | np.ndarray, *, seed: int | None = None
    ) -> None:
        """Set the state (scalars broadcast to all buildings); reseed the noise if ``seed``."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self._x = np.stack(
            [
                np.broadcast_to(np.asarray(t_r_c, dtype=float), (self.n_buildings,)),
                np.broadcast_to(np.asarray(t_m_c, dtype=float), (self.n_buildings,)),
            ],
            axis=1,
        ).copy()

    @property
    def state(self) -> np.ndarray:
        """(B, 2) true ``(T_r, T_m)`` [C]."""
        return self._x.copy()

    def measure(self) -> np.ndarray:
        """(B,) measured room temperature [C]."""
        t_r = self._x[:, 0].copy()
        if self.config.noise_std_c > 0:
            t_r += self._rng.normal(0.0, self.config.noise_std_c, size=t_r.shape)
        return t_r

    def step(
        self,
        u_w: np.ndarray | float,
        t_a_c: np.ndarray | float,
        g_w_per_m2: np.ndarray | float = 0.0,
        i_g_w: np.ndarray | float = 0.0,
    ) -> StepResult:
        """Advance one control interval with inputs held constant; all inputs (B,) or scalar."""
        shape = (self.n_buildings,)
        u = np.broadcast_to(np.asarray(u_w, dtype=float), shape)
        if not np.all(np.isfinite(u)):
            raise InputError("Simulator.step: demanded power u_w has non-finite values")
        u = np.clip(u, 0.0, self.config.u_max_w)
        exog = np.stack(
            [
                np.broadcast_to(np.asarray(v, dtype=float), shape)
                for v in (t_a_c, g_w_per_m2, i_g_w)
            ],
            axis=1,
        )
        # Exogenous part of the input is constant over the interval: precompute its effect.
        drift = exog @ self._bd[:, 1:].T  # (B, 2)
        b_u = self._bd[:, 0]
        a = self._ad
        n = self.config.n_substeps
        x0, x1 = self._x[:, 0].copy(), self._x[:, 1].copy()
        delivered = np.zeros(shape)
        overridden = np.zeros(shape, dtype=bool)
        t_r_sub = np.empty((self.n_buildings, n))
        for j in range(n):
            p = backup_power(x0, u, self.config)
            overridden |= p != u
            delivered += p
            x0, x1 = (
                a[0, 0] * x0 + a[0, 1] * x1 + b_u[0] * p + drift[:, 0],
                a[1, 0] * x0 + a[1, 1] * x1 + b_u[1] * p + drift[:, 1],
            )
            t_r_sub[:, j] = x0
        self._x = np.stack([x0, x1], axis=1)
        return StepResult(
            t_r_c=x0.copy(),
            t_m_c=x1.copy(),
            u_phys_w=delivered / n,
            overridden=overridden,
            t_r_sub_c=t_r_sub,
        )
