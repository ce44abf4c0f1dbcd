"""Training and test days are disjoint: the weather parts of every scenario (issue 8, case 3).

``simulate`` draws from the training part, ``closed-loop`` from the test part (warm-up day and
forecast lead included), ``compare`` and ``reproduce`` one from each. The exhaustive checks call
``Scenario.exogenous`` with the arguments those commands pass; ``test_commands_use_these_draws``
ties the commands themselves to them.
"""

import json

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.errors import InputError
from pinn_mpc_cli.cli import build_parser, main
from scenarios.choices import WEATHER_PARTS
from scenarios.experiments.compare import CompareSettings
from scenarios.experiments.reproduce import ReproduceConfig
from scenarios.inputs.exogenous import BASE_YEAR, TMY3Weather
from scenarios.inputs.registry import scenario_names
from scenarios.inputs.scenario_file import get_scenario

SEEDS = range(10)
TMY3_SCENARIOS = ("winter_household", "cold_storage")


def _training_frame(scenario, *, days, seed):
    """The exogenous frame of ``simulate`` / ``generate`` (training part, no lead)."""
    return scenario.exogenous(days=days, seed=seed, part="train")


def _test_frame(scenario, *, days, seed):
    """The exogenous frame of ``run_closed_loop``: one warm-up day, a horizon of lead rows."""
    return scenario.exogenous(
        days=days + 1, seed=seed, part="test", lead_steps=scenario.horizon_steps
    )


def _calendar_days(scenario, frame):
    """Days of the typical year (MM-DD) for TMY3 weather, dates for synthetic weather."""
    times = pd.DatetimeIndex(frame["time"])
    if isinstance(scenario.weather, TMY3Weather):
        return set(times.strftime("%m-%d"))
    return set(times.strftime("%Y-%m-%d"))


def _union(frames, scenario):
    return set().union(*(_calendar_days(scenario, f) for f in frames))


@pytest.mark.parametrize("name", ["paper_household", *TMY3_SCENARIOS])
@pytest.mark.parametrize(("train_days", "test_days"), [(30, 30), (120, 5)])
def test_simulate_and_closed_loop_never_share_a_day(name, train_days, test_days):
    """Any training seed against any test seed, 0-9: ``simulate --days 30`` (and the 120 days
    of the benchmarks) against ``closed-loop --days 30`` (and 5)."""
    scenario = get_scenario(name)
    training = [_training_frame(scenario, days=train_days, seed=s) for s in SEEDS]
    test = [_test_frame(scenario, days=test_days, seed=s) for s in SEEDS]
    assert all(len(f) == train_days * 48 for f in training)
    assert all(len(f) == (test_days + 2) * 48 for f in test)
    assert _union(training, scenario).isdisjoint(_union(test, scenario))
    # The seeds still vary the weather within each part.
    assert len({f["T_a"].iloc[0] for f in test}) > 1


@pytest.mark.parametrize("name", scenario_names())
@pytest.mark.parametrize("quick", [False, True])
def test_compare_draws_never_share_a_day(name, quick):
    settings = [
        CompareSettings.for_run(train_days=60, days=5, seed=s, quick=quick) for s in SEEDS
    ]
    scenario = get_scenario(name)
    training = [_training_frame(scenario, days=c.train_days, seed=c.seed) for c in settings]
    test = [_test_frame(scenario, days=c.test_days, seed=c.test_seed) for c in settings]
    assert _union(training, scenario).isdisjoint(_union(test, scenario))


def test_reproduce_draws_never_share_a_day():
    config = ReproduceConfig()
    scenario = get_scenario(config.scenario)
    pool = _training_frame(scenario, days=max(config.sizes()), seed=config.train_seed)
    test = scenario.exogenous(days=config.test_days, seed=config.test_seed, part="test")
    assert _calendar_days(scenario, pool).isdisjoint(_calendar_days(scenario, test))


