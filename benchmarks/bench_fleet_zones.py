"""A fleet of buildings of several zones under a cap: does the cap hold, at what cost, how fast.

Run: ``python benchmarks/bench_fleet_zones.py [--buildings 200] [--days 2] [--cap-kw 700]
[--controllers thermostat oracle] [--scenario two_zone_house] [--seed 4]``.
The fleet is drawn around the scenario's building zone by zone and wall by wall (spread 0.2)
and run by :func:`scenarios.fleets.aggregator.run_coordinated_fleet`, each building with its
own zoned controller on its own building, once without a cap and once with ``--cap-kw`` on the
fleet's total electrical power (every actuator of every building) all day. Seed 4 of
``two_zone_house`` is a cold test spell: every building heats all day. Printed per controller
and run: the fleet's KPIs, the largest interval's total against the cap, the capped intervals
over it, the wall time of the run and per control step, and the load average (other work on
the cores lengthens every time).
"""

from __future__ import annotations

import argparse
import os
import time

from scenarios.fleets.aggregator import run_coordinated_fleet
from scenarios.inputs.scenario_file import get_scenario
from scenarios.reports.report import format_fleet
from scenarios.running.closed_loop import one_torch_thread


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="two_zone_house")
    parser.add_argument("--buildings", type=int, default=200)
    parser.add_argument("--days", type=int, default=2)
    parser.add_argument("--seed", type=int, default=4)
    parser.add_argument("--cap-kw", type=float, default=700.0)
    parser.add_argument("--controllers", nargs="+", default=["thermostat", "oracle"])
    a = parser.parse_args()
    scenario = get_scenario(a.scenario)
    print(f"{a.buildings} buildings of {a.scenario}, {a.days} d, seed {a.seed}; load {os.getloadavg()}")
    for controller in a.controllers:
        for cap_kw in (None, a.cap_kw):
            start = time.perf_counter()
            with one_torch_thread():
                result = run_coordinated_fleet(
                    scenario, controller, n_buildings=a.buildings, days=a.days, seed=a.seed, cap_kw=cap_kw
                )
            wall_s = time.perf_counter() - start
            peak_kw = float(result.aggregate_u_phys_w.max()) / 1000.0
            print(format_fleet(result))
            if result.cap is not None and cap_kw is not None:
                print(
                    f"  cap {cap_kw:g} kW: max total / cap = {peak_kw / cap_kw:.6f}, "
                    f"{result.cap['intervals_over']} of {result.cap['intervals']} capped intervals over it, "
                    f"{result.cap['curtailed_steps']} steps curtailed"
                )
            print(
                f"  wall {wall_s:.1f} s; per control step median {result.step_time['total_ms_median']:.0f} ms, "
                f"p95 {result.step_time['total_ms_p95']:.0f} ms; load {os.getloadavg()}"
            )


if __name__ == "__main__":
    main()
