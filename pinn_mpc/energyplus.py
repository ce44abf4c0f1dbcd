"""EnergyPlus as a plant: a building model run step by step through EnergyPlus's Python API.

The engine is ``pyenergyplus-lbnl`` (EnergyPlus and its API as one wheel, Linux x86_64), which
also ships DOE's reference buildings (:func:`bundled_buildings`) and TMY3 weather files
(:func:`bundled_weather`); it is imported only when a model is prepared or run.

:func:`prepare_model` turns a bundled building (by name) or a user's IDF/epJSON into the plant:
the envelope, its schedules and internal loads are kept, everything else (HVAC, plant, service
water, sizing, output requests, and any code the model would run) is dropped; the conditioned
zones are merged into one thermal zone (partitions between them become internal mass, per-area
loads absolute); one ideal electric heater (an ``OtherEquipment`` object, all convective) heats
it. A model declaring ``PythonPlugin:*`` or ``ExternalInterface:*`` objects is refused unless
``allow_code``; then those objects are kept.

:class:`EnergyPlusRun` runs one simulation in a thread of its own and hands over every control
interval through two queues: the controller's power goes in, the room temperature at the end
of the interval and the interval's means come out. The heater's power is set through the API's
``OtherEquipment`` / ``Power Level`` actuator at every zone timestep (6 per hour), where a backup
thermostat may override it. Every wait has a timeout; an error in EnergyPlus (its first severe
message) or in a callback ends the run and reaches the caller; :meth:`EnergyPlusRun.close`
stops the thread and removes the run's temporary directory, on errors and Ctrl-C too.

EnergyPlus's own pitfalls handled here: its ``current_time`` follows the shortened system
timestep, so the clock is built from day of year, hour and zone timestep; handles exist only
once the API reports data ready, and variables are requested before the run; an exception in a
callback would be swallowed by ctypes and deadlock the run, so callbacks catch everything;
callbacks stay registered in pyenergyplus's global list, so each run removes its own; the
EPW's direct solar is beam normal (global horizontal = beam x sin(altitude) + diffuse); the run
period's year is chosen so that weekdays match the weather file's; sizing is off.
"""

from __future__ import annotations

import calendar
import copy
import datetime as dt
import functools
import json
import math
import queue
import re
import shutil
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pinn_mpc.errors import InputError, InternalError

__all__ = [
    "CODE_OBJECT_PREFIXES",
    "EnergyPlusPlant",
    "EnergyPlusRun",
    "HeaterSizing",
    "IntervalMeans",
    "PreparedModel",
    "bundled_buildings",
    "bundled_weather",
    "energyplus_available",
    "extreme_window",
    "holiday_dates",
    "holidays",
    "prepare_model",
    "prepare_plant",
    "resolve_building",
    "resolve_weather",
    "schedule_gains",
    "size_heater",
    "special_day_date",
    "weather_year",
]

#: Object types that make EnergyPlus run code or talk to other programs.
CODE_OBJECT_PREFIXES = ("PythonPlugin:", "ExternalInterface")
HEATER_PREFIX = "PINN-MPC Heater"
MERGED_ZONE = "Merged Zone"
SECONDS_PER_DAY = 86400
DEFAULT_TIMEOUT_S = 300.0
#: Gain of the holding thermostat (:class:`EnergyPlusRun` ``hold_c``) per m2 of floor.
HOLD_GAIN_W_PER_K_M2 = 10.0

# Object types kept from a model: the envelope, its schedules and internal loads; nothing of
# the HVAC, plant, service water, sizing, tariffs, output requests or code.
_KEEP_EXACT = {
    "Version", "Building", "Timestep", "ShadowCalculation", "HeatBalanceAlgorithm",
    "ZoneAirHeatBalanceAlgorithm", "SurfaceConvectionAlgorithm:Inside",
    "SurfaceConvectionAlgorithm:Outside", "Site:Location", "Site:GroundReflectance",
    "RunPeriodControl:SpecialDays", "ScheduleTypeLimits", "GlobalGeometryRules", "Zone",
    "ZoneList", "BuildingSurface:Detailed", "FenestrationSurface:Detailed", "InternalMass",
    "People", "Lights", "ElectricEquipment", "GasEquipment", "HotWaterEquipment",
    "SteamEquipment", "OtherEquipment", "ZoneMixing", "ZoneCrossMixing", "Material",
    "Material:NoMass", "Material:AirGap",
}
_KEEP_PREFIX = (
    "Schedule:", "WindowMaterial:", "Construction", "Shading:", "ZoneInfiltration:",
    "Site:GroundTemperature:",
)
_ZONE_FIELDS = (
    "zone_name", "zone_or_zonelist_name", "zone_or_zonelist_or_space_or_spacelist_name",
    "zone_or_space_name",
)
_LOAD_TYPES = (
    "People", "Lights", "ElectricEquipment", "GasEquipment", "HotWaterEquipment",
    "SteamEquipment", "OtherEquipment", "ZoneInfiltration:DesignFlowRate",
)
#: Calendar years (not leap years) whose 1 January falls on each weekday, Monday first.
_YEAR_BY_WEEKDAY = {0: 2018, 1: 2019, 2: 2014, 3: 2015, 4: 2010, 5: 2011, 6: 2017}
_WEEKDAYS = ("monday", "tuesday", "wednesday", "thursday", "friday", "saturday", "sunday")
_MONTHS = {name.lower(): i for i, name in enumerate(calendar.month_name) if name} | {
    name.lower(): i for i, name in enumerate(calendar.month_abbr) if name
}
_ORDINALS = {"1st": 1, "2nd": 2, "3rd": 3, "4th": 4, "5th": 5, "last": -1}


def energyplus_available() -> bool:
    """True when the EnergyPlus engine (``pyenergyplus-lbnl``) can be imported."""
    try:
        import pyenergyplus.api  # noqa: F401
    except Exception:  # not installed, or no wheel for this platform
        return False
    return True


def _require_energyplus() -> None:
    if not energyplus_available():
        raise InputError(
            "EnergyPlus is not installed: `pip install pyenergyplus-lbnl` (a wheel exists for "
            "Linux x86_64 only)"
        )


def bundled_buildings() -> dict[str, str]:
    """DOE reference buildings shipped with pyenergyplus: name -> IDF path (empty without it)."""
    if not energyplus_available():
        return {}
    from pyenergyplus.dataset import ref_models

    return dict(ref_models)


def bundled_weather() -> dict[str, str]:
    """TMY3 EPW files shipped with pyenergyplus: name -> path (empty without it)."""
    if not energyplus_available():
        return {}
    from pyenergyplus.dataset import weather_files

    return dict(weather_files)


def resolve_weather(name_or_path: str) -> Path:
    """An EPW file: a bundled name (``usa_il_chicago``) or a path to an ``.epw`` file."""
    bundled = bundled_weather()
    if name_or_path in bundled:
        return Path(bundled[name_or_path])
    path = Path(name_or_path)
    if path.suffix.lower() != ".epw" or not path.is_file():
        names = ", ".join(sorted(bundled)) or "none: EnergyPlus is not installed"
        raise InputError(
            f"EnergyPlus weather {name_or_path!r} is neither a bundled weather file ({names}) "
            "nor an existing .epw file"
        )
    return path


