"""The control objective over a horizon, one definition for every user.

Over H intervals j: ``price_j x delivered electrical energy_j [kWh] + comfort_weight x
violation_j [K] x dt_h`` (the energy is the actuator's electrical input, ``u_phys``; a heat
pump's heat is COP times it, :mod:`pinn_mpc.actuator`), where ``violation_j`` is the band violation of the room temperature at the end of
interval j. Built once per decision (:meth:`HorizonObjective.from_forecast`, with
:func:`planning_band`); the sampling planners evaluate it in torch, tests and reports in numpy,
the RC MPCs take its arrays as QP data, the Gymnasium reward is the one-interval objective and
the closed-loop KPIs integrate the same primitives (:func:`band_violation_k`,
:func:`energy_cost_eur`) at the simulator's substep resolution.

A building of several zones (:class:`ZoneObjective`) pays the price on its total electrical
power and each zone's band violation, summed over the zones (as the closed-loop KPIs sum a
building's discomfort); each zone's band is :func:`planning_band` of its own
(:func:`zone_bands`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Self

import numpy as np

from controllers.base import ControlSpec, Forecast, first_values
from pinn_mpc.errors import InternalError
from pinn_mpc.zones import ZoneSpec

if TYPE_CHECKING:
    import torch

__all__ = [
    "OPEN_BAND_C",
    "HorizonObjective",
    "ZoneObjective",
    "band_violation_k",
    "comfort_cost_torch",
    "cost_torch",
    "energy_cost_eur",
    "narrowed",
    "narrowed_band",
    "planning_band",
    "zone_bands",
]

#: A comfort band that never binds (after the run end of the clairvoyant).
OPEN_BAND_C = (-100.0, 200.0)


def band_violation_k(t_r_c: Any, t_min_c: Any, t_max_c: Any) -> Any:
    """Elementwise violation of the comfort band [K], broadcasting (numpy arrays)."""
    return np.maximum(t_min_c - t_r_c, 0.0) + np.maximum(t_r_c - t_max_c, 0.0)


def energy_cost_eur(u_phys_w: Any, price_eur_per_kwh: Any, dt_h: float) -> Any:
    """Elementwise cost of ``u_phys_w`` [W] electrical power for ``dt_h`` hours [EUR] (numpy or torch)."""
    return u_phys_w * (dt_h / 1000.0) * price_eur_per_kwh


def narrowed_band(
    t_min_c: np.ndarray, t_max_c: np.ndarray, margin_k: float | np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The band ``(t_min_c, t_max_c)`` [C] narrowed by ``margin_k`` [K] on each side, to its
    middle where it is narrower than twice the margin (arrays broadcasting: a fleet's margins
    are each building's)."""
    middle = 0.5 * (t_min_c + t_max_c)
    return np.minimum(t_min_c + margin_k, middle), np.maximum(t_max_c - margin_k, middle)


def narrowed(forecast: Forecast, margin_k: float) -> Forecast:
    """``forecast`` with its comfort band narrowed by ``margin_k`` [K] (:func:`narrowed_band`)."""
    t_min, t_max = narrowed_band(
        np.asarray(forecast.T_min, dtype=float), np.asarray(forecast.T_max, dtype=float), margin_k
    )
    return forecast._replace(T_min=t_min, T_max=t_max)


def planning_band(forecast: Forecast, h: int) -> tuple[np.ndarray, np.ndarray]:
    """The band the room temperature at the end of each of the next h intervals must keep, (h,) each.

    The end of interval j is also the start of interval j+1, so it must lie in both bands: without
    this a planner arrives at 17 C exactly when a 20 C day band starts, and the closed-loop KPI
    (the time integral of the violation) charges the whole warm-up. The last value, with no next
    interval in the forecast, uses its own band.
    """
    t_min, t_max = first_values(forecast.T_min, h + 1), first_values(forecast.T_max, h + 1)
    lower = np.maximum(t_min[:-1], t_min[1:])
    upper = np.minimum(t_max[:-1], t_max[1:])
    return lower, upper


def zone_bands(forecast: Forecast, zones: tuple[ZoneSpec, ...], h: int) -> tuple[np.ndarray, np.ndarray]:
    """(h, Z) the band each zone's room keeps at the end of each of the next h intervals [C]:
    :func:`planning_band` of the zone's forecast band, which is (H',) for every zone or (H', Z)
    each zone's. A ValueError names a band of another shape."""
    z_n = len(zones)
    t_min, t_max = (np.asarray(b, dtype=float) for b in (forecast.T_min, forecast.T_max))
    for name, b in (("T_min", t_min), ("T_max", t_max)):
        if not (b.ndim == 1 or (b.ndim == 2 and b.shape[1] == z_n)) or b.shape[0] == 0:
            raise ValueError(
                f"forecast.{name} has shape {b.shape}; give (H,) for every zone or (H, {z_n}), "
                f"one column per zone of {', '.join(z.name for z in zones)}"
            )
    lower, upper = np.empty((h, z_n)), np.empty((h, z_n))
    for z in range(z_n):
        zone = forecast._replace(
            T_min=t_min if t_min.ndim == 1 else t_min[:, z],
            T_max=t_max if t_max.ndim == 1 else t_max[:, z],
        )
        lower[:, z], upper[:, z] = planning_band(zone, h)
    return lower, upper


