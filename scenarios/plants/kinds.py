"""The registry of plant kinds: the one place a plant's kind is looked up.

A kind is a :class:`PlantKind`: its name (``[simulation.plant] kind`` of a scenario file), its
settings type (the table's other keys, a :class:`KindSettings`), its factory (the
:class:`~scenarios.plants.base.LoopPlant` for a run) and what it can do: whether it has a true
state (an oracle and a clairvoyant can run on it), whether it runs fleets of buildings with
their own parameters, whether its episodes start at midnight only. What a kind knows in
advance of a run (a weather file of its own, its holiday calendar, the gains its schedules
deliver, whether those gains are measured, whether its heater is sized when read, the
simulator structure that describes it) its settings answer (:class:`KindSettings`).

The built-in kinds register themselves where they are implemented: the RC simulator's
structures ``2r2c`` and ``3r3c`` (:mod:`scenarios.plants.rc`), the coupled zones'
``multizone`` (:mod:`scenarios.plants.multizone`), ``energyplus``
(:mod:`scenarios.plants.energyplus.kind`). Code outside this layer asks a scenario's
:class:`~scenarios.plants.settings.PlantSettings` what its kind can do, never which kind it
is; a new kind is one module that calls :func:`register`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

import numpy as np

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.multizone import MultiZoneParams
from pinn_mpc.physics import RCParams
from pinn_mpc.plant import Plant
from pinn_mpc.simulator import SimConfig
from pinn_mpc.zones import ONE_ZONE, ZoneSpec
from scenarios.plants.base import LoopPlant

__all__ = [
    "ActuatorSizing",
    "FleetBuildings",
    "KindSettings",
    "PlantKind",
    "PlantRequest",
    "kind_names",
    "plant_kind",
    "register",
]


#: The buildings of a fleet, each its own: one-zone RC parameters, or buildings of several
#: zones (:class:`~pinn_mpc.multizone.MultiZoneParams`) for a plant of zones.
FleetBuildings = Sequence[RCParams] | Sequence[MultiZoneParams]


class ActuatorSizing(Protocol):
    """An actuator sized for a plant: its power [W] and one line saying how it was sized."""

    @property
    def power_w(self) -> float: ...

    def line(self) -> str: ...


@dataclass(frozen=True, kw_only=True)
class KindSettings:
    """A kind's own settings (the ``[simulation.plant]`` keys besides ``kind``), and what the
    kind knows in advance of a run. The defaults are those of a plant that knows nothing in
    advance (the RC simulator): a subclass answers for its kind."""

    #: Fields holding a file path, resolved relative to the scenario file that names them.
    PATH_FIELDS: ClassVar[tuple[str, ...]] = ()

    @property
    def weather_file(self) -> str | None:
        """The weather file the plant runs on (a bundled name or a path), which the
        scenario's weather must then be; None for a plant driven by the scenario's weather."""
        return None

    @property
    def measured_gains(self) -> bool:
        """Whether the building's internal gains are measured: the past gains a controller
        sees are the plant's interval means, and its schedules forecast them."""
        return False

    @property
    def own_gains(self) -> bool:
        """Whether the building has internal gains of its own besides the scenario's series (an
        EnergyPlus building's people, lights and equipment), which its controllers see only
        where they are measured (:attr:`measured_gains`)."""
        return False

    @property
    def zone_specs(self) -> tuple[ZoneSpec, ...]:
        """The building's zones (:mod:`pinn_mpc.zones`): one, unless the kind has several."""
        return ONE_ZONE

    @property
    def zone_adjacency(self) -> np.ndarray | None:
        """(Z, Z) bools, True where two of :attr:`zone_specs` share a surface (the internal walls
        an identification fits); None: not known in advance (every pair may)."""
        return None

    @property
    def zone_shares(self) -> tuple[float, ...]:
        """Each of :attr:`zone_specs`' share of the building (summing to 1), by which a merged
        one-zone control weighs the zones (:class:`controllers.merged.MergedView`): the floor
        area's where the kind knows it, else equal."""
        n_zones = len(self.zone_specs)
        return (1.0 / n_zones,) * n_zones

    @property
    def own_actuators(self) -> tuple[ActuatorSpec, ...] | None:
        """The actuators the plant declares (a building of several zones), which the control
        spec then holds; None: the scenario's one actuator (``SimConfig.actuators``)."""
        return None

    @property
    def needs_facades(self) -> bool:
        """Whether the plant takes the irradiance on the facades (a zone whose windows face
        one), which a run of it must then carry (:data:`pinn_mpc.solar.FACADE_COLUMNS`)."""
        return False

    @property
    def zone_solar_inputs(self) -> tuple[str | None, ...] | None:
        """The irradiance each of :attr:`zone_specs`' windows take (``G`` or one of
        :data:`pinn_mpc.solar.FACADE_COLUMNS`; None for a zone without windows) where the kind
        knows it; None: not known (each zone's aperture on ``G`` is identified)."""
        return None

    @property
    def rc_errs_hours_ahead(self) -> bool:
        """Whether an RC identified from the plant's data errs hours ahead by its structure (a
        building simulated in detail, not an RC of the identified structure): measured without
        noise, a learned model's fallback RC MPC then plans inside the band by its RC's
        filtered replay error while the forecast is colder than its data
        (:func:`scenarios.running.factory.cold_fallback_margin`). False: the RC simulator."""
        return False

    @property
    def sized_when_read(self) -> bool:
        """Whether the plant's actuator is sized when the scenario is read
        (:func:`scenarios.inputs.registry.with_sized_heater`)."""
        return False

    def size_actuator(self, setpoint_c: float, *, heat_per_w: float, dt_s: float) -> ActuatorSizing:
        """The actuator the plant needs to hold ``setpoint_c`` (:attr:`sized_when_read`)."""
        raise InternalError(f"{type(self).__name__}: this plant's actuator is not sized when read")

    @property
    def sizes_own_actuators(self) -> bool:
        """Whether what is sized when read (:attr:`sized_when_read`) is the plant's own
        actuators (:attr:`own_actuators`, :meth:`size_own_actuators`) rather than the
        scenario's one (:meth:`size_actuator`)."""
        return False

    def size_own_actuators(
        self, *, heating_c: float, cooling_c: float, dt_s: float
    ) -> tuple[KindSettings, tuple[ActuatorSizing, ...]]:
        """These settings with the plant's own actuators sized: the heaters to hold
        ``heating_c``, the coolers ``cooling_c`` [C]; and one sizing per kind sized."""
        raise InternalError(f"{type(self).__name__}: this plant's own actuators are not sized when read")

    def holidays(self, times: np.ndarray) -> np.ndarray | None:
        """(N,) 1.0 where the interval starting at ``times`` falls on one of the building's
        holidays, else 0.0; None for a plant without a calendar."""
        return None

    def scheduled_gains(
        self, times: np.ndarray, *, setpoint_c: float, dt_s: float, heat_per_w: float
    ) -> np.ndarray | None:
        """(N,) the internal gains [W] the building's own schedules deliver in the intervals
        starting at ``times`` (a plant whose gains are measured); None otherwise."""
        return None


