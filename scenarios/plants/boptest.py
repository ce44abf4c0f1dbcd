"""A BOPTEST test case as the closed loop's plant, through BOPTEST's web API alone.

BOPTEST (IBPSA Project 1) is the building-control benchmark: Modelica emulators served over
HTTP with fixed test periods, price scenarios, forecasts and KPIs computed by BOPTEST itself.
:class:`BoptestPlant` selects a test on a BOPTEST server (BOPTEST's own service; the address
from the scenario, else ``$BOPTEST_URL``, else ``http://127.0.0.1:8000``), starts it at a test period with BOPTEST's warm-up and price scenario
(:class:`BoptestRun`), and steps it one control interval at a time as
:class:`scenarios.plants.base.LoopPlant` asks: the package's demand in watts becomes the test case's
signal, ``POST /advance`` runs the interval, ``PUT /results`` gives the interval's means.

What the package calls the actuator, the room temperature, the consumed and delivered power,
the weather, the comfort band and the price are points of the test case, named in a
:class:`BoptestPoints` read from the scenario file (:func:`boptest_settings_from_dict`), so
another test case is a scenario file away.

Power is electrical, as everywhere in the package (:mod:`pinn_mpc.actuator`): ``u`` is the
electrical power asked for, ``u_phys`` the interval's mean electrical power the test case
reports on the points BOPTEST's energy KPI sums (for ``bestest_hydronic_heat_pump`` the heat
pump's compressor, its evaporator fan and the floor-heating pump), so the package's energy
and cost are BOPTEST's. The heat reaching the room (``reaQFloHea_y``) is recorded beside it
(:meth:`BoptestPlant.history`). :class:`SignalScaling` maps watts to the 0..1 signal through
the electrical power the machine draws when running (a curve measured on the emulator): a
modulating heat pump does not run below its lowest power (with its fan and pump on), so a
demand below that runs it at its lowest signal or switches it off, whichever is nearer.

The controllers' forecasts of weather, gains, comfort band and price are BOPTEST's
``/forecast`` (:meth:`BoptestPlant.exogenous_frame`), interval means of its samples.
The test stops on the server however the plant is left (:meth:`BoptestPlant.close`, or use it
as a context manager; an error or Ctrl-C included). A plant given a test (``test=``) borrows it:
it re-starts that test for its run instead of selecting one, and leaves stopping it to its owner
(``run_boptest_comparison`` runs all its rows on one test so).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
import pandas as pd

from pinn_mpc.errors import InputError, InternalError, setting
from pinn_mpc.simulator import StepResult
from pinn_mpc.zones import ONE_ZONE
from scenarios.plants.base import PlantStep
from scenarios.plants.boptest_client import BoptestClient, BoptestError, BoptestTest, end_on_exit

__all__ = [
    "PRICE_SCENARIOS",
    "BoptestPlant",
    "BoptestPoints",
    "BoptestRun",
    "BoptestSettings",
    "SignalScaling",
    "BUILTIN_BOPTEST",
    "boptest_settings_from_dict",
    "boptest_description",
    "boptest_file",
    "builtin_boptest",
    "read_boptest_file",
    "record_data",
]

KELVIN = 273.15
SECONDS_PER_DAY = 86400.0
#: The days of BOPTEST's year (its test cases' time runs from 0 s, 1 January, over 365 days).
DAYS_PER_YEAR = 365.0
#: BOPTEST's price scenarios (``electricity_price``).
PRICE_SCENARIOS = ("constant", "dynamic", "highly_dynamic")
#: BOPTEST's test periods: 14 days centred on the test case's day (days.json), after a
#: 7-day warm-up.
TEST_PERIOD_DAYS = 14.0
WARMUP_DAYS = 7.0
#: The price of discomfort [EUR per K h per zone] BOPTEST-gym's reward puts beside the cost
#: in EUR (cost_tot x floor area + 100 x tdis_tot): a 1 K shortfall for an hour costs as much
#: as 100 EUR of electricity, so controllers keep the band unless keeping it is dear.
DEFAULT_COMFORT_WEIGHT = 100.0
#: BOPTEST stores its trajectories every 30 s: the substeps of an interval.
RESULT_SAMPLE_S = 30.0
#: Forecast samples per interval are at most this far apart [s] (interval means).
FORECAST_SAMPLE_S = 300.0


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"{where} must be a finite number, got {value!r}")
    return float(value)


def _name(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise InputError(f"{where} must be a point name (a non-empty string), got {value!r}")
    return value


def _period_day(value: Any, where: str) -> float:
    """The day a test period is centred on (days.json), checked: a whole day of the year with
    the period and its warm-up inside the year."""
    day = _number(value, where)
    low, high = TEST_PERIOD_DAYS / 2 + WARMUP_DAYS, DAYS_PER_YEAR - TEST_PERIOD_DAYS / 2
    if day != int(day) or not low <= day <= high:
        raise InputError(
            f"{where} = {value!r}: a test period is the {TEST_PERIOD_DAYS:g} days centred on this "
            f"day of the year (0 = 1 January) after a {WARMUP_DAYS:g}-day warm-up, so it must be a "
            f"whole day from {low:g} to {high:g} (BOPTEST's days.json of the test case)"
        )
    return day


def _names(value: Any, where: str) -> tuple[str, ...]:
    if isinstance(value, str):
        value = (value,)
    if not isinstance(value, list | tuple) or not value:
        raise InputError(f"{where} must be a point name or a list of them, got {value!r}")
    return tuple(_name(v, f"{where}[{i}]") for i, v in enumerate(value))


@dataclass(frozen=True, kw_only=True)
class SignalScaling:
    """Between the package's demand ``u`` [W, electrical] and the test case's signal.

    ``signal`` and ``power_w`` are knots of the electrical power the machine draws while it
    runs (strictly increasing both, signals in (0, 1]); the signal 0 is off (0 W). A demand
    at or above the lowest knot's power gets the signal interpolated on the curve (clipped to
    the last knot); a demand below it runs the machine at the lowest signal when it is at
    least half that power, else switches it off.
    """

    signal: tuple[float, ...]
    power_w: tuple[float, ...]

    def __post_init__(self) -> None:
        s = tuple(_number(v, f"actuator.signal[{i}]") for i, v in enumerate(self.signal))
        p = tuple(_number(v, f"actuator.power_w[{i}]") for i, v in enumerate(self.power_w))
        if len(s) != len(p) or len(s) < 2:
            raise InputError(
                f"actuator.signal and actuator.power_w need the same number (>= 2) of knots, "
                f"got {len(s)} and {len(p)}"
            )
        if not (0 < s[0] and s[-1] <= 1 and all(a < b for a, b in zip(s, s[1:], strict=False))):
            raise InputError(f"actuator.signal must increase strictly within (0, 1], got {list(s)}")
        if not (0 < p[0] and all(a < b for a, b in zip(p, p[1:], strict=False))):
            raise InputError(f"actuator.power_w must be > 0 and increase strictly, got {list(p)}")
        object.__setattr__(self, "signal", s)
        object.__setattr__(self, "power_w", p)

    @property
    def max_power_w(self) -> float:
        """The electrical power at the highest signal: the package's ``u_max_w``."""
        return self.power_w[-1]

    @property
    def min_power_w(self) -> float:
        """The lowest electrical power the machine runs at."""
        return self.power_w[0]

    def to_signal(self, u_w: float) -> float:
        """The signal for a demand of ``u_w`` watts (see the class docstring)."""
        if not math.isfinite(u_w):
            raise ValueError(f"SignalScaling.to_signal: the demand must be finite, got {u_w!r}")
        if u_w < self.min_power_w:
            return self.signal[0] if u_w >= 0.5 * self.min_power_w else 0.0
        return float(np.interp(u_w, self.power_w, self.signal))

    def to_power_w(self, signal: float) -> float:
        """The electrical power [W] the curve gives for ``signal`` (0 when off)."""
        if signal <= 0:
            return 0.0
        return float(np.interp(signal, self.signal, self.power_w))


