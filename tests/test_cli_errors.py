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
from pinn_mpc.errors import InputError, InternalError, PinnMpcWarning, warn
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
        return str({}["missing"])

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
