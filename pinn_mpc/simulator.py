"""Batched 2R2C simulator with the paper's backup thermostat (Eq. backup).

Each control interval (``dt_s``, default 30 min) is integrated in substeps (default 1 min)
with the exact zero-order-hold discretisation of :mod:`pinn_mpc.physics`; the backup
thermostat is re-evaluated at the start of every substep, so the power actually delivered
(``u_phys``, the interval mean) can differ from the demand ``u``. B buildings step together as
arrays of shape (B,); they share the parameters of ``SimConfig.params`` or, for a fleet, each
has its own (:func:`draw_fleet`, discretised in one batch by :func:`fleet_matrices`). The
substep loop runs compiled (:mod:`pinn_mpc.substeps`).

``SimConfig.actuator`` (:mod:`pinn_mpc.actuator`) turns the electrical demand into heat (the
ideal heater by default, or a heat pump whose COP follows the interval's outdoor temperature);
``u`` and ``u_phys`` stay electrical. ``SimConfig.plant`` (:mod:`pinn_mpc.plant`) is the
models' 2R2C by default, or a 3R3C with an envelope node the models do not have; its third
state is in :attr:`Simulator.full_state` only.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np
import scipy.linalg

from pinn_mpc.actuator import Actuator, ActuatorSpec
from pinn_mpc.errors import InputError, InternalError, setting
from pinn_mpc.physics import GAIN_SCHEDULE_LENGTH, N_INPUTS, PAPER_HOUSEHOLD, RCParams
from pinn_mpc.plant import Plant, plant_matrices

__all__ = [
    "MAX_ACTUATOR_W", "SimConfig", "Simulator", "StepResult", "backup_power", "unmeasured_gains",
]

#: The largest plausible actuator of one building [W] (a hospital's heating plant is a few MW):
#: above it a power was given in the wrong unit.
MAX_ACTUATOR_W = 1.0e8


@dataclass(frozen=True, kw_only=True)
class SimConfig:
    """Building, actuator and backup-thermostat settings of a simulation.

    ``u_max_w`` is electrical; ``actuator`` (the efficiency, the scenario file's
    ``[simulation.actuator]``) and ``plant`` default to today's ideal heater on the 2R2C
    (bit-identical trajectories). :attr:`actuators` declares the actuator they make, which
    the simulator and the controllers ask for its bounds."""

    params: RCParams = field(default_factory=lambda: PAPER_HOUSEHOLD)
    u_max_w: float = 5000.0
    dt_s: float = 1800.0
    substep_s: float = 60.0
    backup_low_c: float = 17.0
    backup_high_c: float = 20.5
    noise_std_c: float = 0.0
    actuator: Actuator = field(default_factory=Actuator)
    plant: Plant = field(default_factory=Plant)

    def __post_init__(self) -> None:
        if self.actuator.kind == "heat_pump" and not self.params.heating:
            raise InputError(
                "SimConfig: a heat_pump actuator heats, but params.eta < 0 (cooling); give the "
                "cooling machine's COP as -eta with the ideal actuator"
            )
        if self.actuator.kind == "chiller":
            raise InputError(
                "SimConfig: the one-zone building's cooling machine has its COP in -eta; give "
                "the ideal actuator (the chiller efficiency is a multi-zone building's actuator's)"
            )
        if not (math.isfinite(self.u_max_w) and self.u_max_w > 0):
            raise InputError(f"SimConfig.u_max_w must be positive, got {self.u_max_w!r}")
        if self.u_max_w > MAX_ACTUATOR_W:
            raise InputError(
                f"SimConfig.u_max_w = {self.u_max_w:.3g} W is above the plausible "
                f"{MAX_ACTUATOR_W:.0e} W of one building's heating or cooling; give it in W"
            )
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

    @cached_property
    def actuators(self) -> tuple[ActuatorSpec, ...]:
        """The building's actuators (:class:`pinn_mpc.actuator.ActuatorSpec`), today one on its
        one zone: electrical power in ``[0, u_max_w]``, heating where ``params.eta > 0`` and
        cooling where it is negative, with the efficiency ``actuator``."""
        return (ActuatorSpec(upper_w=self.u_max_w, heats=self.params.heating, efficiency=self.actuator),)


class StepResult(NamedTuple):
    """Outcome of one control interval for B buildings (true states, not measurements)."""

    t_r_c: np.ndarray  # (B,) room temperature at the end of the interval [C]
    t_m_c: np.ndarray  # (B,) thermal-mass temperature at the end of the interval [C]
    u_phys_w: np.ndarray  # (B,) mean electrical power delivered over the interval [W]
    overridden: np.ndarray  # (B,) bool, the backup changed the demand in some substep
    t_r_sub_c: np.ndarray  # (B, n_substeps) room temperature at the end of each substep [C]


def backup_power(t_r_c: np.ndarray, u_w: np.ndarray, config: SimConfig) -> np.ndarray:
    """Paper Eq. backup, for a heater (or, mirrored, a cooling machine): (B,) -> (B,) [W].

    The rule as numpy; :mod:`pinn_mpc.substeps` applies the same rule inside its loop.
    """
    (actuator,) = config.actuators
    too_cold = t_r_c < config.backup_low_c
    too_warm = t_r_c > config.backup_high_c
    force_on, force_off = (too_cold, too_warm) if actuator.heats else (too_warm, too_cold)
    return np.where(force_on, actuator.upper_w, np.where(force_off, actuator.lower_w, u_w))


#: RCParams fields that :func:`draw_fleet` scales per building; the others (eta, fractions)
#: stay the base building's, so every building has the same kind of actuator.
FLEET_SCALED = ("r_ra_k_per_w", "r_rm_k_per_w", "c_r_j_per_k", "c_m_j_per_k", "solar_aperture_m2")


def draw_fleet(
    base: RCParams, n_buildings: int, *, spread: float, rng: np.random.Generator
) -> tuple[RCParams, ...]:
    """``n_buildings`` buildings around ``base``: each of :data:`FLEET_SCALED` multiplied by its
    own log-normal factor ``exp(spread * N(0, 1))`` (``spread`` 0.2 is about +-20 %, 0 gives
    copies of ``base``). Every building is validated like any RCParams."""
    if isinstance(n_buildings, bool) or not isinstance(n_buildings, int) or n_buildings < 1:
        raise ValueError(f"draw_fleet: n_buildings must be a whole number >= 1, got {n_buildings!r}")
    if not (math.isfinite(spread) and 0.0 <= spread <= 1.0):
        raise InputError(
            f"{setting('spread')} must lie in [0, 1] (log-normal sigma; 0.2 is about +-20 %), "
            f"got {spread!r}"
        )
    factors = np.exp(spread * rng.standard_normal((n_buildings, len(FLEET_SCALED))))
    return tuple(
        dataclasses.replace(
            base, **{name: getattr(base, name) * float(f) for name, f in zip(FLEET_SCALED, row, strict=True)}
        )
        for row in factors
    )


def unmeasured_gains(params: Sequence[RCParams]) -> np.ndarray | None:
    """(B, :data:`~pinn_mpc.physics.GAIN_SCHEDULE_LENGTH`) each building's unmeasured-gain
    schedule [W] (zeros where it has none), or None where no building has one."""
    if not any(p.unmeasured_gains_w for p in params):
        return None
    return np.array([p.unmeasured_gains_w or (0.0,) * GAIN_SCHEDULE_LENGTH for p in params])


def fleet_matrices(
    params: Sequence[RCParams], dt_s: float, plant: Plant | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Exact ZOH discretisation of many buildings in one batched matrix exponential.

    Returns ``Ad`` (B, n, n) and ``Bd`` (B, n, 4), n = 2 for the default plant (building by
    building the same matrices as :func:`pinn_mpc.physics.discretise`, to rounding).
    """
    plant = Plant() if plant is None else plant
    n = plant.n_states
    if not (math.isfinite(dt_s) and dt_s > 0):
        raise ValueError(f"dt_s must be a positive number of seconds, got {dt_s!r}")
    if len(params) == 0:
        raise InternalError("fleet_matrices: no buildings given")
    m = np.zeros((len(params), n + N_INPUTS, n + N_INPUTS))
    for i, p in enumerate(params):
        a, b = plant_matrices(p, plant)
        m[i, :n, :n] = a * dt_s
        m[i, :n, n:] = b * dt_s
    e = scipy.linalg.expm(m)
    return np.ascontiguousarray(e[:, :n, :n]), np.ascontiguousarray(e[:, :n, n:])


