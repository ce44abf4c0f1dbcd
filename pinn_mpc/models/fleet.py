"""Many buildings' planner models rolled out together (buildings x members x plans x horizon).

A fleet planner (:class:`controllers.fleet_sampling.FleetCEM`) rolls every building's plans out
at once. :class:`FleetModels` is the fleet of any planner models, one
:class:`~pinn_mpc.models.rollout.BatchDynamics` per building (a hybrid, PhysNet, an ARX, the
2R2C, a plug-in), as a vectorised map of their own rollouts: the buildings whose models share
a stack key (:attr:`BatchDynamics.stack_key`) roll out as one batch
(:meth:`BatchDynamics.stacked`), every other building through its model's own
:meth:`~BatchDynamics.rollout`. A kind that declares no stack key is thus a fleet's without
doing anything; one that does is as fast as one batch. A fleet of one building is its model,
bit for bit: the one-building case the single controllers' offset filter runs
(:class:`controllers.estimators.OffsetFilter`).

:class:`StackedHybrids` is the hybrids' batch: their rollout constants
(:meth:`pinn_mpc.models.hybrid.HybridNet.rollout_constants`) stacked along the member axis, so
that B buildings x M members step through the horizon as the B*M members of one ensemble,
prepared by the one preparation (:func:`pinn_mpc.models.hybrid.prepare_states`) and stepped by
the one recursion (:func:`pinn_mpc.models.hybrid.roll_states`) a single hybrid's rollout runs,
B at a time; only the windows come raw from the histories here where a single model takes
them scaled (float round-off apart; tests compare the two building by building).

Histories are given raw (data-format units) per building, the plans (B, N, H) [W], the
exogenous forecast (H,) shared by the fleet (one weather). ``members`` keeps each model's first
members only: planning cost grows with buildings x members x samples.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple, cast

import numpy as np
import torch

from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.models.hybrid import (
    FewPlanWeights,
    HybridConstants,
    HybridNet,
    HybridStart,
    prepare_states,
    roll_states,
)
from pinn_mpc.models.learned import LearnedModel
from pinn_mpc.models.rollout import BatchDynamics, Exogenous, Histories, Rollout, StackedDynamics

__all__ = ["FEW_PLANS", "FleetModels", "FleetStart", "StackedHybrids"]

#: Plans per building up to which a hybrids' rollout adds the state's rows of the first layer
#: one by one instead of a batched product (the members' disagreement along one plan, the
#: offset replay).
FEW_PLANS = 4


class FleetStart(NamedTuple):
    """What a fleet rollout needs besides the plans, computed once per decision
    (:meth:`FleetModels.prepare`): each part's start, in the order of the parts."""

    parts: tuple[object, ...]


class _Alone(StackedDynamics):
    """One building whose model rolls out on its own: its :meth:`BatchDynamics.rollout`."""

    def __init__(self, model: BatchDynamics, members: int) -> None:
        self.model, self.members = model, members

    def prepare(self, histories: Histories, exog: Exogenous, h: int, *, drop_last: int = 0) -> object:
        (history,) = histories
        end = {name: len(values) - drop_last for name, values in history.items()}
        return (
            {name: np.asarray(values)[: end[name]] for name, values in history.items()},
            {name: np.asarray(exog[name])[:h] for name in self.model.exog_names},
        )

    def roll(self, start: object, u_w: torch.Tensor) -> Rollout:
        history, exog = cast(tuple[dict[str, np.ndarray], dict[str, np.ndarray]], start)
        with torch.no_grad():
            r = self.model.rollout(history, u_w[0], exog)
        m = self.members
        return Rollout(r.t_r_c[None, :m], r.u_phys_w[None, :m], None if r.t_m_c is None else r.t_m_c[None, :m])


