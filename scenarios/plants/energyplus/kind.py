"""EnergyPlus as the plant kind ``energyplus`` of the registry (:mod:`scenarios.plants.kinds`):
its settings (:class:`~scenarios.plants.energyplus.settings.EnergyPlusSettings`), its factory
(:class:`~scenarios.plants.energyplus.plant.EnergyPlusPlant`, or
:class:`~scenarios.plants.energyplus.plant.ZonedEnergyPlusPlant` where the zones are each
controlled; imported with EnergyPlus only when a plant is made) and what it can do: no true
state (no oracle), one building per engine, runs that start at midnight."""

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
    season_window,
)
from scenarios.plants.kinds import KindSettings, PlantKind, PlantRequest, register

__all__ = ["ENERGYPLUS"]


def _make(settings: KindSettings, request: PlantRequest) -> LoopPlant:
    assert isinstance(settings, EnergyPlusSettings)
    if request.fleet is not None or request.n_buildings != 1:
        raise InputError("a fleet runs on the RC simulator; an EnergyPlus plant is one building")
    if request.times is None:
        raise InternalError("an EnergyPlus plant needs the series' dates (ExogenousSeries.times)")
    from scenarios.plants.energyplus.plant import EnergyPlusPlant, ZonedEnergyPlusPlant

    if settings.controlled:
        return ZonedEnergyPlusPlant(request.config, settings, request.times, seed=request.seed)
    return EnergyPlusPlant(request.config, settings, request.times, seed=request.seed)


def _complete_file(data: dict[str, Any], resolve: Callable[[str], str]) -> None:
    """What a scenario file of an EnergyPlus plant may leave out: ``[building]`` (nominal
    values, :data:`NOMINAL_BUILDING`; a table may give only some, ``eta = -3.0`` making the
    ideal equipment a chiller of COP 3), ``[weather]`` (the plant's EPW in
    :data:`WEATHER_WINDOW`; a ``[weather]`` without ``file_name`` is the plant's EPW in its
    window, as ``scenario export`` writes it, and ``[weather] season = "july"`` the window of
    that month, :func:`~scenarios.plants.energyplus.settings.season_window`),
    ``simulation.u_max_w`` (the plant's ``heater_w``, the zones' heaters' total where they are
    controlled; with neither given, ``heater_w = "auto"``: sized when the scenario is read;
    ``simulation.u_max_w`` alone is then the heaters' total) and ``data_policy``
    (:data:`DATA_POLICY`). The plant's weather and building are checked first, under their own
    keys: the ``[weather]`` made from them, or compared with them, would otherwise be blamed."""
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
    if isinstance(table, dict) and "season" in table:
        _season(table)
    if isinstance(table, dict) and isinstance(weather, str) and "file_name" not in table:
        table.setdefault("type", "TMY3Weather")  # the plant's file, in the window given
        if table["type"] == "TMY3Weather":
            table["file_name"] = weather
    heater = plant.get("heater_w")
    if plant.get("zones") == "controlled":
        _complete_zones(plant, simulation)
        return
    if heater is None and "u_max_w" not in simulation:
        plant["heater_w"] = "auto"
    if isinstance(heater, int | float) and not isinstance(heater, bool) and heater > MAX_ACTUATOR_W:
        raise InputError(
            f"simulation.plant.heater_w = {heater:.3g} W is above the plausible "
            f"{MAX_ACTUATOR_W:.0e} W of one building's heater; give it in W"
        )
    if isinstance(heater, int | float) and not isinstance(heater, bool) and heater > 0:
        simulation.setdefault("u_max_w", float(heater))


def _season(table: dict[str, Any]) -> None:
    """``[weather] season``: the window of that month (tested on, the month before trained on)
    in place of the window's keys."""
    season = table.pop("season")
    given = [key for key in WEATHER_WINDOW if key in table]
    if given:
        raise InputError(
            f"weather.season = {season!r} sets the window; leave out weather.{given[0]} (or season)"
        )
    if not isinstance(season, str):
        raise InputError(f"weather.season = {season!r} must be a month's name, such as \"july\"")
    table.update(season_window(season.lower()))


def _complete_zones(plant: dict[str, Any], simulation: dict[str, Any]) -> None:
    """``zones = "controlled"``: ``heater_w`` is the zones' heaters (``simulation.u_max_w``
    alone their total; neither: ``"auto"``) and ``simulation.u_max_w``, the nominal one-zone
    view's heater, their total where they are given in W."""
    heater = plant.get("heater_w")
    if heater is None:
        plant["heater_w"] = simulation.get("u_max_w", "auto")
        heater = plant["heater_w"]
    for key in ("heater_w", "chiller_w"):
        value = plant.get(key)
        powers = value if isinstance(value, list) else [value]
        for power in powers:
            if isinstance(power, int | float) and not isinstance(power, bool) and power > MAX_ACTUATOR_W:
                raise InputError(
                    f"simulation.plant.{key} = {power:.3g} W is above the plausible "
                    f"{MAX_ACTUATOR_W:.0e} W of one building's {key.removesuffix('_w')}; give it in W"
                )
    total = sum(heater) if isinstance(heater, list) and all(isinstance(p, int | float) for p in heater) else heater
    if isinstance(total, int | float) and not isinstance(total, bool) and total > 0:
        given = simulation.setdefault("u_max_w", float(total))
        if isinstance(given, int | float) and abs(given - total) > 1e-6 * total:
            raise InputError(
                f"simulation.u_max_w = {given:g} W, but simulation.plant.heater_w gives the zones' "
                f"heaters {total:g} W in all; give their power once (leave u_max_w out)"
            )


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
