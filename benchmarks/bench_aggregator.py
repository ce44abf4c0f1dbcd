"""Time per control step of a fleet planned in one batch, uncoordinated and under a cap.

Run: ``python benchmarks/bench_aggregator.py [--rc 100,1000,10000] [--learned 100,1000]
[--steps 10] [--models 4]``.

Every figure is one building fleet of ``winter_household`` (spread 0.2) on its test day
2023-02-12 (seed 13, -1.7 .. 4.3 C: every building heats all day; the fleet benchmark of
``bench_fleet.py`` used a warm day that needs almost no heat), started at 06:00 after 30 steps
of the thermostat, then ``--steps`` control steps timed (median and p95 of the wall time of
everything the controllers do in a step: observe, plan, coordinate, commit; the plant apart):

- ``qp-mpc``: :class:`controllers.fleet.FleetQPMPC`, every building's RC MPC (its own Kalman
  observer and OSQP problem, data built in one pass), without a cap (one plan a step) and under
  a cap from 08:00 to 10:00 of 60 % of the peak the fleet plans there without it (announced at
  06:00, so the timed steps are those before and in the event; 4 dual-ascent plans a step: the
  first steps after the cap enters the horizon, while the prices move most, take longest);
- ``cem``: :class:`controllers.fleet_sampling.FleetCEM` over each building's learned hybrid in
  one batched rollout (``learned_fleet_planner``'s defaults: 32 samples x 2 CEM iterations a
  plan, 1 member planning, 5 for the disagreement, the shadow RC MPC per building; under the
  cap, as ``closed-loop --rc-candidates auto`` plans, each building's RC MPC plan scored among
  the samples of a step's first plan, one CEM iteration, the step's further plans rescoring
  the plans rolled out). The fleet's models are ``--models
  hybrids trained here on 14 days of their buildings' data, assigned round-robin: the timing
  does not depend on the weights (every building's constants are its own copy in the batch).

``--partitions P`` splits each fleet into P partitions, one Ray worker each
(:mod:`scenarios.fleets.partitions`): the driver keeps the loop and the coordination and exchanges the
observations, the prices and the plans with the workers every step.

The machine is shared (the load average is printed): read the medians.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch

from controllers.base import ControlSpec
from controllers.coordination import Coordination, DualAscent
from controllers.fleet import FleetPlanner, FleetQPMPC
from controllers.thermostat import Thermostat
from pinn_mpc.physics import RCParams
from pinn_mpc.simulator import draw_fleet
from scenarios.fleets.aggregator import learned_fleet_planner
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import build_loop, one_torch_thread, prepare_run

SCENARIO, SEED, WARMUP = "winter_household", 13, 30


def time_steps(
    make: Callable[[Sequence[RCParams]], FleetPlanner], n: int, steps: int, cap_fraction: float | None
) -> tuple[float, float, float]:
    """(median, p95) [ms] of the controllers' time per step, and the build time [s]."""
    scenario = get_scenario(SCENARIO)
    fleet = draw_fleet(scenario.sim.params, n, spread=0.2, rng=np.random.default_rng([SEED, 7]))
    run = prepare_run(scenario, days=1, seed=SEED, warmup_steps=WARMUP, weather_part="test")
    loop = build_loop(scenario, run, seed=SEED, fleet=fleet)
    thermostats = [Thermostat(scenario.control_spec()) for _ in fleet]
    for _ in range(WARMUP):
        loop.advance_fleet(thermostats)
    start = time.perf_counter()
    planner = make(fleet)
    planner.reset(SEED)
    built = time.perf_counter() - start
    coordination = None
    times = []
    for _ in range(steps):
        t0 = time.perf_counter()
        forecast = loop.forecast()
        planner.observe([loop.observation(building=i) for i in range(n)], forecast)
        if coordination is None:
            cap = np.full(len(run.series), np.inf)
            if cap_fraction is not None:  # an event 2 h ahead, for 2 h: a share of the free plan
                row = loop.start + loop.k
                free = planner.plan().power_w[:, 4:8].sum(axis=0).max()
                cap[row + 4 : row + 8] = cap_fraction * free
            coordination = Coordination(cap, DualAscent())
        decision = coordination.step(planner, loop.start + loop.k).decision
        times.append(time.perf_counter() - t0)
        loop.step(decision.u_w, decision_s=np.zeros(n), fallback=decision.fallback)
    ms = np.array(times[1:] if steps > 2 else times) * 1000.0  # the first step sets solvers up
    return float(np.median(ms)), float(np.percentile(ms, 95)), built


