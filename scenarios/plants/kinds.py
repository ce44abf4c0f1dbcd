"""The plant kinds (:attr:`scenarios.plants.settings.PlantSettings.kind`): the plant each makes, and what a kind knows in
advance that a scenario asks of it (a building's holiday calendar, the gains its schedules
deliver). The RC kinds (``2r2c``, ``3r3c``) know neither; ``energyplus`` knows both."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.physics import RCParams
from pinn_mpc.simulator import SimConfig
from scenarios.plants.base import LoopPlant
from scenarios.plants.rc import RCPlant
from scenarios.plants.settings import PlantSettings

__all__ = ["holiday_calendar", "make_plant", "scheduled_gains"]


def make_plant(
    config: SimConfig, plant: PlantSettings, *, t_a_c: np.ndarray, g_w_per_m2: np.ndarray, i_g_w: np.ndarray,
    times: np.ndarray | None, seed: int | None, fleet: Sequence[RCParams] | None = None,
) -> LoopPlant:
    """The plant of kind ``plant.kind``: the RC simulator of ``config`` driven by the rows ``t_a_c``,
    ``g_w_per_m2``, ``i_g_w`` (N,), or an EnergyPlus building, which has its own weather and
    gains and places its run by the interval starts ``times`` (N,)."""
    if plant.runs_in_simulator:
        return RCPlant(config, t_a_c=t_a_c, g_w_per_m2=g_w_per_m2, i_g_w=i_g_w, seed=seed, fleet=fleet)
    if fleet is not None:
        raise InputError("a fleet runs on the RC simulator; an EnergyPlus plant is one building")
    if times is None:
        raise InternalError("an EnergyPlus plant needs the series' dates (ExogenousSeries.times)")
    from scenarios.plants.energyplus.plant import EnergyPlusPlant

    return EnergyPlusPlant(config, plant.energyplus, times, seed=seed)


def holiday_calendar(plant: PlantSettings, times: np.ndarray) -> np.ndarray | None:
    """(N,) 1.0 where the interval starting at ``times`` falls on one of the building's
    holidays, else 0.0 (:func:`scenarios.plants.energyplus.schedules.holidays`); None for a
    kind without a calendar."""
    if not plant.is_energyplus:
        return None
    from scenarios.plants.energyplus.schedules import holidays

    return holidays(plant.energyplus, times)


def scheduled_gains(
    plant: PlantSettings, times: np.ndarray, *, setpoint_c: float, dt_s: float, heat_per_w: float
) -> np.ndarray | None:
    """(N,) the internal gains [W] the building's own schedules deliver in the intervals
    starting at ``times``, for a plant whose gains are measured
    (:func:`scenarios.plants.energyplus.schedules.schedule_gains`); None for a kind whose
    gains are the scenario's."""
    if not (plant.is_energyplus and plant.gains == "measured"):
        return None
    from scenarios.plants.energyplus.schedules import schedule_gains

    return schedule_gains(plant.energyplus, times, setpoint_c=setpoint_c, dt_s=dt_s, heat_per_w=heat_per_w)
