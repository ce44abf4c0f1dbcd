"""Test-session set-up: one BLAS and one torch thread per process; Ctrl-C deliverable.

The session's BOPTEST server (``boptest_server``, :mod:`tests.boptest_server`) is a fixture
of every test module.

The suite runs with ``-n 2`` on 2 cores; a second BLAS/torch thread per worker oversubscribes the
machine and makes small linear algebra many times slower. A test run started in the background
of a non-interactive shell inherits SIGINT ignored (as its subprocesses would), which the tests
of what Ctrl-C does cannot test: Python's own handler is put back.
"""

import signal
import threading

import torch
from threadpoolctl import threadpool_limits

from tests.boptest_server import boptest_server  # noqa: F401  (the fixture, for every module)

threadpool_limits(limits=1)
torch.set_num_threads(1)

if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
