"""State estimators: components a controller is given, kept apart from its optimiser (as in do-mpc).

Each turns the observation of step k into what its controller plans from:

- :class:`KalmanEstimator`: (T_r, T_m) from a Kalman observer on an RC model
  (:class:`pinn_mpc.observer.KalmanObserver`), fed with the last interval's inputs.
- :class:`TrueState`: the simulator's true (T_r, T_m); only the reference controllers (oracle,
  clairvoyant) may use it.
- :class:`OffsetFilter`: for learned models, the filtered error of the model's one-step
  prediction of the interval that just ended (offset-free MPC), in kelvin.

``reset()`` forgets everything; ``update(obs)`` is called once per decision, in order.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from controllers.base import ControlSpec, Observation
from pinn_mpc.actuator import Actuator
from pinn_mpc.errors import InputError
from pinn_mpc.observer import DEFAULT_MEASUREMENT_STD_C, KalmanObserver
from pinn_mpc.physics import RCParams

if TYPE_CHECKING:
    from pinn_mpc.models.rollout import BatchDynamics

__all__ = [
    "NOISY_SENSOR_PROCESS_STD_C",
    "RC_MPC_PROCESS_STD_C",
    "KalmanEstimator",
    "OffsetFilter",
    "StateEstimator",
    "TrueState",
]


class StateEstimator(Protocol):
    """Turns observations into a state estimate ``(T_r, T_m)`` (2,) [C]."""

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
        if spec.sensor_noise_std_c > DEFAULT_MEASUREMENT_STD_C:
            return cls(
                params,
                spec.dt_s,
                actuator=spec.actuator,
                measurement_std_c=spec.sensor_noise_std_c,
                process_std_c=NOISY_SENSOR_PROCESS_STD_C,
            )
        return cls(params, spec.dt_s, actuator=spec.actuator, process_std_c=RC_MPC_PROCESS_STD_C)

    def reset(self) -> None:
        self._k_seen: int | None = None

    def update(self, obs: Observation) -> np.ndarray:
        last = obs.last
        if self._k_seen is None or obs.k != self._k_seen + 1 or last is None:
            self.observer.reset(obs.t_r_c)
        else:
            heat_w = last.u_phys * float(self.actuator.gain(last.T_a))
            self.observer.predict(heat_w, last.T_a, last.G, last.I_g)
            self.observer.update(obs.t_r_c)
        self._k_seen = obs.k
        return self.observer.state[0]


class TrueState:
    """The simulator's true state (only against the simulator: it reads ``obs.t_m_true_c``)."""

    def reset(self) -> None:
        pass

    def update(self, obs: Observation) -> np.ndarray:
        if not math.isfinite(obs.t_m_true_c):
            raise InputError(
                f"the true-state estimator needs the true thermal-mass temperature, got "
                f"obs.t_m_true_c={obs.t_m_true_c}; use it only against the simulator"
            )
        return np.array([obs.t_r_c, obs.t_m_true_c], dtype=float)


class OffsetFilter:
    """Output-disturbance estimate [K] for a batch model (offset-free MPC).

    Each update predicts the interval that just ended from the history one interval earlier and
    the power actually delivered; the error against the measured ``T_r`` is filtered with
    ``gain`` into an offset the controller adds to every predicted ``T_r``. It removes the slowly
    varying bias a learned model has in closed-loop operating points. Gain 0 keeps it at 0; a
    history too short for the model leaves it unchanged. The errors it sees are kept for the
    planner's trust monitor (:mod:`controllers.trust`).
    """

    def __init__(self, model: BatchDynamics, gain: float) -> None:
        if not 0.0 <= gain <= 1.0:
            raise InputError(f"offset_gain must lie in [0, 1], got {gain}")
        self.model, self.gain = model, gain
        self.reset()

    def reset(self) -> None:
        self.offset_k = 0.0
        self.innovation_k = float("nan")  # last measured minus predicted T_r, offset included
        self.power_error_w = float("nan")  # last delivered minus predicted under the demand

    def update(self, obs: Observation) -> float:
        """Fold the interval that just ended into the offset; returns the offset [K]. Also
        records ``innovation_k`` and ``power_error_w`` (NaN when the history is too short)."""
        history, last = obs.history, obs.last
        self.innovation_k = self.power_error_w = float("nan")
        if last is None or len(history["u_phys"]) < self.model.depth + 2:
            return self.offset_k
        import torch

        past = {name: np.asarray(values)[:-1] for name, values in history.items()}
        exog = {name: np.array([getattr(last, name)]) for name in self.model.exog_names}
        # Row 0 replays the delivered power (the room's error); row 1 the demand (the power's).
        u_w = torch.tensor([[last.u_phys], [last.u]], dtype=torch.float32)
        with torch.no_grad():
            roll = self.model.rollout(past, u_w, exog)
            predicted = float(roll.t_r_c[:, 0, 0].mean())
            delivered = float(roll.u_phys_w[:, 1, 0].mean())
        error = obs.t_r_c - predicted
        self.power_error_w = last.u_phys - delivered
        if np.isfinite(error):
            self.innovation_k = error - self.offset_k
            self.offset_k += self.gain * (error - self.offset_k)
        return self.offset_k
