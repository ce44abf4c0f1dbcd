"""Per-zone control of a building of several zones against the merged one-zone control of the
same building, days, weather, prices and comfort bands (issue 43), judged by the zoned
scenario's own KPIs (each zone's discomfort, the price on the building's electrical power).

For each seed ``s``: ``train_days`` days of the scenario's training data (its data policy,
seed ``s``, as a sweep's model), then closed loops of ``days`` test days (seed ``s + 1``) of

- ``cem``: cem over the model ``train`` chooses for the zones (``--arch auto``);
- ``qp-mpc``: the QP over zones x actuators on the multi-zone RC ``identify`` fits;
- ``thermostat``: the dual-setpoint thermostat per zone (a reference);
- ``merged-cem``: the one-zone cem over the one-zone physics-informed ARX ``train --arch parx``
  fits on the merged view of the same data (:meth:`controllers.merged.MergedView.frame`: the
  zones' floor-area-weighted mean temperature, the net heat), its one heater's decision split
  over the zones' heaters by floor area (:class:`controllers.merged.MergedZones`). Not
  ``auto``: where the data's chillers took out more heat than the heaters gave, the net heat is
  negative, which the hybrid's training refuses (a power >= 0); ``auto`` chooses this ARX on
  the zones of this building;
- ``merged-qp-mpc``: the one-zone QP MPC on the one-zone RC identified from that merged data,
  split likewise.

The one-zone planners plan one actuator, so these two heat only (the zones'
chillers stay off but for their backup thermostat); ``merged-hc-cem`` and ``merged-hc-qp-mpc``
plan the merged building with one heater and one chiller (their decisions split likewise)
with the planners of several zones (which take one zone with two actuators): cem over the
model of one zone ``train`` chooses for that data, and the QP on the RC of one zone
``identify`` fits. The shares are the plant's (``zone_shares``: EnergyPlus's floor areas;
equal on the package's RC buildings of several zones, which declare no floor).

Run from the checkout: ``PYTHONPATH=. python benchmarks/merged_vs_zones.py --scenario
eplus_small_office_zones --seeds 0-2 --train-days 14 --days 3 --out merged_january`` (each
cell's KPI JSON is written to ``--out`` as it finishes and read back on a rerun; ``--controllers``
picks some). Prints each cell's line, then a table per controller: the objective [EUR], the
cost, each zone's discomfort too cold / too warm [Kh] and the energy [kWh], as the mean over the
seeds and the worst seed's, then the load average. Exits 0.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from controllers.base import Controller
from controllers.merged import MergedView, MergedZones
from scenarios import get_scenario
from scenarios.inputs.registry import Scenario
from scenarios.running.closed_loop import one_torch_thread, run_closed_loop

ZONED = ("cem", "qp-mpc", "thermostat")
MERGED = ("merged-cem", "merged-qp-mpc", "merged-hc-cem", "merged-hc-qp-mpc")
CONTROLLERS = (*ZONED, *MERGED)


#: The models each controller plans on (:func:`fit_models`).
NEEDS = {
    "cem": "zones_model", "qp-mpc": "zones_rc", "thermostat": None,
    "merged-cem": "merged_model", "merged-qp-mpc": "merged_rc",
    "merged-hc-cem": "merged_hc_model", "merged-hc-qp-mpc": "merged_hc_rc",
}


def fit_models(
    scenario: Scenario, views: dict[bool, MergedView], seed: int, train_days: int, names: list[str]
) -> dict[str, Any]:
    """The models the controllers ``names`` plan on (:data:`NEEDS`), fitted on ``train_days``
    days of the scenario's training data of seed ``seed``: the zones' model and RC as a sweep
    fits them, the merged building's (``views[False]``: one heater; ``views[True]``: a heater
    and a chiller) on the merged view of the same data."""
    from pinn_mpc.actuator import actuator_columns
    from pinn_mpc.fitted import fit
    from pinn_mpc.identify_multizone import identify_multizone
    from pinn_mpc.model_choice import choose_zone_model
    from scenarios.experiments.compare import (
        identify_scenario_rc,
        identify_scenario_zones,
        train_scenario_zones,
    )
    from scenarios.running.datagen import generate

    needed = {NEEDS[n] for n in names} - {None}
    if not needed:
        return {}
    data = generate(scenario, days=train_days, seed=seed, policy=scenario.data_policy)
    started = time.perf_counter()
    models: dict[str, Any] = {}
    if "zones_model" in needed:
        choice = train_scenario_zones(scenario, data, seed=seed)
        models["zones_model"] = choice.model
        print(f"seed {seed}: the zones' model {choice.chosen} ({choice.why})", flush=True)
    if "zones_rc" in needed:
        models["zones_rc"] = identify_scenario_zones(scenario, data).params
    merged = views[False].frame(data)
    if "merged_model" in needed:  # train --arch parx (the hybrid's training refuses a negative power)
        models["merged_model"] = fit(merged, arch="parx").model
    if "merged_rc" in needed:
        models["merged_rc"] = identify_scenario_rc(scenario, merged)
    if not needed & {"merged_hc_model", "merged_hc_rc"}:
        return models
    both = views[True].one_zone_spec
    layout: dict[str, Any] = {
        "zones": both.zones, "actuators": both.actuators, "solar_inputs": ["G"], "dt_s": both.dt_s,
        "adjacency": None,
    }
    merged_hc = views[True].frame(data)
    if "merged_hc_model" in needed:
        zone_choice = choose_zone_model(merged_hc, seed=seed, **layout)
        models["merged_hc_model"] = zone_choice.model
        print(f"seed {seed}: merged heat+cool model {zone_choice.chosen} ({zone_choice.why})", flush=True)
    if "merged_hc_rc" in needed:
        models["merged_hc_rc"] = identify_multizone(
            merged_hc, power_columns=actuator_columns("u_phys", both.actuators), **layout,
        ).params
    print(f"seed {seed}: models fitted in {time.perf_counter() - started:.0f} s", flush=True)
    return models


def controller(
    name: str, scenario: Scenario, views: dict[bool, MergedView], models: dict[str, Any], n_steps: int
) -> Controller:
    """The controller ``name`` (:data:`CONTROLLERS`) of the scenario on the fitted ``models``."""
    from controllers.rc_mpc.osqp import QPMPC
    from controllers.sampling import CEM
    from scenarios.running.factory import (
        build_controller,
        model_guard,
        zone_backup_limits,
        zone_planner,
    )

    if name in ZONED:
        return build_controller(
            name, scenario, model=models.get("zones_model") if name == "cem" else None,
            zone_params=models.get("zones_rc") if name == "qp-mpc" else None, n_steps=n_steps,
        )
    if name == "merged-cem":
        model = models["merged_model"]
        return MergedZones(CEM(model, views[False].one_zone_spec, guard=model_guard(model)), views[False])
    if name == "merged-qp-mpc":
        return MergedZones(QPMPC(models["merged_rc"], views[False].one_zone_spec), views[False])
    planner = zone_planner(
        name.removeprefix("merged-hc-"), views[True].one_zone_spec, model=models.get("merged_hc_model"),
        zone_params=models.get("merged_hc_rc"), backup_limits_c=zone_backup_limits(scenario),
    )
    return MergedZones(planner, views[True])


def _seeds(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def _row(kpis: dict[str, Any]) -> dict[str, float]:
    """The figures of one run: objective, cost, energy and each zone's discomfort."""
    row = {k: float(kpis[k]) for k in ("objective", "cost_eur", "energy_kwh", "discomfort_kh")}
    for zone, z in kpis["zones"].items():
        row[f"cold[{zone}]"] = float(z["discomfort_too_cold_kh"])
        row[f"warm[{zone}]"] = float(z["discomfort_too_warm_kh"])
    return row


