"""Hysteresis thermostat on the comfort band: the everyday baseline.

Heating: full power when the measured room temperature falls below ``c - hysteresis_k/2``,
off when it rises above ``c + hysteresis_k/2``, unchanged in between, where the centre
``c = T_min + offset_fraction * (T_max - T_min)`` (default a quarter of the band above its
lower edge, like :func:`controllers.base.fallback_power`). Cooling mirrors this on ``T_max``.
The band is the forecast's first interval, ``forecast.T_min[0]`` / ``forecast.T_max[0]``.
Deciding once per control interval at full power, it overshoots by up to the temperature
change of one interval; that is the baseline's nature, not a bug.
"""

from __future__ import annotations

import math
import time

import numpy as np

from controllers.base import ControlSpec, Forecast, Observation, SolveStats

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
        self._plan: np.ndarray | None = None
        self._stats = SolveStats(time_s=0.0, status="not run", iterations=0, fallback=False)

    def reset(self, seed: int | None = None) -> None:
        self._on = False
        self._plan = None
        self._stats = SolveStats(time_s=0.0, status="not run", iterations=0, fallback=False)

    def thresholds_c(self, t_min_c: float, t_max_c: float) -> tuple[float, float]:
        """(switch-on, switch-off) room temperatures [C] for this band."""
        half = 0.5 * self.hysteresis_k
        offset = self.offset_fraction * (t_max_c - t_min_c)
        if self.spec.actuator.heats:
            return t_min_c + offset - half, t_min_c + offset + half
        return t_max_c - offset + half, t_max_c - offset - half

    def switch(
        self, t_r_c: np.ndarray, was_on: np.ndarray, t_min_c: float, t_max_c: float
    ) -> np.ndarray:
        """The rule for a batch: room temperatures (B,) [C] and states (B,) bool -> on (B,) bool.

        Stateless, so data generation can run it over many buildings at once.
        """
        on_at, off_at = self.thresholds_c(t_min_c, t_max_c)
        if self.spec.actuator.heats:
            return (t_r_c < on_at) | (was_on & (t_r_c <= off_at))
        return (t_r_c > on_at) | (was_on & (t_r_c >= off_at))

    def act(self, obs: Observation, forecast: Forecast) -> float:
        start = time.perf_counter()
        band = float(forecast.T_min[0]), float(forecast.T_max[0])
        self._on = bool(self.switch(np.array([obs.t_r_c]), np.array([self._on]), *band)[0])
        power = self.spec.actuator.on_off(self._on)
        self._plan = np.array([power])
        self._stats = SolveStats(
            time_s=time.perf_counter() - start, status="rule", iterations=0, fallback=False
        )
        return power

    @property
    def last_plan(self) -> np.ndarray | None:
        return self._plan

    @property
    def last_stats(self) -> SolveStats:
        return self._stats
