"""Ctrl-C in the middle of an online run, as a user's, for the resume tests."""

from __future__ import annotations

import _thread
import json
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import pytest

R = TypeVar("R")


def stopped_then_resumed(run: Callable[[bool], R], state: Path, after_step: int) -> tuple[int, R]:
    """Start ``run(False)`` (an online run writing ``state``), interrupt it from a watcher
    thread (KeyboardInterrupt in the main thread) once its saved state's step passes
    ``after_step``, then ``run(True)`` (the resume); returns the step the saved state held at
    the stop and the resumed run's result."""

    def interrupt_after() -> None:
        while True:
            if state.is_file():
                try:
                    step = json.loads(state.read_text())["step"]
                except (json.JSONDecodeError, KeyError):
                    continue  # never with atomic writes; would fail the caller's equality
                if step > after_step:
                    _thread.interrupt_main()
                    return
            time.sleep(0.01)

    watcher = threading.Thread(target=interrupt_after, daemon=True)
    watcher.start()
    with pytest.raises(KeyboardInterrupt):
        run(False)
    watcher.join()
    stopped_at = int(json.loads(state.read_text())["step"])
    return stopped_at, run(True)
