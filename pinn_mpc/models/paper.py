"""What the paper's three networks share (paper section 2.2, appendix A).

Their networks map the scaled feature window to a scaled T_r increment, the delivered power
u_phys and (physics-informed ones) T_m. Shared here: the physics block's start (the prior, on
electrical power), the training loss (L_reg + lambda L_phys, paper Eq. gen-loss) and the fused
recursive rollout over a network's :meth:`PaperNet.rollout_steps`.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
import torch
from torch import nn

from pinn_mpc import physics
from pinn_mpc.models.base import (
    Architecture,
    Batch,
    LossFn,
    LossTerms,
    RolloutInputs,
    TrainingSet,
    regression_loss,
)
from pinn_mpc.models.physics_block import residual_exact, residual_finite_difference
from pinn_mpc.models.rollout import Rollout

if TYPE_CHECKING:
    from pinn_mpc.identify import IdentifyResult
    from pinn_mpc.models.learned import EnsembleModule, LearnedModel
    from pinn_mpc.training import TrainConfig

__all__ = ["PaperArchitecture", "PaperNet", "StaticInputs", "StepFn", "mean_cop", "run_transposed"]

#: A prepared rollout step: ``step(tp, h) -> (obs (M, 2, N), z (M, N) or None)``.
StepFn = Callable[[torch.Tensor, int], tuple[torch.Tensor, torch.Tensor | None]]


def mean_cop(df: pd.DataFrame) -> float:
    """The power-weighted mean heat per electrical watt (1 without a ``cop`` column)."""
    if "cop" not in df.columns:
        return 1.0
    u_w = df["u_phys"].to_numpy(dtype=float)
    return float(np.sum(u_w * df["cop"].to_numpy(dtype=float)) / max(np.sum(u_w), 1e-9))


class StaticInputs:
    """What a rollout's steps share: the scaled exogenous windows ``e_win`` (N0, H,
    n_series*(k+1)), the time of day ``tod`` (N0, H, 2) (N0 is 1 or N) and the demand ``u_s``
    (N, H) of H steps at history depth ``depth``."""

    def __init__(self, e_win: torch.Tensor, u_s: torch.Tensor, tod: torch.Tensor, depth: int):
        k1 = depth + 1
        self.n_series = e_win.shape[-1] // k1
        n0 = max(e_win.shape[0], tod.shape[0])
        self.e_win, self.tod = e_win.expand(n0, -1, -1), tod.expand(n0, -1, -1)
        self.u_rows = u_s.T.contiguous()[:, None, None, :]  # (H, 1, 1, N)
        self.n_e = self.n_series * k1

    def pre(
        self, weight: torch.Tensor, bias: torch.Tensor, rows: list[int], cols: list[int]
    ) -> torch.Tensor:
        """Bias + static inputs through a first layer's weight rows: (H, M, out, N0)."""
        static = torch.cat([self.e_win, self.tod], dim=-1)[..., cols]  # (N0, H, n)
        out = torch.einsum("nhf,mfo->hmon", static, weight[:, rows])
        return out + bias.transpose(1, 2)[None]


def tp_weight(weight: torch.Tensor, t_rows: list[int], p_rows: list[int]) -> torch.Tensor:
    """Transposed rows for the interleaved (T_r, u_phys) window, (M, out, 2 * len(t_rows))."""
    w = torch.stack([weight[:, t_rows], weight[:, p_rows]], dim=2)
    return w.reshape(w.shape[0], -1, w.shape[-1]).transpose(1, 2).contiguous()


def run_transposed(layers: list[tuple[torch.Tensor, torch.Tensor]], x: torch.Tensor) -> torch.Tensor:
    """Transposed folded layers on x (M, in, N): sigmoid on all but the last."""
    for i, (w, b) in enumerate(layers):
        x = torch.baddbmm(b, w, x)
        if i < len(layers) - 1:
            x = torch.sigmoid(x)
    return x


class PaperNet(nn.Module):
    """A network of the paper: ``forward`` as :meth:`Architecture.build_net` says, and
    :meth:`rollout_steps` for the fused rollout."""

    @abstractmethod
    def rollout_steps(self, inputs: StaticInputs, depth: int) -> StepFn:
        """Prepare a recursive rollout over H steps; the same ``(obs, z)`` as ``forward``,
        feature-major (the batch last).

        Returns ``step(tp, h) -> (obs (M, 2, N), z (M, N) or None)``: ``tp`` (M, k+1+H, 2, N)
        holds scaled (T_r, u_phys) per time index, the window of step h being
        ``tp[:, h:h+k+1]``.

        Three things make a step cheap (a rollout's time is nearly all in these steps):

        - Everything that does not depend on the predictions (exogenous windows, time of day) is
          pushed through the first layers once for all steps (:meth:`StaticInputs.pre`), so
          each step only multiplies the T_r/u_phys window and the demand.
        - Feature-major tensors (M, features, N): the narrow output layers become (2 x hidden) @
          (hidden x N) products, which BLAS does several times faster than (N x hidden) @
          (hidden x 2).
        - ``tanh(a) = 2 sigmoid(2a) - 1``, with the factors folded into the weights
          (:func:`pinn_mpc.models.layers.sigmoid_form`): PyTorch's CPU sigmoid is several times
          faster than its tanh.
        """