def resolve_building(name_or_path: str) -> Path:
    """A building model: a bundled reference building's name (``small_office``) or a path to an
    ``.idf`` or ``.epJSON`` file."""
    bundled = bundled_buildings()
    if name_or_path in bundled:
        return Path(bundled[name_or_path])
    path = Path(name_or_path)
    if path.suffix.lower() not in (".idf", ".epjson") or not path.is_file():
        names = ", ".join(sorted(bundled)) or "none: EnergyPlus is not installed"
        raise InputError(
            f"EnergyPlus building {name_or_path!r} is neither a bundled reference building "
            f"({names}) nor an existing .idf or .epJSON file"
        )
    return path


def weather_year(epw: Path) -> int:
    """A calendar year (not a leap year) whose weekdays match the EPW's data period."""
    try:
        with open(epw, encoding="latin-1") as f:
            header = [next(f) for _ in range(8)]
    except (OSError, StopIteration):
        raise InputError(f"{epw}: not a readable EPW weather file (no 8-line header)") from None
    line = next((h for h in header if h.upper().startswith("DATA PERIODS")), "")
    fields = [s.strip().lower() for s in line.split(",")]
    weekday = next((w for w in fields if w in _WEEKDAYS), "sunday")
    return _YEAR_BY_WEEKDAY[_WEEKDAYS.index(weekday)]


# --------------------------------------------------------------------------------------------
# Model preparation
# --------------------------------------------------------------------------------------------


def _run_conversion(idf: Path, outdir: Path) -> None:
    from pyenergyplus.api import EnergyPlusAPI

    api = EnergyPlusAPI()
    state = api.state_manager.new_state()
    try:
        api.runtime.set_console_output_status(state, False)
        api.runtime.run_energyplus(state, ["--convert-only", "-d", str(outdir), str(idf)])
    finally:
        api.state_manager.delete_state(state)


@functools.lru_cache(maxsize=8)
def _load_source(path: str, mtime_ns: int) -> str:
    """The epJSON text of a model file (an IDF converted by EnergyPlus's own converter)."""
    source = Path(path)
    if source.suffix.lower() == ".epjson":
        return source.read_text(encoding="utf-8")
    with tempfile.TemporaryDirectory(prefix="pinn-mpc-eplus-convert-") as tmp:
        _run_conversion(source, Path(tmp))
        target = Path(tmp) / (source.stem + ".epJSON")
        if not target.is_file():
            first = _first_severe(Path(tmp) / "eplusout.err")
            raise InputError(
                f"EnergyPlus could not read {source}: {first or 'its IDF converter wrote no epJSON'}"
            )
        return target.read_text(encoding="utf-8")


def _read_model(path: Path) -> dict[str, Any]:
    text = _load_source(str(path), path.stat().st_mtime_ns)
    try:
        model = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid epJSON ({exc})") from None
    if not isinstance(model, dict) or not model:
        if path.suffix.lower() == ".idf":  # the converter read no objects from it
            raise InputError(f"{path}: EnergyPlus read no objects from it: not an IDF model")
        raise InputError(f"{path}: not an epJSON model (a JSON object of object types)")
    return model


def code_objects(model: dict[str, Any]) -> list[str]:
    """``Type "name"`` of every object that would run code or talk to another program."""
    found = []
    for kind, objects in model.items():
        if kind.startswith(CODE_OBJECT_PREFIXES):
            names = list(objects) if isinstance(objects, dict) else []
            found.append(f'{kind} "{names[0]}"' if names else kind)
    return found


def _vertices(surface: dict[str, Any]) -> list[tuple[float, float, float]]:
    return [
        (v["vertex_x_coordinate"], v["vertex_y_coordinate"], v["vertex_z_coordinate"])
        for v in surface["vertices"]
    ]


def _area_vector(pts: list[tuple[float, float, float]]) -> tuple[float, float, float]:
    """Newell's method: the polygon's normal times its area (outward for EnergyPlus's order)."""
    sx = sy = sz = 0.0
    for i, (x1, y1, z1) in enumerate(pts):
        x2, y2, z2 = pts[(i + 1) % len(pts)]
        sx += y1 * z2 - z1 * y2
        sy += z1 * x2 - x1 * z2
        sz += x1 * y2 - y1 * x2
    return 0.5 * sx, 0.5 * sy, 0.5 * sz


def _area(pts: list[tuple[float, float, float]]) -> float:
    return math.sqrt(sum(c * c for c in _area_vector(pts)))


def _zone_geometry(model: dict[str, Any]) -> dict[str, dict[str, float]]:
    """Floor area, volume (divergence theorem), exterior and exterior wall area per zone."""
    geo: dict[str, dict[str, float]] = {}
    for s in model.get("BuildingSurface:Detailed", {}).values():
        g = geo.setdefault(
            s["zone_name"],
            {"floor_m2": 0.0, "volume_m3": 0.0, "exterior_m2": 0.0, "exterior_wall_m2": 0.0},
        )
        pts = _vertices(s)
        av = _area_vector(pts)
        area = math.sqrt(sum(c * c for c in av))
        g["volume_m3"] += sum(a * p for a, p in zip(av, pts[0], strict=True)) / 3.0
        if s["surface_type"] == "Floor":
            g["floor_m2"] += area
        if s["outside_boundary_condition"] == "Outdoors":
            g["exterior_m2"] += area
            if s["surface_type"] == "Wall":
                g["exterior_wall_m2"] += area
    return geo


def _conditioned_zones(model: dict[str, Any]) -> list[str]:
    """Zones the model conditions (equipment connections or a thermostat), else all zones
    that count in the floor area."""
    zones = {v["zone_name"] for v in model.get("ZoneHVAC:EquipmentConnections", {}).values()}
    zones |= {v["zone_or_zonelist_name"] for v in model.get("ZoneControl:Thermostat", {}).values()}
    zones &= set(model.get("Zone", {}))
    if not zones:
        zones = {z for z, v in model.get("Zone", {}).items() if v.get("part_of_total_floor_area") != "No"}
    return sorted(zones)


def _zone_field(obj: dict[str, Any]) -> str | None:
    return next((f for f in _ZONE_FIELDS if f in obj), None)


def _absolute_loads(model: dict[str, Any], zones: list[str], geo: dict[str, dict[str, float]]) -> None:
    """Per-area, per-exterior-area and air-change loads of ``zones`` as absolute values, so
    that they keep their size when their zone is merged into a bigger one."""
    for kind in _LOAD_TYPES:
        for name, obj in model.get(kind, {}).items():
            zone = obj.get(_zone_field(obj) or "")
            if zone not in zones:
                continue
            g = geo[zone]
            if kind == "People":
                method = obj.get("number_of_people_calculation_method", "People")
                if method == "Area/Person":
                    obj["number_of_people"] = g["floor_m2"] / obj.pop("floor_area_per_person")
                elif method == "People/Area":
                    obj["number_of_people"] = g["floor_m2"] * obj.pop("people_per_floor_area")
                obj["number_of_people_calculation_method"] = "People"
            elif kind == "ZoneInfiltration:DesignFlowRate":
                method = obj.get("design_flow_rate_calculation_method", "Flow/Zone")
                per = {
                    "Flow/Area": ("flow_rate_per_floor_area", g["floor_m2"]),
                    "Flow/ExteriorArea": ("flow_rate_per_exterior_surface_area", g["exterior_m2"]),
                    "Flow/ExteriorWallArea": ("flow_rate_per_exterior_surface_area", g["exterior_wall_m2"]),
                    "AirChanges/Hour": ("air_changes_per_hour", g["volume_m3"] / 3600.0),
                }
                if method in per:
                    key, scale = per[method]
                    obj["design_flow_rate"] = obj.pop(key) * scale
                obj["design_flow_rate_calculation_method"] = "Flow/Zone"
            else:
                level = "lighting_level" if kind == "Lights" else "design_level"
                method = obj.get("design_level_calculation_method", "")
                if method == "Watts/Area":
                    obj[level] = obj.pop("watts_per_floor_area") * g["floor_m2"]
                elif method == "Power/Area":
                    obj[level] = obj.pop("power_per_floor_area") * g["floor_m2"]
                elif method in ("Watts/Person", "Power/Person"):
                    raise InputError(
                        f'{kind} "{name}" is given per person; zones with such loads cannot be '
                        "merged yet"
                    )
                obj["design_level_calculation_method"] = "LightingLevel" if kind == "Lights" else "EquipmentLevel"


