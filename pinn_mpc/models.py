"""The paper's three networks as vectorised seed ensembles, the physics block, LearnedModel.

Every layer holds the weights of all M members, shape (M, in, out), and applies them with one
``torch.baddbmm``; inputs are (M, B, F). The architectures (paper section 2.2, appendix A):

- ``mlp``: plain net, features -> 2x64 tanh -> (T_r,i+1, u_phys,i); regression loss only.
- ``physreg``: shared trunk 2x64 tanh, linear heads for x_obs,i+1 and z_i = T_m,i
  (Eq. physreg-forward).
- ``physnet``: encoder x_f -> 2x24 tanh -> T_m,i; dynamics (T_m,i, x_obs,i, u_i, w_i) ->
  1x128 tanh -> x_obs,i+1 (Eq. physnet-forward). Here x_f also holds the exogenous history
  (see :mod:`pinn_mpc.features`): without T_a,i-1 the encoder cannot pin T_m.

Beyond the paper, ``hybrid`` (:class:`HybridNet`, the default for control): the exact ZOH 2R2C
of the physics block predicts, started at the grey-box identification; a window observer gives
T_m, a learned backup thermostat the delivered power, a small network a penalised residual.

T_r,i+1 is predicted as T_r,i plus a scaled increment; u_phys is clipped to the range seen in
training. :class:`Physics` holds learnable 2R2C
coefficients per member, positive quantities in log space with ``a11 = a12 + c13`` and
``a22 = a21`` by construction and ``b`` keeping the sign of ``eta``. Two physics residuals:

- :func:`residual_finite_difference`: the paper's Eq. est_Tm (T_r row, forward difference).
- :func:`residual_exact`: both rows of the exactly (ZOH) discretised 2R2C, built from
  :func:`pinn_mpc.physics.state_space_entries`; the T_m row links T_m,i to T_m,i+1 of the next
  sample, which makes C_m identifiable. The default.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple, cast

import numpy as np
import pandas as pd
import torch
from torch import nn

from pinn_mpc import physics
from pinn_mpc.actuator import CopCurve
from pinn_mpc.choices import ALL_ARCHS, ARCHS, DEFAULT_ARCH
from pinn_mpc.errors import InputError
from pinn_mpc.features import FeatureConfig, make_windows

__all__ = [
    "ALL_ARCHS",
    "ARCHS",
    "DEFAULT_ARCH",
    "MAX_MEMBERS",
    "EnsembleModule",
    "EnsembleNet",
    "HybridConstants",
    "HybridInputs",
    "HybridNet",
    "LearnedModel",
    "Physics",
    "Rollout",
    "discretise_torch",
    "residual_exact",
    "residual_finite_difference",
]

#: Most ensemble members: far beyond the paper's 20; bounds what training or a model.json can
#: make the program allocate.
MAX_MEMBERS = 1000
HIDDEN = {
    "mlp": (64, 64),
    "physreg": (64, 64),
    "physnet_encoder": (24, 24),
    "physnet_dynamics": (128,),
    "hybrid": (32,),
}


class EnsembleLinear(nn.Module):
    """M independent affine maps: (M, B, n_in) -> (M, B, n_out)."""

    def __init__(
        self, n_members: int, n_in: int, n_out: int, generators: Sequence[torch.Generator]
    ):
        super().__init__()
        self.weight = nn.Parameter(torch.empty(n_members, n_in, n_out))
        self.bias = nn.Parameter(torch.empty(n_members, 1, n_out))
        bound = 1.0 / math.sqrt(n_in)  # PyTorch's nn.Linear default, drawn per member
        with torch.no_grad():
            for m, g in enumerate(generators):
                self.weight[m].uniform_(-bound, bound, generator=g)
                self.bias[m].uniform_(-bound, bound, generator=g)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.baddbmm(self.bias, x, self.weight)


def _mlp(sizes: Sequence[int], m: int, gens: Sequence[torch.Generator]) -> nn.ModuleList:
    return nn.ModuleList(
        EnsembleLinear(m, a, b, gens) for a, b in zip(sizes[:-1], sizes[1:], strict=True)
    )


def _run(layers: nn.ModuleList, x: torch.Tensor) -> torch.Tensor:
    """tanh on every layer but the last (identity output, as in the paper)."""
    for layer in layers[:-1]:
        x = torch.tanh(layer(x))
    out: torch.Tensor = layers[-1](x)
    return out


class EnsembleNet(nn.Module):
    """One of the three architectures for M members. ``forward(x (M, B, F))`` returns
    ``(obs (M, B, 2) scaled (dT_r, u_phys), z (M, B) scaled T_m or None)``."""

    def __init__(
        self,
        arch: str,
        *,
        features: FeatureConfig,
        n_members: int,
        generators: Sequence[torch.Generator],
    ):
        super().__init__()
        if arch not in ARCHS:
            raise InputError(f"unknown architecture {arch!r}; choose one of {', '.join(ARCHS)}")
        self.arch = arch
        self.n_members = n_members
        if arch == "physnet":
            x_f, now = features.x_f_index(), features.now_index()
            self.x_f_index = torch.tensor(x_f)
            self.now_index = torch.tensor(now)
            self.encoder = _mlp((len(x_f), *HIDDEN["physnet_encoder"], 1), n_members, generators)
            self.dynamics = _mlp(
                (1 + len(now), *HIDDEN["physnet_dynamics"], 2), n_members, generators
            )
        else:
            self.trunk = _mlp((features.n_features, *HIDDEN[arch]), n_members, generators)
            self.head = EnsembleLinear(n_members, HIDDEN[arch][-1], 2, generators)
            if arch == "physreg":
                self.z_head = EnsembleLinear(n_members, HIDDEN[arch][-1], 1, generators)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        if self.arch == "physnet":
            z = _run(self.encoder, x.index_select(-1, self.x_f_index))
            dyn_in = torch.cat([z, x.index_select(-1, self.now_index)], dim=-1)
            return _run(self.dynamics, dyn_in), z[..., 0]
        s = x
        for layer in self.trunk:
            s = torch.tanh(layer(s))
        obs = self.head(s)
        if self.arch == "physreg":
            return obs, self.z_head(s)[..., 0]
        return obs, None

    def rollout_steps(
        self, e_win: torch.Tensor, u_s: torch.Tensor, tod: torch.Tensor, depth: int
    ) -> Callable[[torch.Tensor, int], tuple[torch.Tensor, torch.Tensor | None]]:
        """Prepare a recursive rollout over H steps; the same ``(obs, z)`` as :meth:`forward`,
        feature-major (the batch last).

        ``e_win`` (N0, H, n_series*(k+1)) holds each step's scaled exogenous windows, ``u_s``
        (N, H) the scaled demand, ``tod`` (N0, H, 2) the encoded time of day; N0 is 1 (one
        start, N plans) or N. Returns ``step(tp, h) -> (obs (M, 2, N), z (M, N) or None)``:
        ``tp`` (M, k+1+H, 2, N) holds scaled (T_r, u_phys) per time index, the window of step h
        being ``tp[:, h:h+k+1]``.

        Three things make a step cheap (a rollout's time is nearly all in these steps):

        - Everything that does not depend on the predictions (exogenous windows, time of day) is
          pushed through the first layers once for all steps, so each step only multiplies the
          T_r/u_phys window and the demand.
        - Feature-major tensors (M, features, N): the narrow output layers become (2 x hidden) @
          (hidden x N) products, which BLAS does several times faster than (N x hidden) @
          (hidden x 2).
        - ``tanh(a) = 2 sigmoid(2a) - 1``, with the factors folded into the weights
          (:func:`_sigmoid_form`): PyTorch's CPU sigmoid is several times faster than its tanh.
        """
        k, k1 = depth, depth + 1
        n_series = e_win.shape[-1] // k1
        n0 = max(e_win.shape[0], tod.shape[0])
        e_win, tod = e_win.expand(n0, -1, -1), tod.expand(n0, -1, -1)
        u_rows = u_s.T.contiguous()[:, None, None, :]  # (H, 1, 1, N)
        n_e = n_series * k1

        def pre(weight: torch.Tensor, bias: torch.Tensor, rows: list[int], cols: list[int]) -> torch.Tensor:
            """Bias + static inputs through a first layer's weight rows: (H, M, out, N0)."""
            static = torch.cat([e_win, tod], dim=-1)[..., cols]  # (N0, H, n)
            out = torch.einsum("nhf,mfo->hmon", static, weight[:, rows])
            return out + bias.transpose(1, 2)[None]

        def tp_weight(weight: torch.Tensor, t_rows: list[int], p_rows: list[int]) -> torch.Tensor:
            """Transposed rows for the interleaved (T_r, u_phys) window, (M, out, 2 * len(t_rows))."""
            w = torch.stack([weight[:, t_rows], weight[:, p_rows]], dim=2)
            return w.reshape(w.shape[0], -1, w.shape[-1]).transpose(1, 2).contiguous()

        def run_t(layers: list[tuple[torch.Tensor, torch.Tensor]], x: torch.Tensor) -> torch.Tensor:
            """Transposed folded layers on x (M, in, N): sigmoid on all but the last."""
            for i, (w, b) in enumerate(layers):
                x = torch.baddbmm(b, w, x)
                if i < len(layers) - 1:
                    x = torch.sigmoid(x)
            return x

        if self.arch == "physnet":
            enc = _sigmoid_form(self.encoder, tanh_last=False)
            dyn = _sigmoid_form(self.dynamics, tanh_last=False)
            (w_e0, b_e0), (w_d0, b_d0) = enc[0], dyn[0]
            enc_e = [s * k1 + j for s in range(n_series) for j in range(k)]
            pre_enc = pre(w_e0, b_e0, list(range(2 * k, 2 * k + len(enc_e))), enc_e)
            w_enc = tp_weight(w_e0, list(range(k)), list(range(k, 2 * k)))
            # Dynamics rows: z, T_r now, u_phys now, exogenous now (n_series), u, time of day.
            now_e = [s * k1 + k for s in range(n_series)]
            dyn_static_rows = [*range(3, 3 + n_series), 4 + n_series, 5 + n_series]
            pre_dyn = pre(w_d0, b_d0, dyn_static_rows, [*now_e, n_e, n_e + 1])
            w_dyn = w_d0[:, [0, 1, 2, 3 + n_series]].transpose(1, 2).contiguous()  # (M, out, 4)
            enc_rest, dyn_rest = _transposed(enc[1:]), _transposed(dyn[1:])

            def step_net(tp: torch.Tensor, h: int) -> tuple[torch.Tensor, torch.Tensor | None]:
                m, n = tp.shape[0], tp.shape[-1]
                x = torch.baddbmm(pre_enc[h], w_enc, tp[:, h : h + k].reshape(m, 2 * k, n))
                z = run_t(enc_rest, torch.sigmoid(x)) if enc_rest else x  # (M, 1, N)
                small = torch.cat([z, tp[:, h + k], u_rows[h].expand(m, 1, n)], dim=1)
                hidden = torch.sigmoid(torch.baddbmm(pre_dyn[h], w_dyn, small))
                return run_t(dyn_rest, hidden), z[:, 0]

            return step_net
        trunk = _sigmoid_form(self.trunk, tanh_last=True)
        w_t0, b_t0 = trunk[0]
        n_x = 2 * k1 + n_e
        pre_trunk = pre(w_t0, b_t0, [*range(2 * k1, n_x), n_x + 1, n_x + 2], [*range(n_e), n_e, n_e + 1])
        w_trunk = tp_weight(w_t0, list(range(k1)), list(range(k1, 2 * k1)))
        w_u = w_t0[:, n_x][:, :, None]  # (M, out, 1)
        trunk_rest = _transposed(trunk[1:])
        head = _transposed([_fold(self.head.weight, self.head.bias, sigmoid_in=True, tanh_out=False)])[0]
        z_head = (
            _transposed([_fold(self.z_head.weight, self.z_head.bias, sigmoid_in=True, tanh_out=False)])[0]
            if self.arch == "physreg"
            else None
        )

        def step_reg(tp: torch.Tensor, h: int) -> tuple[torch.Tensor, torch.Tensor | None]:
            m, n = tp.shape[0], tp.shape[-1]
            base = torch.addcmul(pre_trunk[h], w_u, u_rows[h])
            s = torch.sigmoid(torch.baddbmm(base, w_trunk, tp[:, h : h + k1].reshape(m, 2 * k1, n)))
            for w, b in trunk_rest:
                s = torch.sigmoid(torch.baddbmm(b, w, s))
            obs = torch.baddbmm(head[1], head[0], s)
            return obs, (torch.baddbmm(z_head[1], z_head[0], s)[:, 0] if z_head else None)

        return step_reg


def _fold(
    weight: torch.Tensor, bias: torch.Tensor, *, sigmoid_in: bool, tanh_out: bool
) -> tuple[torch.Tensor, torch.Tensor]:
    """An ensemble layer (M, in, out), (M, 1, out) rewritten for ``tanh = 2 sigmoid(2 .) - 1``:
    its input is ``sigmoid(2a)`` instead of ``tanh(a)`` when ``sigmoid_in``, and its output
    feeds a sigmoid instead of a tanh when ``tanh_out``. Same function, exactly in real numbers."""
    w, b = weight.detach(), bias.detach()
    if sigmoid_in:  # W tanh(a) + b = 2W sigmoid(2a) + (b - W 1)
        w, b = 2.0 * w, b - w.sum(dim=1, keepdim=True)
    if tanh_out:
        w, b = 2.0 * w, 2.0 * b
    return w, b


def _sigmoid_form(
    layers: nn.ModuleList, *, tanh_last: bool
) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """:func:`_fold` over a chain of layers with tanh between them (and after the last if
    ``tanh_last``); (weight (M, in, out), bias (M, 1, out)) per layer."""
    n = len(layers)
    return [
        _fold(
            cast(EnsembleLinear, layer).weight,
            cast(EnsembleLinear, layer).bias,
            sigmoid_in=i > 0,
            tanh_out=tanh_last or i < n - 1,
        )
        for i, layer in enumerate(layers)
    ]


def _transposed(
    layers: list[tuple[torch.Tensor, torch.Tensor]],
) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """Feature-major layers: weight (M, out, in), bias (M, out, 1)."""
    return [(w.transpose(1, 2).contiguous(), b.transpose(1, 2).contiguous()) for w, b in layers]


_GAIN_NAMES = {"G": ("c11", "c21"), "I_g": ("c12", "c22")}


class Physics(nn.Module):
    """Learnable 2R2C coefficients (per second), one set per member, initialised from a prior.

    Positive quantities live in log space; ``a11 = a12 + c13``, ``a22 = a21``; ``b = sign(eta)
    * exp(log|b|)``. Solar and internal-gain coefficients are learnable only when the data has
    ``G``/``I_g`` (softplus of a parameter, scaled by the prior's ``1/C_r``), else zero.
    """

    def __init__(self, prior: physics.RCParams, *, n_members: int, exog_names: Sequence[str]):
        super().__init__()
        coef = physics.to_coefficients(prior)
        self.sign_b = 1.0 if prior.eta > 0 else -1.0

        def log_param(value: float) -> nn.Parameter:
            return nn.Parameter(torch.full((n_members,), math.log(abs(float(value)))))

        self.log_a12 = log_param(coef.a12)
        self.log_c13 = log_param(coef.c13)
        self.log_a21 = log_param(coef.a21)
        self.log_b = log_param(coef.b)  # log|b|
        self.gain_scale = 1.0 / prior.c_r_j_per_k
        self.gains = tuple(n for g in ("G", "I_g") if g in exog_names for n in _GAIN_NAMES[g])
        for name in self.gains:
            value = max(float(getattr(coef, name)) / self.gain_scale, 1e-3)
            raw = value + math.log(-math.expm1(-value))  # softplus^-1
            self.register_parameter(f"raw_{name}", nn.Parameter(torch.full((n_members,), raw)))

    def coefficients(self) -> physics.Coefficients:
        """Coefficients whose fields are tensors (M,)."""
        a12, c13, a21 = self.log_a12.exp(), self.log_c13.exp(), self.log_a21.exp()
        zero = torch.zeros_like(a12)
        gains = {
            n: nn.functional.softplus(getattr(self, f"raw_{n}")) * self.gain_scale
            if n in self.gains
            else zero
            for n in ("c11", "c12", "c21", "c22")
        }
        return physics.Coefficients(
            a11=a12 + c13,
            a12=a12,
            a21=a21,
            a22=a21,
            b=self.sign_b * self.log_b.exp(),
            c13=c13,
            **gains,
        )


def discretise_torch(coef: physics.Coefficients, dt_s: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Exact ZOH of the 2R2C for tensor coefficients (M,): ``Ad`` (M, 2, 2), ``Bd`` (M, 2, 4).

    Input order ``(u, T_a, G, I_g)``; computed in float64 via ``torch.linalg.matrix_exp``.
    """
    a, b = physics.state_space_entries(coef)
    a_mat = torch.stack([torch.stack(row, dim=-1) for row in a], dim=-2).double()
    b_mat = torch.stack([torch.stack(row, dim=-1) for row in b], dim=-2).double()
    m = a_mat.shape[0]
    top = torch.cat([a_mat, b_mat], dim=-1) * dt_s
    aug = torch.cat([top, torch.zeros(m, physics.N_INPUTS, top.shape[-1], dtype=top.dtype)], dim=-2)
    e = torch.linalg.matrix_exp(aug)
    return e[:, : physics.N_STATES, : physics.N_STATES], e[
        :, : physics.N_STATES, physics.N_STATES :
    ]


def interp_clamped(x: torch.Tensor, knots: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    """Piecewise-linear interpolation of ``values`` at increasing ``knots`` (K,), constant
    beyond the end knots (as :func:`numpy.interp`); ``x`` any shape."""
    xc = x.clamp(float(knots[0]), float(knots[-1]))
    j = torch.searchsorted(knots, xc.detach().contiguous()).clamp(1, len(knots) - 1)
    x0, x1 = knots[j - 1], knots[j]
    w = (xc - x0) / (x1 - x0)
    return values[j - 1] + w * (values[j] - values[j - 1])


#: The residual net's bound before training sets it (finite: weights files hold no inf).
RESIDUAL_UNBOUNDED_K = 1e3
#: The residual's bound: this times the largest |increment| it added on the training data.
RESIDUAL_BOUND_FACTOR = 1.5


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
      demand itself would overshoot made full demand look free: 105 x oracle under CEM).
    - T_r,i+1 = Ad[0] (T_r,i, T_m,i) + Bd[0] (u_phys,i, T_a,i, G_i, I_g,i) + residual net
      (z, x_obs, w), with Bd's first input the heat g(T_a) u_phys. The residual net does not see u, so the heating effect is the physics'
      ``b`` (sign fixed by eta) through the delivered power (Di Natale et al., 2022, put the
      inputs' effect in the physics for the same reason); training penalises the residual.

    ``coefficients`` returns the physics block's coefficients (M,); the block itself belongs to
    :class:`EnsembleModule` (one owner, one set of weights in the state dict).
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
        self.arch = "hybrid"
        self.cop_curve = cop_curve
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
        hidden = HIDDEN["hybrid"]
        self.residual_net = _mlp((len(now), *hidden, 1), n_members, generators)
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

    def delivered_w(self, u_w: torch.Tensor, t_free: torch.Tensor, b_w: torch.Tensor) -> torch.Tensor:
        """Delivered power [W] for demand ``u_w`` when the room would end the interval at
        ``t_free`` [C] without power and ``t_free + b_w p`` with power p (``b_w`` [K/W])."""
        t_off, t_full = (
            (self.backup_high_c, self.backup_low_c)
            if self.heating
            else (self.backup_low_c, self.backup_high_c)
        )
        p_off = ((t_off - t_free) / b_w).clamp(min=0.0)
        p_full = torch.minimum((t_full - t_free) / b_w, self.full_power_w)
        return torch.maximum(torch.minimum(u_w, p_off), p_full)

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
        """T_m at the end of a window [C]: ``t_r`` (M, B, k+1) measured, ``d`` (M, B, k, 4)
        inputs of the k steps; ``ad`` (M, 2, 2), ``bd`` (M, 2, 4). Returns (M, B)."""
        k = d.shape[-2]
        a = lambda i, j: ad[:, i, j][:, None, None]  # noqa: E731
        drive = torch.einsum("mbkd,msd->mbks", d, bd)  # (M, B, k, 2)
        y = t_r[..., 1:] - a(0, 0) * t_r[..., :-1] - drive[..., 0]  # = Ad01 T_m,j
        v = a(1, 0) * t_r[..., :-1] + drive[..., 1]  # T_m,j+1 = Ad11 T_m,j + v_j
        steps = torch.arange(k + 1, dtype=ad.dtype)
        powers = ad[:, 1, 1][:, None] ** steps  # (M, k+1): Ad11^j
        # c_j = sum_{t<j} Ad11^(j-1-t) v_t: lower-triangular (M, k+1, k) convolution.
        idx = torch.arange(k + 1)
        lag = idx[:, None] - 1 - idx[None, :-1]  # (k+1, k)
        conv = torch.where(lag >= 0, powers[:, lag.clamp(min=0)], torch.zeros(()))
        c = torch.einsum("mjt,mbt->mbj", conv, v)  # (M, B, k+1)
        g = powers[:, None, :k]
        s = (g * (y / a(0, 1) - c[..., :k])).sum(-1) / (g**2).sum(-1)
        return powers[:, None, k] * s + c[..., k]

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
        :meth:`EnsembleNet.forward`; ``residual`` (M, B) the residual net's scaled output."""
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
        residual = _run(self.residual_net, z_now.index_select(-1, self.free_index))[..., 0]
        bound = self.residual_bound_k / f.delta_t_r.std
        residual = torch.maximum(torch.minimum(residual, bound), -bound)
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
            layers = _sigmoid_form(self.residual_net, tanh_last=False)
            w0, b0 = layers[0]  # (M, in, out); rows: z, T_r, u_phys, exogenous now, time of day
            # The raw state (u_phys, T_m, T_r) in place of its scaled features.
            w_hidden = torch.stack([w0[:, 2] / pw.std, w0[:, 0] / t.std, w0[:, 1] / t.std], dim=-1)
            w_ad = torch.cat([torch.zeros_like(ad[..., :1]), ad], dim=-1)  # (M, 2, 3)
            shift = (w0[:, 0] + w0[:, 1]) * (t.mean / t.std) + w0[:, 2] * (pw.mean / pw.std)
            rest = _transposed(layers[1:])
            w_last, b_last = rest[-1]  # scaled residual -> T_r increment [K]
            t_off, t_full = (
                (self.backup_high_c, self.backup_low_c)
                if self.heating
                else (self.backup_low_c, self.backup_high_c)
            )
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
        p_win, e_seq), ``u_s``, ``tod`` as :meth:`LearnedModel.rollout_scaled`; ``p_bounds_w``
        the delivered power's range [W]. T_m is observed once from the window, then both states
        propagate through the 2R2C. Returns raw ``(T_r,i+1.. [C], u_phys,i.. [W], T_m,i.. [C])``,
        each (M, N, H).

        The arithmetic of stepping :meth:`_step` (up to float round-off), arranged so that a
        step is ten small ops: what does not depend on the state (the exogenous drive of both
        2R2C rows, the residual net's first layer on the exogenous features and time of day,
        the demand's terms) is computed for all H steps first; per step the state goes through
        one product for the first layer and the free 2R2C response together, feature-major
        (M, features, N) as in :meth:`EnsembleNet.rollout_steps`, tanh folded into a sigmoid;
        the backup thermostat's saturation reads T_r's free response from the same product.
        """
        c = constants
        t_win, p_win, e_seq = windows
        f = self.features
        m, k = self.n_members, f.depth
        n, h_len = u_s.shape
        t, pw = f.temperature, f.power
        hidden = c.b_first.shape[1]
        with torch.no_grad():
            t_r = t_win * t.std + t.mean  # (N0, k+1)
            p_past = p_win * pw.std + pw.mean
            scales = [f.exog[name] for name in f.exog_series]
            e_raw = torch.stack([e_seq[:, j] * sc.std + sc.mean for j, sc in enumerate(scales)])
            exog = self._exog_raw(e_raw)  # (N0, k+H, 3)
            d_win = self._inputs(p_past[..., 1:], exog[..., :k, :])
            window = torch.cat([t_r, d_win.flatten(-2)], dim=-1)  # (N0, k+1+4k)
            states = torch.empty(h_len + 1, m, 3, n)  # (u_phys, T_m, T_r) at each step's start
            states[0, :, 0] = p_past[:, k]
            states[0, :, 1] = torch.matmul(window, c.observer)[..., 0]
            states[0, :, 2] = t_r[:, k]
            drive = torch.einsum("mrc,nhc->hmrn", c.drive_b[..., 1:], exog[:, k : k + h_len])
            n0 = max(e_seq.shape[0], tod.shape[0])
            e_now = e_seq[:, :, k : k + h_len].transpose(1, 2).expand(n0, -1, -1)
            static = torch.cat([e_now, tod[:, :h_len].expand(n0, -1, -1)], dim=-1)
            first = torch.einsum("msj,nhs->hmjn", c.w_static, static) + c.b_first  # (H, M, out, N0)
            u_w = (u_s * pw.std + pw.mean).T.contiguous()[:, None]  # (H, 1, N)
            pre = torch.cat([first, drive], dim=2)  # (H, M, out+2, N0)
            # Heat per electrical watt of each step: the input column of Bd times the COP.
            g = self.gain(exog[:, k : k + h_len, 0])  # (N0, H) or None
            b_u = c.drive_b[..., :1]  # (M, 2, 1)
            b_step = b_u[None] if g is None else b_u[None] * g.T[:, None, None, :]  # (H|1, M, 2, N0)
            inv_b = 1.0 / b_step[:, :, 1:]  # (H|1, M, 1, N0) [W/K] on T_r
            lo, hi = p_bounds_w
            for h in range(h_len):
                now, nxt = states[h], states[h + 1]
                y = torch.baddbmm(pre[h], c.w_state, now)  # (hidden, free 2R2C response)
                x = y[:, :hidden].sigmoid_()
                for w, b in c.middle:
                    x = torch.baddbmm(b, w, x).sigmoid_()
                hb = 0 if g is None else h
                t_free = y[:, hidden + 1 :]  # (M, 1, N): T_r,i+1 without power
                p_off = ((c.t_off - t_free) * inv_b[hb]).clamp_(min=0.0)
                p_full = torch.minimum((c.t_full - t_free) * inv_b[hb], c.full_power_w)
                p_w = torch.maximum(torch.minimum(u_w[h], p_off), p_full)
                torch.clamp(p_w, lo, hi, out=nxt[:, :1])
                torch.addcmul(y[:, hidden:], b_step[hb], nxt[:, :1], out=nxt[:, 1:])
                res = torch.baddbmm(c.b_last, c.w_last, x)
                nxt[:, 2:] += torch.maximum(torch.minimum(res, c.residual_bound_k), -c.residual_bound_k)
            series = states.permute(1, 2, 3, 0)  # (M, 3, N, H+1)
            return (
                series[:, 2, :, 1:].contiguous(),
                series[:, 0, :, 1:].contiguous(),
                series[:, 1, :, :-1].contiguous(),
            )


def residual_exact(
    coef: physics.Coefficients,
    dt_s: float,
    *,
    t_r: torch.Tensor,
    d: torch.Tensor,
    t_m_hat: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Both rows of the ZOH 2R2C over chunks of L consecutive samples [K].

    ``t_r`` (M, C, L+1) measured T_r at rows i .. i+L [C]; ``d`` (M, C, L, 4) inputs
    (u_phys [W], T_a [C], G [W/m2], I_g [W]) of rows i .. i+L-1; ``t_m_hat`` (M, C, L)
    predicted T_m of those rows [C]. Returns the T_r-row residual (M, C, L): predicted T_m,i
    minus the T_m,i that takes T_r,i to T_r,i+1; and the T_m-row residual (M, C, L-1):
    predicted T_m,i+1 minus T_m,i propagated one step.
    """
    ad, bd = discretise_torch(coef, dt_s)
    ad, bd = ad.to(t_r.dtype)[:, None, None], bd.to(t_r.dtype)[:, None, None]  # (M, 1, 1, ...)
    drive = (d[..., None, :] * bd).sum(-1)  # (M, C, L, 2 states)
    t_m_implied = (t_r[..., 1:] - ad[..., 0, 0] * t_r[..., :-1] - drive[..., 0]) / ad[..., 0, 1]
    propagated = (
        ad[..., 1, 0] * t_r[..., :-2] + ad[..., 1, 1] * t_m_hat[..., :-1] + drive[..., :-1, 1]
    )
    return t_m_hat - t_m_implied, t_m_hat[..., 1:] - propagated


def residual_finite_difference(
    coef: physics.Coefficients,
    dt_s: float,
    *,
    t_r: torch.Tensor,
    t_r_hat: torch.Tensor,
    u_phys_hat: torch.Tensor,
    exog: torch.Tensor,
    t_m_hat: torch.Tensor,
) -> torch.Tensor:
    """The paper's Eq. est_Tm [K] over chunks of L consecutive samples: (M, C, L-1).

    For each row i after the first of a chunk: ``T_m_hat,i - T_m^M,i`` with
    ``T_m^M,i = (dT_r,i/dt + a11 T_r_hat,i - b u_phys_hat,i - c13 T_a,i - c11 G_i - c12 I_g,i)/a12``
    and ``dT_r,i/dt = (T_r,i+1 - T_r,i)/dt`` from measured values. ``t_r`` (M, C, L+1)
    measured [C]; ``t_r_hat`` (M, C, L) predicted T_r,i+1 of each sample (so T_r_hat,i comes from
    sample i-1, as in the paper); ``u_phys_hat`` (M, C, L) [W]; ``exog`` (M, C, L, 3) T_a, G,
    I_g; ``t_m_hat`` (M, C, L) [C].
    """
    m = t_r.shape[0]

    def col(v: Any) -> Any:
        return v.to(t_r.dtype).reshape(m, 1, 1) if torch.is_tensor(v) else v

    prev_hat = t_r_hat[..., :-1]
    t_r_dot = (t_r[..., 2:] - t_r[..., 1:-1]) / dt_s
    e = exog[..., 1:, :]
    t_m_model = (
        t_r_dot
        + col(coef.a11) * prev_hat
        - col(coef.b) * u_phys_hat[..., 1:]
        - col(coef.c13) * e[..., 0]
        - col(coef.c11) * e[..., 1]
        - col(coef.c12) * e[..., 2]
    ) / col(coef.a12)
    return t_m_hat[..., 1:] - t_m_model


class Rollout(NamedTuple):
    """Recursive predictions for M members x N plans x H intervals (torch tensors)."""

    t_r_c: torch.Tensor  # (M, N, H) T_r at the end of each interval [C]
    u_phys_w: torch.Tensor  # (M, N, H) delivered power during each interval [W]
    t_m_c: torch.Tensor | None  # (M, N, H) T_m at the start of each interval [C]; None for mlp


class EnsembleModule(nn.Module):
    """Network plus (for the physics-informed architectures) the learnable physics block."""

    def __init__(
        self,
        arch: str,
        *,
        features: FeatureConfig,
        n_members: int,
        prior: physics.RCParams,
        generators: Sequence[torch.Generator],
        cop_curve: CopCurve | None = None,
    ):
        super().__init__()
        self.n_members = n_members
        self.physics = (
            Physics(prior, n_members=n_members, exog_names=features.exog_names)
            if arch != "mlp"
            else None
        )
        self.net: EnsembleNet | HybridNet
        if arch == "hybrid":
            assert self.physics is not None
            self.net = HybridNet(
                features=features,
                n_members=n_members,
                generators=generators,
                coefficients=self.physics.coefficients,
                heating=prior.heating,
                cop_curve=cop_curve,
            )
        else:
            self.net = EnsembleNet(
                arch, features=features, n_members=n_members, generators=generators
            )


class LearnedModel:
    """A trained seed ensemble (eval mode), ready to predict and roll out.

    ``arch``, ``depth``, ``n_members``, ``exog_names`` describe it; ``meta`` holds the training
    record that :mod:`pinn_mpc.artifacts` stores in ``model.json``.
    """

    def __init__(
        self, *, arch: str, features: FeatureConfig, module: EnsembleModule, meta: dict[str, Any]
    ):
        self.arch = arch
        self.depth = features.depth
        self.n_members = module.n_members
        self.exog_names = features.exog_names
        self.features = features
        self.module = module.eval()
        self.meta = meta
        lo, hi = meta["u_phys_range_w"]
        p = features.power
        self._p_lo, self._p_hi = (lo - p.mean) / p.std, (hi - p.mean) / p.std
        t, dlt = features.temperature, features.delta_t_r
        self._dt_ratio, self._dt_offset = dlt.std / t.std, dlt.mean / t.std
        self._hybrid_cache: tuple[torch.Tensor, HybridConstants] | None = None

    @property
    def eta(self) -> float:
        """Heat per W of actuator power the model was trained with: > 0 heating, < 0 cooling."""
        return float(self.meta["eta"])

    @property
    def dt_s(self) -> float:
        """The control interval [s] the model predicts one step of."""
        return self.features.dt_s

    def _step(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
        """Scaled features (M, B, F) -> scaled (T_r,i+1, u_phys,i, T_m,i), each (M, B)."""
        obs, z = self.module.net(x)
        k = self.depth
        t_next = x[..., k] + obs[..., 0] * self._dt_ratio + self._dt_offset
        p = obs[..., 1].clamp(self._p_lo, self._p_hi)
        return t_next, p, z

    def _hybrid_constants(self, net: HybridNet) -> HybridConstants:
        """:meth:`HybridNet.rollout_constants`, kept while the weights stay the same (a
        decision rolls out several times; the matrix exponential and the observer are the
        cost). The weights are compared by value, so changing them in place is seen."""
        with torch.no_grad():
            weights = [t.reshape(-1) for t in (*self.module.parameters(), *self.module.buffers())]
            key = torch.cat(weights)
        cached = self._hybrid_cache
        if cached is None or not torch.equal(cached[0], key):
            cached = self._hybrid_cache = (key, net.rollout_constants())
        return cached[1]

    def _unscale_t(self, v: torch.Tensor) -> torch.Tensor:
        return v * self.features.temperature.std + self.features.temperature.mean

    def rollout_scaled(
        self,
        t_win: torch.Tensor,
        p_win: torch.Tensor,
        e_seq: torch.Tensor,
        u_s: torch.Tensor,
        tod: torch.Tensor,
    ) -> Rollout:
        """Batched recursive rollout in scaled units, N plans (or starts) of H steps.

        ``t_win``, ``p_win`` (N0, k+1) scaled T_r,i-k..T_r,i and u_phys,i-k-1..u_phys,i-1;
        ``e_seq`` (N0, n_series, k+H) scaled exogenous series from i-k to i+H-1; ``u_s`` (N, H)
        scaled demand; ``tod`` (N0, H, 2) encoded time of day. N0 is 1 or N.
        """
        f = self.features
        net = self.module.net
        if isinstance(net, HybridNet):
            t_r, p_w, t_m = net.rollout(
                self._hybrid_constants(net), (t_win, p_win, e_seq), u_s, tod, self.meta["u_phys_range_w"]
            )
            return Rollout(t_r_c=t_r, u_phys_w=p_w, t_m_c=t_m)
        m, k1 = self.n_members, self.depth + 1
        n, h_len = u_s.shape
        tp = torch.empty(m, k1 + h_len, 2, n)  # feature-major: see EnsembleNet.rollout_steps
        tp[:, :k1, 0] = t_win.T
        tp[:, :k1, 1] = p_win.T
        e_win = e_seq.unfold(-1, k1, 1)[..., :h_len, :]  # (N0, n_series, H, k+1)
        e_win = e_win.permute(0, 2, 1, 3).reshape(e_seq.shape[0], h_len, -1)
        z_out = torch.empty(m, h_len, n) if self.arch != "mlp" else None
        # Scaled outputs -> (T_r increment, u_phys): obs * scale + shift, then T_r,i added.
        scale = torch.tensor([[self._dt_ratio], [1.0]])
        shift = torch.tensor([[self._dt_offset], [0.0]])
        with torch.no_grad():
            step = net.rollout_steps(e_win, u_s, tod, self.depth)
            for h in range(h_len):
                obs, z = step(tp, h)
                row = tp.select(1, k1 + h)  # (M, 2, N) view
                torch.addcmul(shift, obs, scale, out=row)
                row.select(1, 0).add_(tp.select(1, k1 + h - 1).select(1, 0))
                row.select(1, 1).clamp_(self._p_lo, self._p_hi)
                if z_out is not None and z is not None:
                    z_out.select(1, h).copy_(z)
        out = tp[:, k1:].permute(0, 3, 1, 2).contiguous()  # (M, N, H, 2)
        return Rollout(
            t_r_c=self._unscale_t(out[..., 0]),
            u_phys_w=out[..., 1] * f.power.std + f.power.mean,
            t_m_c=self._unscale_t(z_out.transpose(1, 2)) if z_out is not None else None,
        )

    def rollout(
        self, history: dict[str, np.ndarray], u_w: torch.Tensor, exog: dict[str, np.ndarray]
    ) -> Rollout:
        """Roll N demand plans forward H intervals, recursively, for all M members at once.

        ``history``: ``T_r`` (>= depth+1,) measured up to and including now [C]; ``u_phys``
        (>= depth+1,) past delivered power [W] (last = previous interval); each exogenous
        series of ``exog_names`` but time of day (``T_a`` ...) (>= depth+1,) up to now.
        ``u_w`` (N, H) demanded power [W]. ``exog``: one array (>= H,) per name in
        ``exog_names`` for the next H intervals (``time_of_day_h`` at each interval start).
        Returns tensors (M, N, H): one batched forward per horizon step.
        """
        k1 = self.depth + 1
        f = self.features
        hist = {
            n: np.asarray(history[n], dtype=float)
            for n in ("T_r", "u_phys", *f.exog_series)
            if n in history
        }
        short = {n: len(hist.get(n, ())) for n in ("T_r", "u_phys", *f.exog_series)}
        short = {n: v for n, v in short.items() if v < k1}
        if short:
            raise InputError(
                f"rollout needs at least depth+1={k1} past values of T_r, u_phys and "
                f"{', '.join(f.exog_series)}; got {short}"
            )
        u_w = torch.as_tensor(u_w, dtype=torch.float32)
        if u_w.ndim != 2:
            raise InputError(f"rollout u_w must have shape (N, H), got {tuple(u_w.shape)}")
        h_len = u_w.shape[1]
        for name in self.exog_names:
            if name not in exog or np.shape(exog[name])[0] < h_len:
                raise InputError(f"rollout exog[{name!r}] must have at least H={h_len} values")
        t_win = (hist["T_r"][-k1:] - f.temperature.mean) / f.temperature.std
        p_win = (hist["u_phys"][-k1:] - f.power.mean) / f.power.std
        seq = {
            n: np.concatenate([hist[n][-k1:-1], np.asarray(exog[n], dtype=float)[:h_len]])
            for n in f.exog_series
        }
        return self.rollout_scaled(
            torch.as_tensor(t_win, dtype=torch.float32)[None],
            torch.as_tensor(p_win, dtype=torch.float32)[None],
            torch.from_numpy(f.scale_exog(seq))[None],
            (u_w - f.power.mean) / f.power.std,
            torch.from_numpy(f.encode_time(np.asarray(exog["time_of_day_h"])[:h_len]))[None],
        )

    def predict_one_step(self, df: pd.DataFrame) -> dict[str, Any]:
        """One-step predictions for every sample of a frame.

        Returns ``T_r_next`` (M, n) [C] (T_r,i+1), ``u_phys`` (M, n) [W] (u_phys,i), ``T_m``
        (M, n) [C] (T_m,i) or None for mlp, and ``row`` (n,) the row index i of each sample.
        """
        win = make_windows(df, self.features)
        x = torch.from_numpy(win.x).expand(self.n_members, -1, -1)
        with torch.no_grad():
            t_next, p, z = self._step(x)
        f = self.features
        return {
            "T_r_next": self._unscale_t(t_next).numpy().astype(float),
            "u_phys": (p * f.power.std + f.power.mean).numpy().astype(float),
            "T_m": self._unscale_t(z).numpy().astype(float) if z is not None else None,
            "row": win.rows,
        }

    def physics_coefficients(self) -> physics.Coefficients | None:
        """Learned coefficients (per second), geometric mean over members (``a11 = a12 + c13``,
        ``a22 = a21`` kept); None for mlp."""
        if self.module.physics is None:
            return None
        with torch.no_grad():
            coef = self.module.physics.coefficients()

        def mean(v: torch.Tensor) -> float:
            v = v.double()
            if torch.all(v > 0):
                return float(v.log().mean().exp())
            if torch.all(v < 0):
                return -float((-v).log().mean().exp())
            return float(v.mean())

        values = {
            name: mean(getattr(coef, name)) for name in physics.Coefficients.__dataclass_fields__
        }
        # Keep the structure of the 2R2C exact after averaging.
        values["a11"] = values["a12"] + values["c13"]
        values["a22"] = values["a21"]
        return physics.Coefficients(**values)

    def member_coefficients(self) -> list[dict[str, float]]:
        """Learned coefficients of each member, as dicts (empty for mlp)."""
        if self.module.physics is None:
            return []
        with torch.no_grad():
            coef = self.module.physics.coefficients()
        names = list(physics.Coefficients.__dataclass_fields__)
        return [{n: float(getattr(coef, n)[m]) for n in names} for m in range(self.n_members)]
