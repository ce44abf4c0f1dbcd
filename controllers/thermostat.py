"""Hysteresis thermostat on the comfort band: the everyday baseline.

Heating: full power when the measured room temperature falls below ``c - hysteresis_k/2``,
off when it rises above ``c + hysteresis_k/2``, unchanged in between, where the centre
``c = T_min + offset_fraction * (T_max - T_min)`` (default a quarter of the band above its
lower edge, like :func:`controllers.base.fallback_power`). Cooling mirrors this on ``T_max``.
The band is the forecast's first interval, ``forecast.T_min[0]`` / ``forecast.T_max[0]``.
Deciding once per control interval at full power, it overshoots by up to the temperature
change of one interval; that is the baseline's nature, not a bug.

A building of several zones and actuators gets a thermostat per actuator on its own zone's
room temperature and band: a heater by the heating rule, a cooler by the cooling rule, so a
zone with both is a dual-setpoint thermostat (heating below a quarter of the band above its
lower edge, cooling above a quarter below its upper edge, a dead band between). ``act``
then returns (A,).
"""

from __future__ import annotations

import math
import time

import numpy as np

from controllers.base import ControlSpec, Forecast, Observation, SolveStats, current_band_c

__all__ = ["Thermostat"]


class Thermostat:
    """On/off rule; ``act`` returns the actuator's off or full power (``spec.actuator.on_off``)
    [W]. Deterministic; keeps one bit of state (on or off) between calls, cleared by ``reset``."""

    name = "thermostat"
    #: A rule on the measured room temperature: no model, no state estimate, nothing to trust.
    knows_true_state = False
    model = None
    trust_report = None

    def __init__(
        self, spec: ControlSpec, *, offset_fraction: float = 0.25, hysteresis_k: float = 0.5
    ):
        if not (0.0 <= offset_fraction <= 0.5):
            raise ValueError(f"Thermostat offset_fraction must lie in [0, 0.5], got {offset_fraction!r}")
        if not (math.isfinite(hysteresis_k) and hysteresis_k >= 0):
            raise ValueError(f"Thermostat hysteresis_k must be >= 0, got {hysteresis_k!r}")
        self.spec = spec
        self.offset_fraction = offset_fraction
        self.hysteresis_k = hysteresis_k
        self._on = False
        self._zone_on = np.zeros(spec.n_actuators, dtype=bool)  # each actuator's, several
        self._plan: np.ndarray | None = None
        self._stats = SolveStats(time_s=0.0, status="not run", iterations=0, fallback=False)

    def reset(self, seed: int | None = None) -> None:
        self._on = False
        self._zone_on = np.zeros(self.spec.n_actuators, dtype=bool)
        self._plan = None
        self._stats = SolveStats(time_s=0.0, status="not run", iterations=0, fallback=False)

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
        """(A,) each actuator's rule on its zone (module docstring)."""
        start = time.perf_counter()
        t_min, t_max = current_band_c(forecast, len(self.spec.zones))
        t_r = obs.t_r_zones_c()
        powers = np.empty(self.spec.n_actuators)
        for i, actuator in enumerate(self.spec.actuators):
            z = actuator.zone
            on = self.switch(
                t_r[z : z + 1], self._zone_on[i : i + 1], float(t_min[z]), float(t_max[z]), heats=actuator.heats
            )[0]
            self._zone_on[i] = on
            powers[i] = actuator.on_off(bool(on))
        self._plan = powers[None, :]
        self._stats = SolveStats(time_s=time.perf_counter() - start, status="rule", iterations=0, fallback=False)
        return powers

    @property
    def last_plan(self) -> np.ndarray | None:
        return self._plan

    @property
    def last_stats(self) -> SolveStats:
        return self._stats
