"""Per-building models against a fleet-pretrained, per-building fine-tuned model, from 14 days.

Run: ``python benchmarks/bench_fleet_models.py [--buildings 12] [--days 14] [--fine-tune-epochs 20]``.

A fleet of ``winter_household`` buildings (spread 0.2) is simulated for ``--days`` days of the
training weather (random-level policy) and 7 days of the test weather. Two ways to a model per
building, both the default architecture (hybrid, 5 members):

- per building: each building's model trained on its own data alone (the default recipe);
- fleet-pretrained, fine-tuned: one model trained on every building's data pooled, then each
  building's model started from its residual net and backup thermostat (the physics block at the
  building's own identification) and trained ``--fine-tune-epochs`` epochs on its own data.

Printed: the 24-step (12 h) recursive T_r MAE on each building's test week (mean over the
buildings and the worst one) and the training wall time of each way, on one core (one torch
thread; the machine's load average is printed: other work lengthens the times).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import torch

from pinn_mpc import TrainConfig, train_model
from pinn_mpc.evaluation import evaluate_model
from pinn_mpc.simulator import draw_fleet
from scenarios.fleets.training import building_frames, pretrain_and_fine_tune
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate

SCENARIO, HORIZON = "winter_household", 24


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--buildings", type=int, default=12)
    parser.add_argument("--days", type=int, default=14)
    parser.add_argument("--fine-tune-epochs", type=int, default=20)
    args = parser.parse_args()
    torch.set_num_threads(1)
    scenario = get_scenario(SCENARIO)
    fleet = draw_fleet(scenario.sim.params, args.buildings, spread=0.2, rng=np.random.default_rng(0))
    train = building_frames(generate(scenario, days=args.days, seed=0, policy="random-level",
                                     n_buildings=args.buildings, fleet=fleet))
    test = building_frames(generate(scenario, days=7, seed=1, policy="random-level",
                                    n_buildings=args.buildings, fleet=fleet, weather_part="test"))
    config = TrainConfig(n_seeds=5, eta=scenario.sim.params.eta, u_max_w=scenario.sim.u_max_w)

    def mae(model, b: int) -> float:
        return float(evaluate_model(model, test[b], [HORIZON])["horizons"][str(HORIZON)]["T_r_mae"])

    start = time.perf_counter()
    own = [train_model(train[b], arch="hybrid", config=config, progress=False) for b in sorted(train)]
    own_s = time.perf_counter() - start
    tuned, seconds = pretrain_and_fine_tune(
        [train[b] for b in sorted(train)], config=config, fine_tune_epochs=args.fine_tune_epochs
    )
    rows = [("per building", own, own_s, ""),
            ("fleet-pretrained, fine-tuned", tuned, seconds["pretrain"] + seconds["fine_tune"],
             f" (pre-training {seconds['pretrain']:.0f} s, fine-tuning {seconds['fine_tune']:.0f} s)")]
    print(f"{args.buildings} {SCENARIO} buildings (spread 0.2), {args.days} training days each, "
          f"{HORIZON}-step T_r MAE on a test week")
    for label, models, wall, detail in rows:
        errors = np.array([mae(m, b) for b, m in zip(sorted(train), models, strict=True)])
        print(f"  {label:30s} MAE mean {errors.mean():.3f} K, worst {errors.max():.3f} K "
              f"(building {int(np.argmax(errors))}); training {wall:.0f} s, "
              f"{wall / args.buildings:.1f} s per building{detail}")
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average (1, 5, 15 min): {load} on {os.cpu_count()} CPUs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
