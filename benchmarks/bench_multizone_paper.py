"""The paper's networks of a building of several zones against the zones' hybrid and ARX: how
well each predicts a day ahead, and how long each takes to fit.

Run: ``python benchmarks/bench_multizone_paper.py [--scenario two_zone_house] [--days 14]
[--seed 0] [--archs physnet physreg hybrid parx]``.
The scenario's data (``simulate``'s, its data policy) of ``--days`` days; each model is fitted
on the first three quarters (as ``train --arch`` fits it, the scenario's layout; the RC the ARX
and the networks carry identified once, the hybrid identifying its own) and predicts
the rooms over the planner's horizon (48 half-hours) from every start in the last quarter,
on the data's delivered powers and weather: the hybrid from its Kalman state
(:func:`pinn_mpc.models.multizone_hybrid.held_out_error_c`), the ARX and the networks from the
measured history. Printed per model: the rooms' mean |error| [K] (all zones, then each), the
fit's wall time and the load average (other work on the cores lengthens every time).
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import numpy as np

from pinn_mpc.model_choice import PLANNER_HORIZON_S
from pinn_mpc.models.arx import SELECTION_SHARE
from pinn_mpc.zones import zone_columns
from scenarios.experiments.compare import identify_scenario_zones, zone_solar_inputs
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate


def main() -> None:
    from pinn_mpc.models.multizone_arx import MultiZoneARX, fit_multizone_arx
    from pinn_mpc.models.multizone_hybrid import (
        MultiZoneHybrid,
        fit_multizone_hybrid,
        held_out_error_c,
    )
    from pinn_mpc.models.multizone_paper import MultiZonePaperModel, fit_multizone_paper

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="two_zone_house")
    parser.add_argument("--days", type=int, default=14)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--archs", nargs="+", default=["physnet", "physreg", "hybrid", "parx"])
    a = parser.parse_args()
    scenario = get_scenario(a.scenario)
    data = generate(scenario, days=a.days, seed=a.seed, policy=scenario.data_policy)
    n = len(data)
    cut = n - int(n * SELECTION_SHARE)
    horizon = round(PLANNER_HORIZON_S / scenario.sim.dt_s)
    starts = np.arange(cut, n - horizon)
    rooms = data[list(zone_columns("T_r", scenario.control_spec().zones))].to_numpy(dtype=float)
    truth = rooms[starts[:, None] + np.arange(1, horizon + 1)]
    print(f"{a.scenario} {a.days} d seed {a.seed}: fitted on {cut} rows, {len(starts)} starts x {horizon} steps held out")
    spec = scenario.control_spec()
    layout: dict[str, Any] = {
        "zones": spec.zones, "actuators": spec.actuators, "solar_inputs": zone_solar_inputs(scenario),
        "dt_s": scenario.sim.dt_s, "adjacency": scenario.plant.settings.zone_adjacency,
    }
    fitted = data.iloc[:cut].reset_index(drop=True)
    began = time.perf_counter()
    identified = identify_scenario_zones(scenario, fitted if "I_g" in fitted.columns else fitted.assign(I_g=0.0))
    print(f"the RC identified once for all in {time.perf_counter() - began:.1f} s (each fit's time below is without it)")
    for arch in a.archs:
        began = time.perf_counter()
        model: MultiZoneHybrid | MultiZoneARX | MultiZonePaperModel
        if arch == "hybrid":  # identifies again: its time includes the identification
            model = fit_multizone_hybrid(fitted, seed=a.seed, **layout)
        elif arch == "parx":
            model = fit_multizone_arx(fitted, identified=identified, **layout)
        else:
            model = fit_multizone_paper(fitted, arch=arch, seed=a.seed, identified=identified, **layout)
        seconds = time.perf_counter() - began
        if isinstance(model, MultiZoneHybrid):
            per_zone = [float("nan")] * rooms.shape[1]
            error = held_out_error_c(model, data, starts, horizon)
        else:
            paths = model.predict_paths(data, starts, horizon)
            per_zone = list(np.mean(np.abs(paths - truth), axis=(0, 1)))
            error = float(np.mean(np.abs(paths - truth)))
        zones = " ".join(f"{v:.3f}" for v in per_zone)
        print(f"{arch:8s} day-ahead MAE {error:.3f} K (zones {zones}); fit {seconds:.1f} s; load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
