"""Nothing lost, nothing silent, nothing unbounded (issue 18): the newer features under
careless input. Each refusal is exit 2 with one line on stderr naming the problem, and the
user's files byte for byte as they were (sha256 before and after)."""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.artifacts import save_model
from pinn_mpc.data import (
    fleet_params_path,
    read_fleet_timeseries,
    read_timeseries,
    write_timeseries,
)
from pinn_mpc.errors import InputError, PinnMpcWarning
from pinn_mpc.identify import identify_rc
from pinn_mpc.io import atomic_write_json, file_sha256
from pinn_mpc.physics import PAPER_HOUSEHOLD, rc_summary
from pinn_mpc.simulator import draw_fleet
from pinn_mpc.training import TrainConfig, train_model
from pinn_mpc_cli.cli import main
from scenarios.experiments.sweep import Cell, scenario_digest
from scenarios.experiments.sweep.grid import _label
from scenarios.experiments.sweep.store import _read_cell
from scenarios.fleets.training import building_model_dir, frame_digest, train_per_building
from scenarios.inputs.measured import CSVWeather
from scenarios.inputs.scenario_file import (
    get_scenario,
    load_scenario_file,
    scenario_inputs,
    scenario_to_toml,
)
from scenarios.plants.energyplus.files import (
    bundled_buildings,
    bundled_weather,
    energyplus_available,
)
from scenarios.plants.energyplus.model import prepare_model
from scenarios.running import budget
from scenarios.running.closed_loop import progress_stage, progress_steps
from scenarios.running.datagen import generate

HOURS = pd.date_range("2023-01-01", periods=24 * 30, freq="h")


def _weather(path: Path, times: pd.DatetimeIndex | list[str] | np.ndarray = HOURS, *,
             t_a: np.ndarray | None = None, g: np.ndarray | None = None) -> Path:
    n = len(times)
    hour = np.arange(n) % 24
    pd.DataFrame({
        "time": times.strftime("%Y-%m-%dT%H:%M:%S") if isinstance(times, pd.DatetimeIndex) else times,
        "T_a": 2.0 + 3.0 * np.sin(2 * np.pi * hour / 24) if t_a is None else t_a,
        "G": np.where(hour == 12, 400.0, 0.0) if g is None else g,
    }).to_csv(path, index=False)
    return path


def _with_section(text: str, section: str, body: str) -> str:
    start = text.index(f"\n[{section}]") + 1
    end = text.index("\n[", start + 1) + 1
    return text[:start] + f"[{section}]\n{body}\n\n" + text[end:]


def _scenario(folder: Path, name: str = "s.toml", *, weather: str | None = "wx.csv",
              extra: str = "", price: str | None = None, edit: tuple[str, str] | None = None) -> Path:
    """winter_household as a file; ``weather`` a CSV in ``folder`` (written if missing)."""
    text = scenario_to_toml(get_scenario("winter_household"))
    if weather is not None:
        if not (folder / weather).exists():
            _weather(folder / weather)
        text = _with_section(text, "weather", f'type = "CSVWeather"\npath = "{weather}"\n'
                             f"test_days = 10\n{extra}")
    if price is not None:
        text = _with_section(text, "price", f'type = "PriceCSV"\npath = "{price}"')
    if edit is not None:
        assert re.search(edit[0], text), edit[0]
        text = re.sub(edit[0], edit[1], text, count=1)
    (folder / name).write_text(text, encoding="utf-8")
    return folder / name


