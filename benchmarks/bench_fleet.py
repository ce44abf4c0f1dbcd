"""Time per control step of a fleet closed loop: 1,000 buildings under qp-mpc, each on its own RC.

Run: ``python benchmarks/bench_fleet.py [--buildings 1000] [--days 1] [--cem-buildings 0]``.
The fleet is drawn around ``winter_household``'s building (spread 0.2) and run by
:func:`scenarios.fleets.fleet.run_fleet_closed_loop` on the test part of the weather, seed 13: the
test day 2023-02-12 (-1.7 .. 4.3 C), when every building heats all day (seed 0's day, 21 C on
average, needed almost no heat, so it timed decisions that did not matter): a day of
thermostat warm-up, then ``--days`` counted days (48 control steps a day), each building with
its own ``qp-mpc`` (OSQP, Kalman observer) on its own parameters, the plant one batched simulator
step per control interval. Printed: wall time per counted control step (median and p95) of all
controllers (every building's observe, forecast and decide, one after another on one core), of
the plant and of both, against the 30-minute control interval, and the load average (other work
on the cores lengthens every figure). ``--cem-buildings N`` also runs N buildings under ``cem``
over each building's exact RC batch model (about 40 ms a decision, so keep N small).
``benchmarks/bench_aggregator.py`` times the fleet planned in one batch and under a cap.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from scenarios.fleets.fleet import FleetResult, run_fleet_closed_loop
from scenarios.inputs.scenario_file import get_scenario
from scenarios.reports.report import format_fleet
from scenarios.running.closed_loop import one_torch_thread

SCENARIO = "winter_household"
#: The test day with heating demand (see the module docstring).
SEED = 13


def report(result: FleetResult, build_and_run_s: float) -> None:
    t = result.step_time
    interval_ms = get_scenario(SCENARIO).sim.dt_s * 1000.0
    print(format_fleet(result))
    for part in ("controllers", "plant", "total"):
        print(
            f"  {part:12s} per control step: median {t[f'{part}_ms_median']:10.1f} ms, "
            f"p95 {t[f'{part}_ms_p95']:10.1f} ms"
        )
    per_building = sorted(k["decision_ms_median"] for k in result.kpis)
    print(
        f"  {len(result.aggregate_u_phys_w)} counted control steps after a day of warm-up, "
        f"{build_and_run_s:.1f} s in all (building the controllers included); one building's "
        f"decision: {per_building[len(per_building) // 2]:.2f} ms (median of the medians)"
    )
    print(
        f"  total p95 per control step is {t['total_ms_p95'] / interval_ms:.4%} of the "
        f"{interval_ms / 60000:.0f}-minute control interval"
    )


def run(controller: str, n_buildings: int, days: int) -> None:
    start = time.perf_counter()
    with one_torch_thread():
        result = run_fleet_closed_loop(
            get_scenario(SCENARIO), controller, n_buildings=n_buildings, days=days, seed=SEED
        )
    report(result, time.perf_counter() - start)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--buildings", type=int, default=1000, help="qp-mpc fleet (default 1000)")
    parser.add_argument("--days", type=int, default=1, help="counted days (default 1)")
    parser.add_argument(
        "--cem-buildings", type=int, default=0, help="also a cem fleet of this size (default 0)"
    )
    args = parser.parse_args()
    run("qp-mpc", args.buildings, args.days)
    if args.cem_buildings > 0:
        run("cem", args.cem_buildings, args.days)
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average (1, 5, 15 min): {load} on {os.cpu_count()} CPUs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
