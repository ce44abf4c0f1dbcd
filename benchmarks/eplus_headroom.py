"""How much a better model could still gain on an EnergyPlus building, which has no oracle.

Run: ``python benchmarks/eplus_headroom.py [--scenario eplus_midrise_apartment] [--seeds 0-2]``
(any built-in or scenario file whose plant is EnergyPlus).

For each seed, as ``sweep`` does (30 days of the scenario's data policy on the training part,
5 test days with test seed ``seed + 1``), it runs on the same test days:

- ``thermostat`` and ``qp-mpc`` on the RC identified from the training data (the reference);
- ``cem`` over the physics-informed ARX fitted on the training data (what ``train`` gives);
- ``cem`` and ``qp-mpc`` over the physics-informed ARX fitted *in sample*: on the scenario's
  data policy run over the test part of the weather itself, days that include the 5 test days
  (checked). No user has such a model; it bounds what a better model of the building could
  gain with the package's planners, as far as the ARX's structure can fit the building.

Prints each run's objective, cost, energy and discomfort and each ratio to ``qp-mpc``, then
the mean ratio per controller over the seeds.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from pinn_mpc.models.arx import ARXModel, fit_physics_informed_arx
from scenarios.experiments.compare import identify_scenario_rc, rc_for_mpc
from scenarios.inputs.exogenous import TMY3Weather
from scenarios.inputs.registry import Scenario
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import one_torch_thread, run_closed_loop
from scenarios.running.datagen import generate
from scenarios.running.factory import build_controller

TRAIN_DAYS = 30
TEST_DAYS = 5


def _seeds(text: str) -> list[int]:
    """``"0-2"`` or ``"0,3"`` as a list of seeds."""
    if "-" in text:
        first, last = (int(x) for x in text.split("-"))
        return list(range(first, last + 1))
    return [int(x) for x in text.split(",")]


def _in_sample_model(scenario: Scenario, seed: int) -> tuple[ARXModel, set[object]]:
    """The physics-informed ARX fitted on a data-policy run over the test part of the weather
    (test seed ``seed + 1``), and the times of that run."""
    if not isinstance(scenario.weather, TMY3Weather):
        raise SystemExit(f"{scenario.name}: the in-sample fit needs a weather file's test part")
    days = scenario.weather.test_days - 2  # room for the warm-up and the forecast lead
    data = generate(scenario, days=days, seed=seed + 1, policy=scenario.data_policy, weather_part="test")
    return fit_physics_informed_arx(data, eta=scenario.sim.params.eta), set(data["time"])


def run_seed(scenario: Scenario, seed: int) -> dict[str, tuple[float, float, float, float]]:
    """(objective, cost, energy kWh, discomfort K h) of each controller on one seed."""
    train = generate(scenario, days=TRAIN_DAYS, seed=seed, policy=scenario.data_policy)
    rc = rc_for_mpc(identify_scenario_rc(scenario, train), scenario)
    trained = fit_physics_informed_arx(train, eta=scenario.sim.params.eta)
    in_sample, in_sample_times = _in_sample_model(scenario, seed)
    n_steps = TEST_DAYS * scenario.steps_per_day
    runs = {
        "thermostat": build_controller("thermostat", scenario, n_steps=n_steps),
        "qp-mpc / RC": build_controller("qp-mpc", scenario, rc_params=rc, n_steps=n_steps),
        "cem / parx": build_controller("cem", scenario, model=trained, n_steps=n_steps),
        "cem / parx in sample": build_controller("cem", scenario, model=in_sample, n_steps=n_steps),
        "qp-mpc / parx in sample": build_controller("qp-mpc", scenario, model=in_sample, n_steps=n_steps),
    }
    out = {}
    for label, controller in runs.items():
        with one_torch_thread():
            result = run_closed_loop(scenario, controller, days=TEST_DAYS, seed=seed + 1)
        times = set(result.trajectory["time"])
        if "in sample" in label and not times <= in_sample_times:
            raise SystemExit(f"seed {seed}: the in-sample data do not cover the test days")
        k = result.kpis
        energy_kwh = float(result.trajectory["u_phys"].sum()) * scenario.sim.dt_s / 3.6e6
        out[label] = (float(k["objective"]), float(k["cost_eur"]), energy_kwh, float(k["discomfort_kh"]))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="eplus_midrise_apartment")
    parser.add_argument("--seeds", default="0-2")
    a = parser.parse_args(argv)
    scenario = get_scenario(a.scenario)
    if scenario.plant.kind != "energyplus":
        raise SystemExit(f"{a.scenario}: not an EnergyPlus scenario")
    ratios: dict[str, list[float]] = {}
    for seed in _seeds(a.seeds):
        out = run_seed(scenario, seed)
        reference = out["qp-mpc / RC"][0]
        for label, (objective, cost, energy, discomfort) in out.items():
            ratio = objective / reference
            ratios.setdefault(label, []).append(ratio)
            print(f"{a.scenario} seed {seed} {label:24s} objective {objective:8.2f} cost {cost:8.2f} "
                  f"energy {energy:7.0f} kWh discomfort {discomfort:6.2f} K h  / qp-mpc {ratio:.3f}", flush=True)
    for label, values in ratios.items():
        print(f"{a.scenario} mean over seeds {label:24s} / qp-mpc {np.mean(values):.3f} "
              f"(worst {max(values):.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
