"""Scenarios as TOML files: export a built-in, read a file back, resolve a name or a path.

A file holds one :class:`scenarios.inputs.registry.Scenario`, serialised generically from its frozen
dataclasses; ``pinn-mpc scenario export NAME --out FILE.toml`` writes a complete, commented one.
Layout (:data:`SECTIONS` maps a dataclass field to its place in the file)::

    name, description, comfort_weight_eur_per_kh, horizon_steps, initial_t_r_c, initial_t_m_c,
    data_policy
    [building]    Scenario.sim.params (RCParams), or rc = "rc.json" (identify / export-rc JSON)
    [simulation]  the other SimConfig fields (actuator limit, control interval, backup, ...)
    [simulation.plant]  Scenario.plant (PlantSettings: the plant's kind and settings;
                  SimConfig.plant follows from it and is not written)
    [sensor]      noise_std_c: SimConfig.noise_std_c, the room-temperature sensor noise
    [weather]     type = "TMY3Weather" | "SyntheticWeather" | "CSVWeather", then its fields
    [price]       type = "PriceProfile" | "PriceCSV", then its fields
    [comfort] [gains] [forecast]   ComfortSchedule, GainsSchedule, ForecastErrors

Reading: every key is checked against the dataclass field it fills (unknown, missing, wrong
type) and the dataclass validates the values (plausible R/C ranges, T_min < T_max, ...); an
error is one InputError naming the file and the key as a dotted path (``building.r_ra_k_per_w``),
the ValueError a dataclass raises for a Python caller included.
Relative paths (``building.rc``, and each class's ``PATH_FIELDS`` such as ``weather.path``) are
relative to the TOML file; a bare weather file name not found there is one of pvlib's TMY3 files.

A new field gets into the file by itself: give the dataclass the field (with a default, so older
files still load) with a type the converter knows: float, int, str, bool, a Literal, a tuple of
these, a nested frozen dataclass (written as a sub-table, e.g. ``[simulation.actuator]``) or a
union of dataclasses (a sub-table with ``type = "ClassName"``). A field that should have a
section of its own is one entry in :data:`SECTIONS`.
"""

from __future__ import annotations

import dataclasses
import os
import re
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, Literal

import tomlkit

from pinn_mpc.errors import InputError
from pinn_mpc.physics import PLAUSIBLE_RANGES
from scenarios.inputs.registry import (
    Scenario,
    builtin_scenario,
    is_scenario_file,
    scenario_names,
    with_sized_heater,
)
from scenarios.plants.kinds import plant_kind
from scenarios.plants.settings import PlantSettings

__all__ = [
    "SECTIONS",
    "builtin_names",
    "defaulted_keys",
    "get_scenario",
    "load_scenario_file",
    "read_toml",
    "scenario_inputs",
    "scenario_from_dict",
    "scenario_list",
    "scenario_to_toml",
]

#: Dotted field path in a Scenario -> dotted path in the file (longest prefix wins).
SECTIONS = {
    "sim": "simulation",
    "sim.params": "building",
    "sim.noise_std_c": "sensor.noise_std_c",
    "plant": "simulation.plant",
}
#: Dotted field paths set from other fields, not written (``Scenario.__post_init__`` sets
#: ``sim.plant``, the simulator's structure, from ``plant``).
DERIVED = ("sim.plant",)
#: The discriminator key of a table whose field is a union of dataclasses.
TYPE_KEY = "type"


def _file_key(internal: str) -> str:
    for prefix in sorted(SECTIONS, key=len, reverse=True):
        if internal == prefix or internal.startswith(prefix + "."):
            return SECTIONS[prefix] + internal[len(prefix) :]
    return internal


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _is_dataclass_type(tp: Any) -> bool:
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


def _union_members(tp: Any) -> tuple[type, ...] | None:
    """The dataclasses of a union-of-dataclasses type, else None."""
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        members = typing.get_args(tp)
        if all(_is_dataclass_type(m) for m in members):
            return members
    return None


# ---------------------------------------------------------------- dataclass -> TOML

