"""The tests' BOPTEST server, one per test session: the server at ``$BOPTEST_URL`` where that is
set, else the local API server (``shared/boptest/api_server.py`` beside the checkout, started
on a free local port) where it starts; otherwise every test that needs a server skips at once,
with the reason: what was looked for, and the local server's own line when it refused to start
(it exits 2 at once without BOPTEST's code, ``$BOPTEST_HOME``, or test cases,
``$BOPTEST_TESTCASES``). ``tests/conftest.py`` makes the fixture :func:`boptest_server`
available to every test module; docs/boptest.md ("Running the BOPTEST tests") says how to give
the tests a server.

No test here needs a server to fail fast: a skip is decided by a probe of ``$BOPTEST_URL`` (a
few seconds) or by the local server's exit, never by a wait for a server that cannot start."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The session server's idle timeout [s] (a test with no call this long ends).
IDLE_TIMEOUT_S = 25.0
#: How long a started local server may take to print its first line: its first start builds its
#: own environment from the package registry (about a minute), and a select loads a test case.
START_TIMEOUT_S = 600.0
#: How long ``$BOPTEST_URL`` has to answer ``GET /version`` before the tests skip.
PROBE_TIMEOUT_S = 5.0


def api_server_script() -> Path | None:
    """``shared/boptest/api_server.py`` in a parent folder of the checkout, or None."""
    for parent in ROOT.parents:
        script = parent / "shared" / "boptest" / "api_server.py"
        if script.is_file():
            return script
    return None


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Server:
    """The session's BOPTEST: ``url``, and whether this session started it (its idle timeout
    is then :data:`IDLE_TIMEOUT_S`)."""

    def __init__(self, url: str, started: bool) -> None:
        self.url, self.started = url, started


def probe(url: str) -> str | None:
    """Why the server at ``url`` cannot serve the tests (None: it answers ``GET /version``)."""
    from scenarios.plants.boptest_client import BoptestClient, BoptestError

    client = BoptestClient(url, timeout_s=PROBE_TIMEOUT_S)
    try:
        client.version()
    except BoptestError as exc:
        return f"$BOPTEST_URL={url} does not answer: {exc}"
    finally:
        client.close()
    return None


def _start_local(script: Path) -> tuple[subprocess.Popen[str] | None, str]:
    """Start ``script`` on a free port; the process and its URL once it serves, or None and the
    reason (its own output) once it has exited without serving."""
    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, str(script), "--port", str(port), "--max-tests", "3",
         "--timeout", str(IDLE_TIMEOUT_S)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )
    lines: list[str] = []
    ready = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if line.startswith("serving BOPTEST"):
                ready.set()
        ready.set()  # end of output: the server exited

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    deadline = time.monotonic() + START_TIMEOUT_S
    while not ready.wait(0.2):
        if time.monotonic() > deadline:
            _stop(proc)
            return None, f"{script.name} printed no 'serving BOPTEST' line within {START_TIMEOUT_S:g} s: " \
                + "".join(lines)[-500:].strip()
    if proc.poll() is not None or not any(line.startswith("serving BOPTEST") for line in lines):
        reader.join(5)
        return None, f"{script} exited ({proc.wait()}): " + " ".join(
            line.strip() for line in lines if line.strip())[-500:]
    return proc, f"http://127.0.0.1:{port}"


def _stop(proc: subprocess.Popen[str]) -> None:
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


_NO_SERVER = "no BOPTEST server (docs/boptest.md, 'Running the BOPTEST tests', says how to give one)"


@pytest.fixture(scope="session")
def boptest_server() -> Iterator[Server]:
    url = os.environ.get("BOPTEST_URL")
    if url:
        reason = probe(url)
        if reason is not None:
            pytest.skip(f"{_NO_SERVER}; {reason}")
        yield Server(url, started=False)
        return
    script = api_server_script()
    if script is None:
        pytest.skip(f"{_NO_SERVER}; no $BOPTEST_URL, and no shared/boptest/api_server.py beside the checkout")
    proc, found = _start_local(script)
    if proc is None:
        pytest.skip(f"{_NO_SERVER}; {found}")
    try:
        yield Server(found, started=True)
    finally:
        _stop(proc)
