"""The time-series format: one row per control interval (see DESIGN.md).

Columns: ``time`` (start of the interval, ISO 8601 or numeric seconds), ``T_r`` [C] at the
start of the interval, optional ``T_m`` [C] (simulated data only), ``u`` [W] demanded during
the interval, ``u_phys`` [W] mean delivered during the interval, ``T_a`` [C]; optional
``G`` [W/m2], the irradiance on the site's vertical facades ``G_south``, ``G_east``,
``G_west``, ``G_north`` [W/m2] (:mod:`pinn_mpc.solar`), ``I_g`` [W], ``price`` [EUR/kWh],
``T_min``/``T_max`` [C] comfort band, ``wind`` [m/s] the wind speed at the weather station
(an EnergyPlus building's weather file: it drives the reference buildings' infiltration),
``holiday`` (1 on the days the building runs its
Sunday-or-holiday schedules, else 0; an EnergyPlus building's ``RunPeriodControl:SpecialDays``),
``cop`` [-] heat delivered per electrical watt of ``u_phys`` (a heat pump's COP; absent or 1 for a
resistance heater; :func:`pinn_mpc.identify.identify_rc` then fits on ``cop`` x ``u_phys``).

A building of several zones has the zone series (``T_r``, ``T_m``, ``T_min``, ``T_max``) once
per zone, as ``T_r[<zone>]`` (:mod:`pinn_mpc.zones`); its comfort band may also be one
``T_min``/``T_max`` for every zone. A file whose only zone columns name one zone is read as a
one-zone file (``T_r[x]`` read as ``T_r``). Readers take one zone unless asked for zones
(``zones=True``): the models and controllers are one zone's today.

:func:`read_timeseries` validates a file and returns a DataFrame whose ``time`` column is
``datetime64[ns]`` (numeric seconds are taken as seconds since 1970-01-01) with a uniform
step, stored in ``df.attrs["dt_s"]``. Every problem raises :class:`InputError` naming the
file, column, row and fix.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from pinn_mpc.errors import InputError, setting, warn
from pinn_mpc.io import atomic_write, atomic_write_json, file_sha256, staged
from pinn_mpc.physics import DT_RANGE_S, GAIN_BLOCK_H, MAX_POWER_W, RCParams
from pinn_mpc.solar import FACADE_COLUMNS
from pinn_mpc.zones import ZONE_SERIES, ZoneSpec, parse_zone_column, zone_columns, zones_in

__all__ = [
    "COLUMNS",
    "KELVIN_MEDIAN_RANGE",
    "KW_SUSPECT_W",
    "NUMERIC",
    "OPTIONAL",
    "POWER",
    "REQUIRED",
    "SITE_COLUMNS",
    "TEMPERATURES",
    "TEMPERATURE_RANGE_C",
    "TYPICAL_MAX_C",
    "WIND",
    "WIND_RANGE_M_S",
    "check_celsius",
    "check_clock_change",
    "day_of_week",
    "fleet_params_path",
    "frame_scheduled_gains_w",
    "parse_column_map",
    "parse_times",
    "read_fleet_params",
    "read_timeseries",
    "schedule_index",
    "schedule_one_hot",
    "validate_timeseries",
    "write_fleet_params",
    "write_timeseries",
    "zone_values",
]

#: The wind speed column [m/s] (a weather station's, at its 10 m mast).
WIND = "wind"
#: What a site's weather file adds to a run's inputs beyond ``T_a`` and ``G``: the facades'
#: irradiance and the wind speed (an EnergyPlus scenario's data, trajectories and forecasts).
SITE_COLUMNS = (*FACADE_COLUMNS, WIND)
REQUIRED = ("time", "T_r", "u", "u_phys", "T_a")
OPTIONAL = ("T_m", "G", *FACADE_COLUMNS, "I_g", "price", "T_min", "T_max", WIND, "holiday", "cop")
COLUMNS = (
    "time", "T_r", "T_m", "u", "u_phys", "T_a", "G", *FACADE_COLUMNS, "I_g", "price", "T_min",
    "T_max", WIND, "holiday", "cop",
)
#: Plausible wind speeds [m/s] (``wind`` column): calm to the strongest gusts weather files hold.
WIND_RANGE_M_S = (0.0, 60.0)
#: Plausible heat per electrical watt (``cop`` column): a resistance heater 1, heat pumps 2-6.
COP_RANGE = (0.5, 10.0)
NUMERIC = tuple(c for c in COLUMNS if c != "time")
#: Physically plausible range of each temperature column [C], to catch unit mix-ups (K, F).
TEMPERATURE_RANGE_C = (-60.0, 90.0)
#: Power columns: the actuator's input [W], >= 0 for heating and cooling alike (eta has the sign).
POWER = ("u", "u_phys")
#: The temperature columns [C]: the room's (``T_r``, ``T_m``, the comfort band) and the outdoor air.
TEMPERATURES = ("T_r", "T_m", "T_a", "T_min", "T_max")
#: The highest typical level (median) [C] of a temperature column: no room in use sits at 45 C,
#: nor does any climate's outdoor air over weeks (the hottest month on record averages under
#: 40 C), while a room at 68-75 F or a summer at 75-95 F does: a median above it is Fahrenheit.
TYPICAL_MAX_C = 45.0
#: Medians that are a temperature in kelvin (-93 .. 127 C), far above any in Celsius or Fahrenheit.
KELVIN_MEDIAN_RANGE = (180.0, 400.0)
#: A power column peaking below this [W] while the room moves by degrees is likely in kW (a
#: 5 kW heater reads 5); a test cell's or a small cold-storage cell's heater may be as small,
#: so it is a warning, not a refusal.
KW_SUSPECT_W = 50.0


#: An actuator's power column in a file of several actuators (:func:`pinn_mpc.actuator.actuator_columns`).
_ACTUATOR_COLUMN = re.compile(r"(u|u_phys)\[[A-Za-z0-9_.\-]+\]")

def day_of_week(times: np.ndarray, holiday: np.ndarray | None = None) -> np.ndarray:
    """(N,) the day of the week (0 = Monday) of each time (datetime64), as floats; 6 (Sunday)
    where ``holiday`` is 1: a building runs its Sunday-or-holiday schedules on its holidays."""
    dow = ((np.asarray(times, dtype="datetime64[D]").astype(np.int64) + 3) % 7).astype(float)  # 1970-01-01: Thursday
    if holiday is not None:
        dow[np.asarray(holiday, dtype=float) > 0] = 6.0
    return dow


def schedule_index(
    time_of_day_h: np.ndarray, day_of_week: np.ndarray, day_types: int = 2, block_h: float = 2.0
) -> np.ndarray:
    """(N,) each interval's schedule coefficient: its block of ``block_h`` hours of the day, the
    weekend's after the workdays' (day_of_week 0 = Monday, 6 = Sunday or a holiday); with 3
    ``day_types`` Saturday's, then Sunday's (the physics-informed ARX's schedule, and the RC's
    unmeasured gains)."""
    block = (np.asarray(time_of_day_h, dtype=float) // block_h).astype(int)
    dow = np.asarray(day_of_week)
    day = (dow >= 5).astype(int) if day_types == 2 else np.clip(dow - 4, 0, 2).astype(int)
    return block + int(round(24 / block_h)) * day


def schedule_one_hot(df: pd.DataFrame, day_types: int = 2, block_h: float = 2.0) -> np.ndarray:
    """(N, day_types * blocks per day) one-hot of each row's schedule coefficient
    (:func:`schedule_index`) in a frame in the data format (its ``holiday`` column, if any, run
    as Sundays)."""
    t = pd.to_datetime(df["time"])
    index = schedule_index(
        (t.dt.hour + t.dt.minute / 60.0).to_numpy(),
        day_of_week(t.to_numpy(), df["holiday"].to_numpy() if "holiday" in df else None),
        day_types, block_h,
    )
    out = np.zeros((len(t), day_types * int(round(24 / block_h))))
    out[np.arange(len(t)), index] = 1.0
    return out


def frame_scheduled_gains_w(df: pd.DataFrame, schedule_w: Sequence[float]) -> np.ndarray:
    """(N,) the internal gains [W] of each row of a frame in the data format: its ``I_g`` (0
    without one) plus the unmeasured gains of ``schedule_w`` in the row's block
    (:attr:`pinn_mpc.physics.RCParams.unmeasured_gains_w`'s layout; empty: none)."""
    measured = df["I_g"].to_numpy(float) if "I_g" in df.columns else np.zeros(len(df))
    if not schedule_w:
        return measured
    return measured + schedule_one_hot(df, 2, GAIN_BLOCK_H) @ np.asarray(schedule_w, dtype=float)


def parse_column_map(text: str | None) -> dict[str, str]:
    """``"T_r=T_int,u_phys=P_hea"`` -> ``{"T_r": "T_int", "u_phys": "P_hea"}`` (ours = theirs)."""
    if not text:
        return {}
    mapping: dict[str, str] = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        ours, sep, theirs = item.partition("=")
        ours, theirs = ours.strip(), theirs.strip()
        if not sep or not ours or not theirs:
            raise InputError(
                f"{setting('columns')} item {item!r} is not NAME=COLUMN; e.g. {setting('columns')} "
                "T_r=T_int,u_phys=P_hea"
            )
        if ours not in COLUMNS and parse_zone_column(ours) is None:
            raise InputError(
                f"{setting('columns')} names unknown column {ours!r}; known: {', '.join(COLUMNS)}, "
                "and a zone's T_r[<zone>], T_m[<zone>], T_min[<zone>], T_max[<zone>]"
            )
        mapping[ours] = theirs
    return mapping


def parse_times(values: pd.Series, source: str) -> pd.Series:
    """A ``time`` column as naive datetime64[ns]: ISO 8601 text (``Z`` and UTC offsets, also
    offsets that change at a daylight-saving switch, are read as instants and given in UTC;
    times without an offset are kept as they are) or numeric seconds since 1970-01-01 UTC.
    A value that is neither is an InputError naming ``source`` and the row."""
    if pd.api.types.is_datetime64_any_dtype(values):
        parsed = pd.to_datetime(values, utc=True)
    else:
        numeric = pd.to_numeric(values, errors="coerce")
        if numeric.notna().all():
            seconds = numeric.to_numpy(dtype=float)
            if not np.all(np.abs(seconds) < 1e11):
                raise InputError(f"{source}: column 'time' has numeric values beyond 1e11 s")
            return pd.Series(pd.to_datetime(seconds, unit="s")).astype("datetime64[ns]")
        parsed = pd.to_datetime(values, errors="coerce", format="ISO8601", utc=True)
    bad = parsed.isna()
    if bad.any():
        row = int(np.flatnonzero(bad.to_numpy())[0])
        raise InputError(
            f"{source}: column 'time' row {row + 1} has {values.iloc[row]!r}, "
            "neither ISO 8601 nor numeric seconds"
        )
    return pd.Series(parsed.dt.tz_convert("UTC").dt.tz_localize(None)).astype("datetime64[ns]")


def _check_range(
    out: pd.DataFrame, col: str, bounds: tuple[float, float], source: str, unit: str, hint: str
) -> None:
    """InputError naming the first row of ``col`` (where the frame has it) outside ``bounds``
    (``unit`` after them, then ``hint``)."""
    if col not in out.columns:
        return
    lo, hi = bounds
    outside = (out[col] < lo) | (out[col] > hi)
    if outside.any():
        row = int(np.flatnonzero(outside.to_numpy())[0])
        raise InputError(
            f"{source}: column {col!r} row {row + 1} is {out[col].iloc[row]:g}, outside the "
            f"plausible {lo:g} .. {hi:g}{unit}{hint}"
        )


def _check_power(out: pd.DataFrame, source: str, u_max_w: float | None) -> None:
    """Power columns (each actuator's ``u[<name>]`` too) within 0 .. min(MAX_POWER_W,
    u_max_w) [W], or InputError naming the row."""
    powers = [*POWER, *(c for c in out.columns if _ACTUATOR_COLUMN.fullmatch(str(c)))]
    for col in (c for c in powers if c in out.columns):
        values = out[col].to_numpy(dtype=float)
        negative = np.flatnonzero(values < 0)
        if negative.size:
            row = int(negative[0])
            raise InputError(
                f"{source}: column {col!r} row {row + 1} is {values[row]:g} W, negative; power is "
                f"the actuator's input, >= 0 for cooling too (mark cooling with {setting('eta')} -COP); "
                "clip meter noise below 0 to 0"
            )
        cap = MAX_POWER_W
        why = f"the plausible range is 0 .. {cap:g} W (10 MW: a very large building)"
        if u_max_w is not None and u_max_w < cap:
            cap, why = u_max_w, f"the actuator delivers at most {u_max_w:g} W"
        # The data format writes 6 decimals, so allow that much rounding above the cap.
        above = np.flatnonzero(values > cap + 1e-6)
        if above.size:
            row = int(above[0])
            raise InputError(
                f"{source}: column {col!r} row {row + 1} is {values[row]:g} W, but {why}; "
                "is the column in W (not mW), and power rather than energy per interval?"
            )


def check_celsius(medians: Mapping[str, float], source: str) -> None:
    """InputError for temperature columns (name -> typical level, the median) in kelvin
    (:data:`KELVIN_MEDIAN_RANGE`) or Fahrenheit (above :data:`TYPICAL_MAX_C`). The columns are
    judged together: a room at 70 beside outdoor air at 40 is a file in Fahrenheit, and so is a
    cold room at 35 beside a summer at 80, so the fix names them all."""
    convert = ", ".join(medians)
    lo_k, hi_k = KELVIN_MEDIAN_RANGE
    for col, median in medians.items():
        if lo_k <= median <= hi_k:
            raise InputError(
                f"{source}: column {col!r} has a median of {median:.1f}, a temperature in kelvin "
                f"({median - 273.15:.1f} C); convert the temperature columns ({convert}) to "
                "Celsius: C = K - 273.15"
            )
    for col, median in medians.items():
        if TYPICAL_MAX_C < median < lo_k:
            raise InputError(
                f"{source}: column {col!r} has a median of {median:.1f}, above the "
                f"{TYPICAL_MAX_C:g} C no room in use or outdoor climate sits at: it looks like "
                f"Fahrenheit ({median:.1f} F is {(median - 32) / 1.8:.1f} C); convert the "
                f"temperature columns ({convert}) to Celsius: C = (F - 32) / 1.8"
            )


#: The mark of a frame :func:`validate_timeseries` returned: its power's unit was judged.
_UNITS_WARNED = "power_unit_checked"


def _warn_power_units(out: pd.DataFrame, source: str, t_r: str = "T_r") -> None:
    """Warn where the power peaks above 0 but below :data:`KW_SUSPECT_W` while the room's
    temperature (column ``t_r``, the first zone's) moves by degrees (5-95 % spread at least
    1 K): kW for W?"""
    col = "u_phys" if "u_phys" in out.columns else "u"
    if col not in out.columns or t_r not in out.columns:
        return
    peak = float(out[col].max())
    lo, hi = np.percentile(out[t_r].to_numpy(dtype=float), [5.0, 95.0])
    if 0 < peak < KW_SUSPECT_W and hi - lo >= 1.0:
        warn(
            f"{source}: column {col!r} peaks at {peak:.3g} W while T_r moves over "
            f"{hi - lo:.1f} K: a heater under {KW_SUSPECT_W:g} W, or power in kW? Models and "
            "controllers take watts: if it is in kW, convert it to W (x 1000)"
        )


_DECIMAL_COMMA = re.compile(r"[-+]?\d+,\d+")


#: Text that ends in a UTC offset or ``Z``: an instant, which no clock change moves.
_UTC_OFFSET = re.compile(r"(Z|[+-]\d\d:?\d\d)$")


def check_clock_change(times: pd.Series, raw: pd.Series, steps: np.ndarray, source: str) -> None:
    """InputError at the first step of ``times`` (``steps`` [s] between them; ``raw`` the column
    as given) that jumps an hour ahead of or back from the usual step (the median) between
    23:00 and 04:00 in times without a UTC offset, as local clock time does where daylight
    saving starts or ends: named with the fix, times in UTC or with their offset. Sorting (the
    fix for a row that goes back) or filling the gap (for skipped rows) would put data an hour
    out of place."""
    if steps.size < 2 or pd.api.types.is_numeric_dtype(raw) or isinstance(raw.dtype, pd.DatetimeTZDtype):
        return
    dt_s = float(np.median(steps))
    ahead, back = np.abs(steps - (dt_s + 3600.0)) < 1e-6, np.abs(steps - (dt_s - 3600.0)) < 1e-6
    for index in np.flatnonzero(ahead | back):
        row = int(index) + 1
        before, now = str(raw.iloc[row - 1]).strip(), str(raw.iloc[row]).strip()
        if _UTC_OFFSET.search(before) or _UTC_OFFSET.search(now) or times.iloc[row - 1].hour not in (23, 0, 1, 2, 3):
            continue
        what, starts, otherwise = (
            ("ahead", "starts", "; if rows are missing there instead, fill the gap with rows")
            if ahead[index] else ("back", "ends", "")
        )
        raise InputError(
            f"{source}: column 'time' jumps an hour {what} at row {row + 1} ({before} then "
            f"{now}), as local clock time does where daylight saving {starts}; give the "
            "times in UTC or with their UTC offset (e.g. pandas: df['time'] = "
            "pd.to_datetime(df['time']).dt.tz_localize('<your time zone>', "
            f"ambiguous='infer').dt.tz_convert('UTC')){otherwise}"
        )


def _check_steps(times: pd.Series, raw: pd.Series, source: str) -> float:
    """The uniform step [s] of a parsed time column, or InputError: a row that goes backwards or
    repeats a time, a step outside :data:`DT_RANGE_S`, a step that is not uniform."""
    ns = times.to_numpy().astype("datetime64[ns]").astype(np.int64)
    steps = np.diff(ns).astype(float) / 1e9
    check_clock_change(times, raw, steps, source)
    not_forward = np.flatnonzero(steps <= 0)
    if not_forward.size:
        row = int(not_forward[0]) + 1  # 0-based index of the offending row
        before, now = raw.iloc[row - 1], raw.iloc[row]
        if steps[row - 1] == 0:
            raise InputError(
                f"{source}: column 'time' has a duplicate timestamp at row {row + 1} ({now!s}, "
                f"as in row {row}); drop the duplicate rows"
            )
        raise InputError(
            f"{source}: column 'time' goes backwards at row {row + 1} ({before!s} then {now!s}); "
            "sort the rows by time"
        )
    dt_s = float(np.median(steps))
    lo, hi = DT_RANGE_S
    if not lo <= dt_s <= hi:
        raise InputError(
            f"{source}: time step is {dt_s:g} s, outside the plausible {lo:g} .. {hi:g} s "
            "(1 min .. 6 h); numeric times are read as seconds (a row index 0, 1, 2 ... is 1 s "
            "apart): give seconds (0, 1800, 3600 ...) or ISO 8601 times (2021-01-01T00:30:00)"
        )
    irregular = np.flatnonzero(np.abs(steps - dt_s) > 1e-6)
    if irregular.size:
        row = int(irregular[0]) + 1
        gap = steps[row - 1]
        if gap > dt_s and abs(gap / dt_s - round(gap / dt_s)) < 1e-6:
            raise InputError(
                f"{source}: column 'time' skips {round(gap / dt_s) - 1:d} interval(s) of "
                f"{dt_s:g} s before row {row + 1} ({raw.iloc[row - 1]!s} then {raw.iloc[row]!s}); "
                "fill the gap with rows (e.g. pandas: df.set_index('time').resample("
                f"'{dt_s:g}s').interpolate().reset_index()) or keep the rows on one side of it"
            )
        raise InputError(
            f"{source}: time step is not uniform at row {row + 1} "
            f"({gap:g} s against {dt_s:g} s); put the rows on a uniform grid (e.g. pandas: "
            f"df.set_index('time').resample('{dt_s:g}s').mean().interpolate().reset_index())"
        )
    return dt_s


def _zone_layout(df: pd.DataFrame, source: str, zones: bool) -> tuple[pd.DataFrame, tuple[ZoneSpec, ...]]:
    """``df`` with its zone columns checked, and its zones (:func:`pinn_mpc.zones.zones_in`);
    a file whose zone columns name one zone gets the one-zone names. InputError for zone
    columns without a room temperature, a series given both ways, a series given for some
    zones only, or several zones where the reader takes one (``zones`` False)."""
    found = zones_in(df.columns)
    zoned = {c: parsed for c in map(str, df.columns) if (parsed := parse_zone_column(c))}
    if not zoned:
        return df, found
    names = [zone.name for zone in found]
    orphans = sorted({name for _, name in zoned.values()} - set(names))
    if not any(series == "T_r" for series, _ in zoned.values()) or orphans:
        raise InputError(
            f"{source}: zone columns name zone(s) {', '.join(orphans or sorted({n for _, n in zoned.values()}))} "
            "without a room temperature T_r[<zone>]; give every zone its T_r[<zone>] column"
        )
    for series in ZONE_SERIES:
        given = [c for c, (s, _) in zoned.items() if s == series]
        if given and series in df.columns:
            raise InputError(
                f"{source}: has both {series!r} and {', '.join(given)}; give {series} once per "
                f"zone ({series}[<zone>]) or, for the comfort band, once for every zone"
            )
        if given and len(given) != len(names):
            lacking = [n for n in names if f"{series}[{n}]" not in given]
            raise InputError(
                f"{source}: {series} is given for some zones but not for {', '.join(lacking)}; "
                f"give {series}[<zone>] for every zone"
            )
    if len(names) == 1:  # one zone, named: the one-zone file
        return df.rename(columns={c: s for c, (s, _) in zoned.items()}), found
    if not zones:
        raise InputError(
            f"{source}: holds {len(names)} zones ({', '.join(names)}); this takes one zone "
            "(train and identify take several, given the building's layout in its scenario): keep one "
            "zone's columns, named T_r, T_min, T_max (e.g. pandas: df.rename(columns={'T_r["
            + names[0] + "]': 'T_r'}))"
        )
    return df, found


def _in_format_order(columns: list[str]) -> list[str]:
    """``columns`` in the data format's order, a zone series' columns at that series' place
    (in their own order), then the others as they come."""

    def base(column: str) -> str:
        parsed = parse_zone_column(column)
        return column if parsed is None else parsed[0]

    known = [c for name in COLUMNS for c in columns if base(c) == name]
    return known + [c for c in columns if c not in known]


def validate_timeseries(
    df: pd.DataFrame,
    *,
    source: str = "data",
    require: tuple[str, ...] = REQUIRED,
    u_max_w: float | None = None,
    zones: bool = False,
) -> pd.DataFrame:
    """Check and normalise a DataFrame in the format; returns a new frame with ``attrs['dt_s']``.

    Besides format and finiteness: temperatures in Celsius (a median in kelvin or Fahrenheit is
    refused, :func:`check_celsius`) and within :data:`TEMPERATURE_RANGE_C`, power columns
    within 0 .. :data:`~pinn_mpc.physics.MAX_POWER_W` (and ``u_max_w``, the actuator's limit,
    when known; a warning where they look like kW, :data:`KW_SUSPECT_W`), time strictly
    increasing at a uniform step within :data:`~pinn_mpc.physics.DT_RANGE_S`. The zone
    columns (module docstring) are checked as their series; a frame of several zones is
    refused unless ``zones``.
    """
    df, building_zones = _zone_layout(df, source, zones)
    per_zone = {s: zone_columns(s, building_zones) for s in ZONE_SERIES}
    # Each zone series' columns in the frame: once per zone, or once for every zone.
    present = {
        s: [c for c in cols if c in df.columns] or [c for c in (s,) if c in df.columns]
        for s, cols in per_zone.items()
    }
    missing = [c for c in require if c not in df.columns and not present.get(c)]
    if "u" in missing and "u_phys" in df.columns:
        missing.remove("u")  # one power column: u = u_phys
    if missing:
        raise InputError(
            f"{source}: missing column(s) {', '.join(missing)}; have {', '.join(map(str, df.columns))}"
            f" (map yours with {setting('columns')}, e.g. {setting('columns')} T_r=T_int,u_phys=P_hea,T_a=T_ext)"
        )
    if len(df) < 2:
        raise InputError(f"{source}: needs at least 2 rows, has {len(df)}")
    if "building" in df.columns and df["building"].nunique() > 1:
        raise InputError(
            f"{source}: holds {df['building'].nunique()} buildings (column 'building', as "
            "`pinn-mpc simulate` writes a fleet's); keep the rows of one building, e.g. with pandas: "
            "df[df.building == 0]"
        )
    raw_time = df["time"].reset_index(drop=True)
    out = pd.DataFrame({"time": parse_times(raw_time, source)})
    # A reader of several zones keeps each actuator's power, u[<name>] and u_phys[<name>].
    actuators = [str(c) for c in df.columns if zones and _ACTUATOR_COLUMN.fullmatch(str(c))]
    ordered = _in_format_order([c for name in COLUMNS for c in present.get(name, [name])] + actuators)
    for col in (c for c in ordered if c != "time" and c in df.columns):
        values = pd.to_numeric(df[col].reset_index(drop=True), errors="coerce")
        bad = ~np.isfinite(values.to_numpy(dtype=float))
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            text = str(df[col].iloc[row]).strip()
            if _DECIMAL_COMMA.fullmatch(text):
                raise InputError(
                    f"{source}: column {col!r} row {row + 1} has {text!r}, a decimal comma; write "
                    "decimal points, or separate the columns with ';' (such a file is read with "
                    "decimal commas)"
                )
            raise InputError(
                f"{source}: column {col!r} row {row + 1} has {text!r}, not a finite number; fill "
                "such rows (e.g. pandas: df.interpolate()); a dropped row leaves a gap in time, "
                "which is refused as well"
            )
        out[col] = values.astype(float)
    if "u" not in out.columns:
        out["u"] = out["u_phys"]
    temperatures = [c for name in TEMPERATURES for c in present.get(name, [name]) if c in out.columns]
    check_celsius({c: float(out[c].median()) for c in temperatures}, source)
    for col in temperatures:
        _check_range(out, col, TEMPERATURE_RANGE_C, source, " C", "; is it in kelvin or Fahrenheit?")
    _check_power(out, source, u_max_w)
    if not df.attrs.get(_UNITS_WARNED):  # a frame this returned (or a part of it) warned once
        _warn_power_units(out, source, per_zone["T_r"][0])
    _check_range(out, "cop", COP_RANGE, source, "", " (heat delivered per electrical watt)")
    _check_range(out, WIND, WIND_RANGE_M_S, source, " m/s", "; is it in km/h or knots?")
    if "holiday" in out.columns and not out["holiday"].isin((0.0, 1.0)).all():
        row = int(np.flatnonzero(~out["holiday"].isin((0.0, 1.0)).to_numpy())[0])
        raise InputError(
            f"{source}: column 'holiday' row {row + 1} is {out['holiday'].iloc[row]:g}; it must "
            "be 1 on the building's holidays and 0 on other days"
        )
    dt_s = _check_steps(out["time"], raw_time, source)
    out = out[[c for c in ordered if c in out.columns]]
    out.attrs["dt_s"] = dt_s
    out.attrs[_UNITS_WARNED] = True
    return out


def _read_csv(path: str | os.PathLike[str]) -> pd.DataFrame:
    """The CSV at ``path`` as it is, or one line that says why not."""
    source = str(path)
    if not Path(path).is_file():
        raise InputError(f"{source}: no such file; check {setting('data', python='the path')}")
    try:
        raw = pd.read_csv(path)
        if len(raw.columns) == 1 and ";" in str(raw.columns[0]):
            # A spreadsheet's export in a decimal-comma locale: ';' between columns.
            raw = pd.read_csv(path, sep=";", decimal=",")
        return raw
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{source}: not a readable CSV ({first})") from exc
    except MemoryError:
        raise InputError(f"{source}: too large to read into this machine's memory") from None


def read_timeseries(
    path: str | os.PathLike[str],
    *,
    columns: Mapping[str, str] | str | None = None,
    require: tuple[str, ...] = REQUIRED,
    zones: bool = False,
) -> pd.DataFrame:
    """Read and validate a CSV in the format; ``columns`` maps our names to the file's; a
    file of several zones is refused unless ``zones`` (:func:`validate_timeseries`)."""
    source = str(path)
    mapping = (
        parse_column_map(columns) if isinstance(columns, str) or columns is None else dict(columns)
    )
    raw = _read_csv(path)
    absent = [theirs for theirs in mapping.values() if theirs not in raw.columns]
    if absent:
        raise InputError(
            f"{source}: {setting('columns')} refers to {', '.join(absent)}, not in the file; "
            f"have {', '.join(map(str, raw.columns))}"
        )
    renamed = raw.rename(columns={theirs: ours for ours, theirs in mapping.items()})
    return validate_timeseries(renamed, source=source, require=require, zones=zones)


def read_fleet_timeseries(
    path: str | os.PathLike[str], *, columns: Mapping[str, str] | str | None = None
) -> dict[int, pd.DataFrame]:
    """Read a fleet data set (``simulate --buildings N``: a ``building`` column of whole
    numbers) and validate each building's rows as :func:`read_timeseries` validates a file;
    returns the frames by building."""
    source = str(path)
    raw = _read_csv(path)
    if "building" not in raw.columns:
        raise InputError(
            f"{source}: no 'building' column; a fleet data set has one (`pinn-mpc simulate` "
            f"writes it for several buildings), or train one model without {setting('per_building')}"
        )
    ids = pd.to_numeric(raw["building"], errors="coerce")
    if ids.isna().any() or not np.all(ids == np.round(ids)) or (ids < 0).any():
        row = int(np.flatnonzero(ids.isna() | (ids != np.round(ids)) | (ids < 0))[0]) + 2
        raise InputError(f"{source}: row {row}: 'building' must be a whole number >= 0")
    mapping = (
        parse_column_map(columns) if isinstance(columns, str) or columns is None else dict(columns)
    )
    renamed = raw.rename(columns={theirs: ours for ours, theirs in mapping.items()})
    frames = {}
    for b in sorted(int(v) for v in ids.unique()):
        part = renamed[ids.to_numpy() == b].drop(columns="building")
        frames[b] = validate_timeseries(part.reset_index(drop=True), source=f"{source} building {b}")
    return frames


def write_timeseries(df: pd.DataFrame, path: str | os.PathLike[str]) -> Path:
    """Write atomically: ``time`` as ISO 8601, numbers with fixed precision (byte-stable)."""
    out = df.copy()
    if pd.api.types.is_datetime64_any_dtype(out["time"]):
        out["time"] = out["time"].dt.strftime("%Y-%m-%dT%H:%M:%S")
    out = out[_in_format_order(list(out.columns))]
    return atomic_write(path, lambda tmp: out.to_csv(tmp, index=False, float_format="%.6f"))


def fleet_params_path(data: str | os.PathLike[str]) -> Path:
    """The file next to a fleet data set with its buildings' parameters (``simulate
    --spread``): ``fleet.csv`` -> ``fleet.fleet.json``."""
    return Path(data).with_suffix(".fleet.json")


def write_fleet_params(data: str | os.PathLike[str], params: Sequence[RCParams], *, spread: float) -> Path:
    """Write the buildings' parameters of the fleet data set ``data`` (already written, or
    staged in the same :func:`~pinn_mpc.io.written_together` block: the file records its
    hash) next to it, atomically; the path written."""
    path = fleet_params_path(data)
    atomic_write_json(path, {"spread": spread, "params": [p.to_dict() for p in params],
                             "data_sha256": file_sha256(staged(data))})
    return path


def read_fleet_params(data: str | os.PathLike[str], n_buildings: int) -> list[RCParams] | None:
    """The buildings' parameters stored next to the fleet data set ``data`` (one per building,
    ``n_buildings`` of them), or None without such a file. A file that is not one, that
    describes another ``data`` (its hash differs) or another number of buildings is refused."""
    sidecar = fleet_params_path(data)
    if not sidecar.is_file():
        return None
    try:
        stored = json.loads(sidecar.read_text())
        params = [RCParams(**p) for p in stored["params"]]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{sidecar}: not a fleet parameter file ({exc})") from None
    if stored.get("data_sha256") not in (None, file_sha256(data)):
        raise InputError(
            f"{sidecar} describes the buildings of another {data} (the data changed since "
            f"`pinn-mpc simulate` wrote both); simulate the fleet again, or remove {sidecar} "
            "to train without the buildings' parameters"
        )
    if len(params) != n_buildings:
        raise InputError(
            f"{sidecar} holds {len(params)} buildings' parameters, {data} {n_buildings} "
            f"buildings; simulate the fleet again, or remove {sidecar}"
        )
    return params


def zone_values(frame: pd.DataFrame, series: str) -> np.ndarray:
    """(T, Z) the zone series ``series`` (``T_r``, ``T_m``, ``T_min``, ``T_max``) of every zone
    of a validated frame, in its zones' order (a one-zone frame: Z = 1); a comfort band given
    once for every zone is each zone's."""
    zones = zones_in(frame.columns)
    columns = [c if c in frame.columns else series for c in zone_columns(series, zones)]
    return frame[columns].to_numpy(dtype=float)
