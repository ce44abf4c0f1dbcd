"""Training and test data: simulate a scenario under a simple policy, in the data format.

Policies:

- ``random`` (the paper's): in each interval, independently per building, demand the
  actuator's full power (its upper bound, ``u_max``) with probability ``on_probability``, else
  off (its lower bound, 0).
- ``random-level``: in each interval, independently per building, a demand drawn uniformly
  from the actuator's bounds, ``[0, u_max]``. On/off data shows a network only the two
  extremes of the power; a controller that modulates the power asks it about the levels in
  between, which this policy covers (a multi-level excitation signal, as system identification
  recommends).
- ``thermostat``: :class:`controllers.thermostat.Thermostat` on the scenario's comfort band
  (its rule :meth:`~controllers.thermostat.Thermostat.switch`, batched over buildings).
- ``closed-loop``: random setpoint steps tracked by a proportional controller with a random
  dither (:class:`SetpointPolicy`): a setpoint drawn uniformly from the scenario's comfort
  band widened by 1 K, held 1-8 h, and a power of the actuator's range x (0.5 / K x
  (setpoint - T_r) + a uniform dither of +-0.25), within its bounds. The room stays near where a controller
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

from controllers.base import ControlSpec, Forecast, Observation
from controllers.thermostat import Thermostat
from pinn_mpc.actuator import ActuatorSpec, actuator_columns
from pinn_mpc.data import SITE_COLUMNS
from pinn_mpc.errors import InputError, InternalError, setting
from pinn_mpc.physics import RCParams
from pinn_mpc.zones import zone_columns, zone_series_columns
from scenarios.choices import POLICIES
from scenarios.inputs.registry import Scenario, check_seed
from scenarios.inputs.series import ExogenousSeries
from scenarios.running.engine import ClosedLoop, LoopRecord

__all__ = ["DataPolicy", "SetpointPolicy", "add_cop", "generate"]

# Random streams apart from the exogenous ones (see scenarios.inputs.registry).
_POLICY_STREAM, _SENSOR_STREAM = 11, 12


def add_cop(scenario: Scenario, frame: pd.DataFrame) -> None:
    """Add ``cop`` to ``frame`` (data of ``scenario``) when its one actuator is a heat pump: the
    heat per electrical watt [-] at each row's outdoor temperature ``T_a`` [degC], as the plant
    applied it (what identification and training take the delivered heat from)."""
    actuators = scenario.sim.actuators
    if len(actuators) == 1 and not actuators[0].is_ideal:
        frame["cop"] = actuators[0].gain(frame["T_a"].to_numpy(dtype=float))


@dataclass(frozen=True, kw_only=True)
class SetpointPolicy:
    """The ``closed-loop`` data policy (module docstring): random setpoint steps tracked by a
    proportional controller with a dither. ``draws`` (N, 3) uniform [0, 1) numbers per interval
    (setpoint, hold, dither); the setpoint range ``[low_c, high_c]``, held ``hold_steps``
    intervals (lowest, highest), ``gain_per_k`` of the actuator's range per kelvin below the
    setpoint, ``dither`` the half-width of the uniform dither as a fraction of that range; the
    power is the ``actuator``'s, within its bounds."""

    actuator: ActuatorSpec
    low_c: float
    high_c: float
    hold_steps: tuple[int, int]
    gain_per_k: float = 0.5
    dither: float = 0.25

    @classmethod
    def for_data(
        cls, actuator: ActuatorSpec, t_min: np.ndarray, t_max: np.ndarray, dt_s: float
    ) -> SetpointPolicy:
        """The policy of ``actuator`` for a comfort band ``t_min``..``t_max`` (C) widened by 1 K,
        setpoints held 1-8 h at ``dt_s``."""
        steps_h = 3600.0 / dt_s
        return cls(
            actuator=actuator,
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
        return self.actuator.at_fraction(level)


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
        raise ValueError(f"unknown policy {policy!r}; choose one of: {', '.join(POLICIES)}")
    if not 0.0 <= on_probability <= 1.0:
        raise ValueError(f"on_probability must lie in [0, 1], got {on_probability!r}")
    if n_buildings < 1:
        raise ValueError(f"n_buildings must be >= 1, got {n_buildings}")
    check_seed(seed)
    if fleet is not None and not scenario.plant.fleets:
        raise InputError("a fleet with its own parameters runs on the RC simulator, not EnergyPlus")
    if n_buildings > 1 and not scenario.plant.fleets:
        raise InputError(
            f"an EnergyPlus building is one building; {setting('n_buildings')} {n_buildings} needs an "
            "RC scenario"
        )
    if n_buildings > 1 and not scenario.control_spec().single:
        raise InputError(
            f"{setting('n_buildings')} {n_buildings}: data of a building of several zones are "
            f"simulated one building at a time; leave it at 1 (a fleet of scenario {scenario.name!r} "
            "runs in `pinn-mpc closed-loop`, its buildings drawn there)"
        )
    exo = scenario.exogenous(days=days, seed=seed, part=weather_part)
    cols = {c: exo[c].to_numpy(dtype=float) for c in ("price", "T_min", "T_max")}
    spec = scenario.control_spec()
    n = len(exo)
    rng = np.random.default_rng([seed, _POLICY_STREAM])
    act = DataPolicy(policy, spec, cols, n=n, n_buildings=n_buildings, on_probability=on_probability, rng=rng)
    sensor_seed = int(np.random.default_rng([seed, _SENSOR_STREAM]).integers(2**63))
    with ClosedLoop(
        scenario.sim, ExogenousSeries.from_frame(exo), spec=spec,
        initial_t_r_c=scenario.initial_t_r_c, initial_t_m_c=scenario.initial_t_m_c,
        seed=sensor_seed, fleet=fleet, n_buildings=n_buildings, plant_settings=scenario.plant,
    ) as loop:
        for k in range(n):
            loop.step(act(k, loop.measured()))
        records = [loop.record(i) for i in range(n_buildings)]
    return _frame(scenario, exo, cols, records)


class DataPolicy:
    """A data policy (module docstring) for ``n_buildings`` buildings over ``n`` intervals:
    called with the interval ``k`` and the buildings' measured room temperatures (B, Z), the
    demand (B,) [W]. Its draws come from ``rng`` up front, in the order the policies have
    always drawn them. A building of several actuators (one building) gets each actuator's
    own draws, (A,) demands: ``random`` and ``random-level`` independently per actuator, the
    ``thermostat`` each actuator's rule on its zone (:class:`Thermostat`), ``closed-loop`` a
    setpoint sequence per zone (:class:`SetpointPolicy`'s, drawn for each zone) which each
    actuator tracks on its zone, a heater below it and a chiller above it, each with its own
    dither."""

    def __init__(
        self, policy: str, spec: ControlSpec, cols: dict[str, np.ndarray], *, n: int, n_buildings: int,
        on_probability: float, rng: np.random.Generator,
    ) -> None:
        self.policy, self.spec, self.cols, self.on_probability = policy, spec, cols, on_probability
        self.actuators = spec.n_actuators
        if self.actuators > 1:
            if policy == "closed-loop":  # each zone its own setpoints, each actuator its dither
                zone_draws = rng.random((len(spec.zones), n, 3))
                self.zone_tracking = [
                    SetpointPolicy.for_data(spec.actuators[0], cols["T_min"], cols["T_max"], spec.dt_s)
                    for _ in spec.zones
                ]
                self.zone_setpoints = np.stack(
                    [p.setpoints(d) for p, d in zip(self.zone_tracking, zone_draws, strict=True)], axis=1
                )  # (n, Z)
            self.draws = rng.random((n, self.actuators))
            self.thermostat = Thermostat(spec)
            return
        if policy == "closed-loop":
            self.tracking = SetpointPolicy.for_data(spec.actuator, cols["T_min"], cols["T_max"], spec.dt_s)
            self.draws = rng.random((n, 3))
            self.setpoints = self.tracking.setpoints(self.draws)
        else:
            self.draws = rng.random((n, n_buildings))
        self.thermostat = Thermostat(spec)
        self.on = np.zeros(n_buildings, dtype=bool)

    def __call__(self, k: int, t_r_zones: np.ndarray) -> np.ndarray:
        if self.actuators > 1:
            return self._zones(k, t_r_zones[0])
        t_r = t_r_zones[:, 0]
        actuator = self.spec.actuator
        if self.policy == "random":
            return actuator.on_off(self.draws[k] < self.on_probability)
        if self.policy == "random-level":
            return actuator.at_fraction(self.draws[k])
        if self.policy == "closed-loop":
            return self.tracking.demand(t_r, self.setpoints[k], self.draws[k])
        # the thermostat's rule, batched over the buildings (it sees only T_r and the band)
        self.on = self.thermostat.switch(t_r, self.on, self.cols["T_min"][k], self.cols["T_max"][k])
        return actuator.on_off(self.on)

    def _zones(self, k: int, t_r: np.ndarray) -> np.ndarray:
        """(A,) the demands of a building of several actuators, its zones at ``t_r`` (Z,)."""
        actuators = self.spec.actuators
        if self.policy == "random":
            return np.array([a.on_off(bool(d < self.on_probability)) for a, d in zip(actuators, self.draws[k], strict=True)])
        if self.policy == "random-level":
            return np.array([a.at_fraction(float(d)) for a, d in zip(actuators, self.draws[k], strict=True)])
        if self.policy == "closed-loop":
            tracking = self.zone_tracking[0]
            levels = np.array([
                tracking.gain_per_k * a.sign * (self.zone_setpoints[k, a.zone] - t_r[a.zone])
                + tracking.dither * (2.0 * d - 1.0)
                for a, d in zip(actuators, self.draws[k], strict=True)
            ])
            return np.array([a.at_fraction(float(level)) for a, level in zip(actuators, levels, strict=True)])
        history = {c: np.array([t]) for c, t in zip(zone_columns("T_r", self.spec.zones), t_r, strict=True)}
        band = {c: self.cols[c][k : k + 1] for c in ("T_min", "T_max")}
        obs = Observation.from_history(k, history, zones=self.spec.zones)
        forecast = Forecast(
            time_of_day_h=np.zeros(1), T_a=np.zeros(1), G=np.zeros(1), I_g=np.zeros(1), price=np.zeros(1), **band
        )
        return np.asarray(self.thermostat.act(obs, forecast), dtype=float)


def _frame(
    scenario: Scenario, exo: pd.DataFrame, cols: dict[str, np.ndarray], records: list[LoopRecord]
) -> pd.DataFrame:
    """The data-format frame of the buildings' loop records, one after another, a ``building``
    column when there is more than one: ``T_m`` where the plant has a true state, the
    outdoor temperature, irradiance and (where they are the scenario's or measured) gains as
    the plant had them, the weather file's facades and wind and the building's holidays where
    the run has them, the COP per row under a heat pump."""
    n_buildings, n = len(records), len(records[0].t_r_c)

    def stacked(name: str) -> np.ndarray:
        return np.concatenate([getattr(r, name) for r in records])

    zones = records[0].zones
    columns: dict[str, np.ndarray] = {
        "time": np.tile(exo["time"].to_numpy()[:n], n_buildings),
        **zone_series_columns("T_r", stacked("t_r_c"), zones),
    }
    if scenario.plant.true_state:
        columns |= zone_series_columns("T_m", stacked("t_m_c"), zones)
    columns |= {"u": stacked("u_w"), "u_phys": stacked("u_phys_w")}
    actuators = records[0].actuators
    if len(actuators) > 1:  # each actuator's power, beside the building's total
        for series, name in (("u", "u_act_w"), ("u_phys", "u_phys_act_w")):
            columns |= dict(zip(actuator_columns(series, actuators), stacked(name).T, strict=True))
    columns["T_a"] = stacked("t_a_c")
    columns |= {c: np.tile(cols[c][:n], n_buildings) for c in ("price", "T_min", "T_max")}
    if scenario.uses_solar:
        columns["G"] = stacked("g_w_per_m2")
    if scenario.gains_given:  # as they happened
        columns["I_g"] = stacked("i_g_w")
    for name in (*SITE_COLUMNS, "holiday"):  # the weather file's facades and wind, the calendar
        if name in exo:
            columns[name] = np.tile(exo[name].to_numpy(dtype=float)[:n], n_buildings)
    frame = pd.DataFrame(columns)
    (actuator,) = scenario.sim.actuators
    add_cop(scenario, frame)
    if n_buildings > 1:
        frame.insert(0, "building", np.repeat(np.arange(n_buildings), n))
    frame.attrs["dt_s"] = float(scenario.sim.dt_s)
    return frame
