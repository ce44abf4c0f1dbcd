"""One batched rollout of many buildings' learned hybrid models (buildings x samples x horizon).

Each building of a fleet has its own trained :mod:`pinn_mpc.models.hybrid` ensemble (its own
weights, scaling and backup thermostat). :class:`FleetHybrid` stacks their rollout constants
(:meth:`pinn_mpc.models.hybrid.HybridNet.rollout_constants`) along the member axis, so that B
buildings x M members step through the horizon as the B*M members of one ensemble, through
the one recursion a single model's rollout runs (:func:`pinn_mpc.models.hybrid.roll_states`),
over B times the columns. What differs is only the preparation, batched over buildings here
and over start points in :meth:`HybridNet.rollout` (float round-off apart; tests compare the two
building by building): T_m observed once from each building's history window, the exogenous
terms of every step, then both states propagated through its 2R2C, the learned backup
saturating the demand, the residual net's bounded correction.

:class:`FleetDynamics` is what a fleet planner (:class:`controllers.fleet_sampling.FleetCEM`)
needs of such a model; :class:`FleetHybrid` declares it.

Histories are given raw (data-format units) per building, the plans (B, N, H) [W], the
exogenous forecast (H,) shared by the fleet (one weather). All models must be hybrids of one
depth, member count and exogenous inputs (:meth:`FleetHybrid.__init__` says which differs). ``members`` keeps each
ensemble's first members only: planning cost grows with buildings x members x samples, and
the compute of a horizon step is mostly the residual net's over all those columns.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import NamedTuple, Protocol, cast

import numpy as np
import torch

from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.models.hybrid import FewPlanWeights, HybridConstants, HybridNet, roll_states
from pinn_mpc.models.learned import LearnedModel
from pinn_mpc.models.rollout import Rollout

__all__ = ["FEW_PLANS", "FleetDynamics", "FleetHybrid", "FleetStart"]

#: Plans per building up to which a rollout's first layer adds the state's rows one by one
#: instead of a batched product (the members' disagreement along one plan, the offset replay).
FEW_PLANS = 4


class FleetStart(NamedTuple):
    """What a fleet rollout needs besides the plans, computed once per decision
    (:meth:`FleetHybrid.prepare`): the state now (B*M, 3, 1), the plan-free terms of every
    step (H, B*M, hidden+2, 1) and the heat per watt on both rows (H|1, B*M, 2, 1), as
    :func:`pinn_mpc.models.hybrid.roll_states` takes them."""

    state0: torch.Tensor
    pre: torch.Tensor
    b_step: torch.Tensor


class FleetDynamics(Protocol):
    """B buildings' models rolled out together: :meth:`prepare` once per decision (the
    plan-free part), then :meth:`roll` for any number of plans (B, N, H); :meth:`rollout` does
    both. Tensors of the :class:`Rollout` are (B, M, N, H)."""

    n_buildings: int
    n_members: int
    depth: int
    eta: float
    exog_names: tuple[str, ...]

    def prepare(
        self,
        histories: Sequence[Mapping[str, np.ndarray]],
        exog: Mapping[str, np.ndarray],
        h: int,
        *,
        drop_last: int = 0,
    ) -> FleetStart: ...

    def roll(self, start: FleetStart, u_w: torch.Tensor) -> Rollout: ...

    def rollout(
        self,
        histories: Sequence[Mapping[str, np.ndarray]],
        u_w: torch.Tensor,
        exog: Mapping[str, np.ndarray],
        *,
        drop_last: int = 0,
    ) -> Rollout: ...


class FleetHybrid(FleetDynamics):
    """B learned hybrids rolled out together (module docstring)."""

    def __init__(self, models: Sequence[LearnedModel], *, members: int | None = None) -> None:
        if not models:
            raise InputError("FleetHybrid needs at least one model")
        first = models[0]
        for i, model in enumerate(models):
            if not isinstance(model.module.net, HybridNet):
                raise InputError(
                    f"FleetHybrid: building {i}'s model is a {model.arch!r}; a fleet batch takes "
                    "the hybrid architecture (the default)"
                )
            same = (model.depth, model.n_members, model.exog_names, model.dt_s, model.eta > 0)
            want = (first.depth, first.n_members, first.exog_names, first.dt_s, first.eta > 0)
            if same != want:
                raise InputError(
                    f"FleetHybrid: building {i}'s model has (depth, members, inputs, dt_s, heating) "
                    f"{same}, building 0's {want}; train the fleet's models with one configuration"
                )
        if members is not None and not 1 <= members <= first.n_members:
            raise InputError(
                f"FleetHybrid.members must lie in 1..{first.n_members} (the models' members), got {members}"
            )
        self.models = tuple(models)
        self.nets = [cast(HybridNet, m.module.net) for m in models]
        self.depth = first.depth
        self.n_members = first.n_members if members is None else members
        self.exog_names, self.dt_s, self.eta = first.exog_names, first.dt_s, first.eta
        self.exog_series = first.features.exog_series
        with torch.no_grad():
            parts = [
                _members(cast(HybridConstants, mod.rollout_constants()), self.n_members) for mod in models
            ]
            self.constants = _stack(parts)
            b, m = len(models), self.n_members
            ranges = torch.tensor([mod.record.u_phys_range_w for mod in models], dtype=torch.float32)
            self.p_lo = ranges[:, 0].repeat_interleave(m)[:, None, None]  # (B*M, 1, 1)
            self.p_hi = ranges[:, 1].repeat_interleave(m)[:, None, None]
            self.n_buildings = b
            self._few = FewPlanWeights.of(self.constants)
        # Each building's scaling of its exogenous series (B, S, 1).
        self._exog_mean = np.array([[[mod.features.exog[n].mean] for n in self.exog_series] for mod in models])
        self._exog_std = np.array([[[mod.features.exog[n].std] for n in self.exog_series] for mod in models])

    def rollout(
        self,
        histories: Sequence[Mapping[str, np.ndarray]],
        u_w: torch.Tensor,
        exog: Mapping[str, np.ndarray],
        *,
        drop_last: int = 0,
    ) -> Rollout:
        """Roll every building's N plans ``u_w`` (B, N, H) [W] forward H intervals from its
        ``histories[b]`` (as :meth:`LearnedModel.rollout`: ``T_r``, ``u_phys`` and the
        exogenous series, at least depth+1 values each) under the fleet's forecast ``exog``
        (one array (>= H,) per name of ``exog_names``). ``drop_last``: start that many
        intervals before the histories' end (their last values unread). Returns tensors
        (B, M, N, H)."""
        u_w = torch.as_tensor(u_w, dtype=torch.float32)
        if u_w.ndim != 3:
            raise InternalError(f"FleetHybrid.rollout: u_w must be (B, N, H), got {tuple(u_w.shape)}")
        return self.roll(self.prepare(histories, exog, u_w.shape[2], drop_last=drop_last), u_w)

    def prepare(
        self,
        histories: Sequence[Mapping[str, np.ndarray]],
        exog: Mapping[str, np.ndarray],
        h: int,
        *,
        drop_last: int = 0,
    ) -> FleetStart:
        """The plan-free part of :meth:`rollout` over ``h`` intervals, once per decision;
        :meth:`roll` then takes any number of plans (B, N, h) from it."""
        b, k1 = self.n_buildings, self.depth + 1
        if len(histories) != b:
            raise InternalError(f"FleetHybrid: {len(histories)} histories for {b} buildings")
        if drop_last < 0:
            raise InternalError(f"FleetHybrid: drop_last must be >= 0, got {drop_last}")
        for name in self.exog_names:
            if name not in exog or np.shape(exog[name])[0] < h:
                raise InternalError(f"FleetHybrid: exog[{name!r}] must have at least H={h} values")
        series_names = ("T_r", "u_phys", *self.exog_series)
        raw = {n: _windows(histories, n, k1, drop_last) for n in series_names}
        future = {n: np.asarray(exog[n], dtype=float)[:h] for n in self.exog_series}
        # Raw exogenous series from i-k to i+H-1 (B, n_series, k+H), as the models see them.
        seq = np.stack(
            [np.concatenate([raw[n][:, :-1], np.broadcast_to(future[n], (b, h))], axis=1)
             for n in self.exog_series],
            axis=1,
        )
        return self._prepare(raw["T_r"], raw["u_phys"], seq, np.asarray(exog["time_of_day_h"])[:h])

    def _prepare(
        self, t_r_np: np.ndarray, p_np: np.ndarray, seq_np: np.ndarray, tod_h: np.ndarray
    ) -> FleetStart:
        c, nets = self.constants, self.nets
        b, m, k = self.n_buildings, self.n_members, self.depth
        h_len = len(tod_h)
        bm = b * m
        hidden = c.b_first.shape[1]
        with torch.no_grad():
            t_r = torch.as_tensor(t_r_np, dtype=torch.float32)  # (B, k+1)
            p_past = torch.as_tensor(p_np, dtype=torch.float32)
            seq = torch.as_tensor(seq_np, dtype=torch.float32)  # (B, S, k+H) raw
            exog = nets[0]._exog_raw(seq.transpose(0, 1))  # (B, k+H, 3)
            gains = [net.gain(exog[i, :, 0]) for i, net in enumerate(nets)]
            g = None if all(x is None for x in gains) else torch.stack(
                [torch.ones(exog.shape[1]) if x is None else x for x in gains]
            )  # (B, k+H) heat per electrical watt
            heat_win = p_past[:, 1:] if g is None else p_past[:, 1:] * g[:, :k]
            d_win = torch.cat([heat_win[..., None], exog[:, :k]], dim=-1)  # (B, k, 4)
            window = torch.cat([t_r, d_win.flatten(-2)], dim=-1)  # (B, k+1+4k)
            state0 = torch.empty(bm, 3, 1)
            state0[:, 0] = p_past[:, k].repeat_interleave(m)[:, None]
            t_m0 = torch.einsum("bw,bmw->bm", window, c.observer.view(b, m, -1))
            state0[:, 1] = t_m0.reshape(bm)[:, None]
            state0[:, 2] = t_r[:, k].repeat_interleave(m)[:, None]
            drive_b = c.drive_b.view(b, m, 2, 4)
            drive = torch.einsum("bmrc,bhc->hbmr", drive_b[..., 1:], exog[:, k : k + h_len])
            # The residual net's first layer on the scaled exogenous inputs now and time of day.
            scaled = torch.as_tensor(
                ((seq_np - self._exog_mean) / self._exog_std).astype(np.float32)
            )  # (B, S, k+H), as FeatureConfig.scale_exog
            tod = torch.as_tensor(self.models[0].features.encode_time(tod_h))  # (H, 2)
            static = torch.cat(
                [scaled[:, :, k : k + h_len].transpose(1, 2), tod[None].expand(b, -1, -1)], dim=-1
            )  # (B, H, S+2)
            w_static = c.w_static.view(b, m, *c.w_static.shape[1:])
            first = torch.einsum("bmsj,bhs->hbmj", w_static, static)  # (H, B, M, out)
            pre = torch.cat([first, drive], dim=-1).reshape(h_len, bm, hidden + 2, 1)
            pre[:, :, :hidden] += c.b_first
            b_u = c.drive_b[..., :1]  # (B*M, 2, 1)
            if g is None:
                b_step = b_u[None]
            else:
                b_step = b_u[None] * g[:, k : k + h_len].T.repeat_interleave(m, dim=1)[:, :, None, None]
            return FleetStart(state0=state0, pre=pre, b_step=b_step)

    def roll(self, start: FleetStart, u_w: torch.Tensor) -> Rollout:
        """Every building's N plans ``u_w`` (B, N, H) [W] from ``start``; tensors (B, M, N, H)."""
        c = self.constants
        b, m = self.n_buildings, self.n_members
        u_w = torch.as_tensor(u_w, dtype=torch.float32)
        h_len = start.pre.shape[0]
        if u_w.ndim != 3 or u_w.shape[0] != b or u_w.shape[2] != h_len:
            raise InternalError(f"FleetHybrid.roll: u_w must be (B={b}, N, H={h_len}), got {tuple(u_w.shape)}")
        n = u_w.shape[1]
        with torch.no_grad():
            u_steps = u_w.permute(2, 0, 1).repeat_interleave(m, dim=1)[:, :, None]  # (H, B*M, 1, N)
            states = roll_states(
                c, start.state0, start.pre, start.b_step, u_steps, (self.p_lo, self.p_hi),
                few=self._few if n <= FEW_PLANS else None,
            )
            series = states.permute(1, 2, 3, 0).reshape(b, m, 3, n, h_len + 1)
            return Rollout(
                t_r_c=series[:, :, 2, :, 1:].contiguous(),
                u_phys_w=series[:, :, 0, :, 1:].contiguous(),
                t_m_c=series[:, :, 1, :, :-1].contiguous(),
            )


