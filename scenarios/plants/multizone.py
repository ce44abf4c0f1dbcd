"""The multi-zone RC simulator as a plant: the kind ``multizone`` of the registry
(:mod:`scenarios.plants.kinds`).

The building is :class:`pinn_mpc.multizone.MultiZoneParams` (each zone a 2R2C, the zones'
air nodes coupled through internal walls), with its own actuators
(:class:`pinn_mpc.actuator.ActuatorSpec`, each named, on a zone, heating or cooling) and a
backup thermostat per actuator (:class:`pinn_mpc.multizone.MultiZoneSimulator`). Its settings
(:class:`MultiZoneSettings`) declare the building and its actuators; the scenario's
``SimConfig`` gives the control interval, the substep, the sensor noise and (unless the
settings give each zone's) the backup limits. Its zones and actuators are the control spec's
(:meth:`scenarios.inputs.registry.Scenario.control_spec`). It has a true state (each zone's
room and mass), so the oracle runs on it. A run holds one building or a fleet: ``n_buildings``
copies of the settings' building, or buildings of their own (each a
:class:`~pinn_mpc.multizone.MultiZoneParams` with the settings' zones, e.g. from
:func:`pinn_mpc.multizone.draw_zoned_fleet`), stepped in one batch with the settings'
actuators and backup limits.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InputError
from pinn_mpc.multizone import MultiZoneConfig, MultiZoneParams, MultiZoneSimulator
from pinn_mpc.plant import Plant
from pinn_mpc.solar import FACADE_COLUMNS
from pinn_mpc.zones import ZoneSpec
from scenarios.plants.base import PlantStep
from scenarios.plants.kinds import KindSettings, PlantKind, PlantRequest, register

__all__ = ["MULTIZONE", "MultiZonePlant", "MultiZoneSettings"]


@dataclass(frozen=True, kw_only=True)
class MultiZoneSettings(KindSettings):
    """A multi-zone RC building (``building``), its actuators (``actuators``, each named, on
    one of its zones) and, optionally, each zone's backup-thermostat limits [C]
    (``backup_low_c``/``backup_high_c``: a number for every zone or one per zone; None: the
    scenario's ``SimConfig`` limits)."""

    building: MultiZoneParams
    actuators: tuple[ActuatorSpec, ...]
    backup_low_c: float | tuple[float, ...] | None = None
    backup_high_c: float | tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.building, MultiZoneParams):
            raise InputError(f"multizone plant: building must be a MultiZoneParams, got {type(self.building).__name__}")
        object.__setattr__(self, "actuators", tuple(self.actuators))
        names = [a.name for a in self.actuators]
        if not self.actuators or "" in names or len(set(names)) != len(names):
            raise InputError(
                f"multizone plant: give one or more actuators, each with its own name (its data "
                f"columns u[<name>]), got names {names}"
            )
        try:  # the actuators on the building's zones, the limits' shape
            low, high = self.backup_limits(17.0, 20.5)
            MultiZoneConfig(params=self.building, actuators=self.actuators, backup_low_c=low, backup_high_c=high)
        except ValueError as exc:
            raise InputError(f"multizone plant: {exc}") from None

    def backup_limits(self, low_c: float, high_c: float) -> tuple[float | tuple[float, ...], float | tuple[float, ...]]:
        """The backup limits (low, high): the settings' own where given, else ``low_c``/``high_c``."""
        return (
            low_c if self.backup_low_c is None else self.backup_low_c,
            high_c if self.backup_high_c is None else self.backup_high_c,
        )

    @property
    def zone_specs(self) -> tuple[ZoneSpec, ...]:
        return self.building.zone_specs

    @property
    def own_actuators(self) -> tuple[ActuatorSpec, ...] | None:
        return self.actuators

    @property
    def needs_facades(self) -> bool:
        return any(z.solar_input != "G" for z in self.building.zones)

    @property
    def zone_solar_inputs(self) -> tuple[str | None, ...] | None:
        return tuple(z.solar_input if z.rc.solar_aperture_m2 > 0 else None for z in self.building.zones)


