"""Data for the learned-model tests: the paper's simulated household (section 4.3.1).

Random on/off demand (p = 0.5), a synthetic daily T_a cycle of 8-27 C, T_r = T_m = 17 C at
the start, 30-min intervals integrated by :class:`pinn_mpc.simulator.Simulator`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from pinn_mpc.data import validate_timeseries
from pinn_mpc.simulator import SimConfig, Simulator


def household_data(days: float, seed: int, config: SimConfig | None = None) -> pd.DataFrame:
    """A validated frame of ``days`` x 48 rows in the data format (with the true ``T_m``)."""
    config = config or SimConfig()
    n = round(days * 86400 / config.dt_s)
    rng = np.random.default_rng(seed)
    sim = Simulator(config, n_buildings=1, seed=seed)
    sim.reset(17.0, 17.0)
    t_s = np.arange(n) * config.dt_s
    hours = (t_s / 3600.0) % 24.0
    t_a = 17.5 - 9.5 * np.cos(2 * np.pi * (hours - 3.0) / 24.0)
    u = np.where(rng.random(n) < 0.5, config.u_max_w, 0.0)
    cols: dict[str, list[float]] = {"T_r": [], "T_m": [], "u_phys": []}
    for k in range(n):
        t_r, t_m = sim.state[0]
        res = sim.step(u[k], t_a[k])
        cols["T_r"].append(t_r)
        cols["T_m"].append(t_m)
        cols["u_phys"].append(float(res.u_phys_w[0]))
    df = pd.DataFrame(
        {
            "time": pd.Timestamp("2021-01-01") + pd.to_timedelta(t_s, unit="s"),
            "T_r": cols["T_r"],
            "T_m": cols["T_m"],
            "u": u,
            "u_phys": cols["u_phys"],
            "T_a": t_a,
        }
    )
    return validate_timeseries(df, source="simulated household")