@dataclass(frozen=True, kw_only=True)
class BoptestPoints:
    """The test case's points the package uses, by their BOPTEST names.

    Measurements (``/measurements``): ``room_temperature`` [K], ``consumed_power`` [W] (summed:
    the package's electrical ``u_phys``), ``delivered_heat`` [W] (recorded), ``outdoor_temperature``
    [K], ``irradiance`` [W/m2]. Inputs (``/inputs``): ``actuator`` (the signal) and its
    ``activate``. Forecasts (``/forecast_points``): ``forecast_outdoor_temperature`` [K],
    ``forecast_irradiance`` [W/m2], ``forecast_gains`` [W] (summed), ``comfort_lower`` and
    ``comfort_upper`` [K], and one price point per price scenario (``prices`` [EUR/kWh]).
    ``test_periods`` are BOPTEST's (days.json: the day each 14-day period is centred on).
    """

    testcase: str
    actuator: str
    activate: str
    scaling: SignalScaling
    room_temperature: str
    consumed_power: tuple[str, ...]
    delivered_heat: str
    outdoor_temperature: str
    irradiance: str
    forecast_outdoor_temperature: str
    forecast_irradiance: str
    forecast_gains: tuple[str, ...]
    comfort_lower: str
    comfort_upper: str
    prices: Mapping[str, str]
    test_periods: Mapping[str, float]
    floor_area_m2: float
    #: The calendar year the test case's time 0 (1 January, 00:00) is dated in: the weekdays
    #: of its schedules.
    year: int = 2018

    def __post_init__(self) -> None:
        missing = [p for p in PRICE_SCENARIOS if p not in self.prices]
        if missing:
            raise InputError(
                f"boptest.prices needs a forecast point for each price scenario; missing {missing}"
            )
        if not self.test_periods:
            raise InputError("boptest.test_periods is empty: give BOPTEST's days.json, e.g. peak_heat_day = 23")
        for period, day in self.test_periods.items():
            _period_day(day, f"boptest.test_periods.{period}")
        _number(self.floor_area_m2, "boptest.floor_area_m2")
        if self.floor_area_m2 <= 0:
            raise InputError(f"boptest.floor_area_m2 must be > 0 m2, got {self.floor_area_m2!r}")

    def period_days(self, time_period: str) -> tuple[float, float]:
        """(first, end) day of the year [d, 0 = 1 January] of a test period (end excluded)."""
        if time_period not in self.test_periods:
            raise InputError(
                f"test period {time_period!r} is not one of {self.testcase}'s: "
                f"{', '.join(self.test_periods)}"
            )
        first = float(self.test_periods[time_period]) - WARMUP_DAYS
        return first, first + TEST_PERIOD_DAYS

    def data_first_day(self, time_period: str, days: float) -> float:
        """The first day of the year [d] of ``days`` days of training data for ``time_period``:
        the days nearest it off every test period and warm-up, those right before its warm-up
        (the building's recent past, as a controller in service is trained) where they fit
        after the data's own warm-up from 1 January, else those right after its end."""
        first, end = self.period_days(time_period)
        candidates = (first - WARMUP_DAYS - days, end)
        for start in candidates:
            if start < WARMUP_DAYS or start + days > 365.0:
                continue
            try:
                self.check_disjoint(start, days)
            except InputError:
                continue
            return float(start)
        raise InputError(
            f"no {days:g} days of training data fit beside test period {time_period} off every "
            f"test period; give fewer days or the data's first day ({setting('first_day')})"
        )

    def check_disjoint(self, first_day: float, days: float) -> None:
        """Refuse a data period [first_day, first_day + days) that overlaps a test period or
        its warm-up (the days controllers are judged on must not be trained on)."""
        for period in self.test_periods:
            first, end = self.period_days(period)
            warm = first - WARMUP_DAYS
            if first_day < end and first_day + days > warm:
                raise InputError(
                    f"days {first_day:g}-{first_day + days:g} of the year overlap BOPTEST's test "
                    f"period {period} with its warm-up (days {warm:g}-{end:g}); choose days "
                    "outside every test period"
                )


