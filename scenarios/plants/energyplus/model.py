"""A building model prepared as the plant: a bundled reference building or a user's IDF/epJSON.

:func:`prepare_model` keeps the envelope, its schedules and internal loads, and drops
everything else (HVAC, plant, service water, sizing, output requests, and any code the model
would run); the conditioned zones are merged into one thermal zone (partitions between them
become internal mass, per-area loads absolute) or kept; one ideal electric heater (an
``OtherEquipment`` object) heats each, and where the zones are kept to be controlled each
(``zones = "controlled"``) one ideal chiller (another, of negative power) cools each too. A
model declaring ``PythonPlugin:*`` or
``ExternalInterface:*`` objects is refused unless ``allow_code``; then those objects are kept.
Sizing is off.
"""

from __future__ import annotations

import copy
import functools
import json
import math
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pinn_mpc.errors import InputError
from pinn_mpc.solar import FACADE_AZIMUTHS_DEG
from scenarios.plants.energyplus.files import first_severe, require_energyplus, resolve_building
from scenarios.plants.energyplus.settings import ZONE_LAYOUTS, EnergyPlusSettings

__all__ = [
    "CHILLER_PREFIX",
    "CODE_OBJECT_PREFIXES",
    "HEATER_PREFIX",
    "MERGED_ZONE",
    "PlantKey",
    "PreparedModel",
    "code_objects",
    "plant_key",
    "prepare_model",
    "prepare_plant",
    "prepared_from_key",
    "zone_adjacency",
    "window_facade",
    "zone_window_facades",
    "zone_layout",
    "zone_names",
]

