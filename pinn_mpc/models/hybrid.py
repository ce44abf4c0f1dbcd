"""The hybrid, recommended for control: the exact ZOH 2R2C of the physics block predicts,
started at the grey-box identification of the training data; a window observer gives T_m, a
learned backup thermostat the delivered power, a small network a penalised residual.

Its loss is L_reg + ``residual_weight`` x mean squared residual-net output + ``anchor_weight``
x mean squared distance of the physics block's log-coefficients from their start (the
identification of the training data); it has no separate physics loss: its physics is its
predictor. After training, the residual's bound is set from what it added on the training data.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, cast

import numpy as np
import pandas as pd
import torch
from torch import nn

from pinn_mpc import physics
from pinn_mpc.actuator import CopCurve
from pinn_mpc.features import FeatureConfig
from pinn_mpc.models.base import (
    HOLD_TOLERANCE_W,
    Architecture,
    Batch,
    LossFn,
    LossTerms,
    NetParts,
    RolloutInputs,
    TrainingSet,
    regression_loss,
)
from pinn_mpc.models.layers import EnsembleLinear, mlp_layers, run_layers, sigmoid_form, transposed
from pinn_mpc.models.physics_block import discretise_torch, interp_clamped, observe_t_m
from pinn_mpc.models.rollout import Rollout, StackedDynamics

if TYPE_CHECKING:
    from pinn_mpc.identify import IdentifyResult
    from pinn_mpc.models.learned import EnsembleModule, LearnedModel
    from pinn_mpc.training import TrainConfig

__all__ = [
    "BACKUP_SHARE",
    "HIDDEN",
    "RESIDUAL_BOUND_FACTOR",
    "RESIDUAL_UNBOUNDED_K",
    "FewPlanWeights",
    "Hybrid",
    "HybridConstants",
    "HybridInputs",
    "HybridNet",
    "HybridStart",
    "backup_guess",
    "prepare_states",
    "roll_states",
    "saturate_backup",
]

#: Hidden layers of the residual net.
HIDDEN = (32,)
#: The residual net's bound before training sets it (finite: weights files hold no inf).
RESIDUAL_UNBOUNDED_K = 1e3
#: The residual's bound: this times the largest |increment| it added on the training data.
RESIDUAL_BOUND_FACTOR = 1.5
#: Share of the largest power by which delivered must differ from demanded to count as an
#: override of the backup thermostat when its thresholds are guessed.
BACKUP_SHARE = 0.1



def saturate_backup(
    u_w: torch.Tensor,
    t_free: torch.Tensor,
    b_w: torch.Tensor,
    t_off: torch.Tensor,
    t_full: torch.Tensor,
    full_power_w: torch.Tensor,
) -> torch.Tensor:
    """Delivered power [W]: the demand ``u_w`` at most the power that ends the interval at the
    backup's "off" threshold ``t_off`` (and not below 0), at least the one that ends it at its
    "full power" threshold ``t_full`` (and not above ``full_power_w``), where the room ends at
    ``t_free + b_w p`` [C] under power p (``b_w`` [K/W], its sign that of heating)."""
    p_off = ((t_off - t_free) / b_w).clamp(min=0.0)
    p_full = torch.minimum((t_full - t_free) / b_w, full_power_w)
    return torch.maximum(torch.minimum(u_w, p_off), p_full)


class HybridInputs(NamedTuple):
    """What :class:`HybridNet` reads from a sample's features (leading dims (..., ))."""

    window: torch.Tensor  # (..., k+1+4k) raw T_r,i-k..T_r,i, then (u_phys, T_a, G, I_g) per step
    now: torch.Tensor  # (..., n_now) scaled x_obs,i, w_i and u_i (features.now_index())
    raw_now: torch.Tensor  # (..., 4) raw T_r,i, T_a,i, G_i, I_g,i (0 where the data lacks one)


class HybridConstants(NamedTuple):
    """The weights of :class:`HybridNet` arranged for its rollout, per member M; the state is
    (u_phys delivered in the step before [W], T_m, T_r [C]), feature-major (M, 3, N)."""

    observer: torch.Tensor  # (M, k+1+4k, 1) T_m observer over the window
    w_state: torch.Tensor  # (M, out+2, 3) residual net's first layer (folded), then Ad
    b_first: torch.Tensor  # (M, out, 1) first layer's bias with the state's scaling folded in
    w_static: torch.Tensor  # (M, n_series+2, out) first layer on scaled exogenous now, time
    middle: list[tuple[torch.Tensor, torch.Tensor]]  # hidden layers after the first, folded
    w_last: torch.Tensor  # (M, 1, in) last layer (folded) to T_r's increment [K]
    b_last: torch.Tensor  # (M, 1, 1)
    residual_bound_k: torch.Tensor  # (M, 1, 1) |T_r increment| of the residual net [K]
    drive_b: torch.Tensor  # (M, 2, 4) Bd, rows (T_m, T_r), inputs (heat, T_a, G, I_g)
    t_off: torch.Tensor  # (M, 1, 1) backup threshold past which it switches off [C]
    t_full: torch.Tensor  # (M, 1, 1) backup threshold past which it forces full power [C]
    full_power_w: torch.Tensor  # (M, 1, 1)


