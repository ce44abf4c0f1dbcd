"""Errors by cause: bad input is one line and exit status 2; an internal error (or any other
unexpected exception) is a bug in pinn-mpc, one line and exit status 1, the traceback with
``--debug``; the library's warnings go through :mod:`warnings` (capturable, filterable) and the
CLI prints each as one line, as before."""

from __future__ import annotations

import logging
import subprocess
import sys
import warnings
from pathlib import Path

import pandas as pd
import pytest

import scenarios.inputs.scenario_file
from pinn_mpc.errors import InputError, InternalError, PinnMpcWarning, setting, warn
from pinn_mpc_cli.cli import BUG_EXIT, main
from scenarios.inputs.measured import read_series_csv
from scenarios.inputs.scenario_file import get_scenario
from scenarios.inputs.series import ExogenousSeries
from scenarios.running.engine import ClosedLoop

ROOT = Path(__file__).resolve().parents[1]


def _stepped_past_its_end() -> str:
    """A real internal misuse: a closed loop stepped after its series is exhausted."""
    scenario = get_scenario("paper_household")
    exo = ExogenousSeries.from_frame(scenario.exogenous(days=1, seed=0, part="test"))
    loop = ClosedLoop(scenario.sim, exo, spec=scenario.control_spec(), initial_t_r_c=20.0, initial_t_m_c=19.0)
    while True:
        loop.step(0.0)


def test_an_internal_misuse_raises_an_internal_error_not_an_input_error():
    with pytest.raises(InternalError, match="exhausted") as caught:
        _stepped_past_its_end()
    assert not isinstance(caught.value, InputError) and isinstance(caught.value, RuntimeError)


def _inject(monkeypatch: pytest.MonkeyPatch, fault: object) -> None:
    """Make ``pinn-mpc scenario list`` meet ``fault`` (a function that raises) where it asks
    the library for the list."""
    monkeypatch.setattr(scenarios.inputs.scenario_file, "scenario_list", fault)


def test_an_internal_error_is_reported_as_a_bug_exit_1(monkeypatch, capsys):
    _inject(monkeypatch, _stepped_past_its_end)
    assert main(["scenario", "list"]) == BUG_EXIT == 1
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and captured.out == ""
    line = lines[0]
    assert line.startswith("pinn-mpc scenario: internal error (a bug in pinn-mpc, not in your input): ")
    assert "InternalError: ClosedLoop.step: the exogenous series is exhausted" in line
    assert "at engine.py:" in line and "in step" in line  # where it was raised
    assert "report it on the project's issue tracker" in line and "--debug" in line
    assert "Traceback" not in captured.err


