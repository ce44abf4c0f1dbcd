"""The learnable 2R2C block and the physics residuals of the training loss.

:class:`Physics` holds learnable 2R2C coefficients per member, positive quantities in log space
with ``a11 = a12 + c13`` and ``a22 = a21`` by construction and ``b`` keeping the sign of
``eta``. Two physics residuals:

- :func:`residual_finite_difference`: the paper's Eq. est_Tm (T_r row, forward difference).
- :func:`residual_exact`: both rows of the exactly (ZOH) discretised 2R2C, built from
  :func:`pinn_mpc.physics.state_space_entries`; the T_m row links T_m,i to T_m,i+1 of the next
  sample, which makes C_m identifiable. The default.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import torch
from torch import nn

from pinn_mpc import physics

__all__ = [
    "Physics",
    "discretise_torch",
    "interp_clamped",
    "observe_t_m",
    "residual_exact",
    "residual_finite_difference",
]

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


def observe_t_m(ad: torch.Tensor, bd: torch.Tensor, t_r: torch.Tensor, d: torch.Tensor) -> torch.Tensor:
    """The hidden T_m at the end of a history window [C], from the 2R2C's exact ZOH ``ad`` (M,
    2, 2), ``bd`` (M, 2, 4): ``t_r`` (M|1, B, k+1) the measured T_r of the window, ``d`` (M|1,
    B, k, 4) the inputs (heat, T_a, G, I_g) of its k steps. With the measured T_r in the T_m
    row, T_m,j = Ad11^j s + c_j is affine in the unknown T_m at the window's start s, and each
    step gives one equation of the T_r row; s is their least-squares solution (closed form,
    differentiable), propagated to the window's end. Returns (M, B)."""
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


def interp_clamped(x: torch.Tensor, knots: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    """Piecewise-linear interpolation of ``values`` at increasing ``knots`` (K,), constant
    beyond the end knots (as :func:`numpy.interp`); ``x`` any shape."""
    xc = x.clamp(float(knots[0]), float(knots[-1]))
    j = torch.searchsorted(knots, xc.detach().contiguous()).clamp(1, len(knots) - 1)
    x0, x1 = knots[j - 1], knots[j]
    w = (xc - x0) / (x1 - x0)
    return values[j - 1] + w * (values[j] - values[j - 1])


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