@pytest.mark.parametrize("name", TMY3_SCENARIOS)
def test_tmy3_parts_are_the_stated_blocks_of_the_season(name):
    """The parts are the stated blocks: the test block, and the window's days before it for
    training."""
    scenario = get_scenario(name)
    weather = scenario.weather
    season = pd.Timestamp(f"{BASE_YEAR + 1}-{weather.window_start}")
    test_start = pd.Timestamp(f"{BASE_YEAR + 1}-{weather.test_start}")
    if test_start < season:
        test_start += pd.Timedelta(days=365)
    core = (test_start - season).days
    expected_train = pd.date_range(season, periods=core, freq="D").strftime("%m-%d")
    expected_test = pd.date_range(test_start, periods=weather.test_days, freq="D").strftime("%m-%d")
    # A run as long as its part has one place: exactly the part.
    training = _calendar_days(scenario, _training_frame(scenario, days=core, seed=0))
    test = _calendar_days(scenario, scenario.exogenous(days=weather.test_days, seed=0, part="test"))
    assert training == set(expected_train)
    assert test == set(expected_test)
    # Shorter runs stay inside.
    for seed in SEEDS:
        assert _calendar_days(scenario, _training_frame(scenario, days=3, seed=seed)) <= training
        assert _calendar_days(scenario, _test_frame(scenario, days=3, seed=seed)) <= test
    assert core == weather.training_core_days and core + weather.test_days <= weather.window_days
    # Stated in the description: first and last day of each part.
    for days in (expected_train, expected_test):
        first, last = (pd.Timestamp(f"{BASE_YEAR}-{d}") for d in (days[0], days[-1]))
        assert f"{first:%b} {first.day} - {last:%b} {last.day}" in scenario.description
    assert scenario.description.endswith(scenario.weather_split)


@pytest.mark.parametrize("name", TMY3_SCENARIOS)
def test_a_long_training_run_extends_away_from_the_test_days(name):
    scenario = get_scenario(name)
    weather = scenario.weather
    longest = 365 - weather.test_days
    frame = _training_frame(scenario, days=longest, seed=0)
    times = pd.DatetimeIndex(frame["time"])
    last_training_day = pd.Timestamp(f"{BASE_YEAR}-{weather.test_start}") - pd.Timedelta(days=1)
    assert f"{times[-1]:%m-%d}" == f"{last_training_day:%m-%d}"
    assert len(_calendar_days(scenario, frame)) == longest  # no day twice: no wrap-around
    test = _union([_test_frame(scenario, days=1, seed=s) for s in range(50)], scenario)
    assert _calendar_days(scenario, frame).isdisjoint(test)
    with pytest.raises(InputError, match=rf"a run of {longest + 1} days .* training weather"):
        _training_frame(scenario, days=longest + 1, seed=0)


def test_runs_that_do_not_fit_their_part_are_refused():
    winter = get_scenario("winter_household")
    fits = winter.weather.test_days - 2  # with the warm-up day and the forecast lead
    frame = _test_frame(winter, days=fits, seed=3)
    assert f"{frame['time'].iloc[0]:%m-%d}" == "02-01"
    with pytest.raises(InputError, match=(
        r"scenario 'winter_household': a run of 60 days \(warm-up and forecast lead rows, if "
        r"any, included\) does not fit in the test weather, the 59 days Feb 1 - Mar 31; use "
        r"fewer days, or draw from the whole window, training and test days mixed "
        r"\(weather_part whole\)$"
    )):
        _test_frame(winter, days=fits + 1, seed=3)
    paper = get_scenario("paper_household")
    longest = paper.weather.longest_training_days
    assert len(_training_frame(paper, days=longest, seed=0)) == longest * 48
    with pytest.raises(InputError, match="does not fit in the training weather"):
        _training_frame(paper, days=longest + 1, seed=0)


@pytest.mark.parametrize("part", ["test", "whole"])
def test_a_run_past_the_last_timestamp_is_refused(part):
    """Without a part's bound, 100000 days would overflow pandas' nanosecond timestamps."""
    with pytest.raises(InputError, match=r"a run of 100000 days from 20\d\d-04-01 would end after 2262"):
        get_scenario("paper_household").exogenous(days=100_000, seed=0, part=part)


def test_synthetic_test_days_are_other_dates_and_other_draws():
    """Stationary weather: the test part is the same process, dated from ``test_start`` and
    drawn from its own streams, so the same seed does not repeat the training weather."""
    scenario = get_scenario("paper_household")
    training = _training_frame(scenario, days=5, seed=0)
    test = scenario.exogenous(days=5, seed=0, part="test")
    assert test["time"].iloc[0] == pd.Timestamp(scenario.weather.test_start)
    assert not np.allclose(test["T_a"], training["T_a"])
    # Same process: same time of day, same daily mean temperature up to the draws.
    assert (test["time"].dt.hour == training["time"].dt.hour).all()
    means = [scenario.exogenous(days=120, seed=0, part=p)["T_a"].mean() for p in ("train", "test")]
    assert means == pytest.approx([scenario.weather.mean_c] * 2, abs=1.0)


