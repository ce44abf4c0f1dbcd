"""EnergyPlus as the plant kind ``energyplus`` of the registry (:mod:`scenarios.plants.kinds`):
its settings (:class:`~scenarios.plants.energyplus.settings.EnergyPlusSettings`), its factory
(:class:`~scenarios.plants.energyplus.plant.EnergyPlusPlant`, imported with EnergyPlus only when
a plant is made) and what it can do: no true state (no oracle), one building per engine, runs
that start at midnight."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.plant import Plant
from pinn_mpc.simulator import MAX_ACTUATOR_W
from scenarios.plants.base import LoopPlant
from scenarios.plants.energyplus.settings import (
    DATA_POLICY,
    NOMINAL_BUILDING,
    WEATHER_WINDOW,
    EnergyPlusSettings,
)
from scenarios.plants.kinds import KindSettings, PlantKind, PlantRequest, register

__all__ = ["ENERGYPLUS"]


def _make(settings: KindSettings, request: PlantRequest) -> LoopPlant:
    assert isinstance(settings, EnergyPlusSettings)
    if request.fleet is not None or request.n_buildings != 1:
        raise InputError("a fleet runs on the RC simulator; an EnergyPlus plant is one building")
    if request.times is None:
        raise InternalError("an EnergyPlus plant needs the series' dates (ExogenousSeries.times)")
    from scenarios.plants.energyplus.plant import EnergyPlusPlant

    return EnergyPlusPlant(request.config, settings, request.times, seed=request.seed)


def _complete_file(data: dict[str, Any], resolve: Callable[[str], str]) -> None:
    """What a scenario file of an EnergyPlus plant may leave out: ``[building]`` (nominal
    values, :data:`NOMINAL_BUILDING`; a table may give only some, ``eta = -3.0`` making the
    ideal equipment a chiller of COP 3), ``[weather]`` (the plant's EPW in
    :data:`WEATHER_WINDOW`; a ``[weather]`` without ``file_name`` is the plant's EPW in its
    window, as ``scenario export`` writes it), ``simulation.u_max_w`` (the plant's
    ``heater_w``; with neither given, ``heater_w = "auto"``: sized when the scenario is read)
    and ``data_policy`` (:data:`DATA_POLICY`). The plant's weather and building are checked
    first, under their own keys: the ``[weather]`` made from them, or compared with them, would
    otherwise be blamed."""
    from scenarios.plants.energyplus.files import resolve_building, resolve_weather

    simulation = data["simulation"]
    plant = simulation["plant"]
    nominal = NOMINAL_BUILDING.to_dict()
    building = data.setdefault("building", dict(nominal))
    if isinstance(building, dict) and "rc" not in building:
        for key, value in nominal.items():
            building.setdefault(key, value)
    data.setdefault("data_policy", DATA_POLICY)
    weather = plant.get("weather")
    for key, resolve_file in (("weather", resolve_weather), ("building", resolve_building)):
        named = plant.get(key)
        if isinstance(named, str) and named:
            try:
                resolve_file(resolve(named))
            except InputError as exc:
                raise InputError(f"simulation.plant.{key}: {exc.marked}") from None
    if "weather" not in data and isinstance(weather, str):
        data["weather"] = {"type": "TMY3Weather", "file_name": weather, **WEATHER_WINDOW}
    table = data.get("weather")
    if isinstance(table, dict) and isinstance(weather, str) and "file_name" not in table:
        table.setdefault("type", "TMY3Weather")  # the plant's file, in the window given
        if table["type"] == "TMY3Weather":
            table["file_name"] = weather
    heater = plant.get("heater_w")
    if heater is None and "u_max_w" not in simulation:
        plant["heater_w"] = "auto"
    if isinstance(heater, int | float) and not isinstance(heater, bool) and heater > MAX_ACTUATOR_W:
        raise InputError(
            f"simulation.plant.heater_w = {heater:.3g} W is above the plausible "
            f"{MAX_ACTUATOR_W:.0e} W of one building's heater; give it in W"
        )
    if isinstance(heater, int | float) and not isinstance(heater, bool) and heater > 0:
        simulation.setdefault("u_max_w", float(heater))


ENERGYPLUS = register(PlantKind(
    name="energyplus",
    summary="an EnergyPlus building (a bundled DOE reference building or an IDF/epJSON) with an "
    "ideal heater actuated through EnergyPlus's API",
    settings_type=EnergyPlusSettings,
    make=_make,
    structure=lambda settings: Plant(),  # the nominal 2R2C of the scenario describes it
    true_state=False,
    fleets=False,
    starts_at_midnight=True,
    complete_file=_complete_file,
))