class MultiZonePlant:
    """:class:`~pinn_mpc.multizone.MultiZoneSimulator` as a
    :class:`~scenarios.plants.base.LoopPlant` of B buildings (``fleet``: each its own
    building; None: ``n_buildings`` of ``config.params``), driven by the rows of the
    exogenous series (``weather``: name -> (N,), :data:`pinn_mpc.multizone.EXOGENOUS_NAMES`
    those it has), so the interval means are those rows."""

    has_true_state = True

    def __init__(
        self, config: MultiZoneConfig, weather: Mapping[str, np.ndarray], *, seed: int | None,
        fleet: Sequence[MultiZoneParams] | None = None, n_buildings: int = 1,
    ) -> None:
        self.sim = MultiZoneSimulator(
            config, seed=seed, fleet=fleet, n_buildings=None if fleet is not None else n_buildings
        )
        self.n_buildings = self.sim.n_buildings
        self.weather = weather
        self.zones = config.params.zone_specs
        self.n_substeps = config.n_substeps
        self.n_actuators = len(config.actuators)

    def reset(self, t_r_c: float, t_m_c: float, *, start: int, seed: int | None) -> None:
        self.sim.reset(t_r_c, t_m_c, seed=seed)

    def measure(self) -> np.ndarray:
        return self.sim.measure()

    def true_state(self) -> np.ndarray:
        """(B, 2) the first zone's room and mass (the one-zone references' view; the zones'
        are :meth:`true_zone_states`)."""
        return self.true_zone_states()[:, :, 0]

    def true_zone_states(self) -> np.ndarray:
        z = len(self.zones)
        state = self.sim.state
        return np.stack([state[:, :z], state[:, z:]], axis=1)

    def step(self, u_w: float | np.ndarray, row: int) -> PlantStep:
        weather = {name: float(values[row]) for name, values in self.weather.items()}
        result = self.sim.step(u_w, weather)
        shape = (self.n_buildings,)
        return PlantStep(
            t_r_c=result.t_r_c, t_m_c=result.t_m_c, u_phys_w=result.power_w.sum(axis=1),
            overridden=np.asarray(result.overridden.any(axis=1)), t_r_sub_c=result.t_r_sub_c,
            t_a_c=np.full(shape, weather["T_a"]), g_w_per_m2=np.full(shape, weather["G"]),
            i_g_w=np.full(shape, weather["I_g"]), u_phys_act_w=result.power_w,
        )

    def close(self) -> None:
        """Nothing to free."""


def _make(settings: KindSettings, request: PlantRequest) -> MultiZonePlant:
    assert isinstance(settings, MultiZoneSettings)
    fleet: list[MultiZoneParams] | None = None
    if request.fleet is not None:
        given = list(request.fleet)
        wrong = [i for i, p in enumerate(given) if not isinstance(p, MultiZoneParams)]
        if wrong:
            raise InputError(
                f"a multi-zone plant's fleet holds multi-zone buildings, but building {wrong[0]} is a "
                f"{type(given[wrong[0]]).__name__}: draw it with pinn_mpc.multizone.draw_zoned_fleet"
            )
        fleet = [p for p in given if isinstance(p, MultiZoneParams)]
    sim = request.config
    low, high = settings.backup_limits(sim.backup_low_c, sim.backup_high_c)
    config = MultiZoneConfig(
        params=settings.building, actuators=settings.actuators, dt_s=sim.dt_s,
        substep_s=sim.substep_s, noise_std_c=sim.noise_std_c, backup_low_c=low, backup_high_c=high,
    )
    weather = {"T_a": request.t_a_c, "G": request.g_w_per_m2, "I_g": request.i_g_w}
    if settings.needs_facades:
        facades = request.facades or {}
        missing = [name for name in FACADE_COLUMNS if name not in facades]
        if missing:
            raise InputError(
                f"the multi-zone building's windows take facade irradiance, but the run has no "
                f"{', '.join(missing)}: give its scenario a TMY3 weather file"
            )
        weather.update({name: np.asarray(facades[name]) for name in FACADE_COLUMNS})
    try:
        return MultiZonePlant(config, weather, seed=request.seed, fleet=fleet, n_buildings=request.n_buildings)
    except ValueError as exc:  # a fleet building of other zones than the settings'
        raise InputError(f"multizone plant: {exc}") from None


MULTIZONE = register(PlantKind(
    name="multizone",
    summary="the package's minute-level RC simulator of coupled zones, each a 2R2C, with heating and cooling",
    settings_type=MultiZoneSettings, make=_make, structure=lambda settings: Plant(),
    true_state=True, fleets=True,
))
