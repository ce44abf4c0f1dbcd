"""An EnergyPlus building as the closed loop's plant (:class:`scenarios.plants.base.LoopPlant`)."""

from __future__ import annotations

import math

import numpy as np

from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.simulator import SimConfig, StepResult
from pinn_mpc.zones import ONE_ZONE
from scenarios.plants.base import PlantStep
from scenarios.plants.energyplus.model import prepare_plant
from scenarios.plants.energyplus.run import EnergyPlusRun
from scenarios.plants.energyplus.settings import EnergyPlusSettings

__all__ = ["EnergyPlusPlant"]


class EnergyPlusPlant:
    """An EnergyPlus building as the closed loop's plant (:class:`scenarios.plants.base.LoopPlant`).

    ``settings`` name the building and the weather
    (:class:`~scenarios.plants.energyplus.settings.EnergyPlusSettings`); ``config`` gives the
    heater's power, the control interval, the backup thermostat, the sensor noise and ``eta``
    (heater or chiller); ``times`` (N,) are the interval starts of the loop's series,
    whose day of the year places each run in the weather file. :meth:`reset` starts a fresh
    EnergyPlus run at the start row's midnight through the series' last day, warmed up at the
    given room temperature; the backup thermostat of ``config`` acts per EnergyPlus timestep;
    the sensor noise of ``config`` is added to every measurement. It has no true state
    (no mass temperature for a controller with perfect knowledge).
    """

    has_true_state = False
    zones = ONE_ZONE  # the zones' mean room temperature (settings.zones: merged or kept)
    n_buildings = 1

    def __init__(
        self, config: SimConfig, settings: EnergyPlusSettings, times: np.ndarray, *, seed: int | None = 0
    ) -> None:
        plant = settings
        eta = config.params.eta
        if not config.actuator.is_ideal or not (eta == 1.0 or eta < 0):
            raise InputError(
                "an EnergyPlus plant is heated by an ideal electric heater (the ideal actuator, "
                f"eta = 1) or cooled by an ideal chiller (eta = -COP), not eta = {eta:g}"
            )
        if (
            isinstance(plant.heater_w, float | int)
            and plant.heater_w
            and abs(plant.heater_w - config.u_max_w) > 1e-6 * plant.heater_w
        ):
            raise InputError(
                f"plant.heater_w = {plant.heater_w:g} W differs from simulation.u_max_w = "
                f"{config.u_max_w:g} W; give the heater's power once"
            )
        self.config, self.settings = config, settings
        self.times = np.asarray(times, dtype="datetime64[s]")
        self.prepared = prepare_plant(plant)
        self.run = EnergyPlusRun(
            self.prepared,
            weather=plant.weather,
            actuator=config.actuators[0],
            dt_s=config.dt_s,
            backup_c=(config.backup_low_c, config.backup_high_c),
            heat_per_w=eta,
        )
        self.n_substeps = int(config.dt_s * self.prepared.timesteps_per_hour // 3600)
        self._rng = np.random.default_rng(seed)
        self._t_r = math.nan
        self._row = -1

    def reset(self, t_r_c: float, t_m_c: float, *, start: int, seed: int | None) -> None:
        """A fresh run from row ``start`` (midnight) to the series' last day, warmed up at
        ``t_r_c`` (``t_m_c`` is not a state EnergyPlus takes)."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        first = self.times[start]
        if first != first.astype("datetime64[D]"):
            raise ValueError(f"an EnergyPlus run starts at midnight, not at {first}")
        days = self.times[start:].astype("datetime64[D]")
        start_day = int((days[0] - days[0].astype("datetime64[Y]")).astype(int)) + 1
        n_days = int((days[-1] - days[0]).astype(int)) + 1
        self.run.warmup_setpoint_c = float(t_r_c)
        # Dated as the series is, so the building's weekday schedules (occupancy, internal
        # gains) fall on the weekdays its time stamps say.
        year = int(days[0].astype("datetime64[Y]").astype(int)) + 1970
        self._t_r = self.run.start(start_day, n_days, year=year)
        self._row = start

    def measure(self) -> np.ndarray:
        t_r = np.array([self._t_r])
        if self.config.noise_std_c > 0:
            t_r += self._rng.normal(0.0, self.config.noise_std_c, size=1)
        return t_r[:, None]

    def step(self, u_w: float | np.ndarray, row: int) -> PlantStep:
        """One interval at row ``row`` (the next of the run)."""
        if row != self._row:
            raise InternalError(f"EnergyPlusPlant.step: the run is at row {self._row}, not {row}")
        u = np.asarray(u_w, dtype=float).reshape(-1)
        if u.size != 1 or not math.isfinite(float(u[0])):
            raise InternalError(f"EnergyPlusPlant.step: one finite power, got {u_w!r}")
        m = self.run.step(float(u[0]))
        self._t_r, self._row = m.t_r_c, row + 1
        sub = m.t_r_sub_c
        if len(sub) != self.n_substeps:  # the first interval after warm-up may be short
            sub = np.interp(np.linspace(0, 1, self.n_substeps), np.linspace(0, 1, len(sub)), sub)
        result = StepResult(
            t_r_c=np.array([m.t_r_c]),
            t_m_c=np.array([math.nan]),
            u_phys_w=np.array([m.u_phys_w]),
            overridden=np.array([m.overridden]),
            t_r_sub_c=sub.reshape(1, -1),
        )
        return PlantStep.of_one_zone(
            result, np.array([m.t_a_c]), np.array([m.g_w_per_m2]), np.array([m.i_g_w])
        )

    def close(self) -> None:
        self.run.close()

