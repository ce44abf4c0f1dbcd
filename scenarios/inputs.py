"""Exogenous inputs of a scenario, one value per control interval (held constant over it).

Every generator takes the interval start times (or the number of intervals) and an explicit
``np.random.Generator``; arrays are (N,) with units in the names. Draws are sequential, so
asking for more intervals with the same generator state extends the series without changing
its beginning (a controller's forecast rows never alter the simulated ones).

- :class:`SyntheticWeather`: outdoor temperature (daily cycle + slow multi-day variation +
  smooth AR(1) noise) and a clear-sky-like irradiance scaled by a daily cloudiness.
- :class:`TMY3Weather`: a real typical year shipped with pvlib (``pvlib.iotools.read_tmy3``),
  resampled from hourly to the control interval; the year wraps around.
- :class:`PriceProfile`: constant, day/night or dynamic (peaks + day level + noise) [EUR/kWh].
- :class:`ComfortSchedule`: day/night comfort band ``T_min``/``T_max`` [C].
- :class:`GainsSchedule`: internal gains [W]: base + scheduled (occupancy) + random events.
"""

from __future__ import annotations

import functools
import math
import pathlib
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pandas as pd

from pinn_mpc.errors import InputError

SECONDS_PER_DAY = 86400.0
HOURS_PER_TYPICAL_YEAR = 8760
#: Timestamps of synthetic and TMY3 series are labelled in this (non-leap) year and onwards.
BASE_YEAR = 2021


def steps_per_day(dt_s: float) -> int:
    """Control intervals per day; the interval must divide the day."""
    n = SECONDS_PER_DAY / dt_s
    if not (math.isfinite(n) and n >= 1 and abs(n - round(n)) < 1e-9):
        raise InputError(f"control interval dt_s={dt_s} does not divide a day; use e.g. 1800")
    return round(n)


def time_of_day_h(times: pd.Series | pd.DatetimeIndex) -> np.ndarray:
    """Hours since midnight of each timestamp, (N,)."""
    t = pd.DatetimeIndex(times)
    return np.asarray((t - t.normalize()).total_seconds() / 3600.0, dtype=float)


def interval_starts(start: pd.Timestamp, n: int, dt_s: float) -> pd.DatetimeIndex:
    """``n`` interval start times from ``start`` with step ``dt_s`` (datetime64[ns])."""
    return pd.DatetimeIndex(start + pd.to_timedelta(np.arange(n) * dt_s, unit="s")).as_unit("ns")


def _in_periods(hour: np.ndarray, periods_h: tuple[tuple[float, float], ...]) -> np.ndarray:
    """(N,) bool: the hour of day lies in one of the [start, end) periods (end may pass 24)."""
    inside = np.zeros(hour.shape, dtype=bool)
    for start, end in periods_h:
        inside |= ((hour - start) % 24.0) < (end - start)
    return inside


def _ar1(rng: np.random.Generator, n: int, *, std: float, correlation_time_s: float, dt_s: float) -> np.ndarray:
    """Stationary AR(1) noise (N,) with the given marginal std and correlation time."""
    phi = math.exp(-dt_s / correlation_time_s)
    innovation = math.sqrt(1.0 - phi * phi)
    out = std * rng.standard_normal(n)
    for k in range(1, n):
        out[k] = phi * out[k - 1] + innovation * out[k]
    return out


def _bump(hour: np.ndarray, centre_h: float, width_h: float) -> np.ndarray:
    """Gaussian bump of height 1 over the hour of day, (N,)."""
    return np.exp(-0.5 * ((hour - centre_h) / width_h) ** 2)


def _check_hours(owner: str, *hours: float) -> None:
    for h in hours:
        if not (0.0 <= h <= 24.0):
            raise InputError(f"{owner}: hour {h!r} must lie in [0, 24]")


