"""The inputs a run is driven by, one value per control interval (:class:`ExogenousSeries`), and
what a controller's forecast of them gets wrong (:class:`ForecastErrors`, its AR(1) errors
along the lead :func:`lead_error_paths`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from controllers.base import Forecast
from pinn_mpc.data import SITE_COLUMNS, day_of_week, zone_values
from pinn_mpc.errors import InternalError
from pinn_mpc.solar import FACADE_COLUMNS
from pinn_mpc.zones import zone_columns, zones_in
from scenarios.inputs.exogenous import time_of_day_h

__all__ = ["EXOGENOUS_FIELDS", "ExogenousSeries", "ForecastErrors", "lead_error_paths"]

#: Columns of an exogenous frame the loop is driven by (besides ``time``).
EXOGENOUS_FIELDS = ("T_a", "G", "I_g", "price", "T_min", "T_max")


@dataclass(frozen=True, kw_only=True)
class ForecastErrors:
    """What a controller's forecast gets wrong (the default: nothing).

    - ``t_a_error_std_c`` [K]: standard deviation of the outdoor-temperature error at 24 h lead.
    - ``g_error_rel_std``: the same for irradiance as a relative error (0.3: +-30 % at 24 h
      lead); the forecast is ``G * max(0, 1 + e)``, so it stays >= 0 and is 0 at night; the
      facades' irradiance, where the run has it, is scaled by the same factor.
    - ``wind_error_rel_std``: the same for the wind speed, where the run has it (an EnergyPlus
      building's weather file): ``wind * max(0, 1 + e)``, an error of its own.
    - ``error_correlation_h`` [h]: correlation time of the errors along the lead (AR(1)).
    - ``gains_known``: False -> the controller sees the gains schedule's expectation (base +
      occupancy + event probability x event power), in its forecast and in the past it
      observes, instead of the gains that happened.

    Each error is an AR(1) process along the lead ``h`` (intervals ahead of now), starting at 0
    for the current interval (h = 0, whose inputs are measured): ``e_h = phi e_(h-1) + q w_h``,
    ``phi = exp(-dt / correlation time)``, ``w_h ~ N(0, 1)``, so ``Var e_h = q^2 (1 - phi^(2h))
    / (1 - phi^2)`` grows with lead; ``q`` is set so that the std at 24 h lead is the given one.
    """

    t_a_error_std_c: float = 0.0
    g_error_rel_std: float = 0.0
    wind_error_rel_std: float = 0.0
    error_correlation_h: float = 12.0
    gains_known: bool = True

    def __post_init__(self) -> None:
        for name in ("t_a_error_std_c", "g_error_rel_std", "wind_error_rel_std"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ValueError(f"ForecastErrors.{name} must be a number >= 0, got {value!r}")
        h = self.error_correlation_h
        if not (isinstance(h, int | float) and math.isfinite(h) and h > 0):
            raise ValueError(f"ForecastErrors.error_correlation_h must be > 0 hours, got {h!r}")
        if not isinstance(self.gains_known, bool):
            raise ValueError(f"ForecastErrors.gains_known must be true or false, got {self.gains_known!r}")

    @property
    def perfect(self) -> bool:
        return (
            self.t_a_error_std_c == 0
            and self.g_error_rel_std == 0
            and self.wind_error_rel_std == 0
            and self.gains_known
        )


def lead_error_paths(
    rng: np.random.Generator, *, n_paths: int, n_leads: int, std_at_24h: float,
    correlation_h: float, dt_s: float,
) -> np.ndarray:
    """AR(1) errors along the lead (see :class:`ForecastErrors`): (n_paths, n_leads), column 0
    (lead 0) is zero and the standard deviation at 24 h lead is ``std_at_24h``."""
    phi = math.exp(-dt_s / (correlation_h * 3600.0))
    lead_24h = 86400.0 / dt_s
    # Var e_h = q^2 sum_{j<h} phi^(2j); solved for q at h = 24 h (a fractional h is fine).
    q = std_at_24h / math.sqrt((1.0 - phi ** (2.0 * lead_24h)) / (1.0 - phi**2))
    shocks = q * rng.standard_normal((n_paths, n_leads))
    errors = np.zeros((n_paths, n_leads))
    for h in range(1, n_leads):
        errors[:, h] = phi * errors[:, h - 1] + shocks[:, h]
    return errors


@dataclass(frozen=True, kw_only=True)
class ExogenousSeries:
    """The inputs a run is driven by, one value per control interval, arrays (N,) named as in
    the data format (and as :class:`controllers.base.Forecast`); the comfort band ``T_min``,
    ``T_max`` is (N,) for every zone or (N, Z) each zone's (a frame's ``T_min[<zone>]``)."""

    time_of_day_h: np.ndarray
    T_a: np.ndarray
    G: np.ndarray
    I_g: np.ndarray
    price: np.ndarray
    T_min: np.ndarray
    T_max: np.ndarray
    #: (N,) interval start times (datetime64), when known: a plant with a calendar needs them.
    times: np.ndarray | None = None

    #: (N,) day of the week of each interval's start, 0 = Monday; by default from ``times``
    #: (NaN without them), 6 (Sunday) on the building's holidays.
    day_of_week: np.ndarray | None = None
    #: (N,) 1 where the interval falls on one of the building's holidays (the days it runs its
    #: Sunday-or-holiday schedules; an EnergyPlus building's), 0 elsewhere; None: no calendar.
    holiday: np.ndarray | None = None
    #: (N,) the irradiance on the site's facades [W/m2] (:data:`pinn_mpc.solar.FACADE_COLUMNS`),
    #: where the run has it (an EnergyPlus scenario's); None otherwise.
    G_south: np.ndarray | None = None
    G_east: np.ndarray | None = None
    G_west: np.ndarray | None = None
    G_north: np.ndarray | None = None
    #: (N,) the wind speed at the weather station [m/s], where the run has it (an EnergyPlus
    #: scenario's weather file); None otherwise. Forecast as the file has it (no error).
    wind: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.day_of_week is None:
            if self.times is None:
                dow = np.full(len(self.T_a), np.nan)
            else:
                dow = day_of_week(self.times, self.holiday)
            object.__setattr__(self, "day_of_week", dow)
        given = [getattr(self, name) for name in (*Forecast._fields, "holiday")]
        lengths = {len(series) for series in given if series is not None}
        if len(lengths) != 1:
            raise InternalError(f"ExogenousSeries: all series need one length, got {sorted(lengths)}")
        facades = [getattr(self, name) is None for name in FACADE_COLUMNS]
        if any(facades) and not all(facades):
            raise InternalError(f"ExogenousSeries: give all of {', '.join(FACADE_COLUMNS)} or none")

    @property
    def has_facades(self) -> bool:
        """Whether the series holds the facades' irradiance."""
        return self.G_south is not None

    @classmethod
    def from_frame(cls, frame: pd.DataFrame) -> ExogenousSeries:
        """From a frame with ``time`` and :data:`EXOGENOUS_FIELDS` (as Scenario.exogenous makes
        it; the comfort band once for every zone or as each zone's ``T_min[<zone>]``,
        ``T_max[<zone>]``), and the facades' irradiance, the wind and ``holiday`` when the frame
        has them."""
        zones = zones_in(frame.columns)
        bands = {
            name: zone_values(frame, name)
            for name in ("T_min", "T_max")
            if all(c in frame.columns for c in zone_columns(name, zones)) and len(zones) > 1
        }
        missing = [c for c in ("time", *EXOGENOUS_FIELDS) if c not in frame.columns and c not in bands]
        if missing:
            raise ValueError(
                f"exogenous frame lacks column(s) {missing}; have {list(frame.columns)}"
            )
        cols = {
            c: frame[c].to_numpy(dtype=float)
            for c in (*EXOGENOUS_FIELDS, *SITE_COLUMNS, "holiday")
            if c in frame.columns
        }
        times = pd.DatetimeIndex(frame["time"]).to_numpy()
        return cls(time_of_day_h=time_of_day_h(frame["time"]), times=times, **(cols | bands))

    def __len__(self) -> int:
        return len(self.T_a)

    def forecast(self, row: int) -> Forecast:
        """Fresh arrays of every row from ``row`` to the end (None where the series has none)."""
        rows: dict[str, Any] = {}
        for name in Forecast._fields:
            series = getattr(self, name)
            rows[name] = None if series is None else np.array(series[row:])
        return Forecast(**rows)