def checksums(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def refused(argv: list[str], capsys: pytest.CaptureFixture[str], *fragments: str) -> str:
    """Run the CLI: exit 2 and one line on stderr holding every fragment; returns the line."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    lines = [line for line in err.splitlines() if "warning" not in line]
    assert len(lines) == 1, err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    return lines[0]


@pytest.fixture
def user(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A user's folder: a scenario file reading a weather CSV, one reading an rc.json, an
    edited exported scenario."""
    monkeypatch.chdir(tmp_path)
    _scenario(tmp_path, "csvw.toml")
    _scenario(tmp_path, "s.toml", weather=None)
    atomic_write_json(tmp_path / "rc.json", rc_summary(PAPER_HOUSEHOLD, source="test"))
    text = scenario_to_toml(get_scenario("paper_household"))
    (tmp_path / "rcs.toml").write_text(_with_section(text, "building", 'rc = "rc.json"'))
    (tmp_path / "edited.toml").write_text("# my edits\n" + text)
    return tmp_path


LOOP = ["closed-loop", "--controller", "thermostat", "--days", "1"]
DATA_LOSS = [
    pytest.param([*LOOP, "--scenario", "s.toml", "--json", "s.toml"],
                 ["--json s.toml", "input --scenario s.toml"], id="closed-loop-json-is-the-scenario"),
    pytest.param(["simulate", "--scenario", "s.toml", "--days", "1", "--out", "s.toml"],
                 ["--out s.toml", "input --scenario s.toml"], id="simulate-out-is-the-scenario"),
    pytest.param(["simulate", "--scenario", "csvw.toml", "--days", "1", "--out", "wx.csv"],
                 ["--out wx.csv", "--scenario csvw.toml's weather.path"], id="simulate-out-is-its-weather"),
    pytest.param([*LOOP, "--scenario", "csvw.toml", "--json", "./wx.csv"],
                 ["--scenario csvw.toml's weather.path"], id="closed-loop-json-is-its-weather"),
    pytest.param([*LOOP, "--scenario", "csvw.toml", "--json", "k.json", "--csv", "wx.csv"],
                 ["--csv wx.csv"], id="closed-loop-csv-is-its-weather"),
    pytest.param([*LOOP, "--scenario", "rcs.toml", "--json", "rc.json"],
                 ["--scenario rcs.toml's building.rc"], id="closed-loop-json-is-its-rc"),
    pytest.param(["compare", "--scenario", "csvw.toml", "--quick", "--json", "wx.csv"],
                 ["--json wx.csv", "weather.path"], id="compare-json-is-its-weather"),
    pytest.param(["scenario", "export", "winter_household", "--out", "edited.toml"],
                 ["edited.toml already exists", "--force"], id="export-onto-an-edited-file"),
    pytest.param(["scenario", "export", "csvw.toml", "--out", "csvw.toml", "--force"],
                 ["same file as the input NAME"], id="export-force-onto-its-own-file"),
    pytest.param(["scenario", "export", "winter_household", "--out", "myscen"],
                 ["end in .toml", "myscen.toml"], id="export-without-suffix"),
]


@pytest.mark.parametrize(("argv", "fragments"), DATA_LOSS)
def test_no_output_replaces_a_file_a_command_reads(user, capsys, argv, fragments):
    before = checksums(user)
    refused(argv, capsys, *fragments)
    assert checksums(user) == before


def test_export_replaces_an_existing_file_only_with_force(user, capsys):
    assert main(["scenario", "export", "winter_household", "--out", "edited.toml", "--force"]) == 0
    assert load_scenario_file(user / "edited.toml") == get_scenario("winter_household")


def test_scenario_inputs_are_the_file_and_what_it_names(user):
    assert scenario_inputs("winter_household") == {}
    assert scenario_inputs("csvw.toml") == {"": Path("csvw.toml"), "weather.path": Path("wx.csv")}
    assert scenario_inputs("rcs.toml")["building.rc"] == Path("rc.json")


# ---------------------------------------------------------------- sweep cells by content


def test_sweep_cells_are_keyed_by_content_not_by_stem(tmp_path):
    (tmp_path / "da").mkdir()
    (tmp_path / "db").mkdir()
    a = str(_scenario(tmp_path / "da", weather=None))
    b = str(_scenario(tmp_path / "db", weather=None, edit=(
        r"comfort_weight_eur_per_kh = [0-9.]+", "comfort_weight_eur_per_kh = 500.0")))
    cells = [Cell(scenario=s, controller="thermostat", seed=0, train_days=None) for s in (a, b)]
    assert cells[0].name != cells[1].name  # same stem, different content
    assert _label("winter_household") == "winter_household"
    before = _label(a)
    text = Path(a).read_text()
    Path(a).write_text(text.replace("comfort_weight_eur_per_kh = 5.0", "comfort_weight_eur_per_kh = 50.0"))
    assert _label(a) != before  # an edited file is a new cell
    Path(a).write_text(text)
    assert _label(a) == before  # the same content, the same cell


def test_a_changed_weather_file_changes_the_digest(tmp_path):
    path = str(_scenario(tmp_path))
    before = scenario_digest(path)
    _weather(tmp_path / "wx.csv", t_a=np.full(len(HOURS), 1.0))
    os.utime(path, ns=(1, 1))  # the digest is computed once per version of the scenario file
    assert scenario_digest(path) != before


def test_a_cell_record_of_another_content_is_refused(tmp_path):
    path = str(_scenario(tmp_path, weather=None))
    cell = Cell(scenario=path, controller="thermostat", seed=0, train_days=None)
    record = tmp_path / "cell.json"
    record.write_text(json.dumps({"cell": dataclasses.asdict(cell), "scenario_sha256": "0" * 64}))
    with pytest.raises(InputError, match="not the record of cell"):
        _read_cell(record, cell)


# ---------------------------------------------------------------- measured inputs


def _gap_times() -> pd.DatetimeIndex:
    return HOURS[(HOURS < pd.Timestamp("2023-01-10")) | (HOURS >= pd.Timestamp("2023-01-16"))]


def test_a_gap_in_the_weather_is_refused_unless_max_gap_h_bridges_it(tmp_path) -> None:
    _weather(tmp_path / "gap.csv", _gap_times())
    with pytest.raises(InputError, match=r"weather.path: .*gap of 6.0 days between rows 216 .* max_gap_h"):
        load_scenario_file(_scenario(tmp_path, weather="gap.csv"))
    scenario = load_scenario_file(
        _scenario(tmp_path, "bridged.toml", weather="gap.csv", extra="max_gap_h = 150.0")
    )
    assert isinstance(scenario.weather, CSVWeather)
    assert scenario.weather.max_gap_h == 150.0


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        (pd.date_range("2023-01-01", periods=6, freq="h"), "cover 6.0 h"),
        (pd.date_range("2023-01-01", periods=30, freq="h"), "cover 30.0 h"),
        (pd.date_range("2023-01-01", periods=48, freq="4h")[:-1], "max_gap_h"),
    ],
)
def test_a_price_file_that_is_not_whole_days_is_refused(tmp_path, rows, message):
    pd.DataFrame({"time": rows, "price": 0.2}).to_csv(tmp_path / "p.csv", index=False)
    with pytest.raises(InputError, match=f"price.path: .*{message}"):
        load_scenario_file(_scenario(tmp_path, weather=None, price="p.csv"))


DST = pd.date_range("2023-03-01", periods=24 * 40, freq="h")  # Europe switches on 26 March