@dataclass(frozen=True, kw_only=True)
class PlantRequest:
    """What a kind's factory is given for one run: the simulation settings, the exogenous rows
    the run is driven by (N,) each (a plant with weather of its own ignores them), the
    interval starts ``times`` (N,) (None without dates), the sensor's ``seed``, the
    buildings: their own parameters (``fleet``, :data:`FleetBuildings`), or ``n_buildings`` of the scenario's, and
    the facades' irradiance (name -> (N,), where the run has it)."""

    config: SimConfig
    t_a_c: np.ndarray
    g_w_per_m2: np.ndarray
    i_g_w: np.ndarray
    times: np.ndarray | None
    seed: int | None
    fleet: FleetBuildings | None = None
    n_buildings: int = 1
    facades: Mapping[str, np.ndarray] | None = None


@dataclass(frozen=True, kw_only=True)
class PlantKind:
    """A plant kind (module docstring). ``structure`` gives the simulator structure of its
    settings (:class:`pinn_mpc.plant.Plant`: the kind's own for an RC kind, the 2R2C whose
    nominal R/C values describe a plant that runs elsewhere); ``make`` its plant for a run;
    ``complete_file`` (None: nothing) fills in what a scenario file of this kind may leave out
    because the plant gives it, on the file's parsed data (plain tables), with a function that
    resolves a path written in the file."""

    name: str
    summary: str
    settings_type: type[KindSettings]
    make: Callable[[KindSettings, PlantRequest], LoopPlant]
    structure: Callable[[KindSettings], Plant]
    true_state: bool
    fleets: bool
    starts_at_midnight: bool = False
    complete_file: Callable[[dict[str, Any], Callable[[str], str]], None] | None = None


_KINDS: dict[str, PlantKind] = {}


def register(kind: PlantKind) -> PlantKind:
    """Add ``kind`` to the registry (once per name) and return it."""
    if kind.name in _KINDS and _KINDS[kind.name] != kind:
        raise InternalError(f"plant kind {kind.name!r} is registered twice")
    _KINDS[kind.name] = kind
    return kind


def _builtins() -> None:
    """Register the built-in kinds (their modules register on import; light: no engine)."""
    import scenarios.plants.energyplus.kind  # noqa: F401
    import scenarios.plants.multizone  # noqa: F401
    import scenarios.plants.rc  # noqa: F401


#: The built-in kinds, in the order they are listed.
_BUILTIN_ORDER = ("2r2c", "3r3c", "energyplus", "multizone")


def kind_names() -> tuple[str, ...]:
    """Every registered kind's name, the built-ins first."""
    _builtins()
    return (*_BUILTIN_ORDER, *(name for name in _KINDS if name not in _BUILTIN_ORDER))


def plant_kind(name: str) -> PlantKind:
    """The registered kind ``name``; InputError naming the kinds if there is none."""
    _builtins()
    if name not in _KINDS:
        raise InputError(f"plant kind {name!r} is unknown; choose one of {', '.join(kind_names())}")
    return _KINDS[name]