@dataclass(frozen=True, kw_only=True)
class BoptestRun:
    """What a run asks of BOPTEST: a test period (``time_period``, with BOPTEST's warm-up) or,
    for data, a period of its own (``first_day`` [d of the year] after ``warmup_days``); the
    price scenario; the control interval ``dt_s``; ``days`` run (a test period: at most 14)."""

    time_period: str | None = "peak_heat_day"
    first_day: float | None = None
    days: float = TEST_PERIOD_DAYS
    price_scenario: str = "dynamic"
    dt_s: float = 1800.0
    warmup_days: float = WARMUP_DAYS

    def __post_init__(self) -> None:
        if (self.time_period is None) == (self.first_day is None):
            raise ValueError("BoptestRun: give a test period (time_period) or first_day, not both")
        if self.price_scenario not in PRICE_SCENARIOS:
            raise ValueError(
                f"price scenario {self.price_scenario!r} is not BOPTEST's; choose one of "
                f"{', '.join(PRICE_SCENARIOS)}"
            )
        dt = _number(self.dt_s, "BoptestRun.dt_s")
        if not (RESULT_SAMPLE_S <= dt <= SECONDS_PER_DAY and SECONDS_PER_DAY % dt == 0):
            raise ValueError(f"BoptestRun.dt_s = {dt:g} s must divide a day and be >= 30 s")
        days = _number(self.days, "the run's days")
        if days <= 0:
            raise ValueError(f"a BOPTEST run of {days:g} days: give a number of days > 0")
        if self.time_period is not None and days > TEST_PERIOD_DAYS:
            raise ValueError(
                f"a BOPTEST test period has {TEST_PERIOD_DAYS:g} days, {days:g} were asked for "
                f"{self.time_period}; give at most {TEST_PERIOD_DAYS:g} (its whole period)"
            )
        if self.first_day is not None and _number(self.first_day, "the run's first day") + days > DAYS_PER_YEAR:
            raise InputError(
                f"days {self.first_day:g}-{self.first_day + days:g} of the year run past its "
                f"end (day {DAYS_PER_YEAR:g}); give an earlier first day or fewer days"
            )
        if _number(self.warmup_days, "BoptestRun.warmup_days") < 0:
            raise ValueError(f"BoptestRun.warmup_days must be >= 0, got {self.warmup_days!r}")

    @property
    def n_intervals(self) -> int:
        """Control intervals of the run."""
        return int(round(self.days * SECONDS_PER_DAY / self.dt_s))


