"""A building of several coupled zones: each zone a 2R2C, their air nodes joined by internal walls.

Zone ``z`` (of Z) is the 2R2C of :mod:`pinn_mpc.physics` with its own R/C values, and its room
air exchanges heat with every other zone's through an internal wall of conductance
``U[z, w]`` [W/K] (symmetric, >= 0, 0 where two zones do not touch)::

    C_r,z dT_r,z/dt = (T_a - T_r,z)/R_ra,z + (T_m,z - T_r,z)/R_rm,z + sum_w U[z,w] (T_r,w - T_r,z)
                      + sum_{a on z} s_a g_a(T_a) p_a + alpha_z A_z S_z + beta_z f_z I_g
    C_m,z dT_m,z/dt = (T_r,z - T_m,z)/R_rm,z + (1 - alpha_z) A_z S_z + (1 - beta_z) f_z I_g

State ``x = (T_r,1 .. T_r,Z, T_m,1 .. T_m,Z)`` [C] (the rooms, then the masses), so
``x[..., :Z]`` are the rooms. One zone is the 2R2C (its matrices to round-off).

**The actuators** (:class:`pinn_mpc.actuator.ActuatorSpec`, any number, each on its
``zone``): actuator ``a`` draws electrical power ``p_a`` in ``[lower_w, upper_w]`` and gives its
zone's air ``s_a g_a(T_a) p_a`` watts of heat, ``s_a`` its sign (+1 heats, -1 cools) and
``g_a`` its heat per electrical watt (:meth:`ActuatorSpec.gain`: 1 for the ideal heater or
chiller, a heat pump's COP at the interval's outdoor temperature). A zone's heat is the sum
over its actuators; a zone may have none (heated only through its walls), one, or a heater and
a cooler. So the zone's ``RCParams.eta`` is not used: the heat per watt is the actuator's,
declared with it, and one zone can hold two machines of different efficiency, which a zone's
one ``eta`` cannot say. A zone's ``eta`` must therefore be left at 1 (anything else is refused
rather than silently ignored); a machine's efficiency other than 1 is its ``Actuator``'s.

**The sun** (``S_z`` above): each zone names the irradiance its windows take
(:attr:`ZoneRC.solar_input`): ``G``, the global horizontal irradiance, as the one-zone 2R2C
has it (its aperture then an effective one), or the irradiance on the facade the zone's
windows face, ``G_south``, ``G_east``, ``G_west`` or ``G_north`` (:mod:`pinn_mpc.solar`; the
aperture then window area x g-value). Both, zone by zone, because zones differ in which facade
they face more than in anything else: a south zone's winter gains are several times what
``G`` times an aperture says in the middle of the day and nothing like it at its ends, and an
east and a west zone take theirs in the morning and in the afternoon, which no split of one
``G`` reproduces; while ``G`` keeps today's buildings (and a weather file without facades)
as they are. **The internal gains** ``I_g`` [W] (occupants, appliances) are the building's,
split over the zones by shares ``f_z`` (:attr:`ZoneRC.gain_share`, summing to 1).

The input matrices take the exogenous inputs in the order :data:`EXOGENOUS_NAMES`
``(T_a, G, I_g, G_south, G_east, G_west, G_north)`` (the 2R2C's ``(T_a, G, I_g)`` first) and
the actuators' electrical power at heat per watt 1 (:func:`continuous_matrices`, for one
building, as numpy arrays): the RC MPC on the true building plans on the same matrices, with
the actuator's column scaled by its heat per watt on each step's forecast, as the 2R2C's
planners do (:mod:`pinn_mpc.actuator`). :func:`discretise` is their exact zero-order hold,
:func:`steady_state` the equilibrium for constant inputs.

:class:`MultiZoneSimulator` steps B buildings (one :class:`MultiZoneParams`, or a fleet of
them with one zone layout) one control interval in substeps, with a backup thermostat per
actuator re-evaluated at the start of each substep as in :mod:`pinn_mpc.simulator`
(:func:`backup_power`): a heater at full power while its zone is below the zone's low limit
and off above its high limit, a cooler mirrored, so a zone with both is a dual-setpoint
thermostat. The substep loop is numpy over the buildings (``benchmarks/bench_multizone.py``
measures it; no compiled kernel was needed).

Misuse of this API (a negative conductance, an actuator on a zone the building does not have,
an array of the wrong shape) is a ValueError naming the field, the value and the fix.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import scipy.linalg

from pinn_mpc.actuator import ActuatorSpec, actuator_columns
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.physics import PLAUSIBLE_RANGES, RCParams
from pinn_mpc.simulator import draw_fleet
from pinn_mpc.solar import FACADE_COLUMNS
from pinn_mpc.zones import ZoneSpec, zone_columns

__all__ = [
    "EXOGENOUS_NAMES",
    "MAX_WALL_CONDUCTANCE_W_PER_K",
    "SOLAR_INPUTS",
    "MultiZoneConfig",
    "MultiZoneParams",
    "MultiZoneSimulator",
    "MultiZoneStep",
    "SystemMatrices",
    "ZoneRC",
    "backup_power",
    "continuous_matrices",
    "discretise",
    "draw_zoned_fleet",
    "history_arrays",
    "needed_inputs",
    "steady_state",
    "wall_tuples",
]

#: The irradiance a zone's windows may take [W/m2]: the global horizontal, or a facade's.
SOLAR_INPUTS = ("G", *FACADE_COLUMNS)
#: The exogenous inputs of the input matrices, in their columns' order (the 2R2C's first).
EXOGENOUS_NAMES = ("T_a", "G", "I_g", *FACADE_COLUMNS)
#: The largest internal-wall conductance [W/K]: the inverse of the smallest plausible
#: resistance (:data:`pinn_mpc.physics.PLAUSIBLE_RANGES`); above it a value is in the wrong unit.
MAX_WALL_CONDUCTANCE_W_PER_K = 1.0 / PLAUSIBLE_RANGES["r_ra_k_per_w"][0]


@dataclass(frozen=True, kw_only=True)
class ZoneRC:
    """One zone of a multi-zone building: its name (``zone``), its 2R2C (``rc``: R/C values,
    solar aperture [m2] and fractions; ``eta`` left at 1, the heat per watt is the actuators'),
    the irradiance its windows take (``solar_input``, one of :data:`SOLAR_INPUTS`) and its share
    of the building's internal gains (``gain_share``, in [0, 1])."""

    zone: ZoneSpec
    rc: RCParams
    gain_share: float
    solar_input: str = "G"

    def __post_init__(self) -> None:
        name = f"ZoneRC({self.zone.name if isinstance(self.zone, ZoneSpec) else self.zone!r})"
        if not isinstance(self.zone, ZoneSpec):
            raise TypeError(f"{name}.zone must be a ZoneSpec, got {type(self.zone).__name__}")
        if not isinstance(self.rc, RCParams):
            raise TypeError(f"{name}.rc must be an RCParams, got {type(self.rc).__name__}")
        if self.rc.eta != 1.0:
            raise ValueError(
                f"{name}.rc.eta = {self.rc.eta:g}: a zone's heat per watt is its actuators' "
                "(ActuatorSpec.heats and efficiency); leave eta at 1"
            )
        if self.solar_input not in SOLAR_INPUTS:
            raise ValueError(
                f"{name}.solar_input = {self.solar_input!r} is unknown; choose one of "
                f"{', '.join(SOLAR_INPUTS)}"
            )
        share = self.gain_share
        if isinstance(share, bool) or not (
            isinstance(share, int | float) and math.isfinite(share) and 0.0 <= share <= 1.0
        ):
            raise ValueError(f"{name}.gain_share = {share!r} must lie in [0, 1]")


@dataclass(frozen=True, kw_only=True)
class MultiZoneParams:
    """A building of Z zones (:class:`ZoneRC`, in order; names unique) and the conductance
    [W/K] of the internal walls between their air nodes, ``wall_conductance_w_per_k`` (Z, Z):
    symmetric, >= 0, zero on the diagonal (any nested sequence or array; kept as tuples).
    The zones' internal-gain shares sum to 1."""

    zones: tuple[ZoneRC, ...]
    wall_conductance_w_per_k: tuple[tuple[float, ...], ...]

    def __post_init__(self) -> None:
        zones = tuple(self.zones) if isinstance(self.zones, list | tuple) else self.zones
        if not isinstance(zones, tuple) or not zones:
            raise ValueError(f"MultiZoneParams.zones must be a non-empty tuple of ZoneRC, got {self.zones!r}")
        wrong = [i for i, z in enumerate(zones) if not isinstance(z, ZoneRC)]
        if wrong:
            raise TypeError(f"MultiZoneParams.zones[{wrong[0]}] is a {type(zones[wrong[0]]).__name__}, not a ZoneRC")
        names = [z.zone.name for z in zones]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"MultiZoneParams.zones: zone name(s) {twice} appear more than once; name each zone once")
        total = math.fsum(z.gain_share for z in zones)
        if abs(total - 1.0) > 1e-9:
            raise ValueError(
                f"MultiZoneParams.zones: the gain shares sum to {total:.6g} "
                f"({', '.join(f'{n}: {z.gain_share:g}' for n, z in zip(names, zones, strict=True))}); "
                "they split the building's internal gains, so they must sum to 1"
            )
        object.__setattr__(self, "zones", zones)
        object.__setattr__(self, "wall_conductance_w_per_k", _checked_walls(self.wall_conductance_w_per_k, names))

    @property
    def n_zones(self) -> int:
        return len(self.zones)

    @property
    def zone_specs(self) -> tuple[ZoneSpec, ...]:
        """The zones' :class:`~pinn_mpc.zones.ZoneSpec`, in order."""
        return tuple(z.zone for z in self.zones)

    @property
    def walls(self) -> np.ndarray:
        """(Z, Z) the internal walls' conductance [W/K]."""
        return np.array(self.wall_conductance_w_per_k, dtype=float).reshape(self.n_zones, self.n_zones)

    def wall_pairs(self) -> dict[tuple[str, str], float]:
        """``{(zone, zone): U [W/K]}`` of every wall with a conductance > 0 (each pair once,
        in the zones' order)."""
        names = [z.name for z in self.zone_specs]
        u = self.walls
        return {
            (names[i], names[j]): float(u[i, j])
            for i in range(len(names)) for j in range(i + 1, len(names)) if u[i, j] > 0
        }

    def lumped(self) -> RCParams:
        """The one 2R2C of the building with its zones merged (the limit of infinitely
        conductive internal walls): conductances and capacities summed, the solar aperture
        summed (every zone's windows counted as taking ``G``) and the fractions weighted by
        what they split. Its steady state with every zone at one temperature is the
        building's; it is the nominal building a one-zone view of it assumes."""
        rcs = [z.rc for z in self.zones]
        aperture = math.fsum(rc.solar_aperture_m2 for rc in rcs)
        solar_air = (
            math.fsum(rc.solar_aperture_m2 * rc.solar_to_air_fraction for rc in rcs) / aperture
            if aperture > 0
            else 0.0
        )
        return RCParams(
            r_ra_k_per_w=1.0 / math.fsum(1.0 / rc.r_ra_k_per_w for rc in rcs),
            r_rm_k_per_w=1.0 / math.fsum(1.0 / rc.r_rm_k_per_w for rc in rcs),
            c_r_j_per_k=math.fsum(rc.c_r_j_per_k for rc in rcs),
            c_m_j_per_k=math.fsum(rc.c_m_j_per_k for rc in rcs),
            solar_aperture_m2=aperture,
            solar_to_air_fraction=solar_air,
            gain_to_air_fraction=math.fsum(z.gain_share * z.rc.gain_to_air_fraction for z in self.zones),
        )


