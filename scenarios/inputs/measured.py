"""Exogenous inputs from a user's CSV files: measured weather and a price profile.

- :class:`CSVWeather`: ``time,T_a[,G]`` (outdoor temperature [C], global horizontal irradiance
  [W/m2], 0 when the column is absent) at any regular step, interpolated to the control
  interval. Its whole days split into parts like the typical-year weathers of
  :mod:`scenarios.inputs.exogenous`: the last ``test_days`` days are the test part, the days before them
  the training part.
- :class:`PriceCSV`: ``time,price`` [EUR/kWh], a profile repeated with its own period (its span,
  which must be whole days, from the midnight before its first row): a day of prices gives the
  same price every day, a week a weekly profile, a calendar year a yearly one.

Times are read as data files read them (:func:`pinn_mpc.data.parse_times`): ISO 8601, where
``Z`` and UTC offsets (also offsets changing at a daylight-saving switch) are instants given
in UTC, the scenario's clock; or numeric seconds since 1970-01-01. Times without an offset
that jump an hour at night, as a local clock does at a daylight-saving switch, are refused
with the fix (:func:`pinn_mpc.data.check_clock_change`). Rows more than
``max_gap_h`` hours apart (default :data:`DEFAULT_MAX_GAP_H`) are refused, not bridged.

Paths are as written in the scenario file, made absolute when the file is read
(:mod:`scenarios.inputs.scenario_file`); each file is read once per process.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd

from pinn_mpc.data import check_celsius, check_clock_change, parse_times
from pinn_mpc.errors import InputError, warn_once
from scenarios.inputs.exogenous import (
    SECONDS_PER_DAY,
    WeatherPart,
    _days_touched,
    _too_long,
    interval_starts,
    weather_part,
)

__all__ = ["DEFAULT_MAX_GAP_H", "CSVWeather", "PriceCSV", "read_series_csv"]

_DAY = pd.Timedelta(days=1)
#: Plausible values of the columns: beyond them a file is refused as mislabelled or corrupt.
_RANGES = {"T_a": (-70.0, 60.0), "G": (0.0, 1500.0), "price": (-1.0, 10.0)}


#: Longest gap between two rows [h] a file may have unless its section allows more.
DEFAULT_MAX_GAP_H = 3.0
#: A column G whose maximum stays below this [W/m2] is likely in kW/m2 (sunlight reaches
#: hundreds of W/m2 on any day with a sun).
_G_MAX_BELOW_W_PER_M2 = 5.0


@functools.lru_cache(maxsize=8)
def read_series_csv(
    path: str,
    required: tuple[str, ...],
    optional: tuple[str, ...],
    max_gap_h: float = DEFAULT_MAX_GAP_H,
    section: str = "weather",
) -> pd.DataFrame:
    """A CSV with a ``time`` column (increasing timestamps) and numeric columns, checked.

    Times are ISO 8601 (``Z`` or UTC offsets, also changing at a daylight-saving switch, read as
    instants and given in UTC) or numeric seconds since 1970-01-01, as in data files. Returns
    the frame with ``time`` as datetime64 and the ``required`` and present ``optional`` columns
    as float; an InputError names the file, column and row of the first problem, including a
    gap between rows longer than ``max_gap_h`` hours (``section``: where the file's scenario
    sets ``max_gap_h``), and a ``T_a`` whose median is in kelvin or Fahrenheit
    (:func:`pinn_mpc.data.check_celsius`). A ``G`` that never reaches a few W/m2 is warned about
    (kW/m2?).
    """
    try:
        frame = pd.read_csv(path)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory; give a CSV file") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a readable CSV ({exc})") from None
    missing = [c for c in ("time", *required) if c not in frame.columns]
    if missing:
        raise InputError(f"{path}: lacks column(s) {missing}; has {list(frame.columns)}")
    if len(frame) < 2:
        raise InputError(f"{path}: needs at least two rows, has {len(frame)}")
    times = parse_times(frame["time"], path)
    steps = np.diff(times.to_numpy()).astype("timedelta64[ns]").astype(np.int64) / 1e9
    check_clock_change(times, frame["time"], steps, path)
    if (steps <= 0).any():
        row = int(np.argmax(steps <= 0)) + 2
        raise InputError(f"{path}: time must increase; row {row} does not")
    out = pd.DataFrame({"time": times})
    if "T_a" in frame.columns:  # the unit before the range, which names no unit
        t_a = pd.to_numeric(frame["T_a"], errors="coerce")
        check_celsius({"T_a": float(t_a.median())}, path)
    for column in (*required, *(c for c in optional if c in frame.columns)):
        values = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
        lo, hi = _RANGES[column]
        bad = ~(np.isfinite(values) & (values >= lo) & (values <= hi))
        if bad.any():
            row = int(np.argmax(bad))
            raise InputError(
                f"{path}: column {column}, row {row + 1}: {frame[column].iloc[row]!r} is not a "
                f"number in the plausible range {lo:g} .. {hi:g}"
            )
        out[column] = values
    if steps.max() > max_gap_h * 3600.0:
        i = int(np.argmax(steps))
        raise InputError(
            f"{path}: a gap of {_hours(steps[i])} between rows {i + 1} ({times.iloc[i]}) and "
            f"{i + 2} ({times.iloc[i + 1]}), more than max_gap_h = {max_gap_h:g} h; fill the "
            f"gap with measurements, or set max_gap_h in [{section}] to bridge it by "
            "interpolation"
        )
    if "G" in out and out["G"].max() < _G_MAX_BELOW_W_PER_M2:
        warn_once(
            f"{path}: column G never exceeds {out['G'].max():g} W/m2, where sunlight reaches "
            "hundreds; is it in kW/m2 (multiply by 1000), or a night-only excerpt?"
        )
    return out


def _hours(seconds: float) -> str:
    return f"{seconds / 86400:.1f} days" if seconds >= 2 * 86400 else f"{seconds / 3600:.1f} h"


def _seconds_since(times: pd.Series | pd.DatetimeIndex, origin: pd.Timestamp) -> np.ndarray:
    return (pd.DatetimeIndex(times) - origin).total_seconds().to_numpy()


@dataclass(frozen=True, kw_only=True)
class CSVWeather:
    """Measured weather from a CSV ``time,T_a[,G]`` (see the module docstring).

    Runs start at midnight; each run's first day is drawn with ``rng``, uniformly among those
    that keep all its rows in its part (``whole``: anywhere in the file's whole days).
    """

    path: str
    test_days: int = 14
    #: Longest gap between rows [h] bridged by linear interpolation; a longer one is refused.
    max_gap_h: float = DEFAULT_MAX_GAP_H
    #: Fields holding a file path, resolved relative to the scenario file that names them.
    PATH_FIELDS: ClassVar[tuple[str, ...]] = ("path",)

    def __post_init__(self) -> None:
        if isinstance(self.test_days, bool) or not isinstance(self.test_days, int) or self.test_days < 1:
            raise ValueError(f"CSVWeather.test_days must be a whole number >= 1, got {self.test_days!r}")
        _check_max_gap("CSVWeather", self.max_gap_h)

    def frame(self) -> pd.DataFrame:
        """The file's rows, checked: ``time`` (datetime64), ``T_a`` and, if present, ``G``."""
        return read_series_csv(self.path, ("T_a",), ("G",), self.max_gap_h, "weather")

    def _days(self) -> tuple[pd.Timestamp, int]:
        """(first midnight in the file, number of whole days from it within the file)."""
        times = self.frame()["time"]
        first = times.iloc[0].ceil("D")
        days = math.floor((times.iloc[-1] - first) / _DAY)
        if days <= self.test_days:
            raise InputError(
                f"{self.path}: {max(days, 0)} whole days of weather, need more than "
                f"test_days={self.test_days} (the test part) to leave training days"
            )
        return first, days

    def check(self) -> None:
        """Read and check the file now (a scenario file is checked when it is loaded)."""
        self._days()

    def split_text(self) -> str:
        first, days = self._days()
        train = days - self.test_days
        test_start = first + pd.Timedelta(days=train)
        last = first + pd.Timedelta(days=days - 1)
        return (
            f"Weather split (days of {self.path}): training {first:%Y-%m-%d} - "
            f"{test_start - _DAY:%Y-%m-%d} ({train} days), test {test_start:%Y-%m-%d} - "
            f"{last:%Y-%m-%d} ({self.test_days} days, holding a test run's warm-up day, counted "
            "days and forecast lead)."
        )

    def sample(
        self, *, n: int, dt_s: float, run_days: int, part: WeatherPart, rng: np.random.Generator
    ) -> tuple[pd.DatetimeIndex, np.ndarray, np.ndarray]:
        """``n`` intervals -> (start times, T_a (n,) [C], G (n,) [W/m2]), interpolated at the
        interval mid-points."""
        part = weather_part(part)
        first, days = self._days()
        need = _days_touched(n, dt_s)
        train = days - self.test_days
        lo, room = {"train": (0, train), "test": (train, self.test_days), "whole": (0, days)}[part]
        if need > room:
            raise _too_long(part if part != "train" else "training", need, f"the {room} days of {self.path}")
        start = first + pd.Timedelta(days=lo + int(rng.integers(room - need + 1)))
        times = interval_starts(start, n, dt_s)
        frame = self.frame()
        knots = _seconds_since(frame["time"], first)
        mid = _seconds_since(times, first) + 0.5 * dt_s
        t_a = np.interp(mid, knots, frame["T_a"].to_numpy())
        g = np.interp(mid, knots, frame["G"].to_numpy()) if "G" in frame else np.zeros(n)
        return times, t_a, g


@dataclass(frozen=True, kw_only=True)
class PriceCSV:
    """Electricity price [EUR/kWh] from a CSV ``time,price``, repeated with its period (see the
    module docstring); each interval gets the price of the last row at or before its start."""

    path: str
    #: Longest gap between rows [h]; a longer one is refused.
    max_gap_h: float = DEFAULT_MAX_GAP_H
    PATH_FIELDS: ClassVar[tuple[str, ...]] = ("path",)

    def __post_init__(self) -> None:
        _check_max_gap("PriceCSV", self.max_gap_h)

    def _profile(self) -> tuple[pd.DataFrame, pd.Timestamp, np.ndarray, float]:
        """(frame, origin midnight, row times [s from it], period [s]); a file that does not
        span whole days is refused: repeating it would give part of every day another day's
        prices, or its last price."""
        frame = read_series_csv(self.path, ("price",), (), self.max_gap_h, "price")
        origin = frame["time"].iloc[0].floor("D")
        knots = _seconds_since(frame["time"], origin)
        step = float(np.median(np.diff(knots)))
        span_s = knots[-1] + step - knots[0]
        days = round(span_s / SECONDS_PER_DAY)
        if days < 1 or abs(span_s - days * SECONDS_PER_DAY) > 0.5 * step:
            raise InputError(
                f"{self.path}: the prices cover {_hours(span_s)} ({frame['time'].iloc[0]} .. "
                f"{frame['time'].iloc[-1]} plus one step), but a price profile repeats with a "
                "period of whole days, so the run would get prices that are not in the file; "
                "give whole days of prices (e.g. 24 hourly rows from 00:00)"
            )
        return frame, origin, knots, days * SECONDS_PER_DAY

    def check(self) -> None:
        self._profile()

    def sample(self, times: pd.DatetimeIndex, *, dt_s: float, rng: np.random.Generator) -> np.ndarray:
        """Interval start times (N,) -> price (N,) [EUR/kWh] (``dt_s``, ``rng`` unused: the
        profile is data)."""
        frame, origin, knots, period_s = self._profile()
        offset = np.mod(_seconds_since(times, origin), period_s)
        # Before the first row of the period: the last row's price (the profile wraps around).
        row = np.searchsorted(knots, offset, side="right") - 1
        return frame["price"].to_numpy()[row % len(knots)]


def _check_max_gap(owner: str, value: float) -> None:
    if isinstance(value, bool) or not (isinstance(value, int | float) and 0 < value <= 24 * 366):
        raise ValueError(f"{owner}.max_gap_h must be a number of hours in (0, 8784], got {value!r}")