@dataclass(frozen=True, kw_only=True)
class BoptestSettings:
    """A BOPTEST scenario's part: the points and the server (``url`` None: ``$BOPTEST_URL``
    or the local default), with the timeout [s] of every ordinary call."""

    points: BoptestPoints
    url: str | None = None
    timeout_s: float = 120.0
    #: The controllers' price of discomfort [EUR per K h of the room outside its band]: the
    #: objective they minimise is cost [EUR] + this x BOPTEST's thermal discomfort.
    comfort_weight_eur_per_kh: float = DEFAULT_COMFORT_WEIGHT

    def __post_init__(self) -> None:
        if not (math.isfinite(self.comfort_weight_eur_per_kh) and self.comfort_weight_eur_per_kh >= 0):
            raise InputError(
                "boptest.comfort_weight_eur_per_kh must be a number >= 0 (EUR per K h), "
                f"got {self.comfort_weight_eur_per_kh!r}"
            )


@dataclass
class _Interval:
    """One interval's record (:meth:`BoptestPlant.history`)."""

    time_s: float
    u_w: float
    signal: float
    values: dict[str, float] = field(default_factory=dict)


def _trapezoid_mean(t: np.ndarray, y: np.ndarray) -> float:
    if len(t) < 2 or t[-1] <= t[0]:
        return float(y[-1])
    return float(np.trapezoid(y, t) / (t[-1] - t[0]))


