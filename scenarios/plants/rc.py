"""The RC simulator as a plant: the minute-level 2R2C or 3R3C of :mod:`pinn_mpc.simulator`, with
its backup thermostat, one building or a fleet stepped in one batch; the kinds ``2r2c`` and
``3r3c`` of the registry (:mod:`scenarios.plants.kinds`), whose settings are the envelope's
(:class:`RCSettings`; the 2R2C has none of its own)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from pinn_mpc.errors import InputError
from pinn_mpc.physics import RCParams
from pinn_mpc.plant import RC_KINDS, Plant
from pinn_mpc.simulator import SimConfig, Simulator
from pinn_mpc.zones import ONE_ZONE
from scenarios.plants.base import PlantStep
from scenarios.plants.kinds import KindSettings, PlantKind, PlantRequest, register
from scenarios.plants.settings import PlantSettings

__all__ = ["RCPlant", "RCSettings", "rc_plant_settings"]


@dataclass(frozen=True, kw_only=True)
class RCSettings(KindSettings):
    """The RC simulator's envelope node (:class:`pinn_mpc.plant.Plant`; the 3R3C's, unused by
    the 2R2C): its capacity [J/K] and its share of R_ra towards the outdoor air."""

    envelope_capacity_j_per_k: float = 1.0e7
    envelope_resistance_fraction: float = 0.5

    def __post_init__(self) -> None:
        try:  # checked for every RC kind, as files always were
            Plant(kind="3r3c", envelope_capacity_j_per_k=self.envelope_capacity_j_per_k,
                  envelope_resistance_fraction=self.envelope_resistance_fraction)
        except InputError as exc:
            raise InputError(str(exc).replace("Plant.", f"{type(self).__name__}.")) from None


class RCPlant:
    """The RC simulator (:class:`pinn_mpc.simulator.Simulator`) as a
    :class:`~scenarios.plants.base.LoopPlant`, driven by the rows of the outdoor temperature
    ``t_a_c`` [C], irradiance ``g_w_per_m2`` [W/m2] and internal gains ``i_g_w`` [W], (N,)
    each, so the interval means are those rows."""

    has_true_state = True
    zones = ONE_ZONE

    def __init__(
        self, config: SimConfig, *, t_a_c: np.ndarray, g_w_per_m2: np.ndarray, i_g_w: np.ndarray,
        seed: int | None, fleet: Sequence[RCParams] | None, n_buildings: int = 1,
    ) -> None:
        self.sim = Simulator(config, seed=seed, fleet=fleet, n_buildings=None if fleet else n_buildings)
        self.t_a_c, self.g_w_per_m2, self.i_g_w = t_a_c, g_w_per_m2, i_g_w
        self.n_buildings = self.sim.n_buildings
        self.n_substeps = config.n_substeps

    def reset(self, t_r_c: float, t_m_c: float, *, start: int, seed: int | None) -> None:
        self.sim.reset(t_r_c, t_m_c, seed=seed)

    def measure(self) -> np.ndarray:
        return self.sim.measure()[:, None]

    def true_state(self) -> np.ndarray:
        return np.array(self.sim.state[:, :2], dtype=float)

    def true_zone_states(self) -> np.ndarray:
        return self.true_state()[:, :, None]

    def step(self, u_w: float | np.ndarray, row: int) -> PlantStep:
        t_a, g, i_g = self.t_a_c[row], self.g_w_per_m2[row], self.i_g_w[row]
        result = self.sim.step(u_w, t_a, g, i_g)
        shape = (self.n_buildings,)
        return PlantStep.of_one_zone(result, np.full(shape, t_a), np.full(shape, g), np.full(shape, i_g))

    def close(self) -> None:
        """Nothing to free."""


def _structure(kind: str):  # the simulator's structure of an RC kind's settings
    def structure(settings: KindSettings) -> Plant:
        assert isinstance(settings, RCSettings)
        return Plant(
            kind=kind, envelope_capacity_j_per_k=settings.envelope_capacity_j_per_k,
            envelope_resistance_fraction=settings.envelope_resistance_fraction,
        )

    return structure


def _make(settings: KindSettings, request: PlantRequest) -> RCPlant:
    fleet = None if request.fleet is None else list(request.fleet)
    if fleet is not None and not all(isinstance(p, RCParams) for p in fleet):
        raise InputError(
            "the RC simulator's fleet holds one-zone buildings (RCParams); a fleet of buildings of "
            "several zones runs on a multizone plant"
        )
    return RCPlant(
        request.config, t_a_c=request.t_a_c, g_w_per_m2=request.g_w_per_m2, i_g_w=request.i_g_w,
        seed=request.seed, fleet=cast("list[RCParams] | None", fleet), n_buildings=request.n_buildings,
    )


for _name in RC_KINDS:
    register(PlantKind(
        name=_name,
        summary=f"the package's minute-level {_name.upper()} simulator with its backup thermostat",
        settings_type=RCSettings, make=_make, structure=_structure(_name), true_state=True,
        fleets=True,
    ))


def rc_plant_settings(structure: Plant) -> PlantSettings:
    """The plant settings of the RC simulator's ``structure`` (its kind and envelope)."""
    return PlantSettings(
        kind=structure.kind,
        settings=RCSettings(
            envelope_capacity_j_per_k=structure.envelope_capacity_j_per_k,
            envelope_resistance_fraction=structure.envelope_resistance_fraction,
        ),
    )