class FewPlanWeights(NamedTuple):
    """The first layer's weights on each state row (3 of (M, out+2, 1)) and the last layer's
    as a column (M, in, 1): with a few plans, adding the rows one by one is several times
    faster than a batched product of that many columns (:func:`roll_states`)."""

    state_rows: tuple[torch.Tensor, torch.Tensor, torch.Tensor]
    last_column: torch.Tensor

    @classmethod
    def of(cls, c: HybridConstants) -> FewPlanWeights:
        rows = tuple(c.w_state[:, :, i : i + 1].contiguous() for i in range(3))
        return cls(cast(tuple[torch.Tensor, torch.Tensor, torch.Tensor], rows), c.w_last.transpose(1, 2).contiguous())


def roll_states(
    c: HybridConstants,
    state0: torch.Tensor,
    pre: torch.Tensor,
    b_step: torch.Tensor,
    u_w: torch.Tensor,
    p_bounds_w: tuple[float, float] | tuple[torch.Tensor, torch.Tensor],
    *,
    few: FewPlanWeights | None = None,
) -> torch.Tensor:
    """The hybrid's recursion over H steps, the one both a model's rollout
    (:meth:`HybridNet.rollout`) and a fleet's (:class:`pinn_mpc.models.fleet.StackedHybrids`, its
    buildings' members stacked along M) run.

    ``c`` the members' :class:`HybridConstants`; ``state0`` (M, 3, N|1) the state now
    (delivered power of the step before [W], T_m, T_r [C]); ``pre`` (H, M, out+2, N|1) the
    plan-free terms of each step (the residual net's first layer on the exogenous inputs and
    its bias, then the exogenous drive of the 2R2C's rows (T_m, T_r)); ``b_step`` (H|1, M, 2,
    N|1) each step's heat per watt on both rows [K/W]; ``u_w`` (H, M|1, 1, N) the demand [W];
    ``p_bounds_w`` the delivered power's range [W] (numbers, or (M, 1, 1) each); ``few``: add
    the first layer's state rows one by one (a few plans; same arithmetic, other round-off).
    Returns the states (H+1, M, 3, N) at each step's start.

    A step is ten small ops: one product for the residual net's first layer and the free 2R2C
    response together, feature-major as in
    :meth:`pinn_mpc.models.paper.PaperNet.rollout_steps`, tanh folded into a sigmoid; the
    backup thermostat's saturation reads T_r's free response from the same product.
    """
    h_len, m, n = u_w.shape[0], state0.shape[0], u_w.shape[-1]
    hidden = c.b_first.shape[1]
    lo, hi = p_bounds_w
    states = torch.empty(h_len + 1, m, 3, n)
    states[0] = state0
    b_t_r = b_step[:, :, 1:]  # (H|1, M, 1, N|1) [K/W] on T_r
    varies = b_step.shape[0] > 1
    for h in range(h_len):
        now, nxt = states[h], states[h + 1]
        if few is None:
            y = torch.baddbmm(pre[h], c.w_state, now)  # (hidden, free 2R2C response)
        else:
            rows = few.state_rows
            y = torch.addcmul(pre[h], rows[0], now[:, :1])
            y.addcmul_(rows[1], now[:, 1:2]).addcmul_(rows[2], now[:, 2:])
        x = y[:, :hidden].sigmoid_()
        for w, b in c.middle:
            x = torch.baddbmm(b, w, x).sigmoid_()
        hb = h if varies else 0
        t_free = y[:, hidden + 1 :]  # (M, 1, N): T_r,i+1 without power
        p_w = saturate_backup(u_w[h], t_free, b_t_r[hb], c.t_off, c.t_full, c.full_power_w)
        if isinstance(lo, torch.Tensor) and isinstance(hi, torch.Tensor):
            torch.clamp(p_w, lo, hi, out=nxt[:, :1])
        else:  # numbers: torch's faster scalar clamp
            torch.clamp(p_w, float(lo), float(hi), out=nxt[:, :1])
        torch.addcmul(y[:, hidden:], b_step[hb], nxt[:, :1], out=nxt[:, 1:])
        if few is None:
            res = torch.baddbmm(c.b_last, c.w_last, x)
        else:
            res = torch.sum(few.last_column * x, dim=1, keepdim=True).add_(c.b_last)
        nxt[:, 2:] += res.clamp_(-c.residual_bound_k, c.residual_bound_k)
    return states