class BoptestPlant:
    """A BOPTEST test as a :class:`scenarios.plants.base.LoopPlant` (one building, no true state).

    Construction selects a test on the server, checks the points against the test case's
    (one clear error naming a missing point), sets the control step and starts the run
    (:class:`BoptestRun`); on any failure the test is stopped. Given a ``test`` (of the same
    test case), the plant borrows it: no select, the run started on it as :meth:`reset`
    re-starts one (BOPTEST re-initialises the test and its KPIs), and neither a failure nor
    :meth:`close` stops it: its owner does (a :class:`BoptestTest` in a ``with`` block).
    :meth:`reset` at row 0 starts the run afresh (unless nothing has been stepped since it
    started); the state it is given is ignored (BOPTEST's warm-up sets the state).
    :meth:`step` holds the demand over row ``row``'s interval. With ``baseline`` the demand is
    ignored and no input is overwritten: the test case's own controller acts (BOPTEST's
    baseline, the reference of its tables).
    """

    has_true_state = False
    n_buildings = 1
    zones = ONE_ZONE  # the test case's room point (BoptestPoints.room_temperature)

    def __init__(
        self, settings: BoptestSettings, run: BoptestRun, *, baseline: bool = False,
        lead_intervals: int = 0, test: BoptestTest | None = None,
    ) -> None:
        self.settings, self.run, self.points = settings, run, settings.points
        self.baseline = baseline
        if lead_intervals < 0:
            raise ValueError(f"BoptestPlant: lead_intervals must be >= 0, got {lead_intervals}")
        self.lead_intervals = int(lead_intervals)
        if run.first_day is not None:
            self.points.check_disjoint(run.first_day, run.days)
        elif run.time_period is not None:
            self.points.period_days(run.time_period)
        self.n_substeps = max(1, int(round(run.dt_s / RESULT_SAMPLE_S)))
        self.borrowed = test is not None
        if test is not None and test.testcase != self.points.testcase:
            raise ValueError(
                f"BoptestPlant: the test given is of test case {test.testcase}, the scenario's "
                f"is {self.points.testcase}"
            )
        self.client = test.client if test is not None else BoptestClient(settings.url, timeout_s=settings.timeout_s)
        try:  # from the select on: a test the plant selected is stopped however this is left
            self.test: BoptestTest = test if test is not None else self.client.select(self.points.testcase)
            self._check_points()
            self.test.set_step(run.dt_s)
            self._start()
        except BaseException:
            self.close()
            raise

    # --- lifecycle ---------------------------------------------------------------------------
    def _check_points(self) -> None:
        p = self.points
        groups = (
            ("input", self.test.inputs(), (p.actuator, p.activate)),
            ("measurement", self.test.measurements(),
             (p.room_temperature, *p.consumed_power, p.delivered_heat, p.outdoor_temperature, p.irradiance)),
            ("forecast point", self.test.forecast_points(),
             (p.forecast_outdoor_temperature, p.forecast_irradiance, *p.forecast_gains,
              p.comfort_lower, p.comfort_upper, *p.prices.values())),
        )
        for kind, known, wanted in groups:
            unknown = [name for name in wanted if name not in known]
            if unknown:
                raise InputError(
                    f"BOPTEST test case {p.testcase} has no {kind} {', '.join(unknown)} (named "
                    f"in the scenario's boptest points); its {kind}s: {', '.join(sorted(known))}"
                )

    def _start(self) -> None:
        """(Re)start the run: BOPTEST's scenario for a test period, else an initialisation."""
        run = self.run
        if run.time_period is not None:
            payload = self.test.set_scenario(
                time_period=run.time_period, electricity_price=run.price_scenario
            )
            state = payload.get("time_period")
            if not isinstance(state, dict):
                raise BoptestError(f"BOPTEST set no test period {run.time_period}: {payload!r}")
            self._state = {k: float(v) for k, v in state.items()}
        else:
            first_day = float(run.first_day or 0.0)  # BoptestRun: first_day without time_period
            self._state = self.test.initialize(
                first_day * SECONDS_PER_DAY, run.warmup_days * SECONDS_PER_DAY
            )
            self.test.set_scenario(electricity_price=run.price_scenario)
        self.start_time_s = self._state["time"]
        self._row = 0
        self._log: list[_Interval] = []
        self._frame = self._forecast_frame()

    def close(self) -> None:
        """Stop the test on the server and close the session (once; later calls do nothing).
        A borrowed test is left running, its session open: its owner ends them."""
        if self.borrowed:
            return
        try:
            if hasattr(self, "test"):  # else the select failed: the client stops what it began
                self.test.stop()
        finally:
            self.client.close()

    def __enter__(self) -> BoptestPlant:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        end_on_exit(self.close, failed=exc_type is not None)

    # --- the LoopPlant interface -------------------------------------------------------------
    def reset(self, t_r_c: float, t_m_c: float, *, start: int, seed: int | None) -> None:
        """Start the run at row ``start`` (0: BOPTEST's start; the state is BOPTEST's warm-up's,
        ``t_r_c``, ``t_m_c`` and ``seed`` do not apply)."""
        if start != 0:
            raise ValueError(
                f"a BOPTEST run starts at its period's start (row 0), not row {start}"
            )
        if self._row != 0 or self._log:
            self._start()

    def measure(self) -> np.ndarray:
        """The room temperature now [C], (1, 1): one building, one zone."""
        return np.array([[self._state[self.points.room_temperature] - KELVIN]])

    def step(self, u_w: float | np.ndarray, row: int) -> PlantStep:
        """Hold the demand ``u_w`` [W] over row ``row``'s interval (the next of the run)."""
        if row != self._row:
            raise InternalError(f"BoptestPlant.step: the run is at row {self._row}, not {row}")
        if row >= self.run.n_intervals:
            raise InternalError(f"BoptestPlant.step: the run has {self.run.n_intervals} intervals")
        u = np.asarray(u_w, dtype=float).reshape(-1)
        if u.size != 1 or not math.isfinite(float(u[0])):
            raise ValueError(f"BoptestPlant.step: one finite power, got {u_w!r}")
        if self.baseline:
            return self._advance({}, float(u[0]), math.nan)
        signal = self.points.scaling.to_signal(float(u[0]))
        return self._advance({self.points.actuator: signal, self.points.activate: 1.0}, float(u[0]), signal)

    def step_baseline(self, row: int) -> PlantStep:
        """Advance row ``row``'s interval with no input overwritten: the test case's own
        controller acts (BOPTEST's baseline)."""
        if row != self._row:
            raise InternalError(f"BoptestPlant.step_baseline: the run is at row {self._row}, not {row}")
        return self._advance({}, math.nan, math.nan)

    def _advance(self, inputs: dict[str, float], u_w: float, signal: float) -> PlantStep:
        p = self.points
        t0 = self._state["time"]
        payload = self.test.advance(inputs)
        if not payload:
            raise InternalError(
                f"BOPTEST's test period ended at {t0 / SECONDS_PER_DAY:g} d of the year: the run "
                "asks for more intervals than the period has"
            )
        self._state = payload
        names = (p.room_temperature, *p.consumed_power, p.delivered_heat, p.outdoor_temperature, p.irradiance, p.actuator)
        res = self.test.results(names, start_time_s=t0, final_time_s=payload["time"])
        t = res["time"]
        means = {name: _trapezoid_mean(t, res[name]) for name in names}
        u_phys = sum(means[name] for name in p.consumed_power)
        t_r_c = payload[p.room_temperature] - KELVIN
        sub_t = t0 + (np.arange(self.n_substeps) + 1) * (payload["time"] - t0) / self.n_substeps
        t_r_sub = np.interp(sub_t, t, res[p.room_temperature]) - KELVIN
        applied = payload.get(p.actuator, signal)
        overridden = bool(inputs) and abs(applied - signal) > 1e-6
        record = _Interval(time_s=t0, u_w=u_w, signal=applied if not inputs else signal)
        record.values = {
            "u_phys": u_phys, "heat_w": means[p.delivered_heat],
            "T_a": means[p.outdoor_temperature] - KELVIN, "G": means[p.irradiance],
            "signal_mean": means[p.actuator], "T_r_end": t_r_c,
        }
        self._log.append(record)
        self._row += 1
        result = StepResult(
            t_r_c=np.array([t_r_c]),
            t_m_c=np.array([math.nan]),
            u_phys_w=np.array([u_phys]),
            overridden=np.array([overridden]),
            t_r_sub_c=t_r_sub.reshape(1, -1),
        )
        gains = float(self._frame["I_g"].iloc[self._row - 1])
        return PlantStep.of_one_zone(
            result, np.array([record.values["T_a"]]), np.array([record.values["G"]]), np.array([gains])
        )

    # --- forecasts, KPIs, the record ---------------------------------------------------------
    def exogenous_frame(self) -> pd.DataFrame:
        """The run's inputs from BOPTEST's ``/forecast`` at the run's start, one row per
        interval (and ``lead_intervals`` more after the run, a controller's forecast at its
        last step) in the data format's names: ``time`` (interval start, dated in the points'
        year), ``T_a`` [C], ``G`` [W/m2], ``I_g`` [W] (the gains points summed), ``price``
        [EUR/kWh] (the run's price scenario), ``T_min``/``T_max`` [C]; interval means of
        samples at most 5 minutes apart (as BOPTEST's KPIs weigh them)."""
        return self._frame.copy()

    def _forecast_frame(self) -> pd.DataFrame:
        p, run = self.points, self.run
        per = max(1, int(math.ceil(run.dt_s / FORECAST_SAMPLE_S)))
        n = run.n_intervals + self.lead_intervals
        names = [p.forecast_outdoor_temperature, p.forecast_irradiance, *p.forecast_gains,
                 p.comfort_lower, p.comfort_upper, p.prices[run.price_scenario]]
        fc = self.test.forecast(names, horizon_s=n * run.dt_s, interval_s=run.dt_s / per)
        if len(fc["time"]) < n * per + 1:
            raise BoptestError(
                f"BOPTEST's forecast has {len(fc['time'])} samples, the run needs {n * per + 1}"
            )

        def means(values: np.ndarray) -> np.ndarray:
            v = values[: n * per + 1]
            blocks = np.lib.stride_tricks.sliding_window_view(v, per + 1)[::per]
            return (blocks[:, 1:-1].sum(axis=1) + 0.5 * (blocks[:, 0] + blocks[:, -1])) / per

        times = pd.Timestamp(year=p.year, month=1, day=1) + pd.to_timedelta(
            fc["time"][: n * per : per], unit="s"
        )
        gains = np.sum([means(fc[name]) for name in p.forecast_gains], axis=0)
        return pd.DataFrame({
            "time": times,
            "T_a": means(fc[p.forecast_outdoor_temperature]) - KELVIN,
            "G": means(fc[p.forecast_irradiance]),
            "I_g": gains,
            "price": means(fc[p.prices[run.price_scenario]]),
            "T_min": means(fc[p.comfort_lower]) - KELVIN,
            "T_max": means(fc[p.comfort_upper]) - KELVIN,
        })

    def kpis(self) -> dict[str, float | None]:
        """BOPTEST's own KPIs of the run so far (``GET /kpi``)."""
        return self.test.kpi()

    def history(self) -> pd.DataFrame:
        """The intervals stepped so far: ``time_s`` [s of the year], ``u`` [W] asked, ``signal``
        sent, ``u_phys`` [W] mean electrical, ``heat_w`` [W] mean heat delivered to the room,
        ``T_a`` [C], ``G`` [W/m2], ``signal_mean`` (the signal as applied), ``T_r_end`` [C]."""
        rows = [{"time_s": r.time_s, "u": r.u_w, "signal": r.signal, **r.values} for r in self._log]
        return pd.DataFrame(rows)


