"""State estimators: components a controller is given, kept apart from its optimiser (as in do-mpc).

Each turns the observation of step k into what its controller plans from:

- :class:`KalmanEstimator`: (T_r, T_m) from a Kalman observer on an RC model
  (:class:`pinn_mpc.observer.KalmanObserver`), fed with the last interval's inputs.
- :class:`MultiZoneKalmanEstimator`: the same of a multi-zone building
  (:class:`pinn_mpc.multizone.MultiZoneParams`), every zone's room measured and its mass hidden.
- :class:`TrueState`: the simulator's true (T_r, T_m); only the reference controllers (oracle,
  clairvoyant) may use it.
- :class:`OffsetFilter`: for learned models, the filtered error of the model's one-step
  prediction of the interval that just ended (offset-free MPC), in kelvin.

``reset()`` forgets everything; ``update(obs)`` is called once per decision, in order.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from controllers.base import ControlSpec, Observation
from pinn_mpc.actuator import Actuator
from pinn_mpc.errors import InternalError
from pinn_mpc.multizone import MultiZoneParams, discretise, history_arrays
from pinn_mpc.observer import (
    DEFAULT_INITIAL_T_M_STD_C,
    DEFAULT_MEASUREMENT_STD_C,
    KalmanObserver,
    MultiZoneObserver,
)
from pinn_mpc.physics import RCParams, gain_schedule_index

if TYPE_CHECKING:
    from pinn_mpc.models.fleet import FleetModels
    from pinn_mpc.models.rollout import BatchDynamics

__all__ = [
    "NOISY_SENSOR_PROCESS_STD_C",
    "RC_MPC_PROCESS_STD_C",
    "FleetKalmanEstimator",
    "FleetOffsetFilter",
    "KalmanEstimator",
    "MultiZoneKalmanEstimator",
    "OffsetFilter",
    "StateEstimator",
    "TrueState",
]


class StateEstimator(Protocol):
    """Turns observations into a state estimate ``(T_r, T_m)`` (2,) [C] (of a building of Z
    zones, (2Z,): the rooms then the masses)."""

    def reset(self) -> None: ...

    def update(self, obs: Observation) -> np.ndarray: ...


#: Process noise (T_r, T_m) [C per interval] of an RC MPC's observer (figures: CHANGELOG).
RC_MPC_PROCESS_STD_C = (0.05, 0.05)
#: The same with a sensor noisier than the observer's default measurement noise.
NOISY_SENSOR_PROCESS_STD_C = (0.05, 0.01)


class KalmanEstimator:
    """A Kalman observer on ``params`` fed by the observations.

    The first call, a step that does not follow the previous one, or an observation without its
    last interval restart the observer at the measured ``T_r`` with ``T_m`` guessed equal to it;
    otherwise the observer predicts over the last interval (its delivered power and exogenous
    inputs) and updates with the new measurement. ``observer_options`` are the keywords of
    :class:`~pinn_mpc.observer.KalmanObserver`. ``actuator`` turns the last interval's
    electrical power into the heat the RC model takes (the heat pump's COP at its T_a).
    :meth:`for_spec` builds it as the RC MPCs do, with the sensor's stated noise.
    """

    def __init__(
        self,
        params: RCParams,
        dt_s: float,
        *,
        actuator: Actuator | None = None,
        **observer_options: Any,
    ) -> None:
        self.params = params
        self.observer = KalmanObserver(params, dt_s, **observer_options)
        self.actuator = Actuator() if actuator is None else actuator
        self.reset()

    @classmethod
    def for_spec(cls, params: RCParams, spec: ControlSpec) -> KalmanEstimator:
        """The observer of an RC MPC: the spec's interval and actuator; the thermal mass free
        to drift (process noise :data:`RC_MPC_PROCESS_STD_C`), since an identified RC misses
        unmeasured internal gains and structure that the mass temperature must absorb; with a
        sensor noisier than the observer's default, its stated noise as measurement noise and
        the mass kept steady (:data:`NOISY_SENSOR_PROCESS_STD_C`), since then the filter
        cannot tell a drifting mass from noise and the plan would chase it."""
        process, measurement = observer_noise(spec)
        return cls(
            params, spec.dt_s, actuator=spec.actuator.efficiency, measurement_std_c=measurement,
            process_std_c=process,
        )

    def reset(self) -> None:
        self._k_seen: int | None = None

    def update(self, obs: Observation) -> np.ndarray:
        last = obs.last
        if self._k_seen is None or obs.k != self._k_seen + 1 or last is None:
            self.observer.reset(obs.t_r_c)
        else:
            heat_w = last.u_phys * float(self.actuator.gain(last.T_a))
            gains_w = float(self.params.gains_w(last.I_g, last.time_of_day_h, last.day_of_week))
            self.observer.predict(heat_w, last.T_a, last.G, gains_w)
            self.observer.update(obs.t_r_c)
        self._k_seen = obs.k
        return self.observer.state[0]


def observer_noise(spec: ControlSpec) -> tuple[tuple[float, float], float]:
    """The RC MPC observer's process (T_r, T_m) and measurement noise [C] for the spec's sensor
    (:meth:`KalmanEstimator.for_spec` says why)."""
    if spec.sensor_noise_std_c > DEFAULT_MEASUREMENT_STD_C:
        return NOISY_SENSOR_PROCESS_STD_C, spec.sensor_noise_std_c
    return RC_MPC_PROCESS_STD_C, DEFAULT_MEASUREMENT_STD_C


class FleetKalmanEstimator:
    """:class:`KalmanEstimator` (built as :meth:`KalmanEstimator.for_spec`) of B buildings, each
    on its own RC matrices ``ad`` (B, 2, 2) and ``bd`` (B, 2, 4) (:func:`pinn_mpc.simulator.fleet_matrices`),
    updated together: the same arithmetic, building by building, as B estimators (each its own
    covariance and its own restart rule), in one vectorised pass instead of B Python calls."""

    def __init__(
        self, ad: np.ndarray, bd: np.ndarray, spec: ControlSpec, *, schedules: np.ndarray | None = None
    ) -> None:
        """``schedules`` (B, :data:`~pinn_mpc.physics.GAIN_SCHEDULE_LENGTH`) each building's
        unmeasured gains [W] (:func:`pinn_mpc.simulator.unmeasured_gains`), None for none."""
        ad, bd = np.asarray(ad, dtype=float), np.asarray(bd, dtype=float)
        self.schedules = schedules
        if ad.ndim != 3 or ad.shape[1:] != (2, 2) or bd.shape != (ad.shape[0], 2, 4):
            raise InternalError(f"FleetKalmanEstimator: ad (B, 2, 2) and bd (B, 2, 4), got {ad.shape}, {bd.shape}")
        process, measurement = observer_noise(spec)
        self.ad, self.bd, self.actuator = ad, bd, spec.actuator.efficiency
        self.q = np.diag(np.square(np.asarray(process, dtype=float)))
        self.r = float(measurement) ** 2
        self.initial_t_m_std_c = DEFAULT_INITIAL_T_M_STD_C
        self.reset()

    @property
    def n_buildings(self) -> int:
        return self.ad.shape[0]

    def reset(self) -> None:
        b = self.n_buildings
        self._k_seen = np.full(b, -2, dtype=np.int64)  # -2: not seen (k + 1 never matches)
        self._x = np.zeros((b, 2))
        self._p = np.broadcast_to(np.eye(2), (b, 2, 2)).copy()

    @property
    def state(self) -> np.ndarray:
        """(B, 2) estimated ``(T_r, T_m)`` [C]."""
        return self._x.copy()

    def update(self, observations: Sequence[Observation]) -> np.ndarray:
        """Every building's :meth:`KalmanEstimator.update`; returns (B, 2) ``(T_r, T_m)`` [C]."""
        b = self.n_buildings
        if len(observations) != b:
            raise InternalError(f"FleetKalmanEstimator: {len(observations)} observations for {b} buildings")
        k = np.fromiter((o.k for o in observations), dtype=np.int64, count=b)
        y = np.fromiter((o.t_r_c for o in observations), dtype=float, count=b)
        lasts = [o.last for o in observations]
        go_on = (k == self._k_seen + 1) & np.fromiter((v is not None for v in lasts), dtype=bool, count=b)
        if go_on.any():
            d = np.array(
                [(v.u_phys, v.T_a, v.G, v.I_g) if v is not None else (0.0, 0.0, 0.0, 0.0) for v in lasts]
            )
            d[:, 0] *= np.asarray(self.actuator.gain(d[:, 1]), dtype=float)
            if self.schedules is not None:
                index = gain_schedule_index(
                    np.array([v.time_of_day_h if v is not None else 0.0 for v in lasts]),
                    np.array([v.day_of_week if v is not None else math.nan for v in lasts]),
                )
                d[:, 3] += self.schedules[np.arange(b), index]
            x = np.einsum("bij,bj->bi", self.ad, self._x) + np.einsum("bij,bj->bi", self.bd, d)
            p = self.ad @ self._p @ self.ad.transpose(0, 2, 1) + self.q
            s = p[:, 0, 0] + self.r
            gain = p[:, :, 0] / s[:, None]  # (B, 2)
            x = x + (y - x[:, 0])[:, None] * gain
            i_kh = np.broadcast_to(np.eye(2), p.shape).copy()
            i_kh[:, :, 0] -= gain
            p = i_kh @ p @ i_kh.transpose(0, 2, 1) + self.r * gain[:, :, None] * gain[:, None, :]
            self._x = np.where(go_on[:, None], x, self._x)
            self._p = np.where(go_on[:, None, None], p, self._p)
        restart = ~go_on
        if restart.any():
            self._x[restart] = y[restart, None]
            self._p[restart] = np.diag([self.r, self.initial_t_m_std_c**2])
        self._k_seen = k
        return self.state


class MultiZoneKalmanEstimator:
    """A Kalman observer of a multi-zone building, fed by the observations: state ``x`` (2Z,)
    the rooms then the masses [C] (:mod:`pinn_mpc.multizone`'s order), every room measured
    (``Observation.t_r_zones_c``), the masses hidden; the model is the exact ZOH of ``params``
    over ``spec.dt_s`` (:func:`pinn_mpc.multizone.discretise`), the filter
    :class:`pinn_mpc.observer.MultiZoneObserver`.

    Each zone's noises are :meth:`KalmanEstimator.for_spec`'s (:func:`observer_noise`: the
    spec's sensor noise as the measurement noise where it is the larger), the initial mass
    guess's standard deviation :data:`~pinn_mpc.observer.DEFAULT_INITIAL_T_M_STD_C`. Its
    restart rule is :class:`KalmanEstimator`'s: the first call, a step that does not follow
    the previous one, or an observation without its last interval start it at the measured
    rooms with each mass guessed equal to its room; otherwise it predicts over the last
    interval, with each actuator's delivered power (``history["u_phys[<name>]"]``, or
    ``u_phys`` for a building's one, :func:`pinn_mpc.actuator.actuator_columns`) times its heat
    per watt at the interval's outdoor temperature and the interval's exogenous inputs, and
    updates with the new measurement. An input the building takes (T_a, I_g, each zone's
    irradiance) missing from the history is an InputError."""

    def __init__(self, params: MultiZoneParams, spec: ControlSpec) -> None:
        self.params, self.spec = params, spec
        process, measurement = observer_noise(spec)
        self.observer = MultiZoneObserver(
            discretise(params, spec.actuators, spec.dt_s), process_std_c=process, measurement_std_c=measurement
        )
        self.reset()

    @property
    def n_zones(self) -> int:
        return self.params.n_zones

    def reset(self) -> None:
        self._k_seen: int | None = None

    @property
    def state(self) -> np.ndarray:
        """(2Z,) the estimated rooms then masses [C] (NaN before the first update)."""
        if self._k_seen is None:
            return np.full(2 * self.n_zones, np.nan)
        return self.observer.state

    def update(self, obs: Observation) -> np.ndarray:
        """Fold the observation of step ``obs.k`` in (class docstring); returns the state (2Z,)."""
        y = obs.t_r_zones_c()
        if self._k_seen is None or obs.k != self._k_seen + 1 or obs.last is None:
            self.observer.reset(y)
        else:
            u_phys, d = self._last_inputs(obs.history)
            heat = u_phys * np.array([s.gain(d[0]) for s in self.spec.actuators], dtype=float)
            self.observer.step(heat, d, y)
        self._k_seen = obs.k
        return self.state

    def _last_inputs(self, history: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The last interval's delivered power per actuator (A,) [W] and exogenous inputs (7,)
        in :data:`pinn_mpc.multizone.EXOGENOUS_NAMES` order (held from its start)."""
        _, powers, inputs = history_arrays(history, self.params, self.spec.actuators)
        return powers[-1], inputs[-2]


class TrueState:
    """The simulator's true state (only against the simulator: it reads ``obs.t_m_true_c``)."""

    def reset(self) -> None:
        pass

    def update(self, obs: Observation) -> np.ndarray:
        if not math.isfinite(obs.t_m_true_c):
            raise ValueError(
                f"the true-state estimator needs the true thermal-mass temperature, got "
                f"obs.t_m_true_c={obs.t_m_true_c}; use it only against the simulator"
            )
        return np.array([obs.t_r_c, obs.t_m_true_c], dtype=float)


class FleetOffsetFilter:
    """Output-disturbance estimates [K] of B buildings' models (offset-free MPC), filtered
    together: :class:`OffsetFilter` of each building, in one batched replay of the interval
    that just ended (:class:`pinn_mpc.models.fleet.FleetModels`), the same arithmetic
    building by building (float64). ``offset_k``, ``innovation_k`` and ``power_error_w`` are
    (B,) arrays."""

    def __init__(self, dynamics: FleetModels, gain: float) -> None:
        if not 0.0 <= gain <= 1.0:
            raise ValueError(f"offset_gain must lie in [0, 1], got {gain}")
        self.dynamics, self.gain = dynamics, gain
        self.reset()

    def reset(self) -> None:
        b = self.dynamics.n_buildings
        self.offset_k = np.zeros(b)
        self.innovation_k = np.full(b, np.nan)  # last measured minus predicted T_r, offset included
        self.power_error_w = np.full(b, np.nan)  # last delivered minus predicted under the demand

    def update(self, observations: Sequence[Observation]) -> np.ndarray:
        """Fold the interval that just ended into every building's offset; returns the
        offsets (B,) [K]. Also records ``innovation_k`` and ``power_error_w`` (NaN while a
        history is too short for the models: then no offset changes)."""
        b = self.dynamics.n_buildings
        if len(observations) != b:
            raise InternalError(f"OffsetFilter: {len(observations)} observations for {b} buildings")
        self.innovation_k, self.power_error_w = np.full(b, np.nan), np.full(b, np.nan)
        lasts = [o.last for o in observations]
        depth = self.dynamics.depth
        if any(last is None or len(o.history["u_phys"]) < depth + 2 for o, last in zip(observations, lasts, strict=True)):
            return self.offset_k
        import torch

        last0 = lasts[0]
        assert last0 is not None
        exog = {name: np.array([getattr(last0, name)]) for name in self.dynamics.exog_names}
        # Row 0 replays the delivered power (the room's error); row 1 the demand (the power's).
        u_w = torch.tensor([[[v.u_phys], [v.u]] for v in lasts if v is not None], dtype=torch.float32)
        with torch.no_grad():
            roll = self.dynamics.rollout([o.history for o in observations], u_w, exog, drop_last=1)
            predicted = roll.t_r_c[:, :, 0, 0, 0].mean(1).double().numpy()
            delivered = roll.u_phys_w[:, :, 1, 0].mean(1).double().numpy()
        error = np.array([o.t_r_c for o in observations], dtype=float) - predicted
        self.power_error_w = np.array([v.u_phys for v in lasts if v is not None], dtype=float) - delivered
        finite = np.isfinite(error)
        self.innovation_k = np.where(finite, error - self.offset_k, np.nan)
        self.offset_k = np.where(finite, self.offset_k + self.gain * (error - self.offset_k), self.offset_k)
        return self.offset_k


class OffsetFilter:
    """Output-disturbance estimate [K] for a batch model (offset-free MPC): the one-building
    case of :class:`FleetOffsetFilter`.

    Each update predicts the interval that just ended from the history one interval earlier and
    the power actually delivered; the error against the measured ``T_r`` is filtered with
    ``gain`` into an offset the controller adds to every predicted ``T_r``. It removes the slowly
    varying bias a learned model has in closed-loop operating points. Gain 0 keeps it at 0; a
    history too short for the model leaves it unchanged. The errors it sees are kept for the
    planner's trust monitor (:mod:`controllers.trust`).
    """

    def __init__(self, model: BatchDynamics, gain: float) -> None:
        from pinn_mpc.models.fleet import FleetModels

        self.model = model
        self._filter = FleetOffsetFilter(FleetModels([model]), gain)

    @property
    def gain(self) -> float:
        return self._filter.gain

    @property
    def offset_k(self) -> float:
        return float(self._filter.offset_k[0])

    @property
    def innovation_k(self) -> float:
        """Last measured minus predicted T_r, offset included [K] (NaN: no prediction)."""
        return float(self._filter.innovation_k[0])

    @property
    def power_error_w(self) -> float:
        """Last delivered minus predicted power under the demand [W] (NaN: no prediction)."""
        return float(self._filter.power_error_w[0])

    def reset(self) -> None:
        self._filter.reset()

    def update(self, obs: Observation) -> float:
        """Fold the interval that just ended into the offset; returns the offset [K]. Also
        records ``innovation_k`` and ``power_error_w`` (NaN when the history is too short)."""
        return float(self._filter.update([obs])[0])
