"""What the physically consistent architectures share (``pcnn``, ``pcnn-parx``; Di Natale et
al., "Physically consistent neural networks for building thermal modeling", Applied Energy
2022): the network of the unforced part, its inputs, and training on a multi-step rollout.

In both, the powers and the outdoor temperature act only through a linear part whose every
response to them is non-negative (each module says why); the network adds, at every interval,
a heat input computed only from what no controller changes: the time of day, the day type,
the irradiance, the internal gains and the wind. It sees no room or mass temperature, no power
and no outdoor temperature, so it adds the same to every plan and every outdoor-temperature
forecast, and every predicted ``T_r`` stays non-decreasing in each heating power (non-increasing
in each cooling power) and in each outdoor temperature of the horizon.

A heat pump's power acts through its coefficient of performance: where the training data has a
``cop`` column (heat per electrical watt, as ``simulate`` writes for a heat pump), the heat the
linear part receives is ``g(T_a) x`` the electrical power, ``g`` the data's COP curve
(:class:`~pinn_mpc.actuator.CopCurve`, the one the hybrid uses) made monotone in the outdoor
temperature (:func:`consistent_cop`): never falling for a heater (a heat pump's COP rises in
milder air), never rising for a cooling machine. The consistency then still holds: ``g`` is
positive, so the heat grows with the power; and ``g(T_a) p`` with ``p >= 0`` (the plan is
clipped to the training data's delivered power, never negative) moves with ``T_a`` in the
heat's own direction, so a warmer interval adds heat that the linear part, whose response to
heat is non-negative, turns into a warmer room, on top of the outdoor temperature's own
non-negative response. Without a ``cop`` column the heat is the power, exactly as before.

Both train on rollouts: each mini-batch chunk of :data:`ROLLOUT_STEPS` consecutive samples is
predicted from its first sample's history on the measured delivered power and weather, and the
loss is the mean squared error of every step's ``T_r`` (in units of the temperature scale),
plus ``residual_weight`` times the mean squared network output (in units of the ``T_r``
increment's scale): the error a planner's day carries, with the network kept small.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, cast

import torch
from torch import nn

from pinn_mpc.actuator import CopCurve
from pinn_mpc.data import WIND
from pinn_mpc.features import FeatureConfig
from pinn_mpc.models.base import Architecture, Batch, LossFn, LossTerms, RolloutInputs, TrainingSet
from pinn_mpc.models.layers import EnsembleLinear, mlp_layers, run_layers
from pinn_mpc.models.physics_block import interp_clamped
from pinn_mpc.models.rollout import Rollout

if TYPE_CHECKING:
    from pinn_mpc.models.learned import EnsembleModule, LearnedModel
    from pinn_mpc.training import TrainConfig

__all__ = [
    "HIDDEN",
    "ROLLOUT_STEPS",
    "ChunkInputs",
    "ConsistentArchitecture",
    "ConsistentNet",
    "UnforcedNet",
    "chunk_inputs",
    "consistent_cop",
]

#: Steps of a training rollout (a day at 30-min intervals).
ROLLOUT_STEPS = 48
#: Hidden layers of the unforced part's network.
HIDDEN = (16,)


class ChunkInputs(NamedTuple):
    """A rollout's scaled inputs with a leading member axis (M or 1): ``t_win``, ``p_win`` (M,
    N, k+1); ``e_seq`` (M, N, n_series, k+H); ``u_s`` (M, N, H); ``tod`` (M, N, H, 2 + 4)."""

    t_win: torch.Tensor
    p_win: torch.Tensor
    e_seq: torch.Tensor
    u_s: torch.Tensor
    tod: torch.Tensor


def chunk_inputs(data: TrainingSet, batch: Batch) -> tuple[ChunkInputs, torch.Tensor]:
    """The rollout inputs of every chunk of ``batch`` (on the measured delivered power) and its
    targets, the measured T_r at the end of each step (M, C, L) [C]."""
    f = data.features
    k1 = f.depth + 1
    n_series = len(f.exog_series)
    head = data.x[batch.first]  # (M, C, F)
    rows = data.x[batch.idx]  # (M, C, L, F)
    windows = [head[..., f.window_start(j) : f.window_start(j) + k1] for j in range(2 + n_series)]
    later = rows[..., 1:, :]
    e_seq = torch.stack(
        [
            torch.cat([windows[2 + j], later[..., f.window_start(2 + j) + f.depth]], dim=-1)
            for j in range(n_series)
        ],
        dim=-2,
    )
    clock = rows[..., f.u_index + 1 : f.u_index + 3 + f.n_calendar]
    inputs = ChunkInputs(windows[0], windows[1], e_seq, data.y[batch.idx][..., 1], clock)
    return inputs, data.t_r[batch.idx + 1]


def with_members(inputs: RolloutInputs) -> ChunkInputs:
    """A planner's :class:`~pinn_mpc.models.base.RolloutInputs` with a member axis of 1."""
    t_win, p_win, e_seq, u_s, tod = inputs
    return ChunkInputs(t_win[None], p_win[None], e_seq[None], u_s[None], tod[None])


