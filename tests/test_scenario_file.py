"""Scenarios as TOML files: export/load round trip, ``--scenario FILE``, bad files, user data."""

import dataclasses
import json
import re
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.errors import InputError
from pinn_mpc_cli.cli import main
from scenarios.inputs.exogenous import load_tmy3
from scenarios.inputs.measured import CSVWeather, PriceCSV
from scenarios.inputs.registry import scenario_names
from scenarios.inputs.scenario_file import get_scenario, load_scenario_file, scenario_to_toml
from scenarios.inputs.series import ForecastErrors

TIME_KEYS = {"decision_ms_median", "decision_ms_mean", "decision_ms_p95", "time_ratio"}


@pytest.mark.parametrize("name", scenario_names())
def test_export_then_load_is_exactly_the_builtin(tmp_path, name):
    path = tmp_path / f"{name}.toml"
    assert main(["scenario", "export", name, "--out", str(path)]) == 0
    assert load_scenario_file(path) == get_scenario(name)
    assert get_scenario(str(path)) == get_scenario(name)  # the one resolver takes a path


def test_fields_beyond_the_builtins_round_trip(tmp_path):
    """Every field is written, including non-defaults the built-ins do not use."""
    base = get_scenario("winter_household")
    custom = dataclasses.replace(
        base,
        sim=dataclasses.replace(base.sim, noise_std_c=0.1),
        forecast=ForecastErrors(t_a_error_std_c=2.0, g_error_rel_std=0.3, gains_known=False),
    )
    path = tmp_path / "custom.toml"
    path.write_text(scenario_to_toml(custom))
    data = tomllib.loads(path.read_text())
    assert data["sensor"] == {"noise_std_c": 0.1}
    assert data["forecast"]["t_a_error_std_c"] == 2.0 and data["forecast"]["gains_known"] is False
    assert load_scenario_file(path) == custom


@pytest.mark.parametrize("name", scenario_names())
def test_closed_loop_on_the_exported_file_gives_the_same_kpis(tmp_path, capsys, name):
    path = tmp_path / f"{name}.toml"
    assert main(["scenario", "export", name, "--out", str(path)]) == 0
    kpis = {}
    # No oracle on an EnergyPlus building (no true RC model or state): the thermostat there.
    controller = get_scenario(name).reference
    for label, scenario in (("name", name), ("file", str(path))):
        out = tmp_path / f"{label}.json"
        argv = ["closed-loop", "--scenario", scenario, "--controller", controller, "--days", "1",
                "--seed", "2", "--json", str(out)]
        assert main(argv) == 0
        kpis[label] = {k: v for k, v in json.loads(out.read_text()).items() if k not in TIME_KEYS}
    assert kpis["file"].pop("scenario_file") == str(path)  # the results name the file too
    assert kpis["file"] == kpis["name"]
    assert kpis["file"]["scenario"] == name and kpis["file"]["objective"] > 0


