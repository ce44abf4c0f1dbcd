"""The sampling controllers (:class:`controllers.sampling.CEM`, :class:`~controllers.sampling.RandomShooting`)
over a building of several zones or actuators (a spec that is not :attr:`ControlSpec.single`).

The model is one of the building's zones and actuators (:attr:`BatchDynamics.actuators`, such
as :class:`pinn_mpc.models.multizone_rc.MultiZoneRCModel`); a plan is (H, A), each actuator's
electrical power. The planners sample each actuator's fraction of its range, ``[0, 1]``
(CEM's mean and standard deviation per step and actuator, :mod:`controllers.planners`), so
that actuators of different bounds share one box; a fraction ``f`` is ``lower_w + f x
span_w``. The objective (:class:`controllers.objective.ZoneObjective`) is the price times the
building's total delivered electrical power plus the comfort weight times each zone's band
violation summed over the zones, against each zone's band narrowed by ``comfort_margin_k``.
The plan is polished by ``polish_iters`` LPs over every step of every actuator
(:class:`controllers.lp_polish.ZonePolish`; CEM's default one, random shooting's none): the
sampling finds the plan's shape, the LP its optimum on the model. The LP is linearised by
probing the model, or from the model's response to the plan where it gives one
(:meth:`~pinn_mpc.models.rollout.BatchDynamics.linear_response`, the multi-zone RC), then
solved by HiGHS, or as a QP by OSQP above :data:`controllers.lp_polish.MAX_LP_PLAN` steps x
actuators (the controller keeps that solver, :class:`controllers.lp_polish.StateQP`, warm from
decision to decision). The warm start is the
previous plan shifted by one step, the first plan half of each actuator's range. ``act``
returns (A,) in ``spec.actuators``' order and keeps the plan (H, A) in ``last_plan``.

Each zone's predicted rooms carry an offset (offset-free MPC, ``offset_gain``, 0.5 by
default as for one zone): the error of the model's prediction of the interval that just ended,
zone by zone, filtered. A model whose rooms run from measured lags (the physics-informed ARX
of every zone) keeps a bias in closed loop that the offset removes; on EnergyPlus's small
office it cut cem's January objective by an eighth. A model whose state a Kalman filter
re-estimates from every room (:attr:`BatchDynamics.estimates_state`: the multi-zone RC and
hybrid) takes none: its one-step errors are the filter's innovations, and on the RC house
filtering them into an offset cost up to 2 % of the objective (worst cell 1.013 -> 1.032
x the oracle).

The comfort margin ``comfort_margin_k`` (None by default: :func:`zone_comfort_margin_k`) is
the least each zone's band is narrowed by: :data:`ZONE_COMFORT_MARGIN_K` over a model that
estimates its state, :data:`ZONE_LAGGED_MARGIN_K` over one that runs from measured lags.

The trust guard (:class:`ZoneGuard`, :class:`controllers.trust.ZoneTrust`), the one-zone
guard's rule (:mod:`controllers.trust`) zone by zone: at every decision the model replays the
last ``replay_steps`` intervals from the history it had then, with the offsets it planned with
then, under each actuator's delivered power, and so does the fallback multi-zone RC from its
Kalman state of then (:class:`controllers.trust.ZoneRCReplay`); each zone's errors against its
measured room are filtered. Each zone's band is narrowed by ``margin_factor`` times its
model's filtered replay error (at most ``max_margin_k``, never less than ``comfort_margin_k``):
a zone the model predicts worse hours ahead keeps more distance from its band's edges. The
model is distrusted when its zones' mean error passes the floor and the ratio to the RC's (or
the error alone while the RC has none): a building's verdict, for the fallback QP takes every
zone at once (judged zone by zone, on EnergyPlus's small office in January, seed 3, the QP
took 21 % of the decisions from an ARX that erred less than the RC over the building, and the
objective rose from 0.72 to 1.12 x the thermostat's). By default (``ZoneGuard.hand_over``
None) the model hands over only beside a credible RC, whose replay error (the zones' mean over
the run's full replays) is under :data:`ZONE_CREDIBLE_RC_K` (the model's filtered one then above
:data:`ZONE_CREDIBLE_FLOOR_K` and twice the RC's): on EnergyPlus's small office the QP on the identified multi-zone RC is
1.9-16 x the thermostat where cem over the ARX is 0.6-1.2 x, and with the hand-over by the
limits alone (``hand_over=True``; sweeps/eplus_zones.toml's cells, 3789177) the QP's 9 % of
January seed 1's decisions raised cem from 0.77 to 1.14 x the thermostat and its 14 % of April
seed 1's (30 days) from 0.80 to 1.19, though the RC replayed those hours better (0.60 K against
the ARX's 2.03 K in April): the RC's replay starts from its Kalman estimate of every hour, its
plan does not. On the RC buildings, whose identified RC replays within hundredths of a kelvin,
a planner that exploits a network's errors hands the building to the QP. Once handed over, the
fallback QP decides until the model has been
within the limits for ``recover_steps`` decisions (doubled after each further switch). Its
decisions are fallbacks (``last_stats.fallback``: the KPIs count the model's own decisions),
and ``trust_report`` counts them with the worst zone's errors. Not watched here (the
one-zone guard watches them): the error of the delivered power, the ensemble's spread and the
forecast's distance from the training data; setpoint-space sampling (random shooting samples
powers here) and on/off plans are one zone's too.

Fallback (never an exception out of ``act``): when the planning fails (a non-finite
prediction or any exception) the decision is the QP MPC's on the model's RC building
(:attr:`BatchDynamics.zone_params`, :class:`controllers.rc_mpc.multizone.MultiZoneMPC`; its
state the Kalman observer :class:`controllers.estimators.MultiZoneKalmanEstimator` that this
controller keeps current at every decision), or without one the band rule of
:func:`controllers.base.fallback_powers`. The decision's stats say it fell back (the KPIs
count it) and the next warm start is from scratch.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch

from controllers.base import (
    ControlSpec,
    Fallback,
    Forecast,
    Observation,
    SolveStats,
    fallback_powers,
)
from controllers.lp_polish import MAX_LP_PLAN, PlanProblem, PolishSettings, StateQP, ZonePolish
from controllers.objective import ZoneObjective
from controllers.trust import TrustSettings, ZoneRCReplay, ZoneTrust
from pinn_mpc.actuator import actuator_columns
from pinn_mpc.errors import InternalError
from pinn_mpc.zones import zone_columns

if TYPE_CHECKING:
    from controllers.estimators import MultiZoneKalmanEstimator
    from controllers.planners import Planner
    from controllers.rc_mpc.multizone import MultiZoneMPC
    from pinn_mpc.models.rollout import BatchDynamics, LinearResponse
    from pinn_mpc.records import TrustReport

__all__ = [
    "ZONE_COMFORT_MARGIN_K", "ZONE_CREDIBLE_FLOOR_K", "ZONE_CREDIBLE_MIN_REPLAYS", "ZONE_CREDIBLE_RC_K", "ZONE_LAGGED_MARGIN_K", "ZONE_TRUST",
    "ZoneGuard", "ZoneSampling", "zone_comfort_margin_k",
]

#: The comfort margin [K] cem and random-shooting plan a building of several zones with over a
#: model whose state a Kalman filter re-estimates from every room
#: (:attr:`BatchDynamics.estimates_state`: the multi-zone RC and hybrid): none. The one-zone
#: default (0.01 K, :mod:`controllers.sampling`) guards against a learned model's millikelvin
#: bias, which the one-zone offset filter leaves; on shoulder_office that margin cost 3 % of
#: the objective (worst cell 1.036 x the oracle against 1.007 without).
ZONE_COMFORT_MARGIN_K = 0.0
#: The comfort margin [K] of cem and random-shooting over a model of several zones that runs from
#: measured lags and does not re-estimate its state (the physics-informed ARX of every zone):
#: its rooms are off by about the model's one-step error, which a plan riding the band edge
#: turns into discomfort (chosen on EnergyPlus's small office, ``CHANGELOG.md``; the guard's
#: adaptive margins come on top of it: beneath them 0.3 K or none did worse in April).
ZONE_LAGGED_MARGIN_K = 0.6
#: The limits of a zoned planner's trust in its model (:class:`ZoneGuard`): each zone's
#: band is narrowed by its filtered replay error (``margin_from_replay``), up to 1 K; with
#: ``ZoneGuard(hand_over=True)`` the model hands over when its zones' mean replay error passes
#: what that margin covers (``error_floor_k`` 1 K) and twice the RC's, and takes over again
#: after the fixed wait only (``recover_below_rc`` off: the zoned pages were measured so).
ZONE_TRUST = TrustSettings(
    margin_from_replay=True, max_margin_k=1.0, error_floor_k=1.0, recover_below_rc=False
)
#: The default hand-over (``ZoneGuard.hand_over`` None) goes to the fallback QP only while its
#: RC is credible: its replay error, the zones' mean over every full replay of the run so far,
#: under this [K] (after :data:`ZONE_CREDIBLE_MIN_REPLAYS` of them). On the RC buildings the
#: identified RC replays within 0.01-0.03 K; on EnergyPlus's small office it errs 0.2-2.8 K,
#: where its QP controls worse than the model it would replace (module docstring).
ZONE_CREDIBLE_RC_K = 0.2
#: Full replays (``replay_steps`` long) of the RC before it can be judged credible: enough that
#: a wrong RC's few good hours do not pass for credibility, few enough that a credible one takes
#: over before an exploited model's plans cost much (chosen on two_zone_house, CHANGELOG.md;
#: tests/test_zone_guard.py holds both).
ZONE_CREDIBLE_MIN_REPLAYS = 4
#: Beside a credible RC the model is distrusted when its zones' mean filtered replay error
#: passes this [K] (the one-zone guard's floor, :class:`controllers.trust.TrustSettings`) and
#: twice the RC's.
ZONE_CREDIBLE_FLOOR_K = 0.3


def zone_comfort_margin_k(model: BatchDynamics) -> float:
    """The comfort margin [K] a planner over ``model`` of several zones plans with by default:
    :data:`ZONE_COMFORT_MARGIN_K` when the model estimates its state
    (:attr:`BatchDynamics.estimates_state`), else :data:`ZONE_LAGGED_MARGIN_K`."""
    return ZONE_COMFORT_MARGIN_K if model.estimates_state else ZONE_LAGGED_MARGIN_K


@dataclass(frozen=True, kw_only=True)
class ZoneGuard:
    """How a planner over several zones watches its model (module docstring): ``settings``,
    the limits of each zone's :class:`controllers.trust.TrustMonitor`; ``hand_over``, when a
    distrusted model hands its decisions to the fallback QP:

    - None (the default): only beside a credible RC, whose replay error, the zones' mean over
      the run's full replays (at least ``credible_min_replays``), is under ``credible_rc_k``, when
      the model's filtered one passes ``credible_floor_k`` and
      ``settings.error_ratio`` times the RC's (a planner that exploits a network's errors on an
      RC building hands over; on EnergyPlus, whose identified RC is not credible, the model
      drives: there the QP on that RC controls worse than the model it would replace, even
      where it replays the past better, module docstring);
    - True: by ``settings``' limits whatever the RC's error;
    - False: never (the errors are still filtered and counted, and the model drives).

    ``adaptive_margin``: whether each zone's band is narrowed by ``settings.margin_factor``
    times its filtered replay error (at most ``settings.max_margin_k``, never less than the
    planner's ``comfort_margin_k``)."""

    settings: TrustSettings = ZONE_TRUST
    hand_over: bool | None = None
    adaptive_margin: bool = True
    credible_rc_k: float = ZONE_CREDIBLE_RC_K
    credible_floor_k: float = ZONE_CREDIBLE_FLOOR_K
    credible_min_replays: int = ZONE_CREDIBLE_MIN_REPLAYS

    def __post_init__(self) -> None:
        if not isinstance(self.settings, TrustSettings):
            raise TypeError(
                f"ZoneGuard.settings must be a controllers.trust.TrustSettings, got {type(self.settings).__name__}"
            )
        if self.hand_over not in (None, True, False):
            raise TypeError(f"ZoneGuard.hand_over must be None, True or False, got {self.hand_over!r}")
        for name in ("credible_rc_k", "credible_floor_k"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"ZoneGuard.{name} must be a positive number of kelvin, got {value!r}")
        if not (isinstance(self.credible_min_replays, int) and self.credible_min_replays >= 1):
            raise ValueError(f"ZoneGuard.credible_min_replays must be a whole number >= 1, got {self.credible_min_replays!r}")

    @property
    def watches(self) -> bool:
        """Whether the guard may hand decisions over (``hand_over`` not False)."""
        return self.hand_over is not False



class NonFiniteModelOutput(Exception):
    """The model predicted a non-finite temperature or power."""


class _LastEstimate:
    """The planner's Kalman observer, updated at every decision (:meth:`observe`), and the state
    it estimated at this decision for the fallback QP (:meth:`update`, NaN when the observer
    could not fold this observation in: the QP then falls back in turn)."""

    def __init__(self, observer: MultiZoneKalmanEstimator) -> None:
        self.observer = observer
        self._k: int | None = None

    def observe(self, obs: Observation) -> None:
        self._k = None
        self.observer.update(obs)
        self._k = obs.k

    def reset(self) -> None:
        self.observer.reset()
        self._k = None

    def update(self, obs: Observation) -> np.ndarray:
        if self._k != obs.k:
            return np.full(2 * self.observer.n_zones, np.nan)
        return self.observer.state


class _ZoneFallback(Fallback):
    """The sampling planners' :class:`controllers.base.Fallback` of plans of several actuators
    (H, A): :meth:`act_all` counts the event, forgets the plan (the next warm start is from
    scratch) and returns the fallback QP's action (A,), or :func:`controllers.base.fallback_powers`
    without one or when the forecast does not fit it."""

    def __init__(self, spec: ControlSpec, qp: MultiZoneMPC | None) -> None:
        super().__init__(spec, reuse_plan=False)
        self.qp = qp

    def act_all(self, obs: Observation, forecast: Forecast) -> np.ndarray:
        self.n_events += 1
        self.plan_w = None
        return self.qp_action(obs, forecast)

    def qp_action(self, obs: Observation, forecast: Forecast) -> np.ndarray:
        """The fallback QP's action (A,) [W], or the band rule's without one or when the QP
        refuses the forecast (no event counted, the plan kept)."""
        if self.qp is not None:
            try:
                return np.asarray(self.qp.act(obs, forecast), dtype=float).reshape(-1)
            except Exception:  # a forecast the QP refuses: the band rule decides
                pass
        return fallback_powers(obs, forecast, self.spec)


class _ZoneOffset:
    """Each zone's output-disturbance estimate [K] (offset-free MPC, as
    :class:`controllers.estimators.OffsetFilter` for one zone): each update predicts the
    interval that just ended from the history one interval earlier and each actuator's
    delivered power, and filters the error against each zone's measured room with ``gain``
    into the offset the planner adds to that zone's every predicted room. Gain 0 keeps it at 0;
    a history too short for the model, or a prediction that is not finite, leaves it
    unchanged."""

    def __init__(self, model: BatchDynamics, gain: float) -> None:
        if not (0.0 <= gain <= 1.0):
            raise ValueError(f"offset_gain must lie in [0, 1], got {gain}")
        self.model, self.gain = model, float(gain)
        self._rooms = zone_columns("T_r", model.zones)
        self.powers = actuator_columns("u_phys", model.actuators or ())
        self.offset_k = np.zeros(len(self._rooms))

    def reset(self) -> None:
        self.offset_k = np.zeros(len(self._rooms))

    def update(self, obs: Observation) -> None:
        """Fold the interval that just ended into each zone's offset."""
        history = obs.history
        if self.gain == 0.0 or len(history.get(self._rooms[0], ())) < self.model.depth + 3:
            return
        past = {name: np.asarray(values)[:-1] for name, values in history.items()}
        exog = {name: np.asarray(history[name], dtype=float)[-2:-1] for name in self.model.exog_names}
        delivered = torch.tensor([[[float(history[c][-1]) for c in self.powers]]], dtype=torch.float64)
        with torch.no_grad():
            predicted = self.model.rollout(past, delivered, exog).t_r_c[0, 0, 0].double().numpy()
        measured = np.array([float(history[c][-1]) for c in self._rooms])
        innovation = measured - predicted - self.offset_k
        if np.all(np.isfinite(innovation)):
            self.offset_k = self.offset_k + self.gain * innovation


class ZoneSampling:
    """The path of :class:`controllers.sampling.CEM` and
    :class:`~controllers.sampling.RandomShooting` over a building of several zones or
    actuators (module docstring), a base of their shared class."""

    model: BatchDynamics
    spec: ControlSpec
    planner: Planner
    polish: PolishSettings
    ensemble: str
    risk_weight: float
    comfort_margin_k: float
    last_cost_eur: float
    fallback: Fallback
    _generator: torch.Generator
    _stats: SolveStats
    _state_qp: StateQP

    def _init_zones(self, offset_gain: float, guard: ZoneGuard) -> None:
        """Check the model against the building of ``spec``, build the fallback, each
        zone's offset filter of ``offset_gain`` and the trust ``guard``."""
        model, spec, name = self.model, self.spec, type(self).__name__
        described = (
            f"{len(spec.zones)} zone(s) ({', '.join(z.name for z in spec.zones)}) and "
            f"{spec.n_actuators} actuator(s) ({', '.join(a.name for a in spec.actuators)})"
        )
        if model.actuators is None:
            raise ValueError(
                f"{name}: the building has {described}, but the model plans one zone's one "
                "actuator; give a model of the building's zones and actuators "
                "(pinn_mpc.models.multizone_rc.MultiZoneRCModel)"
            )
        if tuple(model.actuators) != spec.actuators or tuple(model.zones) != spec.zones:
            raise ValueError(
                f"{name}: the model's zones ({', '.join(z.name for z in model.zones)}) and "
                f"actuators ({', '.join(a.name for a in model.actuators)}) differ from the "
                f"building's, {described}; build the model with the spec's actuators, on the "
                "building's zones in its order"
            )
        self._zone_observer: _LastEstimate | None = None
        self._rc_replay: ZoneRCReplay | None = None  # the fallback RC's replays
        qp = None
        params = model.zone_params
        if params is not None:
            from controllers.estimators import MultiZoneKalmanEstimator
            from controllers.rc_mpc.multizone import MultiZoneMPC

            self._zone_observer = _LastEstimate(MultiZoneKalmanEstimator(params, spec))
            qp = MultiZoneMPC(params, spec, estimator=self._zone_observer, name=f"{name} fallback")
            self._rc_replay = ZoneRCReplay(params, spec, guard.settings.replay_steps)
        self.fallback = _ZoneFallback(spec, qp)
        # A model whose state a filter re-estimates from every room takes no offset.
        self._zone_offset = _ZoneOffset(model, 0.0 if model.estimates_state else offset_gain)
        self.zone_guard = guard
        self._zone_trust = ZoneTrust(
            guard.settings, [z.name for z in spec.zones], sum(a.span_w for a in spec.actuators)
        )
        self._offsets: dict[int, np.ndarray] = {}  # each step's offsets (Z,) [K], for the replays
        self._margins_k = np.full(len(spec.zones), self.comfort_margin_k)
        self._state_qp = StateQP()  # the polish of a plan too large for HiGHS
        self._lower_w = torch.tensor([a.lower_w for a in spec.actuators], dtype=torch.float32)
        self._span_w = torch.tensor([a.span_w for a in spec.actuators], dtype=torch.float32)

    @property
    def zone_qp(self) -> MultiZoneMPC | None:
        """The QP MPC on the model's RC building that decides when the planning fails (None:
        the band rule does)."""
        fallback = self.fallback
        return fallback.qp if isinstance(fallback, _ZoneFallback) else None

    def _reset_zones(self) -> None:
        """Forget the observer, the fallback QP's plan and warm start, the trust and the counts."""
        self.fallback.reset()
        self._zone_offset.reset()
        self._state_qp.reset()
        self._zone_trust.reset()
        self._offsets = {}
        self._margins_k = np.full(len(self.spec.zones), self.comfort_margin_k)
        if self._rc_replay is not None:
            self._rc_replay.reset()
        if self._zone_observer is not None:
            self._zone_observer.reset()
        if self.zone_qp is not None:
            self.zone_qp.reset()

    @property
    def zone_margins_k(self) -> np.ndarray:
        """(Z,) the comfort margin [K] each zone's band was narrowed by at the last decision."""
        return self._margins_k.copy()

    def _zone_trust_report(self) -> TrustReport:
        """The guard's counts since ``reset`` (:class:`pinn_mpc.records.TrustReport`; the
        errors are the worst zone's)."""
        s = self._zone_trust.building.state
        model, rc = self._zone_trust.worst()
        return {
            "model_fallback": self.zone_qp is not None and self.zone_guard.watches,
            "model_fallback_switches": s.switches,
            "model_fallback_steps": s.fallback_steps,
            "model_fallback_reasons": dict(s.reasons),
            "out_of_training_range_steps": 0,
            "model_error_k": round(float(np.abs(self._zone_offset.offset_k).max()), 4),
            "model_replay_error_k": round(model, 4) if math.isfinite(model) else None,
            "rc_replay_error_k": round(rc, 4) if math.isfinite(rc) else None,
        }

    def _act_zones(self, obs: Observation, forecast: Forecast) -> np.ndarray:
        """Each actuator's demanded power for the coming interval (A,) [W], within its bounds:
        the plan's first step, or the fallback's action."""
        start = time.perf_counter()
        try:
            if self._zone_observer is not None:  # every decision, so that it stays current
                self._zone_observer.observe(obs)
            self._zone_offset.update(obs)
            self._watch(obs)
            plan_w, cost, iterations = self._solve_zones(obs, forecast)
        except NonFiniteModelOutput:
            return self._zones_failed(obs, forecast, start, "non-finite model output")
        except Exception as exc:  # a failed solve must not stop a closed-loop run
            return self._zones_failed(obs, forecast, start, f"model error: {type(exc).__name__}: {exc}")
        self.fallback.planned(plan_w)
        self.last_cost_eur = cost
        if self.zone_qp is not None and self.zone_guard.watches:
            reason = self._guard_reason()
            if not self._zone_trust.building.decide(reason):
                assert isinstance(self.fallback, _ZoneFallback)
                action = self.fallback.qp_action(obs, forecast)
                self._stats = SolveStats(
                    time_s=time.perf_counter() - start, status=f"multi-zone QP fallback: {reason or 'recovering'}",
                    iterations=iterations, fallback=True,
                )
                return action
        self._stats = SolveStats(time_s=time.perf_counter() - start, status="ok", iterations=iterations, fallback=False)
        return np.array([a.clip(float(u)) for a, u in zip(self.spec.actuators, plan_w[0], strict=True)])

    def _guard_reason(self) -> str | None:
        """Why the guard does not trust the model now (:class:`ZoneGuard`'s ``hand_over``), or
        None."""
        guard = self.zone_guard
        if guard.hand_over:
            return self._zone_trust.reason()
        return self._zone_trust.credible_reason(guard.credible_rc_k, guard.credible_min_replays, guard.credible_floor_k)

    def _may_hand_over(self) -> bool:
        """Whether the guard may hand this decision to the fallback QP: always with
        ``hand_over`` True, beside a credible RC with None, never with False."""
        guard = self.zone_guard
        return bool(guard.hand_over) or (
            guard.watches and self._zone_trust.rc_credible(guard.credible_rc_k, guard.credible_min_replays)
        )

    def _watch(self, obs: Observation) -> None:
        """Replay the model and the fallback RC over the last intervals, filter each zone's
        errors into the guard, record this step's RC state and offsets, and set each zone's
        margin (module docstring); nothing but the offsets when the guard neither hands over
        nor narrows the bands."""
        watched = self.zone_guard.watches or self.zone_guard.adaptive_margin
        errors = self._zone_replay_errors(obs) if watched else None
        if errors is not None:
            model_k, rc_k, replayed = errors
            self._zone_trust.observe(model_k, rc_k, full=replayed == self.zone_guard.settings.replay_steps)
        if self._rc_replay is not None and self._zone_observer is not None:
            self._rc_replay.record(obs.k, self._zone_observer.observer.state)
        steps = self.zone_guard.settings.replay_steps
        self._offsets[obs.k] = self._zone_offset.offset_k.copy()
        self._offsets.pop(obs.k - steps - 1, None)
        base = self.comfort_margin_k
        if self.zone_guard.adaptive_margin:
            self._margins_k = self._zone_trust.margins_k(base)
        else:
            self._margins_k = np.full(len(self.spec.zones), base)

    def _zone_replay_errors(self, obs: Observation) -> tuple[np.ndarray, np.ndarray, int] | None:
        """Each zone's measured room now minus the replayed one (Z,) [K], of the model (with
        the offsets it planned with then) and of the fallback RC (NaN without one), over the
        last ``replay_steps`` intervals (fewer, down to 2, early in a run) under each
        actuator's delivered power, and the intervals replayed; None while the history is too
        short."""
        history, model = obs.history, self.model
        powers = self._zone_offset.powers
        n = len(history.get(powers[0], ()))
        longest = min(self.zone_guard.settings.replay_steps, n - model.depth - 1)
        rc = self._rc_replay
        r = longest if rc is None else rc.longest(obs.k, longest)
        if r < 2 or obs.k - r not in self._offsets:
            return None
        past = {name: np.asarray(values)[:-r] for name, values in history.items()}
        exog = {name: np.asarray(history[name], dtype=float)[-r - 1 : -1] for name in model.exog_names}
        delivered = np.stack([np.asarray(history[c], dtype=float)[-r:] for c in powers], axis=1)  # (r, A)
        with torch.no_grad():
            roll = model.rollout(past, torch.tensor(delivered[None], dtype=torch.float64), exog)
        predicted = roll.t_r_c[:, 0, -1, :].double().mean(0).numpy() + self._offsets[obs.k - r]  # (Z,)
        measured = obs.t_r_zones_c()
        errors_rc = np.full(len(measured), np.nan) if rc is None else rc.errors_k(obs.k, history, r)
        return measured - predicted, errors_rc, r

    def _zones_failed(self, obs: Observation, forecast: Forecast, start: float, reason: str) -> np.ndarray:
        assert isinstance(self.fallback, _ZoneFallback)
        action = self.fallback.act_all(obs, forecast)
        self.last_cost_eur = math.nan
        if self.zone_qp is not None and self._may_hand_over():
            self._zone_trust.building.decide(reason)  # a model that failed is distrusted
        by = "multi-zone QP" if self.zone_qp is not None else "band rule"
        self._stats = SolveStats(
            time_s=time.perf_counter() - start, status=f"{by} fallback: {reason}", iterations=0, fallback=True
        )
        return action

    def _zone_warm_start(self, h: int) -> torch.Tensor:
        """(h, A) fractions of each actuator's range: the last plan shifted by one step (its last
        step repeated), or half of each range."""
        plan = self.fallback.plan_w
        if plan is None:
            return torch.full((h, self.spec.n_actuators), 0.5)
        fractions = (torch.as_tensor(plan, dtype=torch.float32) - self._lower_w) / self._span_w
        shifted = torch.cat([fractions[1:], fractions[-1:]])
        if len(shifted) < h:
            shifted = torch.cat([shifted, shifted[-1:].expand(h - len(shifted), -1)])
        return shifted[:h].clamp(0.0, 1.0)

    def _solve_zones(self, obs: Observation, forecast: Forecast) -> tuple[np.ndarray, float, int]:
        """(plan (H, A) [W], its planned cost [EUR], iterations)."""
        h = min(self.spec.horizon_steps, forecast.horizon)
        if h < 1:
            raise InternalError("the forecast is empty")
        objective = ZoneObjective.from_forecast(forecast, self.spec, h).tightened_zones(self._margins_k)
        exog = forecast.exogenous(self.model.exog_names, h)
        history, lower, span = obs.history, self._lower_w, self._span_w
        dtype = torch.float32
        offset = torch.as_tensor(self._zone_offset.offset_k, dtype=dtype)  # (Z,)

        def rollout(fractions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
            with torch.no_grad():
                roll = self.model.rollout(history, lower + span * fractions, exog)
                t_r, u_phys = roll.t_r_c.to(dtype) + offset, roll.u_phys_w.to(dtype)  # (M, N, H, Z), (M, N, H)
            if not (bool(torch.isfinite(t_r).all()) and bool(torch.isfinite(u_phys).all())):
                raise NonFiniteModelOutput
            if self.ensemble == "mean":
                return t_r.mean(0, keepdim=True), u_phys.mean(0, keepdim=True)
            return t_r, u_phys

        def score(t_r: torch.Tensor, u_phys: torch.Tensor) -> torch.Tensor:
            costs = objective.cost_torch(u_phys, t_r)  # (M, N)
            if self.risk_weight > 0 and costs.shape[0] > 1:
                return costs.mean(0) + self.risk_weight * costs.std(0, correction=0)
            return costs.mean(0)

        def linearise(fractions: torch.Tensor) -> LinearResponse | None:
            plan_w = (lower + span * fractions.to(dtype)).double().numpy()
            response = self.model.linear_response(history, plan_w, exog)
            if response is None:
                return None  # each zone's offset moves the rooms, not their response
            return dataclasses.replace(response, t_r_c=response.t_r_c + self._zone_offset.offset_k)

        x0 = self._zone_warm_start(h)
        problem = PlanProblem(objective=objective, lower=0.0, upper=1.0)
        polisher = ZonePolish(
            rollout, score, problem, self.polish, x0, linearise=linearise, scale_w=span.double().numpy(),
            solve_state=self._state_qp.solve if h * self.spec.n_actuators > MAX_LP_PLAN else None,
        )
        result = self.planner.optimize(polisher.objective, x0, self._generator)
        plan, cost = result.plan, result.cost
        polished = polisher.finish()
        if polished is not None and polished[1] < cost:
            plan, cost = polished
        if not math.isfinite(cost):
            raise NonFiniteModelOutput
        plan_w = (lower + span * plan.to(dtype)).double().numpy()
        return plan_w, cost, result.iterations + polisher.lps