class FleetModels:
    """B buildings' planner models rolled out together (module docstring): any kinds, one
    interval, heating or cooling alike; ``members`` (default: the smallest ensemble's)
    each model's first members."""

    def __init__(self, models: Sequence[BatchDynamics], *, members: int | None = None) -> None:
        if not models:
            raise ValueError("FleetModels needs at least one model")
        first = models[0]
        for i, model in enumerate(models):
            if (model.dt_s, model.eta > 0) != (first.dt_s, first.eta > 0):
                raise InputError(
                    f"FleetModels: building {i}'s model has (dt_s, heating) {(model.dt_s, model.eta > 0)}, "
                    f"building 0's {(first.dt_s, first.eta > 0)}; a fleet's models step one interval "
                    "and act one way"
                )
        fewest = min(model.n_members for model in models)
        if members is not None and not 1 <= members <= fewest:
            raise ValueError(f"FleetModels.members must lie in 1..{fewest} (the models' members), got {members}")
        self.models = tuple(models)
        self.n_buildings, self.n_members = len(models), fewest if members is None else members
        self.depth = max(model.depth for model in models)
        self.dt_s, self.eta = first.dt_s, first.eta
        self.exog_names = tuple(dict.fromkeys(name for model in models for name in model.exog_names))
        groups: dict[object, list[int]] = {}
        parts: list[tuple[torch.Tensor, StackedDynamics]] = []
        for i, model in enumerate(models):
            key = model.stack_key
            if key is None:
                parts.append((torch.tensor([i]), _Alone(model, self.n_members)))
            else:
                groups.setdefault(key, []).append(i)
        for index in groups.values():  # one building alone rolls out as its model does
            stacked = (
                models[index[0]].stacked([models[i] for i in index], self.n_members) if len(index) > 1
                else _Alone(models[index[0]], self.n_members)
            )
            parts.append((torch.tensor(index), stacked))
        self._parts = sorted(parts, key=lambda part: int(part[0][0]))
        self._whole = len(parts) == 1  # one batch of every building, in order

    def rollout(self, histories: Histories, u_w: torch.Tensor, exog: Exogenous, *, drop_last: int = 0) -> Rollout:
        """Roll every building's N plans ``u_w`` (B, N, H) [W] forward H intervals from its
        ``histories[b]`` (as its model's :meth:`BatchDynamics.rollout` takes it: ``T_r``,
        ``u_phys`` and the exogenous series, at least depth+1 values each) under the fleet's
        forecast ``exog`` (one array (>= H,) per name of ``exog_names``). ``drop_last``: start
        that many intervals before the histories' end (their last values unread). Returns
        tensors (B, M, N, H, Z) (the power (B, M, N, H))."""
        u_w = torch.as_tensor(u_w, dtype=torch.float32)
        if u_w.ndim != 3:
            raise InternalError(f"FleetModels.rollout: u_w must be (B, N, H), got {tuple(u_w.shape)}")
        return self.roll(self.prepare(histories, exog, u_w.shape[2], drop_last=drop_last), u_w)

    def prepare(self, histories: Histories, exog: Exogenous, h: int, *, drop_last: int = 0) -> FleetStart:
        """The plan-free part of :meth:`rollout` over ``h`` intervals, once per decision;
        :meth:`roll` then takes any number of plans (B, N, h) from it."""
        if len(histories) != self.n_buildings:
            raise InternalError(f"FleetModels: {len(histories)} histories for {self.n_buildings} buildings")
        if drop_last < 0:
            raise InternalError(f"FleetModels: drop_last must be >= 0, got {drop_last}")
        for name in self.exog_names:
            if name not in exog or np.shape(exog[name])[0] < h:
                raise InternalError(f"FleetModels: exog[{name!r}] must have at least H={h} values")
        return FleetStart(tuple(
            part.prepare(histories if self._whole else [histories[int(i)] for i in index], exog, h,
                         drop_last=drop_last)
            for index, part in self._parts
        ))

    def roll(self, start: FleetStart, u_w: torch.Tensor) -> Rollout:
        """Every building's N plans ``u_w`` (B, N, H) [W] from ``start``; tensors (B, M, N, H, Z)
        (the power (B, M, N, H))."""
        u_w = torch.as_tensor(u_w, dtype=torch.float32)
        if u_w.ndim != 3 or u_w.shape[0] != self.n_buildings:
            raise InternalError(f"FleetModels.roll: u_w must be (B={self.n_buildings}, N, H), got {tuple(u_w.shape)}")
        if self._whole:
            return self._parts[0][1].roll(start.parts[0], u_w)
        rolls = [part.roll(s, u_w[index]) for (index, part), s in zip(self._parts, start.parts, strict=True)]
        t_m = [r.t_m_c for r in rolls]
        return Rollout(
            t_r_c=self._joined([r.t_r_c for r in rolls]),
            u_phys_w=self._joined([r.u_phys_w for r in rolls]),
            t_m_c=None if any(t is None for t in t_m) else self._joined([cast(torch.Tensor, t) for t in t_m]),
        )

    def _joined(self, tensors: list[torch.Tensor]) -> torch.Tensor:
        """The parts' tensors (G_p, M, N, H, ...) in building order, (B, M, N, H, ...)."""
        dtype = tensors[0].dtype
        for t in tensors[1:]:
            dtype = torch.promote_types(dtype, t.dtype)
        out = torch.empty((self.n_buildings, *tensors[0].shape[1:]), dtype=dtype)
        for (index, _), t in zip(self._parts, tensors, strict=True):
            out[index] = t.to(dtype)
        return out