def table(cells: dict[tuple[str, int], dict[str, Any]], names: list[str]) -> str:
    """Per controller the mean over its seeds and its worst seed's (highest objective) figures."""
    lines = []
    for name in names:
        rows = {seed: _row(k) for (n, seed), k in sorted(cells.items()) if n == name}
        if not rows:
            continue
        worst = max(rows, key=lambda s: rows[s]["objective"])
        keys = list(next(iter(rows.values())))
        mean = {k: float(np.mean([r[k] for r in rows.values()])) for k in keys}
        for label, row in (("mean", mean), (f"worst (seed {worst})", rows[worst])):
            zones = " ".join(
                f"{k.split('[')[1][:-1]} {row[k]:.2f}/{row['warm' + k[4:]]:.2f}" for k in keys if k.startswith("cold[")
            )
            lines.append(
                f"{name:14s} {label:16s} objective {row['objective']:7.2f} EUR  cost {row['cost_eur']:6.2f} EUR  "
                f"energy {row['energy_kwh']:6.1f} kWh  discomfort {row['discomfort_kh']:6.2f} Kh  "
                f"cold/warm Kh: {zones}  (seeds {sorted(rows)})"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--scenario", default="eplus_small_office_zones")
    parser.add_argument("--seeds", default="0-2", help="a seed or a range, e.g. 0-2 (training seed s, test seed s+1)")
    parser.add_argument("--train-days", type=int, default=14)
    parser.add_argument("--days", type=int, default=3, help="test days")
    parser.add_argument("--controllers", default=",".join(CONTROLLERS))
    parser.add_argument("--out", required=True, help="directory of each cell's KPI JSON")
    args = parser.parse_args(argv)
    names = [n.strip() for n in args.controllers.split(",") if n.strip()]
    unknown = [n for n in names if n not in CONTROLLERS]
    if unknown:
        raise SystemExit(f"--controllers: {unknown} not among {', '.join(CONTROLLERS)}")
    scenario = get_scenario(args.scenario)
    spec, shares = scenario.control_spec(), scenario.plant.settings.zone_shares
    chillers = any(not a.heats for a in spec.actuators)
    if not chillers and any(n.startswith("merged-hc-") for n in names):
        raise SystemExit(f"--controllers: {args.scenario} has no chiller; the merged-hc controllers plan one")
    views = {c: MergedView(spec=spec, shares=shares, cooling=c) for c in (False, True) if c <= chillers}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cells: dict[tuple[str, int], dict[str, Any]] = {}
    n_steps = args.days * scenario.steps_per_day
    for seed in _seeds(args.seeds):
        paths = {name: out / f"{args.scenario}_s{seed}_t{args.train_days}_{name}.json" for name in names}
        cells.update({(n, seed): json.loads(p.read_text()) for n, p in paths.items() if p.is_file()})
        todo = [n for n in names if (n, seed) not in cells]
        if not todo:
            continue
        models = fit_models(scenario, views, seed, args.train_days, todo)
        for name in todo:
            started = time.perf_counter()
            with one_torch_thread():
                result = run_closed_loop(
                    scenario, controller(name, scenario, views, models, n_steps), days=args.days,
                    seed=seed + 1, label=name,
                )
            kpis = dict(result.kpis)
            kpis["wall_time_s"] = time.perf_counter() - started
            paths[name].write_text(json.dumps(kpis, indent=1, default=float))
            cells[(name, seed)] = kpis
            print(
                f"seed {seed} {name}: objective {kpis['objective']:.2f} EUR, discomfort "
                f"{kpis['discomfort_kh']:.2f} Kh, energy {kpis['energy_kwh']:.1f} kWh, fallbacks "
                f"{kpis['fallbacks']}, {kpis['wall_time_s']:.0f} s", flush=True,
            )
    print(f"{args.scenario}, {args.train_days} training days, {args.days} test days")
    print(table(cells, names))
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())} on {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    sys.exit(main())
