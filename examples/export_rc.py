"""The R/C values a PhysNet learned, with units, against identification and the truth.

    python examples/export_rc.py --out out/rc

Trains a PhysNet seed ensemble on simulated data, exports the 2R2C its physics block learned
(geometric mean over the members), identifies the 2R2C from the same data by grey-box fitting
(T_m hidden), and prints both next to the scenario's true values with their relative errors.
Writes ``rc_physnet.json`` and ``rc_identified.json`` (the schema ``--rc`` reads) into ``--out``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from pinn_mpc import TrainConfig, export_rc, identify_rc, rc_summary, train_model
from scenarios import generate, get_scenario, scenario_names

#: (rc.json key, label with its unit)
QUANTITIES = (
    ("R_ra_K_per_W", "R_ra [K/W]"),
    ("R_rm_K_per_W", "R_rm [K/W]"),
    ("C_r_J_per_K", "C_r [J/K]"),
    ("C_m_J_per_K", "C_m [J/K]"),
)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="directory to write into")
    parser.add_argument("--scenario", default="paper_household", choices=scenario_names())
    parser.add_argument("--train-days", type=int, default=60)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="small data and model")
    args = parser.parse_args(argv)

    scenario = get_scenario(args.scenario)
    eta = scenario.sim.params.eta
    data = generate(scenario, days=20 if args.quick else args.train_days, seed=args.seed,
                    policy="random-level")
    config = TrainConfig(n_seeds=3 if args.quick else 10, epochs=40 if args.quick else None,
                         first_seed=args.seed, eta=eta, u_max_w=scenario.sim.u_max_w)
    physnet = train_model(data, arch="physnet", config=config, progress=False)
    rc = {
        "physnet": export_rc(physnet, source=f"physnet on {args.scenario}"),
        "identified": rc_summary(identify_rc(data, eta=eta).params, source="identify"),
    }
    true = rc_summary(scenario.sim.params, source=f"scenario {args.scenario}")

    print(f"{'':12}{'true':>11}{'physnet':>11}{'error':>8}{'identified':>12}{'error':>8}")
    for key, label in QUANTITIES:
        cells = [f"{true[key]:11.4g}"]
        for source in ("physnet", "identified"):
            value = rc[source][key]
            cells.append(f"{value:{11 if source == 'physnet' else 12}.4g}")
            cells.append(f"{100 * (value / true[key] - 1):+7.1f}%")
        print(f"{label:12}" + "".join(cells))

    args.out.mkdir(parents=True, exist_ok=True)
    for source, summary in rc.items():
        (args.out / f"rc_{source}.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(f"wrote rc_physnet.json, rc_identified.json in {args.out}")


if __name__ == "__main__":
    main()
