"""EnergyPlus closed-loop throughput: simulated days per wall second under the thermostat.

Run: ``python benchmarks/bench_energyplus.py [--days 20] [--scenario eplus_small_office]``.
Times :func:`scenarios.running.closed_loop.run_closed_loop` of the thermostat on the test part of the
scenario's weather in this process (imports and the first EnergyPlus start excluded by a
1-day run before), best of ``--repeats``, counting the warm-up day the loop also simulates.
Prints the figure and the load average (other work on the cores lowers it); exit status 1
below ``--target`` days per second (10 by default).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from controllers.base import Controller
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.factory import build_controller


def days_per_second(scenario_name: str, days: int, repeats: int) -> float:
    """Best-of-``repeats`` simulated days (counted + the warm-up day) per wall second."""
    scenario = get_scenario(scenario_name)

    def thermostat() -> Controller:
        return build_controller("thermostat", scenario, n_steps=days * scenario.steps_per_day)

    run_closed_loop(scenario, thermostat(), days=1, seed=0, weather_part="test")  # warm caches
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        run_closed_loop(scenario, thermostat(), days=days, seed=0, weather_part="test")
        best = min(best, time.perf_counter() - start)
    return (days + 1) / best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="eplus_small_office")
    parser.add_argument("--days", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--target", type=float, default=10.0)
    a = parser.parse_args(argv)
    rate = days_per_second(a.scenario, a.days, a.repeats)
    load = os.getloadavg()[0]
    print(f"{a.scenario}: thermostat closed loop, {a.days} + 1 days: {rate:.1f} simulated days "
          f"per wall second (best of {a.repeats}; load average {load:.1f} on {os.cpu_count()} cores)")
    return 0 if rate >= a.target else 1


if __name__ == "__main__":
    sys.exit(main())
