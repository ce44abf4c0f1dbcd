"""Kalman filter for the hidden thermal-mass temperature of the discretised 2R2C model.

State ``x = (T_r, T_m)`` [C], measurement ``y = T_r + v``, model (exact zero-order hold from
:func:`pinn_mpc.physics.discretise`, inputs held over the interval)::

    x[k+1] = Ad x[k] + Bd d[k] + w[k],   d = (u_phys [W], T_a [C], G [W/m2], I_g [W])
    w ~ N(0, Q),  Q = diag(process_std_c)^2        (per control interval)
    v ~ N(0, R),  R = measurement_std_c^2

Defaults and why: ``measurement_std_c = 0.05`` K is the resolution of a typical room sensor;
``process_std_c = (0.05, 0.01)`` K per interval lets the filter follow model errors of an
identified parameter set (wrong intra-interval timing of the power, unmodelled gains) while
the small thermal-mass term keeps ``T_m`` smooth. The initial ``T_m`` guess gets a standard
deviation of ``initial_t_m_std_c = 3`` K, so a wrong guess is forgotten within hours.

Batch-friendly: B buildings share the model and the measurement pattern, so the covariance
(2, 2) is common to all and only the means (B, 2) differ.

:class:`MultiZoneObserver` is the same filter of a building of several zones
(:mod:`pinn_mpc.multizone`): every zone's room measured, every zone's mass hidden.
"""

from __future__ import annotations

import math

import numpy as np

from pinn_mpc.multizone import SystemMatrices
from pinn_mpc.physics import RCParams, discretise

__all__ = ["DEFAULT_INITIAL_T_M_STD_C", "DEFAULT_MEASUREMENT_STD_C", "KalmanObserver", "MultiZoneObserver"]

_H = np.array([1.0, 0.0])  # measurement row: y = T_r


def _check_noises(
    name: str, process_std_c: tuple[float, float], measurement_std_c: float, initial_t_m_std_c: float
) -> None:
    """A ValueError naming ``name`` for noises that are not finite and >= 0 (R > 0)."""
    stds = (*process_std_c, measurement_std_c, initial_t_m_std_c)
    if len(process_std_c) != 2 or not all(math.isfinite(s) and s >= 0 for s in stds):
        raise ValueError(
            f"{name}: process_std_c (2 values), measurement_std_c and "
            f"initial_t_m_std_c must be finite and >= 0, got {process_std_c}, "
            f"{measurement_std_c}, {initial_t_m_std_c}"
        )
    if measurement_std_c == 0:
        raise ValueError(f"{name}.measurement_std_c must be > 0 (R must be invertible)")


#: The measurement noise [C] the observer assumes unless told (a good room sensor).
DEFAULT_MEASUREMENT_STD_C = 0.05
#: The standard deviation [C] of the initial thermal-mass guess unless told.
DEFAULT_INITIAL_T_M_STD_C = 3.0


class KalmanObserver:
    """Kalman filter on the discretised RC model for B buildings.

    Call :meth:`reset` with the first measurement, then per interval :meth:`predict` (with the
    inputs of the interval just ended) followed by :meth:`update` (with the new measurement).
    """

    def __init__(
        self,
        params: RCParams,
        dt_s: float,
        *,
        n_batch: int = 1,
        process_std_c: tuple[float, float] = (0.05, 0.01),
        measurement_std_c: float = DEFAULT_MEASUREMENT_STD_C,
        initial_t_m_std_c: float = DEFAULT_INITIAL_T_M_STD_C,
    ) -> None:
        if n_batch < 1:
            raise ValueError(f"KalmanObserver.n_batch must be >= 1, got {n_batch}")
        _check_noises("KalmanObserver", process_std_c, measurement_std_c, initial_t_m_std_c)
        self.params = params
        self.dt_s = dt_s
        self.n_batch = n_batch
        self.ad, self.bd = discretise(params, dt_s)
        self.q = np.diag(np.square(np.asarray(process_std_c, dtype=float)))
        self.r = float(measurement_std_c) ** 2
        self.initial_t_m_std_c = float(initial_t_m_std_c)
        self._x = np.zeros((n_batch, 2))
        self._p = np.eye(2)

    def reset(self, t_r_c: float | np.ndarray, t_m_c: float | np.ndarray | None = None) -> None:
        """Start from measured ``t_r_c`` (B,) and a ``T_m`` guess (B,) (default: ``t_r_c``)."""
        t_r = np.broadcast_to(np.asarray(t_r_c, dtype=float), (self.n_batch,))
        t_m = t_r if t_m_c is None else np.broadcast_to(np.asarray(t_m_c, dtype=float), t_r.shape)
        self._x = np.stack([t_r, t_m], axis=1).copy()
        self._p = np.diag([self.r, self.initial_t_m_std_c**2])

    def predict(
        self,
        u_phys_w: float | np.ndarray,
        t_a_c: float | np.ndarray,
        g_w_per_m2: float | np.ndarray = 0.0,
        i_g_w: float | np.ndarray = 0.0,
    ) -> np.ndarray:
        """Time update over one interval with inputs (B,) or scalar held; returns the mean (B, 2)."""
        d = np.stack(
            [
                np.broadcast_to(np.asarray(v, dtype=float), (self.n_batch,))
                for v in (u_phys_w, t_a_c, g_w_per_m2, i_g_w)
            ],
            axis=1,
        )
        self._x = self._x @ self.ad.T + d @ self.bd.T
        self._p = self.ad @ self._p @ self.ad.T + self.q
        return self.state

    def update(self, t_r_measured_c: float | np.ndarray) -> np.ndarray:
        """Measurement update with the measured room temperature (B,); returns the mean (B, 2)."""
        y = np.broadcast_to(np.asarray(t_r_measured_c, dtype=float), (self.n_batch,))
        s = float(_H @ self._p @ _H) + self.r
        gain = self._p @ _H / s  # (2,)
        self._x = self._x + np.outer(y - self._x[:, 0], gain)
        i_kh = np.eye(2) - np.outer(gain, _H)
        # Joseph form: stays symmetric positive definite in floating point.
        self._p = i_kh @ self._p @ i_kh.T + self.r * np.outer(gain, gain)
        return self.state

    @property
    def state(self) -> np.ndarray:
        """(B, 2) estimated ``(T_r, T_m)`` [C]."""
        return self._x.copy()

    @property
    def covariance(self) -> np.ndarray:
        """(2, 2) estimate covariance [K^2], shared by the batch."""
        return self._p.copy()


