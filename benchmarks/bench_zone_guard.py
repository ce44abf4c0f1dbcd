"""cem over a building of several zones with and without its trust guard and adaptive margins
(:mod:`controllers.zone_sampling`): objective, its parts, the model's own decisions and each
zone's discomfort too cold / too warm and energy, against the thermostat.

Run from the checkout: ``PYTHONPATH=. python benchmarks/bench_zone_guard.py --scenario
eplus_small_office_zones_april --model DIR --seeds 1,3 [--days 3] [--variants default,fixed]``,
``DIR`` the model ``pinn-mpc train --data D --scenario S`` wrote (``simulate --scenario S
--days 14 --seed 0``; the user's path of ``docs/zones.md``). Each run is ``closed-loop``'s
(:func:`scenarios.running.closed_loop.run_closed_loop`, torch on one thread) with the
controller ``closed-loop --controller cem --model DIR`` builds, given the variant's options:

- ``default``: the package's defaults (the zones' margin, the guard, the adaptive margins);
- ``fixed``: the margin alone, neither the guard nor the adaptive margins (before issue 43's guard);
- ``adaptive``: the adaptive margins, no hand-over;
- ``base=X``: the default with ``comfort_margin_k`` X [K];
- ``base=X,noguard``: the same without the hand-over.

Prints one JSON line per seed and variant (the thermostat's first) and one of each zone's
discomfort and energy; then the load average. Exits 0.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from typing import Any

from controllers.zone_sampling import ZoneGuard
from pinn_mpc.fitted import load
from scenarios import get_scenario
from scenarios.running.closed_loop import one_torch_thread, run_closed_loop
from scenarios.running.factory import build_controller


def _options(variant: str) -> dict[str, Any]:
    """The planner options of ``variant`` (module docstring)."""
    if variant == "default":
        return {}
    if variant == "fixed":
        return {"guard": ZoneGuard(hand_over=False, adaptive_margin=False)}
    if variant == "adaptive":
        return {"guard": ZoneGuard(hand_over=False)}
    if variant.startswith("base="):
        value, _, rest = variant.removeprefix("base=").partition(",")
        options: dict[str, Any] = {"comfort_margin_k": float(value)}
        if rest == "noguard":
            options["guard"] = ZoneGuard(hand_over=False)
        elif rest:
            raise SystemExit(f"variant {variant!r}: base=X or base=X,noguard")
        return options
    raise SystemExit(f"unknown variant {variant!r}: default, fixed, adaptive, base=X[,noguard]")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", required=True)
    parser.add_argument("--model", required=True)
    parser.add_argument("--seeds", default="1,3")
    parser.add_argument("--days", type=int, default=3)
    parser.add_argument("--variants", default="default,fixed", help="comma-separated; base=X,noguard with ';'")
    args = parser.parse_args()
    with one_torch_thread():
        _run(args)
    print(f"load average {os.getloadavg()[0]:.1f}")


def _run(args: argparse.Namespace) -> None:
    """The runs of ``args`` (module docstring), each printed as it ends."""
    scenario = get_scenario(args.scenario)
    model = load(args.model)
    n_steps = args.days * round(86400 / scenario.control_spec().dt_s)
    for seed in (int(s) for s in args.seeds.split(",")):
        reference = None
        for variant in ["thermostat", *args.variants.split(";" if ";" in args.variants else ",")]:
            start = time.perf_counter()
            if variant == "thermostat":
                controller = build_controller("thermostat", scenario, n_steps=n_steps)
            else:
                controller = build_controller(
                    "cem", scenario, model=model, n_steps=n_steps, planner_options=_options(variant)
                )
            kpis = run_closed_loop(scenario, controller, days=args.days, seed=seed).kpis
            reference = kpis["objective"] if reference is None else reference
            report = getattr(controller, "trust_report", None)
            line = {
                "seed": seed, "variant": variant, "objective": round(kpis["objective"], 2),
                "to_thermostat": round(kpis["objective"] / reference, 3), "cost_eur": round(kpis["cost_eur"], 2),
                "too_cold_kh": round(kpis["discomfort_too_cold_kh"], 2),
                "too_warm_kh": round(kpis["discomfort_too_warm_kh"], 2), "energy_kwh": round(kpis["energy_kwh"], 1),
                "own_decisions": round(kpis["own_decisions_share"], 3),
                "switches": None if report is None else report["model_fallback_switches"],
                "model_replay_k": None if report is None else report["model_replay_error_k"],
                "rc_replay_k": None if report is None else report["rc_replay_error_k"],
                "run_s": round(time.perf_counter() - start),
            }
            print(json.dumps(line), flush=True)
            zones = {
                zone: [round(z["discomfort_too_cold_kh"], 2), round(z["discomfort_too_warm_kh"], 2), round(z["energy_kwh"], 1)]
                for zone, z in kpis["zones"].items()
            }
            print("  zones [too cold K h, too warm K h, kWh]:", json.dumps(zones), flush=True)


if __name__ == "__main__":
    main()
