"""Simulator throughput: building-minutes simulated per second for 1 and for 1000 buildings.

Run: ``python benchmarks/bench_simulator.py [--days 3]``. Each run steps the batched simulator
of ``paper_household`` (1-min substeps, 30-min control intervals, random demands) for the given
days; the per-building speed-up is the ratio of the two throughputs. Batching must buy at least
100x, or the script exits with status 1.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from pinn_mpc.simulator import Simulator
from scenarios.registry import get_scenario

MIN_SPEEDUP = 100.0


def throughput(n_buildings: int, days: int, *, repeats: int = 3) -> float:
    """Best-of-``repeats`` building-minutes per second."""
    scenario = get_scenario("paper_household")
    exo = scenario.exogenous(days=days, seed=0, part="train")
    t_a = exo["T_a"].to_numpy()
    rng = np.random.default_rng(0)
    demand = np.where(rng.random((len(exo), n_buildings)) < 0.5, scenario.sim.u_max_w, 0.0)
    best = float("inf")
    for _ in range(repeats):
        sim = Simulator(scenario.sim, n_buildings=n_buildings, seed=0)
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
    ratio = many / one
    print(f"1 building:     {one:14,.0f} building-minutes/s ({args.days} days)")
    print(f"1000 buildings: {many:14,.0f} building-minutes/s ({args.days} days)")
    print(f"per-building speed-up of batching: {ratio:,.0f}x (required >= {MIN_SPEEDUP:.0f}x)")
    return 0 if ratio >= MIN_SPEEDUP else 1


if __name__ == "__main__":
    sys.exit(main())
