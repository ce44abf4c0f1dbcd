"""``pcnn-parx``: the physics-informed ARX made a physically consistent network.

Its linear part is :mod:`pinn_mpc.models.positive_arx`'s (the physics-informed ARX's
structure: lags of T_r, the power, T_a and the measured irradiance and gains, a schedule of
unmeasured gains by day type and block of the day, the indoor-outdoor difference weighted by
the time of day), fitted by least squares with every impulse response to a power and to an
outdoor temperature constrained non-negative; a network (:class:`~pinn_mpc.models.consistent.
UnforcedNet`) adds a heat input per interval from the time of day, the day type, the
irradiance, the gains and the wind, trained on 48-step rollouts with the linear part held.
With a heat pump (a ``cop`` column in the data) the linear part's power is the heat, the
electrical power times the data's COP at each interval's outdoor temperature, in the fit and in
every rollout (:mod:`pinn_mpc.models.consistent`).

Why every predicted T_r is non-decreasing in every power and outdoor temperature of the
horizon: the recursion is the linear part plus the network's term; the linear part's response
to each heat and outdoor temperature is non-negative (its module says how the fit makes it
so), each heat is non-decreasing in its power and, through a monotone COP, moves with its
outdoor temperature in the heat's direction, and the network's term depends on neither, nor on any temperature, so it is the same for
every plan and outdoor-temperature forecast. The delivered power it predicts is the demand,
clipped to the training data's range (non-decreasing in the demand). Rollouts longer than the
certified horizon (two weeks) are refused.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import nn

from pinn_mpc.actuator import CopCurve
from pinn_mpc.data import WIND
from pinn_mpc.errors import InputError, setting
from pinn_mpc.features import FeatureConfig
from pinn_mpc.models.base import NetParts, TrainingSet
from pinn_mpc.models.consistent import (
    ChunkInputs,
    ConsistentArchitecture,
    ConsistentNet,
    UnforcedNet,
)
from pinn_mpc.models.positive_arx import CERTIFIED_STEPS_S, RoomSettling, fit_positive_arx

if TYPE_CHECKING:
    import pandas as pd

    from pinn_mpc import physics
    from pinn_mpc.identify import IdentifyResult
    from pinn_mpc.models.learned import EnsembleModule
    from pinn_mpc.training import TrainConfig

__all__ = ["LAGS", "PcnnParx", "PcnnParxNet", "building_settling"]

#: Lags of the linear part (the ARX's): the architecture's depth must be at least this.
LAGS = 8


def building_settling(df: pd.DataFrame, eta: float) -> RoomSettling | None:
    """How the 2R2C identified from ``df`` settles (:func:`pinn_mpc.identify.identify_rc`, on
    the heat where ``df`` has a ``cop`` column): its slowest mode per interval and how much a
    day of one kW more heat warms its room (the exact discretisation); None where the
    identification fails.

    The positive ARX's one-step fit can put its room's own dynamics at a root near 1 that the
    data do not contradict (its held-out error hardly changes) but that the building does: on
    ``heat_pump_household``'s seed 2 (14 and 30 days) its slowest root is 0.9980 / 0.9967 per
    interval, the plant's 0.9943 (the identified RC's 0.9942 / 0.9935), and a day of 1 kW of
    heat warmed the room 1.80 K where it warms the plant 1.34 K (the identified RC 1.37 / 1.48).
    The grey-box RC, which fits the hidden mass explicitly, identifies both within a few
    percent there."""
    from pinn_mpc.identify import identify_rc
    from pinn_mpc.physics import discretise, time_constants_h

    try:
        identified = identify_rc(df, eta=eta, unmeasured_gains=False)
    except InputError:
        return None
    dt_s = float(df.attrs.get("dt_s", 1800.0))
    _, slow_h = time_constants_h(identified.params)
    ad, bd = discretise(identified.params, dt_s)
    x = np.zeros(2)
    for _ in range(round(86400.0 / dt_s)):
        x = ad @ x + bd[:, 0] * 1000.0
    return RoomSettling(pole=math.exp(-dt_s / (slow_h * 3600.0)), day_of_heat_k_per_kw=float(x[0]))


class PcnnParxNet(ConsistentNet):
    """The positive ARX (buffers, one copy per member) and the unforced network."""

    #: Buffers a model saved before them lacks, loaded as zeros (the term absent).
    ZERO_WHEN_ABSENT = ("wind_loss",)

    def __init__(
        self,
        *,
        features: FeatureConfig,
        n_members: int,
        generators: Sequence[torch.Generator],
        cop_curve: CopCurve | None,
        heating: bool,
    ):
        super().__init__()
        if features.depth < LAGS:
            raise InputError(f"pcnn-parx needs a history depth ({setting('depth')}) of at least {LAGS}, got {features.depth}")
        self.features = features
        self.set_cop(cop_curve, heating=heating)
        self.unforced = UnforcedNet(features, n_members, generators, 1)
        m, n_series = n_members, len(features.exog_series)
        self.a: torch.Tensor
        self.b: torch.Tensor
        self.w_exog: torch.Tensor
        self.q: torch.Tensor
        self.s: torch.Tensor
        self.wind_loss: torch.Tensor
        self.register_buffer("a", torch.zeros(m, LAGS))  # T_r,k-j [-]
        self.register_buffer("b", torch.zeros(m, LAGS))  # heat,k-j [K/W]
        self.register_buffer("w_exog", torch.zeros(m, n_series, LAGS))  # each series' lags
        self.register_buffer("q", torch.zeros(m, 24))  # T_r,k - T_a,k by hour of the day
        self.register_buffer("s", torch.zeros(m, 3, 24))  # schedule by day type, hour [K]
        # The wind's infiltration: its weight [1/(m/s)] and the room's mean temperature [C].
        self.register_buffer("wind_loss", torch.zeros(m, 2))

    def set_linear(self, df: pd.DataFrame, eta: float) -> None:
        """Fit the positive ARX on ``df`` (on the heat, with the COP curve; its room settling
        no slower than the RC identified from ``df``, :func:`building_settling`) and hold it in
        every member."""
        cop = None if self.cop_curve is None else self.cop_curve(df["T_a"].to_numpy(dtype=float))
        fit = fit_positive_arx(df, eta=eta, lags=LAGS, cop=cop, building=building_settling(df, eta))
        hours = (np.arange(24) // fit.block_h).astype(int)
        w = np.zeros((len(self.features.exog_series), LAGS))
        names = self.features.exog_series
        w[names.index("T_a")] = fit.c
        for i, name in enumerate(fit.inputs):
            w[names.index(name)] = fit.d[i]
        with torch.no_grad():
            for buf, value in (
                (self.a, fit.a), (self.b, fit.b), (self.w_exog, w), (self.q, fit.q[hours]),
                (self.s, fit.s[:, hours]), (self.wind_loss, np.array([fit.wind_loss, fit.t_ref])),
            ):
                buf.copy_(torch.as_tensor(value, dtype=buf.dtype).expand_as(buf))

    def roll(
        self, inputs: ChunkInputs, p_bounds_w: tuple[float, float]
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None, torch.Tensor]:
        f = self.features
        t_win, p_win, e_seq, u_s, tod = inputs
        k, h_len = f.depth, u_s.shape[-1]
        if h_len * f.dt_s > CERTIFIED_STEPS_S:
            raise InputError(
                f"pcnn-parx certifies its consistency over {CERTIFIED_STEPS_S / 86400:g} days; a "
                f"rollout of {h_len} steps is longer"
            )
        t, pw = f.temperature, f.power
        m = self.a.shape[0]
        lo, hi = p_bounds_w
        t_r = t_win * t.std + t.mean  # (M|1, N, k+1)
        plan = (u_s * pw.std + pw.mean).clamp(lo, hi)  # (M|1, N, H)
        past = p_win[..., -(LAGS - 1) :] * pw.std + pw.mean
        useq = torch.cat([past.expand(*plan.shape[:-1], -1), plan], dim=-1)
        scales = [f.exog[name] for name in f.exog_series]
        e_raw = torch.stack([e_seq[..., j, :] * sc.std + sc.mean for j, sc in enumerate(scales)], dim=-2)
        i_ta = f.exog_series.index("T_a")
        heat = self.heat(useq, e_raw[..., i_ta, k - LAGS + 1 : k + h_len])  # the powers' T_a
        u_lagged = heat.unfold(-1, LAGS, 1)  # (.., H, LAGS): heat_{k-LAGS+1} .. heat_k
        b = self.b.flip(-1)[:, None, None, :]  # (M, 1, 1, LAGS) oldest first
        drive = (u_lagged * b).sum(-1)  # (M, N, H)
        e_lagged = e_raw.unfold(-1, LAGS, 1)[..., k - LAGS + 1 : k - LAGS + 1 + h_len, :]  # (.., S, H, LAGS)
        w = self.w_exog.flip(-1)[:, None, :, None, :]  # (M, 1, S, 1, LAGS)
        drive = drive + (e_lagged * w).sum(-1).sum(-2)
        hour = torch.floor(tod[..., 5] * 24.0 + 1e-4).long().clamp(0, 23)  # (M|1, N, H)
        day = tod[..., 2:5].argmax(-1)
        q_k = torch.gather(self.q[:, None, None, :].expand(m, *hour.shape[1:], 24), -1, hour.expand(m, *hour.shape[1:])[..., None])[..., 0]
        s_k = self.s.reshape(m, 1, 1, 72).expand(m, *hour.shape[1:], 72)
        s_k = torch.gather(s_k, -1, (day * 24 + hour).expand(m, *hour.shape[1:])[..., None])[..., 0]
        t_a = e_raw[..., i_ta, k : k + h_len]
        unforced = self.unforced(e_seq, tod)  # (M, N0, H, 1)
        drive = drive + s_k - q_k * t_a + unforced[..., 0]
        if WIND in f.exog_series:  # its weight on T_a, wind x wind_loss, is never negative
            wind = e_raw[..., f.exog_series.index(WIND), k : k + h_len].clamp(min=0.0)
            g, t_ref = self.wind_loss[:, None, None, 0], self.wind_loss[:, None, None, 1]
            drive = drive + g * wind * (t_a - t_ref)
        hist = t_r[..., -LAGS:].flip(-1).expand(m, *drive.shape[1:-1], LAGS)  # T_r,k .. T_r,k-7
        a = self.a[:, None, :]  # (M, 1, LAGS)
        out = []
        for h in range(h_len):
            nxt = (hist * a).sum(-1) + q_k[..., h] * hist[..., 0] + drive[..., h]
            out.append(nxt)
            hist = torch.cat([nxt[..., None], hist[..., :-1]], dim=-1)
        t_pred = torch.stack(out, dim=-1)
        return t_pred, plan.expand_as(t_pred), None, unforced


class PcnnParx(ConsistentArchitecture):
    """The positive ARX with the unforced network (module docstring); no physics block."""

    has_physics = False

    def build_net(self, parts: NetParts) -> nn.Module:
        return PcnnParxNet(
            features=parts.features, n_members=parts.n_members, generators=parts.generators,
            cop_curve=parts.cop_curve, heating=parts.prior.heating,
        )

    def training_prior(
        self, config: TrainConfig, df: pd.DataFrame, identified: IdentifyResult | None
    ) -> physics.RCParams:
        return config.prior_params()

    def prepare(self, module: EnsembleModule, data: TrainingSet, config: TrainConfig) -> None:
        net = module.net
        assert isinstance(net, PcnnParxNet)
        net.set_linear(data.df, config.eta)
