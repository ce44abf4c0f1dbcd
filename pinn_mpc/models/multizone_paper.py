"""The paper's PhysNet and PhysReg MLP for a building of several zones, coupled through physics.

Each zone ``z`` has the paper's network (:mod:`pinn_mpc.models.physnet`,
:mod:`pinn_mpc.models.physreg`), weights of its own, reading a window of ``depth`` + 1 rows of
the zone's own history: its room temperature, the heat its actuators delivered (each actuator's
electrical power times its efficiency at the outdoor temperature, + heating, - cooling; the
interval's own heat last), the outdoor temperature, the irradiance its windows take (0 without
windows), the internal gains (0 where the data have none), and the interval's clock and
calendar (a workday or not). PhysNet encodes the window but the interval's own inputs into the
zone's hidden mass temperature ``T_m,z`` (2x24 tanh) and its dynamics network (1x128 tanh) maps
``T_m,z``, the room now and the interval's inputs to the room's increment; the PhysReg MLP
maps the whole window through 2x64 tanh to the increment and ``T_m,z``.

The zones are coupled by physics, not by the networks: over an interval each zone's room
also gains ``sum_j K_zj (T_r,j - T_r,z) dt / C_r,z`` [K], the heat its internal walls conduct
(explicit over the interval), with ``K_zj = K_jz = softplus(k_w) >= 0`` one learned conductance
[W/K] per internal wall of the layout (the pairs ``adjacency`` allows; every pair without it)
and ``C_r,z`` the zone's learned air capacity [J/K]. Each zone's 2R2C (``C_r``, ``C_m``,
``1/R_ra``, ``1/R_rm``, positive, in log space) and the walls start at the multi-zone RC
identified from the same data (:func:`pinn_mpc.identify_multizone.identify_multizone`), whose
apertures and gain shares are kept as they were identified.

Training (:func:`fit_multizone_paper`) minimises the paper's loss, ``L_reg + lambda L_phys``,
on all zones at once: ``L_reg`` the mean squared error of the rooms [scaled] over rollouts of
``horizon`` intervals from every row (the recursion the planner runs, on the data's delivered
heat and weather), ``L_phys`` the exact-ZOH residuals of the learned multi-zone 2R2C on the
networks' ``T_m`` of each rollout's first two rows, the windows measured
(:func:`zone_residuals`: every room from the measured rooms and predicted masses, every mass
one row on), divided by the temperature scale squared, as
:func:`pinn_mpc.models.physics_block.residual_exact` does for one zone. The one-zone loop
(:func:`pinn_mpc.training.train_model`) draws mini-batches of one zone's feature windows for an
ensemble of one architecture's :class:`~pinn_mpc.models.learned.EnsembleModule`; these networks
read Z zones' windows whose power is a plan of A actuators, so they have their own short loop
(full rollouts of windows, Adam, the converged recipe's cosine decay).

As a planner model (:class:`~pinn_mpc.models.rollout.BatchDynamics`, the interface of
:class:`~pinn_mpc.models.multizone_rc.MultiZoneRCModel`) it takes plans (N, H, A) of each
actuator's electrical power, clips them to the actuators' bounds and applies each zone's backup
thermostat on the room at each interval's start, as the RC and the ARX of several zones do; it
runs from the measured history (no state filter). It carries the identified multi-zone RC (the
planners' fallback QP's building); ``export-rc`` writes the learned one
(:meth:`MultiZonePaperModel.learned_rc`).

On disk (:data:`MULTIZONE_PAPER_DIRECTORY`) the model is one JSON file of numbers: the layout,
the identified RC, the networks' and the physics' parameters, their scaling and a SHA-256 of
all of it; loading it checks every shape and number and the checksum, and runs nothing.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch
from torch import nn

from pinn_mpc.actuator import ActuatorSpec, actuator_columns
from pinn_mpc.errors import InputError
from pinn_mpc.identify_multizone import MultiZoneIdentifyResult, identify_multizone
from pinn_mpc.io import DirectoryLayout
from pinn_mpc.models.lagged_zones import LaggedZoneModel
from pinn_mpc.models.layers import mlp_layers, run_layers
from pinn_mpc.models.physnet import DYNAMICS, ENCODER
from pinn_mpc.models.registry import ARCHITECTURES
from pinn_mpc.models.rollout import Rollout
from pinn_mpc.multizone import EXOGENOUS_NAMES, MultiZoneParams
from pinn_mpc.zones import ZoneSpec

__all__ = [
    "ARCHS",
    "FORMAT",
    "MULTIZONE_PAPER_DIRECTORY",
    "MULTIZONE_PAPER_FILE",
    "MultiZonePaperModel",
    "PaperZoneTraining",
    "ZoneNets",
    "ZonePhysics",
    "fit_multizone_paper",
    "load_multizone_paper",
    "save_multizone_paper",
    "zone_residuals",
]

#: The file of the model directory.
MULTIZONE_PAPER_FILE = "multizone_paper.json"
#: What ``train --arch physnet|physreg`` writes for a building of several zones.
MULTIZONE_PAPER_DIRECTORY = DirectoryLayout(
    kind="multi-zone paper network directory", files=(MULTIZONE_PAPER_FILE,), markers=(MULTIZONE_PAPER_FILE,)
)
#: The file's format tag.
FORMAT = "pinn-mpc multi-zone paper network 1"


def _arch_of(module: str) -> str:
    """The registry's name of the architecture implemented in ``module``."""
    return next(name for name, spec in ARCHITECTURES.items() if spec.implementation.startswith(f"{module}:"))


