"""benchmarks/bench_online_decisions.py: the decisions it counts as taken while a refit is in
flight are the schedule's (00:00 to 03:00 of each night, six half-hours), and the script runs
an online run to the end and prints the groups (and the same hours with no refit)."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.bench_online_decisions import in_flight_mask, main, night_hours_mask, percentiles_ms


def test_the_window_runs_from_each_refits_start_to_its_takeover() -> None:
    log = (
        {"night": 0, "step": 0, "version": "v000", "verdict": "initial"},  # before the loop
        {"night": 1, "step": 96, "takeover_step": 102},
        {"night": 2, "step": 144, "takeover_step": 150},
    )
    mask = in_flight_mask(log, 200)
    assert np.flatnonzero(mask).tolist() == [*range(96, 102), *range(144, 150)]


def test_the_same_hours_are_each_days_first_six_half_hours_after_the_warm_up() -> None:
    mask = night_hours_mask(48 + 3 * 48, warmup=48, steps_per_day=48)
    assert np.flatnonzero(mask).tolist() == [k for day in range(4) for k in range(48 * day, 48 * day + 6)]


def test_percentiles_are_in_milliseconds() -> None:
    n, median, p95 = percentiles_ms(np.array([0.001, 0.002, 0.003, 0.004, 0.005]))
    assert (n, median) == (5, pytest.approx(3.0))
    assert p95 == pytest.approx(4.8)  # linear between the 4th (4 ms) and 5th (5 ms) of five
    assert percentiles_ms(np.array([]))[0] == 0


def test_two_days_split_one_nights_six_decisions_from_the_other_ninety(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--days", "2"]) == 0
    out = capsys.readouterr().out
    rows = {line[:22].strip(): line[22:].split() for line in out.splitlines()
            if line.startswith(("refit in flight", "no refit running", "same hours, no refit"))}
    # 2 days of 48 half-hours; one night (the second day's) refits, in flight 3 h: 6 decisions
    assert rows["refit in flight"][0] == "6"
    assert rows["no refit running"][0] == "90"
    assert rows["same hours, no refit"][0] == "6"  # the first day's 00:00-03:00
    assert "night 1: refit" in out and "load average:" in out