def test_debug_adds_the_traceback(monkeypatch, capsys):
    _inject(monkeypatch, _stepped_past_its_end)
    assert main(["--debug", "scenario", "list"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("Traceback (most recent call last):")
    assert "_stepped_past_its_end" in err and "scenarios/running/engine.py" in err
    assert err.strip().splitlines()[-1].startswith("pinn-mpc scenario: internal error (a bug in pinn-mpc")


def test_any_other_unexpected_exception_is_a_bug_too(monkeypatch, capsys):
    def broken() -> str:
        empty: dict[str, str] = {}
        return empty["missing"]

    _inject(monkeypatch, broken)
    assert main(["scenario", "list"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "internal error (a bug in pinn-mpc, not in your input): KeyError: 'missing'" in err
    assert "in broken" in err


def test_bad_input_is_still_one_line_and_exit_2(capsys):
    assert main(["scenario", "show", "no_such_scenario"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith("pinn-mpc scenario: error: unknown scenario 'no_such_scenario'")
    assert "bug" not in err


def _kw_irradiance_csv(path: Path) -> Path:
    """Weather in kW/m2 (G never above 1): accepted, with a warning."""
    times = pd.date_range("2021-01-01", periods=72, freq="h")
    pd.DataFrame(
        {"time": times.strftime("%Y-%m-%d %H:%M"), "T_a": 5.0, "G": 0.4 * (times.hour == 12)}
    ).to_csv(path, index=False)
    return path


def test_library_warnings_are_warnings_a_python_user_can_capture(tmp_path):
    path = _kw_irradiance_csv(tmp_path / "kw.csv")
    with pytest.warns(PinnMpcWarning, match="column G never exceeds 0.4 W/m2") as caught:
        read_series_csv(str(path), ("T_a",), ("G",))
    assert len(caught) == 1 and issubclass(PinnMpcWarning, UserWarning)
    # ... and filter: the same call under an "ignore" filter warns nobody (a new file: the
    # message is said once per process).
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", category=PinnMpcWarning)
        read_series_csv(str(_kw_irradiance_csv(tmp_path / "kw2.csv")), ("T_a",), ("G",))


def test_the_cli_prints_library_warnings_as_one_line(monkeypatch, capsys):
    def warns_then_lists() -> str:
        warn("something to look at")
        return "listed"

    _inject(monkeypatch, warns_then_lists)
    assert main(["scenario", "list"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "pinn-mpc: warning: something to look at\n"
    assert captured.out == "listed\n"


def test_a_warning_names_a_setting_by_name_in_python_and_by_flag_on_the_command_line(monkeypatch, capsys):
    """As an InputError's message: a Python caller reads the setting, the command line its flag."""
    def warns_then_lists() -> str:
        warn(f"replaced without {setting('force')}")
        return "listed"

    with pytest.warns(PinnMpcWarning) as caught:
        warns_then_lists()
    assert [str(w.message) for w in caught] == ["replaced without force"]
    _inject(monkeypatch, warns_then_lists)
    assert main(["scenario", "list"]) == 0
    assert capsys.readouterr().err == "pinn-mpc: warning: replaced without --force\n"


def test_the_cli_prints_library_notes_as_one_line(monkeypatch, capsys):
    """A note (``logging`` at INFO, as the heater sizing's) reaches stderr as ``pinn-mpc: ...``;
    after the command the loggers are as they were."""
    log = logging.getLogger("scenarios.registry")
    level = log.level

    def notes_then_lists() -> str:
        log.info("scenario 'x': heater sized")
        return "listed"

    _inject(monkeypatch, notes_then_lists)
    assert main(["scenario", "list"]) == 0
    assert capsys.readouterr().err == "pinn-mpc: scenario 'x': heater sized\n"
    assert log.level == level and not logging.getLogger("scenarios").handlers


def test_python_m_pinn_mpc_runs_the_command_line():
    """``python -m pinn_mpc`` (the installed entry point) and ``python -m pinn_mpc_cli`` are
    the same program as ``pinn-mpc``."""
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}
    for module in ("pinn_mpc", "pinn_mpc_cli"):
        done = subprocess.run(
            [sys.executable, "-m", module, "--version"], capture_output=True, text=True, env=env, check=True
        )
        assert done.stdout.startswith("pinn-mpc ")


def test_a_python_api_check_failed_from_inside_a_command_is_a_bug(monkeypatch, capsys):
    """A ValueError of the library's API checks (a caller's misuse) is no refusal of the user's
    input when the command line is the caller: it is reported as a bug, exit 1."""
    from controllers.base import ControlSpec
    from pinn_mpc.actuator import ActuatorSpec

    def misuses() -> str:
        return str(ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0),), horizon_steps=0))

    _inject(monkeypatch, misuses)
    assert main(["scenario", "list"]) == BUG_EXIT
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "internal error (a bug in pinn-mpc, not in your input): ValueError: ControlSpec.horizon_steps" in err


def test_an_os_error_on_a_file_the_user_did_not_name_is_a_bug(monkeypatch, capsys, tmp_path):
    """A file the package chose itself (here one it reads under a folder of its own) that the
    system refuses is a bug, exit 1; before, every OSError was exit 2 as bad input."""
    chosen = tmp_path / "package-cache" / "entries.json"

    def reads_its_own_file() -> str:
        return chosen.read_text()

    _inject(monkeypatch, reads_its_own_file)
    assert main(["scenario", "list"]) == BUG_EXIT
    err = capsys.readouterr().err.strip()
    assert "internal error" in err and f"FileNotFoundError: [Errno 2] No such file or directory: '{chosen}'" in err


def test_an_os_error_on_a_file_the_user_named_is_theirs(capsys, tmp_path):
    """A file the user named that the system refuses is the user's (exit 2, naming it): /proc
    takes no new files, whoever asks (root passes the check of the folder, the system then
    refuses the file)."""
    out = Path("/proc/pinn_mpc_test.toml")
    assert main(["scenario", "export", "paper_household", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(out) in err and "bug" not in err
    assert not out.exists()
    assert main(["scenario", "export", "paper_household", "--out", str(tmp_path / "s.toml")]) == 0


def test_memory_that_runs_out_unforeseen_is_a_bug_and_a_file_too_large_is_the_users(monkeypatch, capsys, tmp_path):
    """Runs the package sizes are refused before they start (exit 2); memory that runs out
    anyway was not foreseen: exit 1, saying so. A data file too large to read is the user's."""
    def allocates() -> str:
        raise MemoryError

    _inject(monkeypatch, allocates)
    assert main(["scenario", "list"]) == BUG_EXIT
    err = capsys.readouterr().err.strip()
    assert "internal error" in err and "MemoryError (out of memory where no check of the run's size foresaw it)" in err
    data = tmp_path / "d.csv"
    assert main(["simulate", "--scenario", "paper_household", "--days", "1", "--out", str(data)]) == 0
    capsys.readouterr()

    def too_large(*args: object, **kwargs: object) -> pd.DataFrame:
        raise MemoryError

    monkeypatch.setattr(pd, "read_csv", too_large)
    assert main(["identify", "--data", str(data), "--out", str(tmp_path / "rc.json")]) == 2
    assert capsys.readouterr().err.strip() == (
        f"pinn-mpc identify: error: {data}: too large to read into this machine's memory"
    )


def test_a_training_setting_refused_names_its_flag(capsys, tmp_path):
    """TrainConfig names its field to a Python caller; ``train`` names the flag."""
    from pinn_mpc.training import TrainConfig

    with pytest.raises(ValueError, match=r"^TrainConfig\.n_seeds must be 1 \.\. 1000 members, got 1001$"):
        TrainConfig(n_seeds=1001)
    data = tmp_path / "d.csv"
    assert main(["simulate", "--scenario", "paper_household", "--days", "2", "--out", str(data)]) == 0
    capsys.readouterr()
    for flag, value, message in (
        ("--depth", "5000", "--depth must be 1 .. 1008, got 5000"),
        ("--seeds", "1001", "--seeds must be 1 .. 1000 members, got 1001"),
        ("--eta", "50", "--eta = 50 W/W is outside the plausible range"),
    ):
        args = ["train", "--data", str(data), "--arch", "physnet", flag, value, "--out", str(tmp_path / "m")]
        assert main(args) == 2
        assert capsys.readouterr().err.startswith(f"pinn-mpc train: error: {message}")
    assert not (tmp_path / "m").exists()


def test_a_layout_given_for_data_of_one_zone_is_refused_as_such(capsys, tmp_path):
    """``--scenario`` only gives data of several zones their layout: with data of one zone
    ``train`` and ``identify`` refuse it in one line that says so (not that the scenario has
    several zones: an EnergyPlus building's merged zones are one), and write nothing."""
    data = tmp_path / "d.csv"
    assert main(["simulate", "--scenario", "paper_household", "--days", "2", "--out", str(data)]) == 0
    capsys.readouterr()
    for command, out in (("train", tmp_path / "m"), ("identify", tmp_path / "rc.json")):
        assert main([command, "--data", str(data), "--scenario", "paper_household", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err == (
            f"pinn-mpc {command}: error: --scenario paper_household: only data of several zones need a "
            f"layout; {data} holds one zone (T_r): leave --scenario out\n"
        ), err
        assert not out.exists()


def test_scenario_export_judges_the_out_name_before_reading_the_scenario(capsys, tmp_path):
    """``scenario export`` refuses an ``--out`` that is no .toml name first, as it did before the
    command moved to the command line: a scenario file that does not read is not asked."""
    broken = tmp_path / "broken.toml"
    broken.write_text("this is = = not toml\n")
    out = tmp_path / "copy.txt"
    assert main(["scenario", "export", str(broken), "--out", str(out)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"pinn-mpc scenario: error: --out {out}: scenario files end in .toml (that is how "
        f"--scenario tells a file from a built-in name); write --out {out}.toml"
    )
    assert not out.exists()
