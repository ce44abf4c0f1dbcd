"""Exogenous inputs of a scenario, one value per control interval (held constant over it).

Every generator takes the interval start times (or the number of intervals) and an explicit
``np.random.Generator``; arrays are (N,) with units in the names. Draws are sequential, so
asking for more intervals with the same generator state extends the series without changing
its beginning (a controller's forecast rows never alter the simulated ones), except where a
run must fit in a part of the weather (below): there its start depends on all its rows.

Weather parts (:data:`WEATHER_PARTS`): a model must not be judged on the days it was trained
on, so each weather splits its calendar into disjoint parts. ``train`` (``simulate``, the
training data of ``compare`` and ``reproduce``), ``test`` (``closed-loop``, the test days of
``compare`` and ``reproduce``; a run's warm-up day, counted days and forecast lead rows all lie
in it) and ``whole`` (the whole seasonal window, training and test days alike: the draws made
before the split, kept so that old results can be reproduced).

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
from typing import Any, ClassVar, Literal, cast

import numpy as np
import pandas as pd

from pinn_mpc.errors import InputError, setting
from pinn_mpc.solar import FACADE_COLUMNS, interval_means
from scenarios.choices import WEATHER_PARTS, WeatherPart

__all__ = [
    "BASE_YEAR",
    "HOURS_PER_TYPICAL_YEAR",
    "SECONDS_PER_DAY",
    "ComfortSchedule",
    "GainsSchedule",
    "PriceProfile",
    "SyntheticWeather",
    "TMY3Weather",
    "day_span",
    "interval_starts",
    "load_site_irradiance",
    "load_tmy3",
    "resample_typical_year",
    "steps_per_day",
    "time_of_day_h",
    "tmy3_path",
    "weather_part",
]

SECONDS_PER_DAY = 86400.0
HOURS_PER_TYPICAL_YEAR = 8760
#: Timestamps of synthetic and TMY3 series are labelled in this (non-leap) year and onwards.
BASE_YEAR = 2021
_FIRST_DAY = pd.Timestamp(f"{BASE_YEAR}-01-01")
_DAYS_PER_TYPICAL_YEAR = HOURS_PER_TYPICAL_YEAR // 24

#: Runs in a part of TMY3 weather are dated in the season that starts in this year, so test
#: days come after training days and a training run reaching back a year stays in BASE_YEAR.
_SEASON_YEAR = BASE_YEAR + 1



def weather_part(text: str) -> WeatherPart:
    """``text`` checked to name a weather part (see the module docstring)."""
    if text not in WEATHER_PARTS:
        raise ValueError(
            f"unknown weather part {text!r}; choose one of: {', '.join(WEATHER_PARTS)}"
        )
    return cast(WeatherPart, text)


def day_span(times: pd.Series | pd.DatetimeIndex) -> list[str]:
    """[first day, last day] (ISO dates) of interval start times."""
    t = pd.DatetimeIndex(times)
    return [f"{t[0]:%Y-%m-%d}", f"{t[-1]:%Y-%m-%d}"]


def _days_touched(n: int, dt_s: float) -> int:
    """Calendar days that ``n`` intervals from midnight touch."""
    return -(-n // steps_per_day(dt_s))


def _too_long(part: str, need_days: int, room: str) -> InputError:
    return InputError(
        f"a run of {need_days} days (warm-up and forecast lead rows, if any, included) does not "
        f"fit in the {part} weather, {room}; use fewer days, or draw from the whole window, "
        f"training and test days mixed ({setting('weather_part')} whole)"
    )


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
    if (n - 1) * dt_s > (pd.Timestamp.max - start).total_seconds():
        raise InputError(
            f"a run of {n * dt_s / SECONDS_PER_DAY:.0f} days from {start:%Y-%m-%d} would end after "
            f"{pd.Timestamp.max:%Y}, where timestamps end; use fewer days"
        )
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
            raise ValueError(f"{owner}: hour {h!r} must lie in [0, 24]")


@dataclass(frozen=True, kw_only=True)
class SyntheticWeather:
    """Seeded synthetic weather; outdoor temperature [C] and irradiance G [W/m2] per interval.

    ``T_a = mean + daily_amplitude*cos(2 pi (h - warmest_hour)/24) + slow + noise`` where the
    slow part is a sum of two sinusoids of random phase (periods ``slow_periods_days``) with
    total amplitude ``slow_amplitude_c`` and the noise is AR(1) (3 h correlation time).
    ``G`` is ``peak * sin(pi (h - sunrise)/(sunset - sunrise))**1.5`` by day, zero at night,
    times a daily clearness drawn uniformly in [min_clearness, 1], evaluated mid-interval.

    The process is stationary, so the parts differ only in their dates: ``train`` and
    ``whole`` runs start at ``start``, ``test`` runs at ``test_start``, and a training run must
    end before it (the scenario gives test runs random streams of their own).
    """

    start: str = f"{BASE_YEAR}-04-01"
    test_start: str = f"{BASE_YEAR + 1}-04-01"
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
                raise ValueError(f"SyntheticWeather.{name} must be >= 0, got {getattr(self, name)!r}")
        if not 0.0 <= self.min_clearness <= 1.0:
            raise ValueError(f"SyntheticWeather.min_clearness must lie in [0, 1], got {self.min_clearness}")
        _check_hours("SyntheticWeather", self.sunrise_h, self.sunset_h, self.warmest_hour)
        if not self.sunrise_h < self.sunset_h:
            raise ValueError(
                f"SyntheticWeather: sunrise_h={self.sunrise_h} must precede sunset_h={self.sunset_h}"
            )
        if min(self.slow_periods_days) <= 0:
            raise ValueError(f"SyntheticWeather.slow_periods_days must be > 0, got {self.slow_periods_days}")
        starts = {}
        for name in ("start", "test_start"):
            try:
                starts[name] = pd.Timestamp(getattr(self, name))
            except ValueError as exc:
                raise ValueError(
                    f"SyntheticWeather.{name} {getattr(self, name)!r} is not a date (YYYY-MM-DD)"
                ) from exc
        if not starts["start"] + pd.Timedelta(days=1) <= starts["test_start"]:
            raise ValueError(
                f"SyntheticWeather.test_start {self.test_start} must lie at least a day after "
                f"start {self.start}"
            )

    @property
    def longest_training_days(self) -> int:
        """Training runs must end before the first test day."""
        return (pd.Timestamp(self.test_start) - pd.Timestamp(self.start)).days

    def split_text(self) -> str:
        return (
            f"Weather split (the synthetic process is stationary, only the dates differ): "
            f"training runs are dated from {self.start} (up to {self.longest_training_days} "
            f"days), test runs from {self.test_start}."
        )

    def sample(
        self, *, n: int, dt_s: float, run_days: int, part: WeatherPart, rng: np.random.Generator
    ) -> tuple[pd.DatetimeIndex, np.ndarray, np.ndarray]:
        """``n`` intervals -> (start times, T_a (n,) [C], G (n,) [W/m2]).

        ``run_days`` (the simulated days, without forecast lead) matters only to windowed
        weather; synthetic weather has no window and starts at ``start``, or for the ``test``
        part at ``test_start``.
        """
        part = weather_part(part)
        if part == "train" and _days_touched(n, dt_s) > self.longest_training_days:
            raise _too_long(
                "training",
                _days_touched(n, dt_s),
                f"which holds {self.longest_training_days} days from {self.start}",
            )
        first = pd.Timestamp(self.test_start if part == "test" else self.start)
        times = interval_starts(first, n, dt_s)
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
    """A TMY3 file shipped in pvlib's data folder (a bare name found there), an EPW file shipped
    with EnergyPlus (its name, e.g. ``usa_il_chicago``), else ``file_name`` itself as a path (a
    TMY3 ``.csv`` or an EPW ``.epw`` typical year)."""
    import pvlib

    shipped = pathlib.Path(pvlib.__file__).parent / "data" / file_name
    if pathlib.Path(file_name).name == file_name and shipped.is_file():
        return shipped
    from scenarios.plants.energyplus.files import bundled_weather

    bundled = bundled_weather()
    if file_name in bundled:  # an EPW file shipped with EnergyPlus, by name
        return pathlib.Path(bundled[file_name])
    return pathlib.Path(file_name)


@functools.lru_cache(maxsize=4)
def load_tmy3(file_name: str) -> tuple[np.ndarray, np.ndarray, str]:
    """Hourly typical year: (dry-bulb T (8760,) [C], GHI (8760,) [W/m2], station name).

    ``file_name`` as :func:`tmy3_path` resolves it; an ``.epw`` file is read with pvlib's EPW
    reader, anything else with its TMY3 reader. Row i is the hour ending at (i+1) h after
    1 January 00:00 local standard time; temperature is the value at that instant, GHI the
    mean over the hour (the TMY3 and EPW convention).
    """
    path = tmy3_path(file_name)
    if not path.is_file():
        raise InputError(
            f"weather file {file_name!r} not found (neither in pvlib's data folder nor as a path)"
        )
    epw = path.suffix.lower() == ".epw"
    if epw:
        with open(path, encoding="latin-1") as f:
            first = f.readline().strip()
        if not first.upper().startswith("LOCATION,"):
            raise InputError(
                f"weather file {path} is not an EPW file: its first line is "
                f"{first[:40]!r}, where an EPW's is its LOCATION header (8 header lines, then "
                "8760 hourly rows); give an EPW as EnergyPlus's weather site writes it"
            )
    try:
        frame, meta = _read_weather(path, epw)
        station = meta.get("city" if epw else "Name", file_name)
        t_a = frame["temp_air"].to_numpy(dtype=float)
        ghi = frame["ghi"].to_numpy(dtype=float)
    except Exception as exc:  # pvlib raises many kinds on a malformed file; one line for the user
        kind = "EPW" if epw else "TMY3"
        raise InputError(f"weather file {path} is not a readable {kind} file: {exc}") from None
    if len(t_a) != HOURS_PER_TYPICAL_YEAR:
        raise InputError(f"weather file {path} has {len(t_a)} hours, a typical year has {HOURS_PER_TYPICAL_YEAR}")
    if not (np.isfinite(t_a).all() and np.isfinite(ghi).all()):
        raise InputError(f"weather file {path} has missing temperature or GHI values")
    return t_a, np.maximum(ghi, 0.0), str(station).strip('"')


def _read_weather(path: pathlib.Path, epw: bool) -> tuple[pd.DataFrame, dict]:
    """pvlib's reading of an EPW (``epw``) or TMY3 file: its hourly frame and its metadata."""
    import pvlib

    if epw:
        return pvlib.iotools.read_epw(path)
    return pvlib.iotools.read_tmy3(path, map_variables=True)


