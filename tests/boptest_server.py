"""The tests' BOPTEST server: ``shared/boptest/serve.py`` beside the checkout (or above it),
started once per test session on a free local port, or the server at ``$BOPTEST_URL``; a test
that needs one skips, saying why, only where neither exists. ``tests/conftest.py`` makes the
fixture :func:`boptest_server` available to every test module."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The session server's idle timeout [s] (a test with no call this long ends).
IDLE_TIMEOUT_S = 25.0


def serve_script() -> Path | None:
    for parent in ROOT.parents:
        script = parent / "shared" / "boptest" / "serve.py"
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


@pytest.fixture(scope="session")
def boptest_server() -> Iterator[Server]:
    url = os.environ.get("BOPTEST_URL")
    if url:
        yield Server(url, started=False)
        return
    script = serve_script()
    if script is None:
        pytest.skip("no BOPTEST server: neither shared/boptest/serve.py beside the checkout nor $BOPTEST_URL")
    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, str(script), "--port", str(port), "--max-tests", "3",
         "--timeout", str(IDLE_TIMEOUT_S)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )
    lines: list[str] = []
    ready = threading.Event()

    def read() -> None:  # the first start builds the server's environment (about a minute)
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if line.startswith("serving BOPTEST"):
                ready.set()

    threading.Thread(target=read, daemon=True).start()
    try:
        if not ready.wait(600) or proc.poll() is not None:
            raise RuntimeError(f"the BOPTEST server did not start: {''.join(lines)[-2000:]}")
        yield Server(f"http://127.0.0.1:{port}", started=True)
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