def _qp(fleet: Sequence[RCParams], spec: ControlSpec) -> FleetPlanner:
    return FleetQPMPC(fleet, spec)


def learned_models(n_models: int) -> list:
    from pinn_mpc import TrainConfig, train_model
    from scenarios.running.datagen import generate

    scenario = get_scenario(SCENARIO)
    fleet = draw_fleet(scenario.sim.params, n_models, spread=0.2, rng=np.random.default_rng(0))
    data = generate(scenario, days=14, seed=0, policy="random-level", n_buildings=n_models, fleet=fleet)
    config = TrainConfig(n_seeds=5, eta=scenario.sim.params.eta, u_max_w=scenario.sim.u_max_w)
    return [
        train_model(part.drop(columns="building").reset_index(drop=True), arch="hybrid",
                    config=config, progress=False)
        for _, part in data.groupby("building")
    ]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rc", default="100,1000,10000", help="qp-mpc fleet sizes")
    parser.add_argument("--learned", default="100,1000", help="learned cem fleet sizes")
    parser.add_argument("--steps", type=int, default=10, help="timed control steps (default 10)")
    parser.add_argument("--models", type=int, default=4, help="hybrids trained for the cem fleets")
    parser.add_argument(
        "--partitions", type=int, default=1,
        help="split each fleet into this many partitions, one Ray worker each (default 1: none)",
    )
    args = parser.parse_args()
    if args.partitions > 1:
        from scenarios.fleets.partitions import partitioned
        from scenarios.running.ray_engine import ray_engine

        with ray_engine(None, args.partitions):
            return run(args, lambda of, name: partitioned(of, args.partitions, name))
    return run(args, lambda of, name: of(slice(None)))


def _with_spec(factory: Any, spec: Any, fleet: Any) -> Any:
    """``factory``'s planner of ``fleet`` under the control spec ``spec``."""
    return factory(fleet, spec)


def run(args: argparse.Namespace, wrap: Callable[[Any, str], Any]) -> int:
    """Every timing of the module docstring; ``wrap`` turns the factory of a slice of the
    fleet's buildings into the planner factory timed (partitioned across Ray workers, or the
    whole fleet's)."""
    from threadpoolctl import threadpool_limits

    spec = get_scenario(SCENARIO).control_spec()
    sizes = lambda text: [int(v) for v in text.split(",") if v]  # noqa: E731
    print(f"{SCENARIO}, test day seed {SEED} (2023-02-12), from 06:00; ms per control step")
    # As the command line: one BLAS thread (the observers' and identification's matrices are small).
    with one_torch_thread(), threadpool_limits(limits=1, user_api="blas"):
        print(f"torch threads: {torch.get_num_threads()}")
        for n in sizes(args.rc):
            for cap in (None, 0.6):
                qp = wrap(lambda s: _qp, "qp-mpc")
                med, p95, built = time_steps(functools.partial(_with_spec, qp, spec), n, args.steps, cap)
                label = "capped, 4 plans" if cap else "no cap, 1 plan "
                print(f"  qp-mpc {n:6d} buildings, {label}: median {med:9.1f}  p95 {p95:9.1f}  "
                      f"(built in {built:.1f} s)")
        if sizes(args.learned):
            t0 = time.perf_counter()
            models = learned_models(args.models)
            print(f"  ({args.models} hybrids trained in {time.perf_counter() - t0:.0f} s)")
            for n in sizes(args.learned):
                fleet_models = [models[i % len(models)] for i in range(n)]
                for cap in (None, 0.6):
                    # As the command line plans (--rc-candidates auto): the RC candidates under a cap.
                    factory = wrap(
                        lambda s, fm=fleet_models, on=cap is not None: learned_fleet_planner(fm[s], rc_candidates=on),
                        "cem",
                    )
                    med, p95, built = time_steps(functools.partial(_with_spec, factory, spec), n, args.steps, cap)
                    label = "capped, 4 plans" if cap else "no cap, 1 plan "
                    print(f"  cem    {n:6d} buildings, {label}: median {med:9.1f}  p95 {p95:9.1f}  "
                          f"(built in {built:.1f} s)")
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average (1, 5, 15 min): {load} on {os.cpu_count()} CPUs; partitions "
          f"{args.partitions}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