def _windows(histories: Sequence[Mapping[str, np.ndarray]], name: str, k1: int, drop: int) -> np.ndarray:
    """(B, k1) the last ``k1`` values of series ``name`` of every history but its last ``drop``
    ones (one array when the histories are of one length, as a fleet's are)."""
    values = [np.asarray(hist[name], dtype=float) for hist in histories]
    lengths = {len(v) for v in values}
    for i, v in enumerate(values):
        if len(v) < k1 + drop:
            raise InternalError(
                f"FleetHybrid: building {i} has {len(v)} past values of {name}, the models need "
                f"depth+1={k1}{f' before its last {drop}' if drop else ''}"
            )
    if len(lengths) == 1:
        n = lengths.pop()
        return np.stack(values)[:, n - drop - k1 : n - drop]
    return np.stack([v[len(v) - drop - k1 : len(v) - drop] for v in values])


def _members(c: HybridConstants, m: int) -> HybridConstants:
    """The first ``m`` members' constants."""
    fields = {name: getattr(c, name)[:m] for name in HybridConstants._fields if name != "middle"}
    return HybridConstants(middle=[(w[:m], b[:m]) for w, b in c.middle], **fields)


def _stack(parts: Sequence[HybridConstants]) -> HybridConstants:
    """The constants of B models as those of one ensemble of B*M members."""
    cat = lambda name: torch.cat([getattr(p, name) for p in parts])  # noqa: E731
    middle = [
        (torch.cat([p.middle[j][0] for p in parts]), torch.cat([p.middle[j][1] for p in parts]))
        for j in range(len(parts[0].middle))
    ]
    fields = {name: cat(name) for name in HybridConstants._fields if name != "middle"}
    return HybridConstants(middle=middle, **fields)
