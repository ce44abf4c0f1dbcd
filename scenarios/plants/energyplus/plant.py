"""An EnergyPlus building as the closed loop's plant (:class:`scenarios.plants.base.LoopPlant`):
one zone (the zones merged, or kept and heated as one), or each zone controlled on its own
(:class:`ZonedEnergyPlusPlant`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.simulator import SimConfig, StepResult
from pinn_mpc.zones import ONE_ZONE
from scenarios.plants.base import PlantStep
from scenarios.plants.energyplus.model import prepare_plant
from scenarios.plants.energyplus.run import EnergyPlusRun
from scenarios.plants.energyplus.settings import EnergyPlusSettings
from scenarios.plants.energyplus.zoned import ZonedRun

__all__ = ["EnergyPlusPlant", "ZonedEnergyPlusPlant"]


def _run_dates(times: np.ndarray, start: int) -> tuple[int, int, int]:
    """(first day of the year, days, year) of a run from row ``start`` (midnight) of the
    series ``times`` through its last day."""
    first = times[start]
    if first != first.astype("datetime64[D]"):
        raise ValueError(f"an EnergyPlus run starts at midnight, not at {first}")
    days = times[start:].astype("datetime64[D]")
    start_day = int((days[0] - days[0].astype("datetime64[Y]")).astype(int)) + 1
    n_days = int((days[-1] - days[0]).astype(int)) + 1
    year = int(days[0].astype("datetime64[Y]").astype(int)) + 1970
    return start_day, n_days, year


def _substeps(values: np.ndarray, n: int) -> np.ndarray:
    """(n, ...) the zone timesteps' values of an interval, (S, ...): the first interval after
    the warm-up may be short, and is stretched over the interval."""
    if len(values) == n:
        return values
    grid, given = np.linspace(0, 1, n), np.linspace(0, 1, len(values))
    return np.stack([np.interp(grid, given, column) for column in values.reshape(len(values), -1).T], axis=-1).reshape(
        (n, *values.shape[1:])
    )


class _RunPlant:
    """What both EnergyPlus plants do alike: a run dated as the loop's series, started at a
    row's midnight, closed with the plant."""

    run: EnergyPlusRun
    times: np.ndarray
    _rng: np.random.Generator
    _t_r: Any
    _row: int

    def reset(self, t_r_c: float, t_m_c: float, *, start: int, seed: int | None) -> None:
        """A fresh run from row ``start`` (midnight) to the series' last day, warmed up (every
        zone) at ``t_r_c`` (``t_m_c`` is not a state EnergyPlus takes)."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        start_day, n_days, year = _run_dates(self.times, start)
        self.run.warmup_setpoint_c = float(t_r_c)
        # Dated as the series is, so the building's weekday schedules (occupancy, internal
        # gains) fall on the weekdays its time stamps say.
        self._t_r = self.run.start(start_day, n_days, year=year)
        self._row = start

    def close(self) -> None:
        self.run.close()


class EnergyPlusPlant(_RunPlant):
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



class ZonedEnergyPlusPlant(_RunPlant):
    """An EnergyPlus building whose zones are each controlled on its own
    (``settings.zones = "controlled"``) as the closed loop's plant: its zones and actuators
    are the settings' (:attr:`~scenarios.plants.energyplus.settings.EnergyPlusSettings.zone_specs`,
    :attr:`~scenarios.plants.energyplus.settings.EnergyPlusSettings.own_actuators`), run by a
    :class:`~scenarios.plants.energyplus.zoned.ZonedRun`. ``measure`` is each zone's air
    temperature (1, Z) with the sensor noise of ``config``; ``step`` holds (A,) or (1, A)
    electrical powers [W] and returns each zone's temperatures and each actuator's power. The
    backup thermostat of ``config`` acts per actuator on its zone, per EnergyPlus timestep;
    ``reset`` starts each zone warmed up at the given room temperature. No true state."""

    has_true_state = False
    n_buildings = 1

    def __init__(
        self, config: SimConfig, settings: EnergyPlusSettings, times: np.ndarray, *, seed: int | None = 0
    ) -> None:
        actuators = settings.own_actuators
        if not settings.controlled or actuators is None:
            raise InternalError(f"ZonedEnergyPlusPlant: the plant's zones are {settings.zones!r}, not 'controlled'")
        self.config, self.settings = config, settings
        self.zones = settings.zone_specs
        self.actuators = actuators
        self.n_actuators = len(actuators)
        self.times = np.asarray(times, dtype="datetime64[s]")
        self.prepared = prepare_plant(settings)
        self.run = ZonedRun(
            self.prepared, weather=settings.weather, actuators=actuators, dt_s=config.dt_s,
            backup_c=(config.backup_low_c, config.backup_high_c),
        )
        self.n_substeps = int(config.dt_s * self.prepared.timesteps_per_hour // 3600)
        self._rng = np.random.default_rng(seed)
        self._t_r = np.full(len(self.zones), math.nan)
        self._row = -1

    def measure(self) -> np.ndarray:
        t_r = np.array(self._t_r, dtype=float)
        if self.config.noise_std_c > 0:
            t_r += self._rng.normal(0.0, self.config.noise_std_c, size=t_r.shape)
        return t_r[None, :]

    def step(self, u_w: float | np.ndarray, row: int) -> PlantStep:
        """One interval at row ``row`` (the next of the run), each actuator at its power of
        ``u_w`` (A,) or (1, A) [W]."""
        if row != self._row:
            raise InternalError(f"ZonedEnergyPlusPlant.step: the run is at row {self._row}, not {row}")
        u = np.asarray(u_w, dtype=float)
        if u.shape not in ((self.n_actuators,), (1, self.n_actuators)) or not np.all(np.isfinite(u)):
            raise InternalError(
                f"ZonedEnergyPlusPlant.step: one finite power per actuator, ({self.n_actuators},) or "
                f"(1, {self.n_actuators}), got {u_w!r}"
            )
        m = self.run.step(u.reshape(-1))
        assert m.t_r_zones_c is not None and m.t_r_zones_sub_c is not None and m.u_phys_act_w is not None
        self._t_r, self._row = m.t_r_zones_c, row + 1
        return PlantStep(
            t_r_c=m.t_r_zones_c[None, :], t_m_c=np.full((1, len(self.zones)), math.nan),
            u_phys_w=np.array([m.u_phys_w]), overridden=np.array([m.overridden]),
            t_r_sub_c=_substeps(m.t_r_zones_sub_c, self.n_substeps)[None],
            t_a_c=np.array([m.t_a_c]), g_w_per_m2=np.array([m.g_w_per_m2]), i_g_w=np.array([m.i_g_w]),
            u_phys_act_w=m.u_phys_act_w[None, :],
        )