class PaperArchitecture(Architecture):
    """The paper's networks: the physics block starts at the prior on electrical power; the
    loss is L_reg plus, for physics-informed ones, lambda times the physics residual."""

    def training_prior(
        self, config: TrainConfig, df: pd.DataFrame, identified: IdentifyResult | None
    ) -> physics.RCParams:
        """``config``'s prior with eta times the data's mean COP (the networks see electrical
        power)."""
        return replace(config.prior_params(), eta=config.eta * mean_cop(df))

    def physics_weight(self, lam: float) -> float:
        return lam if self.has_physics else 0.0

    def loss_fn(
        self, module: EnsembleModule, data: TrainingSet, config: TrainConfig, lam: float
    ) -> LossFn:
        net, block = module.net, module.physics
        m, chunk = module.n_members, data.chunk
        f = data.features
        t_s, p_s, d_s = f.temperature, f.power, f.delta_t_r
        dt_s = f.dt_s

        def loss(batch: Batch) -> LossTerms:
            first, idx, flat = batch
            c = idx.shape[1]
            obs, z = net(data.x[flat])
            loss_reg = regression_loss(obs, data, batch)
            total = loss_reg
            loss_phys = torch.zeros(())
            if lam > 0 and z is not None and block is not None:
                coef = block.coefficients()
                t_m_hat = (z * t_s.std + t_s.mean).reshape(m, c, chunk)
                t_r_seq = data.t_r[first[..., None] + torch.arange(chunk + 1)]
                if config.residual == "exact":
                    r_room, r_mass = residual_exact(
                        coef, dt_s, t_r=t_r_seq, d=data.inputs[idx], t_m_hat=t_m_hat
                    )
                    w_room = data.held[idx]
                    w_mass = w_room[..., :-1]
                    # Per member, so that members stay independent of each other.
                    sq_room = (w_room * r_room**2).sum((1, 2))
                    total_sq = sq_room + (w_mass * r_mass**2).sum((1, 2))
                    count = w_room.sum((1, 2)) + w_mass.sum((1, 2))
                    sq = torch.mean(total_sq / count.clamp(min=1.0))
                else:
                    obs3 = obs.reshape(m, c, chunk, 2)
                    res = residual_finite_difference(
                        coef,
                        dt_s,
                        t_r=t_r_seq,
                        t_r_hat=t_r_seq[..., :-1] + obs3[..., 0] * d_s.std + d_s.mean,
                        u_phys_hat=obs3[..., 1] * p_s.std + p_s.mean,
                        exog=data.inputs[idx][..., 1:],
                        t_m_hat=t_m_hat,
                    )
                    sq = torch.mean(res**2)
                loss_phys = sq / t_s.std**2
                total = loss_reg + lam * loss_phys
            return LossTerms(total=total, reg=loss_reg, phys=loss_phys)

        return loss

    def rollout_scaled(self, model: LearnedModel, inputs: RolloutInputs) -> Rollout:
        t_win, p_win, e_seq, u_s, tod = inputs
        f = model.features
        net = model.module.net
        assert isinstance(net, PaperNet)
        m, k1 = model.n_members, model.depth + 1
        n, h_len = u_s.shape
        tp = torch.empty(m, k1 + h_len, 2, n)  # feature-major: see PaperNet.rollout_steps
        tp[:, :k1, 0] = t_win.T
        tp[:, :k1, 1] = p_win.T
        e_win = e_seq.unfold(-1, k1, 1)[..., :h_len, :]  # (N0, n_series, H, k+1)
        e_win = e_win.permute(0, 2, 1, 3).reshape(e_seq.shape[0], h_len, -1)
        z_out = torch.empty(m, h_len, n) if self.has_physics else None
        s = model.scaling
        # Scaled outputs -> (T_r increment, u_phys): obs * scale + shift, then T_r,i added.
        scale = torch.tensor([[s.dt_ratio], [1.0]])
        shift = torch.tensor([[s.dt_offset], [0.0]])
        with torch.no_grad():
            step = net.rollout_steps(StaticInputs(e_win, u_s, tod, model.depth), model.depth)
            for h in range(h_len):
                obs, z = step(tp, h)
                row = tp.select(1, k1 + h)  # (M, 2, N) view
                torch.addcmul(shift, obs, scale, out=row)
                row.select(1, 0).add_(tp.select(1, k1 + h - 1).select(1, 0))
                row.select(1, 1).clamp_(s.p_lo, s.p_hi)
                if z_out is not None and z is not None:
                    z_out.select(1, h).copy_(z)
        out = tp[:, k1:].permute(0, 3, 1, 2).contiguous()  # (M, N, H, 2)
        return Rollout.of_one_zone(
            model.unscale_t(out[..., 0]),
            out[..., 1] * f.power.std + f.power.mean,
            model.unscale_t(z_out.transpose(1, 2)) if z_out is not None else None,
        )
