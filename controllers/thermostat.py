"""Hysteresis thermostat on the comfort band: the everyday baseline.

Heating: full power when the measured room temperature falls below ``c - hysteresis_k/2``,
off when it rises above ``c + hysteresis_k/2``, unchanged in between, where the centre
``c = T_min + offset_fraction * (T_max - T_min)`` (default a quarter of the band above its
lower edge, like :func:`controllers.base.fallback_power`). Cooling mirrors this on ``T_max``.
The band is the forecast's first interval, ``forecast.T_min[0]`` / ``forecast.T_max[0]``.
Deciding once per control interval at full power, it overshoots by up to the temperature
change of one interval; that is the baseline's nature, not a bug.

A building of several zones or actuators gets a dual-setpoint thermostat per zone, on the
zone's own room temperature and band, ``act`` returning (A,):

- Setpoints: heating ``c_heat = T_min + offset_fraction * (T_max - T_min)``, cooling
  ``c_cool = T_max - offset_fraction * (T_max - T_min)``; the dead band lies between.
- Mode: each zone heats or cools, never both. It enters heating when its room falls below
  ``c_heat - hysteresis_k/2`` and cooling when it rises above ``c_cool + hysteresis_k/2``,
  and keeps its mode otherwise: the mode changes only when the zone leaves the dead band on
  the other side (no timed lockout). The actuators of the other mode are off (their lower
  bound) and start afresh when their mode comes.
- Stage: ``proportional_band_k = 0`` runs the active actuators on/off with the one-zone rule
  (:meth:`Thermostat.switch`). ``proportional_band_k > 0`` modulates them by an incremental
  PI law on the error to the mode's setpoint (``e = c_heat - T_r`` heating, ``T_r - c_cool``
  cooling) [K]: the fraction of the way from the lower to the upper bound moves by
  ``(e_k - e_{k-1} + dt / integral_time_s * e_k) / proportional_band_k`` every interval and
  is clipped to [0, 1] (no wind-up), starting from 0 (with ``e_{-1} = 0``) when the mode
  begins. It holds the zone at the setpoint without the full-power overshoot of an on/off
  stage when a zone's air answers within one interval, as an EnergyPlus zone does.
"""

from __future__ import annotations

import math
import time

import numpy as np

from controllers.base import ControlSpec, Forecast, Observation, SolveStats, current_band_c

__all__ = ["INTEGRAL_TIME_S", "PROPORTIONAL_BAND_K", "Thermostat"]

#: The zoned thermostat's modulating stage (module docstring): its proportional band [K] and
#: integral time [s].
PROPORTIONAL_BAND_K = 30.0
INTEGRAL_TIME_S = 600.0


