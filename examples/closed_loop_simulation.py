"""One controller on one scenario: the KPIs printed, the KPI JSON, trajectory CSV and a figure
written into ``--out``.

    python examples/closed_loop_simulation.py --out out/loop
    python examples/closed_loop_simulation.py --out out/loop --scenario cold_storage --controller cem

Controllers over a learned model (``cem``, ``random-shooting``) get a PhysNet trained here on
the scenario's training weather; the RC MPCs (``qp-mpc``, ``casadi-mpc``) get 2R2C parameters
identified from the same data; the others need nothing. The run is judged on the scenario's
test weather, which shares no day with the training data.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from pinn_mpc import TrainConfig, identify_rc, train_model, write_timeseries
from scenarios import (
    CONTROLLER_NAMES,
    build_controller,
    format_kpis,
    generate,
    get_scenario,
    plot_trajectory,
    run_closed_loop,
    scenario_names,
)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="directory to write into")
    parser.add_argument("--scenario", default="winter_household", choices=scenario_names())
    parser.add_argument("--controller", default="qp-mpc", choices=CONTROLLER_NAMES)
    parser.add_argument("--days", type=int, default=3, help="counted closed-loop days")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="small data and model, one day")
    args = parser.parse_args(argv)
    days = 1 if args.quick else args.days

    scenario = get_scenario(args.scenario)
    n_steps = days * scenario.steps_per_day
    model = rc_params = None
    if args.controller in ("cem", "random-shooting", "qp-mpc", "casadi-mpc"):
        data = generate(scenario, days=20 if args.quick else 60, seed=args.seed,
                        policy="random-level")
        if args.controller in ("cem", "random-shooting"):
            config = TrainConfig(depth=16, n_seeds=3 if args.quick else 10,
                                 epochs=40 if args.quick else None, first_seed=args.seed,
                                 eta=scenario.sim.params.eta, u_max_w=scenario.sim.u_max_w)
            model = train_model(data, arch="physnet", config=config, progress=False)
        else:
            rc_params = identify_rc(data, eta=scenario.sim.params.eta).params
    controller = build_controller(args.controller, scenario, model=model, rc_params=rc_params,
                                  n_steps=n_steps)
    result = run_closed_loop(scenario, controller, days=days, seed=args.seed + 1)
    print(format_kpis(result.kpis))

    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "kpis.json").write_text(json.dumps(result.kpis, indent=2) + "\n")
    write_timeseries(result.trajectory, args.out / "trajectory.csv")
    plot_trajectory(result.trajectory, args.out / "trajectory.png",
                    title=f"{args.controller} on {args.scenario}")
    print(f"wrote kpis.json, trajectory.csv, trajectory.png in {args.out}")


if __name__ == "__main__":
    main()
