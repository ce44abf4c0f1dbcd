"""Ctrl-C (SIGINT) while a solver runs: solvers written in C catch it themselves (OSQP returns
the status ``interrupted``; it is lost when it arrives after the solver's last check), so the
controllers hold it back around every solve and raise it as KeyboardInterrupt after."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from controllers.base import ControlSpec, Observation, raise_if_interrupted, solver_interrupts_held
from controllers.rc_mpc.casadi import CasadiMPC
from controllers.rc_mpc.osqp import QPMPC
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.physics import PAPER_HOUSEHOLD, rc_summary
from tests.test_rc_mpc import _forecast

ROOT = Path(__file__).resolve().parents[1]
SPEC = ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0),))
#: The time from the signal to the end of the process allowed on a loaded test machine (the
#: aim is well under a second; measured about 0.1 s).
EXIT_SLACK_S = 3.0


@pytest.mark.parametrize("mpc", [QPMPC, CasadiMPC])
def test_ctrl_c_during_solves_interrupts_and_is_no_fallback(mpc) -> None:
    controller = mpc(PAPER_HOUSEHOLD, SPEC)
    forecast = _forecast(SPEC.horizon_steps)
    history = {"T_r": np.array([19.0]), "u": np.zeros(0), "u_phys": np.zeros(0), "T_a": np.array([3.0])}
    obs = Observation.from_history(0, history, 18.0)
    controller.act(obs, forecast)  # the first solve builds the solver
    # to the main thread, as a terminal's Ctrl-C reaches a single-threaded process (under a
    # test runner another thread, with its own mask, could take a process-wide signal)
    main_thread = threading.main_thread().ident or 0
    timer = threading.Timer(0.3, signal.pthread_kill, (main_thread, signal.SIGINT))
    timer.start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        while time.monotonic() - start < 20.0:  # decisions back to back: the signal lands in one
            controller.act(obs, forecast)
    timer.join()
    assert time.monotonic() - start < 0.3 + EXIT_SLACK_S
    assert controller.n_fallbacks == 0


def test_held_interrupt_is_raised_when_the_block_ends() -> None:
    reached = []
    with pytest.raises(KeyboardInterrupt):
        with solver_interrupts_held():
            # to this thread, which holds it back (a process-wide kill may be taken by another
            # thread, e.g. a test runner's, whose mask is its own)
            signal.pthread_kill(threading.main_thread().ident or 0, signal.SIGINT)
            time.sleep(0.05)
            reached.append("end of block")  # held back: the block runs to its end
    assert reached == ["end of block"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.parametrize("status", ["interrupted", "User_Requested_Stop"])
def test_a_solver_status_of_interruption_raises(status: str) -> None:
    with pytest.raises(KeyboardInterrupt, match="interrupted"):
        raise_if_interrupted(status)
    raise_if_interrupted("solved")


def _interrupt_cli(args: list[str], cwd: Path, delay_s: float = 7.0) -> tuple[int, float, str]:
    """Run ``pinn-mpc ARGS``, send SIGINT after ``delay_s``: (exit status, seconds from the
    signal to the end of the process, stderr)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "pinn_mpc", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=cwd,
    )
    time.sleep(delay_s)
    assert proc.poll() is None, f"the run ended before the signal: {proc.communicate()}"
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    try:
        _, stderr = proc.communicate(timeout=120)
    finally:
        proc.kill()
    return proc.returncode, time.monotonic() - sent, stderr


@pytest.mark.slow
def test_ctrl_c_ends_a_qp_mpc_closed_loop_at_once_and_writes_nothing(tmp_path: Path) -> None:
    (tmp_path / "rc.json").write_text(json.dumps(rc_summary(PAPER_HOUSEHOLD, source="test")))
    status, elapsed, stderr = _interrupt_cli(
        ["closed-loop", "--scenario", "paper_household", "--controller", "qp-mpc", "--rc", "rc.json",
         "--days", "400", "--json", "k.json", "--csv", "traj.csv", "--plot", "loop.png"],
        tmp_path,
    )
    assert status == 130, stderr[-2000:]
    assert stderr.strip().splitlines()[-1] == "pinn-mpc closed-loop: interrupted"
    assert "Solver interrupted" not in stderr
    assert elapsed < EXIT_SLACK_S
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rc.json"]


@pytest.mark.slow
def test_ctrl_c_ends_a_capped_fleet_at_once_and_writes_nothing(tmp_path: Path) -> None:
    status, elapsed, stderr = _interrupt_cli(
        ["closed-loop", "--scenario", "paper_household", "--controller", "qp-mpc", "--days", "40",
         "--buildings", "20", "--batched", "--cap-kw", "40", "--json", "k.json"],
        tmp_path,
        delay_s=12.0,
    )
    assert status == 130, stderr[-2000:]
    assert stderr.strip().splitlines()[-1] == "pinn-mpc closed-loop: interrupted"
    assert elapsed < EXIT_SLACK_S
    assert list(tmp_path.iterdir()) == []