def draw_zoned_fleet(
    base: MultiZoneParams, n_buildings: int, *, spread: float, rng: np.random.Generator
) -> tuple[MultiZoneParams, ...]:
    """``n_buildings`` buildings around ``base``, drawn as
    :func:`pinn_mpc.simulator.draw_fleet` draws one-zone buildings: each zone's
    :data:`~pinn_mpc.simulator.FLEET_SCALED` values multiplied by their own log-normal factors
    ``exp(spread * N(0, 1))``, and each internal wall's conductance [W/K] by one of its own
    (the same both ways); the zones' fractions, gain shares and windows stay ``base``'s.
    ``spread`` 0 gives copies of ``base``. Per building, the zones are drawn in order, then
    the walls (upper triangle, row by row)."""
    if isinstance(n_buildings, bool) or not isinstance(n_buildings, int) or n_buildings < 1:
        raise ValueError(f"draw_zoned_fleet: n_buildings must be a whole number >= 1, got {n_buildings!r}")
    walls = base.walls
    rows, cols = np.nonzero(np.triu(walls, k=1))
    buildings = []
    for _ in range(n_buildings):
        zones = tuple(
            dataclasses.replace(z, rc=draw_fleet(z.rc, 1, spread=spread, rng=rng)[0]) for z in base.zones
        )
        factors = np.exp(spread * rng.standard_normal(len(rows)))  # (W,) one per wall
        drawn = np.zeros_like(walls)
        drawn[rows, cols] = walls[rows, cols] * factors
        buildings.append(MultiZoneParams(zones=zones, wall_conductance_w_per_k=wall_tuples(drawn + drawn.T)))
    return tuple(buildings)