def _zone_offsets(model: dict[str, Any], zones: list[str]) -> dict[str, tuple[float, float, float]]:
    """Each zone's origin in the building's coordinates, by which its surfaces' vertices move
    when it joins a zone at the building's origin: zeros when the model gives vertices in
    world coordinates. InputError for a zone rotated against the building's axes."""
    rules: dict[str, Any] = next(iter(model.get("GlobalGeometryRules", {}).values()), {})
    relative = str(rules.get("coordinate_system", "Relative")).lower() == "relative"

    def number(zone: dict[str, Any], key: str) -> float:
        value = zone.get(key, 0.0)
        return float(value) if isinstance(value, int | float) else 0.0  # "" or absent: 0

    offsets: dict[str, tuple[float, float, float]] = {}
    for z in zones:
        zone = model["Zone"][z]
        turn = number(zone, "direction_of_relative_north")
        if relative and turn % 360.0:
            raise InputError(
                f'zone "{z}" is turned {turn:g} degrees against the building\'s axes; zones = '
                "'merged' takes zones on the building's axes only: use zones = 'separate'"
            )
        offsets[z] = (
            (number(zone, "x_origin"), number(zone, "y_origin"), number(zone, "z_origin"))
            if relative else (0.0, 0.0, 0.0)
        )
    return offsets


def _to_building_coordinates(model: dict[str, Any], zones: list[str]) -> None:
    """Move the vertices of ``zones``' surfaces, windows and zone shading from each zone's own
    coordinates (relative to its origin) into the building's, so that, merged into one zone
    at the building's origin, every floor stays where it stood (floors above the ground floor
    at their height, wings beside each other)."""
    offsets = _zone_offsets(model, zones)
    surfaces = model.get("BuildingSurface:Detailed", {})
    zone_of = {name: s["zone_name"] for name, s in surfaces.items()}
    axes = ("x", "y", "z")

    def shift_list(obj: dict[str, Any], offset: tuple[float, float, float]) -> None:
        for v in obj.get("vertices", []):
            for axis, d in zip(axes, offset, strict=True):
                v[f"vertex_{axis}_coordinate"] += d

    for s in surfaces.values():
        if s["zone_name"] in offsets:
            shift_list(s, offsets[s["zone_name"]])
    for shade in model.get("Shading:Zone:Detailed", {}).values():
        zone = zone_of.get(shade.get("base_surface_name", ""))
        if zone in offsets:
            shift_list(shade, offsets[zone])
    for window in model.get("FenestrationSurface:Detailed", {}).values():
        zone = zone_of.get(window.get("building_surface_name", ""))
        if zone in offsets:
            for i in range(1, 5):
                for axis, d in zip(axes, offsets[zone], strict=True):
                    key = f"vertex_{i}_{axis}_coordinate"
                    if isinstance(window.get(key), int | float):
                        window[key] += d


