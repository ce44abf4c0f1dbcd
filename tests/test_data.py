"""The time-series format: writer, validating reader, column mapping."""

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.data import parse_column_map, read_timeseries, validate_timeseries, write_timeseries
from pinn_mpc.errors import InputError


def frame(n=6):
    t = pd.date_range("2024-01-01", periods=n, freq="30min")
    return pd.DataFrame(
        {
            "time": t,
            "T_r": np.linspace(18, 19, n),
            "T_m": np.linspace(17, 18, n),
            "u": np.tile([0.0, 5000.0], n // 2),
            "u_phys": np.tile([0.0, 4500.0], n // 2),
            "T_a": np.linspace(5, 6, n),
        }
    )


def test_round_trip_and_step(tmp_path):
    path = write_timeseries(frame(), tmp_path / "d.csv")
    back = read_timeseries(path)
    assert list(back.columns) == ["time", "T_r", "T_m", "u", "u_phys", "T_a"]
    assert back.attrs["dt_s"] == 1800.0
    np.testing.assert_allclose(back["u_phys"], frame()["u_phys"])
    assert not list(tmp_path.glob("*.tmp"))


def test_column_mapping_and_single_power_column(tmp_path):
    raw = pd.DataFrame(
        {
            "Time": np.arange(4) * 1800.0,
            "T_int": [20, 20.5, 21, 21.2],
            "P_hea": [0, 1000, 0, 0],
            "T_ext": [5, 5, 6, 6],
        }
    )
    raw.to_csv(tmp_path / "real.csv", index=False)
    df = read_timeseries(
        tmp_path / "real.csv", columns="time=Time,T_r=T_int,u_phys=P_hea,T_a=T_ext"
    )
    np.testing.assert_allclose(df["u"], df["u_phys"])
    assert df["time"].iloc[1] - df["time"].iloc[0] == pd.Timedelta(minutes=30)


@pytest.mark.parametrize(
    "mutate, match",
    [
        (
            lambda d: d.assign(T_r=d["T_r"].where(d.index != 3)),
            r"'T_r' row 4 .*not a finite number",
        ),
        (lambda d: d.drop(columns="T_a"), "missing column.*T_a"),
        (lambda d: d.assign(T_a=d["T_a"] + 273.15), "kelvin"),
        (lambda d: d.drop(index=2), r"'time' skips 1 interval\(s\) of 1800 s before row 3"),
        # Power is the actuator's input: never negative, never beyond a building's 10 MW.
        (
            lambda d: d.assign(u_phys=d["u_phys"].where(d.index != 2, -500.0)),
            r"'u_phys' row 3 is -500 W, negative; .*mark cooling with eta -COP",
        ),
        (
            lambda d: d.assign(u=d["u"].where(d.index != 1, 1e12)),
            r"'u' row 2 is 1e\+12 W, but the plausible range is 0 \.\. 1e\+07 W",
        ),
        # A row index in 'time' is 1-s steps; 12-h steps are not a control interval.
        (
            lambda d: d.assign(time=np.arange(len(d))),
            r"time step is 1 s, outside the plausible 60 \.\. 21600 s .*ISO 8601",
        ),
        (
            lambda d: d.assign(time=pd.date_range("2024-01-01", periods=len(d), freq="12h")),
            "time step is 43200 s, outside the plausible",
        ),
        # Wind speed in m/s: km/h or knots of a storm leave the plausible range.
        (
            lambda d: d.assign(wind=np.where(d.index == 2, 90.0, 3.0)),
            r"'wind' row 3 is 90, outside the plausible 0 \.\. 60 m/s; is it in km/h or knots\?",
        ),
        (
            lambda d: d.assign(wind=np.where(d.index == 0, -1.0, 3.0)),
            r"'wind' row 1 is -1, outside the plausible",
        ),
        # A building's holiday calendar is a 0/1 mark per row.
        (
            lambda d: d.assign(holiday=np.where(d.index == 3, 2.0, 0.0)),
            r"'holiday' row 4 is 2; it must be 1 on the building's holidays and 0 on other days",
        ),
        (
            lambda d: d.iloc[::-1],
            r"'time' goes backwards at row 2 \(2024-01-01 02:30:00 then 2024-01-01 02:00:00\)",
        ),
        (
            lambda d: pd.concat([d.iloc[:3], d.iloc[2:]]),
            r"duplicate timestamp at row 4 \(2024-01-01 01:00:00, as in row 3\)",
        ),
    ],
)
def test_bad_data_names_column_row_and_fix(mutate, match):
    with pytest.raises(InputError, match=match):
        validate_timeseries(mutate(frame()).reset_index(drop=True))


@pytest.mark.parametrize("freq", ["1min", "6h"])
def test_steps_at_the_plausible_limits_are_accepted(freq):
    d = frame().assign(time=pd.date_range("2024-01-01", periods=6, freq=freq))
    assert validate_timeseries(d).attrs["dt_s"] == pd.Timedelta(freq).total_seconds()


def test_power_above_the_actuator_limit_is_refused():
    assert len(validate_timeseries(frame(), u_max_w=5000.0)) == 6
    with pytest.raises(InputError, match="'u' row 2 is 5000 W, but the actuator delivers at most 4000 W"):
        validate_timeseries(frame(), u_max_w=4000.0)


def test_mapping_errors(tmp_path):
    with pytest.raises(InputError, match="not NAME=COLUMN"):
        parse_column_map("T_r")
    with pytest.raises(InputError, match="unknown column 'X'"):
        parse_column_map("X=y")
    frame().to_csv(tmp_path / "d.csv", index=False)
    with pytest.raises(InputError, match="refers to nope"):
        read_timeseries(tmp_path / "d.csv", columns="T_r=nope")
    with pytest.raises(InputError, match="no such file"):
        read_timeseries(tmp_path / "missing.csv")


def test_unwritable_target_leaves_nothing(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        write_timeseries(frame(), tmp_path / "no" / "d.csv")
    assert list(tmp_path.iterdir()) == []


def test_a_semicolon_csv_with_decimal_commas_is_read(tmp_path):
    """A spreadsheet's export in a decimal-comma locale reads as the same data."""
    path = tmp_path / "eu.csv"
    frame().to_csv(path, index=False, sep=";", decimal=",")
    read = read_timeseries(path)
    np.testing.assert_allclose(read["T_r"], frame()["T_r"])
    assert read.attrs["dt_s"] == 1800.0


def test_a_decimal_comma_in_a_comma_csv_is_named(tmp_path):
    data = frame().astype({"T_r": str})
    data.loc[2, "T_r"] = "20,5"
    with pytest.raises(InputError, match=r"'T_r' row 3 has '20,5', a decimal comma; write decimal points"):
        validate_timeseries(data)


def test_the_fixes_for_gaps_and_missing_values_lead_out_not_round():
    """Dropping a row with a missing value is refused as a gap; the gap's message names a fix
    that, applied as written, gives data that validates."""
    data = frame().assign(T_r=frame()["T_r"].where(frame().index != 3))
    with pytest.raises(InputError, match=r"fill such rows \(e\.g\. pandas: df\.interpolate\(\)\)"):
        validate_timeseries(data)
    gappy = data.dropna().reset_index(drop=True)
    with pytest.raises(InputError, match="skips 1 interval") as caught:
        validate_timeseries(gappy)
    assert "df.set_index('time').resample('1800s').interpolate().reset_index()" in str(caught.value)
    df = gappy  # the command of the message, as a user would paste it
    fixed = df.set_index('time').resample('1800s').interpolate().reset_index()
    assert len(validate_timeseries(fixed)) == len(frame())
    filled = validate_timeseries(data.interpolate())
    assert np.isfinite(filled["T_r"]).all()


def _weeks(t_r, t_a, power_w, n=96):
    """n half-hours of a room around ``t_r`` (moving over 4 K) beside outdoor air around ``t_a``."""
    swing = 2.0 * np.sin(np.linspace(0, 4 * np.pi, n))
    return pd.DataFrame({
        "time": pd.date_range("2024-01-01", periods=n, freq="30min"),
        "T_r": t_r + swing, "T_a": t_a + swing, "u_phys": power_w * (1 + np.sign(swing)) / 2,
    })


def _f(c):
    return c * 1.8 + 32


@pytest.mark.parametrize(
    "df, match",
    [
        # A heated room at 21 C beside a winter at 5 C, both in F (70 and 41): the room names it.
        (_weeks(_f(21.0), _f(5.0), 5000.0),
         r"column 'T_r' has a median of 69\.8, above the 45 C .*Fahrenheit \(69\.8 F is 21\.0 C\); "
         r"convert the temperature columns \(T_r, T_a\) to Celsius: C = \(F - 32\) / 1\.8"),
        # A cold room at 2 C (35.6 F, plausible as C) beside a summer at 24 C (75 F): the air names it.
        (_weeks(_f(2.0), _f(24.0), 2500.0), r"column 'T_a' has a median of 75\.2, .*Fahrenheit"),
        (_weeks(21.0 + 273.15, 5.0 + 273.15, 5000.0),
         r"column 'T_r' has a median of 294\.1, a temperature in kelvin \(21\.0 C\); .*C = K - 273\.15"),
        # Only the outdoor column in kelvin.
        (_weeks(21.0, 5.0 + 273.15, 5000.0), r"column 'T_a' has a median of 278\.1, a temperature in kelvin"),
    ],
)
def test_temperatures_in_fahrenheit_or_kelvin_are_refused_naming_the_unit(df, match):
    with pytest.raises(InputError, match=match):
        validate_timeseries(df)


@pytest.mark.parametrize(
    "df",
    [
        _weeks(21.0, 5.0, 5000.0),
        _weeks(2.0, 24.0, 2500.0),  # a cold store in summer
        _weeks(28.0, 38.0, 3000.0),  # a hot room in the hottest climates
        _weeks(-20.0, 10.0, 800.0),  # a freezer room
        _weeks(35.0, 40.0, 0.0),  # no heating, temperatures as they come
        _weeks(21.0, 5.0, 30.0).assign(T_r=lambda d: 21 + 0.2 * np.sign(d["T_a"] - 5)),  # a 30 W heater, a steady room
    ],
)
def test_celsius_and_watts_pass_without_a_word(df):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        validate_timeseries(df)


def test_power_that_looks_like_kw_is_warned_about_once():
    from pinn_mpc.errors import PinnMpcWarning

    with pytest.warns(PinnMpcWarning, match=r"'u_phys' peaks at 5 W while T_r moves over 3\.9 K: a heater "
                      r"under 50 W, or power in kW\? .*convert it to W \(x 1000\)"):
        checked = validate_timeseries(_weeks(21.0, 5.0, 5.0), source="kw.csv")
    import warnings

    with warnings.catch_warnings():  # training or evaluating the frame read does not repeat it
        warnings.simplefilter("error")
        validate_timeseries(checked.iloc[10:], source="training data")


def _local_clock(start: str, n: int, freq: str) -> pd.DatetimeIndex:
    """``n`` instants ``freq`` apart from ``start`` (UTC), as a Berlin wall clock shows them (naive)."""
    return pd.date_range(start, periods=n, freq=freq, tz="UTC").tz_convert("Europe/Berlin").tz_localize(None)


@pytest.mark.parametrize(
    ("start", "freq", "match"),
    [
        ("2024-03-31 00:00", "30min", r"jumps an hour ahead at row 3 \(2024-03-31 01:30:00 then 2024-03-31 03:00:00\), .*daylight saving starts"),
        ("2024-03-31 00:00", "1h", r"jumps an hour ahead at row 2 \(2024-03-31 01:00:00 then 2024-03-31 03:00:00\)"),
        ("2024-10-26 23:00", "30min", r"jumps an hour back at row 5 \(2024-10-27 02:30:00 then 2024-10-27 02:00:00\), .*daylight saving ends"),
        # With hourly rows the hour repeated reads as a duplicate timestamp, whose fix (drop it) loses an hour.
        ("2024-10-26 23:00", "1h", r"jumps an hour back at row 3 \(2024-10-27 02:00:00 then 2024-10-27 02:00:00\)"),
    ],
)
def test_local_clock_time_across_a_daylight_saving_change_is_named_with_its_fix(tmp_path, start, freq, match):
    """Times logged on a local clock jump an hour at a daylight-saving change: sorting or filling
    the gap (the fixes of a row going back, of missing rows) would misplace an hour of data, so
    the message says what it is, and its fix (times in UTC) reads back as uniform steps."""
    data = frame(12).assign(time=_local_clock(start, 12, freq).astype(str))
    data.to_csv(tmp_path / "local.csv", index=False)
    with pytest.raises(InputError, match=match):
        read_timeseries(tmp_path / "local.csv")
    with pytest.raises(InputError, match="daylight saving"):  # naive datetimes from Python alike
        validate_timeseries(data.assign(time=pd.to_datetime(data["time"])))
    data["time"] = pd.to_datetime(data["time"]).dt.tz_localize("Europe/Berlin", ambiguous="infer").dt.tz_convert("UTC")
    data.to_csv(tmp_path / "utc.csv", index=False)
    assert read_timeseries(tmp_path / "utc.csv").attrs["dt_s"] == pd.Timedelta(freq).total_seconds()


def test_an_hour_missing_by_day_or_with_offsets_is_a_gap_not_a_clock_change(tmp_path):
    """An hour of rows missing at noon, or where the times carry their UTC offset, is a gap."""
    noon = frame(12).drop(index=[5, 6]).reset_index(drop=True)
    with pytest.raises(InputError, match=r"skips 2 interval\(s\) of 1800 s"):
        validate_timeseries(noon.assign(time=noon["time"] + pd.Timedelta(hours=10)))
    offsets = frame(12).drop(index=[3, 4]).reset_index(drop=True)
    offsets["time"] = offsets["time"].dt.tz_localize("Europe/Berlin").astype(str)
    offsets.to_csv(tmp_path / "offsets.csv", index=False)
    with pytest.raises(InputError, match=r"skips 2 interval\(s\) of 1800 s before row 4"):
        read_timeseries(tmp_path / "offsets.csv")