def _plain(value: Any, tp: Any) -> Any:
    """A field value as TOML data: numbers, strings, lists, tables (dict); a plant as its
    kind and that kind's fields."""
    if isinstance(value, PlantSettings):
        hints = typing.get_type_hints(value.plug.settings_type)
        fields = {k: v for k, v in value.fields().items() if v is not None}
        return {"kind": value.kind, **{k: _plain(v, hints[k]) for k, v in fields.items()}}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        table = {}
        if _union_members(tp):
            table[TYPE_KEY] = type(value).__name__
        hints = typing.get_type_hints(type(value))
        for f in dataclasses.fields(value):
            if getattr(value, f.name) is not None:  # None: not given, its default when read
                table[f.name] = _plain(getattr(value, f.name), hints[f.name])
        return table
    if isinstance(value, tuple):
        return [_plain(v, Any) for v in value]
    return value


def _doc_line(cls: type) -> str:
    """The first paragraph of a class docstring as plain text (reST markup removed)."""
    doc = (cls.__doc__ or "").strip().split("\n\n")[0]
    doc = re.sub(r":\w+:`~?([^`]+)`", r"\1", doc).replace("``", "")
    return " ".join(doc.split())


def _comment_for(field_name: str) -> str | None:
    if field_name in PLAUSIBLE_RANGES:
        lo, hi, unit = PLAUSIBLE_RANGES[field_name]
        return f"[{unit}], plausible {lo:g} .. {hi:g}"
    return None


def _fill(table: Any, data: dict[str, Any], cls: type | None) -> None:
    """Write ``data`` into a tomlkit table: scalars first (commented), then sub-tables."""
    for key, value in data.items():
        if isinstance(value, dict):
            continue
        item = tomlkit.item(value)
        note = _comment_for(key)
        if note:
            item.comment(note)
        table.add(key, item)
    hints = typing.get_type_hints(cls) if cls is not None else {}
    for key, value in data.items():
        if not isinstance(value, dict):
            continue
        sub = tomlkit.table()
        members = _union_members(hints.get(key))
        declared = hints.get(key)
        sub_cls: type | None = declared if _is_dataclass_type(declared) else None
        if members:
            sub_cls = next(m for m in members if m.__name__ == value[TYPE_KEY])
        if sub_cls is not None:
            choice = f" (type: one of {', '.join(m.__name__ for m in members)})" if members else ""
            sub.comment(_doc_line(sub_cls) + choice)
        _fill(sub, value, sub_cls)
        table.add(key, sub)


def _relocate(data: dict[str, Any], mapping: dict[str, str]) -> dict[str, Any]:
    """Move dotted paths of nested dicts (deepest first, so a parent moves with its children
    already out of it)."""
    out = typing.cast(dict[str, Any], _deep_copy(data))
    for source in sorted(mapping, key=lambda k: k.count("."), reverse=True):
        value = _pop_path(out, source)
        if value is not _MISSING:
            _set_path(out, mapping[source], value)
    return out


_MISSING = object()


def _deep_copy(value: Any) -> Any:
    return {k: _deep_copy(v) for k, v in value.items()} if isinstance(value, dict) else value


def _pop_path(data: dict[str, Any], dotted: str) -> Any:
    *parents, last = dotted.split(".")
    node: Any = data
    for key in parents:
        node = node.get(key) if isinstance(node, dict) else None
    if not isinstance(node, dict) or last not in node:
        return _MISSING
    return node.pop(last)


def _set_path(data: dict[str, Any], dotted: str, value: Any) -> None:
    *parents, last = dotted.split(".")
    node = data
    for key in parents:
        node = node.setdefault(key, {})
        if not isinstance(node, dict):
            raise InputError(f"{key}: expected a table, got {node!r}")
    if isinstance(node.get(last), dict) and isinstance(value, dict):
        node[last] = {**value, **node[last]}  # a table some of whose keys arrived first
    else:
        node[last] = value


