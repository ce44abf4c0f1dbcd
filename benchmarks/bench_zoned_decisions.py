"""Decision time of ``qp-mpc`` and ``cem`` on the built-in buildings of several zones: median
and 95th percentile [ms] of their decisions in a closed loop, on ``two_zone_house`` (2 zones, 2
heaters; planned on its true building), ``eplus_small_office_zones`` (5 zones, 10 actuators)
and ``eplus_medium_office_zones`` (15 zones, 30 actuators), the EnergyPlus ones planned on
their multi-zone RC file (``identify --scenario``), horizon 48.

Run from the checkout: ``PYTHONPATH=. python benchmarks/bench_zoned_decisions.py [--days 1]
[--rc eplus_small_office_zones=small_rc.json] [--rc eplus_medium_office_zones=medium_rc.json]``.
A building of EnergyPlus without ``--rc`` is skipped (one line says so). Each run is
``closed-loop``'s (:func:`scenarios.running.closed_loop.run_closed_loop`, seed 0, its plant,
forecast and warm-up; torch on one thread) with the controller ``closed-loop --controller
<name> --rc <file>`` builds. Prints one line per building and controller: zones, actuators,
the decision times (the run's, wall clock, and the CPU time of the deciding thread, which
other jobs on a shared machine inflate less), the fallbacks and the run's objective [EUR];
then the load average.
Exits 0.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

from controllers.base import Forecast, Observation
from pinn_mpc.multizone import MultiZoneParams
from scenarios import get_scenario
from scenarios.running.closed_loop import one_torch_thread, run_closed_loop
from scenarios.running.factory import build_controller, read_zone_rc

BUILDINGS = ("two_zone_house", "eplus_small_office_zones", "eplus_medium_office_zones")
CONTROLLERS = ("qp-mpc", "cem")


def _rc_files(pairs: list[str]) -> dict[str, str]:
    """``--rc SCENARIO=PATH`` pairs as a mapping."""
    files = {}
    for pair in pairs:
        name, sep, path = pair.partition("=")
        if not sep or name not in BUILDINGS:
            raise SystemExit(f"--rc {pair!r}: give SCENARIO=PATH, SCENARIO one of {', '.join(BUILDINGS)}")
        files[name] = path
    return files


def _building(name: str, rc_files: dict[str, str]) -> MultiZoneParams | None:
    """The multi-zone RC the controllers plan on: the RC plant's own, else the file's (None
    without one)."""
    scenario = get_scenario(name)
    own = getattr(scenario.plant.settings, "building", None)
    if isinstance(own, MultiZoneParams):
        return own
    if name not in rc_files:
        return None
    return read_zone_rc(rc_files[name], scenario.control_spec(), name)


def run(name: str, controller: str, params: MultiZoneParams, days: int) -> dict[str, float]:
    """One closed loop of ``days`` days; the decision times and the run's figures."""
    scenario = get_scenario(name)
    built = build_controller(controller, scenario, zone_params=params, n_steps=days * 48)
    cpu_s: list[float] = []
    act = built.act

    def timed(obs: Observation, forecast: Forecast) -> float | np.ndarray:
        start = time.thread_time()
        action = act(obs, forecast)
        cpu_s.append(time.thread_time() - start)
        return action

    built.act = timed  # type: ignore[method-assign]
    with one_torch_thread():  # as closed-loop runs the planners
        result = run_closed_loop(scenario, built, days=days, seed=0)
    ms = result.trajectory["decision_ms"].to_numpy(dtype=float)
    cpu_ms = 1e3 * np.array(cpu_s[-len(ms) :])  # the counted decisions (the warm-up's thermostat is another)
    return {
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
        "cpu_median_ms": float(np.median(cpu_ms)),
        "cpu_p95_ms": float(np.percentile(cpu_ms, 95)),
        "fallbacks": float(result.kpis["fallbacks"]),
        "objective": float(result.kpis["objective"]),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=int, default=1, help="counted days per run (default 1: 48 decisions)")
    parser.add_argument("--rc", action="append", default=[], metavar="SCENARIO=PATH",
                        help="the multi-zone RC file of an EnergyPlus building (repeat per building)")
    parser.add_argument("--buildings", default=",".join(BUILDINGS), help="comma-separated built-ins")
    args = parser.parse_args(argv)
    rc_files = _rc_files(args.rc)
    print(
        f"{'building':<26} {'Z':>3} {'A':>3} {'controller':<10} {'median ms':>10} {'p95 ms':>8} "
        f"{'cpu median':>10} {'cpu p95':>8} {'fallbacks':>9} {'objective EUR':>13}"
    )
    for name in args.buildings.split(","):
        params = _building(name, rc_files)
        spec = get_scenario(name).control_spec()
        if params is None:
            print(f"{name:<26} skipped: give --rc {name}=<file of `pinn-mpc identify --scenario {name}`>")
            continue
        for controller in CONTROLLERS:
            r = run(name, controller, params, args.days)
            print(
                f"{name:<26} {len(spec.zones):>3} {spec.n_actuators:>3} {controller:<10} {r['median_ms']:>10.1f} "
                f"{r['p95_ms']:>8.1f} {r['cpu_median_ms']:>10.1f} {r['cpu_p95_ms']:>8.1f} {r['fallbacks']:>9.0f} "
                f"{r['objective']:>13.3f}",
                flush=True,
            )
    print(f"load average: {', '.join(f'{v:.2f}' for v in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