#: The paper's PhysNet and PhysReg MLP, by the registry's names.
PHYSNET, PHYSREG = _arch_of("pinn_mpc.models.physnet"), _arch_of("pinn_mpc.models.physreg")
#: The architectures: the paper's two physics-informed networks.
ARCHS = (PHYSNET, PHYSREG)
#: The PhysReg MLP's trunk (:class:`pinn_mpc.models.mlp.MLP`'s).
TRUNK = (64, 64)
#: History rows before now each zone's window holds (the registry's depth of both networks).
DEFAULT_DEPTH = 8
#: Exogenous series of each zone's window: T_a, the zone's irradiance, I_g.
N_EXOG = 3
#: The clock (sine, cosine of the day's phase) and the calendar (1 on a weekend or holiday).
N_CLOCK = 3
#: The largest parameter magnitude a saved model may hold: training gives well under 100.
MAX_ABS_PARAM = 1e4
#: A wall the identification left at 0 starts at this conductance [W/K].
_WALL_START_W_PER_K = 1.0


@dataclass(frozen=True, kw_only=True)
class PaperZoneTraining:
    """How :func:`fit_multizone_paper` trains: ``epochs`` over rollouts of ``horizon``
    intervals from every row, ``batch`` rollouts a step, Adam at ``learning_rate`` decayed on a
    cosine to ``lr_final`` (the physics' parameters at ``physics_lr_factor`` times it), the
    physics residual weighted ``lam`` (the paper's lambda), ``depth`` history rows."""

    epochs: int = 150
    horizon: int = 24
    batch: int = 32
    learning_rate: float = 1e-2
    lr_final: float = 1e-4
    physics_lr_factor: float = 1.0
    lam: float = 1.0
    depth: int = DEFAULT_DEPTH

    def __post_init__(self) -> None:
        for name in ("epochs", "horizon", "batch", "depth"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"PaperZoneTraining.{name} must be an integer >= 1, got {value!r}")
        for name in ("learning_rate", "lr_final", "physics_lr_factor"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"PaperZoneTraining.{name} must be a positive number, got {value!r}")
        if not (math.isfinite(self.lam) and self.lam >= 0):
            raise ValueError(f"PaperZoneTraining.lam must be a finite number >= 0, got {self.lam!r}")


def _softplus_inverse(value: float) -> float:
    return value + math.log(-math.expm1(-value))


class ZonePhysics(nn.Module):
    """Each zone's 2R2C and the walls between them, learnable and positive.

    ``log_c_r``, ``log_c_m`` (Z,) log capacities [J/K]; ``log_h_ra``, ``log_h_rm`` (Z,) log
    conductances 1/R [W/K] (air to outdoors, air to mass); ``raw_k`` (W,) the walls'
    conductances before softplus [W/K], one per pair of :attr:`pairs` (W, 2). Buffers (kept as
    identified): ``solar_air``, ``solar_mass`` (Z,) [m2] the aperture's share into air and mass,
    ``gains_air``, ``gains_mass`` (Z,) the internal gains' share into air and mass."""

    pairs: torch.Tensor
    solar_air: torch.Tensor
    solar_mass: torch.Tensor
    gains_air: torch.Tensor
    gains_mass: torch.Tensor

    def __init__(self, params: MultiZoneParams, pairs: Sequence[tuple[int, int]]) -> None:
        super().__init__()
        rcs = [z.rc for z in params.zones]
        z_n = params.n_zones
        self.n_zones = z_n

        def logs(values: Sequence[float]) -> nn.Parameter:
            return nn.Parameter(torch.tensor([math.log(v) for v in values], dtype=torch.float64))

        self.log_c_r = logs([p.c_r_j_per_k for p in rcs])
        self.log_c_m = logs([p.c_m_j_per_k for p in rcs])
        self.log_h_ra = logs([1.0 / p.r_ra_k_per_w for p in rcs])
        self.log_h_rm = logs([1.0 / p.r_rm_k_per_w for p in rcs])
        walls = params.walls
        start = [max(float(walls[i, j]), _WALL_START_W_PER_K) for i, j in pairs]
        self.raw_k = nn.Parameter(torch.tensor([_softplus_inverse(v) for v in start], dtype=torch.float64))
        self.register_buffer("pairs", torch.tensor(list(pairs), dtype=torch.long).reshape(-1, 2))

        def fixed(values: Sequence[float]) -> torch.Tensor:
            return torch.tensor(list(values), dtype=torch.float64)

        self.register_buffer("solar_air", fixed([p.solar_to_air_fraction * p.solar_aperture_m2 for p in rcs]))
        self.register_buffer("solar_mass", fixed([(1 - p.solar_to_air_fraction) * p.solar_aperture_m2 for p in rcs]))
        self.register_buffer("gains_air", fixed([z.gain_share * z.rc.gain_to_air_fraction for z in params.zones]))
        self.register_buffer("gains_mass", fixed([z.gain_share * (1 - z.rc.gain_to_air_fraction) for z in params.zones]))

    def conductances(self) -> torch.Tensor:
        """(Z, Z) the walls' conductances [W/K]: symmetric, >= 0, zero diagonal and zero where
        the layout has no wall."""
        k = torch.zeros(self.n_zones, self.n_zones, dtype=torch.float64)
        value = nn.functional.softplus(self.raw_k)
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        return k.index_put((i, j), value).index_put((j, i), value)

    def coupling_k(self, rooms_c: torch.Tensor, dt_s: float) -> torch.Tensor:
        """(..., Z) each zone's room change over ``dt_s`` [s] from the heat its walls conduct,
        ``sum_j K_zj (T_r,j - T_r,z) dt / C_r,z`` [K], at the rooms ``rooms_c`` (..., Z) [C]
        (or any temperatures in kelvin: only their differences count)."""
        k = self.conductances().to(rooms_c.dtype)
        flow_w = rooms_c @ k.T - rooms_c * k.sum(dim=1)
        return flow_w * dt_s / self.log_c_r.exp().to(rooms_c.dtype)

    def heat_inputs(self, heat_w: torch.Tensor, t_a_c: torch.Tensor, sun: torch.Tensor, gains_w: torch.Tensor) -> torch.Tensor:
        """(..., 2Z + 1) the inputs of :meth:`discretised`: the heat into each zone's air [W]
        (its actuators' ``heat_w`` (..., Z), the sun through its windows ``sun`` (..., Z)
        [W/m2], its share of the internal gains ``gains_w`` (...,) [W]), into each mass [W],
        and the outdoor temperature ``t_a_c`` (...,) [C]."""
        g = gains_w[..., None]
        air = heat_w + sun * self.solar_air + g * self.gains_air
        mass = sun * self.solar_mass + g * self.gains_mass
        return torch.cat([air, mass, t_a_c[..., None]], dim=-1)

    def continuous(self) -> tuple[torch.Tensor, torch.Tensor]:
        """``dx/dt = a x + b v``: ``a`` (2Z, 2Z) for the rooms then the masses [1/s], ``b``
        (2Z, 2Z + 1) for :meth:`heat_inputs`'s ``v``."""
        z_n = self.n_zones
        c_r, c_m = self.log_c_r.exp(), self.log_c_m.exp()
        h_ra, h_rm = self.log_h_ra.exp(), self.log_h_rm.exp()
        k = self.conductances()
        eye = torch.eye(z_n, dtype=torch.float64)
        top = torch.cat([(k - eye * (h_ra + h_rm + k.sum(dim=1))) / c_r[:, None], eye * (h_rm / c_r)[:, None]], dim=1)
        bottom = torch.cat([eye * (h_rm / c_m)[:, None], -eye * (h_rm / c_m)[:, None]], dim=1)
        a = torch.cat([top, bottom], dim=0)
        zeros = torch.zeros(z_n, z_n, dtype=torch.float64)
        b = torch.cat([
            torch.cat([eye / c_r[:, None], zeros, (h_ra / c_r)[:, None]], dim=1),
            torch.cat([zeros, eye / c_m[:, None], torch.zeros(z_n, 1, dtype=torch.float64)], dim=1),
        ], dim=0)
        return a, b

    def discretised(self, dt_s: float) -> tuple[torch.Tensor, torch.Tensor]:
        """The exact zero-order hold over ``dt_s`` [s] of :meth:`continuous`: ``ad`` (2Z, 2Z),
        ``bd`` (2Z, 2Z + 1), through the exponential of the augmented matrix."""
        a, b = self.continuous()
        n, m = b.shape
        aug = torch.zeros(n + m, n + m, dtype=torch.float64)
        aug = aug.index_put((torch.arange(n)[:, None], torch.arange(n + m)[None]), torch.cat([a, b], dim=1) * dt_s)
        e = torch.linalg.matrix_exp(aug)
        return e[:n, :n], e[:n, n:]

    def learned(self, base: MultiZoneParams) -> MultiZoneParams:
        """``base`` with each zone's R and C and the walls' conductances this block's."""
        with torch.no_grad():
            c_r, c_m = self.log_c_r.exp().tolist(), self.log_c_m.exp().tolist()
            r_ra, r_rm = (1.0 / self.log_h_ra.exp()).tolist(), (1.0 / self.log_h_rm.exp()).tolist()
            walls = self.conductances().numpy()
        zones = tuple(
            dataclasses.replace(z, rc=dataclasses.replace(
                z.rc, c_r_j_per_k=c_r[i], c_m_j_per_k=c_m[i], r_ra_k_per_w=r_ra[i], r_rm_k_per_w=r_rm[i],
            ))
            for i, z in enumerate(base.zones)
        )
        return MultiZoneParams(zones=zones, wall_conductance_w_per_k=walls.tolist())