class UnforcedNet(nn.Module):
    """The network of the unforced part: per interval, ``n_out`` heat inputs [K per step] from
    the time of day (sin, cos), the day type (where the features have the calendar) and the
    scaled irradiance, gains and wind of the interval (every exogenous series but T_a)."""

    def __init__(
        self, features: FeatureConfig, n_members: int, generators: Sequence[torch.Generator], n_out: int
    ):
        super().__init__()
        self.series = [j for j, name in enumerate(features.exog_series) if name != "T_a"]
        self.n_clock = 2 + (3 if features.calendar else 0)
        self.layers = mlp_layers((len(self.series) + self.n_clock, *HIDDEN, n_out), n_members, generators)
        self.zero_output()  # start with no unforced heat: the linear part alone
        self.n_members = n_members
        self.depth = features.depth
        self.scale_k = features.delta_t_r.std

    def zero_output(self) -> None:
        """Zero the output layer in every member, in place: the network then adds no heat
        for any input."""
        with torch.no_grad():
            last = cast(EnsembleLinear, self.layers[-1])
            last.weight.zero_()
            last.bias.zero_()

    def forward(self, e_seq: torch.Tensor, tod: torch.Tensor) -> torch.Tensor:
        """``e_seq`` (M|1, N, n_series, k+H) scaled, ``tod`` (M|1, N, H, 2+c) -> (M, N, H, n_out)
        [K per step]."""
        h_len = tod.shape[-2]
        now = e_seq[..., self.series, self.depth : self.depth + h_len].transpose(-1, -2)
        x = torch.cat([tod[..., : self.n_clock], now], dim=-1)  # (M|1, N, H, n_in)
        m = self.n_members
        lead = x.shape[:-1]
        flat = x.expand(m, *lead[1:], x.shape[-1]).reshape(m, -1, x.shape[-1])
        out = run_layers(self.layers, flat)
        return out.reshape(m, *lead[1:], -1) * self.scale_k


def consistent_cop(curve: CopCurve | None, *, heating: bool) -> CopCurve | None:
    """The COP curve a consistent model uses: ``curve`` (the training data's, None without a
    ``cop`` column) made non-decreasing in the outdoor temperature for a heater, non-increasing
    for a cooling machine (:meth:`~pinn_mpc.actuator.CopCurve.monotone`; a curve that already
    is stays as it is, so a saved model's loads unchanged)."""
    return None if curve is None else curve.monotone(increasing=heating)