class Simulator:
    """B buildings stepping together; seeded and deterministic.

    ``reset`` sets the state; ``step`` advances one control interval; ``measure`` returns
    the room temperature as a sensor sees it (with noise when ``noise_std_c > 0``).
    ``fleet`` gives each building its own parameters (e.g. from :func:`draw_fleet`); their
    actuators must heat (or cool) as ``config.params`` does, since the backup rule and
    the actuator of ``config`` (its bounds) apply to all. Without it all share ``config.params``.
    """

    def __init__(
        self,
        config: SimConfig,
        *,
        n_buildings: int | None = None,
        seed: int | None = 0,
        fleet: Sequence[RCParams] | None = None,
    ):
        if fleet is not None:
            if n_buildings is not None and n_buildings != len(fleet):
                raise ValueError(
                    f"Simulator: n_buildings={n_buildings} but the fleet has {len(fleet)} buildings; "
                    "give one of them"
                )
            n_buildings = len(fleet)
            wrong = [i for i, p in enumerate(fleet) if p.heating != config.params.heating]
            if wrong:
                kind = "heats" if config.params.heating else "cools"
                raise InputError(
                    f"Simulator: fleet building(s) {wrong[:5]} have an actuator of the other sign; "
                    f"config.params {kind}, and one backup rule applies to all buildings"
                )
        n_buildings = 1 if n_buildings is None else n_buildings
        if n_buildings < 1:
            raise ValueError(f"n_buildings must be >= 1, got {n_buildings}")
        self.config = config
        self.n_buildings = n_buildings
        # (P, n, n) / (P, n, 4): P = 1 when all buildings share config.params.
        self._ad, self._bd = fleet_matrices(
            [config.params] if fleet is None else fleet, config.substep_s, config.plant
        )
        self._rng = np.random.default_rng(seed)
        self._x = np.zeros((n_buildings, config.plant.n_states))

    def reset(
        self,
        t_r_c: float | np.ndarray,
        t_m_c: float | np.ndarray,
        *,
        seed: int | None = None,
        t_e_c: float | np.ndarray | None = None,
    ) -> None:
        """Set the state (scalars broadcast to all buildings); reseed the noise if ``seed``.

        ``t_e_c`` is the 3R3C's envelope temperature, by default the room's (ignored by the
        2R2C)."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        values = [t_r_c, t_m_c, t_r_c if t_e_c is None else t_e_c][: self.config.plant.n_states]
        self._x = np.stack(
            [np.broadcast_to(np.asarray(v, dtype=float), (self.n_buildings,)) for v in values],
            axis=1,
        ).copy()

    @property
    def state(self) -> np.ndarray:
        """(B, 2) true ``(T_r, T_m)`` [C], the states the models have."""
        return self._x[:, :2].copy()

    @property
    def full_state(self) -> np.ndarray:
        """(B, n) every state of the plant [C]: ``(T_r, T_m)`` or ``(T_r, T_m, T_e)``."""
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
        # numba only once something steps
        from pinn_mpc.substeps import integrate_interval, integrate_interval_n

        shape = (self.n_buildings,)
        u = np.broadcast_to(np.asarray(u_w, dtype=float), shape)
        if not np.all(np.isfinite(u)):
            raise InternalError("Simulator.step: demanded power u_w has non-finite values")
        cfg = self.config
        (actuator,) = cfg.actuators
        u = actuator.clip(u)
        exog = np.stack(
            [
                np.broadcast_to(np.asarray(v, dtype=float), shape)
                for v in (t_a_c, g_w_per_m2, i_g_w)
            ],
            axis=1,
        )
        gain = actuator.gain(exog[:, 0])
        delivered = np.empty(shape)
        overridden = np.empty(shape, dtype=bool)
        t_r_sub = np.empty((self.n_buildings, cfg.n_substeps))
        x = np.ascontiguousarray(self._x, dtype=float)
        kernel = integrate_interval if cfg.plant.n_states == 2 else integrate_interval_n
        kernel(
            x,
            np.ascontiguousarray(u),
            exog,
            self._ad,
            self._bd,
            gain,
            float(actuator.min_power_w),
            float(actuator.lower_w),
            float(actuator.upper_w),
            float(cfg.backup_low_c),
            float(cfg.backup_high_c),
            bool(actuator.heats),
            delivered,
            overridden,
            t_r_sub,
        )
        self._x = x
        return StepResult(
            t_r_c=x[:, 0].copy(),
            t_m_c=x[:, 1].copy(),
            u_phys_w=delivered,
            overridden=overridden,
            t_r_sub_c=t_r_sub,
        )
