"""The actuators a controller sets: their bounds, what they act on, and how their electrical power
becomes heat.

:class:`ActuatorSpec` declares one actuator: its electrical power's bounds ``[lower_w,
upper_w]`` [W], whether it heats or cools, the zone it acts on, and its efficiency (an
:class:`Actuator`, below). It is the one place a control input's bounds are written: a clip, a
planner's box, a QP's bounds, the on and off of an on/off rule and the backup thermostat's
forced power all ask it. Cooling is an actuator of its own, never a negative power: its
electrical power lies in ``[lower_w, upper_w]`` with ``lower_w >= 0`` like a heater's, and its
effect on the zone is negative (``heats=False``; the building's ``eta < 0``), so the price
applies to the power as it is and a zone may have a heater and a cooler at once, each with its
own bounds and efficiency (``docs/layout.md`` says why). Today's buildings have one zone and one
actuator, a heater or a cooling machine (``SimConfig.actuators``, ``ControlSpec.actuators``).

:class:`Actuator` is an actuator's efficiency: how its electrical power becomes heat.

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
  10 C outdoor air, typical of a floor-heated house;
- ``chiller``: a cooling machine's energy efficiency ratio (heat removed per electrical watt),
  the same fraction of the Carnot EER between the chilled supply and the outdoor air::

      EER(T_a) = carnot_efficiency * T_supply_K / (T_a_K - T_supply_K)

  clipped to ``[cop_min, cop_max]`` (``cop_max`` when T_a <= T_supply); e.g. a 12 C supply at
  30 % of Carnot gives 4.8 at 30 C and 3.8 at 35 C outdoor air. A multi-zone building's
  cooling actuators take it (:mod:`pinn_mpc.multizone`); the one-zone building's cooling
  machine keeps its COP in ``-eta`` with the ideal efficiency.

``min_modulation`` (a fraction of the upper bound, ``u_max_w``) is the lowest power the machine
runs at. A demand below it makes the machine cycle within the interval, as a real one does: on
at the minimum for
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
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, overload

import numpy as np

from pinn_mpc.errors import InputError

__all__ = ["ACTUATOR_KINDS", "ACTUATOR_SERIES", "Actuator", "ActuatorSpec", "CopCurve", "KELVIN", "actuator_columns"]

ACTUATOR_KINDS = ("ideal", "heat_pump", "chiller")
KELVIN = 273.15
#: The data format's series that a building has once per actuator: the demanded and the
#: delivered electrical power [W].
ACTUATOR_SERIES = ("u", "u_phys")
#: An actuator's name, as a zone's (:mod:`pinn_mpc.zones`): it names data columns.
_NAME = re.compile(r"[A-Za-z0-9_.\-]+")


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
        supply = (
            ("supply_temp_c", 4.0, 20.0, "C for a chiller (chilled water 6-12, chilled ceilings 16-18)")
            if self.kind == "chiller"
            else ("supply_temp_c", 20.0, 80.0, "C (floor heating 30-35, radiators 45-70)")
        )
        checks = (
            supply,
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
        # The lift from the cold side to the warm: supply to outdoor air for a chiller (its EER,
        # Carnot T_cold / (T_hot - T_cold)), outdoor air to supply for a heat pump.
        lift_k = (t_a + KELVIN) - t_supply_k if self.kind == "chiller" else t_supply_k - (t_a + KELVIN)
        with np.errstate(divide="ignore", invalid="ignore"):
            carnot = np.where(lift_k > 0, t_supply_k / np.where(lift_k > 0, lift_k, 1.0), np.inf)
        return np.clip(self.carnot_efficiency * carnot, self.cop_min, self.cop_max)


@dataclass(frozen=True, kw_only=True)
class ActuatorSpec:
    """One actuator a controller sets (module docstring): electrical power in ``[lower_w,
    upper_w]`` [W], heating (``heats``) or cooling the zone ``zone``, with the efficiency
    ``efficiency`` (the ideal heater by default). Every bound of its power is asked of it:
    :meth:`clip`, :meth:`clip_kw`, :meth:`on_off`, :meth:`at_fraction` and the bounds
    themselves (a planner's box, a QP's rows)."""

    upper_w: float
    lower_w: float = 0.0
    heats: bool = True
    zone: int = 0
    efficiency: Actuator = field(default_factory=Actuator)
    #: Its name in the data (``u[<name>]``, ``u_phys[<name>]``) where a building has several
    #: actuators; "" for a building's one actuator, whose columns are ``u`` and ``u_phys``.
    name: str = ""

    def __post_init__(self) -> None:
        lo, hi = self.lower_w, self.upper_w
        if not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in (lo, hi)):
            raise ValueError(f"ActuatorSpec bounds must be finite numbers [W], got lower_w={lo!r}, upper_w={hi!r}")
        if not 0 <= lo < hi:
            raise ValueError(
                f"ActuatorSpec bounds need 0 <= lower_w < upper_w (electrical power; cooling is an "
                f"actuator of its own with heats=False), got lower_w={lo!r}, upper_w={hi!r}"
            )
        if not isinstance(self.heats, bool):
            raise TypeError(f"ActuatorSpec.heats must be True (heats) or False (cools), got {self.heats!r}")
        if isinstance(self.zone, bool) or not isinstance(self.zone, int) or self.zone < 0:
            raise ValueError(f"ActuatorSpec.zone must be a zone index >= 0, got {self.zone!r}")
        if not (isinstance(self.name, str) and (self.name == "" or _NAME.fullmatch(self.name))):
            raise ValueError(
                f"ActuatorSpec.name must be letters, digits, '_', '-' or '.' (it names the data "
                f"columns u[<name>]), got {self.name!r}"
            )
        if self.efficiency.kind == "heat_pump" and not self.heats:
            raise ValueError(
                "ActuatorSpec: a heat_pump efficiency heats, but heats=False; give a cooling "
                "machine the chiller efficiency (or the ideal one, its COP the building's -eta)"
            )
        if self.efficiency.kind == "chiller" and self.heats:
            raise ValueError("ActuatorSpec: a chiller efficiency cools, but heats=True; give heats=False")

    @property
    def span_w(self) -> float:
        """``upper_w - lower_w`` [W]: the range of its power."""
        return self.upper_w - self.lower_w

    @property
    def lower_kw(self) -> float:
        """``lower_w`` in kW (the QPs' unit)."""
        return self.lower_w / 1000.0

    @property
    def upper_kw(self) -> float:
        """``upper_w`` in kW (the QPs' unit)."""
        return self.upper_w / 1000.0

    @property
    def sign(self) -> float:
        """The sign of its effect on the zone's temperature: 1 heating, -1 cooling."""
        return 1.0 if self.heats else -1.0

    @property
    def min_power_w(self) -> float:
        """The lowest power it runs at [W] (``efficiency.min_modulation`` of ``upper_w``);
        below it the machine cycles within an interval."""
        return self.efficiency.min_modulation * self.upper_w

    @property
    def is_ideal(self) -> bool:
        """Whether its heat is ``eta`` x its power at any power (:attr:`Actuator.is_ideal`)."""
        return self.efficiency.is_ideal

    def gain(self, t_a_c: Any) -> np.ndarray:
        """Heat per electrical watt (before eta) at outdoor temperature ``t_a_c`` [C]
        (:meth:`Actuator.gain`), same shape."""
        return self.efficiency.gain(t_a_c)

    @overload
    def clip(self, u_w: float) -> float: ...

    @overload
    def clip(self, u_w: np.ndarray) -> np.ndarray: ...

    def clip(self, u_w: float | np.ndarray) -> float | np.ndarray:
        """``u_w`` [W] (a number or an array) within ``[lower_w, upper_w]``."""
        return np.clip(u_w, self.lower_w, self.upper_w)

    def clip_kw(self, p_kw: np.ndarray) -> np.ndarray:
        """``p_kw`` [kW] within ``[lower_kw, upper_kw]``: a QP's plan clipped in the QP's unit,
        before it is turned into watts (the order of arithmetic its results were made in)."""
        return np.clip(p_kw, self.lower_kw, self.upper_kw)

    @overload
    def on_off(self, on: bool | np.bool_) -> float: ...

    @overload
    def on_off(self, on: np.ndarray) -> np.ndarray: ...

    def on_off(self, on: bool | np.bool_ | np.ndarray) -> float | np.ndarray:
        """The power of an on/off decision [W]: ``upper_w`` where ``on``, ``lower_w`` elsewhere
        (a bool gives a number, an array of them an array)."""
        if isinstance(on, np.ndarray):
            return np.where(on, self.upper_w, self.lower_w)
        return self.upper_w if on else self.lower_w

    @overload
    def at_fraction(self, fraction: float) -> float: ...

    @overload
    def at_fraction(self, fraction: np.ndarray) -> np.ndarray: ...

    def at_fraction(self, fraction: float | np.ndarray) -> float | np.ndarray:
        """The power [W] at ``fraction`` (a number or an array, clipped to [0, 1]) of the way
        from ``lower_w`` to ``upper_w``."""
        return self.lower_w + np.clip(fraction, 0.0, 1.0) * self.span_w


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

    def monotone(self, *, increasing: bool) -> CopCurve:
        """The nearest curve (least squares over the knots' values, the pool-adjacent-violators
        algorithm) whose COP never falls (``increasing``: a heat pump's, better in milder
        air) or never rises (a cooling machine's, worse in hotter air) with the outdoor
        temperature. A curve that already is keeps its values exactly. Piecewise linear
        between monotone knots and constant beyond them, it is then monotone everywhere."""
        sign = 1.0 if increasing else -1.0
        blocks: list[tuple[float, int]] = []  # (mean of sign x value, knots pooled)
        for v in self.cop:
            mean, count = sign * v, 1
            while blocks and blocks[-1][0] > mean:
                prev, n = blocks.pop()
                mean, count = (prev * n + mean * count) / (n + count), n + count
            blocks.append((mean, count))
        if len(blocks) == len(self.cop):
            return self
        values = tuple(float(sign * m) for m, n in blocks for _ in range(n))
        return CopCurve(t_a_c=self.t_a_c, cop=values)

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


def actuator_columns(series: str, actuators: Sequence[ActuatorSpec]) -> tuple[str, ...]:
    """Each actuator's column of ``series`` (``u`` or ``u_phys``), in their order: ``series``
    itself for a building's one actuator, else ``series[<name>]`` (the building's total power
    keeps the column ``series``)."""
    if series not in ACTUATOR_SERIES:
        raise ValueError(f"actuator_columns: {series!r} is not an actuator series ({', '.join(ACTUATOR_SERIES)})")
    if len(actuators) == 1:
        return (series,)
    return tuple(f"{series}[{a.name}]" for a in actuators)
