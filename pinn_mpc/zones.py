"""A building's zones: declared, and named in the data format.

A building has one or more zones (:class:`ZoneSpec`), each with its own room temperature,
thermal-mass temperature and comfort band. The data format, the closed loop's arrays and a
run's trajectory carry them on a zone axis: in a data frame or CSV each zone has its own
columns, ``T_r[<zone>]``, ``T_m[<zone>]``, ``T_min[<zone>]`` and ``T_max[<zone>]``
(:data:`ZONE_SERIES`), while the one-zone building keeps today's names (``T_r``, ...),
so every one-zone file reads as before. :func:`zone_column` is the one place such a name is
formed and :func:`parse_zone_column` the one place it is read back; an actuator names its zone
by its index in the building's zones (:class:`pinn_mpc.actuator.ActuatorSpec.zone`).

Today's buildings are one zone (:data:`ONE_ZONE`); the data format already reads and writes
several (the models and controllers that use them are the zones-and-cooling issue's).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "ONE_ZONE",
    "ZONE_SERIES",
    "ZoneSpec",
    "parse_zone_column",
    "zone_column",
    "zone_columns",
    "zone_series_columns",
    "zones_in",
]

#: The data format's series that a building has once per zone: its room temperature, its
#: thermal-mass temperature (simulated data) and its comfort band [C].
ZONE_SERIES = ("T_r", "T_m", "T_min", "T_max")
#: A zone's name: letters, digits, ``_``, ``-`` and ``.`` (EnergyPlus's zone names, such as
#: ``Perimeter_ZN_1``, fit), so a column ``T_r[<name>]`` reads back unambiguously.
_NAME = re.compile(r"[A-Za-z0-9_.\-]+")
_COLUMN = re.compile(rf"({'|'.join(ZONE_SERIES)})\[({_NAME.pattern})\]")


@dataclass(frozen=True)
class ZoneSpec:
    """One zone of a building: its ``name`` (the data format's ``T_r[<name>]`` columns)."""

    name: str

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and _NAME.fullmatch(self.name)):
            raise ValueError(
                f"ZoneSpec.name must be letters, digits, '_', '-' or '.', got {self.name!r}"
            )


#: The one-zone building every scenario is today: its columns are ``T_r``, ``T_m``, ...
ONE_ZONE: tuple[ZoneSpec, ...] = (ZoneSpec("room"),)


def zone_column(series: str, zones: Sequence[ZoneSpec], zone: int) -> str:
    """The data format's column of ``series`` (one of :data:`ZONE_SERIES`) for zone index
    ``zone`` of a building with ``zones``: ``series`` itself for a one-zone building, else
    ``series[<name>]``."""
    if series not in ZONE_SERIES:
        raise ValueError(f"zone_column: {series!r} is not a zone series ({', '.join(ZONE_SERIES)})")
    if not 0 <= zone < len(zones):
        raise ValueError(f"zone_column: zone {zone} of a building with {len(zones)} zone(s)")
    return series if len(zones) == 1 else f"{series}[{zones[zone].name}]"


def zone_columns(series: str, zones: Sequence[ZoneSpec]) -> tuple[str, ...]:
    """Every zone's column of ``series``, in the zones' order (:func:`zone_column`)."""
    return tuple(zone_column(series, zones, z) for z in range(len(zones)))


def zone_series_columns(series: str, values: np.ndarray, zones: Sequence[ZoneSpec]) -> dict[str, np.ndarray]:
    """A zone series' values as the data format's columns: (N, Z) as each zone's column
    (:func:`zone_column`), (N,) (one value for every zone, such as a building's comfort band)
    as the column ``series``."""
    if np.ndim(values) == 1:
        return {series: np.asarray(values)}
    return dict(zip(zone_columns(series, zones), np.asarray(values).T, strict=True))


def parse_zone_column(column: str) -> tuple[str, str] | None:
    """``"T_r[south]"`` -> ``("T_r", "south")``; None for any other column (``T_r`` included)."""
    match = _COLUMN.fullmatch(column)
    return None if match is None else (match.group(1), match.group(2))


def zones_in(columns: Iterable[str]) -> tuple[ZoneSpec, ...]:
    """The zones a frame's columns name, in their order: its rooms' (``T_r[<zone>]``), or in a
    frame without rooms (a run's inputs) any zone series'; :data:`ONE_ZONE` where they name
    none."""
    parsed = [p for p in (parse_zone_column(str(c)) for c in columns) if p is not None]
    rooms = [name for series, name in parsed if series == "T_r"]
    names = list(dict.fromkeys(rooms or [name for _, name in parsed]))
    return tuple(ZoneSpec(name) for name in names) if names else ONE_ZONE
