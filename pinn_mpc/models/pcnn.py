"""``pcnn``: the paper's PhysNet made physically consistent (Di Natale et al., 2022).

As PhysNet, a learnable 2R2C ties the room's temperature to a hidden thermal-mass temperature
T_m. Unlike PhysNet, T_m at the start is not a network's estimate but the physics' own: the
hybrid's least-squares observer over the history window (:func:`~pinn_mpc.models.physics_block.
observe_t_m`: T_r up to now, the delivered power and weather of past intervals, given, not
planned or forecast); and no network sees the plan or the outdoor temperature:
the states step through the 2R2C's exact zero-order hold,

    (T_r, T_m)_k+1 = Ad (T_r, T_m)_k + Bd (heat_k, T_a,k, G_k, I_g,k) + n_k

with ``heat`` the demand (clipped to the training data's range), times the data's COP at the
interval's outdoor temperature where the data has one (a heat pump; :mod:`pinn_mpc.models.consistent`
says how the COP keeps the model consistent), times ``eta``'s sign, and ``n_k``
the unforced network's heat input per step on both states (:mod:`pinn_mpc.models.consistent`:
time of day, day type, irradiance, gains, wind).

Why every predicted T_r is non-decreasing in every heating power and outdoor temperature: the
2R2C's system matrix is Metzler (its off-diagonal entries 1/(C_r R_rm), 1/(C_m R_rm) are
positive, as the physics block keeps every R and C positive), so ``Ad = exp(A dt)`` is
element-wise non-negative, and ``Bd = int_0^dt exp(A s) ds B`` is non-negative in the columns
whose ``B`` column is (the outdoor temperature's ``(1/(C_r R_ra), 0)``, the gains'; the power's
``(eta/C_r, 0)`` for a heater, non-positive for a cooling machine). Each predicted state is
then a sum of non-negative multiples of the heats (times eta's sign; each heat non-decreasing
in its power and, through a monotone COP, moving with its outdoor temperature in the heat's
direction), the outdoor temperatures and terms of neither; the network's ``n_k`` and the observer's start depend on no plan and no
forecast outdoor temperature. The learned R and C are the model's (``export-rc``).

Why the observer and the anchor (``anchor_weight``: the physics block learns ten times slower
than the network, pulled back to the grey-box identification of the training data it starts
at, as the hybrid's): PhysNet's encoder sees a few hours of history of a building whose mass
settles over days, and a rollout loss can then trade the mass's capacity against the encoder's
start; the identification, which estimates the hidden mass with the whole record, pins that
mode. ``CHANGELOG.md`` has what the change measured on ``heat_pump_household``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import pandas as pd
import torch
from torch import nn

from pinn_mpc import physics
from pinn_mpc.actuator import CopCurve
from pinn_mpc.features import FeatureConfig
from pinn_mpc.models.base import NetParts
from pinn_mpc.models.consistent import (
    ChunkInputs,
    ConsistentArchitecture,
    ConsistentNet,
    UnforcedNet,
)
from pinn_mpc.models.physics_block import Physics, discretise_torch, observe_t_m

if TYPE_CHECKING:
    from pinn_mpc.identify import IdentifyResult
    from pinn_mpc.training import TrainConfig

__all__ = ["Pcnn", "PcnnNet"]


class PcnnNet(ConsistentNet):
    """The unforced network, the T_m observer and (owned by the module) the physics block."""

    def __init__(
        self,
        *,
        features: FeatureConfig,
        n_members: int,
        generators: Sequence[torch.Generator],
        block: Physics,
        cop_curve: CopCurve | None,
        heating: bool,
    ):
        super().__init__()
        self.features = features
        self.set_cop(cop_curve, heating=heating)
        self.coefficients = block.coefficients  # the block itself is the module's
        self.unforced = UnforcedNet(features, n_members, generators, 2)
        names = features.exog_series
        self._exog_pos = [names.index(n) if n in names else None for n in ("T_a", "G", "I_g")]

    def roll(
        self, inputs: ChunkInputs, p_bounds_w: tuple[float, float]
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None, torch.Tensor]:
        f = self.features
        t_win, p_win, e_seq, u_s, tod = inputs
        k, h_len = f.depth, u_s.shape[-1]
        t, pw = f.temperature, f.power
        lo, hi = p_bounds_w
        ad, bd = discretise_torch(self.coefficients(), f.dt_s)
        ad, bd = ad.float(), bd.float()  # (M, 2, 2), (M, 2, 4)
        m = ad.shape[0]
        scales = [f.exog[name] for name in f.exog_series]
        raw = [  # (T_a, G, I_g) of the window's k+1 intervals and the horizon's, zero where absent
            torch.zeros(()) if j is None else e_seq[..., j, : k + h_len] * scales[j].std + scales[j].mean
            for j in self._exog_pos
        ]
        t_r_win = t_win * t.std + t.mean  # (M|1, N, k+1)
        lead = t_r_win.shape[1:-1]
        # The window's k steps: the delivered power u_phys,i-k .. u_phys,i-1 and the weather
        # of their intervals (given, not planned or forecast).
        p_past = p_win[..., 1:] * pw.std + pw.mean
        past = [v[..., :k].expand(*p_past.shape) if v.ndim else v.expand(*p_past.shape) for v in raw]
        d_win = torch.stack([self.heat(p_past, past[0]), *past], dim=-1)  # (M|1, N, k, 4)
        t_m0 = observe_t_m(ad, bd, t_r_win.expand(m, *lead, -1), d_win.expand(m, *lead, k, 4))
        t_r0 = t_r_win[..., -1]
        plan = (u_s * pw.std + pw.mean).clamp(lo, hi)  # (M|1, N, H)
        raw = [v if not v.ndim else v[..., k:] for v in raw]
        unforced = self.unforced(e_seq, tod)  # (M, N0, H, 2) on (T_r, T_m)
        col = lambda i: bd[:, None, None, :, i]  # noqa: E731  (M, 1, 1, 2)
        drive = col(0) * self.heat(plan, raw[0])[..., None] + unforced  # raw[0]: T_a
        for i, v in enumerate(raw, start=1):
            drive = drive + col(i) * (v[..., None] if v.ndim else v)
        n = drive.shape[1]
        state = torch.stack([t_r0.expand(m, n), t_m0.expand(m, n)], dim=-1)  # (M, N, 2)
        a_t = ad.transpose(1, 2)[:, None]  # (M, 1, 2, 2): state @ Ad^T
        t_r_out, t_m_out = [], []
        for h in range(h_len):
            t_m_out.append(state[..., 1])
            state = (state[..., None, :] @ a_t)[..., 0, :] + drive[..., h, :]
            t_r_out.append(state[..., 0])
        t_pred = torch.stack(t_r_out, dim=-1)
        return t_pred, plan.expand_as(t_pred), torch.stack(t_m_out, dim=-1), unforced


class Pcnn(ConsistentArchitecture):
    """The consistent PhysNet (module docstring). Its physics block starts at the grey-box
    identification of the training data, learns ten times slower than the network and is
    anchored there (``anchor_weight``, as the hybrid's)."""

    physics_lr_factor = 0.1
    gain_schedule = True

    def build_net(self, parts: NetParts) -> nn.Module:
        assert parts.physics_block is not None
        return PcnnNet(
            features=parts.features, n_members=parts.n_members, generators=parts.generators,
            block=parts.physics_block, cop_curve=parts.cop_curve, heating=parts.prior.heating,
        )

    def training_prior(
        self, config: TrainConfig, df: pd.DataFrame, identified: IdentifyResult | None
    ) -> physics.RCParams:
        """The identification of ``df`` (its prior where it fails), unless ``config`` gives one."""
        if config.prior is None and identified is not None:
            return identified.params
        return config.prior_params()
