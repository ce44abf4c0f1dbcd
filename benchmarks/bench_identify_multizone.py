"""Multi-zone identification: fit time and parameter errors for 2 and 5 zones.

Run from the checkout (the data are the tests' :mod:`tests.multizone_data`)::

    PYTHONPATH=$PWD python benchmarks/bench_identify_multizone.py [--days 14] [--seeds 0 1 2]

The data: a building run by :class:`pinn_mpc.multizone.MultiZoneSimulator` (minute substeps,
backup thermostats at 12 and 30 C, sensor noise 0.05 C) at 30-min intervals under a synthetic
winter, every heater at a random level held 1 to 8 hours. The buildings: the
two-zone house (a south zone with windows on G_south and a north zone without, one wall of
60 W/K) and a row of five zones (each wall between neighbours 40-120 W/K, windows on the
south, east, west or north facade). The five zones are fitted twice: with every pair as a
possible wall (the default; the six pairs that do not touch should come out near 0) and with
the row's four walls given (``adjacency``).

Printed per building and seed: the fit's wall time on one core (``identify_multizone`` alone,
the data made beforehand), the worst relative error of any zone's R or C, of the solar
apertures, of the walls that exist, the largest conductance fitted where there is no wall
[W/K], the largest error of a gain share, and the worst zone's RMSE [C]; then the load
average (other work lengthens the times). Exits 0.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from threadpoolctl import threadpool_limits

from pinn_mpc.identify_multizone import identify_multizone
from tests.multizone_data import (
    DT_S,
    heater_columns,
    multizone_frame,
    row_of_zones,
    two_zone_house,
)

RC_FIELDS = ("r_ra_k_per_w", "r_rm_k_per_w", "c_r_j_per_k", "c_m_j_per_k")


def _row(name: str, params, actuators, *, days: int, seed: int, adjacency=None) -> str:
    frame = multizone_frame(params, actuators, days=days, seed=seed)
    suns = [z.solar_input if z.rc.solar_aperture_m2 > 0 else None for z in params.zones]
    with threadpool_limits(limits=1, user_api="blas"):
        start = time.perf_counter()
        result = identify_multizone(
            frame, zones=params.zone_specs, actuators=actuators, power_columns=heater_columns(actuators),
            solar_inputs=suns, dt_s=DT_S, adjacency=adjacency,
        )
        seconds = time.perf_counter() - start
    pairs = [(f, t) for f, t in zip(result.params.zones, params.zones, strict=True)]
    rc = max(abs(getattr(f.rc, k) / getattr(t.rc, k) - 1) for f, t in pairs for k in RC_FIELDS)
    sun = max(
        (abs(f.rc.solar_aperture_m2 / t.rc.solar_aperture_m2 - 1) for f, t in pairs if t.rc.solar_aperture_m2 > 0),
        default=float("nan"),
    )
    true_walls, walls = params.walls, result.params.walls
    wall = float(np.max(np.abs(walls[true_walls > 0] / true_walls[true_walls > 0] - 1)))
    no_wall = float(np.max(walls[true_walls == 0], initial=0.0))
    share = max(abs(f.gain_share - t.gain_share) for f, t in pairs)
    return (
        f"{name:<22} {seed:>4} {seconds:>7.2f} {100 * rc:>7.2f} {100 * sun:>7.2f} {100 * wall:>7.2f} "
        f"{no_wall:>9.2f} {share:>7.3f} {max(result.rmse_c):>7.3f}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=int, default=14)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    args = parser.parse_args(argv)
    house, heaters = two_zone_house(60.0)
    row, row_heaters = row_of_zones(5)
    print(f"{args.days} days of 30-min data, sensor noise 0.05 C; errors in % (share: absolute)")
    print(f"{'building':<22} {'seed':>4} {'fit s':>7} {'R,C %':>7} {'sun %':>7} {'wall %':>7} "
          f"{'no-wall W/K':>9} {'share':>7} {'rmse C':>7}")
    for seed in args.seeds:
        print(_row("2 zones", house, heaters, days=args.days, seed=seed), flush=True)
    for seed in args.seeds:
        print(_row("5 zones, every pair", row, row_heaters, days=args.days, seed=seed), flush=True)
    for seed in args.seeds:
        print(_row("5 zones, walls given", row, row_heaters, days=args.days, seed=seed, adjacency=row.walls > 0), flush=True)
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; python {sys.version.split()[0]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