def _merge_zones(model: dict[str, Any], zones: list[str], geo: dict[str, dict[str, float]]) -> int:
    """Merge ``zones`` into one at the building's origin: their geometry moves into the
    building's coordinates, partitions between them become internal mass (both faces
    exposed: twice the area of a half-thickness construction when the construction is
    symmetric), every other surface and load moves to the merged zone. Returns the number of
    partitions turned into mass."""
    _absolute_loads(model, zones, geo)
    _to_building_coordinates(model, zones)
    surfaces = model["BuildingSurface:Detailed"]
    constructions = model.get("Construction", {})
    removed: set[str] = set()
    partitions = []
    for sname, s in surfaces.items():
        other = s.get("outside_boundary_condition_object")
        if (
            s["zone_name"] in zones
            and s["outside_boundary_condition"] == "Surface"
            and other in surfaces
            and surfaces[other]["zone_name"] in zones
        ):
            if other not in removed:
                partitions.append((sname, s))
            removed |= {sname, other}
    for sname in removed:
        del surfaces[sname]
    masses = model.setdefault("InternalMass", {})
    for sname, s in partitions:
        cname = s["construction_name"]
        layers = [constructions[cname]["outside_layer"]] + [
            constructions[cname][f"layer_{i}"] for i in range(2, 11) if f"layer_{i}" in constructions[cname]
        ]
        area = _area(_vertices(s))
        if len(layers) % 2 == 0 and layers == layers[::-1]:
            half = f"{cname} half"
            constructions.setdefault(
                half,
                {"outside_layer": layers[0], **{f"layer_{i + 2}": lay for i, lay in enumerate(layers[1 : len(layers) // 2])}},
            )
            masses[f"{sname} partition"] = {
                "construction_name": half, "surface_area": 2 * area, "zone_or_zonelist_name": MERGED_ZONE,
            }
        else:  # the right mass, half the exposed area
            masses[f"{sname} partition"] = {
                "construction_name": cname, "surface_area": area, "zone_or_zonelist_name": MERGED_ZONE,
            }
    for objects in model.values():
        for obj in objects.values():
            f = _zone_field(obj) if isinstance(obj, dict) else None
            if f and obj[f] in zones:
                obj[f] = MERGED_ZONE
    first = model["Zone"][zones[0]]
    for z in zones:
        del model["Zone"][z]
    model["Zone"][MERGED_ZONE] = {
        **first, "floor_area": "Autocalculate", "part_of_total_floor_area": "Yes",
        "x_origin": 0.0, "y_origin": 0.0, "z_origin": 0.0, "direction_of_relative_north": 0.0,
    }
    return len(partitions)


@dataclass(frozen=True, kw_only=True)
class PreparedModel:
    """A building ready to run: the epJSON (its run period set per run) and what it holds.

    ``zones`` are the thermal zones heated (one, ``Merged Zone``, when merged), ``heaters``
    their heaters, ``weights`` each zone's share of the conditioned floor area (zone
    multipliers counted; they sum to 1) and ``multipliers`` the zones' multipliers: a power
    ``u`` is split as ``u * weight / multiplier`` per heater, so the building receives ``u``,
    and T_r is the floor-area-weighted mean of the zones' air temperatures."""

    model: dict[str, Any]
    source: str
    zones: tuple[str, ...]
    heaters: tuple[str, ...]
    weights: tuple[float, ...]
    multipliers: tuple[int, ...]
    floor_m2: float
    volume_m3: float
    merged_zones: tuple[str, ...]
    timesteps_per_hour: int

    @property
    def zone(self) -> str:
        """The first heated zone (the only one when merged)."""
        return self.zones[0]

    @property
    def heater(self) -> str:
        """The first zone's heater (the only one when merged)."""
        return self.heaters[0]


def prepare_model(
    building: str,
    *,
    allow_code: bool = False,
    timesteps_per_hour: int = 6,
    zones: str = "merged",
    radiant_fraction: float = 0.0,
) -> PreparedModel:
    """A building (a bundled name or an IDF/epJSON path) without its HVAC, its conditioned
    zones merged into one (``zones="merged"``) or kept (``"separate"``), an ideal electric
    heater (0 W until a run sets it; ``radiant_fraction`` of its heat radiant) in each.
    A model with code objects (:data:`CODE_OBJECT_PREFIXES`) is refused unless ``allow_code``."""
    if zones not in ("merged", "separate"):
        raise InputError(f"plant.zones = {zones!r} is not one of 'merged', 'separate'")
    if isinstance(radiant_fraction, bool) or not 0.0 <= radiant_fraction <= 1.0:
        raise InputError(f"plant.radiant_fraction = {radiant_fraction!r} must lie in [0, 1]")
    _require_energyplus()
    path = resolve_building(building)
    src = _read_model(path)
    found = code_objects(src)
    if found and not allow_code:
        raise InputError(
            f"{path} declares {found[0]}: running it would run code from the model; "
            "set allow_code = true in [simulation.plant] if you trust it"
        )
    conditioned = _conditioned_zones(src)
    if not conditioned:
        raise InputError(f"{path}: the model has no zones with floor area to heat")
    geo = _zone_geometry(src)
    if any(z not in geo for z in conditioned):
        raise InputError(f"{path}: zone(s) {[z for z in conditioned if z not in geo]} have no surfaces")
    model = {
        k: copy.deepcopy(v)
        for k, v in src.items()
        if k in _KEEP_EXACT or k.startswith(_KEEP_PREFIX) or (allow_code and k.startswith(CODE_OBJECT_PREFIXES))
    }
    model["SimulationControl"] = {
        "SimulationControl 1": {
            "do_zone_sizing_calculation": "No",
            "do_system_sizing_calculation": "No",
            "do_plant_sizing_calculation": "No",
            "run_simulation_for_sizing_periods": "No",
            "run_simulation_for_weather_file_run_periods": "Yes",
            "do_hvac_sizing_simulation_for_sizing_periods": "No",
        }
    }
    model["Timestep"] = {"Timestep 1": {"number_of_timesteps_per_hour": timesteps_per_hour}}
    if zones == "merged":
        _merge_zones(model, conditioned, geo)
        heated, weights, multipliers = [MERGED_ZONE], [1.0], [1]
    else:
        heated = conditioned
        multipliers = [int(model["Zone"][z].get("multiplier", 1)) for z in heated]
        areas = [geo[z]["floor_m2"] * m for z, m in zip(heated, multipliers, strict=True)]
        weights = [a / sum(areas) for a in areas] if len(heated) > 1 else [1.0]
    model.setdefault("Schedule:Constant", {})["PINN-MPC Always On"] = {"hourly_value": 1.0}
    heaters = [f"{HEATER_PREFIX} {z}" for z in heated]
    for zone, heater in zip(heated, heaters, strict=True):
        model.setdefault("OtherEquipment", {})[heater] = {
            "fuel_type": "Electricity",
            "zone_or_zonelist_or_space_or_spacelist_name": zone,
            "schedule_name": "PINN-MPC Always On",
            "design_level_calculation_method": "EquipmentLevel",
            "design_level": 0.0,
            "fraction_latent": 0.0,
            "fraction_radiant": float(radiant_fraction),
            "fraction_lost": 0.0,
            "end_use_subcategory": "PINN-MPC Heater",
        }
    return PreparedModel(
        model=model,
        source=str(path),
        zones=tuple(heated),
        heaters=tuple(heaters),
        weights=tuple(weights),
        multipliers=tuple(multipliers),
        floor_m2=sum(geo[z]["floor_m2"] for z in conditioned),
        volume_m3=sum(geo[z]["volume_m3"] for z in conditioned),
        merged_zones=tuple(conditioned) if zones == "merged" else (),
        timesteps_per_hour=timesteps_per_hour,
    )


def prepare_plant(plant: Any) -> PreparedModel:
    """:func:`prepare_model` of a scenario's EnergyPlus :class:`~pinn_mpc.plant.Plant`."""
    return prepare_model(
        plant.building, allow_code=plant.allow_code, zones=plant.zones,
        radiant_fraction=plant.radiant_fraction,
    )


# --------------------------------------------------------------------------------------------
# A run: EnergyPlus in a thread, stepped every control interval through two queues
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class IntervalMeans:
    """One control interval of a run: the room at its end and the means over it."""

    t_r_c: float  # zone air temperature at the end of the interval [C]
    t_r_sub_c: np.ndarray  # (S,) zone air temperature at the end of each zone timestep [C]
    u_phys_w: float  # the heater's mean heating rate as EnergyPlus reports it [W]
    t_a_c: float  # outdoor dry-bulb [C]
    g_w_per_m2: float  # global horizontal irradiance [W/m2]
    i_g_w: float  # the building's own sensible internal gains (the heater's excluded) [W]
    overridden: bool  # the backup thermostat changed the power in some zone timestep


_STOP = object()


def _first_severe(err_file: Path) -> str | None:
    """EnergyPlus's first severe (or fatal) message with its continuation lines, one line."""
    try:
        lines = err_file.read_text(errors="replace").splitlines()
    except OSError:
        return None
    for i, line in enumerate(lines):
        if "** Severe  **" in line or "**  Fatal  **" in line:
            parts = [line.split("**", 2)[-1].strip()]
            for more in lines[i + 1 :]:
                if "**   ~~~   **" not in more:
                    break
                parts.append(more.split("**", 2)[-1].strip())
            return re.sub(r"\s+", " ", " ".join(parts))
    return None


class EnergyPlusRun:
    """One EnergyPlus simulation of a :class:`PreparedModel`, stepped one interval at a time.

    :meth:`start` begins a run at 00:00 of ``start_day`` (day of the year, 1 = 1 January) for
    ``days`` days (at most a year, into the next year too: the weather file's typical year
    repeats); EnergyPlus's warm-up days hold the room near ``warmup_setpoint_c`` and the
    call returns the room temperature then. :meth:`step` holds a heater power for one control
    interval (``dt_s``) and returns its :class:`IntervalMeans`. A backup thermostat (full power
    below ``backup_c[0]``, none above ``backup_c[1]``; mirrored for a chiller) acts per zone
    timestep. ``heat_per_w`` is the heat per watt of power (1: the ideal electric heater;
    minus a COP: an ideal chiller, whose equipment extracts heat, a negative
    ``OtherEquipment`` power); the reported power is the heat delivered divided by it. With
    ``hold_c`` set, the power asked is ignored and an ideal thermostat (integral control per
    zone timestep, as in the warm-up) holds T_r at ``hold_c``: :func:`size_heater` measures
    the power that takes. Use it as a context manager, or call :meth:`close`.
    """

    def __init__(
        self,
        prepared: PreparedModel,
        *,
        weather: str,
        u_max_w: float,
        dt_s: float = 1800.0,
        backup_c: tuple[float, float] | None = None,
        warmup_setpoint_c: float = 20.5,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        heat_per_w: float = 1.0,
        hold_c: float | None = None,
    ) -> None:
        _require_energyplus()
        if not (math.isfinite(heat_per_w) and heat_per_w != 0):
            raise InputError(f"EnergyPlusRun: heat_per_w must be a nonzero number, got {heat_per_w!r}")
        self.prepared = prepared
        self.heat_per_w = float(heat_per_w)
        self.hold_c = hold_c
        #: The holding thermostat's gain: W per K of error per zone timestep (per m2 of floor).
        self.hold_gain_w_per_k = HOLD_GAIN_W_PER_K_M2 * prepared.floor_m2 / abs(self.heat_per_w)
        self.epw = resolve_weather(weather)
        self.year = weather_year(self.epw)
        self.u_max_w, self.dt_s = float(u_max_w), int(dt_s)
        step_s = 3600 // prepared.timesteps_per_hour
        if self.dt_s % step_s or SECONDS_PER_DAY % self.dt_s:
            raise InputError(
                f"EnergyPlus: the control interval {dt_s:g} s must be a whole number of its "
                f"{step_s} s timesteps and divide the day"
            )
        self.backup_c = backup_c
        self.warmup_setpoint_c = warmup_setpoint_c
        self.timeout_s = timeout_s
        self._thread: threading.Thread | None = None
        self._state: Any = None
        self._callbacks: list[Any] = []
        self._tmp: Path | None = None
        self._done = True
        self._start_day = 1

    # ---- the caller's side --------------------------------------------------------------

    def start(self, start_day: int, days: int, *, year: int | None = None) -> float:
        """Start a fresh run (closing one in progress); the room temperature at its start.

        ``year`` (a non-leap year, and so the next one when the run crosses 31 December) sets
        the calendar, so the building's weekday schedules follow the caller's dates; by default
        the year whose weekdays match the weather file.
        """
        from pyenergyplus import runtime as ep_runtime
        from pyenergyplus.api import EnergyPlusAPI

        self.close()
        if not (1 <= start_day <= 365 and 1 <= days <= 365):
            raise InputError(
                f"EnergyPlus runs at most a year from a day of the year: {days} day(s) from day "
                f"{start_day}; use 1 .. 365 of each"
            )
        run_year = self.year if year is None else int(year)
        crosses = start_day + days - 1 > 365
        for y in (run_year, run_year + 1) if crosses else (run_year,):
            if calendar.isleap(y):
                raise InputError(
                    f"EnergyPlus runs on a typical (365-day) weather year, so a run cannot be "
                    f"dated in the leap year {y}; date the series in non-leap years"
                )
        begin = dt.date(run_year, 1, 1) + dt.timedelta(days=start_day - 1)
        end = begin + dt.timedelta(days=days - 1)
        self._start_day = start_day
        model = copy.deepcopy(self.prepared.model)
        model["RunPeriod"] = {
            "PINN-MPC Run": {
                "begin_month": begin.month, "begin_day_of_month": begin.day, "begin_year": run_year,
                "end_month": end.month, "end_day_of_month": end.day, "end_year": end.year,
                "use_weather_file_holidays_and_special_days": "No",
                "use_weather_file_daylight_saving_period": "No",
                "apply_weekend_holiday_rule": "No",
                "use_weather_file_rain_indicators": "Yes",
                "use_weather_file_snow_indicators": "Yes",
            }
        }
        self._tmp = Path(tempfile.mkdtemp(prefix="pinn-mpc-eplus-"))
        path = self._tmp / "model.epJSON"
        path.write_text(json.dumps(model), encoding="utf-8")
        self._end_s = (start_day + days - 1) * SECONDS_PER_DAY
        self.api = api = EnergyPlusAPI()
        self._state = state = api.state_manager.new_state()
        api.runtime.set_console_output_status(state, False)
        self._handles: dict[str, Any] | None = None
        self._u = 0.0
        self._last_t_r: float | None = None
        self._acc = self._new_acc()
        self._stopping = False
        self._done = False
        self._error: BaseException | None = None
        self._act_q: queue.Queue[Any] = queue.Queue(maxsize=1)
        self._obs_q: queue.Queue[tuple[str, Any]] = queue.Queue()
        for name, key in self._variables():
            api.exchange.request_variable(state, name, key)
        n_before = len(ep_runtime.all_callbacks)
        api.runtime.callback_begin_zone_timestep_after_init_heat_balance(state, self._on_begin)
        api.runtime.callback_end_zone_timestep_after_zone_reporting(state, self._on_end)
        self._callbacks = ep_runtime.all_callbacks[n_before:]
        args = ["-d", str(self._tmp), "-w", str(self.epw), str(path)]
        self._thread = threading.Thread(target=self._run, args=(args,), name="energyplus", daemon=True)
        self._thread.start()
        first = self._receive_or_close()
        assert isinstance(first, float)
        return first

    def step(self, u_w: float) -> IntervalMeans:
        """Hold heater power ``u_w`` [W] (clipped to 0 .. u_max_w) for one control interval."""
        if self._done or self._thread is None:
            raise InternalError("EnergyPlusRun.step: no run in progress (start one, or the run has ended)")
        self._act_q.put(min(max(float(u_w), 0.0), self.u_max_w), timeout=self.timeout_s)
        result = self._receive_or_close()
        assert isinstance(result, IntervalMeans)
        return result

    @property
    def running(self) -> bool:
        return self._thread is not None

    def close(self) -> None:
        """Stop a run in progress (EnergyPlus stops at its next zone timestep), wait for its
        thread, free its state and remove its temporary directory."""
        thread, self._thread = self._thread, None
        try:
            if thread is not None:
                if thread.is_alive():
                    self._stopping = True
                    try:
                        self._act_q.put_nowait(_STOP)
                    except queue.Full:
                        pass
                thread.join(timeout=self.timeout_s)
                if thread.is_alive():
                    raise RuntimeError(f"EnergyPlus did not stop within {self.timeout_s:g} s")
        finally:
            self._done = True
            if self._state is not None and (thread is None or not thread.is_alive()):
                from pyenergyplus import runtime as ep_runtime

                self.api.state_manager.delete_state(self._state)
                self._state = None
                for cb in self._callbacks:
                    if cb in ep_runtime.all_callbacks:
                        ep_runtime.all_callbacks.remove(cb)
                self._callbacks = []
            if self._tmp is not None:
                shutil.rmtree(self._tmp, ignore_errors=True)
                self._tmp = None

    def __enter__(self) -> EnergyPlusRun:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _receive_or_close(self) -> float | IntervalMeans:
        """:meth:`_receive`; on any error or interrupt the run is closed first."""
        try:
            return self._receive()
        except BaseException:
            self.close()
            raise

    def _receive(self) -> float | IntervalMeans:
        try:
            kind, payload = self._obs_q.get(timeout=self.timeout_s)
        except queue.Empty:
            raise RuntimeError(
                f"EnergyPlus sent nothing for {self.timeout_s:g} s; the run was stopped"
            ) from None
        if kind == "error":
            self._done = True
            raise payload
        if kind == "done":
            self._done = True
            raise InternalError("EnergyPlusRun.step: the run has ended (start a longer one)")
        return payload

    # ---- the EnergyPlus thread ----------------------------------------------------------

    _GAIN_VARIABLES = (
        "Zone Total Internal Convective Heating Rate",
        "Zone Total Internal Radiant Heating Rate",
        "Zone Total Internal Visible Radiation Heating Rate",
    )

    def _variables(self) -> list[tuple[str, str]]:
        env = "Environment"
        variables = [
            ("Site Outdoor Air Drybulb Temperature", env),
            ("Site Direct Solar Radiation Rate per Area", env),
            ("Site Diffuse Solar Radiation Rate per Area", env),
            ("Site Solar Altitude Angle", env),
        ]
        for zone, heater in zip(self.prepared.zones, self.prepared.heaters, strict=True):
            variables += [("Zone Mean Air Temperature", zone)]
            variables += [(name, zone) for name in self._GAIN_VARIABLES]
            variables += [("Other Equipment Total Heating Rate", heater)]
        return variables

    def _run(self, args: list[str]) -> None:
        rc: int | None = None
        try:
            rc = self.api.runtime.run_energyplus(self._state, args)
        except BaseException as exc:  # reported to the caller
            self._error = self._error or exc
        if self._stopping and self._error is None:
            return
        if self._error is not None:
            self._obs_q.put(("error", self._error))
        elif rc != 0 or self._handles is None:
            first = _first_severe(Path(args[1]) / "eplusout.err")
            self._obs_q.put((
                "error",
                InputError(
                    f"EnergyPlus could not run {self.prepared.source}: "
                    f"{first or f'it returned {rc} without a severe message'}"
                ),
            ))
        else:
            self._obs_q.put(("done", None))

    def _get_handles(self, state: Any) -> dict[str, Any]:
        ex = self.api.exchange
        var = {(n, k): ex.get_variable_handle(state, n, k) for n, k in self._variables()}
        act = [ex.get_actuator_handle(state, "OtherEquipment", "Power Level", h) for h in self.prepared.heaters]
        missing = [f"{n} of {k}" for (n, k), v in var.items() if v < 0]
        missing += [f"actuator of {h}" for h, a in zip(self.prepared.heaters, act, strict=True) if a < 0]
        if missing:
            raise RuntimeError(f"EnergyPlus has no handle for {missing}")
        return {"var": var, "act": act}

    def _read(self, state: Any) -> dict[str, float]:
        assert self._handles is not None
        ex, var, prepared = self.api.exchange, self._handles["var"], self.prepared

        def g(name: str, key: str = "Environment") -> float:
            return float(ex.get_variable_value(state, var[(name, key)]))

        alt = g("Site Solar Altitude Angle")
        ghi = g("Site Direct Solar Radiation Rate per Area") * max(0.0, math.sin(math.radians(alt))) + g(
            "Site Diffuse Solar Radiation Rate per Area"
        )
        # Per zone instance; a zone multiplier repeats both the heat and the gains.
        mult = prepared.multipliers
        heat = sum(m * g("Other Equipment Total Heating Rate", h) for h, m in zip(prepared.heaters, mult, strict=True))
        gains = sum(
            m * sum(g(n, zone) for n in self._GAIN_VARIABLES) for zone, m in zip(prepared.zones, mult, strict=True)
        )
        t_r = sum(w * g("Zone Mean Air Temperature", z) for z, w in zip(prepared.zones, prepared.weights, strict=True))
        return {
            "T_r": t_r,
            "T_a": g("Site Outdoor Air Drybulb Temperature"),
            "G": ghi,
            "u_phys": heat / self.heat_per_w,
            "I_g": gains - heat,
        }

    def _seconds(self, state: Any) -> int:
        """Seconds from 1 January 00:00 of the run's first year to the start of this zone
        timestep (from the day, the hour and the zone timestep's number, not the system
        timestep's clock; a day of the year before the run's first is in the next year)."""
        ex = self.api.exchange
        step_s = 3600 // self.prepared.timesteps_per_hour
        n = ex.zone_time_step_number(state) - 1
        day = ex.day_of_year(state)
        if day < self._start_day:
            day += 365
        return int((day - 1) * SECONDS_PER_DAY + ex.hour(state) * 3600 + n * step_s)

    @staticmethod
    def _new_acc() -> dict[str, Any]:
        return {"n": 0, "T_a": 0.0, "G": 0.0, "u_phys": 0.0, "I_g": 0.0, "T_r": [], "overridden": False}

    def _means(self) -> IntervalMeans:
        acc, n = self._acc, max(self._acc["n"], 1)
        self._acc = self._new_acc()
        return IntervalMeans(
            t_r_c=float(acc["T_r"][-1]),
            t_r_sub_c=np.asarray(acc["T_r"], dtype=float),
            u_phys_w=acc["u_phys"] / n,
            t_a_c=acc["T_a"] / n,
            g_w_per_m2=acc["G"] / n,
            i_g_w=acc["I_g"] / n,
            overridden=bool(acc["overridden"]),
        )

    def _set_heater(self, state: Any, u: float) -> None:
        """Power ``u`` [W] to the building: its heat split over the zones by floor area."""
        assert self._handles is not None
        prepared, heat = self.prepared, u * self.heat_per_w
        for act, w, m in zip(self._handles["act"], prepared.weights, prepared.multipliers, strict=True):
            self.api.exchange.set_actuator_value(state, act, heat * w / m)

    def _integral_control(self, setpoint_c: float, gain_w_per_k: float) -> None:
        """The warm-up's thermostat: the power moves by ``gain_w_per_k`` per K of error per
        zone timestep (towards more power below the setpoint for a heater, above for a chiller)."""
        if self._last_t_r is not None:
            error = setpoint_c - self._last_t_r if self.heat_per_w > 0 else self._last_t_r - setpoint_c
            u = self._u + gain_w_per_k * error
            self._u = min(max(u, 0.0), self.u_max_w)

    def _on_begin(self, state: Any) -> None:
        """Begin of a zone timestep: set the heater; at an interval boundary hand over and
        wait for the next power."""
        try:
            if self._stopping or self._error is not None:
                return
            ex = self.api.exchange
            if self._handles is None:
                if not ex.api_data_fully_ready(state):
                    return
                self._handles = self._get_handles(state)
            if ex.warmup_flag(state):  # integral control to the warm-up setpoint
                gain = 0.1 * self.u_max_w if self.hold_c is None else self.hold_gain_w_per_k
                self._integral_control(self.warmup_setpoint_c, gain)
                self._set_heater(state, self._u)
                return
            if self._seconds(state) % self.dt_s == 0:
                if self._last_t_r is None:
                    self._last_t_r = self._read(state)["T_r"]
                first = float(self._last_t_r)
                self._obs_q.put(("obs", first if self._acc["n"] == 0 else self._means()))
                try:
                    msg = self._act_q.get(timeout=self.timeout_s)
                except queue.Empty:
                    msg = _STOP
                if msg is _STOP:
                    self._stopping = True
                    self._set_heater(state, 0.0)
                    self.api.runtime.stop_simulation(state)
                    return
                if self.hold_c is None:
                    self._u = float(msg)
            if self.hold_c is not None:
                self._integral_control(self.hold_c, self.hold_gain_w_per_k)
            u = self._u
            if self.backup_c is not None and self._last_t_r is not None:
                low, high = self.backup_c
                force_on, force_off = (
                    (self._last_t_r < low, self._last_t_r > high)
                    if self.heat_per_w > 0
                    else (self._last_t_r > high, self._last_t_r < low)
                )
                if force_on:
                    u = self.u_max_w
                elif force_off:
                    u = 0.0
                if u != self._u:
                    self._acc["overridden"] = True
            self._set_heater(state, u)
        except BaseException as exc:  # a callback must not raise into EnergyPlus
            self._fail(state, exc)

    def _on_end(self, state: Any) -> None:
        """End of a zone timestep: read the zone and the weather, add them to the interval."""
        try:
            if self._handles is None or self._stopping or self._error is not None:
                return
            r = self._read(state)
            self._last_t_r = r["T_r"]
            if self.api.exchange.warmup_flag(state):
                return
            acc = self._acc
            acc["n"] += 1
            for key in ("T_a", "G", "u_phys", "I_g"):
                acc[key] += r[key]
            acc["T_r"].append(r["T_r"])
            if self._seconds(state) + 3600 // self.prepared.timesteps_per_hour >= self._end_s:
                self._obs_q.put(("obs", self._means()))
        except BaseException as exc:  # a callback must not raise into EnergyPlus
            self._fail(state, exc)

    def _fail(self, state: Any, exc: BaseException) -> None:
        self._error = exc
        self._stopping = True
        self.api.runtime.stop_simulation(state)
        self._obs_q.put(("error", exc))


class EnergyPlusPlant:
    """An EnergyPlus building as the closed loop's plant (:class:`scenarios.engine.LoopPlant`).

    ``config.plant`` names the building and the weather (kind ``energyplus``, see
    :class:`pinn_mpc.plant.Plant`); ``times`` (N,) are the interval starts of the loop's series,
    whose day of the year places each run in the weather file. :meth:`reset` starts a fresh
    EnergyPlus run at the start row's midnight through the series' last day, warmed up at the
    given room temperature; the backup thermostat of ``config`` acts per EnergyPlus timestep;
    the sensor noise of ``config`` is added to every measurement. It has no true mass
    temperature (``hidden_t_m`` is NaN).
    """

    has_true_state = False
    n_buildings = 1

    def __init__(self, config: Any, times: np.ndarray, *, seed: int | None = 0) -> None:
        plant = config.plant
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
        self.config = config
        self.times = np.asarray(times, dtype="datetime64[s]")
        self.prepared = prepare_plant(plant)
        self.run = EnergyPlusRun(
            self.prepared,
            weather=plant.weather,
            u_max_w=config.u_max_w,
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
            raise InputError(f"an EnergyPlus run starts at midnight, not at {first}")
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
        return t_r

    def hidden_t_m(self) -> np.ndarray:
        return np.array([math.nan])

    def step(self, u_w: float | np.ndarray, row: int) -> Any:
        """One interval at row ``row`` (the next of the run): a :class:`~pinn_mpc.simulator.PlantStep`."""
        from pinn_mpc.simulator import PlantStep, StepResult

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
        return PlantStep(result, np.array([m.t_a_c]), np.array([m.g_w_per_m2]), np.array([m.i_g_w]))

    def close(self) -> None:
        self.run.close()


# --------------------------------------------------------------------------------------------
# Heater sizing
# --------------------------------------------------------------------------------------------


def _daily_mean_dry_bulb(epw: Path) -> np.ndarray:
    """(365,) the EPW's daily mean dry-bulb temperature [C] (column 7 of its hourly rows)."""
    import pvlib

    try:
        dry_bulb = pvlib.iotools.read_epw(epw)[0]["temp_air"].to_numpy(dtype=float)
    except Exception:  # pvlib raises many kinds on a malformed file; one line for the user
        raise InputError(f"{epw}: not a readable EPW weather file (no dry-bulb column)") from None
    if len(dry_bulb) < 365 * 24:
        raise InputError(f"{epw}: {len(dry_bulb)} hourly rows; sizing needs a whole year (8760)")
    return dry_bulb[: 365 * 24].reshape(365, 24).mean(axis=1)


def extreme_window(epw: Path, days: int = 3, *, hottest: bool = False) -> int:
    """The first day of the year (1 = 1 January) of the coldest (``hottest``: the hottest)
    ``days`` consecutive days of the weather file, by their daily mean dry-bulb."""
    daily = _daily_mean_dry_bulb(epw)
    window = np.convolve(daily, np.ones(days) / days, mode="valid")
    return int(np.argmax(window) if hottest else np.argmin(window)) + 1


@dataclass(frozen=True)
class HeaterSizing:
    """What :func:`size_heater` found: the power, the peak it came from and where."""

    power_w: float  # the heater's (chiller's) power: peak x margin, rounded up to 1 kW
    peak_w: float  # the largest interval mean power the ideal thermostat needed
    setpoint_c: float  # the temperature held
    start_day: int  # first day of the year of the window
    days: int
    margin: float
    epw: str
    cooling: bool = False

    def line(self) -> str:
        """One line for the run's log."""
        first = dt.date(2001, 1, 1) + dt.timedelta(days=self.start_day - 1)
        last = first + dt.timedelta(days=self.days - 1)
        kind, extreme = ("chiller", "hottest") if self.cooling else ("heater", "coldest")
        return (
            f"plant.heater_w = \"auto\": {kind} sized {self.power_w / 1000:g} kW (peak "
            f"{self.peak_w / 1000:.1f} kW x {self.margin:g} to hold {self.setpoint_c:g} C on the "
            f"{extreme} {self.days} days of {Path(self.epw).name}, {first:%d %b}-{last:%d %b})"
        )


def _unlimited_power_w(prepared: PreparedModel, heat_per_w: float) -> float:
    """A power no building of this floor area needs (1 kW/m2 of heat): a thermostat with it
    holds its setpoint unconstrained."""
    return 1000.0 * prepared.floor_m2 / abs(heat_per_w)


def _held_run(
    prepared: PreparedModel, weather: str, setpoint_c: float, heat_per_w: float, dt_s: float,
    start_day: int, days: int, year: int | None,
) -> list[IntervalMeans]:
    """Every interval of a run whose room an ideal thermostat holds at ``setpoint_c``."""
    with EnergyPlusRun(
        prepared, weather=weather, u_max_w=_unlimited_power_w(prepared, heat_per_w), dt_s=dt_s,
        heat_per_w=heat_per_w, warmup_setpoint_c=setpoint_c, hold_c=setpoint_c,
    ) as run:
        run.start(start_day, days, year=year)
        return [run.step(0.0) for _ in range(days * SECONDS_PER_DAY // int(dt_s))]


def _plant_key(plant: Any) -> tuple[str, bool, str, float]:
    return (plant.building, bool(plant.allow_code), plant.zones, float(plant.radiant_fraction))


def _prepared(key: tuple[str, bool, str, float]) -> PreparedModel:
    """:func:`prepare_model` of a :func:`_plant_key` (the cached runs' hashable argument)."""
    building, allow_code, zones, radiant = key
    return prepare_model(building, allow_code=allow_code, zones=zones, radiant_fraction=radiant)


@functools.lru_cache(maxsize=16)
def _size_heater_cached(
    prepared_key: tuple[str, bool, str, float], weather: str, setpoint_c: float, heat_per_w: float,
    margin: float, days: int, dt_s: float,
) -> HeaterSizing:
    prepared = _prepared(prepared_key)
    epw = resolve_weather(weather)
    cooling = heat_per_w < 0
    start_day = extreme_window(epw, days, hottest=cooling)
    big_w = _unlimited_power_w(prepared, heat_per_w)
    means = _held_run(prepared, weather, setpoint_c, heat_per_w, dt_s, start_day, days, None)
    peak = max(m.u_phys_w for m in means)
    if peak >= 0.99 * big_w:
        raise InputError(
            f"sizing the {'chiller' if cooling else 'heater'} of {prepared.source}: even "
            f"{big_w / 1000:g} kW did not hold {setpoint_c:g} C; give heater_w"
        )
    power = math.ceil(peak * margin / 1000.0) * 1000.0
    return HeaterSizing(
        power_w=power, peak_w=peak, setpoint_c=setpoint_c, start_day=start_day, days=days,
        margin=margin, epw=str(epw), cooling=cooling,
    )


def size_heater(
    plant: Any,
    setpoint_c: float,
    *,
    heat_per_w: float = 1.0,
    margin: float = 1.2,
    days: int = 3,
    dt_s: float = 1800.0,
) -> HeaterSizing:
    """The heater an EnergyPlus :class:`~pinn_mpc.plant.Plant` needs to hold ``setpoint_c``
    (the comfort band's lower bound) through the weather file's coldest ``days`` days.

    The building (as the plant prepares it: zones, radiant fraction) runs on the coldest
    window of its EPW (:func:`extreme_window`, by daily mean dry-bulb), warmed up at the
    setpoint, under an ideal thermostat (integral control per zone timestep) with a heater
    no building needs (1 kW per m2 of floor); the largest interval mean power it used, times
    ``margin``, rounded up to a whole kW, is the heater. For a chiller (``heat_per_w < 0``) the
    same on the hottest days, ``setpoint_c`` the band's upper bound, in electrical power.
    Computed once per process for the same inputs; nothing is written to disk.
    """
    if not (math.isfinite(margin) and margin >= 1.0):
        raise InputError(f"size_heater: margin must be >= 1, got {margin!r}")
    return _size_heater_cached(_plant_key(plant), plant.weather, float(setpoint_c), float(heat_per_w), margin, days, dt_s)


def special_day_date(text: str, year: int) -> dt.date:
    """The date in ``year`` of a ``RunPeriodControl:SpecialDays`` start date, in any form
    EnergyPlus reads: ``1/15`` (month/day), ``January 15`` or ``15 January``, ``3rd Monday in
    January``, ``Last Monday in May``. InputError on anything else."""
    words = str(text).strip().lower().replace(",", " ").split()
    try:
        if len(words) == 1 and "/" in words[0]:
            month, day = (int(x) for x in words[0].split("/"))
            return dt.date(year, month, day)
        if len(words) == 2:
            month_word, day_word = words if words[0] in _MONTHS else words[::-1]
            return dt.date(year, _MONTHS[month_word], int(day_word))
        if len(words) == 4 and words[2] == "in":
            nth, weekday, month = _ORDINALS[words[0]], _WEEKDAYS.index(words[1]), _MONTHS[words[3]]
            days = [
                d for d in range(1, calendar.monthrange(year, month)[1] + 1)
                if dt.date(year, month, d).weekday() == weekday
            ]
            return dt.date(year, month, days[nth if nth < 0 else nth - 1])
    except (KeyError, ValueError, IndexError):
        pass
    raise InputError(
        f"RunPeriodControl:SpecialDays start date {text!r} is not a date EnergyPlus reads "
        "(e.g. 1/15, January 15, 3rd Monday in January, Last Monday in May)"
    )


def holiday_dates(model: dict[str, Any], year: int) -> frozenset[dt.date]:
    """The days of ``year`` on which the building (an epJSON model) runs its holiday schedules:
    its ``RunPeriodControl:SpecialDays`` of type Holiday, each for its duration."""
    out: set[dt.date] = set()
    for obj in model.get("RunPeriodControl:SpecialDays", {}).values():
        if str(obj.get("special_day_type", "Holiday")).lower() != "holiday":
            continue
        first = special_day_date(obj.get("start_date", ""), year)
        out.update(first + dt.timedelta(days=i) for i in range(int(obj.get("duration", 1))))
    return frozenset(d for d in out if d.year == year)


@functools.lru_cache(maxsize=16)
def _holiday_dates_cached(prepared_key: tuple[str, bool, str, float], year: int) -> frozenset[dt.date]:
    return holiday_dates(_prepared(prepared_key).model, year)


def holidays(plant: Any, times: np.ndarray) -> np.ndarray:
    """(N,) 1.0 where the interval starting at ``times`` falls on one of the building's
    holidays (:func:`holiday_dates`: the days it runs its Sunday-or-holiday schedules), else 0.0.
    A building's holiday calendar is known in advance, like its gains schedules."""
    days = np.asarray(times, dtype="datetime64[D]")
    years = days.astype("datetime64[Y]").astype(int) + 1970
    found: set[np.datetime64] = set()
    for year in np.unique(years):
        found.update(np.datetime64(d, "D") for d in _holiday_dates_cached(_plant_key(plant), int(year)))
    return np.isin(days, np.array(sorted(found), dtype="datetime64[D]")).astype(float)


@functools.lru_cache(maxsize=16)
def _schedule_gains_cached(
    prepared_key: tuple[str, bool, str, float], weather: str, setpoint_c: float, heat_per_w: float,
    dt_s: float, start_day: int, days: int, year: int,
) -> np.ndarray:
    prepared = _prepared(prepared_key)
    means = _held_run(prepared, weather, setpoint_c, heat_per_w, dt_s, start_day, days, year)
    gains = np.array([m.i_g_w for m in means])
    gains.flags.writeable = False
    return gains


def schedule_gains(
    plant: Any, times: np.ndarray, *, setpoint_c: float, dt_s: float, heat_per_w: float = 1.0
) -> np.ndarray:
    """(N,) the internal gains [W] (the heater's excluded) the building's own schedules
    deliver in the intervals starting at ``times``, as interval means.

    A building's gains schedules (occupancy, lighting, equipment) are known in advance; the
    gains that happen are not quite them (EnergyPlus's people give off less sensible heat in
    a warmer room). So these come from a run of their own over the same dates with the room
    held at ``setpoint_c`` by an ideal thermostat: what the schedules give at that
    temperature, known before the plant runs. Computed once per process for the same inputs.
    """
    times = np.asarray(times, dtype="datetime64[s]")
    days = times.astype("datetime64[D]")
    year = int(days[0].astype("datetime64[Y]").astype(int)) + 1970
    start_day = int((days[0] - days[0].astype("datetime64[Y]")).astype(int)) + 1
    n_days = int((days[-1] - days[0]).astype(int)) + 1
    gains = _schedule_gains_cached(
        _plant_key(plant), plant.weather, float(setpoint_c), float(heat_per_w), float(dt_s),
        start_day, n_days, year,
    )
    rows = ((times - days[0].astype("datetime64[s]")).astype(int) // int(dt_s)).astype(int)
    return np.array(gains[rows])
