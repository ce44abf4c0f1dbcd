"""Multi-zone QP MPC decision time: median and 95th percentile [ms] of the decisions of the
oracle (:func:`controllers.rc_mpc.references.oracle_multizone`, qp-mpc's OSQP) and of casadi-mpc
(:class:`controllers.rc_mpc.multizone_casadi.MultiZoneCasadiMPC`, the same problem by
``casadi.qpsol``) on the true state, in a closed loop of 2, 5 and 15 zones, each zone with a
heater and a cooler (A = 2Z), horizon H = 48.

Run: ``python benchmarks/bench_multizone_mpc.py [--steps 96] [--zones 2,5,15] [--horizon 48]
[--controllers qp-mpc,casadi-mpc] [--eps 1e-3]``.
Each building is a row of Z zones of a light 2R2C (``R_ra`` 5 mK/W, ``C_m`` 1e7 J/K), each
wall between neighbours 150 W/K, odd zones facing south (``G_south``), in spring weather (nights
near 5 C, sunny afternoons near 21 C) with a 20-22 C band, so both machines of a zone work
within a day; the loop steps :class:`pinn_mpc.multizone.MultiZoneSimulator` and warm-starts the
solver as a run does. ``--eps`` sets OSQP's ``eps_abs`` and ``eps_rel`` for both (the default is
:data:`controllers.rc_mpc.osqp.OSQP_OPTIONS`'). Prints one line per Z and controller: the QP's
size, the controller's construction time [s], the decision times, OSQP's median iterations
(0: CasADi's plugin does not report them), the fallbacks, the discomfort [K h] and the energy
cost [EUR] of the run; then the load average. Exits 0.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from controllers.base import Controller, ControlSpec, Forecast, Observation
from controllers.rc_mpc.multizone import MultiZoneMPC
from controllers.rc_mpc.multizone_casadi import MultiZoneCasadiMPC
from controllers.rc_mpc.references import oracle_multizone
from pinn_mpc.actuator import ActuatorSpec, actuator_columns
from pinn_mpc.multizone import (
    MultiZoneConfig,
    MultiZoneParams,
    MultiZoneSimulator,
    ZoneRC,
    wall_tuples,
)
from pinn_mpc.physics import RCParams
from pinn_mpc.zones import ZoneSpec, zone_columns

LIGHT = RCParams(
    r_ra_k_per_w=5e-3, r_rm_k_per_w=1e-3, c_r_j_per_k=2e6, c_m_j_per_k=1e7,
    solar_aperture_m2=3.0, solar_to_air_fraction=0.4,
)
INPUTS = ("T_a", "G", "I_g", "G_south")


def building(n_zones: int) -> tuple[MultiZoneParams, ControlSpec]:
    """A row of ``n_zones`` zones, each with a heater and a cooler."""
    zones = tuple(
        ZoneRC(zone=ZoneSpec(f"z{z}"), rc=LIGHT, gain_share=1.0 / n_zones, solar_input="G_south" if z % 2 else "G")
        for z in range(n_zones)
    )
    walls = np.zeros((n_zones, n_zones))
    for z in range(n_zones - 1):
        walls[z, z + 1] = walls[z + 1, z] = 150.0
    params = MultiZoneParams(zones=zones, wall_conductance_w_per_k=wall_tuples(walls))
    actuators = tuple(
        ActuatorSpec(upper_w=power, zone=z, heats=heats, name=f"{kind}{z}")
        for z in range(n_zones)
        for kind, heats, power in (("heat", True, 4000.0), ("cool", False, 3000.0))
    )
    return params, ControlSpec(actuators=actuators, zones=params.zone_specs, horizon_steps=48)


def spring(n: int) -> dict[str, np.ndarray]:
    """n half-hour steps of spring weather, a flat-ish price and a 20-22 C band."""
    hours = (np.arange(n) * 0.5) % 24.0
    daylight = np.maximum(0.0, np.sin(np.pi * (hours - 7.0) / 10.0))
    return {
        "time_of_day_h": hours,
        "T_a": 13.0 + 8.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0),
        "G": 650.0 * daylight,
        "I_g": np.where((hours >= 7) & (hours < 22), 400.0, 150.0),
        "G_south": 975.0 * daylight,
        "price": np.where((hours > 17) & (hours < 21), 0.45, np.where(hours < 6, 0.12, 0.25)),
        "T_min": np.full(n, 20.0),
        "T_max": np.full(n, 22.0),
    }


class LoopRun(NamedTuple):
    """What a closed loop of a controller over a building measured."""

    times_s: np.ndarray  # (K,) each decision's time
    iterations: np.ndarray  # (K,) each decision's solver iterations
    discomfort_kh: float  # every zone's band violation, integrated over the substeps
    energy_cost_eur: float  # the price times the delivered electrical energy


def closed_loop(params: MultiZoneParams, spec: ControlSpec, controller: Controller, steps: int) -> LoopRun:
    """``steps`` decisions of ``controller`` on the building in :func:`spring` weather, its
    observation's history holding each zone's room, each actuator's delivered power and the
    inputs, as a run's does."""
    series = spring(steps + spec.horizon_steps + 1)
    sim = MultiZoneSimulator(MultiZoneConfig(params=params, actuators=spec.actuators, backup_low_c=10.0, backup_high_c=35.0))
    sim.reset(21.0, 20.5)
    rooms = zone_columns("T_r", params.zone_specs)
    powers = actuator_columns("u_phys", spec.actuators)
    history = {c: np.array([t]) for c, t in zip(rooms, sim.measure()[0], strict=True)}
    history |= {name: series[name][:1] for name in ("time_of_day_h", *INPUTS)}
    history |= {c: np.zeros(0) for c in (*powers, "u_phys")}
    times, iterations, discomfort, cost = [], [], 0.0, 0.0
    for k in range(steps):
        obs = Observation.from_history(k, history, sim.state[0, params.n_zones :], zones=params.zone_specs)
        forecast = Forecast(**{name: v[k : k + spec.horizon_steps + 1] for name, v in series.items()})
        action = controller.act(obs, forecast)
        times.append(controller.last_stats.time_s)
        iterations.append(controller.last_stats.iterations)
        step = sim.step(action, {name: series[name][k] for name in INPUTS})
        over = np.maximum(series["T_min"][k] - step.t_r_sub_c, 0) + np.maximum(step.t_r_sub_c - series["T_max"][k], 0)
        discomfort += float(over.mean(axis=1).sum()) * spec.dt_h
        cost += float(step.power_w.sum()) / 1000.0 * spec.dt_h * float(series["price"][k])
        for c, v in zip(rooms, sim.measure()[0], strict=True):
            history[c] = np.append(history[c], v)
        for c, v in zip((*powers, "u_phys"), (*step.power_w[0], step.power_w.sum()), strict=True):
            history[c] = np.append(history[c], v)
        for name in ("time_of_day_h", *INPUTS):
            history[name] = series[name][: k + 2]
    return LoopRun(np.array(times), np.array(iterations), discomfort, cost)


