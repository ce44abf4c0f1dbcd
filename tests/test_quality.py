"""ruff and mypy run as part of the test suite, so CI and the README's test command check them."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CODE = ["pinn_mpc", "pinn_mpc_cli", "controllers", "scenarios", "tests", "benchmarks", "examples", "docs"]


def _run(args: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=900)


def test_ruff_clean():
    if shutil.which("ruff") is None:
        pytest.fail("ruff is not installed; install the test extra: pip install -e '.[test]'")
    result = _run(["ruff", "check", *CODE])
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.slow
def test_mypy_clean():
    result = _run([sys.executable, "-m", "mypy"])
    assert result.returncode == 0, result.stdout[-5000:] + result.stderr[-2000:]
