"""The scenario's plant (``[simulation.plant]`` of a scenario file): its kind and that kind's
settings, in one table.

``kind`` is one of :data:`PLANT_KINDS`: the RC structures the package's simulator integrates
(``2r2c``, ``3r3c``: :class:`pinn_mpc.plant.Plant`, whose envelope fields the table carries) or
``energyplus`` (:class:`scenarios.plants.energyplus.settings.EnergyPlusSettings`, whose fields
the table carries too). The table's keys are the union of the kinds' fields; those of another
kind keep their defaults (a file ``pinn-mpc scenario export`` wrote lists them all).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar, Literal

from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.plant import RC_KINDS, Plant
from scenarios.plants.energyplus.settings import EnergyPlusSettings, check_settings

__all__ = ["PLANT_KINDS", "PlantSettings"]

#: Every plant kind: the simulator's RC structures, then the plants that run elsewhere.
PLANT_KINDS = (*RC_KINDS, "energyplus")
#: The fields of :class:`EnergyPlusSettings` the table carries.
_ENERGYPLUS_FIELDS = tuple(f.name for f in dataclasses.fields(EnergyPlusSettings))


@dataclass(frozen=True, kw_only=True)
class PlantSettings:
    """The scenario's plant: its kind and the settings of that kind (module docstring)."""

    kind: str = "2r2c"
    envelope_capacity_j_per_k: float = 1.0e7
    envelope_resistance_fraction: float = 0.5
    building: str = ""
    weather: str = ""
    heater_w: float | str = 0.0
    allow_code: bool = False
    zones: Literal["merged", "separate"] = "merged"
    radiant_fraction: float = 0.0
    gains: Literal["unknown", "measured"] = "unknown"
    #: Fields holding a file path, resolved relative to the scenario file that names them.
    PATH_FIELDS: ClassVar[tuple[str, ...]] = EnergyPlusSettings.PATH_FIELDS

    def __post_init__(self) -> None:
        owner = type(self).__name__
        if self.kind not in PLANT_KINDS:
            raise InputError(f"{owner}.kind {self.kind!r} is unknown; choose one of {', '.join(PLANT_KINDS)}")
        if self.is_energyplus:
            check_settings(
                building=self.building, weather=self.weather, heater_w=self.heater_w,
                zones=self.zones, gains=self.gains, radiant_fraction=self.radiant_fraction,
                owner=owner,
            )
        elif (
            self.building or self.weather or self.heater_w or self.allow_code
            or self.zones != "merged" or self.radiant_fraction or self.gains != "unknown"
        ):
            raise InputError(
                "plant: building, weather, heater_w, allow_code, zones, radiant_fraction and "
                f"gains belong to kind = \"energyplus\", not {self.kind!r}"
            )
        try:
            _ = self.rc  # the envelope fields are checked for every kind, as files always were
        except InputError as exc:
            raise InputError(str(exc).replace("Plant.", f"{owner}.")) from None

    @property
    def is_energyplus(self) -> bool:
        return self.kind == "energyplus"

    @property
    def runs_in_simulator(self) -> bool:
        """Whether the package's RC simulator is the plant (``kind`` one of its RC structures)."""
        return self.kind in RC_KINDS

    @property
    def rc(self) -> Plant:
        """The structure the RC simulator integrates (``SimConfig.plant``): the kind's own for
        an RC kind, the default 2R2C for a plant that runs elsewhere (the scenario's nominal
        R/C values describe it)."""
        kind = self.kind if self.kind in RC_KINDS else "2r2c"
        return Plant(
            kind=kind,
            envelope_capacity_j_per_k=self.envelope_capacity_j_per_k,
            envelope_resistance_fraction=self.envelope_resistance_fraction,
        )

    @property
    def energyplus(self) -> EnergyPlusSettings:
        """The EnergyPlus plant's settings (``kind = "energyplus"`` only)."""
        if not self.is_energyplus:
            raise InternalError(f"PlantSettings.energyplus of a {self.kind!r} plant")
        return EnergyPlusSettings(**{name: getattr(self, name) for name in _ENERGYPLUS_FIELDS})

    @classmethod
    def of_energyplus(cls, settings: EnergyPlusSettings) -> PlantSettings:
        """The table of an EnergyPlus plant with ``settings``."""
        return cls(kind="energyplus", **{name: getattr(settings, name) for name in _ENERGYPLUS_FIELDS})

    @classmethod
    def of_rc(cls, plant: Plant) -> PlantSettings:
        """The table of the RC structure ``plant``."""
        return cls(
            kind=plant.kind, envelope_capacity_j_per_k=plant.envelope_capacity_j_per_k,
            envelope_resistance_fraction=plant.envelope_resistance_fraction,
        )
