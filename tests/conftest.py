"""Test-session set-up: one BLAS and one torch thread per process; Ctrl-C deliverable.

The session's BOPTEST server (``boptest_server``, :mod:`tests.boptest_server`) is a fixture
of every test module.

The suite runs with ``-n 2`` on 2 cores; a second BLAS/torch thread per worker oversubscribes the
machine and makes small linear algebra many times slower. A test run started in the background
of a non-interactive shell inherits SIGINT ignored (as its subprocesses would), which the tests
of what Ctrl-C does cannot test: Python's own handler is put back.

The slow (end-to-end) tests run first. With ``--dist worksteal`` (``pyproject.toml``) the
first worker starts on them while the second works through the short tests and then takes
half of what the first has left, so neither waits long on the other at the end (in
collection order one worker was left with the long tests of the last modules alone).
"""

import signal
import threading

import pytest
import torch
from threadpoolctl import threadpool_limits

from tests.boptest_server import boptest_server  # noqa: F401  (the fixture, for every module)

threadpool_limits(limits=1)
torch.set_num_threads(1)

if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Put the tests marked ``slow`` first, each group in collection order (module docstring)."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
