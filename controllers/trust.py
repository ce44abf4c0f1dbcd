"""When a learned model is not to be trusted, and what a planner over it does then.

A planner over a learned model (:mod:`controllers.sampling`) watches these signals each
decision, all in closed loop:

- the realised multi-step error of its model's room temperature against that of the RC it
  falls back on: both replay the last ``replay_steps`` intervals from where they stood then
  (the learned model from its history, the RC from its Kalman estimate) under the power that
  was delivered, and their errors against the measured T_r now are filtered; the model is
  distrusted when its error passes ``error_floor_k`` and ``error_ratio`` times the RC's, or
  ``error_alone_k`` while the RC's observer is still settling (a wrong gain or time constant
  shows over hours, not in one interval, where the offset filter hides it);
- the realised error of its model's delivered power: the prediction of the interval that just
  ended under the power that was *demanded*, against the power the plant delivered (the backup
  thermostat and the actuator are part of the model; the offset filter cannot see them), as a
  fraction of the actuator's range, filtered;
- the ensemble's disagreement along the chosen plan: the largest standard deviation over the
  members of the predicted room temperature;
- how far the forecast's inputs leave the ranges of the training data (counted, not acted on:
  physics carries a model some way out of its data).

When an error or the disagreement passes its limit, or the model's planning fails (a
non-finite prediction, an error), the decision is handed to the fallback: the MPC on the RC
identified from the same training data (``train`` stores it with every model it writes,
networks and ARX alike), which runs as a shadow every step so that its observer is current
when it takes over. It also decides, without a verdict on the model, while the history is too
short for the model. The model takes over again at the first decision within the limits where
its filtered replay error is below ``recover_ratio`` times the RC's (``recover_below_rc``:
the fallback then predicts little better, or worse, than the model it stands in for; the
distrust threshold, twice the RC's, keeps the two from flapping), and at the latest after
``recover_steps`` decisions within the limits, twice as many after each further switch (a
model found wrong again is given less benefit of the doubt). The planner also plans against
the comfort band narrowed by the filtered error of its room temperature (one step ahead, or with ``margin_from_replay`` also over the replayed hours; never
less than its ``comfort_margin_k``), so a model that errs more keeps more distance from the
band's edges. With ``margin_from_replay`` the fallback RC MPC is held to the same rule: it
plans against the band narrowed by the RC's own filtered replay error
(:meth:`TrustMonitor.fallback_margin_k`), for an RC that errs as much as the model it replaces
otherwise rides the band's edge and the plant sits just outside it. With
``fallback_margin_when_colder`` the fallback alone follows that rule, and only while the
forecast is colder than the data the model and its RC were fitted on.

Over a building of several zones (:mod:`controllers.zone_sampling`) the same monitor filters
each zone's replay errors (:class:`ZoneTrust`: the model's against those of the multi-zone RC
its QP fallback plans on, :class:`ZoneRCReplay`) and narrows each zone's band by its own; one
more monitor holds the building's verdict.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from pinn_mpc.physics import RCParams, discretise, step

if TYPE_CHECKING:
    from controllers.base import ControlSpec
    from pinn_mpc.multizone import MultiZoneParams

__all__ = ["RCReplay", "TrustMonitor", "TrustSettings", "TrustState", "ZoneRCReplay", "ZoneTrust"]

#: Decisions of an RC MPC before its Kalman estimates start replays (its observer settles).
SETTLE_STEPS = 3


@dataclass(frozen=True, kw_only=True)
class TrustSettings:
    """Limits of the :class:`TrustMonitor` (module docstring).

    ``replay_steps``: intervals replayed; ``error_floor_k`` and ``error_ratio``: the model's
    filtered replay error [K] must pass both the floor and the ratio to the RC's to distrust
    it; ``error_alone_k``: the same without the RC's (its observer settling);
    ``power_error_frac``: filtered |error| of the delivered power over the actuator's range; ``spread_k``: the members' largest std of T_r
    along the plan [K]; ``filter_gain``: weight of a new error in the filters; ``recover_steps``:
    decisions within the limits before the model drives again (doubled after each further
    switch, at most ``max_recover_steps``); ``recover_below_rc``: the model drives again at
    once when, within the limits, its filtered replay error is below ``recover_ratio`` times
    the RC's (off: only the wait; the ratio below ``error_ratio``, so that a model handed back
    is not distrusted at its next decision); ``margin_factor``: the band is
    narrowed by this times the filtered |innovation| (at most ``max_margin_k``), or with
    ``margin_from_replay`` by the larger of that and the filtered replay error: the error a
    plan carries hours ahead, for plants whose measured temperature is noise-free (a noisy
    sensor's error is in the replay error too, and a margin for it only costs energy); with
    it the fallback RC MPC's band is narrowed by ``margin_factor`` times the RC's filtered
    replay error (at most ``max_margin_k``) too; ``fallback_margin_when_colder``: that margin
    for the fallback alone, and only while the forecast is colder than the data the model and
    its RC were fitted on (where an RC that errs by its structure errs most).
    """

    replay_steps: int = 8
    error_floor_k: float = 0.3
    error_ratio: float = 2.0
    error_alone_k: float = 1.0
    power_error_frac: float = 0.2
    spread_k: float = 0.5
    filter_gain: float = 0.3
    recover_steps: int = 12
    max_recover_steps: int = 48
    recover_below_rc: bool = True
    recover_ratio: float = 1.5
    margin_factor: float = 1.0
    max_margin_k: float = 0.5
    margin_from_replay: bool = False
    fallback_margin_when_colder: bool = False

    def __post_init__(self) -> None:
        for name in (
            "error_floor_k", "error_ratio", "error_alone_k", "power_error_frac", "spread_k",
            "max_margin_k",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"TrustSettings.{name} must be a positive number, got {value!r}")
        if not 0 < self.filter_gain <= 1:
            raise ValueError(f"TrustSettings.filter_gain must lie in (0, 1], got {self.filter_gain}")
        if not (math.isfinite(self.recover_ratio) and 0 < self.recover_ratio < self.error_ratio):
            raise ValueError(
                f"TrustSettings.recover_ratio must lie in (0, error_ratio = {self.error_ratio}), "
                f"got {self.recover_ratio}: set recover_ratio below error_ratio"
            )
        if not (math.isfinite(self.margin_factor) and self.margin_factor >= 0):
            raise ValueError(f"TrustSettings.margin_factor must be >= 0, got {self.margin_factor}")
        if self.replay_steps < 1:
            raise ValueError(f"TrustSettings.replay_steps must be >= 1, got {self.replay_steps}")
        if not 1 <= self.recover_steps <= self.max_recover_steps:
            raise ValueError(
                f"TrustSettings.recover_steps must lie in 1 .. max_recover_steps "
                f"({self.max_recover_steps}), got {self.recover_steps}"
            )


@dataclass
class TrustState:
    """What the monitor counts over a run (reset with the controller)."""

    error_k: float = 0.0  # filtered |innovation| of T_r [K]
    replay_k: float = float("nan")  # filtered |replay error| of the model [K]
    replay_rc_k: float = float("nan")  # the same of the fallback RC [K]
    power_error_frac: float = 0.0  # filtered |delivered power error| / range
    trusted: bool = True
    calm_steps: int = 0
    switches: int = 0  # model -> fallback transitions
    fallback_steps: int = 0  # decisions the fallback made
    out_of_range_steps: int = 0  # decisions whose forecast left the training ranges
    reasons: dict[str, int] = field(default_factory=dict)  # why the model was distrusted


class TrustMonitor:
    """Filters the error signals and decides, each interval, whether the model drives."""

    def __init__(self, settings: TrustSettings, u_range_w: float) -> None:
        if not (math.isfinite(u_range_w) and u_range_w > 0):
            raise ValueError(f"TrustMonitor needs a positive power range, got {u_range_w!r}")
        self.settings, self.u_range_w = settings, u_range_w
        self.state = TrustState()

    def reset(self) -> None:
        self.state = TrustState()

    def observe(
        self,
        innovation_k: float,
        power_error_w: float,
        replay_k: float = float("nan"),
        replay_rc_k: float = float("nan"),
    ) -> None:
        """One interval's realised errors (NaN where unknown: left out of the filters)."""
        s, g = self.state, self.settings.filter_gain
        if math.isfinite(innovation_k):
            s.error_k += g * (abs(innovation_k) - s.error_k)
        if math.isfinite(replay_k):
            s.replay_k = abs(replay_k) if not math.isfinite(s.replay_k) else s.replay_k + g * (abs(replay_k) - s.replay_k)
        if math.isfinite(replay_rc_k):
            s.replay_rc_k = (
                abs(replay_rc_k)
                if not math.isfinite(s.replay_rc_k)
                else s.replay_rc_k + g * (abs(replay_rc_k) - s.replay_rc_k)
            )
        if math.isfinite(power_error_w):
            s.power_error_frac += g * (abs(power_error_w) / self.u_range_w - s.power_error_frac)

    def margin_k(self, base_k: float) -> float:
        """The comfort margin to plan with: ``base_k``, or more where the model errs more."""
        error = self.state.error_k
        if self.settings.margin_from_replay and math.isfinite(self.state.replay_k):
            error = max(error, self.state.replay_k)
        return max(base_k, self._margin_for(error))

    def fallback_margin_k(self, colder: bool = False) -> float:
        """The margin [K] the fallback RC MPC plans with: the model's rule applied to the RC's
        filtered replay error with ``margin_from_replay``, or with
        ``fallback_margin_when_colder`` where ``colder`` (the forecast is colder than the data
        the RC was fitted on); else 0, and 0 before the RC has been replayed."""
        error = self.state.replay_rc_k
        s = self.settings
        if not ((s.margin_from_replay or (s.fallback_margin_when_colder and colder)) and math.isfinite(error)):
            return 0.0
        return self._margin_for(error)

    def _margin_for(self, error_k: float) -> float:
        """``margin_factor`` times a filtered error [K], at most ``max_margin_k``."""
        return min(self.settings.margin_factor * error_k, self.settings.max_margin_k)

    def reason(self, spread_k: float | None = None) -> str | None:
        """Why the model is not to be trusted now (None when it is)."""
        s, lim = self.state, self.settings
        if math.isfinite(s.replay_rc_k):
            if s.replay_k > lim.error_floor_k and s.replay_k > lim.error_ratio * s.replay_rc_k:
                return "prediction error above the RC's"
        elif s.replay_k > lim.error_alone_k:
            return "prediction error"
        if s.power_error_frac > lim.power_error_frac:
            return "delivered power error"
        if spread_k is not None and not spread_k <= lim.spread_k:  # NaN counts as too large
            return "ensemble disagreement"
        return None

    def _below_rc(self) -> bool:
        """With ``recover_below_rc``: whether the model's filtered replay error is below
        ``recover_ratio`` times the RC's (both known)."""
        s = self.state
        return (
            self.settings.recover_below_rc
            and math.isfinite(s.replay_k)
            and math.isfinite(s.replay_rc_k)
            and s.replay_k < self.settings.recover_ratio * s.replay_rc_k
        )

    def stand_in(self, reason: str) -> None:
        """Count a decision the fallback made for a model that could not decide (``reason``,
        e.g. too short a history for it), without a verdict on the model: no switch, and its
        trust is unchanged."""
        s = self.state
        s.reasons[reason] = s.reasons.get(reason, 0) + 1
        s.fallback_steps += 1

    def decide(self, reason: str | None) -> bool:
        """Record this decision's verdict; True when the model drives it."""
        s = self.state
        if reason is not None:
            s.reasons[reason] = s.reasons.get(reason, 0) + 1
            s.calm_steps = 0
            if s.trusted:
                s.switches += 1
            s.trusted = False
        elif not s.trusted:
            s.calm_steps += 1
            needed = self.settings.recover_steps * 2 ** max(s.switches - 1, 0)
            if s.calm_steps >= min(needed, self.settings.max_recover_steps) or self._below_rc():
                s.trusted = True
        if not s.trusted:
            s.fallback_steps += 1
        return s.trusted


class _Replay:
    """The observer's estimates of the recent steps an RC replays from (:class:`RCReplay` of
    one zone, :class:`ZoneRCReplay` of a building of several): :meth:`record` keeps the
    estimate of each step (after :data:`SETTLE_STEPS`), :meth:`longest` finds the longest
    replay from a kept one."""

    def __init__(self, spec: ControlSpec, replay_steps: int) -> None:
        self.spec, self.replay_steps = spec, replay_steps
        self.reset()

    def reset(self) -> None:
        self._estimates: dict[int, np.ndarray] = {}
        self._steps = 0

    def record(self, k: int, estimate_c: Sequence[float] | np.ndarray) -> None:
        """The observer's estimate [C] at step ``k``, once it has settled."""
        self._steps += 1
        if self._steps > SETTLE_STEPS:
            self._estimates[k] = np.array(estimate_c, dtype=float)
            self._estimates.pop(k - self.replay_steps - 1, None)

    def longest(self, k: int, longest: int) -> int:
        """The longest replay (2 .. ``longest`` intervals) from a recorded estimate at step
        ``k``, else ``longest``."""
        return next((j for j in range(longest, 1, -1) if k - j in self._estimates), longest)

    def _start(self, k: int, r: int) -> np.ndarray | None:
        """The finite estimate recorded ``r`` >= 1 steps before step ``k``, else None."""
        start = self._estimates.get(k - r)
        if r < 1 or start is None or not np.all(np.isfinite(start)):
            return None
        return start


class RCReplay(_Replay):
    """An RC replaying the recent past from where its observer stood: the multi-step error of
    the RC an MPC plans on (the guard's fallback, or ``qp-mpc`` itself where it plans with
    a margin from it). :meth:`record` keeps the observer's ``(T_r, T_m)`` estimate of each
    step (after :data:`SETTLE_STEPS`); :meth:`error_k` replays the RC from the estimate of
    ``r`` steps ago under the power that was delivered and the measured weather."""

    def __init__(self, rc: RCParams, spec: ControlSpec, replay_steps: int) -> None:
        self.rc = rc
        self.matrices = discretise(rc, spec.dt_s)
        super().__init__(spec, replay_steps)

    def error_k(
        self, k: int, t_r_c: float, hist: Mapping[str, Sequence[float] | np.ndarray], r: int
    ) -> float:
        """Measured ``t_r_c`` minus the RC's T_r replayed over the last ``r`` intervals of
        ``hist`` from its estimate at step ``k - r`` [K]; NaN without a finite one."""
        start = self._start(k, r)
        if start is None:
            return math.nan
        zeros = np.zeros(len(hist["T_r"]))
        u_phys = np.asarray(hist["u_phys"], dtype=float)[-r:]
        t_a, g, i_g = (
            np.asarray(hist.get(n, zeros), dtype=float)[-r - 1 : -1] for n in ("T_a", "G", "I_g")
        )
        if self.rc.unmeasured_gains_w:
            tod, dow = (
                np.asarray(hist[n], dtype=float)[-r - 1 : -1] if n in hist else None
                for n in ("time_of_day_h", "day_of_week")
            )
            i_g = self.rc.gains_w(i_g, np.zeros(r) if tod is None else tod, dow)
        d = np.stack([u_phys * self.spec.actuator.gain(t_a), t_a, g, i_g], axis=1)  # (r, 4)
        x = start[None]
        for j in range(r):
            x = step(x, d[j : j + 1], *self.matrices)
        return t_r_c - float(x[0, 0])


class ZoneRCReplay(_Replay):
    """:class:`RCReplay` of a building of several zones (``params``, the multi-zone RC a
    zoned planner falls back on): :meth:`record` keeps its Kalman observer's state (2Z,) of
    each step, the rooms then the masses [C]; :meth:`errors_k` replays the building's exact
    ZOH (:func:`pinn_mpc.multizone.discretise`) from the state of ``r`` steps ago under each
    actuator's delivered power and the measured inputs."""

    def __init__(self, params: MultiZoneParams, spec: ControlSpec, replay_steps: int) -> None:
        from pinn_mpc.multizone import discretise as discretise_zones

        self.params = params
        self.zone_matrices = discretise_zones(params, spec.actuators, spec.dt_s)
        super().__init__(spec, replay_steps)

    def errors_k(self, k: int, hist: Mapping[str, Sequence[float] | np.ndarray], r: int) -> np.ndarray:
        """(Z,) each zone's measured room now minus the RC's replayed over the last ``r``
        intervals of ``hist`` from its state at step ``k - r`` [K]; NaN without a finite one."""
        from pinn_mpc.multizone import history_arrays

        start = self._start(k, r)
        if start is None:
            return np.full(self.params.n_zones, np.nan)
        rooms, powers, inputs = history_arrays(hist, self.params, self.spec.actuators)
        if len(powers) < r:
            return np.full(self.params.n_zones, np.nan)
        d = inputs[-r - 1 : -1]  # (r, 7) each interval's inputs, held from its start
        heat = powers[-r:] * np.stack([a.gain(d[:, 0]) for a in self.spec.actuators], axis=-1)  # (r, A)
        a, b_u, b_d = self.zone_matrices
        x = start
        for j in range(r):
            x = a @ x + b_u @ heat[j] + b_d @ d[j]
        return rooms[-1] - x[: self.params.n_zones]


class ZoneTrust:
    """The trust of a planner over a building of several zones in its model: one
    :class:`TrustMonitor` of each zone filters that zone's replay errors (the model's and the
    fallback RC's) and gives its comfort margin (:meth:`TrustMonitor.margin_k`); one more, the
    building's, filters the zones' mean absolute replay errors and holds the verdict
    (:meth:`TrustMonitor.reason` on them, :meth:`TrustMonitor.decide`: switches, recovery,
    counts). The verdict is the building's because the fallback QP takes every zone at once:
    it pays where the model errs more than the RC over the building, not where the RC is
    better in one zone for a few hours. It also keeps the RC's mean replay error over the run
    (the zones' mean, over its full-length replays), which judges whether the RC is credible at all
    (:meth:`rc_credible`)."""

    def __init__(self, settings: TrustSettings, zone_names: Sequence[str], u_range_w: float) -> None:
        self.settings, self.zone_names = settings, tuple(zone_names)
        self.zones = [TrustMonitor(settings, u_range_w) for _ in self.zone_names]
        self.building = TrustMonitor(settings, u_range_w)
        self._rc_sum_k, self._rc_replays = 0.0, 0

    def reset(self) -> None:
        for monitor in (*self.zones, self.building):
            monitor.reset()
        self._rc_sum_k, self._rc_replays = 0.0, 0

    def observe(self, replay_k: np.ndarray, replay_rc_k: np.ndarray, full: bool = True) -> None:
        """Each zone's replay error (Z,) [K] of the model and of the RC (NaN: not known; the
        building's mean only when every zone's is known); ``full``: the replay was
        ``replay_steps`` long (only those count toward the RC's credibility, :meth:`rc_credible`:
        shorter ones, early in a run, err less whatever the RC)."""
        for monitor, model, rc in zip(self.zones, replay_k, replay_rc_k, strict=True):
            monitor.observe(math.nan, math.nan, float(model), float(rc))
        rc = float(np.mean(np.abs(replay_rc_k)))
        self.building.observe(math.nan, math.nan, float(np.mean(np.abs(replay_k))), rc)
        if full and math.isfinite(rc):
            self._rc_sum_k, self._rc_replays = self._rc_sum_k + rc, self._rc_replays + 1

    def margins_k(self, base_k: float) -> np.ndarray:
        """(Z,) each zone's comfort margin [K]: ``margin_factor`` times its filtered replay
        error, at least ``base_k``, at most ``max_margin_k`` (unless ``base_k`` is more)."""
        return np.array([monitor.margin_k(base_k) for monitor in self.zones])

    def reason(self) -> str | None:
        """Why the model is not to be trusted now, by the building's mean errors, with the zone
        the model errs most in (None when it is)."""
        reason = self.building.reason()
        return None if reason is None else f"{reason} (most in {self._worst_zone()})"

    def rc_credible(self, credible_k: float, min_replays: int) -> bool:
        """Whether the RC has replayed the past within ``credible_k`` [K] on the mean over the
        run (the zones' mean error of each full replay), after at least ``min_replays`` of them:
        a slow judgement, which the hours where a wrong RC happens to replay well do not
        sway."""
        return self._rc_replays >= min_replays and self._rc_sum_k / self._rc_replays < credible_k

    def credible_reason(self, credible_k: float, min_replays: int, floor_k: float) -> str | None:
        """Why the model is not to be trusted now beside a credible RC (:meth:`rc_credible`):
        its filtered replay error, the zones' mean, above ``floor_k`` and ``error_ratio`` times
        the RC's; None when it is trusted or the RC is not credible."""
        s = self.building.state
        if not self.rc_credible(credible_k, min_replays):
            return None
        if s.replay_k > floor_k and s.replay_k > self.settings.error_ratio * s.replay_rc_k:
            return f"prediction error above a credible RC's (most in {self._worst_zone()})"
        return None

    def _worst_zone(self) -> str:
        """The zone whose filtered replay error of the model is the largest."""
        errors = [m.state.replay_k if math.isfinite(m.state.replay_k) else -1.0 for m in self.zones]
        return self.zone_names[int(np.argmax(errors))]

    def worst(self) -> tuple[float, float]:
        """The largest filtered replay error over the zones [K], of the model and of the RC
        (NaN before the first)."""
        model = [m.state.replay_k for m in self.zones if math.isfinite(m.state.replay_k)]
        rc = [m.state.replay_rc_k for m in self.zones if math.isfinite(m.state.replay_rc_k)]
        return (max(model) if model else math.nan), (max(rc) if rc else math.nan)
