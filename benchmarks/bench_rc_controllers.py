"""Decision time of the RC MPCs at H=48 in closed loop against the simulator.

Runs ``qp-mpc`` (target median <= 5 ms) and ``casadi-mpc`` (target <= 20 ms) on the paper's
household for two days (96 decisions, after a warm-up decision that builds the solver's memory)
with a day-shaped outdoor temperature, a three-level price and a day/night comfort band, the
observer estimating the hidden T_m. Prints the median, p95 and max per controller::

    python benchmarks/bench_rc_controllers.py [--steps 96]
"""

from __future__ import annotations

import argparse

import numpy as np

from controllers.base import ControlSpec
from controllers.rc_mpc.casadi import CasadiMPC
from controllers.rc_mpc.osqp import QPMPC
from controllers.rc_mpc.problem import RCMPC
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.physics import PAPER_HOUSEHOLD
from pinn_mpc.simulator import SimConfig
from scenarios.inputs.series import ExogenousSeries
from scenarios.running.engine import ClosedLoop

TARGET_MS = {"qp-mpc": 5.0, "casadi-mpc": 20.0}


def decision_times_s(controller: RCMPC, n_steps: int) -> np.ndarray:
    """Closed loop of n_steps on the engine; the wall time of each ``act`` call (n_steps,) [s]."""
    spec = controller.spec
    total = n_steps + spec.horizon_steps + 1
    hours = (np.arange(total) * spec.dt_h) % 24.0
    exogenous = ExogenousSeries(
        time_of_day_h=hours,
        T_a=3.0 + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0),
        G=np.zeros(total),
        I_g=np.zeros(total),
        price=np.where((hours > 17) & (hours < 21), 0.45, np.where(hours < 6, 0.12, 0.25)),
        T_min=np.where((hours >= 7) & (hours < 22), 20.0, 17.0),
        T_max=np.full(total, 23.0),
    )
    config = SimConfig(params=controller.params, u_max_w=spec.u_max_w)
    loop = ClosedLoop(config, exogenous, spec=spec, initial_t_r_c=19.0, initial_t_m_c=17.0)
    controller.reset(seed=0)
    times = [loop.advance(controller).time_s for _ in range(n_steps + 1)]
    return np.array(times[1:])  # the first call also allocates the solver's memory


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=96)
    args = parser.parse_args()
    spec = ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0),), horizon_steps=48)
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