@dataclass(frozen=True, kw_only=True)
class HorizonObjective:
    """The objective of H intervals: price [EUR/kWh] and band [C] arrays (H,), weights."""

    price_eur_per_kwh: np.ndarray
    t_min_c: np.ndarray
    t_max_c: np.ndarray
    dt_h: float
    comfort_weight_eur_per_kh: float

    def __post_init__(self) -> None:
        shapes = {np.shape(a) for a in (self.price_eur_per_kwh, self.t_min_c, self.t_max_c)}
        if len(shapes) != 1 or len(next(iter(shapes))) != 1:
            raise InternalError(
                f"HorizonObjective: price and band must be arrays of one shape (H,), got {shapes}"
            )

    @classmethod
    def from_forecast(cls, forecast: Forecast, spec: ControlSpec, horizon_steps: int) -> Self:
        """The objective of the next ``horizon_steps`` intervals: the forecast's price and
        :meth:`bands` (a shorter forecast repeats its last value)."""
        lower, upper = cls.bands(forecast, spec, horizon_steps)
        return cls(
            price_eur_per_kwh=first_values(forecast.price, horizon_steps),
            t_min_c=lower,
            t_max_c=upper,
            dt_h=spec.dt_h,
            comfort_weight_eur_per_kh=spec.comfort_weight_eur_per_kh,
        )

    @classmethod
    def bands(cls, forecast: Forecast, spec: ControlSpec, horizon_steps: int) -> tuple[np.ndarray, np.ndarray]:
        """The band (:func:`planning_band`), (H,) each."""
        return planning_band(forecast, horizon_steps)

    @property
    def horizon_steps(self) -> int:
        return len(self.price_eur_per_kwh)

    def until(self, n_active: int) -> HorizonObjective:
        """The objective with nothing to pay for after ``n_active`` steps (zero price, a band
        that never binds): the shrinking horizon of a run that ends there."""
        if n_active >= self.horizon_steps:
            return self
        price, t_min, t_max = (
            np.array(a) for a in (self.price_eur_per_kwh, self.t_min_c, self.t_max_c)
        )
        price[n_active:] = 0.0
        t_min[n_active:], t_max[n_active:] = OPEN_BAND_C
        return dataclasses.replace(self, price_eur_per_kwh=price, t_min_c=t_min, t_max_c=t_max)

    def tightened(self, margin_k: float) -> HorizonObjective:
        """The objective with the band narrowed by ``margin_k`` [K] on each side (to its middle
        where it is narrower than twice the margin): constraint tightening for a planner whose
        model is off by a few millikelvin."""
        if margin_k == 0:
            return self
        t_min, t_max = narrowed_band(self.t_min_c, self.t_max_c, margin_k)
        return dataclasses.replace(self, t_min_c=t_min, t_max_c=t_max)

    def stage_costs(self, u_phys_w: np.ndarray, t_r_c: np.ndarray) -> np.ndarray:
        """Cost of each interval (..., H) [EUR] of delivered electrical power and end-of-interval T_r (..., H)."""
        h = self.horizon_steps
        violation = band_violation_k(np.asarray(t_r_c, dtype=float), self.t_min_c, self.t_max_c)
        energy = energy_cost_eur(np.asarray(u_phys_w, dtype=float), self.price_eur_per_kwh, self.dt_h)
        if np.shape(violation)[-1] != h:
            raise InternalError(f"HorizonObjective: predictions must end in H={h}, got {np.shape(t_r_c)}")
        return energy + self.comfort_weight_eur_per_kh * self.dt_h * violation

    def cost(self, u_phys_w: np.ndarray, t_r_c: np.ndarray) -> np.ndarray:
        """The objective (...,) [EUR] of predictions (..., H) (numpy, float64)."""
        return np.sum(self.stage_costs(u_phys_w, t_r_c), axis=-1)

    def cost_torch(self, u_phys_w: torch.Tensor, t_r_c: torch.Tensor) -> torch.Tensor:
        """The objective (...,) [EUR] of predictions (..., H) in torch, in their dtype."""
        import torch

        dtype = t_r_c.dtype
        price, t_min, t_max = (
            torch.as_tensor(a, dtype=dtype) for a in (self.price_eur_per_kwh, self.t_min_c, self.t_max_c)
        )
        return cost_torch(u_phys_w, t_r_c, price, t_min, t_max, self.dt_h, self.comfort_weight_eur_per_kh)