@pytest.mark.parametrize(
    ("reference", "write"),
    [
        pytest.param(HOURS, lambda t: t.strftime("%Y-%m-%dT%H:%M:%SZ"), id="Z"),
        pytest.param(DST, lambda t: [x.isoformat() for x in
                                     t.tz_localize("UTC").tz_convert("Europe/Brussels")],
                     id="offsets-changing-at-dst"),
        pytest.param(HOURS, lambda t: (t - pd.Timestamp("1970-01-01")).total_seconds().astype(int),
                     id="epoch-seconds"),
    ],
)
def test_weather_times_are_instants_in_every_notation(tmp_path, reference, write) -> None:
    """The same instants written with Z, with local offsets across a DST switch and as epoch
    seconds give the same weather as naive UTC times."""
    t_a = np.linspace(0, 10, len(reference))
    _weather(tmp_path / "mine.csv", write(reference), t_a=t_a)
    _weather(tmp_path / "utc.csv", reference, t_a=t_a)
    mine = load_scenario_file(_scenario(tmp_path, "mine.toml", weather="mine.csv"))
    utc = load_scenario_file(_scenario(tmp_path, "utc.toml", weather="utc.csv"))
    assert isinstance(mine.weather, CSVWeather) and isinstance(utc.weather, CSVWeather)
    pd.testing.assert_frame_equal(mine.weather.frame(), utc.weather.frame())
    assert mine.weather.split_text().split(":")[1] == utc.weather.split_text().split(":")[1]


def test_data_with_offsets_changing_at_dst_reads_without_a_traceback(tmp_path):
    frame = generate(get_scenario("paper_household"), days=2, seed=0)
    utc = pd.DatetimeIndex(frame["time"]) - pd.Timedelta(days=5)  # 27-29 March 2021
    local = utc.tz_localize("UTC").tz_convert("Europe/Brussels")
    assert local[0].utcoffset() != local[-1].utcoffset()  # the file crosses the switch
    frame["time"] = [t.isoformat() for t in local]
    frame.to_csv(tmp_path / "d.csv", index=False)
    read = read_timeseries(tmp_path / "d.csv")
    assert read.attrs["dt_s"] == 1800.0
    assert (read["time"].to_numpy() == utc.to_numpy()).all()


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        ((r"initial_t_r_c = [-0-9.]+", "initial_t_r_c = 500.0"),
         "initial_t_r_c = 500 C is outside the plausible -50 .. 80 C"),
        ((r"initial_t_m_c = [-0-9.]+", "initial_t_m_c = -300.0"), "initial_t_m_c = -300 C"),
        ((r"(?s)\n\[building\].*?\n(?=\[simulation\])", "\n"), "[building] is missing"),
        ((r"solar_aperture_m2 = [^\n]*\n", ""), "building.solar_aperture_m2: missing"),
        ((r"eta = [^\n]*\n", ""), "building.eta: missing"),
        ((r"u_max_w = [^\n]*", "u_max_w = 5e9"),
         "simulation.u_max_w = 5e+09 W is above the plausible 1e+08 W"),
    ],
)
def test_implausible_or_missing_scenario_values_are_refused(tmp_path, edit, message):
    with pytest.raises(InputError, match=re.escape(message)):
        load_scenario_file(_scenario(tmp_path, weather=None, edit=edit))


@pytest.mark.parametrize(
    ("t_a", "g", "warning"),
    [
        (2.0 * 1.8 + 32 + np.zeros(len(HOURS)), None, "is T_a in Fahrenheit (35.6 F would be 2.0 C)"),
        (None, np.where(np.arange(len(HOURS)) % 24 == 12, 0.4, 0.0), "G never exceeds 0.4 W/m2"),
    ],
)
def test_implausible_units_are_warned_with_the_likely_cause(tmp_path, t_a, g, warning):
    _weather(tmp_path / "units.csv", t_a=t_a, g=g)
    with pytest.warns(PinnMpcWarning, match=re.escape(warning)):
        load_scenario_file(_scenario(tmp_path, weather="units.csv"))


def test_a_file_with_a_builtins_name_is_named_in_the_results(tmp_path, capsys):
    path = _scenario(tmp_path, weather=None, edit=('name = "winter_household"', 'name = "cold_storage"'))
    out = tmp_path / "k.json"
    assert main([*LOOP, "--scenario", str(path), "--json", str(out)]) == 0
    captured = capsys.readouterr()
    assert "name = 'cold_storage' is a built-in scenario's, but the file differs" in captured.err
    assert f"thermostat on cold_storage (file {path})" in captured.out
    assert json.loads(out.read_text())["scenario_file"] == str(path)


def test_a_bom_is_skipped_and_show_lists_the_defaults(tmp_path, capsys):
    path = _scenario(tmp_path, weather=None, edit=(r"\[forecast\][^\[]*", ""))
    path.write_text(path.read_text(), encoding="utf-8-sig")
    assert load_scenario_file(path) == get_scenario("winter_household")
    assert main(["scenario", "show", str(path)]) == 0
    assert "at their defaults (as shown above): forecast.error_correlation_h" in capsys.readouterr().out


# ---------------------------------------------------------------- work before it starts


