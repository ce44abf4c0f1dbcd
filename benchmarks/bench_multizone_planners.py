"""Decision time of ``cem`` over a multi-zone RC building: median and 95th percentile [ms] of
its decisions in a closed loop of 2, 5 and 12 zones, each zone with a heater and a cooler
(A = 2Z), horizon H = 48, with the default samples, iterations and LP polish
(:class:`controllers.sampling.CEM` over :class:`pinn_mpc.models.multizone_rc.MultiZoneRCModel`
of the true building, :mod:`controllers.zone_sampling`).

Run from the checkout: ``PYTHONPATH=. python benchmarks/bench_multizone_planners.py [--steps 96]
[--zones 2,5,12] [--planner cem]``. The buildings, the weather and the loop are
``bench_multizone_mpc.py``'s (its oracle run beside, for the objective's ratio). Torch runs on
one thread, as ``closed-loop`` runs the planners. Prints one line per Z: the planner's decision
times, its median iterations (sampling iterations plus LPs), its fallbacks, the run's objective
(energy cost plus the scenario default's 1 EUR/(K h) times the discomfort) and its ratio to the
oracle's; then the load average. Exits 0.
"""

from __future__ import annotations

import sys

import numpy as np
import torch

from benchmarks.bench_multizone_mpc import building, closed_loop, print_rows, zones_parser
from controllers.rc_mpc.references import oracle_multizone
from controllers.sampling import CEM, RandomShooting
from pinn_mpc.models.multizone_rc import MultiZoneRCModel


def run(n_zones: int, steps: int, planner: str) -> dict[str, float]:
    """The planner's and the oracle's closed loops of ``steps`` decisions on the building of
    ``n_zones`` zones."""
    params, spec = building(n_zones)
    model = MultiZoneRCModel(params, spec.actuators, spec.dt_s, backup_low_c=10.0, backup_high_c=35.0)
    controller = (CEM if planner == "cem" else RandomShooting)(model, spec)
    controller.reset(seed=0)
    loop = closed_loop(params, spec, controller, steps)
    reference = closed_loop(params, spec, oracle_multizone(params, spec), steps)
    weight = spec.comfort_weight_eur_per_kh
    objective = loop.energy_cost_eur + weight * loop.discomfort_kh
    ms = loop.times_s * 1e3
    return {
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
        "iterations": float(np.median(loop.iterations)),
        "fallbacks": controller.n_fallbacks,
        "objective": objective,
        "ratio": objective / (reference.energy_cost_eur + weight * reference.discomfort_kh),
    }


def main(argv: list[str] | None = None) -> int:
    parser = zones_parser(__doc__)
    parser.add_argument("--planner", choices=("cem", "random-shooting"), default="cem")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)

    def row(z: int) -> str:
        r = run(z, args.steps, args.planner)
        return (
            f"{z:>3} {2 * z:>3} {r['median_ms']:>10.1f} {r['p95_ms']:>8.1f} {r['iterations']:>5.0f} "
            f"{r['fallbacks']:>9} {r['objective']:>13.3f} {r['ratio']:>8.4f}"
        )

    print_rows(f"{'Z':>3} {'A':>3} {'median ms':>10} {'p95 ms':>8} {'iter':>5} {'fallbacks':>9} {'objective EUR':>13} {'/ oracle':>8}", args.zones, row)
    return 0


if __name__ == "__main__":
    sys.exit(main())