@pytest.mark.parametrize("name", scenario_names())
def test_whole_is_the_draw_from_before_the_split(name):
    """``whole``: the start day uniform among those keeping ``days`` in the window, drawn by
    the weather stream ``[seed, 1]``, labelled in BASE_YEAR; training/test streams untouched."""
    scenario = get_scenario(name)
    weather = scenario.weather
    for seed in SEEDS:
        frame = scenario.exogenous(days=5, seed=seed, part="whole", lead_steps=48)
        first = pd.Timestamp(frame["time"].iloc[0])
        if isinstance(weather, TMY3Weather):
            offset = int(np.random.default_rng([seed, 1]).integers(weather.window_days - 5 + 1))
            start = pd.Timestamp(f"{BASE_YEAR}-{weather.window_start}") + pd.Timedelta(days=offset)
            assert first == pd.Timestamp(f"{BASE_YEAR}-{start:%m-%d}")
        else:
            assert first == pd.Timestamp(weather.start)
            training = scenario.exogenous(days=5, seed=seed, part="train", lead_steps=48)
            pd.testing.assert_frame_equal(frame, training)


@pytest.mark.parametrize(("command", "default"), [("simulate", "train"), ("closed-loop", "test")])
def test_cli_offers_every_weather_part(command, default, capsys):
    required = ["--scenario", "x", "--days", "1", "--out", "o", "--controller", "c", "--json", "j"]
    required = required[:6] if command == "simulate" else required[:4] + required[6:]
    parser = build_parser()
    assert parser.parse_args([command, *required]).weather_part == default
    for part in WEATHER_PARTS:
        assert parser.parse_args([command, *required, "--weather-part", part]).weather_part == part
    with pytest.raises(SystemExit):
        parser.parse_args([command, *required, "--weather-part", "all"])
    assert "invalid choice: 'all' (choose from 'train', 'test', 'whole')" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert f"default: {default})" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("name", scenario_names())
def test_commands_use_these_draws(name, tmp_path, capsys):
    """``simulate`` writes the training frame's days, ``closed-loop`` reports the test frame's."""
    scenario = get_scenario(name)
    csv_path, json_path = tmp_path / "d.csv", tmp_path / "k.json"
    argv = ["--scenario", name, "--days", "3", "--seed", "4"]
    assert main(["simulate", *argv, "--out", str(csv_path)]) == 0
    data = pd.read_csv(csv_path, parse_dates=["time"])
    training = _training_frame(scenario, days=3, seed=4)
    np.testing.assert_array_equal(data["time"].to_numpy(), training["time"].to_numpy())
    if scenario.plant.settings.weather_file is not None:  # EnergyPlus's own reading of the same weather file
        # (its first interval after the warm-up days interpolates from the day before)
        np.testing.assert_allclose(data["T_a"][1:], training["T_a"][1:], atol=2.0)
        assert np.mean(np.abs(data["T_a"] - training["T_a"])) < 0.3
    else:
        np.testing.assert_allclose(data["T_a"], training["T_a"])
    assert "(train weather)" in capsys.readouterr().out
    assert main(["closed-loop", *argv, "--controller", "thermostat", "--json", str(json_path)]) == 0
    kpis = json.loads(json_path.read_text())
    test = _test_frame(scenario, days=3, seed=4)
    times = pd.DatetimeIndex(test["time"])
    assert kpis["weather_part"] == "test"
    assert kpis["weather_days"] == [f"{times[0]:%Y-%m-%d}", f"{times[-1]:%Y-%m-%d}"]
    assert kpis["counted_days"] == [f"{times[48]:%Y-%m-%d}", f"{times[4 * 48 - 1]:%Y-%m-%d}"]
    assert _calendar_days(scenario, training).isdisjoint(_calendar_days(scenario, test))


def test_cli_weather_part_override_and_refusal(tmp_path, capsys):
    json_path = tmp_path / "k.json"
    argv = ["closed-loop", "--scenario", "cold_storage", "--controller", "thermostat",
            "--seed", "0", "--json", str(json_path)]
    assert main([*argv, "--days", "34"]) == 2
    err = capsys.readouterr().err
    assert "a run of 36 days" in err and "--weather-part whole" in err
    assert len(err.strip().splitlines()) == 1 and not json_path.exists()
    assert main([*argv, "--days", "1", "--weather-part", "whole"]) == 0
    kpis = json.loads(json_path.read_text())
    whole = get_scenario("cold_storage").exogenous(days=2, seed=0, part="whole", lead_steps=48)
    assert kpis["weather_part"] == "whole"
    assert kpis["weather_days"][0] == f"{whole['time'].iloc[0]:%Y-%m-%d}"
