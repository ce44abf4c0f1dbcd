"""Multi-zone simulator step time: milliseconds per control interval for B = 1 and 1000 buildings
of Z = 2 and 5 zones, shared parameters and a fleet with its own.

Run: ``python benchmarks/bench_multizone.py [--steps 96]``. Each building is a row of Z zones
of ``paper_household``'s R/C values, each wall between neighbours 150 W/K, a heater in every
zone and a cooler in the first (a dual-setpoint zone); demands are random so the backup
thermostat acts. Each interval is 30 one-minute substeps (numpy over the buildings,
:class:`pinn_mpc.multizone.MultiZoneSimulator`). For scale, the same line gives the 2R2C
simulator's (:mod:`pinn_mpc.substeps`, numba) time for B x Z one-zone buildings: the work of
the same number of zones, uncoupled. Prints the table and the load average; exits 0.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

import numpy as np

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.multizone import (
    MultiZoneConfig,
    MultiZoneParams,
    MultiZoneSimulator,
    ZoneRC,
    wall_tuples,
)
from pinn_mpc.physics import PAPER_HOUSEHOLD
from pinn_mpc.simulator import SimConfig, Simulator
from pinn_mpc.zones import ZoneSpec


def building(n_zones: int, scale: float = 1.0) -> MultiZoneConfig:
    """A row of ``n_zones`` zones, capacities times ``scale``, with its actuators."""
    rc = dataclasses.replace(
        PAPER_HOUSEHOLD, c_r_j_per_k=PAPER_HOUSEHOLD.c_r_j_per_k * scale, solar_aperture_m2=4.0
    )
    zones = tuple(
        ZoneRC(zone=ZoneSpec(f"z{z}"), rc=rc, gain_share=1.0 / n_zones) for z in range(n_zones)
    )
    walls = np.zeros((n_zones, n_zones))
    for z in range(n_zones - 1):
        walls[z, z + 1] = walls[z + 1, z] = 150.0
    actuators = (
        *(ActuatorSpec(upper_w=5000.0, zone=z) for z in range(n_zones)),
        ActuatorSpec(upper_w=3000.0, zone=0, heats=False),
    )
    params = MultiZoneParams(zones=zones, wall_conductance_w_per_k=wall_tuples(walls))
    return MultiZoneConfig(params=params, actuators=actuators, backup_high_c=23.0)


def ms_per_step(n_buildings: int, n_zones: int, steps: int, *, fleet: bool) -> float:
    """Best of three runs of ``steps`` intervals, in ms per interval."""
    cfg = building(n_zones)
    rng = np.random.default_rng(0)
    buildings = [building(n_zones, s).params for s in rng.uniform(0.8, 1.2, n_buildings)] if fleet else None
    demand = rng.uniform(0.0, 1.0, (steps, n_buildings, len(cfg.actuators))) * 5000.0
    t_a = rng.uniform(-5.0, 10.0, steps)
    best = float("inf")
    for _ in range(3):
        sim = MultiZoneSimulator(cfg, n_buildings=n_buildings, fleet=buildings)
        sim.reset(19.0, 18.5)
        start = time.perf_counter()
        for k in range(steps):
            sim.step(demand[k], {"T_a": t_a[k], "G": 100.0, "I_g": 300.0})
        best = min(best, time.perf_counter() - start)
    return best / steps * 1e3


def ms_per_step_2r2c(n_buildings: int, steps: int) -> float:
    """The 2R2C simulator's best-of-three ms per interval for ``n_buildings``."""
    rng = np.random.default_rng(0)
    demand = rng.uniform(0.0, 5000.0, (steps, n_buildings))
    best = float("inf")
    for _ in range(3):
        sim = Simulator(SimConfig(), n_buildings=n_buildings)
        sim.reset(19.0, 18.5)
        sim.step(demand[0], 0.0)  # compiles (or loads) the kernel outside the clock
        start = time.perf_counter()
        for k in range(steps):
            sim.step(demand[k], 0.0, 100.0, 300.0)
        best = min(best, time.perf_counter() - start)
    return best / steps * 1e3


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=96, help="control intervals per run")
    args = parser.parse_args()
    print(f"{'B':>6} {'Z':>3} {'shared ms/step':>15} {'fleet ms/step':>14} {'2R2C x BZ ms/step':>18}")
    for n_buildings in (1, 1000):
        for n_zones in (2, 5):
            shared = ms_per_step(n_buildings, n_zones, args.steps, fleet=False)
            own = ms_per_step(n_buildings, n_zones, args.steps, fleet=True)
            ref = ms_per_step_2r2c(n_buildings * n_zones, args.steps)
            print(f"{n_buildings:>6} {n_zones:>3} {shared:>15.3f} {own:>14.3f} {ref:>18.3f}")
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average (1, 5, 15 min): {load} on {os.cpu_count()} CPUs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
