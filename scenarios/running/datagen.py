"""Training and test data: simulate a scenario under a simple policy, in the data format.

Policies:

- ``random`` (the paper's): in each interval, independently per building, demand ``u_max``
  with probability ``on_probability``, else 0.
- ``random-level``: in each interval, independently per building, a demand drawn uniformly
  from ``[0, u_max]``. On/off data shows a network only the two extremes of the power; a
  controller that modulates the power asks it about the levels in between, which this policy
  covers (a multi-level excitation signal, as system identification recommends).
- ``thermostat``: :class:`controllers.thermostat.Thermostat` on the scenario's comfort band
  (its rule :meth:`~controllers.thermostat.Thermostat.switch`, batched over buildings).
- ``closed-loop``: random setpoint steps tracked by a proportional controller with a random
  dither (:class:`SetpointPolicy`): a setpoint drawn uniformly from the scenario's comfort
  band widened by 1 K, held 1-8 h, and a power of ``u_max`` x (0.5 / K x (setpoint - T_r) +
  a uniform dither of +-0.25), clipped to [0, u_max]. The room stays near where a controller
  keeps it, inside the backup thermostat's band, while the power still takes every level;
  on a plant whose backup would otherwise act inside intervals (EnergyPlus, whose random
  levels overheat the room to the backup's 28 C) it is the scenario's default
  (:attr:`scenarios.inputs.registry.Scenario.data_policy`).

Rows are control intervals: ``T_r``/``T_m`` at the start of the interval (true values, plus
the scenario's measurement noise on ``T_r`` if any), ``u`` demanded and ``u_phys`` the mean
delivered power over it, then the exogenous inputs held over it. ``G`` appears only when the
building has a solar aperture, ``I_g`` only when the scenario has internal gains; ``price``,
``T_min`` and ``T_max`` always. With ``n_buildings > 1`` all buildings (same weather,
independent random demands) run in one batched simulator and the frame is long: an integer
``building`` column (0..B-1) precedes ``time``, and each building's rows are contiguous.

On an EnergyPlus plant (one building) the rows hold the outdoor temperature and irradiance
EnergyPlus had, as interval means, and no ``T_m`` (it has none); its internal gains stay
unmeasured, as in a real building.

The weather comes from the scenario's training part by default (``simulate``, training data);
test data for open-loop evaluation comes from the test part, the days closed loops run on.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pandas as pd

from controllers.thermostat import Thermostat
from pinn_mpc.data import SITE_COLUMNS
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.physics import RCParams
from pinn_mpc.simulator import Simulator
from scenarios.choices import POLICIES
from scenarios.inputs.registry import Scenario, check_seed

__all__ = ["SetpointPolicy", "generate"]

# Random streams apart from the exogenous ones (see scenarios.inputs.registry).
_POLICY_STREAM, _SENSOR_STREAM = 11, 12


@dataclass(frozen=True, kw_only=True)
class SetpointPolicy:
    """The ``closed-loop`` data policy (module docstring): random setpoint steps tracked by a
    proportional controller with a dither. ``draws`` (N, 3) uniform [0, 1) numbers per interval
    (setpoint, hold, dither); the setpoint range ``[low_c, high_c]``, held ``hold_steps``
    intervals (lowest, highest), ``gain_per_k`` of ``u_max_w`` per kelvin below the setpoint,
    ``dither`` the half-width of the uniform dither as a fraction of ``u_max_w``."""

    u_max_w: float
    low_c: float
    high_c: float
    hold_steps: tuple[int, int]
    gain_per_k: float = 0.5
    dither: float = 0.25

    @classmethod
    def for_data(cls, u_max_w: float, t_min: np.ndarray, t_max: np.ndarray, dt_s: float) -> SetpointPolicy:
        """The policy for a comfort band ``t_min``..``t_max`` (C) widened by 1 K, setpoints held
        1-8 h at ``dt_s``."""
        steps_h = 3600.0 / dt_s
        return cls(
            u_max_w=u_max_w,
            low_c=float(np.min(t_min)) - 1.0,
            high_c=float(np.max(t_max)) + 1.0,
            hold_steps=(max(1, round(steps_h)), max(1, round(8 * steps_h))),
        )

    def setpoints(self, draws: np.ndarray) -> np.ndarray:
        """(N,) the setpoint of each interval from ``draws`` (N, 3)."""
        n = len(draws)
        out = np.empty(n)
        lo, hi = self.hold_steps
        k = 0
        while k < n:
            hold = lo + int(draws[k, 1] * (hi - lo + 1))
            out[k : k + hold] = self.low_c + draws[k, 0] * (self.high_c - self.low_c)
            k += hold
        return out

    def demand(self, t_r: np.ndarray, setpoint: float, draw: np.ndarray) -> np.ndarray:
        """The power [W] for room temperatures ``t_r`` at ``setpoint``, dither from ``draw`` (3,)."""
        level = self.gain_per_k * (setpoint - t_r) + self.dither * (2.0 * draw[2] - 1.0)
        return np.clip(level, 0.0, 1.0) * self.u_max_w


def generate(
    scenario: Scenario,
    *,
    days: int,
    seed: int,
    policy: Literal["random", "random-level", "thermostat", "closed-loop"] | str = "random",
    n_buildings: int = 1,
    on_probability: float = 0.5,
    weather_part: str = "train",
    fleet: Sequence[RCParams] | None = None,
) -> pd.DataFrame:
    """Simulate ``days`` days of ``scenario`` under a data-collection policy.

    Parameters
    ----------
    scenario
        The scenario to simulate.
    days
        Days to simulate.
    seed
        Seed of the weather draw, price, policy and sensor noise; the frame is deterministic
        in ``seed`` and ``weather_part``.
    policy
        ``"random-level"`` (a uniform random power per interval, best for models that will
        drive a controller), ``"random"`` (the paper's on/off with ``on_probability``) or
        ``"thermostat"`` or ``"closed-loop"`` (random setpoints tracked, :class:`SetpointPolicy`).
    n_buildings
        Buildings simulated at once (a ``building`` column is added when more than one).
    on_probability
        Probability of full power per interval under ``"random"``.
    fleet
        The ``n_buildings`` buildings' own parameters (e.g.
        :func:`pinn_mpc.simulator.draw_fleet`); default: all the scenario's building.
    weather_part
        ``"train"`` (default), ``"test"`` or ``"whole"`` (see :mod:`scenarios.inputs.exogenous`).

    Returns
    -------
    pandas.DataFrame
        ``days * steps_per_day`` rows (times ``n_buildings``) in the data format;
        ``attrs['dt_s']`` is the control interval [s].
    """
    if fleet is not None and len(fleet) != n_buildings:
        raise InternalError(f"generate: {len(fleet)} fleet parameters for n_buildings={n_buildings}")
    if policy not in POLICIES:
        raise InputError(f"unknown policy {policy!r}; choose one of: {', '.join(POLICIES)}")
    if not 0.0 <= on_probability <= 1.0:
        raise InputError(f"on_probability must lie in [0, 1], got {on_probability!r}")
    if n_buildings < 1:
        raise InputError(f"n_buildings must be >= 1, got {n_buildings}")
    check_seed(seed)
    exo = scenario.exogenous(days=days, seed=seed, part=weather_part)
    cols = {c: exo[c].to_numpy(dtype=float) for c in ("T_a", "G", "I_g", "price", "T_min", "T_max")}
    if scenario.plant.is_energyplus:
        if fleet is not None:
            raise InputError("a fleet with its own parameters runs on the RC simulator, not EnergyPlus")
        return _generate_energyplus(scenario, exo, cols, seed=seed, policy=policy,
                                    n_buildings=n_buildings, on_probability=on_probability)
    return _generate_rc(
        scenario, exo, cols, seed=seed, policy=policy, n_buildings=n_buildings,
        on_probability=on_probability, fleet=fleet,
    )


def _generate_rc(
    scenario: Scenario,
    exo: pd.DataFrame,
    cols: dict[str, np.ndarray],
    *,
    seed: int,
    policy: str,
    n_buildings: int,
    on_probability: float,
    fleet: Sequence[RCParams] | None,
) -> pd.DataFrame:
    """:func:`generate` on the RC simulator: ``n_buildings`` buildings (``fleet``'s own
    parameters, or the scenario's) stepped in one batch under the policy."""
    spec = scenario.control_spec()
    n = len(exo)
    sensor_seed = int(np.random.default_rng([seed, _SENSOR_STREAM]).integers(2**63))
    sim = Simulator(scenario.sim, seed=sensor_seed, fleet=fleet, n_buildings=None if fleet else n_buildings)
    sim.reset(scenario.initial_t_r_c, scenario.initial_t_m_c)
    t_r = np.empty((n_buildings, n))
    t_m = np.empty((n_buildings, n))
    u = np.empty((n_buildings, n))
    u_phys = np.empty((n_buildings, n))
    rng = np.random.default_rng([seed, _POLICY_STREAM])
    if policy == "closed-loop":
        tracking = SetpointPolicy.for_data(spec.u_max_w, cols["T_min"], cols["T_max"], scenario.sim.dt_s)
        draws = rng.random((n, 3))
        setpoints = tracking.setpoints(draws)
    else:
        draws = rng.random((n, n_buildings))
    thermostat = Thermostat(spec)
    on = np.zeros(n_buildings, dtype=bool)
    for k in range(n):
        t_r[:, k] = sim.measure()
        t_m[:, k] = sim.state[:, 1]
        if policy == "random":
            u[:, k] = np.where(draws[k] < on_probability, spec.u_max_w, 0.0)
        elif policy == "random-level":
            u[:, k] = draws[k] * spec.u_max_w
        elif policy == "closed-loop":
            u[:, k] = tracking.demand(t_r[:, k], setpoints[k], draws[k])
        else:  # the thermostat's rule, batched over the buildings (it sees only T_r and the band)
            on = thermostat.switch(t_r[:, k], on, cols["T_min"][k], cols["T_max"][k])
            u[:, k] = np.where(on, spec.u_max_w, 0.0)
        result = sim.step(u[:, k], cols["T_a"][k], cols["G"][k], cols["I_g"][k])
        u_phys[:, k] = result.u_phys_w

    return _rc_frame(scenario, exo, cols, t_r=t_r, t_m=t_m, u=u, u_phys=u_phys)


def _rc_frame(
    scenario: Scenario,
    exo: pd.DataFrame,
    cols: dict[str, np.ndarray],
    *,
    t_r: np.ndarray,
    t_m: np.ndarray,
    u: np.ndarray,
    u_phys: np.ndarray,
) -> pd.DataFrame:
    """The data-format frame of :func:`_generate_rc`'s (buildings, intervals) arrays: the
    buildings one after another, a ``building`` column when there is more than one."""
    n_buildings, n = t_r.shape
    columns = ["T_a", "price", "T_min", "T_max"]
    if scenario.uses_solar:
        columns.append("G")
    if scenario.gains.active:
        columns.append("I_g")
    frame = pd.DataFrame(
        {
            "time": np.tile(exo["time"].to_numpy()[:n], n_buildings),
            "T_r": t_r.ravel(),
            "T_m": t_m.ravel(),
            "u": u.ravel(),
            "u_phys": u_phys.ravel(),
            **{c: np.tile(cols[c][:n], n_buildings) for c in columns},
        }
    )
    if not scenario.sim.actuator.is_ideal:  # a heat pump: heat per electrical watt, per row
        frame["cop"] = scenario.sim.actuator.gain(frame["T_a"].to_numpy(dtype=float))
    if n_buildings > 1:
        frame.insert(0, "building", np.repeat(np.arange(n_buildings), n))
    frame.attrs["dt_s"] = float(scenario.sim.dt_s)
    return frame


def _generate_energyplus(
    scenario: Scenario,
    exo: pd.DataFrame,
    cols: dict[str, np.ndarray],
    *,
    seed: int,
    policy: str,
    n_buildings: int,
    on_probability: float,
) -> pd.DataFrame:
    """:func:`generate` on an EnergyPlus plant: one building, the plant's own weather."""
    from scenarios.plants.energyplus.plant import EnergyPlusPlant

    if n_buildings != 1:
        raise InputError(
            f"an EnergyPlus building is one building; --buildings {n_buildings} needs an RC scenario"
        )
    spec = scenario.control_spec()
    n = len(exo)
    sensor_seed = int(np.random.default_rng([seed, _SENSOR_STREAM]).integers(2**63))
    rng = np.random.default_rng([seed, _POLICY_STREAM])
    tracking = SetpointPolicy.for_data(spec.u_max_w, cols["T_min"], cols["T_max"], scenario.sim.dt_s)
    if policy == "closed-loop":
        loop_draws = rng.random((n, 3))
        setpoints = tracking.setpoints(loop_draws)
    else:
        draws = rng.random(n)
    thermostat = Thermostat(spec)
    on = np.zeros(1, dtype=bool)
    t_r, u, u_phys, t_a, g, i_g = (np.empty(n) for _ in range(6))
    plant = EnergyPlusPlant(scenario.sim, scenario.plant.energyplus, exo["time"].to_numpy(), seed=sensor_seed)
    try:
        plant.reset(scenario.initial_t_r_c, scenario.initial_t_m_c, start=0, seed=None)
        for k in range(n):
            measured = plant.measure()
            t_r[k] = measured[0]
            if policy == "random":
                u[k] = spec.u_max_w if draws[k] < on_probability else 0.0
            elif policy == "random-level":
                u[k] = draws[k] * spec.u_max_w
            elif policy == "closed-loop":
                u[k] = float(tracking.demand(measured, setpoints[k], loop_draws[k])[0])
            else:
                on = thermostat.switch(measured, on, cols["T_min"][k], cols["T_max"][k])
                u[k] = spec.u_max_w if on[0] else 0.0
            step = plant.step(u[k], k)
            u_phys[k], t_a[k], g[k] = step.result.u_phys_w[0], step.t_a_c[0], step.g_w_per_m2[0]
            i_g[k] = step.i_g_w[0]
    finally:
        plant.close()
    frame = pd.DataFrame(
        {
            "time": exo["time"].to_numpy()[:n],
            "T_r": t_r,
            "u": u,
            "u_phys": u_phys,
            "T_a": t_a,
            "price": cols["price"],
            "T_min": cols["T_min"],
            "T_max": cols["T_max"],
            "G": g,
        }
    )
    if scenario.plant.gains == "measured":  # the gains as they happened, measured
        frame["I_g"] = i_g
    for name in SITE_COLUMNS:  # the facades' irradiance and wind of the plant's weather file
        if name in exo:
            frame[name] = exo[name].to_numpy(dtype=float)[:n]
    if "holiday" in exo:  # the building's holiday calendar
        frame["holiday"] = exo["holiday"].to_numpy(dtype=float)[:n]
    frame.attrs["dt_s"] = float(scenario.sim.dt_s)
    return frame