class HybridStart(NamedTuple):
    """What :func:`roll_states` starts from besides the plans (:func:`prepare_states`), for
    B buildings' members stacked (B*M): ``state0`` (B*M, 3, N0) the state now, ``pre`` (H,
    B*M, out+2, N0) the plan-free terms of every step, ``b_step`` (H|1, B*M, 2, N0) the heat
    per watt on both rows."""

    state0: torch.Tensor
    pre: torch.Tensor
    b_step: torch.Tensor


def prepare_states(
    c: HybridConstants,
    t_r: torch.Tensor,
    p_past: torch.Tensor,
    exog: torch.Tensor,
    static: torch.Tensor,
    gain: torch.Tensor | None,
) -> HybridStart:
    """The plan-free part of the hybrid's rollout, once per decision, for B buildings whose
    members' constants ``c`` are stacked (B*M: building b's members b*M .. b*M+M-1), each from
    N0 starts (one model's rollout: B = 1; a fleet's: N0 = 1). Raw inputs: ``t_r`` (B, N0, k+1)
    T_r,i-k..T_r,i [C]; ``p_past`` (B, N0, k+1) u_phys,i-k-1..u_phys,i-1 [W]; ``exog`` (B, N0,
    k+H, 3) (T_a, G, I_g) from i-k to i+H-1; ``static`` (B, N0, H, n_series+2) the scaled
    exogenous series and encoded time of day of each step; ``gain`` (B, N0, k+H) heat per
    electrical watt (None: 1). T_m is observed once from the window, the exogenous drive of
    both 2R2C rows and the residual net's first layer on the static inputs computed for all H
    steps: what :func:`roll_states` takes besides the plans."""
    b, n0, k1 = t_r.shape
    k, h_len = k1 - 1, static.shape[2]
    bm, hidden = c.observer.shape[0], c.b_first.shape[1]
    m = bm // b
    heat = p_past[..., 1:] if gain is None else p_past[..., 1:] * gain[..., :k]
    d_win = torch.cat([heat[..., None], exog[..., :k, :]], dim=-1)  # (B, N0, k, 4)
    window = torch.cat([t_r, d_win.flatten(-2)], dim=-1)  # (B, N0, k+1+4k)
    drive_b = c.drive_b.view(b, m, 2, 4)
    w_static = c.w_static.view(b, m, *c.w_static.shape[1:])
    observer = c.observer.view(b, m, -1)
    # The T_m observer, the exogenous drive and the first layer on the static inputs: a fleet's
    # contracted building by building (its batch's fastest order), one model's from N0 starts
    # (the order its rollout has always had); the two agree to float round-off.
    if b > 1 and n0 == 1:
        t_m0 = torch.einsum("bw,bmw->bm", window[:, 0], observer)[..., None]
        drive = torch.einsum("bmrc,bhc->hbmr", drive_b[..., 1:], exog[:, 0, k : k + h_len])
        first = torch.einsum("bmsj,bhs->hbmj", w_static, static[:, 0])
        pre = torch.cat([first, drive], dim=-1).reshape(h_len, b, m, hidden + 2, 1)
    else:
        t_m0 = torch.matmul(window[:, None], observer[..., None])[..., 0]
        drive = torch.einsum("bmrc,bnhc->hbmrn", drive_b[..., 1:], exog[:, :, k : k + h_len])
        first = torch.einsum("bmsj,bnhs->hbmjn", w_static, static)
        pre = torch.cat([first, drive], dim=3)
    pre[:, :, :, :hidden] += c.b_first.view(b, m, hidden, 1)
    state0 = torch.empty(b, m, 3, n0)  # (u_phys, T_m, T_r) now
    state0[:, :, 0] = p_past[..., k][:, None]
    state0[:, :, 1] = t_m0
    state0[:, :, 2] = t_r[..., k][:, None]
    pre = pre.reshape(h_len, bm, hidden + 2, n0)
    b_u = drive_b[..., :1]  # (B, M, 2, 1)
    if gain is None:
        b_step = b_u.reshape(1, bm, 2, 1)
    else:  # the input column of Bd times each step's gain
        g = gain[..., k : k + h_len].permute(2, 0, 1)[:, :, None, None, :]  # (H, B, 1, 1, N0)
        b_step = (b_u[None] * g).reshape(h_len, bm, 2, n0)
    return HybridStart(state0.reshape(bm, 3, n0), pre, b_step)


