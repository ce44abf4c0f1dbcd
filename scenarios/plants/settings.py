"""The scenario's plant (``[simulation.plant]`` of a scenario file): its kind and that kind's
settings, and the plant it makes for a run.

``kind`` names a kind of the registry (:mod:`scenarios.plants.kinds`: ``2r2c`` and ``3r3c``,
the package's RC simulator; ``energyplus``); ``settings`` are that kind's own
(:attr:`~scenarios.plants.kinds.PlantKind.settings_type`). In a scenario file the table holds
``kind`` and the kind's fields (:meth:`PlantSettings.from_fields`, :meth:`PlantSettings.fields`);
a file written when every kind's fields were listed in every table is read as before: another
kind's field at its default is dropped. Everything else asks this object what its kind can
do, never which kind it is.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pinn_mpc.errors import InputError
from pinn_mpc.plant import Plant
from pinn_mpc.simulator import SimConfig
from scenarios.plants.base import LoopPlant
from scenarios.plants.kinds import (
    FleetBuildings,
    KindSettings,
    PlantKind,
    PlantRequest,
    kind_names,
    plant_kind,
)

__all__ = ["PlantSettings", "make_plant"]


#: What files written before a table held only its kind's fields listed for a field that has
#: no default in its kind (an RC plant's table held ``building = ""``).
_LISTED_DEFAULTS = {"building": "", "weather": ""}


def _rc_settings() -> KindSettings:
    return plant_kind("2r2c").settings_type()


@dataclass(frozen=True, kw_only=True)
class PlantSettings:
    """The scenario's plant: the name of its kind and the kind's settings (module docstring)."""

    kind: str = "2r2c"
    settings: KindSettings = field(default_factory=_rc_settings)

    def __post_init__(self) -> None:
        expected = self.plug.settings_type
        if type(self.settings) is not expected:
            raise ValueError(
                f"PlantSettings: kind {self.kind!r} takes {expected.__name__}, got "
                f"{type(self.settings).__name__}"
            )

    @property
    def plug(self) -> PlantKind:
        """The registry's entry of this kind."""
        return plant_kind(self.kind)

    @property
    def rc(self) -> Plant:
        """The structure the RC simulator integrates (``SimConfig.plant``): the kind's own for
        an RC kind, the default 2R2C for a plant that runs elsewhere (the scenario's nominal
        R/C values describe it)."""
        return self.plug.structure(self.settings)

    @property
    def true_state(self) -> bool:
        """Whether the plant has a true RC state (an oracle and a clairvoyant can run on it)."""
        return self.plug.true_state

    @property
    def fleets(self) -> bool:
        """Whether the plant runs many buildings with their own parameters in one batch."""
        return self.plug.fleets

    @property
    def starts_at_midnight(self) -> bool:
        """Whether the plant's runs start at midnight only."""
        return self.plug.starts_at_midnight

    @property
    def reference(self) -> str:
        """The controller every other is measured against: the oracle where the plant has a
        true state, else the thermostat (as BOPTEST measures against its baseline)."""
        return "oracle" if self.true_state else "thermostat"

    @classmethod
    def from_fields(cls, kind: str, fields: Mapping[str, Any]) -> tuple[type[KindSettings], dict[str, Any]]:
        """The settings type of ``kind`` and those of ``fields`` (a ``[simulation.plant]``
        table without ``kind``) that are its own; another registered kind's field at its
        default is dropped (files listed every kind's fields), anything else is refused."""
        settings_type = plant_kind(kind).settings_type
        own = {f.name: f for f in dataclasses.fields(settings_type) if f.init}
        others: dict[str, Any] = {}  # another kind's field: its default, as files listed it
        for name in kind_names():
            for f in dataclasses.fields(plant_kind(name).settings_type):
                if f.init and f.name not in own:
                    others.setdefault(f.name, _LISTED_DEFAULTS.get(f.name, f.default))
        taken = {}
        for key, value in fields.items():
            if key in own:
                taken[key] = value
            elif key in others and value == others[key]:
                continue
            elif key in others:
                raise InputError(f"plant: {key} belongs to another kind of plant, not {kind!r}")
            else:
                raise InputError(
                    f"{key}: unknown key; [simulation.plant] of kind {kind!r} takes kind"
                    + "".join(f", {name}" for name in own)
                )
        return settings_type, taken

    def fields(self) -> dict[str, Any]:
        """The kind's fields (the ``[simulation.plant]`` table besides ``kind``)."""
        return {f.name: getattr(self.settings, f.name) for f in dataclasses.fields(self.settings) if f.init}


def make_plant(
    config: SimConfig, plant: PlantSettings, *, t_a_c: np.ndarray, g_w_per_m2: np.ndarray,
    i_g_w: np.ndarray, times: np.ndarray | None, seed: int | None,
    fleet: FleetBuildings | None = None, n_buildings: int = 1,
    facades: Mapping[str, np.ndarray] | None = None,
) -> LoopPlant:
    """The plant of ``plant``'s kind for a run (:class:`~scenarios.plants.kinds.PlantRequest`
    says what each argument is)."""
    request = PlantRequest(
        config=config, t_a_c=t_a_c, g_w_per_m2=g_w_per_m2, i_g_w=i_g_w, times=times, seed=seed,
        fleet=fleet, n_buildings=n_buildings, facades=facades,
    )
    return plant.plug.make(plant.settings, request)