class MultiZoneObserver:
    """Kalman filter of one building of Z zones on its exact zero-order hold ``matrices``
    (:func:`pinn_mpc.multizone.discretise` over the control interval).

    State ``x`` (2Z,) the rooms then the masses [C] (:mod:`pinn_mpc.multizone`'s order), every
    room measured, every mass hidden; each zone's process noise is ``process_std_c`` (room,
    mass) [C per interval], the measurement noise ``measurement_std_c`` [C]. :meth:`reset`
    starts at the measured rooms with each mass guessed equal to its room (standard deviation
    ``initial_t_m_std_c``); :meth:`step` predicts over one interval with each actuator's heat
    [W] (its electrical power times its heat per watt) and the exogenous inputs (7,) held, in
    :data:`pinn_mpc.multizone.EXOGENOUS_NAMES` order, then updates with the rooms measured at
    its end.
    """

    def __init__(
        self,
        matrices: SystemMatrices,
        *,
        process_std_c: tuple[float, float] = (0.05, 0.01),
        measurement_std_c: float = DEFAULT_MEASUREMENT_STD_C,
        initial_t_m_std_c: float = DEFAULT_INITIAL_T_M_STD_C,
    ) -> None:
        _check_noises("MultiZoneObserver", process_std_c, measurement_std_c, initial_t_m_std_c)
        self.matrices = matrices
        self.n_zones = matrices.a.shape[0] // 2
        self.q = np.diag(np.repeat(np.square(np.asarray(process_std_c, dtype=float)), self.n_zones))  # (2Z, 2Z)
        self.r = float(measurement_std_c) ** 2
        self.initial_t_m_std_c = float(initial_t_m_std_c)
        self._x = np.full(2 * self.n_zones, np.nan)
        self._p = np.eye(2 * self.n_zones)

    def reset(self, t_r_c: np.ndarray) -> np.ndarray:
        """Start from the measured rooms (Z,) [C], each mass guessed equal to its room; returns
        the state (2Z,)."""
        y = np.asarray(t_r_c, dtype=float).reshape(self.n_zones)
        z_n = self.n_zones
        self._x = np.concatenate([y, y])
        self._p = np.diag(np.concatenate([np.full(z_n, self.r), np.full(z_n, self.initial_t_m_std_c**2)]))
        return self.state

    def step(self, heat_w: np.ndarray, d: np.ndarray, t_r_c: np.ndarray) -> np.ndarray:
        """Predict over one interval (each actuator's heat ``heat_w`` (A,) [W], the exogenous
        inputs ``d`` (7,)) and update with the rooms ``t_r_c`` (Z,) [C] measured at its end;
        returns the state (2Z,)."""
        z_n = self.n_zones
        a, b_u, b_d = self.matrices
        x = a @ self._x + b_u @ heat_w + b_d @ d
        p = a @ self._p @ a.T + self.q
        gain = np.linalg.solve(p[:z_n, :z_n] + self.r * np.eye(z_n), p[:z_n, :]).T  # (2Z, Z)
        self._x = x + gain @ (np.asarray(t_r_c, dtype=float) - x[:z_n])
        i_kh = np.eye(2 * z_n)
        i_kh[:, :z_n] -= gain
        # Joseph form: stays symmetric positive definite in floating point.
        self._p = i_kh @ p @ i_kh.T + self.r * gain @ gain.T
        return self.state

    @property
    def state(self) -> np.ndarray:
        """(2Z,) the estimated rooms then masses [C] (NaN before :meth:`reset`)."""
        return self._x.copy()