# --------------------------------------------------------------------------------------------
# Scenario files
# --------------------------------------------------------------------------------------------

_POINT_KEYS = {
    "room_temperature": _name, "consumed_power": _names, "delivered_heat": _name,
    "outdoor_temperature": _name, "irradiance": _name,
}
_FORECAST_KEYS = {
    "outdoor_temperature": _name, "irradiance": _name, "gains": _names,
    "comfort_lower": _name, "comfort_upper": _name,
}


def _table(data: Mapping[str, Any], key: str, where: str) -> Mapping[str, Any]:
    value = data.get(key)
    if not isinstance(value, Mapping):
        raise InputError(f"{where}: [{key}] is missing or not a table")
    return value


def _unknown(table: Mapping[str, Any], known: set[str], where: str) -> None:
    extra = sorted(set(table) - known)
    if extra:
        raise InputError(f"{where}: unknown key(s) {extra}; known: {sorted(known)}")


def boptest_settings_from_dict(data: Mapping[str, Any], *, where: str = "boptest") -> BoptestSettings:
    """A scenario file's ``[boptest]`` table (its sub-tables ``points``, ``actuator``,
    ``forecast``, ``prices``, ``test_periods``) as :class:`BoptestSettings`, checked key by key:
    an unknown or missing key is one clear error naming it."""
    top = {"testcase", "url", "timeout_s", "comfort_weight_eur_per_kh", "floor_area_m2", "year",
           "points", "actuator", "forecast", "prices", "test_periods"}
    _unknown(data, top, where)
    points = _table(data, "points", where)
    _unknown(points, set(_POINT_KEYS), f"{where}.points")
    forecast = _table(data, "forecast", where)
    _unknown(forecast, set(_FORECAST_KEYS), f"{where}.forecast")
    actuator = _table(data, "actuator", where)
    _unknown(actuator, {"signal", "activate", "curve_signal", "curve_power_w"}, f"{where}.actuator")
    for table, keys, name in ((points, _POINT_KEYS, "points"), (forecast, _FORECAST_KEYS, "forecast")):
        absent = [k for k in keys if k not in table]
        if absent:
            raise InputError(f"{where}.{name}: missing key(s) {absent}")
    for key in ("signal", "activate", "curve_signal", "curve_power_w"):
        if key not in actuator:
            raise InputError(f"{where}.actuator: missing key {key!r}")
    for key in ("testcase", "floor_area_m2"):
        if key not in data:
            raise InputError(f"{where}: missing key {key!r}")
    prices = _table(data, "prices", where)
    _unknown(prices, set(PRICE_SCENARIOS), f"{where}.prices")
    periods = _table(data, "test_periods", where)
    curve_s, curve_p = actuator["curve_signal"], actuator["curve_power_w"]
    if not (isinstance(curve_s, list) and isinstance(curve_p, list)):
        raise InputError(f"{where}.actuator: curve_signal and curve_power_w must be lists of numbers")
    year = data.get("year", 2018)
    if isinstance(year, bool) or not isinstance(year, int) or not 1900 <= year <= 2200:
        raise InputError(f"{where}.year must be a calendar year (e.g. 2018), got {year!r}")
    url = data.get("url")
    if url is not None and not isinstance(url, str):
        raise InputError(f"{where}.url must be a string such as \"http://127.0.0.1:8000\", got {url!r}")
    return BoptestSettings(
        points=BoptestPoints(
            testcase=_name(data["testcase"], f"{where}.testcase"),
            actuator=_name(actuator["signal"], f"{where}.actuator.signal"),
            activate=_name(actuator["activate"], f"{where}.actuator.activate"),
            scaling=SignalScaling(signal=tuple(curve_s), power_w=tuple(curve_p)),
            room_temperature=_name(points["room_temperature"], f"{where}.points.room_temperature"),
            consumed_power=_names(points["consumed_power"], f"{where}.points.consumed_power"),
            delivered_heat=_name(points["delivered_heat"], f"{where}.points.delivered_heat"),
            outdoor_temperature=_name(points["outdoor_temperature"], f"{where}.points.outdoor_temperature"),
            irradiance=_name(points["irradiance"], f"{where}.points.irradiance"),
            forecast_outdoor_temperature=_name(forecast["outdoor_temperature"], f"{where}.forecast.outdoor_temperature"),
            forecast_irradiance=_name(forecast["irradiance"], f"{where}.forecast.irradiance"),
            forecast_gains=_names(forecast["gains"], f"{where}.forecast.gains"),
            comfort_lower=_name(forecast["comfort_lower"], f"{where}.forecast.comfort_lower"),
            comfort_upper=_name(forecast["comfort_upper"], f"{where}.forecast.comfort_upper"),
            prices={k: _name(v, f"{where}.prices.{k}") for k, v in prices.items()},
            test_periods={k: _period_day(v, f"{where}.test_periods.{k}") for k, v in periods.items()},
            floor_area_m2=_number(data["floor_area_m2"], f"{where}.floor_area_m2"),
            year=year,
        ),
        url=url,
        timeout_s=_number(data.get("timeout_s", 120.0), f"{where}.timeout_s"),
        comfort_weight_eur_per_kh=_number(
            data.get("comfort_weight_eur_per_kh", DEFAULT_COMFORT_WEIGHT),
            f"{where}.comfort_weight_eur_per_kh",
        ),
    )