def run(n_zones: int, steps: int, eps: float | None, controller: str = "qp-mpc", horizon: int = 48) -> dict[str, float]:
    """A closed loop of ``steps`` decisions of ``controller`` (``qp-mpc``: the oracle,
    ``casadi-mpc``) over horizon ``horizon``; the decision times and the run's figures."""
    params, spec = building(n_zones)
    spec = dataclasses.replace(spec, horizon_steps=horizon)
    options = {} if eps is None else {"eps_abs": eps, "eps_rel": eps}
    start = time.perf_counter()
    mpc: MultiZoneMPC
    if controller == "casadi-mpc":
        mpc = MultiZoneCasadiMPC(params, spec, estimator="true", solver_options={"osqp": options})
    elif controller == "qp-mpc":
        mpc = oracle_multizone(params, spec, solver_options=options)
    else:
        raise ValueError(f"bench_multizone_mpc: controller {controller!r} is unknown; choose qp-mpc or casadi-mpc")
    build_s = time.perf_counter() - start
    loop = closed_loop(params, spec, mpc, steps)
    ms = loop.times_s * 1e3
    return {
        "variables": mpc.qp.n_variables,
        "build_s": build_s,
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
        "iterations": float(np.median(loop.iterations)),
        "fallbacks": mpc.n_fallbacks,
        "discomfort_kh": loop.discomfort_kh,
        "cost_eur": loop.energy_cost_eur,
    }


def zones_parser(doc: str) -> argparse.ArgumentParser:
    """The options of a benchmark over zone counts: ``--steps`` and ``--zones``."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--steps", type=int, default=96, help="decisions per building (default 96, two days)")
    parser.add_argument("--zones", default="2,5,12", help="comma-separated zone counts")
    return parser


def print_rows(header: str, zones: str, row: Callable[[int], str]) -> None:
    """The header, one row per zone count of ``zones`` (comma-separated), the load average."""
    print(header)
    for z in (int(v) for v in zones.split(",")):
        print(row(z))
    print(f"load average: {', '.join(f'{v:.2f}' for v in os.getloadavg())}")


def main(argv: list[str] | None = None) -> int:
    parser = zones_parser(__doc__)
    parser.add_argument("--eps", type=float, default=None, help="OSQP eps_abs = eps_rel (default: OSQP_OPTIONS')")
    parser.add_argument("--horizon", type=int, default=48, help="horizon H [steps] (default 48)")
    parser.add_argument("--controllers", default="qp-mpc,casadi-mpc", help="comma-separated: qp-mpc, casadi-mpc")
    parser.set_defaults(zones="2,5,15")
    args = parser.parse_args(argv)

    def row(z: int) -> str:
        lines = []
        for name in args.controllers.split(","):
            r = run(z, args.steps, args.eps, name, args.horizon)
            lines.append(
                f"{z:>3} {2 * z:>3} {r['variables']:>6} {name:>10} {r['build_s']:>7.2f} {r['median_ms']:>10.1f} "
                f"{r['p95_ms']:>8.1f} {r['iterations']:>6.0f} {r['fallbacks']:>9} {r['discomfort_kh']:>13.3f} "
                f"{r['cost_eur']:>8.3f}"
            )
        return "\n".join(lines)

    header = (
        f"{'Z':>3} {'A':>3} {'vars':>6} {'controller':>10} {'build s':>7} {'median ms':>10} {'p95 ms':>8} "
        f"{'iter':>6} {'fallbacks':>9} {'discomfort Kh':>13} {'cost EUR':>8}"
    )
    print(f"H = {args.horizon}, {args.steps} decisions per building")
    print_rows(header, args.zones, row)
    return 0


if __name__ == "__main__":
    sys.exit(main())