@functools.lru_cache(maxsize=4)
def load_site_irradiance(file_name: str) -> dict[str, Any]:
    """What :func:`pinn_mpc.solar.facade_irradiance` needs of a weather file besides the
    instants: its hourly global, beam normal and diffuse horizontal irradiance (8760,) [W/m2]
    and its site (latitude, longitude, time zone, altitude), as keyword arguments;
    ``file_name`` as :func:`load_tmy3` takes it (which has checked the file by then)."""
    load_tmy3(file_name)
    path = tmy3_path(file_name)
    try:
        frame, meta = _read_weather(path, path.suffix.lower() == ".epw")
        return {
            "ghi_w_per_m2": frame["ghi"].to_numpy(dtype=float),
            "dni_w_per_m2": frame["dni"].to_numpy(dtype=float),
            "dhi_w_per_m2": frame["dhi"].to_numpy(dtype=float),
            "latitude_deg": float(meta["latitude"]),
            "longitude_deg": float(meta["longitude"]),
            "utc_offset_h": float(meta["TZ"]),
            "altitude_m": float(meta["altitude"]),
        }
    except Exception as exc:  # pvlib raises many kinds on a malformed file; one line for the user
        raise InputError(
            f"weather file {path}: no beam and diffuse irradiance or site for the facades ({exc})"
        ) from None