def read_boptest_file(path: str) -> BoptestSettings:
    """The ``[boptest]`` table of the TOML scenario file at ``path``."""
    import tomllib

    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the scenario file ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML ({exc})") from None
    return boptest_settings_from_dict(_table(data, "boptest", path), where=f"{path}: boptest")


#: The built-in BOPTEST scenarios: name -> the scenario file beside this module.
BUILTIN_BOPTEST = {
    "boptest_hydronic_heat_pump": Path(__file__).with_name("boptest_hydronic_heat_pump.toml"),
}


def boptest_file(name_or_path: str) -> Path | None:
    """The scenario file of a BOPTEST scenario: a built-in's (:data:`BUILTIN_BOPTEST`) or a
    TOML file with a ``[boptest]`` table; None for anything else."""
    import os
    import tomllib

    if name_or_path in BUILTIN_BOPTEST:
        return BUILTIN_BOPTEST[name_or_path]
    if not (name_or_path.lower().endswith(".toml") and os.path.isfile(name_or_path)):
        return None
    try:
        with open(name_or_path, "rb") as handle:
            table = tomllib.load(handle).get("boptest")
    except (OSError, tomllib.TOMLDecodeError):
        return None
    return Path(name_or_path) if isinstance(table, Mapping) else None


def boptest_description(settings: BoptestSettings) -> str:
    """One line on a BOPTEST scenario: its test case, test periods and price scenarios."""
    p = settings.points
    return (
        f"BOPTEST's test case {p.testcase} ({p.floor_area_m2:g} m2), run on a BOPTEST server "
        f"through its web API (BOPTEST's KPIs); test periods {', '.join(p.test_periods)} "
        f"({TEST_PERIOD_DAYS:g} days after a {WARMUP_DAYS:g}-day warm-up), price scenarios "
        f"{', '.join(PRICE_SCENARIOS)}; the actuator's electrical limit {p.scaling.max_power_w:g} W."
    )