def wall_tuples(walls: Any) -> tuple[tuple[float, ...], ...]:
    """A (Z, Z) conductance matrix [W/K] (an array or nested sequences) as the tuples
    :class:`MultiZoneParams` keeps (checked there)."""
    return tuple(tuple(float(v) for v in row) for row in np.asarray(walls, dtype=float))


def _checked_walls(value: Any, names: Sequence[str]) -> tuple[tuple[float, ...], ...]:
    """``value`` as a (Z, Z) tuple of tuples, or a ValueError naming the first problem."""
    label = "MultiZoneParams.wall_conductance_w_per_k"
    n = len(names)
    try:
        u = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{label} must be a ({n}, {n}) array of conductances [W/K], got {value!r}") from None
    if u.shape != (n, n):
        raise ValueError(
            f"{label} has shape {u.shape}, but the building has {n} zone(s) ({', '.join(names)}); "
            f"give a ({n}, {n}) array"
        )
    for (i, j), v in np.ndenumerate(u):
        where = f"{label}[{i}, {j}] ({names[i]}-{names[j]})"
        if not math.isfinite(v):
            raise ValueError(f"{where} is {v}, not a finite conductance [W/K]")
        if v < 0:
            raise ValueError(f"{where} = {v:g} W/K is negative; a wall's conductance is >= 0 (0: no wall)")
        if v > MAX_WALL_CONDUCTANCE_W_PER_K:
            raise ValueError(
                f"{where} = {v:.4g} W/K is above the plausible {MAX_WALL_CONDUCTANCE_W_PER_K:.0e} W/K; "
                "give it in W/K"
            )
        if i == j and v != 0:
            raise ValueError(f"{where} = {v:g} W/K: a zone has no wall with itself; set the diagonal to 0")
        if v != u[j, i]:
            raise ValueError(
                f"{where} = {v:g} W/K but [{j}, {i}] = {u[j, i]:g} W/K: a wall conducts the same "
                "both ways; make the array symmetric"
            )
    return tuple(tuple(float(v) for v in row) for row in u)


