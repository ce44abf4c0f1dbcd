"""Decision time of random shooting and CEM at a 48-step horizon.

    python benchmarks/bench_planners.py [--model hybrid|physnet|pcnn|pcnn-parx|parx|arx|rc|all] [--members 10] [--decisions 20] [--guard] [--scenario winter_household]

Data: the ``winter_household`` scenario (``--scenario``: another, e.g. ``heat_pump_household``,
whose data's ``cop`` column the hybrid and the consistent families apply) under the random-level
policy. ``hybrid`` (the model
``train`` makes by default and ``compare`` recommends), ``physnet`` and the physically
consistent ``pcnn`` and ``pcnn-parx`` train an ensemble shaped
as ``pinn-mpc compare`` trains it (10 members, depth 16: the models whose decisions the
comparison reports) for a few epochs (decision time does not depend on how well
it is trained; the network sizes are the paper's); ``parx`` and ``arx`` are the least-squares
ARX models (``train --arch parx|arx``; ``parx`` is what ``train``'s default chooses where the
hybrid predicts worse), fitted on the same data; ``rc`` is the exact 2R2C physics
(:class:`RCBatchModel`). CEM runs with its defaults, LP polish and offset included.
Each controller makes ``--decisions`` consecutive warm-started decisions along the data
(after two untimed ones); the median / p95 wall-clock decision time and the median CPU time
of the process are printed with the load average: on a shared machine the wall time grows
with the load, the CPU time much less, so the verdict on the target is on the CPU time (on an
idle core the two agree). One intra-op torch thread: the tensors are small and
the machine's 2 cores are shared.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

import numpy as np
import pandas as pd
import torch

from controllers.base import ControlSpec, Forecast, Observation
from controllers.planners import CEMPlanner
from controllers.sampling import CEM, RandomShooting
from pinn_mpc.models.rc import RCBatchModel
from pinn_mpc.models.rollout import BatchDynamics
from scenarios.experiments.compare import CompareSettings
from scenarios.inputs.exogenous import time_of_day_h
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate

TARGET_MS = 30.0  # CPU time of a CEM decision (issue 10)
_CEM = CEMPlanner(lower=0.0, upper=1.0)  # the defaults
_COMPARE = CompareSettings(train_days=1, test_days=1, seed=0)  # the comparison's model shape


def _observation(df: pd.DataFrame, k: int, spec: ControlSpec) -> tuple[Observation, Forecast]:
    """Observation at row k (history rows 0..k) and the forecast of rows k..k+H-1."""
    tod = time_of_day_h(df["time"])
    h = spec.horizon_steps
    history = {c: df[c].to_numpy(dtype=float)[: k + 1] for c in ("T_r", "T_m", "T_a")}
    history.update({c: df[c].to_numpy(dtype=float)[:k] for c in ("u", "u_phys")})
    for c in ("G", "I_g"):
        history[c] = df[c].to_numpy(dtype=float)[: k + 1] if c in df else np.zeros(k + 1)
    history["time_of_day_h"] = tod[: k + 1]
    dow = df["day_of_week"].to_numpy(dtype=float)  # the ARX's schedule reads the calendar
    history["day_of_week"] = dow[: k + 1]
    col = {
        c: df[c].to_numpy(dtype=float)[k : k + h] if c in df else np.zeros(h)
        for c in ("T_a", "G", "I_g", "price", "T_min", "T_max")
    }
    forecast = Forecast(time_of_day_h=tod[k : k + h], day_of_week=dow[k : k + h], **col)
    obs = Observation.from_history(k, history, 0.0)
    return obs, forecast


def _time_decisions(
    controller: CEM | RandomShooting, df: pd.DataFrame, first: int, n: int
) -> tuple[np.ndarray, np.ndarray, int]:
    """Wall and CPU times [ms] of n timed decisions after two untimed warm-up decisions, and
    how many of them the guard's RC MPC made. Without a guard a fallback is an error: the
    time would not be the planner's."""
    controller.reset(seed=0)
    times, cpu_times = [], []
    fallbacks = 0
    for i in range(n + 2):
        obs, forecast = _observation(df, first + i, controller.spec)
        start, cpu_start = time.perf_counter(), time.process_time()
        controller.act(obs, forecast)
        elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu_start
        fallbacks += controller.last_stats.fallback
        if i >= 2:
            times.append(elapsed * 1000.0)
            cpu_times.append(cpu * 1000.0)
    if fallbacks and controller.shadow is None:
        status = controller.last_stats.status
        raise RuntimeError(f"{controller.name}: {fallbacks} fallbacks, last: {status}")
    return np.array(times), np.array(cpu_times), fallbacks


