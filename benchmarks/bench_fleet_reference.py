"""How much discomfort a cap must cost, and how close the coordinated closed loop comes.

Run: ``python benchmarks/bench_fleet_reference.py [--buildings 20,100] [--models DIR]
[--closed-loop rc,cem] [--json OUT]``.

The fleet is ``winter_household`` (spread 0.2; with ``--models DIR`` the buildings whose
models ``train --per-building`` wrote there, their first N, else a draw), one test day (seed
13, 2023-02-12, heating all day), a cap from 17:00 to 19:00 at 60 % of the uncoordinated
fleet's peak in that window:

- the bound (:func:`scenarios.fleets.reference.fleet_reference`): the day as one convex
  problem over all buildings' exact RCs with perfect forecasts, run open loop on the plant,
  uncapped and capped at the same cap as each closed loop below (60 % of that closed loop's own
  uncapped window peak): under the MPC's objective over the day and the forecast lead the last
  plan sees (``mpc_objective``), over the day alone (``mpc_objective_day_only``: the least
  objective of the day; it lets the building mass run down for the next day), and under a
  comfort weight of 1e3 EUR/K h (``least_discomfort``: the least discomfort the cap allows at
  any energy cost);
- ``--closed-loop rc``: the batched qp-mpc on the buildings' exact RCs
  (:func:`scenarios.fleets.aggregator.run_coordinated_fleet`) uncapped and capped;
- ``--closed-loop cem``: the batched cem over the buildings' learned models (``--models``;
  ``--rc-candidates``: scoring the shadow RC MPC's plan in every plan).

``--coordination old`` runs the plain dual ascent (subgradient prices, the last plan scaled down
when over the cap) instead of the secant prices and the first actions settled on the cap.

Discomfort is per building [K h], measured on the plant (minute substeps) as the KPIs are.
The machine is shared: the load average is printed with the step times.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Any

import numpy as np

from controllers.coordination import DualAscent
from scenarios.fleets.aggregator import cap_in_force, learned_fleet_planner, run_coordinated_fleet
from scenarios.fleets.reference import fleet_reference
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import one_torch_thread

SCENARIO, SEED, WINDOW, SHARE = "winter_household", 13, "17:00-19:00", 0.6
STIFF_COMFORT = 1e3  # EUR per K h: the least discomfort at any energy cost
#: (label, comfort weight (None: the scenario's), plan the forecast lead too)
VARIANTS = (
    ("mpc_objective", None, True),
    ("mpc_objective_day_only", None, False),
    ("least_discomfort", STIFF_COMFORT, True),
)


def _per_building(values: Any) -> float:
    return float(np.mean(values))


def bound(scenario: Any, fleet: Any, cap_kw: float) -> dict[str, Any]:
    """The reference's discomfort per building, uncapped and capped at ``cap_kw``."""
    out: dict[str, Any] = {"cap_kw": cap_kw}
    for label, weight, lead in VARIANTS:
        t0 = time.perf_counter()
        free = fleet_reference(scenario, fleet, days=1, seed=SEED, comfort_weight_eur_per_kh=weight, lead=lead)
        capped = fleet_reference(scenario, fleet, days=1, seed=SEED, cap_kw=cap_kw, cap_window=WINDOW,
                                 comfort_weight_eur_per_kh=weight, lead=lead)
        assert capped.cap is not None
        out[label] = {
            "free_kh": _per_building(free.discomfort_kh),
            "capped_kh": _per_building(capped.discomfort_kh),
            "increase_kh": _per_building(capped.discomfort_kh) - _per_building(free.discomfort_kh),
            "model_increase_kh": _per_building(capped.model_discomfort_kh) - _per_building(free.model_discomfort_kh),
            "objective_free_eur": float(sum(k["objective"] for k in free.kpis)),
            "objective_capped_eur": float(sum(k["objective"] for k in capped.kpis)),
            "energy_free_kwh": float(free.energy_kwh.sum()),
            "energy_capped_kwh": float(capped.energy_kwh.sum()),
            "intervals_over": capped.cap["intervals_over"],
            "window_kw": (capped.aggregate_w[34:38] / 1000.0).round(2).tolist(),
            "cap_price_eur_per_kwh": capped.plan.cap_price_eur_per_kwh[34:38].round(3).tolist(),
            "seconds": time.perf_counter() - t0,
        }
    return out


