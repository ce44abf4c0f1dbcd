"""A building of several zones controlled as one merged zone: the one-zone control the package
had before zones, run on the zoned building so the two can be compared on the same KPIs.

:class:`MergedView` is how such a controller sees the building: one room temperature, the
zones' floor-area-weighted mean (``shares``, one per zone, summing to 1), one heater whose
bounds are the sums of the zones' heaters' and, with ``cooling``, one chiller whose bounds are
the sums of the zones' chillers'. Each zone's comfort band is merged into the band of the
mean (the same shares' mean of the bounds; the zones' common band where they share one). In
the one-actuator view (``cooling`` False, the one-zone planners' building) the merged heater's
power in the history and in a training frame is the zones' net heat over the heater's gain:
the heaters' heat minus what the chillers (the backup's, or those of the data) took out, so
a one-zone model fitted on the merged frame sees every watt of heat that reached the zones.
In the two-actuator view each merged actuator's power is the sum of its kind's.

A decision of one power per merged actuator is split over the zones' actuators of its kind
by :func:`split_by_share`: in proportion to each one's zone's share, what an actuator's bound
refuses going to the others in proportion to theirs, so the split sums to the planned power
and every actuator stays within its bounds. In the one-actuator view the chillers stay at
their lower bound (the merged control has no chiller).

:class:`MergedZones` wraps a controller of the merged view (a one-zone planner over a
one-zone model or RC of the merged data) into a controller of the building.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from controllers.base import Controller, ControlSpec, Forecast, Observation, SolveStats
from pinn_mpc.actuator import ActuatorSpec, actuator_columns
from pinn_mpc.zones import ONE_ZONE, ZONE_SERIES, parse_zone_column, zone_columns

if TYPE_CHECKING:
    import pandas as pd

    from pinn_mpc.models.rollout import BatchDynamics
    from pinn_mpc.records import TrustReport

__all__ = ["MergedView", "MergedZones", "split_by_share"]

#: The merged actuators' names in the two-actuator view (the data's ``u[heat]``, ``u[cool]``).
HEAT, COOL = "heat", "cool"


def split_by_share(
    total_w: float, weights: np.ndarray, lower_w: np.ndarray, upper_w: np.ndarray
) -> np.ndarray:
    """(N,) powers [W] that sum to ``total_w`` [W], each within its bounds ``lower_w`` (N,),
    ``upper_w`` (N,) [W], proportional to ``weights`` (N,, > 0) where no bound binds: each
    actuator gets ``clip(weight x level, lower, upper)`` at the one level that makes them sum to
    ``total_w`` (exact: the sum is piecewise linear in the level, between the bounds'
    breakpoints). ``total_w`` beyond the bounds' sums is a ValueError."""
    w = np.asarray(weights, dtype=float)
    lo, hi = np.asarray(lower_w, dtype=float), np.asarray(upper_w, dtype=float)
    if not (w.shape == lo.shape == hi.shape and w.ndim == 1 and w.size > 0):
        raise ValueError(
            f"split_by_share: weights, lower_w and upper_w must be (N,) arrays of one length, got "
            f"shapes {w.shape}, {lo.shape}, {hi.shape}"
        )
    if not (np.all(np.isfinite(w)) and np.all(w > 0)):
        raise ValueError(f"split_by_share: weights must be finite and > 0, got {w.tolist()}")
    low, high = float(lo.sum()), float(hi.sum())
    tolerance = 1e-9 * max(1.0, abs(high))
    if not (math.isfinite(total_w) and low - tolerance <= total_w <= high + tolerance):
        raise ValueError(
            f"split_by_share: total_w = {total_w!r} W lies outside the actuators' bounds' sums "
            f"[{low:g}, {high:g}] W; clip the planned power to them first"
        )
    total = min(max(total_w, low), high)
    levels = np.unique(np.concatenate([lo / w, hi / w]))  # where an actuator meets a bound

    def summed(level: float) -> float:
        return float(np.clip(w * level, lo, hi).sum())

    sums = np.array([summed(level) for level in levels])  # non-decreasing in the level
    i = int(np.searchsorted(sums, total))  # the first breakpoint whose sum reaches the total
    if i == 0:
        return lo.copy()
    a, b = levels[i - 1], levels[min(i, len(levels) - 1)]
    rise = sums[min(i, len(levels) - 1)] - sums[i - 1]
    level = b if rise <= 0 else a + (total - sums[i - 1]) / rise * (b - a)
    split = np.clip(w * level, lo, hi)
    # the sum is linear between the breakpoints: what rounding left goes to an unbound actuator
    free = np.flatnonzero((split > lo) & (split < hi))
    if free.size:
        split[free[0]] += total - split.sum()
    return split


