"""Decision time of an online run while a refit runs (issue 45): median and 95th percentile
[ms] of the decisions taken while a refit worker was in flight against those taken while none
was.

Run from the checkout: ``PYTHONPATH=. python benchmarks/bench_online_decisions.py [--scenario
heat_pump_household] [--days 7] [--data-days 3] [--seed 0] [--controller cem]``. One online run
(:func:`scenarios.running.online.run_online`, as ``closed-loop --online`` runs it: one torch
and one BLAS thread in the run, the refit worker's own) of ``--days`` days of service, starting from
``--data-days`` days of the scenario's data (its data policy, seed ``--seed``, the days right
before the run: :func:`scenarios.running.online.data_before_run`), the run's seed ``--seed``.
A refit is in flight from its start (:data:`~scenarios.running.online.REFIT_HOUR`, 00:00) to
its takeover (:data:`~scenarios.running.online.TAKEOVER_H` later, 03:00), as the run's log
records each night; a refit still running at its takeover (``late``) was in flight for every
decision of its window. The counted decisions (the warm-up's thermostat excluded) are split by
that window; a third group, the decisions of the same hours with no refit (the first day of
service's, before any night's refit), tells the refit from the time of day. Prints the groups'
counts, median and p95 decision time [ms] (wall clock, as the run records them), each night's
refit wall time and whether it was late, the run's objective [EUR] and own decisions; then the
load average. Exits 0.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from scenarios import get_scenario
from scenarios.running.closed_loop import one_torch_thread, prepare_run
from scenarios.running.online import (
    REFIT_HOUR,
    TAKEOVER_H,
    OnlineSettings,
    data_before_run,
    run_online,
)


def in_flight_mask(log: Sequence[Mapping[str, Any]], n_steps: int) -> np.ndarray:
    """(n_steps,) True at the steps from each night's refit start to its takeover (excluded)."""
    mask = np.zeros(n_steps, dtype=bool)
    for entry in log:
        if "takeover_step" in entry:  # a night's refit (the initial one runs before the loop)
            start, end = int(entry["step"]), int(entry["takeover_step"])
            mask[start:end] = True
    return mask


def night_hours_mask(n_steps: int, *, warmup: int, steps_per_day: int) -> np.ndarray:
    """(n_steps,) True at the steps of each day's refit window hours (from
    :data:`REFIT_HOUR` for :data:`TAKEOVER_H`), whether a refit runs then or not."""
    start = REFIT_HOUR * steps_per_day // 24
    hour_steps = max(1, round(TAKEOVER_H * steps_per_day / 24))
    of_day = (np.arange(n_steps) - warmup) % steps_per_day
    return (of_day >= start) & (of_day < start + hour_steps)


def percentiles_ms(seconds: np.ndarray) -> tuple[int, float, float]:
    """Count, median and 95th percentile [ms] of decision times [s] (NaN for none)."""
    if len(seconds) == 0:
        return 0, float("nan"), float("nan")
    ms = 1e3 * seconds
    return len(ms), float(np.median(ms)), float(np.percentile(ms, 95))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="heat_pump_household", help="a built-in or a scenario file")
    parser.add_argument("--days", type=int, default=7, help="days of service (default 7)")
    parser.add_argument("--data-days", type=int, default=3, help="days of data the run starts from (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="the data's and the run's seed (default 0)")
    parser.add_argument("--controller", default="cem", help="the online controller (default cem)")
    args = parser.parse_args(argv)
    scenario = get_scenario(args.scenario)
    run = prepare_run(scenario, days=args.days, seed=args.seed, warmup_steps=None, weather_part="test")
    data = data_before_run(scenario, days=args.data_days, seed=args.seed, policy=scenario.data_policy,
                           first_time=pd.Timestamp(run.exo["time"].iloc[0]))
    # As `pinn-mpc` runs every command: one BLAS thread in the run, one torch thread.
    with tempfile.TemporaryDirectory(prefix="bench_online_") as out, one_torch_thread(), \
            threadpool_limits(limits=1, user_api="blas"):
        result = run_online(scenario, data, days=args.days, seed=args.seed, out_dir=out,
                            settings=OnlineSettings(controller=args.controller))
        with np.load(Path(out) / "loop.npz") as arrays:
            decision_s = np.asarray(arrays["decision_s"], dtype=float)  # (K,) every step's
    counted = np.zeros(len(decision_s), dtype=bool)
    counted[run.counted] = True
    flight = in_flight_mask(result.log, len(decision_s))
    print(f"{scenario.name}: online {args.controller}, {args.days} days from {args.data_days} days of data, "
          f"seed {args.seed}")
    print(f"{'decisions':<22} {'n':>5} {'median ms':>10} {'p95 ms':>8}")
    hours = night_hours_mask(len(decision_s), warmup=run.warmup, steps_per_day=scenario.steps_per_day)
    groups = (
        ("refit in flight", counted & flight),
        ("no refit running", counted & ~flight),
        ("same hours, no refit", counted & hours & ~flight),  # the first day's 00:00-03:00
    )
    for label, mask in groups:
        n, median, p95 = percentiles_ms(decision_s[mask])
        print(f"{label:<22} {n:>5} {median:>10.1f} {p95:>8.1f}")
    for entry in result.log:
        if "takeover_step" in entry:
            print(f"night {entry['night']}: refit {float(entry['wall_s']):.1f} s "
                  f"({'late: waited for at its takeover' if entry['late'] else 'done before its takeover'}), "
                  f"verdict {entry['verdict']}")
    kpis = result.kpis
    print(f"objective {float(kpis['objective']):.3f} EUR, own decisions "
          f"{100 * float(kpis['own_decisions_share']):.1f} %")
    print(f"load average: {', '.join(f'{v:.2f}' for v in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