class Thermostat:
    """On/off rule; ``act`` returns the actuator's off or full power (``spec.actuator.on_off``)
    [W]. Deterministic; keeps one bit of state (on or off) between calls, cleared by ``reset``.
    A building of several zones or actuators gets the dual-setpoint thermostat per zone
    (module docstring): ``act`` returns (A,) [W], the state kept is each zone's mode and each
    actuator's stage."""

    name = "thermostat"
    #: A rule on the measured room temperature: no model, no state estimate, nothing to trust.
    knows_true_state = False
    model = None
    trust_report = None

    def __init__(
        self, spec: ControlSpec, *, offset_fraction: float = 0.25, hysteresis_k: float = 0.5,
        proportional_band_k: float = PROPORTIONAL_BAND_K, integral_time_s: float = INTEGRAL_TIME_S,
    ):
        if not (0.0 <= offset_fraction <= 0.5):
            raise ValueError(f"Thermostat offset_fraction must lie in [0, 0.5], got {offset_fraction!r}")
        if not (math.isfinite(hysteresis_k) and hysteresis_k >= 0):
            raise ValueError(f"Thermostat hysteresis_k must be >= 0, got {hysteresis_k!r}")
        if not (math.isfinite(proportional_band_k) and proportional_band_k >= 0):
            raise ValueError(
                f"Thermostat proportional_band_k must be finite and >= 0 [K] (0: on/off), got {proportional_band_k!r}"
            )
        if not (math.isfinite(integral_time_s) and integral_time_s > 0):
            raise ValueError(
                f"Thermostat integral_time_s must be finite and > 0 [s], got {integral_time_s!r}"
            )
        self.spec = spec
        self.offset_fraction = offset_fraction
        self.hysteresis_k = hysteresis_k
        self.proportional_band_k = proportional_band_k
        self.integral_time_s = integral_time_s
        self._zone_of = np.array([a.zone for a in spec.actuators])  # (A,) each actuator's zone
        self._heats = np.array([a.heats for a in spec.actuators])  # (A,)
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        self._on = False
        n_zones, n_actuators = len(self.spec.zones), self.spec.n_actuators
        self._zone_on = np.zeros(n_actuators, dtype=bool)  # each actuator's on/off stage
        self._mode = np.zeros(n_zones, dtype=int)  # each zone's: 1 heating, -1 cooling, 0 neither yet
        self._fraction = np.zeros(n_actuators)  # each actuator's modulating stage, of its span
        self._error_k = np.zeros(n_actuators)  # each actuator's last error [K]
        self._plan: np.ndarray | None = None
        self._stats = SolveStats(time_s=0.0, status="not run", iterations=0, fallback=False)

    @property
    def zone_modes(self) -> np.ndarray:
        """(Z,) each zone's mode after the last decision: 1 heating, -1 cooling, 0 neither yet."""
        return self._mode.copy()

    def thresholds_c(self, t_min_c: float, t_max_c: float, *, heats: bool | None = None) -> tuple[float, float]:
        """(switch-on, switch-off) room temperatures [C] for this band, of a heater or a
        cooler (``heats``; None: the building's one actuator)."""
        half = 0.5 * self.hysteresis_k
        offset = self.offset_fraction * (t_max_c - t_min_c)
        if self.spec.actuator.heats if heats is None else heats:
            return t_min_c + offset - half, t_min_c + offset + half
        return t_max_c - offset + half, t_max_c - offset - half

    def switch(
        self, t_r_c: np.ndarray, was_on: np.ndarray, t_min_c: float, t_max_c: float,
        *, heats: bool | None = None,
    ) -> np.ndarray:
        """The rule for a batch: room temperatures (B,) [C] and states (B,) bool -> on (B,) bool,
        of a heater or a cooler (``heats``; None: the building's one actuator).

        Stateless, so data generation can run it over many buildings at once.
        """
        heats = self.spec.actuator.heats if heats is None else heats
        on_at, off_at = self.thresholds_c(t_min_c, t_max_c, heats=heats)
        if heats:
            return (t_r_c < on_at) | (was_on & (t_r_c <= off_at))
        return (t_r_c > on_at) | (was_on & (t_r_c >= off_at))

    def act(self, obs: Observation, forecast: Forecast) -> float | np.ndarray:
        if not self.spec.single:
            return self._act_zones(obs, forecast)
        start = time.perf_counter()
        band = float(forecast.T_min[0]), float(forecast.T_max[0])
        self._on = bool(self.switch(np.array([obs.t_r_c]), np.array([self._on]), *band)[0])
        power = self.spec.actuator.on_off(self._on)
        self._plan = np.array([power])
        self._stats = SolveStats(
            time_s=time.perf_counter() - start, status="rule", iterations=0, fallback=False
        )
        return power

    def _act_zones(self, obs: Observation, forecast: Forecast) -> np.ndarray:
        """(A,) the dual-setpoint thermostat of each zone (module docstring)."""
        start = time.perf_counter()
        t_min, t_max = current_band_c(forecast, len(self.spec.zones))  # (Z,) each
        t_r = obs.t_r_zones_c()  # (Z,)
        offset = self.offset_fraction * (t_max - t_min)
        heat_c, cool_c = t_min + offset, t_max - offset  # (Z,) the setpoints
        half = 0.5 * self.hysteresis_k
        mode = np.where(t_r < heat_c - half, 1, np.where(t_r > cool_c + half, -1, self._mode))
        self._mode = mode
        active = mode[self._zone_of] == np.where(self._heats, 1, -1)  # (A,)
        powers = np.empty(self.spec.n_actuators)
        for i, actuator in enumerate(self.spec.actuators):
            z = actuator.zone
            if not active[i]:  # off, to start afresh when its mode comes
                self._zone_on[i], self._fraction[i], self._error_k[i] = False, 0.0, 0.0
                powers[i] = actuator.lower_w
            elif self.proportional_band_k == 0.0:
                on = self.switch(
                    t_r[z : z + 1], self._zone_on[i : i + 1], float(t_min[z]), float(t_max[z]), heats=actuator.heats
                )[0]
                self._zone_on[i] = on
                powers[i] = actuator.on_off(bool(on))
            else:
                error = float(heat_c[z] - t_r[z] if actuator.heats else t_r[z] - cool_c[z])
                step = error - self._error_k[i] + self.spec.dt_s / self.integral_time_s * error
                self._fraction[i] = min(max(self._fraction[i] + step / self.proportional_band_k, 0.0), 1.0)
                self._error_k[i] = error
                powers[i] = actuator.at_fraction(self._fraction[i])
        self._plan = powers[None, :]
        self._stats = SolveStats(time_s=time.perf_counter() - start, status="rule", iterations=0, fallback=False)
        return powers

    @property
    def last_plan(self) -> np.ndarray | None:
        return self._plan

    @property
    def last_stats(self) -> SolveStats:
        return self._stats