def zone_residuals(
    physics: ZonePhysics, dt_s: float, *, rooms_c: torch.Tensor, masses_c: torch.Tensor, inputs: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The exact-ZOH residuals of the learned building over consecutive rows [K]: ``rooms_c``
    (T, ..., Z) measured rooms, ``masses_c`` (T, ..., Z) the networks' masses [C], ``inputs``
    (T, ..., 2Z + 1) (:meth:`ZonePhysics.heat_inputs`) of each row's interval, the rows along
    the first axis (any batch axes after it). Returns (T-1, ..., Z) each measured room minus the
    room the building gives from the row before (its measured room, predicted mass), and
    (T-1, ..., Z) each predicted mass minus the building's."""
    ad, bd = physics.discretised(dt_s)
    x = torch.cat([rooms_c, masses_c], dim=-1).to(torch.float64)
    nxt = x[:-1] @ ad.T + inputs[:-1].to(torch.float64) @ bd.T
    z_n = rooms_c.shape[-1]
    return rooms_c[1:] - nxt[..., :z_n], masses_c[1:] - nxt[..., z_n:]


class ZoneNets(nn.Module):
    """Every zone's network, one ensemble member per zone (:mod:`pinn_mpc.models.layers`):
    ``forward(x (Z, B, F))`` returns the scaled room increment and ``T_m`` (each (Z, B)).

    The window's features (F), scaled: the room at rows ``i-depth .. i``, the heat then each
    of the :data:`N_EXOG` exogenous series at the same rows (row ``i``'s the interval's own),
    then the :data:`N_CLOCK` clock and calendar of row ``i``."""

    past_index: torch.Tensor
    now_index: torch.Tensor

    def __init__(self, arch: str, n_zones: int, depth: int, seed: int) -> None:
        super().__init__()
        if arch not in ARCHS:
            raise ValueError(f"ZoneNets.arch must be one of {', '.join(ARCHS)}, got {arch!r}")
        self.arch, self.depth = arch, depth
        k1 = depth + 1
        gens = [torch.Generator().manual_seed(seed + z) for z in range(n_zones)]
        n_features = (2 + N_EXOG) * k1 + N_CLOCK
        now = [k1 - 1 + s * k1 for s in range(2 + N_EXOG)]  # each series' row i
        clock = list(range(n_features - N_CLOCK, n_features))
        past = [f for f in range(n_features) if f not in now and f not in clock] + [now[0]]
        self.register_buffer("past_index", torch.tensor(sorted(past)))
        self.register_buffer("now_index", torch.tensor(now + clock))
        self.n_features = n_features
        if arch == PHYSNET:
            self.encoder = mlp_layers((len(past), *ENCODER, 1), n_zones, gens)
            self.dynamics = mlp_layers((1 + len(now) + N_CLOCK, *DYNAMICS, 1), n_zones, gens)
        else:
            self.trunk = mlp_layers((n_features, *TRUNK, 2), n_zones, gens)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if self.arch == PHYSNET:
            z = run_layers(self.encoder, x.index_select(-1, self.past_index))
            out = run_layers(self.dynamics, torch.cat([z, x.index_select(-1, self.now_index)], dim=-1))
            return out[..., 0], z[..., 0]
        out = run_layers(self.trunk, x)
        return out[..., 0], out[..., 1]


@dataclass(frozen=True, kw_only=True)
class ZoneScaling:
    """The networks' scaling: temperatures ``(T - t_mean_c) / t_std_k``, the room increment
    ``delta_std_k`` [K] per unit of output, each zone's heat over ``heat_scale_w`` (Z,) [W],
    irradiance over ``solar_scale`` [W/m2], internal gains over ``gains_scale_w`` [W]."""

    t_mean_c: float
    t_std_k: float
    delta_std_k: float
    heat_scale_w: tuple[float, ...]
    solar_scale: float
    gains_scale_w: float

    def __post_init__(self) -> None:
        values = (self.t_mean_c, self.t_std_k, self.delta_std_k, *self.heat_scale_w, self.solar_scale, self.gains_scale_w)
        if not all(isinstance(v, int | float) and math.isfinite(v) for v in values):
            raise ValueError("ZoneScaling: every value must be a finite number")
        if min(values[1:]) <= 0:
            raise ValueError("ZoneScaling: the scales (t_std_k, delta_std_k, heat_scale_w, solar_scale, gains_scale_w) must be > 0")

    @classmethod
    def of(cls, rooms: np.ndarray, heat_w: np.ndarray, sun: np.ndarray, gains_w: np.ndarray) -> ZoneScaling:
        """From the training data's rooms (T, Z) [C], heat (T, Z) [W], sun (T, Z), gains (T,)."""
        def spread(v: np.ndarray, least: float) -> float:
            return max(float(np.sqrt(np.mean(np.square(v)))), least)

        return cls(
            t_mean_c=float(np.mean(rooms)), t_std_k=max(float(np.std(rooms)), 0.1),
            delta_std_k=max(float(np.std(np.diff(rooms, axis=0))), 1e-3),
            heat_scale_w=tuple(spread(heat_w[:, z], 1.0) for z in range(heat_w.shape[1])),
            solar_scale=spread(sun, 1.0), gains_scale_w=spread(gains_w, 1.0),
        )


class _Series:
    """A building's series for the networks, scaled, of ``dtype`` (the networks'): ``rooms``
    (T, Z), ``heat`` (T, Z), ``exog`` (T, Z, :data:`N_EXOG`) and ``clock`` (T, :data:`N_CLOCK`)."""

    def __init__(
        self, s: ZoneScaling, *, rooms_c: np.ndarray, heat_w: np.ndarray, t_a_c: np.ndarray, sun: np.ndarray,
        gains_w: np.ndarray, tod_h: np.ndarray, day: np.ndarray, dtype: torch.dtype = torch.float32,
    ) -> None:
        f64 = dtype
        self.rooms = torch.as_tensor((rooms_c - s.t_mean_c) / s.t_std_k, dtype=f64)
        self.heat = torch.as_tensor(heat_w / np.asarray(s.heat_scale_w), dtype=f64)
        t_a = np.broadcast_to(((t_a_c - s.t_mean_c) / s.t_std_k)[:, None], sun.shape)
        gains = np.broadcast_to((gains_w / s.gains_scale_w)[:, None], sun.shape)
        self.exog = torch.as_tensor(np.stack([t_a, sun / s.solar_scale, gains], axis=-1), dtype=f64)
        phase = 2.0 * math.pi * tod_h / 24.0
        rest = (np.nan_to_num(day, nan=0.0) >= 5).astype(float)
        self.clock = torch.as_tensor(np.stack([np.sin(phase), np.cos(phase), rest], axis=1), dtype=f64)


class _Stepper:
    """One interval of every zone's network plus the walls: from the windows (B, depth+1, Z)
    of scaled rooms and heat (the heat's last row the interval's), exogenous windows
    (B, depth+1, Z, N_EXOG) and the clock (B, N_CLOCK), the scaled rooms at the interval's end
    and the masses now (each (B, Z))."""

    def __init__(self, nets: ZoneNets, physics: ZonePhysics, scaling: ZoneScaling, dt_s: float) -> None:
        self.nets, self.physics, self.dt_s = nets, physics, dt_s
        self.t_std, self.ratio = scaling.t_std_k, scaling.delta_std_k / scaling.t_std_k

    def __call__(
        self, rooms: torch.Tensor, heat: torch.Tensor, exog: torch.Tensor, clock: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        b, k1, z_n = rooms.shape
        x = torch.cat([
            rooms.permute(2, 0, 1), heat.permute(2, 0, 1),
            exog.permute(2, 0, 3, 1).reshape(z_n, b, N_EXOG * k1), clock.expand(z_n, b, N_CLOCK),
        ], dim=-1)
        increment, t_m = self.nets(x)
        now = rooms[:, -1]
        walls = self.physics.coupling_k(now.double() * self.t_std, self.dt_s).to(now.dtype) / self.t_std  # differences
        return now + increment.T * self.ratio + walls, t_m.T


def _rollout_data(step: _Stepper, series: _Series, starts: torch.Tensor, horizon: int, depth: int) -> torch.Tensor:
    """(B, horizon, Z) the scaled rooms rolled from each of ``starts`` (B,) on the series' heat
    and weather, the windows before each start measured."""
    offsets = torch.arange(-depth, 1)
    rooms = series.rooms[starts[:, None] + offsets]  # (B, k+1, Z)
    out = []
    for j in range(horizon):
        rows = starts[:, None] + offsets + j
        nxt, _ = step(rooms, series.heat[rows], series.exog[rows], series.clock[starts + j])
        rooms = torch.cat([rooms[:, 1:], nxt[:, None]], dim=1)
        out.append(nxt)
    return torch.stack(out, dim=1)


class MultiZonePaperModel(LaggedZoneModel):
    """The paper's networks of every zone and the walls between them (module docstring), as a
    planner model (:class:`~pinn_mpc.models.lagged_zones.LaggedZoneModel`: ``identified``,
    ``actuators``, ``dt_s``, ``solar_inputs``, ``uses_gains``, ``training`` and the backup
    limits as it takes them) and a fitted model (:class:`~pinn_mpc.models.rollout.FittedModel`,
    family ``nets.arch``): ``nets`` and ``physics`` the trained modules, ``scaling`` their
    inputs' scaling. ``identified`` is also the physics' start."""

    def __init__(
        self,
        *,
        nets: ZoneNets,
        physics: ZonePhysics,
        scaling: ZoneScaling,
        identified: MultiZoneIdentifyResult,
        actuators: Sequence[ActuatorSpec],
        dt_s: float,
        **layout: Any,
    ) -> None:
        super().__init__(identified, actuators, dt_s, **layout)
        z_n = identified.params.n_zones
        if physics.n_zones != z_n or len(scaling.heat_scale_w) != z_n:
            raise ValueError(
                f"MultiZonePaperModel: physics of {physics.n_zones} zone(s) and scaling of {len(scaling.heat_scale_w)} "
                f"for a building of {z_n}"
            )
        self.nets, self.physics, self.scaling = nets.eval(), physics.eval(), scaling
        self._onto = torch.zeros(len(self.actuators), z_n, dtype=torch.float64)  # actuator -> its zone, signed
        for i, a in enumerate(self.actuators):
            self._onto[i, a.zone] = a.sign

    @property
    def family(self) -> str:
        return self.nets.arch

    @property
    def depth(self) -> int:
        return self.nets.depth

    def learned_rc(self) -> MultiZoneIdentifyResult:
        """The learned building: :attr:`identified` with each zone's R and C and the walls'
        conductances the trained physics' (its fit statistics the identification's)."""
        return replace(self.identified, params=self.physics.learned(self.identified.params))

    def for_planning(
        self,
        *,
        backup_low_c: float | tuple[float, ...],
        backup_high_c: float | tuple[float, ...],
        process_std_c: tuple[float, float] | None = None,
        measurement_std_c: float | None = None,
    ) -> MultiZonePaperModel:
        """This model with the planner's backup limits [C]; the filter's noises
        (``process_std_c``, ``measurement_std_c``) do not apply: it runs from the history."""
        return MultiZonePaperModel(
            nets=self.nets, physics=self.physics, scaling=self.scaling, identified=self.identified,
            actuators=self.actuators, dt_s=self.dt_s, solar_inputs=self.solar_inputs, uses_gains=self.uses_gains,
            training=self.training, backup_low_c=backup_low_c, backup_high_c=backup_high_c,
        )

    # -- the recursion -----------------------------------------------------------------------
    def _stepper(self) -> _Stepper:
        return _Stepper(self.nets, self.physics, self.scaling, self.dt_s)

    def _gains(self, t_a_c: np.ndarray) -> np.ndarray:
        """(..., A) each actuator's heat per electrical watt at the outdoor temperatures."""
        return np.stack([a.gain(t_a_c) for a in self.actuators], axis=-1)

    def _series(self, series: Mapping[str, np.ndarray], heat_w: np.ndarray) -> _Series:
        """The scaled series of rows whose named ``series`` (:attr:`exog_names`) and zone heat
        ``heat_w`` (T, Z) [W] are given, the rooms a placeholder."""
        t_a = np.asarray(series["T_a"], dtype=float)
        sun = np.zeros((len(t_a), len(self.zones)))
        for z, name in enumerate(self.solar_inputs):
            if name is not None:
                sun[:, z] = np.asarray(series[name], dtype=float)
        gains = np.asarray(series["I_g"], dtype=float) if self.uses_gains else np.zeros(len(t_a))
        return _Series(
            self.scaling, rooms_c=np.zeros_like(sun), heat_w=heat_w, t_a_c=t_a, sun=sun, gains_w=gains,
            tod_h=np.asarray(series["time_of_day_h"], dtype=float), day=np.asarray(series["day_of_week"], dtype=float),
            dtype=next(self.nets.parameters()).dtype,
        )

    @property
    def first_path_start(self) -> int:
        """The first row of a frame :meth:`predict_paths` predicts from: a window of
        ``depth`` rows before it."""
        return self.depth

    def predict_paths(self, frame: pd.DataFrame, starts: np.ndarray, horizon: int) -> np.ndarray:
        """(len(starts), horizon, Z) each zone's room [C] at the end of the ``horizon``
        intervals after each start row of ``frame`` (data of its building, as
        :func:`fit_multizone_paper` takes them): rolled from the measured rooms up to each
        start, on the data's delivered powers and weather."""
        starts = np.asarray(starts, dtype=int)
        lo = self.first_path_start
        if starts.size and (starts.min() < lo or starts.max() + horizon > len(frame) - 1):
            raise ValueError(f"MultiZonePaperModel.predict_paths: starts must lie in {lo} .. {len(frame) - 1 - horizon}")
        rooms, heat_w, series = _frame_arrays(frame, self.zones, self.actuators, self.exog_names)
        data = self._series(series, heat_w)
        data.rooms = torch.as_tensor((rooms - self.scaling.t_mean_c) / self.scaling.t_std_k, dtype=data.heat.dtype)
        with torch.no_grad():
            paths = _rollout_data(self._stepper(), data, torch.as_tensor(starts), horizon, self.depth)
        return paths.double().numpy() * self.scaling.t_std_k + self.scaling.t_mean_c

    def rollout(
        self, history: dict[str, np.ndarray], u_w: torch.Tensor, exog: dict[str, np.ndarray]
    ) -> Rollout:
        """u_w (N, H, A) [W] each actuator's demanded electrical power -> each zone's T_r at the
        end of each interval and its T_m at each interval's start, (1, N, H, Z) [C], and the
        building's total delivered electrical power (1, N, H) [W], float64. ``history``: each
        zone's ``T_r[<zone>]`` up to now, each actuator's delivered ``u_phys[<name>]`` of the
        past intervals, the series of :attr:`exog_names` but the clock up to now (at least
        ``depth`` + 1 rows); ``exog`` (>= H,) per :attr:`exog_names` from now."""
        a_n, z_n, k = len(self.actuators), len(self.zones), self.depth
        plan = self.plan_bounds(u_w)
        n, h, _ = u_w.shape
        room_names, power_names, weather = self.check_history(history)
        short = [x for x in (*room_names, *weather) if len(history[x]) < k + 1]
        short += [x for x in power_names if len(history[x]) < k]
        if short:
            raise InputError(f"{self.family} of several zones: needs {k + 1} rows of history, {', '.join(short)} has fewer")
        series = {x: np.concatenate([np.asarray(history[x], dtype=float)[-k - 1 : -1], np.asarray(exog[x], dtype=float)[:h]])
                  for x in weather}
        series |= {x: np.concatenate([np.zeros(k), np.asarray(exog[x], dtype=float)[:h]]) for x in ("time_of_day_h", "day_of_week")}
        powers_past = np.stack([np.asarray(history[x], dtype=float)[-k:] for x in power_names], axis=1).reshape(k, a_n)
        gain = self._gains(series["T_a"])  # (k+H, A)
        heat_past = (powers_past * gain[:k]) @ self._onto.numpy()  # (k, Z)
        data = self._series(series, np.concatenate([heat_past, np.zeros((h, z_n))]))
        s = self.scaling
        scale = torch.as_tensor(s.heat_scale_w)
        rooms_now = np.stack([np.asarray(history[x], dtype=float)[-k - 1 :] for x in room_names], axis=1)
        dtype = data.heat.dtype  # the networks'
        rooms = torch.as_tensor((rooms_now - s.t_mean_c) / s.t_std_k, dtype=dtype).expand(n, k + 1, z_n)
        heat = data.heat[:k].expand(n, k, z_n)
        gain_t = torch.as_tensor(gain[k:])
        step = self._stepper()
        out, masses, powers = [], [], []
        with torch.no_grad():
            for j in range(h):
                p = self.delivered_w(rooms[:, -1] * s.t_std_k + s.t_mean_c, plan, j)
                heat = torch.cat([heat, ((p * gain_t[j]) @ self._onto / scale).to(dtype)[:, None]], dim=1)
                rows = torch.arange(j, j + k + 1)
                nxt, t_m = step(rooms, heat, data.exog[rows].expand(n, k + 1, z_n, N_EXOG), data.clock[k + j].expand(n, N_CLOCK))
                rooms = torch.cat([rooms[:, 1:], nxt[:, None]], dim=1)
                heat = heat[:, 1:]
                out.append(nxt)
                masses.append(t_m)
                powers.append(p.sum(dim=1))
        t_r = torch.stack(out, dim=1).double() * s.t_std_k + s.t_mean_c
        t_m_c = torch.stack(masses, dim=1).double() * s.t_std_k + s.t_mean_c
        return Rollout(t_r[None], torch.stack(powers, dim=1)[None], t_m_c[None])

    # -- on disk ---------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """The model file's dict (module docstring), its ``sha256`` over the rest."""
        state = {name: value.tolist() for name, value in (*self.nets.state_dict().items(),)}
        physics = {name: value.tolist() for name, value in self.physics.state_dict().items()}
        learned = self.learned_rc()
        body = {
            "format": FORMAT,
            "family": self.family,
            "dt_s": self.dt_s,
            "depth": self.depth,
            "zones": [z.name for z in self.zones],
            "solar_inputs": list(self.solar_inputs),
            "uses_gains": self.uses_gains,
            "actuators": [asdict(a) for a in self.actuators],
            "scaling": asdict(self.scaling),
            "networks": state,
            "physics": physics,
            "learned_rc": learned.to_json(),
            "rc": self.identified.to_json(),
            "training_data": self.training,
        }
        return body | {"sha256": _digest(body)}


def _digest(body: Mapping[str, Any]) -> str:
    return hashlib.sha256(json.dumps(body, sort_keys=True, allow_nan=False).encode()).hexdigest()


def _frame_arrays(
    frame: pd.DataFrame, zones: Sequence[ZoneSpec], actuators: Sequence[ActuatorSpec], names: Sequence[str]
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The data's rooms (T, Z) [C], each zone's delivered heat (T, Z) [W] and the series
    ``names`` (the clock and calendar from ``time``); InputError naming what it lacks."""
    from pinn_mpc.models.multizone_arx import _frame_arrays as arrays

    rooms, powers, series = arrays(frame, zones, actuators, names)
    gain = np.stack([a.gain(series["T_a"]) * a.sign for a in actuators], axis=-1)
    heat = np.zeros((len(frame), len(zones)))
    for i, a in enumerate(actuators):
        heat[:, a.zone] += powers[:, i] * gain[:, i]
    return rooms, heat, series


def _wall_pairs(n_zones: int, adjacency: Sequence[Sequence[bool]] | np.ndarray | None) -> list[tuple[int, int]]:
    """The pairs of zones (i < j) that may share a wall: ``adjacency``'s, every pair without it."""
    if adjacency is None:
        return [(i, j) for i in range(n_zones) for j in range(i + 1, n_zones)]
    adj = np.asarray(adjacency, dtype=bool)
    if adj.shape != (n_zones, n_zones):
        raise ValueError(f"fit_multizone_paper: adjacency must be ({n_zones}, {n_zones}), got {adj.shape}")
    return [(i, j) for i in range(n_zones) for j in range(i + 1, n_zones) if adj[i, j] or adj[j, i]]


def fit_multizone_paper(
    frame: pd.DataFrame,
    *,
    arch: str,
    zones: Sequence[ZoneSpec],
    actuators: Sequence[ActuatorSpec],
    solar_inputs: Sequence[str | None],
    dt_s: float,
    seed: int = 0,
    settings: PaperZoneTraining | None = None,
    adjacency: Sequence[Sequence[bool]] | np.ndarray | None = None,
    identified: MultiZoneIdentifyResult | None = None,
) -> MultiZonePaperModel:
    """Train ``arch`` (``physnet`` or ``physreg``) of every zone on ``frame`` (module
    docstring): the building of ``zones`` and ``actuators``, each zone's windows taking its
    ``solar_inputs`` (None: no windows), at the data's step ``dt_s`` [s]; the networks drawn
    from ``seed``, trained as ``settings`` says (:class:`PaperZoneTraining`'s defaults if
    None); the walls those ``adjacency`` allows (None: every pair). ``identified``: the
    multi-zone RC the physics starts at (identified from ``frame`` if None). InputError where
    the data cannot be fitted."""
    from pinn_mpc.training import _threads, data_summary

    if arch not in ARCHS:
        raise ValueError(f"fit_multizone_paper: arch must be one of {', '.join(ARCHS)}, got {arch!r}")
    settings = PaperZoneTraining() if settings is None else settings
    if "I_g" not in frame.columns:
        frame = frame.assign(I_g=0.0)
    if identified is None:
        identified = identify_multizone(
            frame, zones=zones, actuators=actuators, power_columns=actuator_columns("u_phys", actuators),
            solar_inputs=solar_inputs, dt_s=dt_s, adjacency=adjacency,
        )
    uses_gains = bool(np.any(frame["I_g"].to_numpy(dtype=float) != 0))
    k, h = settings.depth, settings.horizon
    starts = np.arange(k, len(frame) - 1 - h + 1)
    if len(starts) < 2:
        raise InputError(
            f"{arch} of several zones: {len(frame)} rows are too few for windows of {k + 1} rows and rollouts of "
            f"{h} intervals; give more days of data"
        )
    solar = tuple(n for n in EXOGENOUS_NAMES if n in solar_inputs)
    names = ("T_a", *solar, "I_g", "time_of_day_h", "day_of_week")
    rooms_c, heat_w, series = _frame_arrays(frame, zones, actuators, names)
    sun = np.zeros_like(rooms_c)
    for z, name in enumerate(solar_inputs):
        if name is not None:
            sun[:, z] = series[name]
    gains_w = series["I_g"] if uses_gains else np.zeros(len(frame))
    if not (np.all(np.isfinite(rooms_c)) and np.all(np.isfinite(heat_w)) and np.all(np.isfinite(sun))
            and np.all(np.isfinite(series["T_a"])) and np.all(np.isfinite(gains_w))):
        raise InputError(f"{arch} of several zones: the data have missing values; fill or drop them")
    scaling = ZoneScaling.of(rooms_c, heat_w, sun, gains_w)
    data = _Series(
        scaling, rooms_c=rooms_c, heat_w=heat_w, t_a_c=series["T_a"], sun=sun, gains_w=gains_w,
        tod_h=series["time_of_day_h"], day=series["day_of_week"],
    )
    z_n = len(zones)
    physics = ZonePhysics(identified.params, _wall_pairs(z_n, adjacency))
    nets = ZoneNets(arch, z_n, k, seed)
    step = _Stepper(nets, physics, scaling, dt_s)
    rooms_t = torch.tensor(rooms_c)
    inputs = physics.heat_inputs(
        torch.tensor(heat_w), torch.tensor(series["T_a"]), torch.tensor(sun), torch.tensor(gains_w)
    ).detach()
    offsets = torch.arange(-k, 1)
    generator = torch.Generator().manual_seed(seed)
    n_batches = math.ceil(len(starts) / settings.batch)
    total = settings.epochs * n_batches
    groups = [
        {"params": list(nets.parameters()), "factor": 1.0},
        {"params": list(physics.parameters()), "factor": settings.physics_lr_factor},
    ]
    optimiser = torch.optim.Adam(groups, lr=settings.learning_rate)
    decay = settings.lr_final / settings.learning_rate
    starts_t = torch.as_tensor(starts)
    losses: tuple[float, float] = (math.nan, math.nan)
    began = time.perf_counter()
    with _threads(1):
        nets.train()
        done = 0
        for _ in range(settings.epochs):
            order = starts_t[torch.randperm(len(starts_t), generator=generator)]
            for b in range(n_batches):
                batch = order[b * settings.batch : (b + 1) * settings.batch]
                paths = _rollout_data(step, data, batch, h, k)
                truth = data.rooms[batch[:, None] + torch.arange(1, h + 1)]
                loss_reg = torch.mean((paths - truth) ** 2)
                loss_phys = torch.zeros((), dtype=torch.float64)
                if settings.lam > 0:  # on each rollout's first row and the next (a pair of consecutive rows)
                    pair = torch.stack([batch, batch + 1], dim=1).reshape(-1)
                    rows = pair[:, None] + offsets
                    _, t_m = step(data.rooms[rows], data.heat[rows], data.exog[rows], data.clock[pair])
                    r_room, r_mass = zone_residuals(
                        physics, dt_s, rooms_c=rooms_t[pair].reshape(-1, 2, z_n).transpose(0, 1),
                        masses_c=(t_m.double() * scaling.t_std_k + scaling.t_mean_c).reshape(-1, 2, z_n).transpose(0, 1),
                        inputs=inputs[pair].reshape(-1, 2, inputs.shape[1]).transpose(0, 1),
                    )
                    loss_phys = (torch.mean(r_room**2) + torch.mean(r_mass**2)) / scaling.t_std_k**2
                for group in optimiser.param_groups:
                    cosine = decay + (1 - decay) * 0.5 * (1 + math.cos(math.pi * done / max(total, 1)))
                    group["lr"] = settings.learning_rate * cosine * group["factor"]
                optimiser.zero_grad(set_to_none=True)
                (loss_reg + settings.lam * loss_phys).backward()
                optimiser.step()
                done += 1
                losses = (float(loss_reg.detach()), float(loss_phys.detach()))
    seconds = time.perf_counter() - began
    training = data_summary(frame) | {
        "dt_s": float(dt_s), "seed": int(seed), "settings": asdict(settings), "train_seconds": seconds,
        "final_loss": {"reg": losses[0], "phys": losses[1]},
    }
    return MultiZonePaperModel(
        nets=nets, physics=physics, scaling=scaling, identified=identified, actuators=actuators, dt_s=dt_s,
        solar_inputs=solar_inputs, uses_gains=uses_gains, training=training,
    )


def save_multizone_paper(model: MultiZonePaperModel, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` as ``path/multizone_paper.json`` (the directory is created); the file written."""
    from pinn_mpc.models.multizone_hybrid import write_zone_model_file

    return write_zone_model_file(model.to_json(), path, MULTIZONE_PAPER_FILE)


def _load_state(module: nn.Module, raw: Any, file: Path, what: str) -> None:
    """Copy the numbers ``raw`` (name -> nested lists) into ``module``'s parameters and
    buffers, each name, shape and value checked; InputError naming ``file`` otherwise."""
    again = "train it again"
    own = module.state_dict()
    if not isinstance(raw, dict) or set(raw) != set(own):
        raise InputError(f"{file}: {what} must hold exactly {', '.join(own)}; {again}")
    values = {}
    for name, target in own.items():
        try:
            value = torch.as_tensor(np.asarray(raw[name], dtype=float), dtype=target.dtype)
        except (TypeError, ValueError):
            raise InputError(f"{file}: {what}.{name} must be an array of numbers; {again}") from None
        if value.numel() == 0 == target.numel():  # JSON's [] keeps no shape
            value = value.reshape(target.shape)
        if tuple(value.shape) != tuple(target.shape):
            raise InputError(f"{file}: {what}.{name} has shape {tuple(value.shape)}, not {tuple(target.shape)}; {again}")
        if value.numel() and not float(value.double().abs().max()) <= MAX_ABS_PARAM:
            raise InputError(f"{file}: {what}.{name} holds a value beyond {MAX_ABS_PARAM:g} (or not finite); {again}")
        values[name] = value
    module.load_state_dict(values)


def load_multizone_paper(path: str | os.PathLike[str]) -> MultiZonePaperModel:
    """Read ``path/multizone_paper.json``: its checksum, every shape and number checked
    (reading runs nothing from the file); InputError naming the file otherwise."""
    from pinn_mpc.models.multizone_hybrid import read_zone_model_file

    file = Path(path) / MULTIZONE_PAPER_FILE
    again = "train it again"
    data, identified, actuators, dt_s = read_zone_model_file(file, FORMAT, "multi-zone paper network")
    body = {key: value for key, value in data.items() if key != "sha256"}
    if data.get("sha256") != _digest(body):
        raise InputError(f"{file}: its numbers do not match its sha256 (the file was edited or damaged); {again}")
    arch, depth = data.get("family"), data.get("depth")
    if arch not in ARCHS or isinstance(depth, bool) or not isinstance(depth, int) or not 1 <= depth <= 64:
        raise InputError(f"{file}: family must be one of {', '.join(ARCHS)} and depth 1 .. 64; {again}")
    solar, uses_gains = data.get("solar_inputs"), data.get("uses_gains")
    z_n = identified.params.n_zones
    if (not isinstance(solar, list) or len(solar) != z_n or not all(s is None or s in EXOGENOUS_NAMES for s in solar)
            or not isinstance(uses_gains, bool)):
        raise InputError(f"{file}: solar_inputs must name each zone's irradiance or null, uses_gains true or false; {again}")
    raw_physics = data.get("physics")
    pairs = raw_physics.get("pairs") if isinstance(raw_physics, dict) else None
    try:
        pair_list = [(int(i), int(j)) for i, j in np.asarray(pairs, dtype=int).reshape(-1, 2)]
        if not all(0 <= i < j < z_n for i, j in pair_list):
            raise ValueError
        scaling = ZoneScaling(**{**data["scaling"], "heat_scale_w": tuple(data["scaling"]["heat_scale_w"])})
    except (TypeError, ValueError, KeyError):
        raise InputError(f"{file}: physics.pairs must be pairs of zones and scaling its numbers; {again}") from None
    physics = ZonePhysics(identified.params, pair_list)
    nets = ZoneNets(arch, z_n, depth, 0)
    _load_state(physics, raw_physics, file, "physics")
    _load_state(nets, data.get("networks"), file, "networks")
    training = data.get("training_data", {})
    if not isinstance(training, dict):
        raise InputError(f"{file}: training_data must be an object; {again}")
    try:
        return MultiZonePaperModel(
            nets=nets, physics=physics, scaling=scaling, identified=identified, actuators=actuators, dt_s=dt_s,
            solar_inputs=solar, uses_gains=uses_gains, training=training,
        )
    except ValueError as exc:
        raise InputError(f"{file}: {exc}; {again}") from None
