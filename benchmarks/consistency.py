"""Physical consistency of every model family (issue 44): the share of random draws in which
every predicted T_r is non-decreasing in each heating power (non-increasing in each cooling
power) and in each outdoor temperature (:mod:`pinn_mpc.consistency`).

Each family is fitted once on 14 days of ``simulate`` data (the scenario's default policy,
seed 0) of ``winter_household`` (heating) and ``cold_storage`` (cooling) (``--scenarios``:
others, e.g. ``heat_pump_household``, whose data's ``cop`` column the hybrid and the consistent
families apply), as ``train --arch`` fits it with 3 members; 200 draws each, on the same data's
histories, horizon 48.

    python benchmarks/consistency.py [--draws 200] [--json out.json] [--scenarios A,B]
"""

from __future__ import annotations

import argparse
import json
import warnings

import numpy as np

from pinn_mpc.consistency import check_draw, draw
from pinn_mpc.data import validate_timeseries
from pinn_mpc.fitted import fit
from pinn_mpc.models.registry import MODEL_CHOICES
from pinn_mpc.training import TrainConfig
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate

HORIZON = 48
SCENARIOS = ("winter_household", "cold_storage")


def measure(n_draws: int, scenarios: tuple[str, ...] = SCENARIOS) -> list[dict[str, object]]:
    rows: list[dict[str, object]] = []
    for name in scenarios:
        scenario = get_scenario(name)
        df = validate_timeseries(generate(scenario, days=14, seed=0, policy=scenario.data_policy), source=name)
        eta = scenario.sim.params.eta
        u_max = float(df["u_phys"].max())
        for family in MODEL_CHOICES:
            model = fit(df, arch=family, config=TrainConfig(n_seeds=3, eta=eta)).model
            rng = np.random.default_rng(0)
            results = [
                check_draw(model, df, draw(rng, n_rows=len(df), first=64, horizon=HORIZON, u_max_w=u_max))
                for _ in range(n_draws)
            ]
            power = float(np.mean([p for p, _ in results]))
            t_a = float(np.mean([t for _, t in results]))
            both = float(np.mean([p and t for p, t in results]))
            rows.append({"scenario": name, "family": family, "power": power, "t_a": t_a, "both": both})
            print(f"{name:18s} {family:10s} power {power:6.1%}  T_a {t_a:6.1%}  both {both:6.1%}", flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=200)
    parser.add_argument("--json", default=None)
    parser.add_argument("--scenarios", default=",".join(SCENARIOS), help="comma-separated scenario names")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    rows = measure(args.draws, tuple(args.scenarios.split(",")))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(rows, fh, indent=2)


if __name__ == "__main__":
    main()
