"""A learned model against an identified RC model, on the same training data and test days.

    python examples/learned_vs_rc.py --out out/vs

Simulates training data on the scenario's training weather, trains a PhysNet seed ensemble and
identifies the 2R2C parameters (T_m hidden) from it, then runs on the same unseen test days:
CEM over the PhysNet, the QP MPC on the identified RC, the QP MPC on the RC the PhysNet learned
(its physics block), and the oracle (the QP MPC with the true parameters and state) as the
reference. Prints the KPI table and writes it as ``table.json`` into ``--out``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from pinn_mpc import TrainConfig, export_rc, identify_rc, params_from_summary, train_model
from scenarios import (
    build_controller,
    generate,
    get_scenario,
    kpi_table_text,
    run_closed_loop,
)

#: What to compare on: a built-in scenario, days of training data and of
#: closed loop, and the seed of the data and the models (the test days use ``SEED + 1``).
SCENARIO = "winter_household"
TRAIN_DAYS, TEST_DAYS, SEED = 60, 3, 0


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="directory to write into")
    parser.add_argument("--quick", action="store_true", help="20 training days, one test day")
    args = parser.parse_args(argv)
    train_days, days = (20, 1) if args.quick else (TRAIN_DAYS, TEST_DAYS)

    scenario = get_scenario(SCENARIO)
    eta = scenario.sim.params.eta
    data = generate(scenario, days=train_days, seed=SEED, policy="random-level")
    config = TrainConfig(depth=16, n_seeds=3 if args.quick else 10,
                         epochs=40 if args.quick else None, first_seed=SEED, eta=eta,
                         u_max_w=scenario.sim.u_max_w)
    physnet = train_model(data, arch="physnet", config=config, progress=False)
    identified = identify_rc(data, eta=eta).params
    learned_rc = params_from_summary(export_rc(physnet, source="physnet"))

    n_steps = days * scenario.steps_per_day
    runs = {
        "cem / physnet": build_controller("cem", scenario, model=physnet, n_steps=n_steps),
        "qp-mpc / identified RC": build_controller("qp-mpc", scenario, rc_params=identified,
                                                   n_steps=n_steps),
        "qp-mpc / physnet RC": build_controller("qp-mpc", scenario, rc_params=learned_rc,
                                                n_steps=n_steps),
        "oracle": build_controller("oracle", scenario, n_steps=n_steps),
    }
    rows = []
    for label, controller in runs.items():
        result = run_closed_loop(scenario, controller, days=days, seed=SEED + 1, label=label)
        rows.append(result.kpis)
    for row in rows:  # the oracle ran last
        row["objective_to_oracle"] = row["objective"] / rows[-1]["objective"]
    print(kpi_table_text(rows))

    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "table.json").write_text(json.dumps(rows, indent=2) + "\n")
    print(f"wrote table.json in {args.out}")


if __name__ == "__main__":
    main()
