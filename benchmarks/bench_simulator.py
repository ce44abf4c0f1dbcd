"""Simulator throughput: building-minutes simulated per second for 1, 1000 and 10,000 buildings.

Run: ``python benchmarks/bench_simulator.py [--days 3]``. Each run steps the batched simulator
of ``paper_household`` (1-min substeps, 30-min control intervals, random on/off demands, so
the backup thermostat acts) for the given days: 1 and 1000 identical buildings, then a fleet of
10,000 buildings with their own parameters (``draw_fleet``, spread 0.2). Exit status 1 unless
batching buys at least 100x per building and the fleet reaches 1e8 building-minutes/s (on an
idle machine; the load average is printed, since other work on the cores lowers both).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence

import numpy as np

from pinn_mpc.physics import RCParams
from pinn_mpc.simulator import Simulator, draw_fleet
from scenarios.inputs.scenario_file import get_scenario

MIN_SPEEDUP = 100.0
FLEET_SIZE = 10_000
FLEET_TARGET = 1e8  # building-minutes per second


def throughput(
    n_buildings: int, days: int, *, fleet: Sequence[RCParams] | None = None, repeats: int = 3
) -> float:
    """Best-of-``repeats`` building-minutes per second."""
    scenario = get_scenario("paper_household")
    exo = scenario.exogenous(days=days, seed=0, part="train")
    t_a = exo["T_a"].to_numpy()
    rng = np.random.default_rng(0)
    demand = np.where(rng.random((len(exo), n_buildings)) < 0.5, scenario.sim.u_max_w, 0.0)
    best = float("inf")
    for _ in range(repeats):
        sim = Simulator(scenario.sim, n_buildings=n_buildings, seed=0, fleet=fleet)
        sim.reset(scenario.initial_t_r_c, scenario.initial_t_m_c)
        sim.step(demand[0], t_a[0])  # compiles (or loads) the substep kernel outside the clock
        sim.reset(scenario.initial_t_r_c, scenario.initial_t_m_c)
        start = time.perf_counter()
        for k in range(len(exo)):
            sim.step(demand[k], t_a[k])
        best = min(best, time.perf_counter() - start)
    minutes = len(exo) * scenario.sim.dt_s / 60.0 * n_buildings
    return minutes / best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=int, default=3)
    args = parser.parse_args()
    one = throughput(1, args.days)
    many = throughput(1000, args.days)
    base = get_scenario("paper_household").sim.params
    fleet = draw_fleet(base, FLEET_SIZE, spread=0.2, rng=np.random.default_rng(0))
    fleet_rate = throughput(FLEET_SIZE, args.days, fleet=fleet)
    ratio = many / one
    print(f"1 building:       {one:14,.0f} building-minutes/s ({args.days} days)")
    print(f"1000 buildings:   {many:14,.0f} building-minutes/s")
    print(f"{FLEET_SIZE:,} fleet:    {fleet_rate:14,.0f} building-minutes/s "
          f"(own parameters per building; target >= {FLEET_TARGET:.0e})")
    print(f"per-building speed-up of batching: {ratio:,.0f}x (required >= {MIN_SPEEDUP:.0f}x)")
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average (1, 5, 15 min): {load} on {os.cpu_count()} CPUs")
    return 0 if ratio >= MIN_SPEEDUP and fleet_rate >= FLEET_TARGET else 1


if __name__ == "__main__":
    sys.exit(main())