def closed_loop(scenario: Any, fleet: Any, planner: Any, dual: DualAscent) -> dict[str, Any]:
    """The coordinated fleet uncapped and capped at 60 % of its own uncapped window peak."""
    n = len(fleet)
    runs: dict[str, Any] = {}
    free = run_coordinated_fleet(scenario, planner(), n_buildings=n, days=1, seed=SEED, fleet=fleet)
    in_window = ~np.isnan(cap_in_force(free.times, {"kw": 1.0, "window": WINDOW}))
    cap_kw = SHARE * free.aggregate_u_phys_w[in_window].max() / 1000.0
    capped = run_coordinated_fleet(scenario, planner(), n_buildings=n, days=1, seed=SEED, fleet=fleet,
                                   cap_kw=cap_kw, cap_window=WINDOW, dual=dual)
    for label, r in (("free", free), ("capped", capped)):
        runs[label] = {
            "discomfort_kh": _per_building([k["discomfort_kh"] for k in r.kpis]),
            "energy_kwh": float(sum(k["energy_kwh"] for k in r.kpis)),
            "objective_eur": float(r.totals["objective"]),
            "step_ms_median": r.step_time["controllers_ms_median"],
            "window_kw": (r.aggregate_u_phys_w[in_window] / 1000.0).round(2).tolist(),
            "cap": r.cap,
            "plans_per_step": r.info.get("plans_per_step"),
        }
    runs["cap_kw"] = cap_kw
    runs["increase_kh"] = runs["capped"]["discomfort_kh"] - runs["free"]["discomfort_kh"]
    runs["load"] = os.getloadavg()
    return runs


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--buildings", default="20,100", help="fleet sizes")
    parser.add_argument("--models", default=None, help="a `train --per-building` directory")
    parser.add_argument("--closed-loop", default="", help="rc, cem or rc,cem: closed loops to compare")
    parser.add_argument("--json", default=None, help="write the figures here")
    parser.add_argument(
        "--coordination", default="new", choices=("new", "old"),
        help="new: secant prices and the first actions settled on the cap (default); old: the "
        "plain dual ascent, scaled down when over",
    )
    parser.add_argument("--rc-candidates", action="store_true",
                        help="the batched cem scores its shadow RC MPC's plan in every plan")
    args = parser.parse_args()
    from threadpoolctl import threadpool_limits

    from pinn_mpc.simulator import draw_fleet

    scenario = get_scenario(SCENARIO)
    models, params = None, None
    if args.models:
        from scenarios.fleets.training import load_fleet_models

        models, params = load_fleet_models(args.models)
    loops = [v for v in args.closed_loop.split(",") if v]
    dual = DualAscent() if args.coordination == "new" else DualAscent(secant=False, interpolate=False)
    report: dict[str, Any] = {}
    with one_torch_thread(), threadpool_limits(limits=1, user_api="blas"):
        for n in (int(v) for v in args.buildings.split(",") if v):
            fleet = (list(params[:n]) if params is not None else
                     draw_fleet(scenario.sim.params, n, spread=0.2, rng=np.random.default_rng([SEED, 7])))
            entry: dict[str, Any] = {}
            caps = {}
            for kind in loops:
                if kind == "rc":
                    entry["rc"] = closed_loop(scenario, fleet, lambda: "qp-mpc", dual)
                elif kind == "cem":
                    if models is None:
                        parser.error("--closed-loop cem needs --models DIR")
                    fleet_models = models[:n]
                    entry["cem"] = closed_loop(
                        scenario, fleet,
                        lambda fm=fleet_models: learned_fleet_planner(fm, rc_candidates=args.rc_candidates),
                        dual,
                    )
                else:
                    parser.error(f"--closed-loop: rc or cem, got {kind!r}")
                caps[kind] = entry[kind]["cap_kw"]
                c = entry[kind]
                print(f"{n} buildings, {kind}: cap {c['cap_kw']:.1f} kW; objective {c['free']['objective_eur']:.1f} "
                      f"-> {c['capped']['objective_eur']:.1f} EUR; discomfort per building "
                      f"{c['free']['discomfort_kh']:.3f} -> {c['capped']['discomfort_kh']:.3f} "
                      f"(+{c['increase_kh']:.3f}); intervals over {c['capped']['cap']['intervals_over']}; "
                      f"energy {c['free']['energy_kwh']:.0f} -> {c['capped']['energy_kwh']:.0f} kWh; "
                      f"window {c['capped']['window_kw']} kW; step {c['free']['step_ms_median']:.0f} / "
                      f"{c['capped']['step_ms_median']:.0f} ms (load {c['load'][0]:.1f})", flush=True)
            if not caps:  # the reference's own uncapped window peak
                free = fleet_reference(scenario, fleet, days=1, seed=SEED)
                caps["reference"] = SHARE * free.aggregate_w[34:38].max() / 1000.0
            entry["bound"] = {}
            for kind, cap_kw in caps.items():
                b = entry["bound"][kind] = bound(scenario, fleet, cap_kw)
                for label, _, _ in VARIANTS:
                    v = b[label]
                    print(f"{n} buildings, bound at the {kind} cap {cap_kw:.1f} kW, {label}: "
                          f"{v['free_kh']:.3f} -> {v['capped_kh']:.3f} (+{v['increase_kh']:.3f} K h per "
                          f"building; model +{v['model_increase_kh']:.3f}); energy {v['energy_free_kwh']:.0f} "
                          f"-> {v['energy_capped_kwh']:.0f} kWh; objective {v['objective_free_eur']:.1f} -> "
                          f"{v['objective_capped_eur']:.1f} EUR; window {v['window_kw']} kW; cap prices "
                          f"{v['cap_price_eur_per_kwh']} EUR/kWh ({v['seconds']:.0f} s)", flush=True)
            report[str(n)] = entry
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average (1, 5, 15 min): {load} on {os.cpu_count()} CPUs")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