def scenario_to_toml(scenario: Scenario) -> str:
    """The complete, commented TOML text of ``scenario`` (read back by :func:`load_scenario_file`)."""
    plain = _plain(scenario, Scenario)
    for derived in DERIVED:
        _pop_path(plain, derived)
    moved = _relocate(plain, SECTIONS)
    weather = moved.get("weather")
    if scenario.plant.settings.weather_file is not None and isinstance(weather, dict):
        # One place for the weather: the plant's (simulation.plant.weather); [weather] keeps
        # only its window, and gets the file from the plant when read.
        weather.pop("file_name", None)
    first = [k for k in moved if not isinstance(moved[k], dict)] + ["building", "simulation", "sensor"]
    data = {k: moved[k] for k in first} | moved
    doc = tomlkit.document()
    doc.add(tomlkit.comment(f"pinn-mpc scenario {scenario.name!r}: use it as --scenario FILE.toml"))
    doc.add(tomlkit.comment("Units are in the key names (_c Celsius, _w watt, _s seconds, _h hours)."))
    doc.add(tomlkit.comment("[building] may instead be one line: rc = \"rc.json\" (from identify or"))
    doc.add(tomlkit.comment("export-rc, relative to this file). Weather: type TMY3Weather (file_name a"))
    doc.add(tomlkit.comment("pvlib TMY3 name or a TMY3/EPW path), SyntheticWeather or CSVWeather (path of"))
    doc.add(tomlkit.comment("a CSV time,T_a[,G], test_days); price: PriceProfile or PriceCSV (CSV time,price)."))
    doc.add(tomlkit.nl())
    _fill(doc, data, Scenario)
    # Sections that are not dataclasses of their own get their comment here.
    for section, note in (
        ("building", "Building (2R2C): " + _doc_line(type(scenario.sim.params))),
        ("simulation", "Simulation: actuator limit, control interval, substep, backup thermostat."),
        ("sensor", "Room-temperature sensor: Gaussian noise std [K] on every measurement."),
    ):
        if section in doc:
            doc[section].comment(note)
    return tomlkit.dumps(doc)


# ---------------------------------------------------------------- TOML -> dataclass

def _error(where: str, problem: str) -> InputError:
    return InputError(f"{_file_key(where)}: {problem}")