def comfort_cost_torch(
    t_r_c: torch.Tensor, t_min_c: torch.Tensor, t_max_c: torch.Tensor, dt_h: float, comfort_weight_eur_per_kh: float
) -> torch.Tensor:
    """The comfort term of each interval (..., H) [EUR] of end-of-interval T_r (..., H) in a
    band (tensors broadcasting against it: a fleet's bands are each building's)."""
    violation = (t_min_c - t_r_c).relu_() + (t_r_c - t_max_c).relu_()
    return violation.mul_(comfort_weight_eur_per_kh * dt_h)  # in place: a fleet's are large


def cost_torch(
    u_phys_w: torch.Tensor,
    t_r_c: torch.Tensor,
    price_eur_per_kwh: torch.Tensor,
    t_min_c: torch.Tensor,
    t_max_c: torch.Tensor,
    dt_h: float,
    comfort_weight_eur_per_kh: float,
) -> torch.Tensor:
    """The objective (...,) [EUR] of predictions (..., H) under a price and band (tensors
    broadcasting against them; :meth:`HorizonObjective.cost_torch` is one building's)."""
    step_cost = energy_cost_eur(u_phys_w, price_eur_per_kwh, dt_h) + comfort_cost_torch(
        t_r_c, t_min_c, t_max_c, dt_h, comfort_weight_eur_per_kh
    )
    return step_cost.sum(dim=-1)


@dataclass(frozen=True, kw_only=True)
class ZoneObjective(HorizonObjective):
    """The objective of H intervals of a building of Z zones: the price (H,) [EUR/kWh] of the
    building's total electrical energy and each zone's band ``t_min_c``, ``t_max_c`` (H, Z) [C]
    (module docstring); its predictions are the total delivered power (..., H) [W] and each
    zone's end-of-interval T_r (..., H, Z) [C]."""

    def __post_init__(self) -> None:
        h = np.shape(self.price_eur_per_kwh)
        bands = {np.shape(self.t_min_c), np.shape(self.t_max_c)}
        band = next(iter(bands))
        if len(h) != 1 or len(bands) != 1 or len(band) != 2 or band[0] != h[0]:
            raise InternalError(f"ZoneObjective: price (H,) and bands (H, Z), got {h} and {sorted(bands)}")

    @classmethod
    def bands(cls, forecast: Forecast, spec: ControlSpec, horizon_steps: int) -> tuple[np.ndarray, np.ndarray]:
        """Each zone's band of ``spec``'s zones (:func:`zone_bands`), (H, Z) each."""
        return zone_bands(forecast, spec.zones, horizon_steps)

    def tightened_zones(self, margins_k: np.ndarray) -> ZoneObjective:
        """The objective with each zone's band narrowed by its margin ``margins_k`` (Z,) [K] on
        each side (to its middle where it is narrower than twice the margin)."""
        margins = np.asarray(margins_k, dtype=float)
        if margins.shape != (np.shape(self.t_min_c)[1],):
            raise InternalError(f"ZoneObjective: one margin per zone, got {margins.shape} for bands {np.shape(self.t_min_c)}")
        if not np.any(margins):
            return self
        t_min, t_max = narrowed_band(self.t_min_c, self.t_max_c, margins)
        return dataclasses.replace(self, t_min_c=t_min, t_max_c=t_max)

    def stage_costs(self, u_phys_w: np.ndarray, t_r_c: np.ndarray) -> np.ndarray:
        """Cost of each interval (..., H) [EUR] of the total delivered power (..., H) and each
        zone's end-of-interval T_r (..., H, Z), the zones' violations summed."""
        violation = band_violation_k(np.asarray(t_r_c, dtype=float), self.t_min_c, self.t_max_c).sum(axis=-1)
        energy = energy_cost_eur(np.asarray(u_phys_w, dtype=float), self.price_eur_per_kwh, self.dt_h)
        return energy + self.comfort_weight_eur_per_kh * self.dt_h * violation

    def cost_torch(self, u_phys_w: torch.Tensor, t_r_c: torch.Tensor) -> torch.Tensor:
        """The objective (...,) [EUR] in torch, in the predictions' dtype (:meth:`stage_costs`)."""
        import torch

        dtype = t_r_c.dtype
        price, t_min, t_max = (
            torch.as_tensor(a, dtype=dtype) for a in (self.price_eur_per_kwh, self.t_min_c, self.t_max_c)
        )
        comfort = comfort_cost_torch(t_r_c, t_min, t_max, self.dt_h, self.comfort_weight_eur_per_kh).sum(dim=-1)
        return (energy_cost_eur(u_phys_w, price, self.dt_h) + comfort).sum(dim=-1)