def _check_actuators(actuators: Sequence[ActuatorSpec], params: MultiZoneParams) -> None:
    for a, spec in enumerate(actuators):
        if not isinstance(spec, ActuatorSpec):
            raise TypeError(f"actuators[{a}] is a {type(spec).__name__}, not an ActuatorSpec")
        if spec.zone >= params.n_zones:
            names = ", ".join(z.zone.name for z in params.zones)
            raise ValueError(
                f"actuators[{a}].zone = {spec.zone} is out of range: the building has "
                f"{params.n_zones} zone(s) ({names}), indices 0 .. {params.n_zones - 1}"
            )


class SystemMatrices(NamedTuple):
    """``dx/dt = a x + b_u p + b_d d`` (continuous) or ``x+ = a x + b_u p + b_d d`` (one
    zero-order-hold step), for x (2Z,) the rooms then the masses [C], p (A,) the actuators'
    electrical power [W] at heat per watt 1 (scale column ``a`` by ``ActuatorSpec.gain``) and
    d (7,) the exogenous inputs in :data:`EXOGENOUS_NAMES` order. With a leading axis P when
    several buildings are discretised together."""

    a: np.ndarray  # (2Z, 2Z)
    b_u: np.ndarray  # (2Z, A)
    b_d: np.ndarray  # (2Z, 7)


def continuous_matrices(params: MultiZoneParams, actuators: Sequence[ActuatorSpec]) -> SystemMatrices:
    """The continuous-time matrices of the building (module docstring) [1/s, K/(W s), ...].

    ``a`` times ``diag(C)`` (the capacities, rooms then masses) is symmetric: the walls and
    the air-to-mass resistances conduct the same both ways."""
    _check_actuators(actuators, params)
    z_n = params.n_zones
    a = np.zeros((2 * z_n, 2 * z_n))
    b_u = np.zeros((2 * z_n, len(actuators)))
    b_d = np.zeros((2 * z_n, len(EXOGENOUS_NAMES)))
    walls = params.walls
    t_a, i_g = EXOGENOUS_NAMES.index("T_a"), EXOGENOUS_NAMES.index("I_g")
    for z, zone in enumerate(params.zones):
        p = zone.rc
        room, mass = z, z_n + z
        to_out, to_mass = 1.0 / p.r_ra_k_per_w, 1.0 / p.r_rm_k_per_w
        a[room, room] = -(to_out + to_mass + walls[z].sum()) / p.c_r_j_per_k
        a[room, mass] = to_mass / p.c_r_j_per_k
        a[room, :z_n] += walls[z] / p.c_r_j_per_k
        a[mass, mass] = -to_mass / p.c_m_j_per_k
        a[mass, room] = to_mass / p.c_m_j_per_k
        b_d[room, t_a] = to_out / p.c_r_j_per_k
        sun = EXOGENOUS_NAMES.index(zone.solar_input)
        b_d[room, sun] = p.solar_to_air_fraction * p.solar_aperture_m2 / p.c_r_j_per_k
        b_d[mass, sun] = (1.0 - p.solar_to_air_fraction) * p.solar_aperture_m2 / p.c_m_j_per_k
        b_d[room, i_g] = p.gain_to_air_fraction * zone.gain_share / p.c_r_j_per_k
        b_d[mass, i_g] = (1.0 - p.gain_to_air_fraction) * zone.gain_share / p.c_m_j_per_k
    for col, spec in enumerate(actuators):
        b_u[spec.zone, col] = spec.sign / params.zones[spec.zone].rc.c_r_j_per_k
    return SystemMatrices(a=a, b_u=b_u, b_d=b_d)