@functools.lru_cache(maxsize=4)
def load_site_wind(file_name: str) -> np.ndarray:
    """The weather file's hourly wind speed (8760,) [m/s]; ``file_name`` as :func:`load_tmy3`
    takes it. InputError when the file has none or it is not plausible."""
    from pinn_mpc.data import WIND_RANGE_M_S

    load_tmy3(file_name)
    path = tmy3_path(file_name)
    try:
        frame, _ = _read_weather(path, path.suffix.lower() == ".epw")
        speed = frame["wind_speed"].to_numpy(dtype=float)
    except Exception as exc:  # pvlib raises many kinds on a malformed file; one line for the user
        raise InputError(f"weather file {path}: no wind speed ({exc})") from None
    lo, hi = WIND_RANGE_M_S
    bad = np.flatnonzero(~((speed >= lo) & (speed <= hi)))
    if len(speed) != HOURS_PER_TYPICAL_YEAR or bad.size:
        where = f"; hour {bad[0] + 1} has {speed[bad[0]]:g} (an EPW's 999 is a missing value)" if bad.size else ""
        raise InputError(
            f"weather file {path}: its wind speeds must be {HOURS_PER_TYPICAL_YEAR} hourly values "
            f"in {lo:g} .. {hi:g} m/s{where}; fill the gaps first"
        )
    return speed