def test_scenario_list_and_show(capsys):
    assert main(["scenario", "list"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    from scenarios.plants.boptest import BUILTIN_BOPTEST

    # the package's own scenarios, then BOPTEST's (which run on a BOPTEST server)
    assert [line.split(":")[0] for line in lines] == [*scenario_names(), *BUILTIN_BOPTEST]
    assert all("Weather split" in line for line in lines[: len(scenario_names())])
    assert main(["scenario", "show", "cold_storage"]) == 0
    shown = tomllib.loads(capsys.readouterr().out)
    assert shown["name"] == "cold_storage" and shown["building"]["eta"] == -2.5
    assert shown["weather"]["type"] == "TMY3Weather"


def _edit(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


BAD_FILES = {
    "unknown-key": (
        lambda t: _edit(t, "backup_low_c = 16.0", "backup_low_c = 16.0\nbackup_lo_c = 15.0"),
        "simulation.backup_lo_c: unknown key",
    ),
    "negative-resistance": (
        lambda t: _edit(t, "r_ra_k_per_w = 0.00375", "r_ra_k_per_w = -0.00375"),
        "building.r_ra_k_per_w is negative",
    ),
    "missing-weather-file": (
        lambda t: _edit(t, '"723170TYA.CSV"', '"my_station.epw"'),
        "weather.file_name: weather file 'my_station.epw' not found",
    ),
    "band-min-above-max": (
        lambda t: _edit(t, "night_min_c = 17.0", "night_min_c = 23.0"),
        r"comfort.night_min_c \(23.0\) must be below night_max_c \(22.0\)",
    ),
    "toml-syntax": (lambda t: _edit(t, "horizon_steps = 48", "horizon_steps = "), "not valid TOML"),
    "wrong-type": (
        lambda t: _edit(t, "t_a_error_std_c = 0.0", 't_a_error_std_c = "2"'),
        "forecast.t_a_error_std_c: expected a number",
    ),
    "negative-sensor-noise": (
        lambda t: _edit(t, "noise_std_c = 0.0", "noise_std_c = -0.1"),
        "sensor.noise_std_c must be >= 0",
    ),
    "relocated-key-in-the-wrong-section": (
        lambda t: _edit(t, "backup_low_c = 16.0", "backup_low_c = 16.0\nnoise_std_c = 0.1"),
        "simulation.noise_std_c: unknown key; it is written as sensor.noise_std_c",
    ),
    "missing-required": (
        lambda t: _edit(t, "initial_t_r_c = 20.0\n", ""), "initial_t_r_c: missing"
    ),
    "rc-and-values": (
        lambda t: _edit(t, "\n[building]", '\n[building]\nrc = "rc.json"'),
        "building: give rc or the R/C values, not both",
    ),
    "unknown-weather-type": (
        lambda t: _edit(t, 'type = "TMY3Weather"', 'type = "EPW"'),
        "weather.type: 'EPW' is not one of",
    ),
}


@pytest.mark.parametrize("case", list(BAD_FILES))
def test_a_bad_file_is_one_line_naming_the_key_exit_2_nothing_written(tmp_path, capsys, case):
    edit, message = BAD_FILES[case]
    path = tmp_path / "bad.toml"
    path.write_text(edit(scenario_to_toml(get_scenario("winter_household"))))
    out = tmp_path / "kpis.json"
    argv = ["closed-loop", "--scenario", str(path), "--controller", "thermostat", "--days", "1",
            "--json", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert str(path) in err
    assert re.search(message, err), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


def test_every_list_of_scenarios_is_the_one_list(capsys):
    """scenario list, the unknown-scenario message and every --help that lists scenarios name
    the same built-ins (issue 46: BOPTEST's was left out of all but the first)."""
    from pinn_mpc_cli.parser import build_parser
    from scenarios.inputs.scenario_file import builtin_names
    from scenarios.plants.boptest import BUILTIN_BOPTEST

    names = builtin_names()
    assert names == [*scenario_names(), *BUILTIN_BOPTEST] and "boptest_hydronic_heat_pump" in names
    assert main(["scenario", "list"]) == 0
    assert [line.split(":")[0] for line in capsys.readouterr().out.strip().splitlines()] == names
    with pytest.raises(InputError) as refused:
        get_scenario("nope")
    assert re.search(r"choose one of: (.*), or give", str(refused.value)).group(1).split(", ") == names
    parser = build_parser()
    for argv in (["simulate"], ["closed-loop"], ["compare"], ["scenario", "show"], ["scenario", "export"]):
        with pytest.raises(SystemExit):
            parser.parse_args([*argv, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        listed = re.search(r"one of: (.*?); or a", text).group(1).split(", ")
        assert listed == names, argv
    # the README's list: tests/test_public_api.py::test_readme_names_the_scenarios_and_controllers


def test_unknown_name_and_export_refusals(tmp_path, capsys):
    with pytest.raises(InputError, match="unknown scenario 'nope'.*scenario file"):
        get_scenario("nope")
    path = tmp_path / "w.toml"
    assert main(["scenario", "export", "winter_household", "--out", str(path)]) == 0
    capsys.readouterr()
    assert main(["scenario", "export", str(path), "--out", str(path)]) == 2
    assert "--out" in capsys.readouterr().err
    assert load_scenario_file(path) == get_scenario("winter_household")  # not clobbered


# ------------------------------------------------------------- the user's own data files


def _epw_text(t_a: np.ndarray, ghi: np.ndarray) -> str:
    """A minimal EPW typical year (8 header lines, 35 fields per hour) for pvlib's reader."""
    header = [
        "LOCATION,Testville,NC,USA,TMY3,723170,36.1,-79.9,-5.0,270.0",
        "DESIGN CONDITIONS,0",
        "TYPICAL/EXTREME PERIODS,0",
        "GROUND TEMPERATURES,0",
        "HOLIDAYS/DAYLIGHT SAVINGS,No,0,0,0",
        "COMMENTS 1,written by the test",
        "COMMENTS 2,",
        "DATA PERIODS,1,1,Data,Sunday, 1/ 1,12/31",
    ]
    times = pd.date_range("2021-01-01 01:00", periods=8760, freq="h")
    rows = []
    for i, t in enumerate(times):
        hour = 24 if t.hour == 0 else t.hour
        day = t - pd.Timedelta(hours=1) if t.hour == 0 else t
        fields = [1999, day.month, day.day, hour, 60, "?9?9?9?9E0?9?9?9?9?9?9?9?9?9?9?9?9?9?9?9*9*9?9",
                  t_a[i], 0.0, 50, 101000, 0, 0, 300, ghi[i], 0, 0] + [0] * 19
        rows.append(",".join(str(f) for f in fields))
    return "\n".join(header + rows) + "\n"


def test_epw_weather_is_read_with_pvlib_and_matches_the_same_year_as_tmy3(tmp_path):
    t_a, ghi, _ = load_tmy3("723170TYA.CSV")
    (tmp_path / "station.epw").write_text(_epw_text(t_a, ghi))
    text = _edit(scenario_to_toml(get_scenario("winter_household")), '"723170TYA.CSV"', '"station.epw"')
    (tmp_path / "epw.toml").write_text(text)
    scenario = load_scenario_file(tmp_path / "epw.toml")
    assert scenario.weather.file_name == str(tmp_path / "station.epw")  # relative to the TOML
    epw_t_a, epw_ghi, station = load_tmy3(scenario.weather.file_name)
    np.testing.assert_allclose(epw_t_a, t_a)
    np.testing.assert_allclose(epw_ghi, ghi)
    assert station == "Testville"
    builtin = get_scenario("winter_household").exogenous(days=2, seed=4, part="test")
    mine = scenario.exogenous(days=2, seed=4, part="test")
    pd.testing.assert_frame_equal(mine, builtin)


def _csv_scenario(tmp_path: Path, *, test_days: int = 5) -> Path:
    hours = pd.date_range("2023-01-01 00:00", "2023-01-21 23:00", freq="h")
    h = np.arange(len(hours), dtype=float)
    pd.DataFrame({"time": hours.strftime("%Y-%m-%dT%H:%M"), "T_a": 5.0 + 0.01 * h,
                  "G": np.where(hours.hour == 12, 400.0, 0.0)}).to_csv(tmp_path / "wx.csv", index=False)
    day = pd.date_range("2023-05-01", periods=24, freq="h")
    pd.DataFrame({"time": day, "price": 0.1 + 0.01 * np.arange(24)}).to_csv(
        tmp_path / "tariff.csv", index=False
    )
    text = scenario_to_toml(get_scenario("winter_household"))
    start, end = text.index("[weather]"), text.index("[price]")
    text = (text[:start] + f'[weather]\ntype = "CSVWeather"\npath = "wx.csv"\ntest_days = {test_days}\n\n'
            + text[end:])
    start, end = text.index("[price]"), text.index("[comfort]")
    text = text[:start] + '[price]\ntype = "PriceCSV"\npath = "tariff.csv"\n\n' + text[end:]
    (tmp_path / "mine.toml").write_text(text)
    return tmp_path / "mine.toml"


def test_csv_weather_and_price_split_interpolate_and_repeat(tmp_path):
    scenario = load_scenario_file(_csv_scenario(tmp_path))
    assert scenario.weather == CSVWeather(path=str(tmp_path / "wx.csv"), test_days=5)
    assert scenario.price == PriceCSV(path=str(tmp_path / "tariff.csv"))
    assert "training 2023-01-01 - 2023-01-15 (15 days), test 2023-01-16 - 2023-01-20" in scenario.weather_split
    for seed in range(5):
        test = scenario.exogenous(days=2, seed=seed, part="test", lead_steps=48)
        train = scenario.exogenous(days=4, seed=seed, part="train")
        assert test["time"].min() >= pd.Timestamp("2023-01-16")
        assert train["time"].max() < pd.Timestamp("2023-01-16")
        for frame in (test, train):
            # T_a is linear in time: its mid-interval interpolation is exact.
            hours = (frame["time"] - pd.Timestamp("2023-01-01")).dt.total_seconds() / 3600 + 0.25
            np.testing.assert_allclose(frame["T_a"], 5.0 + 0.01 * hours, atol=1e-12)
            # One day of prices, repeated: the price is the hour's, whatever the date.
            np.testing.assert_allclose(frame["price"], 0.1 + 0.01 * frame["time"].dt.hour)
    with pytest.raises(InputError, match="does not fit in the test weather"):
        scenario.exogenous(days=5, seed=0, part="test", lead_steps=48)


def test_a_csv_file_scenario_runs_closed_loop(tmp_path):
    path = _csv_scenario(tmp_path)
    out = tmp_path / "k.json"
    assert main(["closed-loop", "--scenario", str(path), "--controller", "oracle", "--days", "1",
                 "--json", str(out)]) == 0
    assert json.loads(out.read_text())["counted_days"][0] >= "2023-01-16"


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("time,T_a\n2023-01-01,1\n2023-01-01,2\n", "time must increase; row 2 does not"),
        # A station's local clock at the spring switch: an hour out of place if bridged.
        ("time,T_a\n2023-03-26T00:00,1\n2023-03-26T01:00,1\n2023-03-26T03:00,1\n2023-03-26T04:00,1\n",
         r"jumps an hour ahead at row 3 \(2023-03-26T01:00 then 2023-03-26T03:00\), .*daylight saving starts; "
         r"give the times in UTC"),
        # An irregular step before it does not hide it.
        ("time,T_a\n" + "".join(f"{t},1\n" for t in ("2023-03-25T20:00", "2023-03-25T21:00", "2023-03-25T21:30",
         "2023-03-25T22:30", "2023-03-25T23:30", "2023-03-26T00:30", "2023-03-26T01:30", "2023-03-26T03:30",
         "2023-03-26T04:30")), r"jumps an hour ahead at row 8 \(2023-03-26T01:30 then 2023-03-26T03:30\)"),
        ("time,T_a\n2023-01-01,1\n2023-01-02,abc\n", "column T_a, row 2: 'abc' is not a number"),
        ("time,temp\n2023-01-01,1\n2023-01-02,2\n", r"lacks column\(s\) \['T_a'\]"),
        # A summer in Fahrenheit or a winter in kelvin: the unit, not the range (issue 46).
        ("time,T_a\n2023-07-01,75\n2023-07-02,80\n", r"column 'T_a' has a median of 77\.5, .*"
         r"Fahrenheit .*C = \(F - 32\) / 1\.8"),
        ("time,T_a\n2023-01-01,270\n2023-01-02,275\n", r"column 'T_a' has a median of 272\.5, a "
         r"temperature in kelvin \(-0\.6 C\); .*C = K - 273\.15"),
    ],
)
def test_a_bad_weather_csv_names_the_key_column_and_row(tmp_path, content, message):
    path = _csv_scenario(tmp_path)
    (tmp_path / "wx.csv").write_text(content)
    with pytest.raises(InputError, match=f"weather.path: .*{message}"):
        load_scenario_file(path)


@pytest.fixture(scope="module")
def identified_scenario(tmp_path_factory):
    """A scenario file whose building is ``rc = "rc.json"`` written by ``identify``."""
    folder = tmp_path_factory.mktemp("own_building")
    data = folder / "data.csv"
    assert main(["simulate", "--scenario", "winter_household", "--days", "14", "--seed", "3",
                 "--out", str(data)]) == 0
    assert main(["identify", "--data", str(data), "--out", str(folder / "rc.json")]) == 0
    text = scenario_to_toml(get_scenario("winter_household"))
    start, end = text.index("\n[building]"), text.index("\n[simulation]")
    text = text[:start] + '\n[building]\nrc = "rc.json"\n' + text[end:]
    text = _edit(text, 'name = "winter_household"', 'name = "my_house"')
    (folder / "my_house.toml").write_text(text)
    return folder


def test_an_identified_rc_file_scenario_runs_closed_loop(identified_scenario, capsys):
    folder = identified_scenario
    scenario = load_scenario_file(folder / "my_house.toml")
    rc = json.loads((folder / "rc.json").read_text())
    assert scenario.sim.params.r_ra_k_per_w == rc["R_ra_K_per_W"]
    # Identified on data from the winter household: within a few % of its true R_ra.
    assert scenario.sim.params.r_ra_k_per_w == pytest.approx(0.00375, rel=0.05)
    out = folder / "qp.json"
    assert main(["closed-loop", "--scenario", str(folder / "my_house.toml"), "--controller",
                 "qp-mpc", "--rc", str(folder / "rc.json"), "--days", "1", "--seed", "1",
                 "--json", str(out)]) == 0
    kpis = json.loads(out.read_text())
    # Seed 1 draws cold February days: the MPC heats, keeps the band and never falls back.
    assert kpis["scenario"] == "my_house" and kpis["fallbacks"] == 0
    assert kpis["energy_kwh"] > 10 and kpis["discomfort_kh"] < 0.5


# compare --quick on a scenario file whose building is an identified RC: the walkthrough
# (tests/test_docs.py::test_walkthrough_runs_as_written) runs it as docs/your-building.md gives it.


def test_an_exported_energyplus_scenario_names_its_weather_once(tmp_path):
    """The export writes the plant's weather in one place (simulation.plant.weather): another
    city there is the scenario's weather; an older export with [weather].file_name still reads."""
    path = tmp_path / "office.toml"
    assert main(["scenario", "export", "eplus_small_office", "--out", str(path)]) == 0
    text = path.read_text()
    assert 'weather = "usa_il_chicago"' in text and "\nfile_name =" not in text
    other = tmp_path / "denver.toml"
    other.write_text(text.replace('weather = "usa_il_chicago"', 'weather = "usa_co_denver"')
                     .replace('name = "eplus_small_office"', 'name = "office_denver"'))
    scenario = load_scenario_file(other)
    assert scenario.weather.file_name == scenario.plant.settings.weather_file == "usa_co_denver"
    assert (scenario.weather.window_start, scenario.weather.test_days) == ("01-01", 28)
    older = tomllib.loads(text)
    older["weather"]["file_name"] = "usa_il_chicago"
    import tomlkit

    (tmp_path / "older.toml").write_text(tomlkit.dumps(older))
    assert load_scenario_file(tmp_path / "older.toml") == get_scenario("eplus_small_office")
