"""What every controller shares: observation, forecast, objective, protocol, fallback.

The objective is the same for every controller so comparisons are fair: over the horizon,
energy cost (price x delivered energy) plus ``comfort_weight`` x discomfort [K h], where the
discomfort of step j is the band violation of the room temperature at the end of interval j
(against the band of interval j) times the interval length in hours.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from pinn_mpc.errors import InputError


class Forecast(NamedTuple):
    """Exogenous inputs for the next H control intervals, each an array (H,)."""

    time_of_day_h: np.ndarray  # start of each interval, hours since midnight
    t_a_c: np.ndarray  # outdoor temperature [C]
    g_w_per_m2: np.ndarray  # global horizontal irradiance [W/m2]
    i_g_w: np.ndarray  # internal gains [W]
    price_eur_per_kwh: np.ndarray
    t_min_c: np.ndarray  # comfort band, lower [C]
    t_max_c: np.ndarray  # comfort band, upper [C]

    @property
    def horizon(self) -> int:
        return len(self.t_a_c)


class Observation(NamedTuple):
    """What a controller sees at the start of interval k.

    ``history`` holds the past in the data format's names: ``T_r`` (k+1,) measured room
    temperatures up to and including now; ``u`` and ``u_phys`` (k,) demanded and delivered power
    of past intervals [W]; ``T_a``, ``G``, ``I_g``, ``time_of_day_h`` (k+1,) up to now.
    ``t_m_true_c`` is the simulator's hidden thermal-mass temperature: only ``oracle`` may use it.
    """

    k: int
    t_r_c: float
    history: dict[str, np.ndarray]
    t_m_true_c: float


class SolveStats(NamedTuple):
    time_s: float
    status: str
    iterations: int
    fallback: bool


@dataclass(frozen=True, kw_only=True)
class ControlSpec:
    """Actuator and objective settings shared by all controllers of a run."""

    u_max_w: float
    dt_s: float = 1800.0
    horizon_steps: int = 48
    comfort_weight_eur_per_kh: float = 1.0
    heating: bool = True

    def __post_init__(self) -> None:
        if not (math.isfinite(self.u_max_w) and self.u_max_w > 0):
            raise InputError(f"ControlSpec.u_max_w must be positive, got {self.u_max_w!r}")
        if self.horizon_steps < 1:
            raise InputError(f"ControlSpec.horizon_steps must be >= 1, got {self.horizon_steps}")
        if not (self.comfort_weight_eur_per_kh >= 0):
            raise InputError(
                f"ControlSpec.comfort_weight_eur_per_kh must be >= 0, got {self.comfort_weight_eur_per_kh}"
            )

    @property
    def dt_h(self) -> float:
        return self.dt_s / 3600.0


def check_heating(eta: float, spec: ControlSpec, *, what: str) -> None:
    """Every controller given a model or RC parameters checks, at construction, that they heat
    (eta > 0) when the scenario's actuator heats and cool (eta < 0) when it cools."""
    if (eta > 0) == spec.heating:
        return
    if spec.heating:
        raise InputError(
            f"{what}: eta={eta:g}, a cooling machine, but the scenario's actuator is a heater; "
            "use a model or RC file made for heating (eta > 0)"
        )
    raise InputError(
        f"{what}: eta={eta:g}, a heater, but the scenario's actuator is a cooling machine; "
        "use cooling data with `train --eta -COP` or `identify --eta -COP` (e.g. -2.5)"
    )


def band_violation_k(t_r_c: np.ndarray, t_min_c: np.ndarray, t_max_c: np.ndarray) -> np.ndarray:
    """Elementwise violation of the comfort band [K], broadcasting."""
    return np.maximum(t_min_c - t_r_c, 0.0) + np.maximum(t_r_c - t_max_c, 0.0)


def first_values(values: np.ndarray, n: int) -> np.ndarray:
    """A fresh array of the first n values (n,), the last one repeated when there are fewer."""
    a = np.asarray(values, dtype=float).reshape(-1)
    if a.size == 0:
        raise InputError("forecast array is empty; the controller needs at least one step")
    if a.size >= n:
        return a[:n].copy()
    return np.concatenate([a, np.full(n - a.size, a[-1])])


def planning_band(forecast: Forecast, h: int) -> tuple[np.ndarray, np.ndarray]:
    """The band the room temperature at the end of each of the next h intervals must keep, (h,) each.

    The end of interval j is also the start of interval j+1, so it must lie in both bands: without
    this a planner arrives at 17 C exactly when a 20 C day band starts, and the closed-loop KPI
    (the time integral of the violation) charges the whole warm-up. The last value, with no next
    interval in the forecast, uses its own band.
    """
    t_min, t_max = first_values(forecast.t_min_c, h + 1), first_values(forecast.t_max_c, h + 1)
    lower = np.maximum(t_min[:-1], t_min[1:])
    upper = np.minimum(t_max[:-1], t_max[1:])
    return lower, upper


def plan_cost(
    u_phys_w: np.ndarray, t_r_next_c: np.ndarray, forecast: Forecast, spec: ControlSpec
) -> np.ndarray:
    """Objective of plans: arrays (..., H) of delivered power and end-of-interval T_r -> (...,) [EUR].

    Discomfort is measured against :func:`planning_band`.
    """
    h = u_phys_w.shape[-1]
    energy_kwh = u_phys_w / 1000.0 * spec.dt_h
    cost = energy_kwh * forecast.price_eur_per_kwh[:h]
    lower, upper = planning_band(forecast, h)
    violation = band_violation_k(t_r_next_c, lower, upper)
    return np.sum(cost + spec.comfort_weight_eur_per_kh * violation * spec.dt_h, axis=-1)


@runtime_checkable
class Controller(Protocol):
    """``reset`` then ``act`` once per control interval; ``act`` returns demanded power [W]."""

    name: str

    def reset(self, seed: int | None = None) -> None: ...

    def act(self, obs: Observation, forecast: Forecast) -> float: ...

    @property
    def last_plan(self) -> np.ndarray | None: ...

    @property
    def last_stats(self) -> SolveStats: ...


def fallback_power(obs: Observation, forecast: Forecast, spec: ControlSpec) -> float:
    """The documented safe action when a solver fails or a model output is not finite.

    A band-keeping rule on the measured room temperature: full power when the room is in the
    lower (heating) or upper (cooling) quarter of the band or beyond it, otherwise off.
    """
    t_min, t_max = float(forecast.t_min_c[0]), float(forecast.t_max_c[0])
    quarter = 0.25 * (t_max - t_min)
    if spec.heating:
        return spec.u_max_w if obs.t_r_c < t_min + quarter else 0.0
    return spec.u_max_w if obs.t_r_c > t_max - quarter else 0.0