class StackedHybrids(StackedDynamics):
    """G learned hybrids of one stack key rolled out together (module docstring)."""

    def __init__(self, models: Sequence[LearnedModel], *, members: int) -> None:
        self.models = tuple(models)
        self.nets = [cast(HybridNet, m.module.net) for m in models]
        self.depth = models[0].depth
        self.n_members = members
        self.exog_series = models[0].features.exog_series
        with torch.no_grad():
            parts = [_members(cast(HybridConstants, mod.rollout_constants()), members) for mod in models]
            self.constants = _stack(parts)
            ranges = torch.tensor([mod.record.u_phys_range_w for mod in models], dtype=torch.float32)
            self.p_lo = ranges[:, 0].repeat_interleave(members)[:, None, None]  # (G*M, 1, 1)
            self.p_hi = ranges[:, 1].repeat_interleave(members)[:, None, None]
            self._few = FewPlanWeights.of(self.constants)
        # Each building's scaling of its exogenous series (G, S, 1).
        self._exog_mean = np.array([[[mod.features.exog[n].mean] for n in self.exog_series] for mod in models])
        self._exog_std = np.array([[[mod.features.exog[n].std] for n in self.exog_series] for mod in models])

    def prepare(self, histories: Histories, exog: Exogenous, h: int, *, drop_last: int = 0) -> object:
        """:func:`pinn_mpc.models.hybrid.prepare_states` of every building from its raw window."""
        g, k1 = len(self.models), self.depth + 1
        raw = {n: _windows(histories, n, k1, drop_last) for n in ("T_r", "u_phys", *self.exog_series)}
        future = {n: np.asarray(exog[n], dtype=float)[:h] for n in self.exog_series}
        # Raw exogenous series from i-k to i+H-1 (G, n_series, k+H), as the models see them.
        seq_np = np.stack(
            [np.concatenate([raw[n][:, :-1], np.broadcast_to(future[n], (g, h))], axis=1)
             for n in self.exog_series],
            axis=1,
        )
        with torch.no_grad():
            seq = torch.as_tensor(seq_np, dtype=torch.float32)
            exog_c = self.nets[0]._exog_raw(seq.transpose(0, 1))  # (G, k+H, 3)
            gains = [net.gain(exog_c[i, :, 0]) for i, net in enumerate(self.nets)]
            gain = None if all(x is None for x in gains) else torch.stack(
                [torch.ones(exog_c.shape[1]) if x is None else x for x in gains]
            )  # (G, k+H) heat per electrical watt
            # The scaled exogenous inputs now (as FeatureConfig.scale_exog) and time of day.
            scaled = torch.as_tensor(((seq_np - self._exog_mean) / self._exog_std).astype(np.float32))
            tod = torch.as_tensor(self.models[0].features.encode_time(np.asarray(exog["time_of_day_h"])[:h]))
            static = torch.cat(
                [scaled[:, :, k1 - 1 : k1 - 1 + h].transpose(1, 2), tod[None].expand(g, -1, -1)], dim=-1
            )  # (G, H, S+2)
            return prepare_states(
                self.constants,
                torch.as_tensor(raw["T_r"], dtype=torch.float32)[:, None],
                torch.as_tensor(raw["u_phys"], dtype=torch.float32)[:, None],
                exog_c[:, None],
                static[:, None],
                None if gain is None else gain[:, None],
            )

    def roll(self, start: object, u_w: torch.Tensor) -> Rollout:
        """Every building's N plans ``u_w`` (G, N, H) [W] from ``start``; tensors (G, M, N, H, 1)
        (the power (G, M, N, H))."""
        if not isinstance(start, HybridStart):
            raise InternalError(f"StackedHybrids.roll: a start of prepare(), got {type(start).__name__}")
        g, m = len(self.models), self.n_members
        h_len = start.pre.shape[0]
        if u_w.ndim != 3 or u_w.shape[0] != g or u_w.shape[2] != h_len:
            raise InternalError(f"StackedHybrids.roll: u_w must be (G={g}, N, H={h_len}), got {tuple(u_w.shape)}")
        n = u_w.shape[1]
        with torch.no_grad():
            u_steps = u_w.permute(2, 0, 1).repeat_interleave(m, dim=1)[:, :, None]  # (H, G*M, 1, N)
            states = roll_states(
                self.constants, *start, u_steps, (self.p_lo, self.p_hi),
                few=self._few if n <= FEW_PLANS else None,
            )
            series = states.permute(1, 2, 3, 0).reshape(g, m, 3, n, h_len + 1)
            return Rollout.of_one_zone(
                series[:, :, 2, :, 1:].contiguous(),
                series[:, :, 0, :, 1:].contiguous(),
                series[:, :, 1, :, :-1].contiguous(),
            )


def _windows(histories: Histories, name: str, k1: int, drop: int) -> np.ndarray:
    """(G, k1) the last ``k1`` values of series ``name`` of every history but its last ``drop``
    ones (one array when the histories are of one length, as a fleet's are)."""
    values = [np.asarray(hist[name], dtype=float) for hist in histories]
    lengths = {len(v) for v in values}
    for i, v in enumerate(values):
        if len(v) < k1 + drop:
            raise InternalError(
                f"StackedHybrids: building {i} has {len(v)} past values of {name}, the models need "
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
    """The constants of G models as those of one ensemble of G*M members."""
    cat = lambda name: torch.cat([getattr(p, name) for p in parts])  # noqa: E731
    middle = [
        (torch.cat([p.middle[j][0] for p in parts]), torch.cat([p.middle[j][1] for p in parts]))
        for j in range(len(parts[0].middle))
    ]
    fields = {name: cat(name) for name in HybridConstants._fields if name != "middle"}
    return HybridConstants(middle=middle, **fields)