def _convert(tp: Any, value: Any, where: str, base: Path) -> Any:
    """A TOML value as the field type ``tp`` (see the module docstring for the types)."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    members = _union_members(tp)
    if members:
        if not isinstance(value, dict):
            raise _error(where, f"expected a table, got {value!r}")
        names = {m.__name__: m for m in members}
        kind = value.get(TYPE_KEY)
        if kind not in names:
            raise _error(_join(where, TYPE_KEY), f"{kind!r} is not one of {', '.join(names)}")
        rest = {k: v for k, v in value.items() if k != TYPE_KEY}
        return _build(names[kind], rest, where, base)
    if origin in (typing.Union, types.UnionType):  # of scalars: the first type the value is
        for member in args:
            try:
                return _convert(member, value, where, base)
            except InputError:
                continue
        raise _error(where, f"expected one of {', '.join(a.__name__ for a in args)}, got {value!r}")
    if _is_dataclass_type(tp):
        if not isinstance(value, dict):
            raise _error(where, f"expected a table, got {value!r}")
        return _build(tp, value, where, base)
    if origin is Literal:
        if value not in args:
            raise _error(where, f"{value!r} is not one of {', '.join(map(repr, args))}")
        return value
    if origin is tuple:
        if not isinstance(value, list):
            raise _error(where, f"expected a list, got {value!r}")
        item_types = [args[0]] * len(value) if len(args) == 2 and args[1] is Ellipsis else list(args)
        if len(item_types) != len(value):
            raise _error(where, f"expected {len(item_types)} values, got {len(value)}")
        return tuple(_convert(t, v, f"{where}[{i}]", base) for i, (t, v) in enumerate(zip(item_types, value, strict=True)))
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise _error(where, f"expected a number, got {value!r}")
        return float(value)
    if tp in (int, bool, str):
        if not isinstance(value, tp) or (tp is int and isinstance(value, bool)):
            raise _error(where, f"expected {tp.__name__}, got {value!r}")
        return value
    raise _error(where, f"fields of type {tp!r} cannot be read from a file")


def _resolve(text: str, base: Path) -> str:
    """A path written in the file: relative to the file's folder when that file exists there;
    otherwise as written (a bare name may be one of pvlib's TMY3 files)."""
    if not text:  # not given (an RC plant has no EnergyPlus building)
        return text
    candidate = base / os.path.expanduser(text)
    if Path(text).is_absolute() or candidate.exists() or Path(text).name != text:
        return str(candidate)
    return text


def _build_plant(table: dict[str, Any], where: str, base: Path) -> PlantSettings:
    """The plant of a ``[simulation.plant]`` table: its kind (default the 2R2C) and that kind's
    settings (:meth:`PlantSettings.from_fields` says which keys are its own)."""
    kind = table.get("kind", PlantSettings().kind)
    if not isinstance(kind, str):
        raise _error(_join(where, "kind"), f"expected a string, got {kind!r}")
    try:
        plant_kind(kind)
        settings_type, own = PlantSettings.from_fields(kind, {k: v for k, v in table.items() if k != "kind"})
    except InputError as exc:
        message = str(exc).removeprefix("plant: ")
        key = message.split(":")[0]
        if "unknown key" in message:
            raise _error(_join(where, key), message.split(": ", 1)[1]) from None
        raise InputError(f"{_file_key(where)}: {message}") from None
    return PlantSettings(kind=kind, settings=_build(settings_type, own, where, base))


def _build(cls: type, table: dict[str, Any], where: str, base: Path) -> Any:
    if cls is PlantSettings:
        return _build_plant(table, where, base)
    hints = typing.get_type_hints(cls)
    known = {f.name: f for f in dataclasses.fields(cls) if f.init}
    here = [n for n in known if _file_key(_join(where, n)) == _join(_file_key(where), n)]
    for key in table:
        if key not in known:
            raise _error(_join(where, key), f"unknown key; [{_file_key(where) or 'top level'}] takes {', '.join(here)}")
    kwargs = {}
    for name, f in known.items():
        key = _join(where, name)
        if name not in table:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise _error(key, "missing (required)")
            continue
        value = _convert(hints[name], table[name], key, base)
        if name in getattr(cls, "PATH_FIELDS", ()):
            value = _resolve(value, base)
        kwargs[name] = value
    section = _file_key(where)
    try:
        obj = cls(**kwargs)
    except ValueError as exc:  # a value the class refuses; it names itself: say where in the file instead
        message = str(exc)
        for name in sorted(known, key=len, reverse=True):  # a name may prefix another
            message = message.replace(f"{cls.__name__}.{name}", _file_key(_join(where, name)))
        message = message.replace(cls.__name__, section or cls.__name__)
        raise InputError(message if message.startswith(section) else f"{section}: {message}") from None
    if hasattr(obj, "check"):  # a file it names must exist and be readable now
        key = _join(section, getattr(cls, "PATH_FIELDS", ("",))[0])
        try:
            obj.check()
        except InputError as exc:
            raise InputError(f"{key}: {exc.marked}") from None
    return obj


def _plant_defaults(data: dict[str, Any], base: Path) -> None:
    """What a file may leave out because its plant gives it: the plant kind's
    (:attr:`scenarios.plants.kinds.PlantKind.complete_file`, e.g. an EnergyPlus building's
    nominal R/C values, its weather file and heater), filled into ``data`` before it is read."""
    simulation = data.get("simulation")
    plant = simulation.get("plant") if isinstance(simulation, dict) else None
    if not isinstance(plant, dict):
        return
    kind = plant_kind(str(plant.get("kind", PlantSettings().kind)))
    if kind.complete_file is not None:
        kind.complete_file(data, lambda text: _resolve(text, base))


def scenario_from_dict(data: dict[str, Any], *, base: Path, default_name: str) -> Scenario:
    """A Scenario from parsed TOML data (``base``: the folder relative paths start from)."""
    data = _deep_copy(data)
    _plant_defaults(data, base)
    building = data.get("building")
    if building is None:
        raise InputError(
            "[building] is missing: the building is not defaulted; give its R/C values (as "
            "`pinn-mpc scenario export winter_household` writes them) or one line, "
            'rc = "rc.json"'
        )
    if isinstance(building, dict) and "rc" not in building:
        from pinn_mpc.physics import RCParams

        absent = [
            f.name for f in dataclasses.fields(RCParams)
            if f.name not in building and f.name != "unmeasured_gains_w"
        ]
        if absent:
            raise InputError(
                f"building.{absent[0]}: missing (the building is not defaulted: a deleted "
                f"solar aperture would silently mean no windows); give {', '.join(absent)} "
                "(0 for none), as `pinn-mpc scenario export` writes them"
            )
    if isinstance(building, dict) and "rc" in building:
        others = sorted(set(building) - {"rc"})
        if others:
            raise InputError(f"building: give rc or the R/C values, not both (also has {others})")
        if not isinstance(building["rc"], str):
            raise InputError(f"building.rc: expected a path string, got {building['rc']!r}")
        from pinn_mpc.artifacts import read_rc

        if (base / building["rc"]).is_dir():
            raise InputError(
                f"building.rc: {base / building['rc']} is a directory; give the rc.json file "
                "written by `pinn-mpc identify` or `pinn-mpc export-rc`"
            )
        try:
            params = read_rc(base / building["rc"])
        except InputError as exc:
            raise InputError(f"building.rc: {exc.marked}") from None
        # the plant takes its internal gains from the scenario, not an identified schedule
        data["building"] = params.without_unmeasured_gains().to_dict()
    for section, content in data.items():
        if section in {p.split(".")[0] for p in SECTIONS.values()} and not isinstance(content, dict):
            raise InputError(f"{section}: expected a table, got {content!r}")
    # A field with a section of its own is not also taken where the dataclass has it
    # (``simulation.noise_std_c`` is ``sensor.noise_std_c``).
    for inner, place in SECTIONS.items():
        parent = inner.rpartition(".")[0]
        if parent in SECTIONS:
            written = SECTIONS[parent] + inner[len(parent) :]
            if _pop_path(_deep_copy(data), written) is not _MISSING:
                raise InputError(f"{written}: unknown key; it is written as {place}")
    if "plant" in data:  # Scenario.plant is written as [simulation.plant] only
        here = [f.name for f in dataclasses.fields(Scenario) if f.name not in SECTIONS]
        raise InputError(f"plant: unknown key; [top level] takes {', '.join(here)}")
    data.setdefault("name", default_name)
    data.setdefault("description", f"Scenario file {default_name}.")
    internal = _relocate(data, {v: k for k, v in SECTIONS.items()})
    # A section that only held relocated keys (``[sensor]``): anything left in it is unknown.
    for place in SECTIONS.values():
        section = place.split(".")[0]
        left = internal.get(section)
        if section not in SECTIONS.values() and isinstance(left, dict):
            if left:
                raise InputError(f"{section}.{next(iter(left))}: unknown key")
            del internal[section]
    scenario = typing.cast(Scenario, _build(Scenario, internal, "", base))
    if scenario.plant.settings.sized_when_read:
        given = data.get("simulation", {}).get("u_max_w")
        scenario = with_sized_heater(scenario, given_u_max_w=given)
    return scenario


def read_toml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The parsed TOML of a scenario file (a UTF-8 byte-order mark, as some editors write, is
    skipped); a missing or unparsable file is one InputError naming it."""
    source = Path(path)
    if source.is_dir():
        raise InputError(f"{source}: is a directory; give the scenario's .toml file")
    if not source.is_file():
        raise InputError(f"{source}: no such scenario file")
    try:
        return tomllib.loads(source.read_text(encoding="utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise InputError(f"{source}: not UTF-8 text ({exc}); save it as UTF-8") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: not valid TOML ({exc})") from None


def load_scenario_file(path: str | os.PathLike[str]) -> Scenario:
    """A Scenario from a TOML file; any problem is one InputError naming the file and the key."""
    source = Path(path)
    data = read_toml(source)
    try:
        scenario = scenario_from_dict(data, base=source.parent, default_name=source.stem)
    except InputError as exc:
        raise InputError(f"{source}: {exc.marked}") from None
    _warn_implausible(scenario, source)
    return scenario


def _warn_implausible(scenario: Scenario, source: Path) -> None:
    """Warn about a file that carries a built-in's name but is another scenario, and about
    measured weather that looks like the wrong unit: a heated building whose outdoor
    temperature is mostly above its comfort band (Fahrenheit?)."""
    from pinn_mpc.errors import warn_once
    from scenarios.inputs.measured import CSVWeather

    if scenario.name in scenario_names():
        builtin = get_scenario(scenario.name)
        if dataclasses.replace(scenario, description=builtin.description) != builtin:
            warn_once(
                f"{source}: name = {scenario.name!r} is a built-in scenario's, but the file "
                "differs from it; results name the file too (scenario_file), or rename it"
            )
    weather = scenario.weather
    if not (isinstance(weather, CSVWeather) and scenario.sim.params.heating):
        return
    median = float(weather.frame()["T_a"].median())
    top = max(scenario.comfort.day_max_c, scenario.comfort.night_max_c)
    if median > top:
        warn_once(
            f"{source}: weather.path {weather.path}: the median T_a is {median:.1f} C, above "
            f"the comfort band's top ({top:g} C) of a heated building; is T_a in Fahrenheit "
            f"({median:.1f} F would be {(median - 32) / 1.8:.1f} C)? Convert it to Celsius"
        )


def defaulted_keys(path: str | os.PathLike[str]) -> list[str]:
    """The keys (dotted, as in the file) a scenario file leaves out, so that their defaults
    apply: every key of the complete file :func:`scenario_to_toml` writes that it lacks."""
    source = Path(path)
    given = _leaf_keys(read_toml(source))
    complete = _leaf_keys(tomllib.loads(scenario_to_toml(load_scenario_file(source))))
    left_out = complete - given - {"name", "description"}
    if "building.rc" in given:  # the rc.json gives the whole building
        left_out = {k for k in left_out if not k.startswith("building.")}
    return sorted(left_out)


def _leaf_keys(data: dict[str, Any], prefix: str = "") -> set[str]:
    out: set[str] = set()
    for key, value in data.items():
        dotted = _join(prefix, key)
        out |= _leaf_keys(value, dotted) if isinstance(value, dict) else {dotted}
    return out


def scenario_inputs(name_or_path: str) -> dict[str, Path]:
    """Every file a scenario reads, by its key in the file: for a scenario file, the file
    itself (key ``""``), the ``building.rc`` it names, its weather and price files (CSV,
    TMY3, EPW: ``weather.path``, ``weather.file_name``, ``price.path``) and an EnergyPlus
    plant's model and weather files (``simulation.plant.building``, ``.weather``: an IDF or
    epJSON, an EPW); for a built-in name, none. Commands protect them as inputs (no output
    may replace them)."""
    from scenarios.inputs.exogenous import tmy3_path

    if not is_scenario_file(name_or_path):
        return {}
    source = Path(name_or_path)
    files = {"": source}
    building = read_toml(source).get("building")
    if isinstance(building, dict) and isinstance(building.get("rc"), str):
        files["building.rc"] = source.parent / building["rc"]
    scenario = get_scenario(name_or_path)
    for section, part in (("weather", scenario.weather), ("price", scenario.price)):
        for name in getattr(part, "PATH_FIELDS", ()):
            value = getattr(part, name)
            path = tmy3_path(value) if name == "file_name" else Path(value)
            if path.is_file():
                files[f"{section}.{name}"] = path
    plant = scenario.plant.settings
    for name in plant.PATH_FIELDS:
        path = Path(getattr(plant, name))  # a bundled name is no file here
        if path.is_file():
            files[f"simulation.plant.{name}"] = path
    return files


# ---------------------------------------------------------------- pinn-mpc scenario

def builtin_names() -> list[str]:
    """Every built-in name ``--scenario`` takes: the package's own scenarios
    (:func:`scenarios.scenario_names`, sorted), then the BOPTEST built-ins
    (:data:`scenarios.plants.boptest.BUILTIN_BOPTEST`). The one list that ``scenario list``,
    the unknown-scenario message and the command line's help show."""
    from scenarios.plants.boptest import BUILTIN_BOPTEST

    return [*scenario_names(), *BUILTIN_BOPTEST]