def _learned(arch: str, data: pd.DataFrame, members: int, epochs: int, eta: float) -> BatchDynamics:
    from pinn_mpc.training import TrainConfig, train_model

    config = TrainConfig(depth=_COMPARE.depth, n_seeds=members, epochs=epochs, eta=eta)
    return train_model(data, arch=arch, config=config, progress=False)


def _linear(name: str, data: pd.DataFrame) -> BatchDynamics:
    from pinn_mpc.models.arx import fit_linear

    return fit_linear(name, data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", choices=["hybrid", "physnet", "pcnn", "pcnn-parx", "parx", "arx", "rc", "all"], default="all")
    parser.add_argument("--members", type=int, default=_COMPARE.n_seeds)
    parser.add_argument("--epochs", type=int, default=2)
    parser.add_argument("--decisions", type=int, default=20)
    parser.add_argument("--samples", type=int, default=_CEM.n_samples, help="CEM samples")
    parser.add_argument("--iters", type=int, default=_CEM.n_iters, help="CEM iterations")
    parser.add_argument(
        "--guard", action="store_true",
        help="learned models also with their RC fallback (the shadow QP MPC and the replays)",
    )
    parser.add_argument("--scenario", default="winter_household", help="the scenario whose data the models learn")
    args = parser.parse_args()
    torch.set_num_threads(1)

    scenario = get_scenario(args.scenario)
    eta = scenario.sim.params.eta
    spec = scenario.control_spec()
    df = generate(scenario, days=8, seed=0, policy=_COMPARE.policy)
    data = df.drop(columns=["T_m"])  # what a model learns from: the measured columns
    df["day_of_week"] = pd.to_datetime(df["time"]).dt.day_of_week.astype(float)
    models: dict[str, Callable[[], BatchDynamics]] = {
        "rc": lambda: RCBatchModel(
            scenario.sim.params,
            dt_s=spec.dt_s,
            actuator=spec.actuator,
            backup_low_c=scenario.sim.backup_low_c,
            backup_high_c=scenario.sim.backup_high_c,
        ),
        "hybrid": lambda: _learned("hybrid", data, args.members, args.epochs, eta),
        "physnet": lambda: _learned("physnet", data, args.members, args.epochs, eta),
        "pcnn": lambda: _learned("pcnn", data, args.members, args.epochs, eta),
        "pcnn-parx": lambda: _learned("pcnn-parx", data, args.members, args.epochs, eta),
        "parx": lambda: _linear("parx", data),
        "arx": lambda: _linear("arx", data),
    }
    names = list(models) if args.model == "all" else [args.model]
    print(f"horizon {spec.horizon_steps} steps, torch threads {torch.get_num_threads()}")
    for name in names:
        model = models[name]()
        label = f"{name} x{model.n_members}"
        controllers: list[tuple[str, CEM | RandomShooting]] = [
            ("", CEM(model, spec, n_samples=args.samples, n_iters=args.iters)),
            ("", RandomShooting(model, spec)),
        ]
        if args.guard and name != "rc":
            from scenarios.running.factory import model_guard

            guard = model_guard(model)
            controllers += [
                (" +guard", CEM(model, spec, n_samples=args.samples, n_iters=args.iters, guard=guard)),
                (" +guard", RandomShooting(model, spec, guard=guard)),
            ]
        for suffix, controller in controllers:
            ms, cpu_ms, fallbacks = _time_decisions(controller, df, first=24, n=args.decisions)
            p = controller.planner
            size = f"{p.n_samples} samples x {getattr(p, 'n_iters', 1)} iters"
            verdict = ""
            if controller.name == "cem":
                over = np.median(cpu_ms) > TARGET_MS
                verdict = f"  OVER {TARGET_MS:.0f} ms cpu" if over else "  OK"
            print(
                f"{label:12s} {controller.name + suffix:22s} {size:22s} median {np.median(ms):6.1f} ms"
                f"  p95 {np.percentile(ms, 95):6.1f} ms  cpu {np.median(cpu_ms):6.1f} ms"
                f"  load {os.getloadavg()[0]:.1f}{verdict}"
                + (f"  ({fallbacks} by the RC MPC)" if fallbacks else "")
            )


if __name__ == "__main__":
    main()