def _discretise_many(
    buildings: Sequence[MultiZoneParams], actuators: Sequence[ActuatorSpec], dt_s: float
) -> SystemMatrices:
    """Exact ZOH of many buildings in one batched exponential of the augmented matrix:
    ``a`` (P, 2Z, 2Z), ``b_u`` (P, 2Z, A), ``b_d`` (P, 2Z, 7)."""
    if isinstance(dt_s, bool) or not (isinstance(dt_s, int | float) and math.isfinite(dt_s) and dt_s > 0):
        raise ValueError(f"dt_s must be a positive number of seconds, got {dt_s!r}")
    mats = [continuous_matrices(p, actuators) for p in buildings]
    n, n_u = mats[0].b_u.shape
    size = n + n_u + len(EXOGENOUS_NAMES)
    m = np.zeros((len(mats), size, size))
    for i, mat in enumerate(mats):
        m[i, :n, :n] = mat.a * dt_s
        m[i, :n, n : n + n_u] = mat.b_u * dt_s
        m[i, :n, n + n_u :] = mat.b_d * dt_s
    e = scipy.linalg.expm(m)
    return SystemMatrices(
        a=np.ascontiguousarray(e[:, :n, :n]),
        b_u=np.ascontiguousarray(e[:, :n, n : n + n_u]),
        b_d=np.ascontiguousarray(e[:, :n, n + n_u :]),
    )


def discretise(params: MultiZoneParams, actuators: Sequence[ActuatorSpec], dt_s: float) -> SystemMatrices:
    """Exact zero-order hold over ``dt_s`` [s] (inputs held): ``x+ = a x + b_u p + b_d d``, the
    exponential of the augmented matrix ``[[A, B], [0, 0]] dt`` (as
    :func:`pinn_mpc.physics.discretise` falls back on)."""
    one = _discretise_many([params], actuators, dt_s)
    return SystemMatrices(a=one.a[0], b_u=one.b_u[0], b_d=one.b_d[0])


def _needed_inputs(buildings: Sequence[MultiZoneParams]) -> tuple[str, ...]:
    """The exogenous inputs a step must be given: the outdoor temperature, the internal gains
    and the irradiance every zone with an aperture takes."""
    suns = {z.solar_input for p in buildings for z in p.zones if z.rc.solar_aperture_m2 > 0}
    return tuple(n for n in EXOGENOUS_NAMES if n in {"T_a", "I_g"} | suns)


def needed_inputs(params: MultiZoneParams) -> tuple[str, ...]:
    """The exogenous inputs (names of :data:`EXOGENOUS_NAMES`, in its order) the building
    takes: T_a, I_g and the irradiance of every zone with windows; the others may be absent
    (0)."""
    return _needed_inputs([params])


