"""The dual-setpoint thermostat per zone on the built-in buildings of several zones, by stage:
on/off and modulating (proportional band x integral time).

Run: ``python benchmarks/bench_zoned_thermostat.py [--scenarios shoulder_office ...] [--days 3]
[--stages 0:3600 4:3600 ...]``. Each stage ``P:Ti`` is a :class:`controllers.thermostat.Thermostat`
with ``proportional_band_k = P`` [K] (0: on/off) and ``integral_time_s = Ti`` [s], run in closed
loop (:func:`scenarios.running.closed_loop.run_closed_loop`, seed 0, the test days) on each
scenario. Prints per scenario and stage the objective, energy, discomfort too cold / too warm
(summed over zones), the heat/cool changeovers (a zone's heating followed by its cooling in the
next interval, or the reverse, as demanded) per zone-day, the intervals with a zone's heating
and cooling both demanded (0 by construction; the plant's backup thermostat may still run both) and the largest excursion above a zone's cooling setpoint in an
interval after it heated [K]. EnergyPlus scenarios need the energyplus package.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from controllers.thermostat import Thermostat
from pinn_mpc.actuator import actuator_columns
from pinn_mpc.zones import zone_columns
from scenarios import get_scenario
from scenarios.running.closed_loop import run_closed_loop

SCENARIOS = (
    "shoulder_office", "two_zone_house", "eplus_small_office_zones", "eplus_small_office_zones_april",
    "eplus_small_office_zones_july",
)


def run(name: str, days: int, band_k: float, integral_s: float) -> str:
    """One table row: ``name`` under the thermostat of this stage for ``days``."""
    scenario = get_scenario(name)
    spec = scenario.control_spec()
    thermostat = Thermostat(spec, proportional_band_k=band_k, integral_time_s=integral_s)
    result = run_closed_loop(scenario, thermostat, days=days, seed=0)
    kpis, traj = result.kpis, result.trajectory
    power = traj[list(actuator_columns("u", spec.actuators))].to_numpy()  # (N, A) demanded
    t_r = traj[list(zone_columns("T_r", spec.zones))].to_numpy()  # (N, Z) at each interval's start
    z = len(spec.zones)
    heating, cooling = np.zeros((len(power), z), bool), np.zeros((len(power), z), bool)
    for i, a in enumerate(spec.actuators):
        (heating if a.heats else cooling)[:, a.zone] |= power[:, i] > 0.0
    changeovers = int(np.sum(heating[:-1] & cooling[1:]) + np.sum(cooling[:-1] & heating[1:]))
    band = traj["T_max"].to_numpy() - traj["T_min"].to_numpy()
    cool_c = (traj["T_max"].to_numpy() - thermostat.offset_fraction * band)[:, None]  # (N, 1)
    after_heat = np.where(heating[:-1], t_r[1:] - cool_c[1:], -np.inf)
    overshoot = max(float(after_heat.max()), 0.0)
    zones = kpis["zones"].values()
    cold = sum(v["discomfort_too_cold_kh"] for v in zones)
    warm = sum(v["discomfort_too_warm_kh"] for v in zones)
    stage = "on/off" if band_k == 0 else f"P {band_k:g} K, Ti {integral_s:g} s"
    return (
        f"{name:32s} {stage:22s} {kpis['objective']:9.2f} {kpis['energy_kwh']:9.2f} {cold:8.2f} {warm:8.2f} "
        f"{changeovers / (z * days):7.2f} {int(np.sum(heating & cooling)):5d} {overshoot:6.2f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS))
    parser.add_argument("--days", type=int, default=3)
    parser.add_argument("--stages", nargs="+", default=["0:3600", "4:3600"], help="P:Ti pairs")
    args = parser.parse_args()
    print(
        f"{'scenario':32s} {'stage':22s} {'objective':>9s} {'kWh':>9s} {'cold Kh':>8s} {'warm Kh':>8s} "
        f"{'chg/zd':>7s} {'both':>5s} {'over K':>6s}"
    )
    for name in args.scenarios:
        for stage in args.stages:
            band_k, integral_s = (float(v) for v in stage.split(":"))
            print(run(name, args.days, band_k, integral_s), flush=True)
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
