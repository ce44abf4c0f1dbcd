"""Data for the multi-zone identification tests and benchmark: a building of
:mod:`pinn_mpc.multizone` run by :class:`~pinn_mpc.multizone.MultiZoneSimulator` under a
synthetic winter and a random-level policy, written in the data format.

The weather is computed here, not read: the outdoor temperature a daily sinusoid plus a random
walk, the sun a half-sine between 08:00 and 16:00 scaled by each day's cloud cover (on a south
facade, and a flatter one on east, west and north facades and on the ground), the internal
gains a base with morning and evening peaks and some noise. Each actuator holds a random level
of its range for a random 1 to 8 hours, independently of the others, so every zone's heat and
the differences between the zones move. The zones' backup thermostats are at 12 and 30 C.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.multizone import (
    MultiZoneConfig,
    MultiZoneParams,
    MultiZoneSimulator,
    ZoneRC,
    wall_tuples,
)
from pinn_mpc.physics import RCParams
from pinn_mpc.zones import ZoneSpec, zone_column

__all__ = ["DT_S", "heater_columns", "multizone_frame", "row_of_zones", "two_zone_house"]

DT_S = 1800.0
_PER_DAY = round(86400.0 / DT_S)


def heater_columns(actuators: Sequence[ActuatorSpec]) -> tuple[str, ...]:
    """The power column of each actuator: ``u_phys[a<index>]``."""
    return tuple(f"u_phys[a{i}]" for i in range(len(actuators)))


def two_zone_house(wall_w_per_k: float = 60.0) -> tuple[MultiZoneParams, tuple[ActuatorSpec, ...]]:
    """A south zone (windows on ``G_south``) and a north zone (no windows) joined by an internal
    wall of ``wall_w_per_k`` [W/K]; an ideal 5 kW heater in each; gains split 0.6 / 0.4."""
    south = RCParams(
        r_ra_k_per_w=6e-3, r_rm_k_per_w=1.5e-3, c_r_j_per_k=3e6, c_m_j_per_k=2e7,
        solar_aperture_m2=5.0, solar_to_air_fraction=0.3, gain_to_air_fraction=0.6,
    )
    north = RCParams(
        r_ra_k_per_w=5e-3, r_rm_k_per_w=1e-3, c_r_j_per_k=2.5e6, c_m_j_per_k=1.5e7,
        gain_to_air_fraction=0.5,
    )
    params = MultiZoneParams(
        zones=(
            ZoneRC(zone=ZoneSpec("south"), rc=south, gain_share=0.6, solar_input="G_south"),
            ZoneRC(zone=ZoneSpec("north"), rc=north, gain_share=0.4),
        ),
        wall_conductance_w_per_k=((0.0, wall_w_per_k), (wall_w_per_k, 0.0)),
    )
    return params, (ActuatorSpec(upper_w=5000.0, zone=0), ActuatorSpec(upper_w=5000.0, zone=1))


def row_of_zones(n_zones: int, seed: int = 0) -> tuple[MultiZoneParams, tuple[ActuatorSpec, ...]]:
    """``n_zones`` zones in a row, each wall between neighbours 40-120 W/K; R/C values drawn
    around a light house's, the even zones facing south, the odd ones east, west or north in
    turn; a 5 kW ideal heater in each; equal gain shares."""
    rng = np.random.default_rng(seed)
    facades = ("G_east", "G_west", "G_north")
    zones = []
    for z in range(n_zones):
        scale = rng.uniform(0.7, 1.4, 4)
        rc = RCParams(
            r_ra_k_per_w=6e-3 * scale[0], r_rm_k_per_w=1.2e-3 * scale[1],
            c_r_j_per_k=2.5e6 * scale[2], c_m_j_per_k=1.8e7 * scale[3],
            solar_aperture_m2=float(rng.uniform(2.0, 6.0)), solar_to_air_fraction=0.3,
            gain_to_air_fraction=0.6,
        )
        sun = "G_south" if z % 2 == 0 else facades[(z // 2) % len(facades)]
        zones.append(ZoneRC(zone=ZoneSpec(f"z{z}"), rc=rc, gain_share=1.0 / n_zones, solar_input=sun))
    walls = np.zeros((n_zones, n_zones))
    for z in range(n_zones - 1):
        walls[z, z + 1] = walls[z + 1, z] = float(rng.uniform(40.0, 120.0))
    params = MultiZoneParams(zones=tuple(zones), wall_conductance_w_per_k=wall_tuples(walls))
    return params, tuple(ActuatorSpec(upper_w=5000.0, zone=z) for z in range(n_zones))


def _weather(days: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    n = days * _PER_DAY
    hours = np.arange(n) * DT_S / 3600.0
    t_a = 3.0 + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0) + np.cumsum(rng.normal(0.0, 0.15, n))
    cloud = rng.uniform(0.2, 1.0, days).repeat(_PER_DAY)
    # The interval's middle, so a half-sine between 08:00 and 16:00 has no sun outside it.
    arc = np.clip(np.sin(np.pi * (hours % 24 + 0.25 - 8.0) / 8.0), 0.0, None) * ((hours % 24) < 16)
    diffuse = 60.0 * cloud * arc
    i_g = 150.0 + 450.0 * ((hours % 24 >= 17) & (hours % 24 < 22)) + 250.0 * ((hours % 24 >= 6) & (hours % 24 < 8))
    return {
        "T_a": t_a,
        "G": 300.0 * cloud * arc,
        "I_g": i_g + rng.normal(0.0, 40.0, n).clip(-140.0, None),
        "G_south": 550.0 * cloud * arc,
        "G_east": diffuse + 250.0 * cloud * arc * ((hours % 24) < 12),
        "G_west": diffuse + 250.0 * cloud * arc * ((hours % 24) >= 12),
        "G_north": diffuse,
    }


def _levels(n: int, upper_w: float, rng: np.random.Generator) -> np.ndarray:
    """(n,) random levels in [0, upper_w], each held 1 to 8 hours."""
    out = np.empty(n)
    k = 0
    while k < n:
        hold = int(rng.integers(2, 17))
        out[k : k + hold] = rng.uniform(0.0, upper_w)
        k += hold
    return out


def multizone_frame(
    params: MultiZoneParams,
    actuators: Sequence[ActuatorSpec],
    *,
    days: int,
    seed: int,
    noise_std_c: float = 0.05,
) -> pd.DataFrame:
    """``days`` x 48 rows: ``time`` [s], each zone's measured ``T_r[<zone>]`` (and its true
    ``T_m[<zone>]``) at the start of the interval, each actuator's mean delivered power
    (:func:`heater_columns`), ``T_a``, ``G``, ``I_g`` and the four facades' irradiance."""
    rng = np.random.default_rng(seed)
    weather = _weather(days, rng)
    n = days * _PER_DAY
    demand = np.stack([_levels(n, a.upper_w, rng) for a in actuators], axis=1)
    config = MultiZoneConfig(
        params=params, actuators=tuple(actuators), dt_s=DT_S, backup_low_c=12.0,
        backup_high_c=30.0, noise_std_c=noise_std_c,
    )
    sim = MultiZoneSimulator(config, seed=seed)
    sim.reset(18.0, 17.0)
    zones = params.zone_specs
    t_r, t_m, power = np.empty((n, len(zones))), np.empty((n, len(zones))), np.empty((n, len(actuators)))
    for k in range(n):
        t_r[k], t_m[k] = sim.measure()[0], sim.state[0, len(zones):]
        power[k] = sim.step(demand[k], {name: v[k] for name, v in weather.items()}).power_w[0]
    columns: dict[str, np.ndarray] = {"time": np.arange(n) * DT_S}
    columns |= {zone_column("T_r", zones, z): t_r[:, z] for z in range(len(zones))}
    columns |= {zone_column("T_m", zones, z): t_m[:, z] for z in range(len(zones))}
    columns |= dict(zip(heater_columns(actuators), power.T, strict=True))
    return pd.DataFrame(columns | weather)


def cem_plans_the_house_for_a_day(model_dir: Path, tmp_path: Path) -> tuple[int, str, dict]:
    """``closed-loop --scenario two_zone_house --controller cem --model model_dir --days 1``:
    its exit status, what it wrote on stderr and its KPI JSON (empty when it wrote none)."""
    import contextlib
    import io
    import json

    from pinn_mpc_cli.cli import main

    out = tmp_path / "cem.json"
    argv = ["closed-loop", "--scenario", "two_zone_house", "--controller", "cem", "--model", str(model_dir),
            "--days", "1", "--json", str(out)]
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        status = main(argv)
    return status, err.getvalue(), json.loads(out.read_text()) if out.is_file() else {}
