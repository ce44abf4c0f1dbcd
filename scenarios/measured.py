"""Exogenous inputs from a user's CSV files: measured weather and a price profile.

- :class:`CSVWeather`: ``time,T_a[,G]`` (outdoor temperature [C], global horizontal irradiance
  [W/m2], 0 when the column is absent) at any regular step, interpolated to the control
  interval. Its whole days split into parts like the typical-year weathers of
  :mod:`scenarios.inputs`: the last ``test_days`` days are the test part, the days before them
  the training part.
- :class:`PriceCSV`: ``time,price`` [EUR/kWh], a profile repeated with its own period (its span
  rounded to whole days, from the midnight before its first row): a day of prices gives the
  same price every day, a week a weekly profile, a calendar year a yearly one.

Paths are as written in the scenario file, made absolute when the file is read
(:mod:`scenarios.scenario_file`); each file is read once per process.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd

from pinn_mpc.errors import InputError
from scenarios.inputs import (
    SECONDS_PER_DAY,
    WeatherPart,
    _days_touched,
    _too_long,
    interval_starts,
    weather_part,
)

__all__ = ["CSVWeather", "PriceCSV", "read_series_csv"]

_DAY = pd.Timedelta(days=1)
#: Plausible values of the columns: beyond them a file is refused as mislabelled or corrupt.
_RANGES = {"T_a": (-70.0, 60.0), "G": (0.0, 1500.0), "price": (-1.0, 10.0)}


@functools.lru_cache(maxsize=8)
def read_series_csv(path: str, required: tuple[str, ...], optional: tuple[str, ...]) -> pd.DataFrame:
    """A CSV with a ``time`` column (increasing timestamps) and numeric columns, checked.

    Returns the frame with ``time`` as datetime64 and the ``required`` and present ``optional``
    columns as float; an InputError names the file, column and row of the first problem.
    """
    try:
        frame = pd.read_csv(path)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a readable CSV ({exc})") from None
    missing = [c for c in ("time", *required) if c not in frame.columns]
    if missing:
        raise InputError(f"{path}: lacks column(s) {missing}; has {list(frame.columns)}")
    if len(frame) < 2:
        raise InputError(f"{path}: needs at least two rows, has {len(frame)}")
    try:
        times = pd.to_datetime(frame["time"])
    except (ValueError, TypeError) as exc:
        raise InputError(f"{path}: column time is not ISO 8601 timestamps ({exc})") from None
    steps = np.diff(times.to_numpy()).astype("timedelta64[ns]").astype(np.int64)
    if (steps <= 0).any():
        row = int(np.argmax(steps <= 0)) + 2
        raise InputError(f"{path}: time must increase; row {row} does not")
    out = pd.DataFrame({"time": times})
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
    return out


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
    #: Fields holding a file path, resolved relative to the scenario file that names them.
    PATH_FIELDS: ClassVar[tuple[str, ...]] = ("path",)

    def __post_init__(self) -> None:
        if isinstance(self.test_days, bool) or not isinstance(self.test_days, int) or self.test_days < 1:
            raise InputError(f"CSVWeather.test_days must be a whole number >= 1, got {self.test_days!r}")

    def _frame(self) -> pd.DataFrame:
        return read_series_csv(self.path, ("T_a",), ("G",))

    def _days(self) -> tuple[pd.Timestamp, int]:
        """(first midnight in the file, number of whole days from it within the file)."""
        times = self._frame()["time"]
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
        frame = self._frame()
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
    PATH_FIELDS: ClassVar[tuple[str, ...]] = ("path",)

    def check(self) -> None:
        read_series_csv(self.path, ("price",), ())

    def sample(self, times: pd.DatetimeIndex, *, dt_s: float, rng: np.random.Generator) -> np.ndarray:
        """Interval start times (N,) -> price (N,) [EUR/kWh] (``dt_s``, ``rng`` unused: the
        profile is data)."""
        frame = read_series_csv(self.path, ("price",), ())
        origin = frame["time"].iloc[0].floor("D")
        knots = _seconds_since(frame["time"], origin)
        step = float(np.median(np.diff(knots)))
        period_s = max(1, round((knots[-1] + step) / SECONDS_PER_DAY)) * SECONDS_PER_DAY
        offset = np.mod(_seconds_since(times, origin), period_s)
        # Before the first row of the period: the last row's price (the profile wraps around).
        row = np.searchsorted(knots, offset, side="right") - 1
        return frame["price"].to_numpy()[row % len(knots)]