#: Object types that make EnergyPlus run code or talk to other programs.
CODE_OBJECT_PREFIXES = ("PythonPlugin:", "ExternalInterface")
HEATER_PREFIX = "PINN-MPC Heater"
CHILLER_PREFIX = "PINN-MPC Chiller"
MERGED_ZONE = "Merged Zone"

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
    "Material:NoMass", "Material:AirGap", "WindowProperty:FrameAndDivider",
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
            first = first_severe(Path(tmp) / "eplusout.err")
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
                # The per-area value's key is the kind's (Lights and ElectricEquipment:
                # watts_per_floor_area; gas, hot water, steam: power_per_floor_area),
                # whichever name the method has.
                per_area = [k for k in ("watts_per_floor_area", "power_per_floor_area") if k in obj]
                if method in ("Watts/Area", "Power/Area") and per_area:
                    obj[level] = obj.pop(per_area[0]) * g["floor_m2"]
                elif method in ("Watts/Area", "Power/Area"):
                    raise InputError(
                        f'{kind} "{name}" is given per floor area ({method}) without a value; give '
                        'it one, or set [simulation.plant] zones = "separate"'
                    )
                elif method in ("Watts/Person", "Power/Person"):
                    raise InputError(
                        f'{kind} "{name}" is given per person; zones with such loads cannot be '
                        'merged yet: set [simulation.plant] zones = "separate"'
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
        if s["zone_name"] not in zones:
            continue
        boundary = s["outside_boundary_condition"]
        if boundary == "Surface" and other in surfaces and surfaces[other]["zone_name"] in zones:
            if other not in removed:
                partitions.append((sname, s))
            removed |= {sname, other}
        elif boundary == "Zone" and other in zones:  # one surface, its other face made by EnergyPlus
            partitions.append((sname, s))
            removed.add(sname)
    for sname in removed:
        del surfaces[sname]
    # Windows and doors in a partition (a skylight between a room and its plenum) go with it.
    for objects in model.values():
        for oname, obj in list(objects.items()):
            if isinstance(obj, dict) and obj.get("building_surface_name") in removed:
                del objects[oname]
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
    floor_heights = {
        round(min(z for _, _, z in _vertices(s)), 1)
        for s in surfaces.values()
        if s["zone_name"] in zones and str(s.get("surface_type", "")).lower() == "floor"
    }
    if len(floor_heights) > 1:
        # Storeys merged make a zone EnergyPlus's interior solar distribution refuses (not
        # convex): the sun that enters falls on the floor instead.
        for building in model.get("Building", {}).values():
            if str(building.get("solar_distribution", "")).startswith("FullInterior"):
                building["solar_distribution"] = "FullExterior"
    for kind in ("ZoneMixing", "ZoneCrossMixing", "ZoneRefrigerationDoorMixing"):
        mixing = model.get(kind, {})
        for mname, obj in list(mixing.items()):
            ends = [obj.get(k) for k in ("zone_or_space_name", "zone_1_name", "source_zone_or_space_name", "zone_2_name")]
            ends = [e for e in ends if e is not None]
            if ends and all(e in zones for e in ends):  # air moved within the merged zone
                del mixing[mname]
            else:
                for k in ("source_zone_or_space_name", "zone_2_name"):
                    if obj.get(k) in zones:
                        obj[k] = MERGED_ZONE
    for objects in model.values():
        for obj in objects.values():
            f = _zone_field(obj) if isinstance(obj, dict) else None
            if f and obj[f] in zones:
                obj[f] = MERGED_ZONE
    first = model["Zone"][zones[0]]
    for z in zones:
        del model["Zone"][z]
    # The volume is the zones' sum: EnergyPlus cannot compute it of a merged zone whose
    # surfaces do not enclose it (partitions gone, plenums and unheated zones left out).
    model["Zone"][MERGED_ZONE] = {
        **first, "floor_area": "Autocalculate", "part_of_total_floor_area": "Yes",
        "volume": sum(geo[z]["volume_m3"] for z in zones),
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
    and T_r is the floor-area-weighted mean of the zones' air temperatures. Zones kept to be
    controlled each have a chiller too (``chillers``, in the zones' order; empty otherwise);
    ``zone_floor_m2`` is each zone's own floor area [m2] (one instance of a multiplied zone)."""

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
    chillers: tuple[str, ...] = ()
    zone_floor_m2: tuple[float, ...] = ()

    @property
    def zone(self) -> str:
        """The first heated zone (the only one when merged)."""
        return self.zones[0]

    @property
    def heater(self) -> str:
        """The first zone's heater (the only one when merged)."""
        return self.heaters[0]


def _add_heaters(
    model: dict[str, Any], zones: list[str], radiant_fraction: float, *, prefix: str = HEATER_PREFIX
) -> list[str]:
    """One ideal electric heater (``OtherEquipment``, 0 W until a run sets it, always on) in
    each of ``zones``, named ``<prefix> <zone>`` (a chiller's prefix: the same object, its
    power set negative); their names."""
    model.setdefault("Schedule:Constant", {})["PINN-MPC Always On"] = {"hourly_value": 1.0}
    heaters = [f"{prefix} {z}" for z in zones]
    for zone, heater in zip(zones, heaters, strict=True):
        model.setdefault("OtherEquipment", {})[heater] = {
            "fuel_type": "Electricity",
            "zone_or_zonelist_or_space_or_spacelist_name": zone,
            "schedule_name": "PINN-MPC Always On",
            "design_level_calculation_method": "EquipmentLevel",
            "design_level": 0.0,
            "fraction_latent": 0.0,
            "fraction_radiant": float(radiant_fraction),
            "fraction_lost": 0.0,
            "end_use_subcategory": prefix,
        }
    return heaters


def zone_names(zones: tuple[str, ...]) -> tuple[str, ...]:
    """EnergyPlus's zone names as the package's (:class:`pinn_mpc.zones.ZoneSpec`: letters,
    digits, ``_``, ``-``, ``.``): every other character (a space) becomes ``_``. InputError
    when two zones would get one name."""
    names = tuple(re.sub(r"[^A-Za-z0-9_.\-]", "_", z) for z in zones)
    if len(set(names)) != len(names):
        twins = sorted({z for z, n in zip(zones, names, strict=True) if names.count(n) > 1})
        raise InputError(
            f"zones {twins} would have the same name in the data ({', '.join(sorted(set(names)))}): "
            "rename them in the model, or use zones = 'merged' or 'separate'"
        )
    return names


def prepare_model(
    building: str,
    *,
    allow_code: bool = False,
    timesteps_per_hour: int = 6,
    zones: str = "merged",
    radiant_fraction: float = 0.0,
) -> PreparedModel:
    """A building (a bundled name or an IDF/epJSON path) without its HVAC, its conditioned
    zones merged into one (``zones="merged"``) or kept (``"separate"``, ``"controlled"``), an
    ideal electric heater (0 W until a run sets it; ``radiant_fraction`` of its heat radiant)
    in each; kept to be controlled, an ideal chiller (all convective) in each too.
    A model with code objects (:data:`CODE_OBJECT_PREFIXES`) is refused unless ``allow_code``."""
    if zones not in ZONE_LAYOUTS:
        raise ValueError(f"plant.zones = {zones!r} is not one of {', '.join(map(repr, ZONE_LAYOUTS))}")
    if isinstance(radiant_fraction, bool) or not 0.0 <= radiant_fraction <= 1.0:
        raise ValueError(f"plant.radiant_fraction = {radiant_fraction!r} must lie in [0, 1]")
    require_energyplus()
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
    heaters = _add_heaters(model, heated, radiant_fraction)
    chillers = _add_heaters(model, heated, 0.0, prefix=CHILLER_PREFIX) if zones == "controlled" else []
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
        chillers=tuple(chillers),
        zone_floor_m2=(
            (sum(geo[z]["floor_m2"] for z in conditioned),) if zones == "merged"
            else tuple(geo[z]["floor_m2"] for z in heated)
        ),
    )


def prepare_plant(plant: EnergyPlusSettings) -> PreparedModel:
    """:func:`prepare_model` of an EnergyPlus plant's :class:`~scenarios.plants.energyplus.settings.EnergyPlusSettings`."""
    return prepare_model(
        plant.building, allow_code=plant.allow_code, zones=plant.zones,
        radiant_fraction=plant.radiant_fraction,
    )



@functools.lru_cache(maxsize=16)
def _zone_layout_cached(key: PlantKey) -> tuple[tuple[str, ...], tuple[float, ...]]:
    prepared = prepared_from_key(key)
    return zone_names(prepared.zones), prepared.weights


@functools.lru_cache(maxsize=16)
def _zone_adjacency_cached(key: PlantKey) -> tuple[tuple[bool, ...], ...]:
    prepared = prepared_from_key(key)
    index = {z: i for i, z in enumerate(prepared.zones)}
    touching = [[False] * len(index) for _ in index]
    surfaces = prepared.model.get("BuildingSurface:Detailed", {})
    for s in surfaces.values():
        other = surfaces.get(s.get("outside_boundary_condition_object", ""))
        if s["outside_boundary_condition"] != "Surface" or other is None:
            continue
        i, j = index.get(s["zone_name"]), index.get(other["zone_name"])
        if i is not None and j is not None and i != j:
            touching[i][j] = touching[j][i] = True
    return tuple(map(tuple, touching))


def _window_area_vector(window: dict[str, Any]) -> tuple[float, float, float]:
    """A window's (FenestrationSurface:Detailed) outward normal times its area [m2]."""
    pts = [
        (window[f"vertex_{i}_x_coordinate"], window[f"vertex_{i}_y_coordinate"], window[f"vertex_{i}_z_coordinate"])
        for i in range(1, 5)
        if isinstance(window.get(f"vertex_{i}_x_coordinate"), int | float)
    ]
    return _area_vector(pts) if len(pts) >= 3 else (0.0, 0.0, 0.0)


def window_facade(area_vector: tuple[float, float, float], north_axis_deg: float) -> str:
    """The irradiance a window of outward ``area_vector`` (x east, y north, z up in the
    building's axes) takes, the building turned ``north_axis_deg`` clockwise from true north:
    ``G`` for a skylight (facing up more than sideways), else the facade of
    :data:`pinn_mpc.solar.FACADE_AZIMUTHS_DEG` nearest its azimuth."""
    ax, ay, az = area_vector
    if abs(az) >= math.hypot(ax, ay):
        return "G"
    azimuth = (math.degrees(math.atan2(ax, ay)) + north_axis_deg) % 360.0
    return min(
        FACADE_AZIMUTHS_DEG, key=lambda name: abs((azimuth - FACADE_AZIMUTHS_DEG[name] + 180.0) % 360.0 - 180.0)
    )


@functools.lru_cache(maxsize=16)
def _zone_window_facades_cached(key: PlantKey) -> tuple[str, ...]:
    prepared = prepared_from_key(key)
    model = prepared.model
    building: dict[str, Any] = next(iter(model.get("Building", {}).values()), {})
    north = building.get("north_axis", 0.0)
    north = float(north) if isinstance(north, int | float) else 0.0
    rules: dict[str, Any] = next(iter(model.get("GlobalGeometryRules", {}).values()), {})
    relative = str(rules.get("coordinate_system", "Relative")).lower() == "relative"
    surfaces = model.get("BuildingSurface:Detailed", {})
    areas: dict[str, dict[str, float]] = {z: {} for z in prepared.zones}
    for window in model.get("FenestrationSurface:Detailed", {}).values():
        zone = surfaces.get(window.get("building_surface_name", ""), {}).get("zone_name")
        if zone not in areas:
            continue
        vector = _window_area_vector(window)
        turn = model["Zone"][zone].get("direction_of_relative_north", 0.0) if relative else 0.0
        facade = window_facade(vector, north + (float(turn) if isinstance(turn, int | float) else 0.0))
        multiplier = window.get("multiplier", 1.0)
        scale = float(multiplier) if isinstance(multiplier, int | float) else 1.0
        areas[zone][facade] = areas[zone].get(facade, 0.0) + math.hypot(*vector) * scale
    return tuple(max(a, key=a.__getitem__) if a else "G" for a in (areas[z] for z in prepared.zones))


def zone_window_facades(plant: EnergyPlusSettings) -> tuple[str, ...]:
    """The irradiance each zone of :func:`zone_layout` takes through its windows: the facade
    (:data:`pinn_mpc.solar.FACADE_COLUMNS`) its largest window area faces, by the windows'
    outward normals turned by the building's north axis (and a zone's own relative north);
    ``G`` (global horizontal) where that area is skylights or the zone has no windows (its
    roof's and walls' absorbed sun). Computed once per process."""
    return _zone_window_facades_cached(plant_key(plant))


def zone_adjacency(plant: EnergyPlusSettings) -> tuple[tuple[bool, ...], ...]:
    """(Z, Z) of the zones of :func:`zone_layout`: True where two of them share a surface (a
    wall, a floor or a ceiling between them); zones that touch only through a zone left out
    (a plenum) do not. Computed once per process."""
    return _zone_adjacency_cached(plant_key(plant))


def zone_layout(plant: EnergyPlusSettings) -> tuple[tuple[str, ...], tuple[float, ...]]:
    """The zones an EnergyPlus plant's model has heated (:func:`zone_names`) and each one's
    share of the floor area (:attr:`PreparedModel.weights`); computed once per process."""
    return _zone_layout_cached(plant_key(plant))


#: What :func:`prepare_plant` reads of a plant: building, allow_code, zones, radiant fraction
#: (hashable, the cached runs' key).
PlantKey = tuple[str, bool, str, float]


def plant_key(plant: EnergyPlusSettings) -> PlantKey:
    """The :data:`PlantKey` of an EnergyPlus plant."""
    return (plant.building, bool(plant.allow_code), plant.zones, float(plant.radiant_fraction))


def prepared_from_key(key: PlantKey) -> PreparedModel:
    """:func:`prepare_model` of a :data:`PlantKey` (the cached runs' hashable argument)."""
    building, allow_code, zones, radiant = key
    return prepare_model(building, allow_code=allow_code, zones=zones, radiant_fraction=radiant)