class ConsistentNet(nn.Module):
    """A consistent architecture's network: ``roll(inputs)`` -> (T_r (M, N, H) [C], u_phys (M,
    N, H) [W], T_m (M, N, H) [C] or None, the unforced network's output (M, N, H, n) [K]).

    ``cop_curve`` is the heat per electrical watt it applies (:func:`consistent_cop`; None: the
    heat is the power)."""

    unforced: UnforcedNet
    features: FeatureConfig
    cop_curve: CopCurve | None = None
    _cop: tuple[torch.Tensor, torch.Tensor] | None = None

    def set_cop(self, curve: CopCurve | None, *, heating: bool) -> None:
        """Apply ``curve`` (the data's COP curve, None without one) made monotone
        (:func:`consistent_cop`)."""
        self.cop_curve = consistent_cop(curve, heating=heating)
        self._cop = None if self.cop_curve is None else (
            torch.tensor(self.cop_curve.t_a_c), torch.tensor(self.cop_curve.cop)
        )

    def heat(self, p_w: torch.Tensor, t_a_c: torch.Tensor) -> torch.Tensor:
        """The heat per unit of eta [W] of electrical power ``p_w`` at outdoor temperature
        ``t_a_c`` [C] (same shapes, or broadcasting): ``p_w`` itself without a COP curve."""
        return p_w if self._cop is None else p_w * interp_clamped(t_a_c, *self._cop)

    @abstractmethod
    def roll(
        self, inputs: ChunkInputs, p_bounds_w: tuple[float, float]
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None, torch.Tensor]: ...

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """One step of :meth:`roll` from scaled features x (M, B, F), as
        :meth:`pinn_mpc.models.base.Architecture.build_net` says (the delivered power is the
        demand)."""
        f = self.features
        k1 = f.depth + 1
        win = [x[..., f.window_start(j) : f.window_start(j) + k1] for j in range(2 + len(f.exog_series))]
        inputs = ChunkInputs(
            win[0], win[1], torch.stack(win[2:], dim=-2), x[..., f.u_index : f.u_index + 1],
            x[..., None, f.u_index + 1 : f.u_index + 3 + f.n_calendar],
        )
        t_r, p_w, t_m, _ = self.roll(inputs, (0.0, float("inf")))
        t, d, pw = f.temperature, f.delta_t_r, f.power
        t_now = win[0][..., f.depth] * t.std + t.mean
        obs = torch.stack([(t_r[..., 0] - t_now - d.mean) / d.std, (p_w[..., 0] - pw.mean) / pw.std], dim=-1)
        return obs, None if t_m is None else (t_m[..., 0] - t.mean) / t.std


class ConsistentArchitecture(Architecture):
    """An architecture trained on rollouts of :data:`ROLLOUT_STEPS` (module docstring); it reads
    the calendar and the wind."""

    calendar = True
    optional_exog = (WIND,)
    format_versions = (2,)

    def chunk_length(self, lam: float, linked: int) -> int:
        return ROLLOUT_STEPS

    def prepare(self, module: EnsembleModule, data: TrainingSet, config: TrainConfig) -> None:  # noqa: B027
        """Fit what is fitted before the rollout loss (nothing unless an architecture needs it)."""

    def loss_fn(
        self, module: EnsembleModule, data: TrainingSet, config: TrainConfig, lam: float
    ) -> LossFn:
        net = module.net
        assert isinstance(net, ConsistentNet)
        self.prepare(module, data, config)
        f = data.features
        lo = float(data.df["u_phys"].min())
        hi = float(data.df["u_phys"].max())
        weight = config.residual_weight
        block = module.physics
        start = [] if block is None else [p.detach().clone() for p in block.parameters()]

        def loss(batch: Batch) -> LossTerms:
            inputs, target = chunk_inputs(data, batch)
            t_r, _, _, unforced = net.roll(inputs, (lo, hi))
            reg = torch.mean(((t_r - target) / f.temperature.std) ** 2)
            total = reg + weight * torch.mean((unforced / f.delta_t_r.std) ** 2)
            if block is not None:  # the physics anchored at its start, the identified RC
                anchor = sum(torch.mean((p - p0) ** 2) for p, p0 in zip(block.parameters(), start, strict=True))
                total = total + config.anchor_weight * cast(torch.Tensor, anchor)
            return LossTerms(total=total, reg=reg, phys=torch.zeros(()))

        return loss

    def record_fields(self, config: TrainConfig, cop_curve: CopCurve | None) -> dict[str, Any]:
        used = consistent_cop(cop_curve, heating=config.eta > 0)
        anchor = {"anchor_weight": config.anchor_weight} if self.has_physics else {}
        return {
            "residual_weight": config.residual_weight,
            **anchor,
            "cop_curve": None if used is None else used.to_dict(),
        }

    def rollout_scaled(self, model: LearnedModel, inputs: RolloutInputs) -> Rollout:
        net = model.module.net
        assert isinstance(net, ConsistentNet)
        lo, hi = model.record.u_phys_range_w
        with torch.no_grad():
            t_r, p_w, t_m, _ = net.roll(with_members(inputs), (lo, hi))
        return Rollout.of_one_zone(t_r, p_w, t_m)
