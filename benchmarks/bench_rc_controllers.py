"""Decision time of the RC MPCs at H=48 in closed loop against the simulator.

Runs ``qp-mpc`` (target median <= 5 ms) and ``casadi-mpc`` (target <= 20 ms) on the paper's
household for two days (96 decisions, after a warm-up decision that builds the solver's memory)
with a day-shaped outdoor temperature, a three-level price and a day/night comfort band, the
observer estimating the hidden T_m. Prints the median, p95 and max per controller::

    python benchmarks/bench_rc_controllers.py [--steps 96]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from controllers.base import ControlSpec, Forecast, Observation
from controllers.qp_mpc import QPMPC
from controllers.rc_mpc import CasadiMPC
from controllers.rc_problem import RCMPCBase
from pinn_mpc.physics import PAPER_HOUSEHOLD
from pinn_mpc.simulator import SimConfig, Simulator

TARGET_MS = {"qp-mpc": 5.0, "casadi-mpc": 20.0}


def decision_times_s(controller: RCMPCBase, n_steps: int) -> np.ndarray:
    """Closed loop of n_steps; returns the wall time of each ``act`` call (n_steps,) [s]."""
    spec = controller.spec
    total = n_steps + spec.horizon_steps + 1
    hours = (np.arange(total) * spec.dt_h) % 24.0
    t_a = 3.0 + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0)
    price = np.where((hours > 17) & (hours < 21), 0.45, np.where(hours < 6, 0.12, 0.25))
    t_min = np.where((hours >= 7) & (hours < 22), 20.0, 17.0)
    fc_all = Forecast(hours, t_a, np.zeros(total), np.zeros(total), price, t_min, np.full(total, 23.0))
    sim = Simulator(SimConfig(params=controller.params, u_max_w=spec.u_max_w), seed=0)
    sim.reset(19.0, 17.0)
    hist: dict[str, list[float]] = {"T_r": [19.0], "u": [], "u_phys": [], "T_a": [t_a[0]]}
    controller.reset(seed=0)
    times = []
    for k in range(n_steps + 1):
        obs = Observation(
            k=k,
            t_r_c=hist["T_r"][-1],
            history={name: np.array(v) for name, v in hist.items()},
            t_m_true_c=float(sim.state[0, 1]),
        )
        fc = Forecast(*(np.asarray(a)[k:] for a in fc_all))
        start = time.perf_counter()
        u = controller.act(obs, fc)
        times.append(time.perf_counter() - start)
        r = sim.step(u, t_a[k])
        hist["T_r"].append(float(r.t_r_c[0]))
        hist["u"].append(u)
        hist["u_phys"].append(float(r.u_phys_w[0]))
        hist["T_a"].append(float(t_a[k + 1]))
    return np.array(times[1:])  # the first call also allocates the solver's memory


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=96)
    args = parser.parse_args()
    spec = ControlSpec(u_max_w=5000.0, horizon_steps=48)
    for controller in (QPMPC(PAPER_HOUSEHOLD, spec), CasadiMPC(PAPER_HOUSEHOLD, spec)):
        t_ms = decision_times_s(controller, args.steps) * 1e3
        median = float(np.median(t_ms))
        verdict = "ok" if median <= TARGET_MS[controller.name] else "ABOVE TARGET"
        print(
            f"{controller.name:11s} H=48: median {median:6.2f} ms  p95 "
            f"{np.quantile(t_ms, 0.95):6.2f} ms  max {t_ms.max():6.2f} ms  "
            f"(target <= {TARGET_MS[controller.name]:g} ms: {verdict}; "
            f"fallbacks {controller.n_fallbacks})"
        )


if __name__ == "__main__":
    main()