@dataclass(frozen=True, kw_only=True)
class MergedView:
    """The building ``spec`` (several zones, a heater in one or more of them) seen as one zone
    (module docstring): ``shares`` (Z,) each zone's share of the floor area (> 0, summing to 1
    within 1e-6; a zone's floor area over the building's), ``cooling`` whether the merged
    building also has one chiller (the building needs chillers then, of one efficiency)."""

    spec: ControlSpec
    shares: tuple[float, ...]
    cooling: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.spec, ControlSpec):
            raise TypeError(f"MergedView.spec must be the building's ControlSpec, got {type(self.spec).__name__}")
        shares = tuple(float(s) for s in self.shares)
        n_zones = len(self.spec.zones)
        if len(shares) != n_zones or not all(math.isfinite(s) and s > 0 for s in shares):
            raise ValueError(
                f"MergedView.shares = {list(shares)}: give one floor-area share > 0 per zone "
                f"({n_zones}: {', '.join(z.name for z in self.spec.zones)})"
            )
        if abs(sum(shares) - 1.0) > 1e-6:
            raise ValueError(
                f"MergedView.shares sum to {sum(shares):.6g}; give each zone's floor area over the "
                "building's (they sum to 1)"
            )
        object.__setattr__(self, "shares", shares)
        if not self.heaters:
            raise ValueError("MergedView.spec: the building has no heater; the merged view plans one")
        if self.cooling and not self.coolers:
            raise ValueError("MergedView.cooling = True, but the building has no chiller; give cooling = False")
        for kind, members in zip((HEAT, COOL), self._members(), strict=False):
            efficiencies = {self.spec.actuators[i].efficiency for i in members}
            if len(efficiencies) > 1:
                raise ValueError(
                    f"MergedView.spec: the building's {kind}ing actuators have {len(efficiencies)} "
                    "different efficiencies; a merged actuator has one (give them one, or plan the zones)"
                )

    @property
    def heaters(self) -> tuple[int, ...]:
        """The building's heaters' indices in ``spec.actuators``."""
        return tuple(i for i, a in enumerate(self.spec.actuators) if a.heats)

    @property
    def coolers(self) -> tuple[int, ...]:
        """The building's chillers' indices in ``spec.actuators``."""
        return tuple(i for i, a in enumerate(self.spec.actuators) if not a.heats)

    def _members(self) -> tuple[tuple[int, ...], ...]:
        """Each merged actuator's members: the heaters, then (``cooling``) the chillers."""
        return (self.heaters, self.coolers) if self.cooling else (self.heaters,)

    @property
    def one_zone_spec(self) -> ControlSpec:
        """The merged building's control spec: one zone, one heater (``cooling``: and one
        chiller, named ``heat`` and ``cool``), each with its kind's summed bounds and
        efficiency; the building's interval, horizon, comfort weight and sensor noise."""
        actuators = []
        for members in self._members():
            first = self.spec.actuators[members[0]]
            actuators.append(ActuatorSpec(
                upper_w=sum(self.spec.actuators[i].upper_w for i in members),
                lower_w=sum(self.spec.actuators[i].lower_w for i in members),
                heats=first.heats, efficiency=first.efficiency,
                name=(HEAT if first.heats else COOL) if self.cooling else "",
            ))
        s = self.spec
        return ControlSpec(
            actuators=tuple(actuators), zones=ONE_ZONE, dt_s=s.dt_s, horizon_steps=s.horizon_steps,
            comfort_weight_eur_per_kh=s.comfort_weight_eur_per_kh, sensor_noise_std_c=s.sensor_noise_std_c,
        )

    def mean_c(self, zones_c: np.ndarray) -> np.ndarray:
        """(...,) the floor-area-weighted mean over the last axis of (..., Z) zone values [C]."""
        return np.asarray(zones_c, dtype=float) @ np.asarray(self.shares)

    def split(self, power_w: float | np.ndarray) -> np.ndarray:
        """(A,) the building's actuators' powers [W] for the merged actuators' ``power_w`` (a
        number, or one per merged actuator): each split over its kind's actuators by their
        zones' shares (:func:`split_by_share`); in the one-actuator view the chillers at their
        lower bound."""
        merged = np.asarray(power_w, dtype=float).reshape(-1)
        members = self._members()
        if merged.size != len(members):
            raise ValueError(
                f"MergedView.split: one power per merged actuator ({len(members)}), got {power_w!r}"
            )
        out = np.array([a.lower_w for a in self.spec.actuators], dtype=float)
        for total, idx in zip(merged, members, strict=True):
            acts = [self.spec.actuators[i] for i in idx]
            counts = np.array([sum(b.zone == a.zone for b in acts) for a in acts], dtype=float)
            weights = np.array([self.shares[a.zone] for a in acts]) / counts  # a zone's share among its kind
            out[list(idx)] = split_by_share(
                float(total), weights, np.array([a.lower_w for a in acts]), np.array([a.upper_w for a in acts])
            )
        return out

    def _merged_powers(self, powers: dict[str, np.ndarray], t_a_c: np.ndarray) -> dict[str, np.ndarray]:
        """The merged actuators' power columns (``u`` or ``u_phys`` and, in the two-actuator
        view, its ``[heat]``, ``[cool]``) of the building's actuators' ``powers`` (name ->
        (K,) [W]) at outdoor temperatures ``t_a_c`` (K,) [C]: the module docstring's net heat
        in the one-actuator view, each kind's sum in the two-actuator view."""
        acts = self.spec.actuators
        if not self.cooling:
            heater = acts[self.heaters[0]]
            heat = sum(a.sign * a.gain(t_a_c) * powers[a.name] for a in acts)
            return {"": np.asarray(heat / heater.gain(t_a_c), dtype=float)}
        kinds = {HEAT: self.heaters, COOL: self.coolers}
        sums = {kind: np.sum([powers[acts[i].name] for i in idx], axis=0) for kind, idx in kinds.items()}
        return {"": sums[HEAT] + sums[COOL], **sums}

    def history(self, history: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The merged building's history of the building's (:class:`Observation`'s): ``T_r``
        the zones' mean, ``u``, ``u_phys`` (and each merged actuator's) the merged powers, the
        building's other series as they are; the zones' and actuators' own columns left out."""
        rooms = np.column_stack([history[c] for c in zone_columns("T_r", self.spec.zones)])  # (k+1, Z)
        merged: dict[str, np.ndarray] = {
            name: values for name, values in history.items()
            if parse_zone_column(name) is None and not _actuator_column(name, self.spec.actuators)
            and name not in ("u", "u_phys", *ZONE_SERIES)
        }
        merged["T_r"] = self.mean_c(rooms)
        for series in ("u", "u_phys"):
            if series not in history:
                continue
            k = len(history[series])
            powers = {a.name: np.asarray(history[f"{series}[{a.name}]"], dtype=float) for a in self.spec.actuators}
            t_a = np.asarray(history["T_a"], dtype=float)[:k]  # each past interval's start
            for name, values in self._merged_powers(powers, t_a).items():
                merged[f"{series}[{name}]" if name else series] = values
        return merged

    def observation(self, obs: Observation) -> Observation:
        """The merged building's observation of the building's ``obs`` (:meth:`history`); its
        hidden masses unknown (NaN)."""
        return Observation.from_history(obs.k, self.history(obs.history), math.nan, zones=ONE_ZONE)

    def forecast(self, forecast: Forecast) -> Forecast:
        """``forecast`` with each zone's band (H, Z) merged into the mean's (H,) (the shares'
        mean of each bound); a band of every zone (H,) as it is."""
        bands = {}
        for name in ("T_min", "T_max"):
            band = np.asarray(getattr(forecast, name), dtype=float)
            bands[name] = self.mean_c(band) if band.ndim == 2 else band
        return forecast._replace(**bands)

    def frame(self, df: pd.DataFrame) -> pd.DataFrame:
        """The merged view of a frame of the building's data (the data format's columns of
        several zones, such as ``simulate`` writes): one zone's columns (``T_r`` the zones'
        mean, ``u`` and ``u_phys`` the merged powers, each band the mean's), the other
        columns as they are and its ``attrs`` kept: what a one-zone model of the merged
        building is trained or identified on."""
        zones = self.spec.zones
        rooms = df[list(zone_columns("T_r", zones))].to_numpy(dtype=float)  # (N, Z)
        drop = [c for c in df.columns if parse_zone_column(str(c)) is not None or _actuator_column(str(c), self.spec.actuators)]
        out = df.drop(columns=[*drop, "u", "u_phys"], errors="ignore")
        out.insert(1, "T_r", self.mean_c(rooms))
        t_a = df["T_a"].to_numpy(dtype=float)
        position = 2
        for series in ("u", "u_phys"):
            powers = dict(zip(
                (a.name for a in self.spec.actuators),
                df[list(actuator_columns(series, self.spec.actuators))].to_numpy(dtype=float).T, strict=True,
            ))
            for name, values in self._merged_powers(powers, t_a).items():
                out.insert(position, f"{series}[{name}]" if name else series, values)
                position += 1
        for bound in ("T_min", "T_max"):
            columns = [f"{bound}[{z.name}]" for z in zones]
            if all(c in df.columns for c in columns):
                out[bound] = self.mean_c(df[columns].to_numpy(dtype=float))
        out.attrs = dict(df.attrs)
        return out


def _actuator_column(name: str, actuators: Sequence[ActuatorSpec]) -> bool:
    """Whether ``name`` is an actuator's own power column (``u[<name>]``, ``u_phys[<name>]``)."""
    return any(name in (f"u[{a.name}]", f"u_phys[{a.name}]") for a in actuators)


class MergedZones:
    """The controller of a building of several zones that runs ``inner``, a controller of the
    building's :class:`MergedView` ``view`` (built on ``view.one_zone_spec``): each interval it
    hands ``inner`` the merged observation and forecast and splits its decision over the
    building's actuators (:meth:`MergedView.split`); ``act`` returns (A,) [W]."""

    def __init__(self, inner: Controller, view: MergedView) -> None:
        if not isinstance(view, MergedView):
            raise TypeError(f"MergedZones.view must be a MergedView, got {type(view).__name__}")
        if not isinstance(inner, Controller):
            raise TypeError(f"MergedZones.inner must be a Controller (reset, act, ...), got {type(inner).__name__}")
        if inner.knows_true_state:
            raise ValueError(
                f"MergedZones.inner = {inner.name!r} plans on the plant's true state, which a merged "
                "building has not; give a controller of a model or RC of the merged data"
            )
        self.inner, self.view = inner, view
        self.name = f"merged-{inner.name}"

    def reset(self, seed: int | None = None) -> None:
        self.inner.reset(seed)

    def act(self, obs: Observation, forecast: Forecast) -> np.ndarray:
        """(A,) each actuator's power [W]: ``inner``'s decision on the merged building, split."""
        decision = self.inner.act(self.view.observation(obs), self.view.forecast(forecast))
        merged = self.view.one_zone_spec.actuators
        clipped = [a.clip(float(u)) for a, u in zip(merged, np.asarray(decision, dtype=float).reshape(-1), strict=True)]
        return self.view.split(np.array(clipped))

    @property
    def last_plan(self) -> np.ndarray | None:
        """``inner``'s last plan: of the merged actuators' power [W]."""
        return self.inner.last_plan

    @property
    def last_stats(self) -> SolveStats:
        return self.inner.last_stats

    @property
    def knows_true_state(self) -> bool:
        return False

    @property
    def model(self) -> BatchDynamics | None:
        """The model ``inner`` plans over (of the merged building)."""
        return self.inner.model

    @property
    def trust_report(self) -> TrustReport | None:
        return self.inner.trust_report
