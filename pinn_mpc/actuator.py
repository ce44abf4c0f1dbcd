"""The actuator between the demanded electrical power and the heat the building receives.

``u`` and ``u_phys`` are ELECTRICAL power everywhere (data, models, KPIs, the objective's price
term). The building receives ``eta * gain(T_a) * u_phys`` watts of heat, where ``gain`` is

- ``ideal`` (the default): 1, an electric resistance heater (or, with eta = -COP, a cooling
  machine of constant COP), the package's behaviour before heat pumps;
- ``heat_pump``: the coefficient of performance of an air-source heat pump, a fixed fraction of
  the Carnot COP between the outdoor air and the supply (flow) temperature::

      COP(T_a) = carnot_efficiency * T_supply_K / (T_supply_K - T_a_K)

  clipped to ``[cop_min, cop_max]`` (and ``cop_max`` when T_a >= T_supply). This is the usual
  "exergetic efficiency" model of heat-pump COP (e.g. VDI 4650; Ruhnau, Hirth & Praktiknjo,
  "Time series of heat demand and heat pump efficiency for energy system modeling",
  Sci. Data 6, 189 (2019), who fit COP = 6.08 - 0.09 dT + 0.0005 dT^2 for air sources); with
  the defaults (35 C supply, 45 % of Carnot) it gives 3.96 at 0 C, 3.08 at -10 C and 5.55 at
  10 C outdoor air, typical of a floor-heated house.

``min_modulation`` (fraction of ``u_max_w``) is the lowest power the machine runs at. A demand
below it makes the machine cycle within the interval, as a real one does: on at the minimum for
the first ``round(n_sub u / p_min)`` substeps, then off, so the interval mean matches the demand
to a substep's share (1/30 of p_min at 30-min intervals and 1-min substeps) while the room sees
the on/off swing. 0 (the default) runs at any demand.

The COP depends on T_a only, held over a control interval, so for a given outdoor temperature
the building is still linear in electrical power: an RC MPC plans on ``B_u,k = COP(T_a,k) b``
with the COP evaluated on the forecast (its plan variable is the delivered heat, see
:mod:`controllers.rc_mpc.problem`) and the QP stays a QP.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pinn_mpc.errors import InputError

__all__ = ["ACTUATOR_KINDS", "Actuator", "CopCurve", "KELVIN"]

ACTUATOR_KINDS = ("ideal", "heat_pump")
KELVIN = 273.15


@dataclass(frozen=True, kw_only=True)
class Actuator:
    """How electrical power becomes heat (module docstring); the default is the ideal heater."""

    kind: str = "ideal"
    supply_temp_c: float = 35.0
    carnot_efficiency: float = 0.45
    cop_min: float = 1.0
    cop_max: float = 6.0
    min_modulation: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in ACTUATOR_KINDS:
            raise InputError(
                f"actuator.kind {self.kind!r} is unknown; choose one of {', '.join(ACTUATOR_KINDS)}"
            )
        checks = (
            ("supply_temp_c", 20.0, 80.0, "C (floor heating 30-35, radiators 45-70)"),
            ("carnot_efficiency", 0.05, 1.0, "(a fraction of the Carnot COP, typically 0.3-0.55)"),
            ("cop_min", 0.5, 10.0, ""),
            ("cop_max", 0.5, 10.0, ""),
        )
        for name, lo, hi, unit in checks:
            value = getattr(self, name)
            if isinstance(value, bool) or not (
                isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi
            ):
                raise InputError(f"actuator.{name} = {value!r} must lie in {lo:g} .. {hi:g} {unit}".rstrip())
        if not self.cop_min <= self.cop_max:
            raise InputError(
                f"actuator.cop_min = {self.cop_min} must not exceed cop_max = {self.cop_max}"
            )
        m = self.min_modulation
        if isinstance(m, bool) or not (isinstance(m, int | float) and math.isfinite(m) and 0 <= m < 1):
            raise InputError(
                f"actuator.min_modulation = {m!r} must lie in [0, 1) (a fraction of u_max_w)"
            )

    @property
    def is_ideal(self) -> bool:
        """True when heat = eta x electrical power at any power (today's behaviour)."""
        return self.kind == "ideal" and self.min_modulation == 0

    def gain(self, t_a_c: Any) -> np.ndarray:
        """Heat per electrical watt (before eta) at outdoor temperature ``t_a_c`` [C], same shape."""
        t_a = np.asarray(t_a_c, dtype=float)
        if self.kind == "ideal":
            return np.ones_like(t_a)
        t_supply_k = self.supply_temp_c + KELVIN
        lift_k = t_supply_k - (t_a + KELVIN)
        with np.errstate(divide="ignore", invalid="ignore"):
            carnot = np.where(lift_k > 0, t_supply_k / np.where(lift_k > 0, lift_k, 1.0), np.inf)
        return np.clip(self.carnot_efficiency * carnot, self.cop_min, self.cop_max)


@dataclass(frozen=True, kw_only=True)
class CopCurve:
    """Heat per electrical watt against outdoor temperature, as a data set shows it: piecewise
    linear through ``cop`` at knots ``t_a_c`` [C] (increasing), constant beyond the end knots
    (a model never extrapolates the COP past what its data saw)."""

    t_a_c: tuple[float, ...]
    cop: tuple[float, ...]

    def __post_init__(self) -> None:
        t, c = np.asarray(self.t_a_c, dtype=float), np.asarray(self.cop, dtype=float)
        if t.ndim != 1 or t.shape != c.shape or len(t) < 2:
            raise ValueError(
                f"COP curve needs two or more knots of equal length, got {len(t)} and {len(c)}"
            )
        if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
            raise ValueError(f"COP curve knots must be finite and increasing, got {list(t)}")
        if not (np.all(np.isfinite(c)) and np.all((c >= 0.1) & (c <= 20.0))):
            raise ValueError(f"COP curve values must lie in 0.1 .. 20, got {list(c)}")

    @classmethod
    def fit(cls, t_a_c: np.ndarray, cop: np.ndarray, *, n_knots: int = 12) -> CopCurve | None:
        """The curve through measured ``cop`` (heat per electrical watt, e.g. a ``cop`` column)
        at outdoor temperatures ``t_a_c``: least squares on a piecewise-linear basis with a
        small curvature penalty. None when the COP is 1 throughout (a resistance heater)."""
        t, c = np.asarray(t_a_c, dtype=float), np.asarray(cop, dtype=float)
        if np.allclose(c, 1.0):
            return None
        lo, hi = float(t.min()), float(t.max())
        if hi - lo < 1e-6:
            return cls(t_a_c=(lo - 0.5, lo + 0.5), cop=(float(c.mean()),) * 2)
        knots = np.linspace(lo, hi, n_knots)
        # Hat basis: column j is the linear interpolant of the j-th unit vector.
        basis = np.stack([np.interp(t, knots, np.eye(n_knots)[j]) for j in range(n_knots)], axis=1)
        curvature = np.diff(np.eye(n_knots), 2, axis=0) * np.sqrt(1e-3 * len(t))
        values = np.linalg.lstsq(
            np.vstack([basis, curvature]), np.concatenate([c, np.zeros(n_knots - 2)]), rcond=None
        )[0]
        values = np.clip(values, float(c.min()), float(c.max()))
        return cls(t_a_c=tuple(map(float, knots)), cop=tuple(map(float, values)))

    def __call__(self, t_a_c: Any) -> np.ndarray:
        """The COP at outdoor temperature(s) ``t_a_c`` [C], same shape."""
        return np.interp(np.asarray(t_a_c, dtype=float), self.t_a_c, self.cop)

    def to_dict(self) -> dict[str, list[float]]:
        return {"t_a_c": list(self.t_a_c), "cop": list(self.cop)}

    @classmethod
    def from_dict(cls, data: Any) -> CopCurve:
        try:
            return cls(t_a_c=tuple(map(float, data["t_a_c"])), cop=tuple(map(float, data["cop"])))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"COP curve must hold lists t_a_c and cop, got {data!r}") from exc