def history_arrays(
    history: Mapping[str, Any], params: MultiZoneParams, actuators: Sequence[ActuatorSpec]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A building's past in the data format's names (an observation's history: each zone's
    ``T_r[<zone>]`` (k+1,) up to now, each actuator's delivered ``u_phys[<name>]`` (k,), the
    inputs (k+1,)) as arrays: the rooms (k+1, Z) [C], the delivered powers (k, A) [W] and the
    exogenous inputs (k+1, 7) in :data:`EXOGENOUS_NAMES` order, 0 for those the building does
    not take. An :class:`~pinn_mpc.errors.InputError` names the columns it lacks."""
    rooms_at = zone_columns("T_r", params.zone_specs)
    powers_at = actuator_columns("u_phys", actuators)
    needed = needed_inputs(params)
    k = len(history[rooms_at[0]]) - 1 if rooms_at[0] in history else 0
    missing = [c for c in rooms_at if c not in history]
    missing += [c for c in powers_at if k > 0 and c not in history]
    missing += [n for n in needed if n not in history]
    if missing or k < 0:
        raise InputError(
            f"the history lacks {missing or rooms_at}: a multi-zone building's state needs each zone's "
            f"room temperature ({', '.join(rooms_at)}) up to now, each actuator's delivered power "
            f"({', '.join(powers_at)}) and the building's inputs ({', '.join(needed)})"
        )
    rooms = np.stack([np.asarray(history[c], dtype=float)[-(k + 1) :] for c in rooms_at], axis=1)
    powers = np.zeros((k, len(powers_at)))
    for i, c in enumerate(powers_at):
        if k > 0:
            powers[:, i] = np.asarray(history[c], dtype=float)[-k:]
    inputs = np.zeros((k + 1, len(EXOGENOUS_NAMES)))
    for name in needed:
        inputs[:, EXOGENOUS_NAMES.index(name)] = np.asarray(history[name], dtype=float)[-(k + 1) :]
    return rooms, powers, inputs


def _exogenous(weather: Mapping[str, Any], needed: Sequence[str], n_buildings: int) -> np.ndarray:
    """(B, 7) exogenous inputs in :data:`EXOGENOUS_NAMES` order from ``weather`` (name -> a
    number or (B,)); the names not needed and not given are 0."""
    unknown = sorted(set(weather) - set(EXOGENOUS_NAMES))
    if unknown:
        raise ValueError(f"weather: unknown input(s) {unknown}; the inputs are {', '.join(EXOGENOUS_NAMES)}")
    missing = [n for n in needed if n not in weather]
    if missing:
        raise ValueError(
            f"weather lacks {missing}: the building needs {', '.join(needed)} (T_a, I_g, and the "
            "irradiance each zone with windows takes); give them, 0 where there is none"
        )
    d = np.zeros((n_buildings, len(EXOGENOUS_NAMES)))
    for name, value in weather.items():
        v = np.asarray(value, dtype=float)
        if v.shape not in ((), (n_buildings,)):
            raise ValueError(f"weather[{name!r}] has shape {v.shape}; give a number or ({n_buildings},), one per building")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"weather[{name!r}] has non-finite values")
        d[:, EXOGENOUS_NAMES.index(name)] = v
    return d


def _gains(actuators: Sequence[ActuatorSpec], t_a_c: np.ndarray) -> np.ndarray:
    """(B, A) each actuator's heat per electrical watt at the outdoor temperatures (B,)."""
    if not actuators:
        return np.zeros((t_a_c.shape[0], 0))
    return np.stack([spec.gain(t_a_c) for spec in actuators], axis=-1)


def steady_state(
    params: MultiZoneParams,
    actuators: Sequence[ActuatorSpec],
    *,
    power_w: Sequence[float] | np.ndarray,
    weather: Mapping[str, float],
) -> tuple[np.ndarray, np.ndarray]:
    """The equilibrium ``(T_r (Z,), T_m (Z,))`` [C] for constant inputs: each actuator's
    electrical power ``power_w`` (A,) [W] and ``weather`` (name -> number, the names of
    :data:`EXOGENOUS_NAMES`; T_a, I_g and each zone's irradiance required): solves
    ``A x + B_u (g p) + B_d d = 0``, g the actuators' heat per watt at T_a."""
    mats = continuous_matrices(params, actuators)
    p = _power_array(power_w, 1, len(actuators))
    d = _exogenous(weather, _needed_inputs([params]), 1)
    forcing = mats.b_u @ (_gains(actuators, d[:, 0]) * p)[0] + mats.b_d @ d[0]
    x = np.linalg.solve(mats.a, -forcing)
    return x[: params.n_zones], x[params.n_zones :]


def _power_array(power_w: Any, n_buildings: int, n_actuators: int) -> np.ndarray:
    """(B, A) from a number, (A,) or (B, A); a ValueError names a shape that is none of them."""
    p = np.asarray(power_w, dtype=float)
    if p.shape not in ((), (n_actuators,), (n_buildings, n_actuators)):
        raise ValueError(
            f"power_w has shape {p.shape}; give one power per actuator, ({n_actuators},) or "
            f"({n_buildings}, {n_actuators}) for {n_buildings} building(s)"
        )
    return np.broadcast_to(p, (n_buildings, n_actuators))


def _per_zone(value: Any, n_zones: int, name: str) -> np.ndarray:
    """(Z,) from a number or a sequence of Z numbers, or a ValueError naming ``name``."""
    v = np.asarray(value, dtype=float)
    if v.shape not in ((), (n_zones,)) or not np.all(np.isfinite(v)):
        raise ValueError(f"MultiZoneConfig.{name} = {value!r} must be a number or {n_zones} finite numbers (one per zone)")
    return np.broadcast_to(v, (n_zones,))


@dataclass(frozen=True, kw_only=True)
class MultiZoneConfig:
    """A multi-zone simulation: the building (``params``), its actuators (each on a zone of it),
    the control interval ``dt_s`` and substep ``substep_s`` [s], the backup thermostat's limits
    [C] (one for every zone, or a tuple of one per zone) and the sensor noise [K] of each
    zone's room temperature. The defaults are :class:`pinn_mpc.simulator.SimConfig`'s."""

    params: MultiZoneParams
    actuators: tuple[ActuatorSpec, ...]
    dt_s: float = 1800.0
    substep_s: float = 60.0
    backup_low_c: float | tuple[float, ...] = 17.0
    backup_high_c: float | tuple[float, ...] = 20.5
    noise_std_c: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.params, MultiZoneParams):
            raise TypeError(f"MultiZoneConfig.params must be a MultiZoneParams, got {type(self.params).__name__}")
        object.__setattr__(self, "actuators", tuple(self.actuators))
        _check_actuators(self.actuators, self.params)
        for name in ("dt_s", "substep_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ValueError(f"MultiZoneConfig.{name} must be a positive number of seconds, got {v!r}")
        ratio = self.dt_s / self.substep_s
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(f"MultiZoneConfig.dt_s = {self.dt_s} must be a whole multiple of substep_s = {self.substep_s}")
        low, high = self.backup_limits_c
        bad = np.flatnonzero(~(low < high))
        if bad.size:
            z = int(bad[0])
            raise ValueError(
                f"MultiZoneConfig backup limits of zone {self.params.zones[z].zone.name!r} must satisfy "
                f"low < high, got {low[z]:g} / {high[z]:g}"
            )
        noise = self.noise_std_c
        if isinstance(noise, bool) or not (isinstance(noise, int | float) and math.isfinite(noise) and noise >= 0):
            raise ValueError(f"MultiZoneConfig.noise_std_c must be >= 0 [K], got {noise!r}")

    @property
    def n_substeps(self) -> int:
        return round(self.dt_s / self.substep_s)

    @property
    def backup_limits_c(self) -> tuple[np.ndarray, np.ndarray]:
        """(low (Z,), high (Z,)) each zone's backup-thermostat limits [C]."""
        z_n = self.params.n_zones
        return _per_zone(self.backup_low_c, z_n, "backup_low_c"), _per_zone(self.backup_high_c, z_n, "backup_high_c")


class MultiZoneStep(NamedTuple):
    """One control interval of B buildings of Z zones and A actuators (true states)."""

    t_r_c: np.ndarray  # (B, Z) each zone's room temperature at the interval's end [C]
    t_m_c: np.ndarray  # (B, Z) each zone's thermal-mass temperature at the interval's end [C]
    power_w: np.ndarray  # (B, A) each actuator's mean delivered electrical power [W]
    overridden: np.ndarray  # (B, A) bool, the backup changed its demand in some substep
    t_r_sub_c: np.ndarray  # (B, S, Z) each zone's room temperature at each substep's end [C]


class _Backup(NamedTuple):
    """The backup thermostat's arrays, per actuator (A,): its zone, mode, bounds and its zone's
    limits."""

    zone: np.ndarray
    heats: np.ndarray
    lower_w: np.ndarray
    upper_w: np.ndarray
    low_c: np.ndarray
    high_c: np.ndarray

    @classmethod
    def of(cls, config: MultiZoneConfig) -> _Backup:
        specs = config.actuators
        zone = np.array([s.zone for s in specs], dtype=int)
        low, high = config.backup_limits_c
        return cls(
            zone=zone,
            heats=np.array([s.heats for s in specs], dtype=bool),
            lower_w=np.array([s.lower_w for s in specs], dtype=float),
            upper_w=np.array([s.upper_w for s in specs], dtype=float),
            low_c=low[zone],
            high_c=high[zone],
        )

    def power(self, t_r_c: np.ndarray, demand_w: np.ndarray) -> np.ndarray:
        t = t_r_c[:, self.zone]
        too_cold, too_warm = t < self.low_c, t > self.high_c
        force_on = np.where(self.heats, too_cold, too_warm)
        force_off = np.where(self.heats, too_warm, too_cold)
        return np.where(force_on, self.upper_w, np.where(force_off, self.lower_w, demand_w))


def backup_power(t_r_c: np.ndarray, demand_w: np.ndarray, config: MultiZoneConfig) -> np.ndarray:
    """The backup thermostat (paper Eq. backup) per actuator: ``t_r_c`` (B, Z) the zones' room
    temperatures, ``demand_w`` (B, A) -> (B, A) [W]. A heater runs at ``upper_w`` while its
    zone is below the zone's low limit and at ``lower_w`` above its high limit; a cooler the
    other way round; between the limits each runs at its demand."""
    return _Backup.of(config).power(np.asarray(t_r_c, dtype=float), np.asarray(demand_w, dtype=float))


class MultiZoneSimulator:
    """B multi-zone buildings stepping together; seeded and deterministic.

    ``fleet`` gives each building its own :class:`MultiZoneParams` with the zones of
    ``config.params`` (same names, in order); without it all share ``config.params``. The
    actuators and the backup limits of ``config`` apply to every building. ``reset`` sets the
    state, ``step`` advances one control interval, ``measure`` reads each zone's room
    temperature as a sensor does (with noise when ``noise_std_c > 0``)."""

    def __init__(
        self,
        config: MultiZoneConfig,
        *,
        n_buildings: int | None = None,
        seed: int | None = 0,
        fleet: Sequence[MultiZoneParams] | None = None,
    ):
        buildings = [config.params] if fleet is None else list(fleet)
        if fleet is not None:
            if not buildings:
                raise ValueError("MultiZoneSimulator: the fleet is empty; give at least one building")
            if n_buildings is not None and n_buildings != len(buildings):
                raise ValueError(
                    f"MultiZoneSimulator: n_buildings={n_buildings} but the fleet has {len(buildings)} "
                    "buildings; give one of them"
                )
            layout = config.params.zone_specs
            other = [i for i, p in enumerate(buildings) if p.zone_specs != layout]
            if other:
                names = ", ".join(z.name for z in layout)
                raise ValueError(
                    f"MultiZoneSimulator: fleet building(s) {other[:5]} have other zones than "
                    f"config.params ({names}); every building has the same zones, in order"
                )
            n_buildings = len(buildings)
        n_buildings = 1 if n_buildings is None else n_buildings
        if isinstance(n_buildings, bool) or not isinstance(n_buildings, int) or n_buildings < 1:
            raise ValueError(f"MultiZoneSimulator: n_buildings must be a whole number >= 1, got {n_buildings!r}")
        self.config = config
        self.n_buildings = n_buildings
        self.n_zones = config.params.n_zones
        # (P, ...) with P = 1 when every building is config.params.
        self._mats = _discretise_many(buildings, config.actuators, config.substep_s)
        self._needed = _needed_inputs(buildings)
        self._backup = _Backup.of(config)
        self._min_power_w = np.array([s.min_power_w for s in config.actuators], dtype=float)
        self._rng = np.random.default_rng(seed)
        self._x = np.zeros((n_buildings, 2 * self.n_zones))

    def reset(self, t_r_c: Any, t_m_c: Any, *, seed: int | None = None) -> None:
        """Set the state: ``t_r_c`` and ``t_m_c`` [C] each a number, (Z,) or (B, Z); reseed
        the noise if ``seed``."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        shape = (self.n_buildings, self.n_zones)
        parts = []
        for name, value in (("t_r_c", t_r_c), ("t_m_c", t_m_c)):
            v = np.asarray(value, dtype=float)
            if v.shape not in ((), (self.n_zones,), shape) or not np.all(np.isfinite(v)):
                raise ValueError(
                    f"MultiZoneSimulator.reset: {name} has shape {v.shape}; give finite numbers, "
                    f"a number, ({self.n_zones},) or {shape}"
                )
            parts.append(np.broadcast_to(v, shape))
        self._x = np.concatenate(parts, axis=1)

    @property
    def state(self) -> np.ndarray:
        """(B, 2Z) the true state, the rooms then the masses [C] (the matrices' order)."""
        return self._x.copy()

    def measure(self) -> np.ndarray:
        """(B, Z) each zone's measured room temperature [C]."""
        t_r = self._x[:, : self.n_zones].copy()
        if self.config.noise_std_c > 0:
            t_r += self._rng.normal(0.0, self.config.noise_std_c, size=t_r.shape)
        return t_r

    def step(self, power_w: Any, weather: Mapping[str, Any]) -> MultiZoneStep:
        """Advance one control interval, inputs held: ``power_w`` each actuator's demanded
        electrical power [W], a number, (A,) or (B, A) (clipped to its bounds); ``weather``
        name -> a number or (B,): T_a [C], I_g [W], and the irradiance [W/m2] each zone with
        windows takes (:data:`EXOGENOUS_NAMES`)."""
        cfg = self.config
        n_b, z_n, n_sub = self.n_buildings, self.n_zones, cfg.n_substeps
        demand = _power_array(power_w, n_b, len(cfg.actuators))
        if not np.all(np.isfinite(demand)):
            raise InternalError("MultiZoneSimulator.step: demanded power power_w has non-finite values")
        backup, min_power = self._backup, self._min_power_w
        lower = backup.lower_w
        demand = np.clip(demand, lower, backup.upper_w)
        d = _exogenous(weather, self._needed, n_b)
        gain = _gains(cfg.actuators, d[:, 0])
        # Below its minimum modulation a machine cycles: on at the minimum for the first
        # n_on substeps, then off (the 2R2C kernel's rule, pinn_mpc.substeps).
        cycling = (lower < demand) & (demand < min_power)
        n_on = np.where(cycling, np.rint(demand / np.where(cycling, min_power, 1.0) * n_sub), -1)
        ad, bu, bd = self._mats
        shared = ad.shape[0] == 1
        # The exogenous inputs are held over the interval: one constant per state.
        forced = d @ bd[0].T if shared else (bd @ d[:, :, None])[:, :, 0]
        x = self._x.copy()
        total = np.zeros_like(demand)
        overridden = np.zeros(demand.shape, dtype=bool)
        t_r_sub = np.empty((n_b, n_sub, z_n))
        for j in range(n_sub):
            wanted = np.where(cycling, np.where(j < n_on, min_power, lower), demand)
            p = backup.power(x[:, :z_n], wanted)
            overridden |= p != wanted
            total += p
            heat = gain * p
            if shared:
                x = x @ ad[0].T + heat @ bu[0].T + forced
            else:
                x = (ad @ x[:, :, None] + bu @ heat[:, :, None])[:, :, 0] + forced
            t_r_sub[:, j] = x[:, :z_n]
        self._x = x
        return MultiZoneStep(
            t_r_c=x[:, :z_n].copy(),
            t_m_c=x[:, z_n:].copy(),
            power_w=total / n_sub,
            overridden=overridden,
            t_r_sub_c=t_r_sub,
        )

