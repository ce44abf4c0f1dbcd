"""Errors by cause (issue 42): a Python caller's misuse of the API is a plain ValueError, never
an InputError (which the command line reports as the user's to fix, exit 2); a value the
user gives through a file stays an InputError naming the key; a library message names the
setting, and only the command line names the flag."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controllers.base import ControlSpec
from controllers.coordination import DualAscent
from controllers.planners import CEMPlanner
from controllers.thermostat import Thermostat
from controllers.trust import TrustSettings
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InputError, setting
from pinn_mpc.observer import KalmanObserver
from pinn_mpc.physics import PAPER_HOUSEHOLD, discretise
from pinn_mpc.simulator import draw_fleet
from pinn_mpc.training import TrainConfig
from scenarios.experiments.compare import CompareSettings
from scenarios.fleets.aggregator import parse_cap_window
from scenarios.inputs.exogenous import ComfortSchedule
from scenarios.inputs.registry import check_seed
from scenarios.inputs.scenario_file import get_scenario, scenario_to_toml
from scenarios.plants.boptest import BoptestRun
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.datagen import generate

HEATER = ActuatorSpec(upper_w=5000.0)
SPEC = ControlSpec(actuators=(HEATER,))

#: Checks no flag and no file reaches: (what is called, what the message says).
API_CHECKS = {
    "ControlSpec": (lambda: ControlSpec(actuators=(HEATER,), horizon_steps=0), r"ControlSpec\.horizon_steps must be >= 1, got 0"),
    "CEMPlanner": (lambda: CEMPlanner(lower=0.0, upper=1.0, n_iters=0), r"CEMPlanner\.n_iters must be >= 1"),
    "Thermostat": (lambda: Thermostat(SPEC, offset_fraction=0.9), r"offset_fraction must lie in \[0, 0\.5\]"),
    "TrustSettings": (lambda: TrustSettings(filter_gain=0.0), r"TrustSettings\.filter_gain must lie in \(0, 1\]"),
    "DualAscent": (lambda: DualAscent(iterations=0), r"DualAscent\.iterations must be an integer in 1\.\.100"),
    "KalmanObserver": (lambda: KalmanObserver(PAPER_HOUSEHOLD, 1800.0, n_batch=0), r"n_batch must be >= 1"),
    "discretise": (lambda: discretise(PAPER_HOUSEHOLD, 0.0), r"dt_s must be a positive number of seconds"),
    "draw_fleet": (
        lambda: draw_fleet(PAPER_HOUSEHOLD, 0, spread=0.2, rng=np.random.default_rng(0)),
        r"n_buildings must be a whole number >= 1, got 0",
    ),
    "TrainConfig": (lambda: TrainConfig(depth=5000), r"TrainConfig\.depth must be 1 \.\. 1008, got 5000"),
    "check_seed": (lambda: check_seed(-1), r"seed must be a non-negative whole number, got -1"),
    "generate": (
        lambda: generate(get_scenario("paper_household"), days=1, seed=0, policy="bangbang"),
        r"unknown policy 'bangbang'",
    ),
    "run_closed_loop": (
        lambda: run_closed_loop(get_scenario("paper_household"), Thermostat(SPEC), days=0, seed=0),
        r"closed loop: days must be >= 1, got 0",
    ),
    "CompareSettings": (
        lambda: CompareSettings(train_days=7, test_days=1, seed=0, policy="bangbang"),
        r"compare: unknown policy 'bangbang'",
    ),
    "BoptestRun": (lambda: BoptestRun(days=0.0), r"a BOPTEST run of 0 days"),
    "ComfortSchedule": (
        lambda: ComfortSchedule(day_min_c=22.0, day_max_c=20.0, night_min_c=16.0, night_max_c=24.0),
        r"ComfortSchedule\.day_min_c \(22\.0\) must be below day_max_c \(20\.0\)",
    ),
}


@pytest.mark.parametrize("name", list(API_CHECKS))
def test_a_python_callers_misuse_is_a_plain_value_error(name: str) -> None:
    call, message = API_CHECKS[name]
    with pytest.raises(ValueError, match=message) as caught:
        call()
    assert type(caught.value) is ValueError, f"{name}: {type(caught.value).__name__}"


def test_a_config_the_scenario_file_builds_is_refused_naming_the_key(tmp_path: Path) -> None:
    """The comfort band's ValueError (a Python caller's) is the file's InputError, with the file
    and the key instead of the class."""
    text = scenario_to_toml(get_scenario("winter_household")).replace("day_min_c = 20.0", "day_min_c = 25.0", 1)
    assert "day_min_c = 25.0" in text
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(InputError) as caught:
        get_scenario(str(path))
    assert str(caught.value) == (
        f"{path}: comfort.day_min_c (25.0) must be below day_max_c (22.0): the comfort band "
        "needs min < max"
    )


def test_a_message_names_the_setting_and_the_command_line_its_flag() -> None:
    """Marked with :func:`setting`: a Python caller reads the setting's name, the command line
    (``InputError.text`` with its flags) the flag; a setting it has no flag for keeps its name."""
    with pytest.raises(InputError) as caught:
        parse_cap_window("17-19")
    exc = caught.value
    assert str(exc) == "cap_window '17-19' is not HH:MM-HH:MM (e.g. 17:00-19:00)"
    assert exc.text({"cap_window": "--cap-window"}) == (
        "--cap-window '17-19' is not HH:MM-HH:MM (e.g. 17:00-19:00)"
    )
    assert exc.text({}) == str(exc) and "\x1f" in exc.marked
    quoted = InputError(f"x.csv: {setting('data', python='the path')} and {exc.marked}")
    assert str(quoted) == "x.csv: the path and cap_window '17-19' is not HH:MM-HH:MM (e.g. 17:00-19:00)"
    assert quoted.text({"data": "--data", "cap_window": "--cap-window"}).startswith(
        "x.csv: --data and --cap-window '17-19'"
    )


def test_no_library_message_names_a_flag() -> None:
    """The flags are the command line's: no code line of the three packages (docstrings and
    comments aside) names one of them, but the first comment of an exported scenario file,
    which stays as it was: a sweep's scenario digest is that text's."""
    import benchmarks.seams as seams

    root = Path(__file__).resolve().parents[1]
    assert seams.flag_lines(root) == [
        "scenarios/inputs/scenario_file.py: doc.add(tomlkit.comment(f\"pinn-mpc scenario "
        "{scenario.name!r}: use it as --scenario FILE.toml\"))"
    ]