@dataclass(frozen=True, kw_only=True)
class SyntheticWeather:
    """Seeded synthetic weather; outdoor temperature [C] and irradiance G [W/m2] per interval.

    ``T_a = mean + daily_amplitude*cos(2 pi (h - warmest_hour)/24) + slow + noise`` where the
    slow part is a sum of two sinusoids of random phase (periods ``slow_periods_days``) with
    total amplitude ``slow_amplitude_c`` and the noise is AR(1) (3 h correlation time).
    ``G`` is ``peak * sin(pi (h - sunrise)/(sunset - sunrise))**1.5`` by day, zero at night,
    times a daily clearness drawn uniformly in [min_clearness, 1], evaluated mid-interval.
    """

    start: str = f"{BASE_YEAR}-04-01"
    mean_c: float = 15.0
    daily_amplitude_c: float = 4.0
    slow_amplitude_c: float = 3.0
    slow_periods_days: tuple[float, float] = (4.0, 9.0)
    noise_std_c: float = 0.7
    peak_irradiance_w_per_m2: float = 700.0
    min_clearness: float = 0.3
    sunrise_h: float = 6.5
    sunset_h: float = 19.5
    warmest_hour: float = 15.0

    def __post_init__(self) -> None:
        for name in ("daily_amplitude_c", "slow_amplitude_c", "noise_std_c", "peak_irradiance_w_per_m2"):
            if not getattr(self, name) >= 0:
                raise InputError(f"SyntheticWeather.{name} must be >= 0, got {getattr(self, name)!r}")
        if not 0.0 <= self.min_clearness <= 1.0:
            raise InputError(f"SyntheticWeather.min_clearness must lie in [0, 1], got {self.min_clearness}")
        _check_hours("SyntheticWeather", self.sunrise_h, self.sunset_h, self.warmest_hour)
        if not self.sunrise_h < self.sunset_h:
            raise InputError(
                f"SyntheticWeather: sunrise_h={self.sunrise_h} must precede sunset_h={self.sunset_h}"
            )
        if min(self.slow_periods_days) <= 0:
            raise InputError(f"SyntheticWeather.slow_periods_days must be > 0, got {self.slow_periods_days}")

    def sample(
        self, *, n: int, dt_s: float, run_days: int, rng: np.random.Generator
    ) -> tuple[pd.DatetimeIndex, np.ndarray, np.ndarray]:
        """``n`` intervals -> (start times, T_a (n,) [C], G (n,) [W/m2]).

        ``run_days`` (the simulated days, without forecast lead) matters only to windowed
        weather; synthetic weather has no window and always starts at ``start``.
        """
        times = interval_starts(pd.Timestamp(self.start), n, dt_s)
        mid_h = time_of_day_h(times) + 0.5 * dt_s / 3600.0
        elapsed_days = (np.arange(n) + 0.5) * dt_s / SECONDS_PER_DAY
        phases = rng.uniform(0.0, 2.0 * math.pi, size=2)
        # A generator per purpose, seeded before any n-sized draw, keeps each series a prefix
        # of a longer one.
        clearness_rng = np.random.default_rng(rng.integers(2**63))
        noise = _ar1(rng, n, std=self.noise_std_c, correlation_time_s=3 * 3600.0, dt_s=dt_s)
        daily = self.daily_amplitude_c * np.cos(2.0 * math.pi * (mid_h - self.warmest_hour) / 24.0)
        slow = sum(
            0.5 * self.slow_amplitude_c * np.sin(2.0 * math.pi * elapsed_days / period + phase)
            for period, phase in zip(self.slow_periods_days, phases, strict=True)
        )
        t_a = self.mean_c + daily + slow + noise
        day_index = np.floor(elapsed_days).astype(int)
        clearness = clearness_rng.uniform(self.min_clearness, 1.0, size=int(day_index[-1]) + 1 if n else 0)
        solar_phase = (mid_h % 24.0 - self.sunrise_h) / (self.sunset_h - self.sunrise_h)
        shape = np.where(
            (solar_phase > 0) & (solar_phase < 1), np.sin(math.pi * np.clip(solar_phase, 0, 1)), 0.0
        )
        g = self.peak_irradiance_w_per_m2 * shape**1.5 * (clearness[day_index] if n else 1.0)
        return times, t_a, np.maximum(g, 0.0)


def tmy3_path(file_name: str) -> pathlib.Path:
    """Path of a TMY3 file shipped in pvlib's data folder."""
    import pvlib

    return pathlib.Path(pvlib.__file__).parent / "data" / file_name


@functools.lru_cache(maxsize=4)
def load_tmy3(file_name: str) -> tuple[np.ndarray, np.ndarray, str]:
    """Hourly typical year: (dry-bulb T (8760,) [C], GHI (8760,) [W/m2], station name).

    Row i is the hour ending at (i+1) h after 1 January 00:00 local standard time; temperature
    is the value at that instant, GHI the mean over the hour (TMY3 convention).
    """
    import pvlib

    path = tmy3_path(file_name)
    if not path.is_file():
        raise InputError(f"TMY3 file {file_name!r} is not in pvlib's data folder {path.parent}")
    frame, meta = pvlib.iotools.read_tmy3(path, map_variables=True)
    if len(frame) != HOURS_PER_TYPICAL_YEAR:
        raise InputError(f"TMY3 file {path} has {len(frame)} rows, expected {HOURS_PER_TYPICAL_YEAR}")
    t_a = frame["temp_air"].to_numpy(dtype=float)
    ghi = frame["ghi"].to_numpy(dtype=float)
    return t_a, np.maximum(ghi, 0.0), str(meta.get("Name", file_name)).strip('"')