def scenario_list() -> str:
    """One line per built-in scenario (:func:`builtin_names`): its name and description
    (which ends with its weather split, or names the BOPTEST test case)."""
    from scenarios.plants.boptest import BUILTIN_BOPTEST, boptest_description, builtin_boptest

    return "\n".join(
        f"{name}: {boptest_description(builtin_boptest(name))}" if name in BUILTIN_BOPTEST
        else f"{name}: {get_scenario(name).description}"
        for name in builtin_names()
    )


def get_scenario(name_or_path: str) -> Scenario:
    """A built-in scenario by name, or a scenario file: the one resolver behind every
    ``--scenario``.

    Parameters
    ----------
    name_or_path
        A built-in name (:func:`scenarios.scenario_names`) or the path of a ``.toml`` scenario
        file (see :mod:`scenarios.inputs.scenario_file`).

    Returns
    -------
    Scenario

    Raises
    ------
    InputError
        An unknown name (the message lists the valid ones); a bad file (the message names
        the file and the key).
    """
    if name_or_path in scenario_names():
        return builtin_scenario(name_or_path)
    from scenarios.plants.boptest import boptest_file

    if boptest_file(name_or_path) is not None:
        raise InputError(
            f"{name_or_path} is a BOPTEST scenario: it runs on a BOPTEST server, through "
            "simulate, closed-loop, compare and sweep (see `pinn-mpc scenario show "
            f"{name_or_path}`); this asks for one of the package's own scenarios"
        )
    if is_scenario_file(name_or_path):
        return load_scenario_file(name_or_path)
    if os.path.isfile(name_or_path):
        raise InputError(
            f"{name_or_path!r} is a file, but scenario files end in .toml (without it the name "
            f"is taken for a built-in); rename it {name_or_path}.toml"
        )
    raise InputError(
        f"unknown scenario {name_or_path!r}; choose one of: {', '.join(builtin_names())}, or give "
        "a scenario file (.toml; `pinn-mpc scenario export` writes one)"
    )