def builtin_boptest(name: str) -> BoptestSettings:
    """The settings of a built-in BOPTEST scenario by name (:data:`BUILTIN_BOPTEST`)."""
    if name not in BUILTIN_BOPTEST:
        raise ValueError(
            f"no built-in BOPTEST scenario {name!r}; built-in: {', '.join(BUILTIN_BOPTEST)}"
        )
    return read_boptest_file(str(BUILTIN_BOPTEST[name]))


#: The demand of a data policy: (interval k, measured room temperature [C], the interval's
#: row of the run's inputs) -> electrical power [W].
Demand = Callable[[int, float, pd.Series], float]


def record_data(
    settings: BoptestSettings, run: BoptestRun, demand: Demand, *,
    intervals: Callable[[int], Iterable[int]] = range,
) -> pd.DataFrame:
    """Training data from the emulator: ``run`` (a period of its own, ``first_day``, disjoint
    from every test period and its warm-up, else refused) under ``demand``, in the data
    format: one row per interval, ``time`` (start), ``T_r`` [C] at the start, ``u`` [W] asked,
    ``u_phys`` [W] mean electrical, ``T_a`` [C] and ``G`` [W/m2] as the emulator had them,
    ``I_g`` [W], ``price`` [EUR/kWh], ``T_min``/``T_max`` [C]; ``heat_w`` [W], the heat
    delivered to the room, beside them. ``intervals(n)`` gives the n intervals' indices in
    order (``range``, or a progress reporter's). The test is stopped on the server whatever
    happens."""
    if run.first_day is None:
        raise ValueError(
            "training data runs on days of its own (BoptestRun.first_day), never on a test period"
        )
    with BoptestPlant(settings, run) as plant:
        frame = plant.exogenous_frame()
        n = run.n_intervals
        t_r, u, u_phys, t_a, g = (np.empty(n) for _ in range(5))
        for k in intervals(n):
            t_r[k] = float(plant.measure()[0, 0])
            u[k] = float(demand(k, t_r[k], frame.iloc[k]))
            step = plant.step(u[k], k)
            u_phys[k], t_a[k], g[k] = step.u_phys_w[0], step.t_a_c[0], step.g_w_per_m2[0]
        heat = plant.history()["heat_w"].to_numpy()
    data = pd.DataFrame({
        "time": frame["time"], "T_r": t_r, "u": u, "u_phys": u_phys, "T_a": t_a, "G": g,
        "I_g": frame["I_g"], "price": frame["price"], "T_min": frame["T_min"],
        "T_max": frame["T_max"], "heat_w": heat,
    })
    data.attrs["dt_s"] = float(run.dt_s)
    return data