def resample_typical_year(
    t_a_hourly_c: np.ndarray, ghi_hourly_w_per_m2: np.ndarray, *, start_s: float, n: int, dt_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Hourly typical year (8760,) -> per interval (n,), wrapping around the year.

    ``start_s`` is the first interval start in seconds after 1 January 00:00. Temperature is
    linearly interpolated at mid-interval (for intervals within an hour this is the interval
    mean of the interpolant); GHI, an hourly mean, becomes the exact interval mean of the
    piecewise-constant hourly series, so daily energy is preserved.
    """
    t_a = _interpolated_hourly(t_a_hourly_c, start_s=start_s, n=n, dt_s=dt_s)
    return t_a, _interval_means(ghi_hourly_w_per_m2, start_s=start_s, n=n, dt_s=dt_s)


def _interpolated_hourly(hourly: np.ndarray, *, start_s: float, n: int, dt_s: float) -> np.ndarray:
    """A typical year's hourly values (8760,), each standing at its hour's end and linearly
    interpolated between (as EnergyPlus reads temperature and wind), at the middles of ``n``
    intervals of ``dt_s`` from ``start_s`` [s after 1 January 00:00], wrapping around the year."""
    period_s = HOURS_PER_TYPICAL_YEAR * 3600.0
    middles = start_s + np.arange(n) * dt_s + 0.5 * dt_s
    knots_s = (np.arange(HOURS_PER_TYPICAL_YEAR) + 1) * 3600.0
    return np.interp(middles, knots_s, hourly, period=period_s)


def _seconds_into_year(first: pd.Timestamp) -> float:
    """Seconds from 1 January 00:00 of ``first``'s year to ``first``."""
    return (first - pd.Timestamp(year=first.year, month=1, day=1)).total_seconds()


def _interval_means(
    hourly_w_per_m2: np.ndarray, *, start_s: float, n: int, dt_s: float
) -> np.ndarray:
    """Hourly means of a typical year (8760,) -> the exact interval means (n,) of the
    piecewise-constant hourly series (its energy preserved), wrapping around the year, >= 0."""
    period_s = HOURS_PER_TYPICAL_YEAR * 3600.0
    starts = start_s + np.arange(n) * dt_s
    energy_knots = np.concatenate([[0.0], np.cumsum(hourly_w_per_m2) * 3600.0])
    energy_t = np.arange(HOURS_PER_TYPICAL_YEAR + 1) * 3600.0

    def energy(t_s: np.ndarray) -> np.ndarray:
        years = np.floor(t_s / period_s)
        return years * energy_knots[-1] + np.interp(t_s - years * period_s, energy_t, energy_knots)

    return np.maximum((energy(starts + dt_s) - energy(starts)) / dt_s, 0.0)


def _day_of_year(owner: str, month_day: str) -> int:
    """``"MM-DD"`` -> day of the (non-leap) typical year, 0 = 1 January."""
    try:
        return (pd.Timestamp(f"{BASE_YEAR}-{month_day}") - _FIRST_DAY).days
    except ValueError as exc:
        raise ValueError(f"{owner} {month_day!r} is not MM-DD") from exc


def _month_day(day: int) -> str:
    """Day of the typical year -> e.g. ``"Feb 1"``."""
    t = _FIRST_DAY + pd.Timedelta(days=day % _DAYS_PER_TYPICAL_YEAR)
    return f"{t:%b} {t.day}"


@dataclass(frozen=True, kw_only=True)
class TMY3Weather:
    """Real typical-year weather from pvlib's TMY3 files, in a seasonal window.

    The window starts at ``window_start`` (``"MM-DD"``) and lasts ``window_days`` days (it may
    wrap past 31 December). Inside it, ``test_days`` days from ``test_start`` are the test part
    and the window's days before them the training part. Each run's start day is drawn with
    ``rng``, uniformly among those that keep the run in its part:

    - ``test``: all rows of the run (warm-up, counted days, forecast lead) in the test part; a
      longer run is refused.
    - ``train``: all rows in the training part; a longer run starts earlier, in the weeks before
      the window, and still ends the day before the test part (so training sizes beyond the
      season fit without touching a test day); longer than ``365 - test_days`` days, refused.
    - ``whole``: ``run_days`` (the forecast lead not counted) inside the window; a longer run
      continues past its end (the draws before the split).

    ``whole`` runs are labelled from :data:`BASE_YEAR`, runs in a part in season order (the
    window starts in ``BASE_YEAR + 1``); both are non-leap years until 2024, so calendar and
    typical year agree for runs shorter than about two years.
    """

    file_name: str = "723170TYA.CSV"
    window_start: str = "11-01"
    window_days: int = 151
    test_start: str = "02-01"
    test_days: int = 59
    #: Fields holding a file path, resolved relative to the scenario file that names them.
    PATH_FIELDS: ClassVar[tuple[str, ...]] = ("file_name",)

    def __post_init__(self) -> None:
        if not 1 <= self.window_days <= _DAYS_PER_TYPICAL_YEAR:
            raise ValueError(f"TMY3Weather.window_days must lie in [1, 365], got {self.window_days}")
        core = self.training_core_days  # also checks both dates
        if not (1 <= core and self.test_days >= 1 and core + self.test_days <= self.window_days):
            raise ValueError(
                f"TMY3Weather: the test part ({self.test_days} days from {self.test_start}) must "
                f"lie inside the window ({self.window_days} days from {self.window_start}) with "
                "at least one training day before it"
            )

    def check(self) -> None:
        """Read and check the weather file now (a scenario file is checked when it is loaded)."""
        load_tmy3(self.file_name)

    @property
    def training_core_days(self) -> int:
        """Days of the window before the test part: where training runs that fit are drawn."""
        start = _day_of_year("TMY3Weather.window_start", self.window_start)
        test = _day_of_year("TMY3Weather.test_start", self.test_start)
        return (test - start) % _DAYS_PER_TYPICAL_YEAR

    @property
    def longest_training_days(self) -> int:
        return _DAYS_PER_TYPICAL_YEAR - self.test_days

    def split_text(self) -> str:
        start = _day_of_year("window_start", self.window_start)
        test = _day_of_year("test_start", self.test_start)
        return (
            f"Weather split (days of the typical year): training {_month_day(start)} - "
            f"{_month_day(test - 1)} ({self.training_core_days} days; a longer training run "
            f"starts earlier and still ends {_month_day(test - 1)}, up to "
            f"{self.longest_training_days} days), test {_month_day(test)} - "
            f"{_month_day(test + self.test_days - 1)} ({self.test_days} days, holding a test "
            "run's warm-up day, counted days and forecast lead)."
        )

    def _start_offset(
        self, part: WeatherPart, *, need_days: int, run_days: int, rng: np.random.Generator
    ) -> int:
        """Days from the window start to the run's first day (negative: before the window)."""
        core = self.training_core_days
        if part == "whole":
            return int(rng.integers(max(self.window_days - run_days, 0) + 1))
        test = _day_of_year("test_start", self.test_start)
        test_block = f"{_month_day(test)} - {_month_day(test + self.test_days - 1)}"
        if part == "test":
            if need_days > self.test_days:
                raise _too_long("test", need_days, f"the {self.test_days} days {test_block}")
            return core + int(rng.integers(self.test_days - need_days + 1))
        if need_days <= core:
            return int(rng.integers(core - need_days + 1))
        if need_days > self.longest_training_days:
            room = (
                f"which may reach back {self.longest_training_days} days from "
                f"{_month_day(test - 1)} before meeting the test days {test_block}"
            )
            raise _too_long("training", need_days, room)
        return core - need_days

    def facades(self, times: pd.DatetimeIndex, *, dt_s: float) -> dict[str, np.ndarray]:
        """The facades' irradiance (:data:`FACADE_COLUMNS` -> (n,) [W/m2]) in the intervals
        starting at ``times`` (consecutive, as :meth:`sample` gives them): interval means
        (:func:`pinn_mpc.solar.interval_means`) from the weather file's irradiance at its site
        (:func:`load_site_irradiance`), placed in the typical year by the day of the year of
        the first time stamp, as :meth:`sample` places ``G``."""
        times = pd.DatetimeIndex(times)
        if len(times) == 0:
            return {name: np.zeros(0) for name in FACADE_COLUMNS}
        site = load_site_irradiance(self.file_name)
        return interval_means(_seconds_into_year(times[0]), len(times), dt_s, year=times[0].year, **site)

    def wind(self, times: pd.DatetimeIndex, *, dt_s: float) -> np.ndarray:
        """The weather file's wind speed (n,) [m/s] in the intervals starting at ``times``
        (consecutive, placed in the typical year as :meth:`facades` places them): its hourly
        values, which EnergyPlus interpolates linearly between the hours, at each interval's
        middle, as ``T_a``."""
        times = pd.DatetimeIndex(times)
        if len(times) == 0:
            return np.zeros(0)
        return _interpolated_hourly(
            load_site_wind(self.file_name), start_s=_seconds_into_year(times[0]), n=len(times), dt_s=dt_s
        )

    def sample(
        self, *, n: int, dt_s: float, run_days: int, part: WeatherPart, rng: np.random.Generator
    ) -> tuple[pd.DatetimeIndex, np.ndarray, np.ndarray]:
        """``n`` intervals -> (start times, T_a (n,) [C], G (n,) [W/m2]).

        The start day is drawn as the class docstring says: for ``whole`` it leaves room for
        ``run_days`` in the window, so forecast lead rows (``n`` beyond ``run_days``) never
        move it; for ``train`` and ``test`` all ``n`` rows must fit in the part.
        """
        part = weather_part(part)
        t_a_hourly, ghi_hourly, _ = load_tmy3(self.file_name)
        offset = self._start_offset(part, need_days=_days_touched(n, dt_s), run_days=run_days, rng=rng)
        window = _day_of_year("window_start", self.window_start)
        start_s = ((window + offset) % _DAYS_PER_TYPICAL_YEAR) * SECONDS_PER_DAY
        t_a, ghi = resample_typical_year(t_a_hourly, ghi_hourly, start_s=start_s, n=n, dt_s=dt_s)
        if part == "whole":  # the labels from before the split, day of the year in BASE_YEAR
            start = _FIRST_DAY + pd.Timedelta(seconds=start_s)
        else:  # season order: training before test, in non-leap years from BASE_YEAR on
            start = pd.Timestamp(f"{_SEASON_YEAR}-{self.window_start}") + pd.Timedelta(days=offset)
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
            raise ValueError(
                f"PriceProfile.kind {self.kind!r} is unknown; use constant, day_night or dynamic"
            )
        for name in ("level_eur_per_kwh", "night_eur_per_kwh", "peak_eur_per_kwh",
                     "noise_std_eur_per_kwh", "floor_eur_per_kwh"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"PriceProfile.{name} must be >= 0, got {getattr(self, name)!r}")
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
        for band in ("day", "night"):
            low, high = getattr(self, f"{band}_min_c"), getattr(self, f"{band}_max_c")
            if not low < high:
                raise ValueError(
                    f"ComfortSchedule.{band}_min_c ({low}) must be below {band}_max_c ({high}): "
                    "the comfort band needs min < max"
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
                raise ValueError(f"GainsSchedule.{name} must be >= 0, got {getattr(self, name)!r}")
        if not 0.0 <= self.event_probability <= 1.0:
            raise ValueError(
                f"GainsSchedule.event_probability must lie in [0, 1], got {self.event_probability}"
            )
        for start, end in self.periods_h:
            _check_hours("GainsSchedule.periods_h", start)
            if not start < end <= start + 24.0:
                raise ValueError(f"GainsSchedule period ({start}, {end}) must have start < end")

    @property
    def active(self) -> bool:
        return self.base_w > 0 or (bool(self.periods_h) and (self.scheduled_w > 0 or self.event_w > 0))

    def sample(self, times: pd.DatetimeIndex, *, rng: np.random.Generator) -> np.ndarray:
        """Interval start times (N,) -> gains (N,) [W]."""
        inside = _in_periods(time_of_day_h(times), self.periods_h)
        events = rng.random(len(times)) < self.event_probability
        return self.base_w + inside * (self.scheduled_w + events * self.event_w)

    def expected(self, times: pd.DatetimeIndex) -> np.ndarray:
        """Interval start times (N,) -> the expectation of :meth:`sample` (N,) [W]: what a
        controller that does not measure the gains knows of them."""
        inside = _in_periods(time_of_day_h(times), self.periods_h)
        return self.base_w + inside * (self.scheduled_w + self.event_probability * self.event_w)