class HybridNet(nn.Module):
    """The recommended model for control: the 2R2C *is* the predictor, networks only correct it.

    For sample i (raw units; ``Ad``, ``Bd`` the exact ZOH of the learnable :class:`Physics`):

    - T_m,i: a physics observer over the history window. With the measured T_r in the
      T_m row, T_m,j = Ad11^(j-i+k) s + c_j is affine in the unknown T_m,i-k = s, and each step
      of the window gives one equation of the T_r row; s is their least-squares solution (closed
      form, differentiable), propagated to row i. No network estimates the hidden state, so none
      can absorb what the physics should explain (PhysNet's encoder does, and its export drifts).
    - u_phys,i: the demand, saturated by a learned backup thermostat as the power that ends the
      interval at its threshold: with T_end(p) = T_free + b g p the physics' T_r,i+1 under
      delivered power p (g the actuator's heat per electrical watt, the COP curve),
      ``p = max(min(u, max(p_off, 0)), min(p_full, P_max))`` where T_end(p_off) is the "off"
      threshold (upper for heating, lower for cooling) and T_end(p_full) the "full power" one.
      The thresholds are learned. Delivered power never falls as the demand rises, and far from
      the thresholds it is exactly the demand (a gate that switched the heater off when the
      demand itself would overshoot made full demand look free; see ``CHANGELOG.md``).
    - T_r,i+1 = Ad[0] (T_r,i, T_m,i) + Bd[0] (u_phys,i, T_a,i, G_i, I_g,i) + residual net
      (z, x_obs, w), with Bd's first input the heat g(T_a) u_phys. The residual net does not see u, so the heating effect is the physics'
      ``b`` (sign fixed by eta) through the delivered power (Di Natale et al., 2022, put the
      inputs' effect in the physics for the same reason); training penalises the residual.

    ``coefficients`` returns the physics block's coefficients (M,); the block itself belongs to
    :class:`pinn_mpc.models.EnsembleModule` (one owner, one set of weights in the state dict).
    """

    def __init__(
        self,
        *,
        features: FeatureConfig,
        n_members: int,
        generators: Sequence[torch.Generator],
        coefficients: Callable[[], physics.Coefficients],
        heating: bool,
        cop_curve: CopCurve | None = None,
    ):
        super().__init__()
        self._cop = (
            None
            if cop_curve is None
            else (torch.tensor(cop_curve.t_a_c), torch.tensor(cop_curve.cop))
        )
        self.heating = heating
        self.n_members = n_members
        self.features = features
        self.coefficients = coefficients
        now = features.now_index()
        self.now_index = torch.tensor(now)
        # Everything of "now" but the demand u (third from last): the residual net's inputs.
        free = [j + 1 for j in range(len(now)) if j != len(now) - 3]
        self.free_index = torch.tensor([0, *free])  # into (z, now...)
        self.residual_net = mlp_layers((len(now), *HIDDEN, 1), n_members, generators)
        with torch.no_grad():  # start as the bare physics: no residual
            last = cast(EnsembleLinear, self.residual_net[-1])
            last.weight.zero_()
            last.bias.zero_()
        # Backup thermostat [C], [W]; set from the data by init_backup before training.
        self.backup_low_c = nn.Parameter(torch.full((n_members, 1), -100.0))
        self.backup_high_c = nn.Parameter(torch.full((n_members, 1), 100.0))
        self.full_power_w: torch.Tensor
        self.register_buffer("full_power_w", torch.zeros(n_members, 1))  # per member, like all
        # |T_r increment| the residual net may add [K]: set after training to what it added
        # on the training data (with a margin), so it cannot extrapolate without bound.
        self.residual_bound_k: torch.Tensor
        self.register_buffer("residual_bound_k", torch.full((n_members, 1), RESIDUAL_UNBOUNDED_K))
        names = features.exog_series
        # Position of T_a, G, I_g in the exogenous windows (None when the data lacks it).
        self._exog_pos = [names.index(n) if n in names else None for n in ("T_a", "G", "I_g")]

    def init_backup(self, low_c: float, high_c: float, full_power_w: float) -> None:
        """Start the learned backup thermostat at thresholds ``low_c`` < ``high_c`` [C]."""
        with torch.no_grad():
            self.backup_low_c.fill_(low_c)
            self.backup_high_c.fill_(high_c)
            self.full_power_w.fill_(full_power_w)

    def gain(self, t_a_c: torch.Tensor) -> torch.Tensor | None:
        """Heat per electrical watt at outdoor temperature ``t_a_c`` [C] (same shape), from the
        COP curve; None for a heater or chiller of constant gain (the physics' eta)."""
        return None if self._cop is None else interp_clamped(t_a_c, *self._cop)

    def thresholds(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The backup's ("off", "full power") thresholds [C], (M, 1) each: (upper, lower) for
        heating, (lower, upper) for cooling."""
        if self.heating:
            return self.backup_high_c, self.backup_low_c
        return self.backup_low_c, self.backup_high_c

    def delivered_w(self, u_w: torch.Tensor, t_free: torch.Tensor, b_w: torch.Tensor) -> torch.Tensor:
        """Delivered power [W] for demand ``u_w`` when the room would end the interval at
        ``t_free`` [C] without power and ``t_free + b_w p`` with power p (``b_w`` [K/W])."""
        return saturate_backup(u_w, t_free, b_w, *self.thresholds(), self.full_power_w)

    def _matrices(self) -> tuple[torch.Tensor, torch.Tensor]:
        ad, bd = discretise_torch(self.coefficients(), self.features.dt_s)
        return ad.float(), bd.float()

    def _inputs(self, p_w: torch.Tensor, exog_c: torch.Tensor) -> torch.Tensor:
        """(heat, T_a, G, I_g) stacked last: ``p_w`` (...,) electrical power, ``exog_c`` (..., 3)
        -> (..., 4); the heat is g(T_a) p_w with a COP curve, else p_w."""
        g = self.gain(exog_c[..., 0])
        heat = p_w if g is None else p_w * g
        return torch.cat([heat[..., None], exog_c], dim=-1)

    def _raw(self, x: torch.Tensor, window: int) -> torch.Tensor:
        """Window ``window`` of scaled features x (..., F) in raw units: (..., k+1)."""
        f = self.features
        k1 = f.depth + 1
        v = x[..., window * k1 : (window + 1) * k1]
        if window == 0:
            return v * f.temperature.std + f.temperature.mean
        if window == 1:
            return v * f.power.std + f.power.mean
        s = f.exog[f.exog_series[window - 2]]
        return v * s.std + s.mean

    def _exog_raw(self, series: torch.Tensor) -> torch.Tensor:
        """Raw (T_a, G, I_g) from raw series (n_series, ...) -> (..., 3), zeros where absent."""
        zero = torch.zeros_like(series[0])
        return torch.stack([zero if j is None else series[j] for j in self._exog_pos], dim=-1)

    def split(self, x: torch.Tensor) -> HybridInputs:
        """What the hybrid reads from scaled features x (..., F); it does not depend on the
        weights, so training computes it once for all samples."""
        k = self.features.depth
        t_r = self._raw(x, 0)
        p_past = self._raw(x, 1)  # u_phys,i-k-1 .. u_phys,i-1
        n_series = len(self.features.exog_series)
        series = torch.stack([self._raw(x, 2 + j) for j in range(n_series)])
        exog = self._exog_raw(series)  # (..., k+1, 3)
        d_win = self._inputs(p_past[..., 1:], exog[..., :-1, :])  # (..., k, 4)
        return HybridInputs(
            window=torch.cat([t_r, d_win.flatten(-2)], dim=-1),
            now=x.index_select(-1, self.now_index),
            raw_now=torch.cat([t_r[..., k, None], exog[..., k, :]], dim=-1),
        )

    def observe_t_m(
        self,
        ad: torch.Tensor,
        bd: torch.Tensor,
        t_r: torch.Tensor,
        d: torch.Tensor,
    ) -> torch.Tensor:
        """T_m at the end of a window [C] (:func:`~pinn_mpc.models.physics_block.observe_t_m`):
        ``t_r`` (M, B, k+1) measured, ``d`` (M, B, k, 4) inputs of the k steps; ``ad`` (M, 2,
        2), ``bd`` (M, 2, 4). Returns (M, B)."""
        return observe_t_m(ad, bd, t_r, d)

    def observer_weights(self, ad: torch.Tensor, bd: torch.Tensor) -> torch.Tensor:
        """:meth:`observe_t_m` is linear in the window (see :class:`HybridInputs`): its weights
        (M, k+1+4k, 1), from applying it to the k+1+4k unit windows."""
        k = self.features.depth
        basis = torch.eye(k + 1 + 4 * k).expand(ad.shape[0], -1, -1)
        weights = self.observe_t_m(ad, bd, basis[..., : k + 1], basis[..., k + 1 :].unflatten(-1, (k, 4)))
        return weights[..., None]

    def observe_linear(self, ad: torch.Tensor, bd: torch.Tensor, window: torch.Tensor) -> torch.Tensor:
        """:meth:`observe_t_m` as one matrix product over ``window`` (M, B, k+1+4k). Returns (M, B)."""
        return torch.bmm(window, self.observer_weights(ad, bd))[..., 0]

    def forward_terms(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(obs, z, residual)`` for scaled features x (M, B, F): ``obs``, ``z`` as
        :meth:`pinn_mpc.models.base.Architecture.build_net`; ``residual`` (M, B) the residual net's scaled output."""
        return self.forward_split(self.split(x))

    def forward_split(self, inputs: HybridInputs) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """:meth:`forward_terms` on the output of :meth:`split` (each (M, B, ...))."""
        f = self.features
        ad, bd = self._matrices()
        t_m = self.observe_linear(ad, bd, inputs.window)
        z = (t_m - f.temperature.mean) / f.temperature.std
        raw = inputs.raw_now
        obs, residual = self._step(ad, bd, raw[..., 0], t_m, z, inputs.now, exog_now=raw[..., 1:])
        return obs, z, residual

    def _step(
        self,
        ad: torch.Tensor,
        bd: torch.Tensor,
        t_r: torch.Tensor,
        t_m: torch.Tensor,
        z: torch.Tensor,
        now: torch.Tensor,
        *,
        exog_now: torch.Tensor,
        p_bounds: tuple[float, float] | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """One step from raw T_r, T_m (M, B), the scaled "now" features (M, B, n_now) and the
        raw (T_a, G, I_g) now (M, B, 3):
        ``(obs (M, B, 2) scaled (dT_r, u_phys), residual (M, B))``."""
        f = self.features
        z_now = torch.cat([z[..., None], now], dim=-1)
        b0 = bd[:, None, 0]
        u_w = now[..., -3] * f.power.std + f.power.mean
        free = (ad[:, None, 0, 0] - 1) * t_r + ad[:, None, 0, 1] * t_m  # without inputs
        t_free = t_r + free + (exog_now * b0[..., 1:]).sum(-1)
        g = self.gain(exog_now[..., 0])
        b_w = b0[..., 0] if g is None else b0[..., 0] * g
        p_w = self.delivered_w(u_w, t_free, b_w)
        p_s = (p_w - f.power.mean) / f.power.std
        if p_bounds is not None:
            p_s = p_s.clamp(*p_bounds)
        residual = run_layers(self.residual_net, z_now.index_select(-1, self.free_index))[..., 0]
        bound = self.residual_bound_k / f.delta_t_r.std
        residual = residual.clamp(-bound, bound)
        d = self._inputs(p_s * f.power.std + f.power.mean, exog_now)
        dt_r = free + (d * b0).sum(-1)
        obs0 = (dt_r - f.delta_t_r.mean) / f.delta_t_r.std + residual
        return torch.stack([obs0, p_s], dim=-1), residual

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        obs, z, _ = self.forward_terms(x)
        return obs, z

    def rollout_constants(self) -> HybridConstants:
        """What :meth:`rollout` needs from the weights; it depends on nothing else, so a caller
        keeps it while the weights do not change."""
        f = self.features
        t, pw = f.temperature, f.power
        with torch.no_grad():
            ad, bd = self._matrices()
            ad, bd = ad.flip(1, 2), bd.flip(1)  # states and rows (T_m, T_r)
            layers = sigmoid_form(self.residual_net, tanh_last=False)
            w0, b0 = layers[0]  # (M, in, out); rows: z, T_r, u_phys, exogenous now, time of day
            # The raw state (u_phys, T_m, T_r) in place of its scaled features.
            w_hidden = torch.stack([w0[:, 2] / pw.std, w0[:, 0] / t.std, w0[:, 1] / t.std], dim=-1)
            w_ad = torch.cat([torch.zeros_like(ad[..., :1]), ad], dim=-1)  # (M, 2, 3)
            shift = (w0[:, 0] + w0[:, 1]) * (t.mean / t.std) + w0[:, 2] * (pw.mean / pw.std)
            rest = transposed(layers[1:])
            w_last, b_last = rest[-1]  # scaled residual -> T_r increment [K]
            t_off, t_full = self.thresholds()
            return HybridConstants(
                observer=self.observer_weights(ad.flip(1, 2), bd.flip(1)),
                w_state=torch.cat([w_hidden, w_ad], dim=1),
                b_first=(b0[:, 0] - shift)[..., None],
                w_static=w0[:, 3:],
                middle=rest[:-1],
                w_last=w_last * f.delta_t_r.std,
                b_last=b_last * f.delta_t_r.std,
                residual_bound_k=self.residual_bound_k.detach()[..., None].clone(),
                drive_b=bd,
                t_off=t_off.detach()[..., None].clone(),
                t_full=t_full.detach()[..., None].clone(),
                full_power_w=self.full_power_w.detach()[..., None].clone(),
            )

    def rollout(
        self,
        constants: HybridConstants,
        windows: Sequence[torch.Tensor],
        u_s: torch.Tensor,
        tod: torch.Tensor,
        p_bounds_w: tuple[float, float],
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Recursive rollout: ``constants`` from :meth:`rollout_constants`, ``windows`` = (t_win,
        p_win, e_seq), ``u_s``, ``tod`` as :meth:`pinn_mpc.models.LearnedModel.rollout_scaled`; ``p_bounds_w``
        the delivered power's range [W]. T_m is observed once from the window, then both states
        propagate through the 2R2C. Returns raw ``(T_r,i+1.. [C], u_phys,i.. [W], T_m,i.. [C])``,
        each (M, N, H).

        The arithmetic of stepping :meth:`_step` (up to float round-off): what does not depend
        on the state (the exogenous drive of both 2R2C rows, the residual net's first layer on
        the exogenous features and time of day, the demand's terms) is computed for all H steps
        first, then :func:`roll_states` steps the state.
        """
        c = constants
        t_win, p_win, e_seq = windows
        f = self.features
        k = f.depth
        h_len = u_s.shape[1]
        t, pw = f.temperature, f.power
        with torch.no_grad():
            t_r = t_win * t.std + t.mean  # (N0, k+1)
            p_past = p_win * pw.std + pw.mean
            scales = [f.exog[name] for name in f.exog_series]
            e_raw = torch.stack([e_seq[:, j] * sc.std + sc.mean for j, sc in enumerate(scales)])
            exog = self._exog_raw(e_raw)  # (N0, k+H, 3)
            n0 = max(e_seq.shape[0], tod.shape[0])
            e_now = e_seq[:, :, k : k + h_len].transpose(1, 2).expand(n0, -1, -1)
            static = torch.cat([e_now, tod[:, :h_len].expand(n0, -1, -1)], dim=-1)
            g = self.gain(exog[..., 0])  # (N0, k+H) heat per electrical watt, or None
            start = prepare_states(
                c, t_r[None], p_past[None], exog[None], static[None], None if g is None else g[None]
            )
            u_w = (u_s * pw.std + pw.mean).T.contiguous()[:, None]  # (H, 1, N)
            series = roll_states(c, *start, u_w, p_bounds_w).permute(1, 2, 3, 0)
            return (
                series[:, 2, :, 1:].contiguous(),
                series[:, 0, :, 1:].contiguous(),
                series[:, 1, :, :-1].contiguous(),
            )


def backup_guess(df: pd.DataFrame, *, heating: bool) -> tuple[float, float, float]:
    """Start of the hybrid's learned backup thermostat: (low, high) [C] and full power [W].

    Intervals whose delivered power exceeds (falls short of) the demand by more than
    :data:`BACKUP_SHARE` of the largest power were forced on (off);
    the threshold starts at the 90th percentile of the room's lowest temperature over the
    forced intervals on the cold side (the 10th of the highest on the hot side); with no
    such interval, 5 K beyond what the data saw.
    """
    t_r = df["T_r"].to_numpy(dtype=float)
    gap = df["u_phys"].to_numpy(dtype=float)[:-1] - df["u"].to_numpy(dtype=float)[:-1]
    lo, hi = np.minimum(t_r[:-1], t_r[1:]), np.maximum(t_r[:-1], t_r[1:])
    # An override moves a sizeable share of full power; a machine's minimum modulation only
    # rounds the demand (a heat pump cycling below it: a few per cent of its minimum power).
    tolerance = max(HOLD_TOLERANCE_W, BACKUP_SHARE * float(df["u_phys"].max()))
    forced_on, forced_off = gap > tolerance, gap < -tolerance
    cold, hot = (forced_on, forced_off) if heating else (forced_off, forced_on)
    low = float(np.percentile(lo[cold], 90)) if cold.any() else float(t_r.min()) - 5.0
    high = float(np.percentile(hi[hot], 10)) if hot.any() else float(t_r.max()) + 5.0
    if not low < high:
        low, high = float(t_r.min()) - 5.0, float(t_r.max()) + 5.0
    return low, high, float(df["u_phys"].max())


class Hybrid(Architecture):
    """The 2R2C with learned corrections (:class:`HybridNet`). Its physics block starts at the
    identification of the training data, learns ten times slower than the network, and works
    on the heat (the COP curve times u_phys); a model directory of format 1 held an older
    backup thermostat, so only format 2 is read."""

    physics_lr_factor = 0.1
    format_versions = (2,)
    gain_schedule = True

    def build_net(self, parts: NetParts) -> nn.Module:
        assert parts.physics_block is not None
        return HybridNet(
            features=parts.features,
            n_members=parts.n_members,
            generators=parts.generators,
            coefficients=parts.physics_block.coefficients,
            heating=parts.prior.heating,
            cop_curve=parts.cop_curve,
        )

    def training_prior(
        self, config: TrainConfig, df: pd.DataFrame, identified: IdentifyResult | None
    ) -> physics.RCParams:
        """The identification of ``df`` unless ``config`` gives a prior (its physics works on
        the heat, g(T_a) x u_phys)."""
        if config.prior is not None:
            return config.prior_params()
        if identified is not None:
            return identified.params
        from pinn_mpc.identify import identify_rc

        return identify_rc(df, eta=config.eta, unmeasured_gains=False).params  # raises what made it fail

    def loss_fn(
        self, module: EnsembleModule, data: TrainingSet, config: TrainConfig, lam: float
    ) -> LossFn:
        net, block = module.net, module.physics
        assert isinstance(net, HybridNet) and block is not None
        net.init_backup(*backup_guess(data.df, heating=net.heating))
        split = net.split(data.x)  # what the hybrid reads, once for all samples
        start = [p.detach().clone() for p in block.parameters()]

        def loss(batch: Batch) -> LossTerms:
            obs, _, res = net.forward_split(HybridInputs(*(v[batch.flat] for v in split)))
            loss_reg = regression_loss(obs, data, batch)
            anchor = sum(torch.mean((p - p0) ** 2) for p, p0 in zip(block.parameters(), start, strict=True))
            total = loss_reg + config.residual_weight * torch.mean(res**2)
            total = total + config.anchor_weight * cast(torch.Tensor, anchor)
            return LossTerms(total=total, reg=loss_reg, phys=torch.zeros(()))

        return loss

    def after_training(self, module: EnsembleModule, data: TrainingSet) -> None:
        """Bound the residual by :data:`RESIDUAL_BOUND_FACTOR` times the largest increment it
        added on the training data."""
        net = module.net
        assert isinstance(net, HybridNet)
        m, n_samples = module.n_members, data.x.shape[0]
        module.eval()
        with torch.no_grad():
            split = net.split(data.x)
            every = torch.arange(n_samples).expand(m, -1)
            _, _, res = net.forward_split(HybridInputs(*(v[every] for v in split)))  # (M, S)
            largest = (res.abs() * data.features.delta_t_r.std).amax(dim=1, keepdim=True)
            net.residual_bound_k.copy_(RESIDUAL_BOUND_FACTOR * largest + 1e-3)

    def record_fields(self, config: TrainConfig, cop_curve: CopCurve | None) -> dict[str, Any]:
        return {
            "residual_weight": config.residual_weight,
            "anchor_weight": config.anchor_weight,
            "cop_curve": cop_curve.to_dict() if cop_curve is not None else None,
        }

    def rollout_constants(self, net: nn.Module) -> HybridConstants:
        assert isinstance(net, HybridNet)
        return net.rollout_constants()

    def stack_key(self, model: LearnedModel) -> Hashable | None:
        """Hybrids of one depth, exogenous inputs and interval stack (each building its own
        weights, scaling, COP curve and backup thermostat); one with a gain schedule rolls
        out alone (its gains come from the calendar)."""
        if model.features.gain_schedule_w:
            return None
        return (self.name, model.depth, model.exog_names, model.dt_s)

    def stacked(self, models: Sequence[LearnedModel], members: int) -> StackedDynamics:
        from pinn_mpc.models.fleet import StackedHybrids

        return StackedHybrids(models, members=members)

    def rollout_scaled(self, model: LearnedModel, inputs: RolloutInputs) -> Rollout:
        net = model.module.net
        assert isinstance(net, HybridNet)
        constants = cast(HybridConstants, model.rollout_constants())
        lo, hi = model.record.u_phys_range_w
        t_r, p_w, t_m = net.rollout(
            constants, inputs[:3], inputs.u_s, inputs.tod, (lo, hi)
        )
        return Rollout.of_one_zone(t_r, p_w, t_m)