def test_simulate_memory_is_estimated_before_anything_runs(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(budget, "available_memory_bytes", lambda: 8_000_000_000)
    out = tmp_path / "big.csv"
    line = refused(["simulate", "--scenario", "winter_household", "--buildings", "100000",
                    "--days", "30", "--out", str(out)], capsys, "needs about 58 GB of memory",
                   "use at most 11111 buildings for 30 days")
    assert "144,000,000 rows" in line
    assert not out.exists()


def test_fleets_and_grids_are_sized_before_they_start(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(budget, "available_memory_bytes", lambda: 8_000_000_000)
    fleet = ["closed-loop", "--scenario", "winter_household", "--controller", "qp-mpc",
             "--days", "1", "--json", str(tmp_path / "k.json"), "--buildings"]
    refused([*fleet, "100000"], capsys, "needs about 102 GB of memory", "use at most")
    refused([*fleet, "5000"], capsys, "5,000 qp-mpc controllers", "roughly", "--large")
    refused(["sweep", "--scenarios", "winter_household", "--controllers", "qp-mpc", "--seeds",
             "0-100000", "--out", str(tmp_path / "sw")], capsys, "200,002 cells", "--large")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_long_runs_print_progress_lines_off_a_terminal():
    """One line per ``every_s`` of the (fake) clock, with the steps done and the time left."""
    ticks = iter(range(0, 10_000, 10))
    stream = io.StringIO()
    steps = list(progress_steps(100, "cem", True, stream=stream, clock=lambda: next(ticks), every_s=250))
    assert steps == list(range(100))
    lines = stream.getvalue().splitlines()
    assert len(lines) == 3
    assert lines[0] == "cem: 25 of 100 steps (25 %), 4 min elapsed, about 12 min left"
    assert list(progress_steps(3, "x", False, stream=stream)) == [0, 1, 2]


def test_a_stage_counts_its_steps_and_the_time_left():
    """:class:`Stage`: what a long stage is at, exactly, on a (fake) clock of 10 s a tick."""
    ticks = iter(range(0, 10_000, 10))
    with progress_stage("training data", False, clock=lambda: next(ticks)) as stage:
        assert stage.line() == "training data: 10 s elapsed"
        stage.detail = "selecting a test"
        assert stage.line() == "training data: selecting a test, 20 s elapsed"
        done = []
        for k in stage.steps(4, "interval"):
            done.append((k, stage.detail))
    assert done == [
        (0, "0 of 4 intervals"),
        (1, "1 of 4 intervals (25 %), about 30 s left"),
        (2, "2 of 4 intervals (50 %), about 20 s left"),
        (3, "3 of 4 intervals (75 %), about 10 s left"),
    ]


def test_a_long_stage_says_what_it_does_as_it_starts_and_while_it_runs():
    """The start line, then a line every ``every_s`` seconds from a thread of its own, also
    while the stage waits in one call (here a sleep); nothing without ``progress``."""
    import time

    stream = io.StringIO()
    with progress_stage("training data on BOPTEST", True, stream=stream, every_s=0.02) as stage:
        stage.detail = "selecting a test"
        time.sleep(0.3)  # one call that takes long: a server's warm-up
        for _ in stage.steps(3, "interval"):
            time.sleep(0.1)
    lines = stream.getvalue().splitlines()
    assert lines[0] == "training data on BOPTEST"
    beats = lines[1:]
    assert any(re.fullmatch(r"training data on BOPTEST: selecting a test, \d+ s elapsed", b) for b in beats)
    assert any(re.fullmatch(r"training data on BOPTEST: [12] of 3 intervals \(\d+ %\), about \d+ s left, \d+ s elapsed", b) for b in beats)
    assert all(b.startswith("training data on BOPTEST: ") for b in beats)
    n = len(lines)
    time.sleep(0.1)
    assert len(stream.getvalue().splitlines()) == n  # the stage ended: its lines too
    quiet = io.StringIO()
    with progress_stage("x", False, stream=quiet, every_s=0.01):
        time.sleep(0.05)
    assert quiet.getvalue() == ""


def test_a_sweep_says_what_it_starts_and_what_is_still_running():
    from scenarios.experiments.sweep.engine import _progress_line, _start_line

    assert _start_line(8, 2, 3, 2) == (
        "sweep: 8 cell(s) to run (2 reused), 3 model(s) to train, on 2 recording(s) of BOPTEST "
        "training data first"
    )
    assert _start_line(8, 0, 0, 0) == "sweep: 8 cell(s) to run (0 reused), 0 model(s) to train"
    assert _progress_line(4, 10, 2, 1, 600.0, waiting={"model": 0, "cell": 6}) == (
        "sweep: 4 of 10 cells (2 reused), 1 model(s) trained, 10 min elapsed, about 30 min "
        "left; running or queued: 6 cell(s)"
    )
    assert _progress_line(0, 10, 0, 0, 120.0, waiting={"model": 2, "cell": 10}).endswith(
        "no cell finished yet; running or queued: 2 model(s), 10 cell(s)"
    )


# ---------------------------------------------------------------- messages


def test_messages_name_the_real_problem(user, capsys):
    model = user / "m"
    model.mkdir()
    (model / "model.json").write_text("{}")
    loop = [*LOOP[:2], "qp-mpc", "--days", "1", "--scenario", "winter_household", "--json", "k.json"]
    refused([*loop, "--rc", "m"], capsys, "--rc m is a directory", "export-rc --model m")
    refused([*LOOP, "--scenario", "winter_household", "--json", "k.json", "--buildings", "3",
             "--plot", "p.png"], capsys, "--plot does not apply", "trajectory figure shows one building")
    line = refused([*LOOP[:2], "cem", "--days", "1", "--scenario", "winter_household", "--json",
                    "k.json"], capsys, "--model MODEL_DIR", "pinn-mpc train --data data.csv --out")
    assert "physnet" not in line
    (user / "myscen").write_text((user / "s.toml").read_text())
    refused([*LOOP, "--scenario", "myscen", "--json", "k.json"], capsys,
            "'myscen' is a file, but scenario files end in .toml", "rename it myscen.toml")
    assert not (user / "k.json").exists()


def test_an_eta_of_the_wrong_sign_is_named_as_such():
    data = generate(get_scenario("paper_household"), days=3, seed=0, policy="random-level")
    with pytest.raises(InputError, match=r"eta = -2.5 says the actuator cools, but in the data more power warms"):
        identify_rc(data, eta=-2.5)


@pytest.mark.parametrize("arch", ["auto", "parx", "arx", "hybrid", "mlp", "physnet"])
def test_every_model_on_cooling_data_without_eta_names_the_eta(tmp_path, capsys, arch):
    """train --arch parx on cold_storage data without --eta said to vary the power, while
    auto said --eta -2.5, and arx and the networks trained on the wrong sign with a warning
    that no RC could be identified (issue 46): every architecture names the eta."""
    data = tmp_path / "cold.csv"
    assert main(["simulate", "--scenario", "cold_storage", "--days", "7", "--seed", "0", "--out", str(data)]) == 0
    capsys.readouterr()
    refused(["train", "--arch", arch, "--data", str(data), "--out", str(tmp_path / "m")], capsys,
            "eta = 1 says the actuator heats, but in the data more power cools the room",
            "for a cooling machine give --eta -COP, e.g. --eta -2.5")
    assert not (tmp_path / "m").exists()


# ---------------------------------------------------------------- EnergyPlus scenario files

needs_energyplus = pytest.mark.skipif(not energyplus_available(), reason="EnergyPlus is not installed")


def _eplus_file(folder: Path, name: str = "ep.toml", **plant: str) -> Path:
    """eplus_small_office as a file without [weather] (the plant's EPW gives it), with the
    plant's ``building`` or ``weather`` replaced."""
    text = re.sub(r"(?s)\n\[weather\].*?\n(?=\[price\])", "\n",
                  scenario_to_toml(get_scenario("eplus_small_office")))
    for key, value in plant.items():
        text, n = re.subn(rf"(?m)^{key} = .*$", f'{key} = "{value}"', text, count=1)
        assert n == 1, key
    (folder / name).write_text(text, encoding="utf-8")
    return folder / name


@pytest.fixture
def office(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A user's folder: a copy of the small office's IDF and of Chicago's EPW, and a scenario
    file running them."""
    monkeypatch.chdir(tmp_path)
    shutil.copy(bundled_buildings()["small_office"], tmp_path / "office.idf")
    shutil.copy(bundled_weather()["usa_il_chicago"], tmp_path / "chicago.epw")
    _eplus_file(tmp_path, building="office.idf", weather="chicago.epw")
    return tmp_path


@needs_energyplus
@pytest.mark.slow
def test_identify_on_the_energyplus_office_warns_that_a_2r2c_does_not_fit(tmp_path, capsys):
    """identify on the EnergyPlus office wrote an RC whose rmse is 1.3-1.7 C without a word
    (issue 46). With its unmeasured gains identified as a schedule the office fits within 1 C
    and nothing is said; where the data hold gains that explain nothing (an ``I_g`` column, so
    no schedule) the fit is poor again and the warning says what to check and what fits."""
    data, rc = tmp_path / "office.csv", tmp_path / "rc.json"
    assert main(["simulate", "--scenario", "eplus_small_office", "--days", "14", "--seed", "0",
                 "--out", str(data)]) == 0
    capsys.readouterr()
    assert main(["identify", "--data", str(data), "--out", str(rc)]) == 0
    written = json.loads(rc.read_text())
    assert written["fit"]["rmse_c"] < 1.0 and len(written["unmeasured_gains_W"]) == 24
    out, err = capsys.readouterr()
    assert "reproduces the data" not in err and "kW on a workday" in out
    frame = pd.read_csv(data)
    frame["I_g"] = 100.0 * (np.arange(len(frame)) % 2)  # gains that explain nothing
    frame.to_csv(data, index=False)
    assert main(["identify", "--data", str(data), "--out", str(rc), "--force"]) == 0
    rmse = json.loads(rc.read_text())["fit"]["rmse_c"]
    err = capsys.readouterr().err
    assert rmse > 1.0 and f"reproduces the data with an rmse of {rmse:.2f} C, above 1 C" in err
    assert "heating power delivered (--columns)" in err and "then qp-mpc or cem over it" in err


EPLUS_DATA_LOSS = [
    pytest.param(["simulate", "--scenario", "ep.toml", "--days", "1", "--out", "office.idf"],
                 ["--out office.idf", "simulation.plant.building"], id="simulate-out-is-its-idf"),
    pytest.param([*LOOP, "--scenario", "ep.toml", "--json", "./office.idf"],
                 ["--json office.idf", "simulation.plant.building"], id="closed-loop-json-is-its-idf"),
    pytest.param([*LOOP, "--scenario", "ep.toml", "--json", "k.json", "--csv", "chicago.epw"],
                 ["--csv chicago.epw", "is the same file as the input"], id="closed-loop-csv-is-its-epw"),
    pytest.param(["compare", "--scenario", "ep.toml", "--quick", "--json", "office.idf"],
                 ["--json office.idf", "simulation.plant.building"], id="compare-json-is-its-idf"),
]


@needs_energyplus
@pytest.mark.parametrize(("argv", "fragments"), EPLUS_DATA_LOSS)
def test_no_output_replaces_an_energyplus_model_or_weather_file(office, capsys, argv, fragments):
    before = checksums(office)
    refused(argv, capsys, *fragments)
    assert checksums(office) == before


@needs_energyplus
def test_an_energyplus_files_model_and_weather_are_in_its_content(office):
    inputs = {k: p.resolve() for k, p in scenario_inputs("ep.toml").items()}
    assert inputs["simulation.plant.building"] == office / "office.idf"
    assert inputs["simulation.plant.weather"] == office / "chicago.epw"
    before = scenario_digest("ep.toml")
    with open(office / "office.idf", "a") as f:
        f.write("\n! an edit: the building is another one\n")
    os.utime(office / "ep.toml", ns=(1, 1))  # the digest is computed once per version of the file
    assert scenario_digest("ep.toml") != before  # a sweep runs the edited building anew


@needs_energyplus
@pytest.mark.parametrize(
    ("weather", "message"),
    [
        ("chicago", "simulation.plant.weather: EnergyPlus weather 'chicago' is neither a bundled "
                    "weather file (usa_az_phoenix"),
        ("nothere.epw", "simulation.plant.weather: EnergyPlus weather 'nothere.epw' is neither"),
        ("garbage.epw", "garbage.epw is not an EPW file: its first line is 'not,an,epw', where an "
                        "EPW's is its LOCATION header"),
    ],
)
def test_a_bad_energyplus_weather_is_named_as_the_plants(office, weather, message):
    (office / "garbage.epw").write_text("not,an,epw\n1,2,3\n")
    with pytest.raises(InputError, match=re.escape(message)):
        load_scenario_file(_eplus_file(office, "w.toml", weather=weather))


@needs_energyplus
@pytest.mark.parametrize("building", ["small_ofice", "nothere.idf"])
def test_a_bad_energyplus_building_is_refused_when_the_file_is_read(office, building):
    """A misspelled building was accepted by `scenario show` and refused ~10 s into a run."""
    with pytest.raises(InputError, match=re.escape(
            f"simulation.plant.building: EnergyPlus building {building!r} is neither a bundled")):
        load_scenario_file(_eplus_file(office, "b.toml", building=building))


@needs_energyplus
def test_a_heater_in_the_wrong_unit_is_refused_before_energyplus_runs(office):
    """1e12 W (u_max_w left to follow it) ran into EnergyPlus's 'temperature of 1136702 C ...
    malformed zone' after a minute."""
    path = _eplus_file(office, "h.toml")
    path.write_text(re.sub(r"(?m)^u_max_w = .*\n", "", path.read_text()).replace(
        "heater_w = 25000.0", "heater_w = 1e12"))
    with pytest.raises(InputError, match=re.escape(
            "simulation.plant.heater_w = 1e+12 W is above the plausible 1e+08 W")):
        load_scenario_file(path)


@needs_energyplus
def test_an_idf_without_objects_is_named_as_an_idf(office):
    (office / "garbage.idf").write_text("this is not an idf {{{\n")
    with pytest.raises(InputError, match=r"garbage.idf: EnergyPlus read no objects from it: not an IDF model"):
        prepare_model(str(office / "garbage.idf"))


# ---------------------------------------------------------------- fleets


def _fleet_csv(folder: Path, name: str = "fleet.csv", *, n: int = 2, days: int = 1,
               sidecar: dict | None = None) -> Path:
    scenario = get_scenario("winter_household")
    fleet = draw_fleet(scenario.sim.params, n, spread=0.2, rng=np.random.default_rng(3))
    path = folder / name
    write_timeseries(generate(scenario, days=days, seed=0, n_buildings=n, fleet=fleet), path)
    if sidecar is not None:
        body = {"spread": 0.2, "params": [dataclasses.asdict(p) for p in fleet], **sidecar}
        atomic_write_json(fleet_params_path(path), body)
    return path


def test_simulate_never_leaves_a_stale_fleet_file(tmp_path, capsys, monkeypatch):
    """One building over a fleet's data is refused (its parameters file would describe other
    data); a fleet without --spread writes its own (every building the scenario's)."""
    monkeypatch.chdir(tmp_path)
    _fleet_csv(tmp_path, sidecar={})
    before = checksums(tmp_path)
    refused(["simulate", "--scenario", "winter_household", "--days", "1",
             "--out", "fleet.csv"], capsys, "fleet.fleet.json next to it holds the buildings of an "
            "earlier `simulate --buildings N` run", "add --buildings N")
    assert checksums(tmp_path) == before
    assert main(["simulate", "--scenario", "winter_household", "--days", "1", "--buildings", "3",
                 "--out", "fleet.csv", "--force"]) == 0  # the old fleet's data and parameters replaced
    stored = json.loads((tmp_path / "fleet.fleet.json").read_text())
    nominal = get_scenario("winter_household").sim.params.to_dict()
    assert stored["spread"] == 0.0 and stored["params"] == [nominal] * 3
    assert stored["data_sha256"] == file_sha256(tmp_path / "fleet.csv")


@pytest.mark.parametrize(
    ("sidecar", "n", "message"),
    [
        ({"data_sha256": "0" * 64}, 2, "fleet.fleet.json describes the buildings of another fleet.csv"),
        ({}, 3, "fleet.fleet.json holds 2 buildings' parameters, fleet.csv 3 buildings"),
    ],
    ids=["other-data", "other-count"],
)
def test_per_building_training_refuses_a_fleet_file_of_other_data(tmp_path, capsys, monkeypatch,
                                                                  sidecar, n, message):
    monkeypatch.chdir(tmp_path)
    _fleet_csv(tmp_path, n=n)
    if n != 2:  # the parameters of a 2-building fleet next to 3 buildings' data
        _fleet_csv(tmp_path, "two.csv", sidecar=sidecar)
        os.replace(tmp_path / "two.fleet.json", tmp_path / "fleet.fleet.json")
    else:
        _fleet_csv(tmp_path, sidecar=sidecar)
    before = checksums(tmp_path)
    refused(["train", "--data", "fleet.csv", "--per-building", "--seeds", "1", "--epochs", "1",
             "--out", "m"], capsys, message)
    assert checksums(tmp_path) == before


def test_simulate_spread_records_its_data_for_training(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--scenario", "winter_household", "--days", "1", "--buildings", "2",
                 "--spread", "0.2", "--out", "f.csv"]) == 0
    assert capsys.readouterr().out.strip().endswith("; wrote their parameters to f.fleet.json")
    assert json.loads((tmp_path / "f.fleet.json").read_text())["data_sha256"] == file_sha256(tmp_path / "f.csv")


@pytest.mark.parametrize(
    ("stored", "message"),
    [
        ({"data_sha256": {"0": "x", "1": "y"}}, "holds models trained on other data (building 0's rows "
                                                "differ, and 1 more)"),
        ({}, "its fleet.json records no data digests"),
        ({"config": {"epochs": 3}}, "holds models trained otherwise (epochs 3 -> 2)"),
    ],
    ids=["other-data", "no-digests", "other-settings"],
)
def test_per_building_training_never_resumes_a_foreign_directory(tmp_path, stored, message):
    frames = read_fleet_timeseries(_fleet_csv(tmp_path))
    config = TrainConfig(n_seeds=1, epochs=2)
    settings = json.loads(json.dumps({k: v for k, v in dataclasses.asdict(config).items() if k != "prior"}))
    mine = {"arch": "hybrid", "config": settings, "buildings": [0, 1],
            "data_sha256": {str(b): frame_digest(f) for b, f in frames.items()}}
    out = tmp_path / "models"
    (out / "buildings" / "b00000").mkdir(parents=True)
    (out / "buildings" / "b00000" / "model.json").write_text("{}")
    record = {**mine, **stored, "config": {**settings, **stored.get("config", {})}}
    if not stored:
        del record["data_sha256"]
    atomic_write_json(out / "fleet.json", record)
    before = checksums(out)
    with pytest.raises(InputError, match=re.escape(message)):
        train_per_building(frames, out, arch="hybrid", config=config, workers=1)
    assert checksums(out) == before


@pytest.mark.parametrize("target", ["fleet.json", "buildings/b00001/model.json",
                                    "buildings/b00000/weights.safetensors"])
def test_no_fleet_output_replaces_a_per_building_model(tmp_path, capsys, monkeypatch, target):
    monkeypatch.chdir(tmp_path)
    for b in (0, 1):
        (tmp_path / "m" / "buildings" / f"b{b:05d}").mkdir(parents=True)
        for name in ("model.json", "weights.safetensors"):
            (tmp_path / "m" / "buildings" / f"b{b:05d}" / name).write_text(f"{b} {name}")
    (tmp_path / "m" / "fleet.json").write_text('{"buildings": [0, 1]}')
    before = checksums(tmp_path)
    refused(["closed-loop", "--scenario", "winter_household", "--controller", "cem", "--days", "1",
             "--buildings", "2", "--model", "m", "--json", f"m/{target}"], capsys,
            f"--json m/{target} is the same file as the input --model")
    assert checksums(tmp_path) == before


@pytest.mark.parametrize("controller", ["cem", "random-shooting"])
def test_per_building_models_are_not_one_model(tmp_path, capsys, monkeypatch, controller):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "m" / "buildings" / "b00000").mkdir(parents=True)
    (tmp_path / "m" / "fleet.json").write_text('{"buildings": [0]}')
    refused(["closed-loop", "--scenario", "winter_household", "--controller", controller, "--days",
             "1", "--model", "m", "--json", "k.json"], capsys,
            "--model m holds one model per building (train --per-building), not one model",
            "--buildings N")
    assert not (tmp_path / "k.json").exists()


def test_per_building_models_are_checked_against_the_scenario(tmp_path, capsys, monkeypatch):
    """Models of 10 kW buildings driving 4 kW heat pumps: refused as one model is."""
    monkeypatch.chdir(tmp_path)
    frames = read_fleet_timeseries(_fleet_csv(tmp_path, days=2, sidecar={}))
    config = TrainConfig(n_seeds=1, epochs=1)
    (tmp_path / "m" / "buildings").mkdir(parents=True)
    for b, frame in frames.items():
        save_model(train_model(frame, arch="hybrid", config=config, progress=False),
                   building_model_dir(tmp_path / "m", b))
    params = json.loads((tmp_path / "fleet.fleet.json").read_text())["params"]
    atomic_write_json(tmp_path / "m" / "fleet.json", {"buildings": [0, 1], "params": params})
    refused(["closed-loop", "--scenario", "heat_pump_household", "--controller", "cem", "--days",
             "1", "--buildings", "2", "--model", "m", "--json", "k.json"], capsys,
            "--model m, building 0: the model was trained on powers up to",
            "'heat_pump_household''s actuator gives at most 4000 W")
    assert not (tmp_path / "k.json").exists()


@pytest.fixture(scope="module")
def identified_rcs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """rc.json files `identify` writes from 4 days of three scenarios' data."""
    folder = tmp_path_factory.mktemp("rcs")
    for name in ("winter_household", "paper_household", "heat_pump_household"):
        assert main(["simulate", "--scenario", name, "--days", "4", "--seed", "1",
                     "--out", str(folder / f"{name}.csv")]) == 0
        assert main(["identify", "--data", str(folder / f"{name}.csv"),
                     "--out", str(folder / f"{name}.json")]) == 0
    return folder


def test_identify_records_the_power_range_and_actuator_of_its_data(identified_rcs):
    data = pd.read_csv(identified_rcs / "winter_household.csv")
    rc = json.loads((identified_rcs / "winter_household.json").read_text())
    assert rc["power_range_w"] == pytest.approx([data["u_phys"].min(), data["u_phys"].max()])
    assert rc["heat_pump_data"] is False
    assert json.loads((identified_rcs / "heat_pump_household.json").read_text())["heat_pump_data"] is True


@pytest.mark.parametrize(
    ("rc", "scenario", "fragments"),
    [
        ("winter_household", "paper_household",
         ("the RC of winter_household.json was identified on powers up to 9", "at most 5000 W")),
        ("heat_pump_household", "winter_household",
         ("the RC of heat_pump_household.json was identified on heat-pump data",)),
    ],
)
def test_an_rc_identified_on_another_actuator_is_refused(identified_rcs, capsys, tmp_path, rc, scenario, fragments):
    """qp-mpc with an rc.json of another building's data ran without a word (a 5 kW household's
    RC on the 25 kW office, the second probe's E38)."""
    refused(["closed-loop", "--scenario", scenario, "--controller", "qp-mpc", "--days", "1",
             "--rc", str(identified_rcs / f"{rc}.json"), "--json", str(tmp_path / "k.json")],
            capsys, *fragments)
    assert not (tmp_path / "k.json").exists()


def test_an_rc_of_a_smaller_actuator_is_warned_about(identified_rcs, capsys, tmp_path):
    from scenarios.running.factory import check_rc_fits

    notes = check_rc_fits(identified_rcs / "paper_household.json", get_scenario("eplus_small_office"))
    assert len(notes) == 1 and "data reach 4" in notes[0] and "under half the scenario's 25000 W" in notes[0]
    assert check_rc_fits(identified_rcs / "winter_household.json", get_scenario("winter_household")) == []
    old = json.loads((identified_rcs / "winter_household.json").read_text())
    del old["power_range_w"], old["heat_pump_data"]  # an rc.json written before they were recorded
    (tmp_path / "old.json").write_text(json.dumps(old))
    assert check_rc_fits(tmp_path / "old.json", get_scenario("paper_household")) == []


@pytest.fixture(scope="module")
def careless(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """simulate's output converted with pandas as a careless user would (issue 46): every
    temperature column to Fahrenheit or kelvin, the power columns to kW."""
    folder = tmp_path_factory.mktemp("careless")
    assert main(["simulate", "--scenario", "winter_household", "--days", "7", "--seed", "0",
                 "--out", str(folder / "c.csv")]) == 0
    data = pd.read_csv(folder / "c.csv")
    temps = ["T_r", "T_m", "T_a", "T_min", "T_max"]
    data.assign(**{c: data[c] * 1.8 + 32 for c in temps}).to_csv(folder / "f.csv", index=False)
    data.assign(**{c: data[c] + 273.15 for c in temps}).to_csv(folder / "k.csv", index=False)
    data.assign(u=data["u"] / 1000, u_phys=data["u_phys"] / 1000).to_csv(folder / "kw.csv", index=False)
    return folder


@pytest.mark.parametrize(("data", "unit", "fix"), [
    ("f.csv", "it looks like Fahrenheit", "C = (F - 32) / 1.8"),
    ("k.csv", "a temperature in kelvin", "C = K - 273.15"),
])
@pytest.mark.parametrize("command", [
    ["identify", "--out", "rc.json"],
    ["train", "--arch", "arx", "--out", "m"],
    ["evaluate", "--model", "m", "--json", "e.json"],
])
def test_temperatures_in_another_unit_are_refused_by_every_command(careless, capsys, monkeypatch, tmp_path,
                                                                   data, unit, fix, command):
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--arch", "arx", "--data", str(careless / "c.csv"), "--out", "m"]) == 0
    before = checksums(tmp_path)
    refused([*command, "--data", str(careless / data)], capsys, "column 'T_r' has a median of", unit, fix)
    assert checksums(tmp_path) == before


def test_power_in_kw_is_warned_about_and_its_models_refused_on_the_scenario(careless, capsys, monkeypatch, tmp_path):
    """identify and train on kW warn naming kW; qp-mpc over that RC and cem over that model
    heated 0.00 kWh a day with the model 'trusted in 48 of 48': refused, naming kW."""
    monkeypatch.chdir(tmp_path)
    for command in (["identify", "--out", "rc.json"], ["train", "--arch", "arx", "--out", "m"]):
        assert main([*command, "--data", str(careless / "kw.csv")]) == 0
        assert "or power in kW? Models and controllers take watts" in capsys.readouterr().err
    loop = ["closed-loop", "--scenario", "winter_household", "--days", "1", "--json", "k.json"]
    for given, made in ((["--controller", "qp-mpc", "--rc", "rc.json"], "identify"),
                        (["--controller", "cem", "--model", "m"], "train")):
        refused([*loop, *given], capsys, "a thousand times more: the data's power was in kW",
                f"convert its power columns to W (x 1000) and {made} again")
    assert not (tmp_path / "k.json").exists()


def test_a_model_trained_on_gains_the_controllers_are_not_given_is_refused(identified_rcs, tmp_path):
    """A closed-loop record of an EnergyPlus building carries the internal gains the plant had,
    which its controllers are never given (unmeasured): a model or an RC fitted on such a
    record would plan with 0 W of them. Refused where the building has gains its controllers
    are not given; taken where they are given, where the building has none, and once the
    data's I_g column is dropped."""
    from pinn_mpc import fitted
    from scenarios.running.datagen import generate
    from scenarios.running.factory import (
        FitChecks,
        check_data_fits,
        check_model_fits,
        check_rc_fits,
    )

    data = generate(get_scenario("winter_household"), days=3, seed=0, policy="random-level")
    assert data["I_g"].max() > 0
    with_gains = fitted.fit(data, arch="arx", config=TrainConfig()).model
    office = get_scenario("eplus_small_office")
    assert office.gains_hidden and not get_scenario("paper_household").gains_hidden
    with pytest.raises(InputError, match=r"the model was trained on internal gains \(I_g up to 0\.\d+ kW\), "
                       r"but the controllers of scenario 'eplus_small_office' are not given its internal "
                       r"gains \(they are unmeasured\).* drop the data's I_g column and train again"):
        check_model_fits(with_gains, office)
    check_model_fits(with_gains, get_scenario("winter_household"))  # its own building: given them
    # A building without gains (5 kW: the power's limit widened, the gains alone judged).
    check_model_fits(with_gains, get_scenario("paper_household"), FitChecks(power_slack=2.5))
    without = data.drop(columns="I_g")
    without.attrs = dict(data.attrs)
    check_model_fits(fitted.fit(without, arch="arx", config=TrainConfig()).model, office)
    with pytest.raises(InputError, match=r"the RC of winter_household.json was identified on measured "
                       r"internal gains \(an I_g column\).* drop the data's I_g column and identify again"):
        check_rc_fits(identified_rcs / "winter_household.json", office)
    with pytest.raises(InputError, match=r"the data at hand was recorded with internal gains .* not given"):
        check_data_fits(data, office)  # an online run's data at hand: its refits would learn them
    check_data_fits(without, office)