def resample_typical_year(
    t_a_hourly_c: np.ndarray, ghi_hourly_w_per_m2: np.ndarray, *, start_s: float, n: int, dt_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Hourly typical year (8760,) -> per interval (n,), wrapping around the year.

    ``start_s`` is the first interval start in seconds after 1 January 00:00. Temperature is
    linearly interpolated at mid-interval (for intervals within an hour this is the interval
    mean of the interpolant); GHI, an hourly mean, becomes the exact interval mean of the
    piecewise-constant hourly series, so daily energy is preserved.
    """
    period_s = HOURS_PER_TYPICAL_YEAR * 3600.0
    starts = start_s + np.arange(n) * dt_s
    knots_s = (np.arange(HOURS_PER_TYPICAL_YEAR) + 1) * 3600.0
    t_a = np.interp(starts + 0.5 * dt_s, knots_s, t_a_hourly_c, period=period_s)
    energy_knots = np.concatenate([[0.0], np.cumsum(ghi_hourly_w_per_m2) * 3600.0])
    energy_t = np.concatenate([[0.0], knots_s])

    def energy(t_s: np.ndarray) -> np.ndarray:
        years = np.floor(t_s / period_s)
        return years * energy_knots[-1] + np.interp(t_s - years * period_s, energy_t, energy_knots)

    ghi = (energy(starts + dt_s) - energy(starts)) / dt_s
    return t_a, np.maximum(ghi, 0.0)


@dataclass(frozen=True, kw_only=True)
class TMY3Weather:
    """Real typical-year weather from pvlib's TMY3 files, in a seasonal window.

    The window starts at ``window_start`` (``"MM-DD"``) and lasts ``window_days`` days (it may
    wrap past 31 December). The generator picks the start day uniformly so that a run of
    ``run_days`` stays inside the window when it fits; a longer run continues past its end. Times are labelled from :data:`BASE_YEAR` (non-leap years
    until 2024, so calendar and typical year agree for runs shorter than about two years).
    """

    file_name: str = "723170TYA.CSV"
    window_start: str = "11-01"
    window_days: int = 151

    def __post_init__(self) -> None:
        try:
            pd.Timestamp(f"{BASE_YEAR}-{self.window_start}")
        except ValueError as exc:
            raise InputError(f"TMY3Weather.window_start {self.window_start!r} is not MM-DD") from exc
        if not 1 <= self.window_days <= 365:
            raise InputError(f"TMY3Weather.window_days must lie in [1, 365], got {self.window_days}")

    def sample(
        self, *, n: int, dt_s: float, run_days: int, rng: np.random.Generator
    ) -> tuple[pd.DatetimeIndex, np.ndarray, np.ndarray]:
        """``n`` intervals -> (start times, T_a (n,) [C], G (n,) [W/m2]).

        The start day leaves room for ``run_days`` in the window, so forecast lead rows
        (``n`` beyond ``run_days``) never move the start.
        """
        t_a_hourly, ghi_hourly, _ = load_tmy3(self.file_name)
        offset_day = int(rng.integers(max(self.window_days - run_days, 0) + 1))
        first = pd.Timestamp(f"{BASE_YEAR}-{self.window_start}") + pd.Timedelta(days=offset_day)
        start_s = ((first - pd.Timestamp(f"{BASE_YEAR}-01-01")).days % 365) * SECONDS_PER_DAY
        t_a, ghi = resample_typical_year(t_a_hourly, ghi_hourly, start_s=start_s, n=n, dt_s=dt_s)
        start = pd.Timestamp(f"{BASE_YEAR}-01-01") + pd.Timedelta(seconds=start_s)
        return interval_starts(start, n, dt_s), t_a, ghi


@dataclass(frozen=True, kw_only=True)
class PriceProfile:
    """Electricity price [EUR/kWh] per interval.

    - ``constant``: ``level_eur_per_kwh`` throughout.
    - ``day_night``: ``level`` in [day_start_h, day_end_h), ``night_eur_per_kwh`` otherwise.
    - ``dynamic``: a day-ahead-like profile: ``level`` times a daily factor (lognormal, 15 %)
      plus a morning peak (``peak_eur_per_kwh`` x 0.6 around 08 h) and an evening peak
      (``peak`` around 19 h), a midday solar dip, and AR(1) noise (2 h correlation); floored at
      ``floor_eur_per_kwh`` (> 0), so the price is never negative.
    """

    kind: Literal["constant", "day_night", "dynamic"] = "constant"
    level_eur_per_kwh: float = 0.25
    night_eur_per_kwh: float = 0.15
    day_start_h: float = 7.0
    day_end_h: float = 22.0
    peak_eur_per_kwh: float = 0.15
    noise_std_eur_per_kwh: float = 0.02
    floor_eur_per_kwh: float = 0.01

    def __post_init__(self) -> None:
        if self.kind not in ("constant", "day_night", "dynamic"):
            raise InputError(
                f"PriceProfile.kind {self.kind!r} is unknown; use constant, day_night or dynamic"
            )
        for name in ("level_eur_per_kwh", "night_eur_per_kwh", "peak_eur_per_kwh",
                     "noise_std_eur_per_kwh", "floor_eur_per_kwh"):
            if not getattr(self, name) >= 0:
                raise InputError(f"PriceProfile.{name} must be >= 0, got {getattr(self, name)!r}")
        _check_hours("PriceProfile", self.day_start_h, self.day_end_h)

    def sample(self, times: pd.DatetimeIndex, *, dt_s: float, rng: np.random.Generator) -> np.ndarray:
        """Interval start times (N,) -> price (N,) [EUR/kWh]."""
        n = len(times)
        hour = time_of_day_h(times)
        if self.kind == "constant":
            return np.full(n, self.level_eur_per_kwh)
        if self.kind == "day_night":
            day = _in_periods(hour, ((self.day_start_h, self.day_end_h),))
            return np.where(day, self.level_eur_per_kwh, self.night_eur_per_kwh)
        mid_h = hour + 0.5 * dt_s / 3600.0
        day_index = np.floor(np.arange(n) * dt_s / SECONDS_PER_DAY).astype(int)
        level_rng = np.random.default_rng(rng.integers(2**63))
        factor = np.exp(0.15 * level_rng.standard_normal(int(day_index[-1]) + 1 if n else 0))
        shape = 0.6 * _bump(mid_h, 8.0, 1.5) + _bump(mid_h, 19.0, 2.0)
        dip = 0.25 * self.level_eur_per_kwh * _bump(mid_h, 13.0, 2.0)
        noise = _ar1(rng, n, std=self.noise_std_eur_per_kwh, correlation_time_s=7200.0, dt_s=dt_s)
        price = self.level_eur_per_kwh * (factor[day_index] if n else 1.0)
        price = price + self.peak_eur_per_kwh * shape - dip + noise
        return np.maximum(price, self.floor_eur_per_kwh)


@dataclass(frozen=True, kw_only=True)
class ComfortSchedule:
    """Comfort band [C]: the day band in [day_start_h, day_end_h), the night band otherwise."""

    day_min_c: float
    day_max_c: float
    night_min_c: float
    night_max_c: float
    day_start_h: float = 7.0
    day_end_h: float = 22.0

    def __post_init__(self) -> None:
        if not (self.day_min_c < self.day_max_c and self.night_min_c < self.night_max_c):
            raise InputError(
                f"ComfortSchedule bands must have min < max, got day {self.day_min_c}-{self.day_max_c}"
                f" and night {self.night_min_c}-{self.night_max_c}"
            )
        _check_hours("ComfortSchedule", self.day_start_h, self.day_end_h)

    def sample(self, times: pd.DatetimeIndex) -> tuple[np.ndarray, np.ndarray]:
        """Interval start times (N,) -> (T_min (N,), T_max (N,)) [C], by the interval start."""
        day = _in_periods(time_of_day_h(times), ((self.day_start_h, self.day_end_h),))
        return (
            np.where(day, self.day_min_c, self.night_min_c),
            np.where(day, self.day_max_c, self.night_max_c),
        )


@dataclass(frozen=True, kw_only=True)
class GainsSchedule:
    """Internal gains [W]: ``base_w`` always, ``scheduled_w`` in ``periods_h`` (occupancy), and
    in those periods a random event (e.g. a door opening) adding ``event_w`` to an interval with
    probability ``event_probability``. The default is no gains at all."""

    base_w: float = 0.0
    scheduled_w: float = 0.0
    periods_h: tuple[tuple[float, float], ...] = ()
    event_w: float = 0.0
    event_probability: float = 0.0

    def __post_init__(self) -> None:
        for name in ("base_w", "scheduled_w", "event_w"):
            if not getattr(self, name) >= 0:
                raise InputError(f"GainsSchedule.{name} must be >= 0, got {getattr(self, name)!r}")
        if not 0.0 <= self.event_probability <= 1.0:
            raise InputError(
                f"GainsSchedule.event_probability must lie in [0, 1], got {self.event_probability}"
            )
        for start, end in self.periods_h:
            _check_hours("GainsSchedule.periods_h", start)
            if not start < end <= start + 24.0:
                raise InputError(f"GainsSchedule period ({start}, {end}) must have start < end")

    @property
    def active(self) -> bool:
        return self.base_w > 0 or (bool(self.periods_h) and (self.scheduled_w > 0 or self.event_w > 0))

    def sample(self, times: pd.DatetimeIndex, *, rng: np.random.Generator) -> np.ndarray:
        """Interval start times (N,) -> gains (N,) [W]."""
        inside = _in_periods(time_of_day_h(times), self.periods_h)
        events = rng.random(len(times)) < self.event_probability
        return self.base_w + inside * (self.scheduled_w + events * self.event_w)
