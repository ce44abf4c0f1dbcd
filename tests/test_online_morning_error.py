"""benchmarks/online_morning_error.py: the share of the heater power's variance the half-hour
of the day explains is 1 for a power set by the hour and 0 for one set by the day alone, and
the script makes an online run and judges its running model and a model trained once on the
morning of its second day."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmarks.online_morning_error import hour_share, main


def _frame(u: np.ndarray) -> pd.DataFrame:
    return pd.DataFrame({"time": pd.date_range("2023-01-02", periods=len(u), freq="30min"), "u": u})


def test_a_power_set_by_the_half_hour_is_explained_whole() -> None:
    slot_power = np.linspace(0.0, 9000.0, 48)
    assert hour_share(_frame(np.tile(slot_power, 3))) == pytest.approx(1.0)


def test_a_power_set_by_the_day_alone_is_not_explained_at_all() -> None:
    u = np.concatenate([np.full(48, 1000.0), np.full(48, 5000.0)])  # every half-hour's mean alike
    assert hour_share(_frame(u)) == pytest.approx(0.0, abs=1e-12)


def test_an_online_run_is_made_and_its_second_morning_judged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    argv = ["--run", "heat_pump_household", "--online-dir", str(run), "--days", "2", "--members", "2",
            "--model", str(run / "versions" / "v000" / "model"), "--from-day", "1"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    rows = [line.split() for line in out.splitlines() if line[:4].strip().isdigit()]
    assert [row[0] for row in rows] == ["2"]  # day 1 ran the initial version, judged by no night
    assert all(np.isfinite(float(v)) for v in rows[0][2:])
    assert "running: 1 mornings" in out and "pretrained: 1 mornings" in out
    assert "online run's days of service: power std" in out
