"""Grey-box identification of a multi-zone RC building (:mod:`pinn_mpc.multizone`) from data in
which the thermal masses are hidden.

Output-error method, as :mod:`pinn_mpc.identify` for one zone: the building's exact zero-order
hold is simulated over the whole data set from each zone's measured ``T_r[0]`` and an unknown
``T_m0``, the inputs held over each interval, and the simulated room temperatures of every
zone are fitted to the measured ones by :func:`scipy.optimize.least_squares` in
log-parameters. The matrices are :func:`pinn_mpc.multizone.continuous_matrices`'; the
simulation runs in the network's modes (``C^(1/2) A C^(-1/2)`` is symmetric, so its
eigenvalues are real and its eigenvectors orthogonal), one first-order recursion per mode.

**Known**: each actuator's electrical power (a column per actuator, its interval mean) and its
heat per watt (:meth:`pinn_mpc.actuator.ActuatorSpec.gain` at the interval's ``T_a``, with its
sign), the outdoor temperature ``T_a``, the irradiance each zone's windows take (``G`` or a
facade's) and the building's internal gains ``I_g``. The heat per watt being known fixes the
scale: each zone's ``C_r`` follows from how fast its heaters move its air.

**Unknown**, per zone: ``R_ra, R_rm, C_r, C_m``, the hidden ``T_m0``, and, as
:func:`~pinn_mpc.identify.identify_rc` does, the solar aperture and its fraction to the air
when the zone's irradiance column varies, the internal gains' fraction to the air when
``I_g`` varies; per pair of zones given as touching, the internal wall's conductance
``U >= 0``. **The internal gains' shares** ``f_z`` are identified too (when ``I_g`` varies and
there are several zones, unless given): a building's data rarely say how its occupants and
appliances spread over its zones, while the fit can tell, since each zone's air answers to
its share of ``I_g`` at the hours ``I_g`` moves; they are kept summing to 1
(``f = softmax(0, v_2 .. v_Z)``), so the building's ``I_g`` stays its whole gains.

**Starts**: each zone first alone, its neighbours' measured air temperatures an input through
the walls (their interval mean, the mean of the two ends), from the grid of
:func:`~pinn_mpc.identify.identify_rc` around a day-averaged energy balance (the same 2R2C
parameters, with that zone's gain share and wall conductances added); then the whole building
jointly from those values (each wall's conductance the geometric mean of its two zones'
estimates, the shares the zones' normalised gains).

A fit that ends on the edge of a plausible R or C range is refused as identify_rc refuses it
(a mass at its largest capacity is kept, with a note); a wall at the smallest conductance
searched (:data:`MIN_WALL_CONDUCTANCE_W_PER_K`) is a wall the data do not see: it is set to 0,
with a note. The model ignores what happens inside an interval (a backup thermostat switching
a heater for part of it), so the residual is not pure sensor noise.

:class:`MultiZoneIdentifyResult` holds the building and the fit; :meth:`~MultiZoneIdentifyResult.to_json`
is the multi-zone RC file (every zone's values under the one-zone ``rc.json`` keys, the walls
by their zones' names), read back by :meth:`~MultiZoneIdentifyResult.from_json`, which
refuses a malformed file with one line.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import scipy.linalg
import scipy.optimize

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.data import check_celsius
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.identify import _best_start, _energy_balance_guess, _Layout
from pinn_mpc.multizone import (
    EXOGENOUS_NAMES,
    MAX_WALL_CONDUCTANCE_W_PER_K,
    SOLAR_INPUTS,
    MultiZoneParams,
    ZoneRC,
    continuous_matrices,
    wall_tuples,
)
from pinn_mpc.physics import DT_RANGE_S, SUMMARY_KEYS, params_from_summary
from pinn_mpc.zones import ZoneSpec, zone_column

__all__ = [
    "JSON_FORMAT",
    "MIN_WALL_CONDUCTANCE_W_PER_K",
    "MultiZoneIdentifyResult",
    "identify_multizone",
]

#: The ``format`` of the multi-zone RC file (:meth:`MultiZoneIdentifyResult.to_json`).
JSON_FORMAT = "pinn-mpc multi-zone RC 1"
#: The smallest wall conductance searched [W/K]: that of the largest plausible resistance
#: (10 K/W, :data:`pinn_mpc.physics.PLAUSIBLE_RANGES`); a wall fitted there is reported as 0.
MIN_WALL_CONDUCTANCE_W_PER_K = 0.1
#: Below this standard deviation an irradiance [W/m2] or I_g [W] column counts as constant.
_MIN_STD = 1.0
#: The rows a fit needs at least: a day at 30 min (identify_rc's).
_MIN_ROWS = 48
#: Bound of the gain shares' logits: a share e^-10 of the others' is none.
_LOGIT = 10.0
#: Evaluations of the one-zone refinement that starts the joint fit, and of the joint fit.
_ALONE_NFEV, _JOINT_NFEV = 60, 400
_PREFIX = "identify_multizone"
#: The keys of a zone's 2R2C in the file: the one-zone rc.json's, eta left out (the actuators').
_RC_KEYS = tuple(k for k in SUMMARY_KEYS if k != "eta")


@dataclass(frozen=True, kw_only=True)
class MultiZoneIdentifyResult:
    """An identified multi-zone building (``params``) and its fit: each zone's output-error
    RMSE of the simulated room temperature [C] and identified initial mass temperature [C]
    (in the zones' order), the rows fitted, whether each zone's sun and the gain shares were
    identified, the residual evaluations spent and what a user should know (``notes``)."""

    params: MultiZoneParams
    rmse_c: tuple[float, ...]
    t_m0_c: tuple[float, ...]
    n_rows: int
    identified_solar: tuple[bool, ...]
    identified_gain_shares: bool
    cost_evaluations: int
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        n = self.params.n_zones
        for name in ("rmse_c", "t_m0_c", "identified_solar"):
            if len(getattr(self, name)) != n:
                raise InternalError(
                    f"MultiZoneIdentifyResult.{name} has {len(getattr(self, name))} values for {n} zone(s)"
                )
        if not all(math.isfinite(v) and v >= 0 for v in self.rmse_c):
            raise InternalError(f"MultiZoneIdentifyResult.rmse_c must be finite and >= 0, got {self.rmse_c}")

    @property
    def walls(self) -> dict[tuple[str, str], float]:
        """``{(zone, zone): U [W/K]}`` of every wall with a conductance > 0 (each pair once,
        in the zones' order)."""
        return self.params.wall_pairs()

    def to_json(self) -> dict[str, Any]:
        """The multi-zone RC file as a dict for :func:`json.dump`: ``zones`` (each its
        ``name``, ``solar_input``, ``gain_share`` and the one-zone rc.json's R [K/W], C [J/K],
        aperture [m2] and fractions), ``walls`` (``{"zones": [a, b], "U_W_per_K": U}`` for each
        wall with a conductance > 0) and ``fit`` (per zone ``rmse_c`` and ``t_m0_c`` [C])."""
        names = [z.name for z in self.params.zone_specs]
        zones = [
            {"name": z.zone.name, "solar_input": z.solar_input, "gain_share": z.gain_share}
            | {key: float(getattr(z.rc, SUMMARY_KEYS[key])) for key in _RC_KEYS}
            for z in self.params.zones
        ]
        return {
            "format": JSON_FORMAT,
            "zones": zones,
            "walls": [{"zones": list(pair), "U_W_per_K": u} for pair, u in self.walls.items()],
            "fit": {
                "method": "output-error least squares, exact ZOH multi-zone RC, T_m hidden",
                "rmse_c": dict(zip(names, self.rmse_c, strict=True)),
                "t_m0_c": dict(zip(names, self.t_m0_c, strict=True)),
                "n_rows": self.n_rows,
                "identified_solar": dict(zip(names, self.identified_solar, strict=True)),
                "identified_gain_shares": self.identified_gain_shares,
                "cost_evaluations": self.cost_evaluations,
                "notes": list(self.notes),
            },
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any] | str, *, source: str = "multi-zone RC file") -> MultiZoneIdentifyResult:
        """Read :meth:`to_json`'s dict back (or its JSON text: parsed as data, nothing in it is
        run). A malformed file is an :class:`~pinn_mpc.errors.InputError` of one line that
        names ``source``, the key and the fix."""
        return _from_json(data, source)


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _from_json(data: Mapping[str, Any] | str, source: str) -> MultiZoneIdentifyResult:
    def refuse(what: str) -> InputError:
        return InputError(_one_line(f"{source}: {what}; write it as MultiZoneIdentifyResult.to_json() does"))

    if isinstance(data, str):
        try:
            data = json.loads(data, parse_constant=lambda c: _raise(refuse(f"holds {c}, not a number")))
        except json.JSONDecodeError as exc:
            raise refuse(f"is not JSON ({exc.msg} at line {exc.lineno} column {exc.colno})") from None
    if not isinstance(data, Mapping):
        raise refuse(f"holds a {type(data).__name__}, not an object")
    if data.get("format") != JSON_FORMAT:
        raise refuse(f"format is {data.get('format')!r}, not {JSON_FORMAT!r}")
    extra = sorted(set(data) - {"format", "zones", "walls", "fit", "source"})  # source: who wrote it
    if extra:
        raise refuse(f"has unknown key(s) {extra}")
    raw_zones, raw_walls, fit = data.get("zones"), data.get("walls"), data.get("fit")
    if not isinstance(raw_zones, list) or not raw_zones or not all(isinstance(z, Mapping) for z in raw_zones):
        raise refuse("'zones' must be a non-empty list of objects, one per zone")
    if not isinstance(raw_walls, list) or not all(isinstance(w, Mapping) for w in raw_walls):
        raise refuse("'walls' must be a list of objects {\"zones\": [a, b], \"U_W_per_K\": U}")
    if not isinstance(fit, Mapping):
        raise refuse("'fit' must be an object")
    try:
        zones = tuple(_zone_from_json(z, i) for i, z in enumerate(raw_zones))
        names = [z.zone.name for z in zones]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"zones: the name(s) {twice} appear more than once; name each zone once")
        walls = np.zeros((len(zones), len(zones)))
        for k, wall in enumerate(raw_walls):
            i, j, u = _wall_from_json(wall, k, names)
            if walls[i, j] != 0:
                raise ValueError(f"walls[{k}]: the wall {names[i]}-{names[j]} is given twice")
            walls[i, j] = walls[j, i] = u
        params = MultiZoneParams(zones=zones, wall_conductance_w_per_k=wall_tuples(walls))
        per_zone = {
            key: _per_zone_values(fit, key, names, kind)
            for key, kind in (("rmse_c", float), ("t_m0_c", float), ("identified_solar", bool))
        }
        notes = fit.get("notes", [])
        if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
            raise ValueError("fit.notes must be a list of strings")
        shares = fit.get("identified_gain_shares")
        if not isinstance(shares, bool):
            raise ValueError(f"fit.identified_gain_shares = {shares!r} must be true or false")
        return MultiZoneIdentifyResult(
            params=params,
            rmse_c=tuple(per_zone["rmse_c"]),
            t_m0_c=tuple(per_zone["t_m0_c"]),
            n_rows=_count(fit, "n_rows"),
            identified_solar=tuple(per_zone["identified_solar"]),
            identified_gain_shares=shares,
            cost_evaluations=_count(fit, "cost_evaluations"),
            notes=tuple(notes),
        )
    except (InputError, InternalError, ValueError, TypeError) as exc:
        raise refuse(getattr(exc, "marked", str(exc))) from None


def _raise(exc: Exception) -> Any:
    raise exc


def _zone_from_json(raw: Mapping[str, Any], index: int) -> ZoneRC:
    where = f"zones[{index}]"
    allowed = {"name", "solar_input", "gain_share", *_RC_KEYS}
    extra = sorted(set(raw) - allowed)
    if extra:
        raise ValueError(f"{where} has unknown key(s) {extra}; a zone's keys are {sorted(allowed)}")
    name = raw.get("name")
    if not isinstance(name, str):
        raise ValueError(f"{where}.name = {name!r} must be the zone's name (a string)")
    where = f"zone {name!r}"
    try:
        rc = params_from_summary({k: raw[k] for k in _RC_KEYS if k in raw})
    except InputError as exc:
        raise ValueError(f"{where}: {exc.marked}") from None
    share = raw.get("gain_share")
    if isinstance(share, bool) or not isinstance(share, int | float):
        raise ValueError(f"{where}: gain_share = {share!r} must be a number in [0, 1]")
    sun = raw.get("solar_input")
    if not isinstance(sun, str):
        raise ValueError(f"{where}: solar_input = {sun!r} must be one of {', '.join(SOLAR_INPUTS)}")
    return ZoneRC(zone=ZoneSpec(name), rc=rc, gain_share=float(share), solar_input=sun)


def _wall_from_json(raw: Mapping[str, Any], index: int, names: Sequence[str]) -> tuple[int, int, float]:
    where = f"walls[{index}]"
    extra = sorted(set(raw) - {"zones", "U_W_per_K"})
    if extra:
        raise ValueError(f"{where} has unknown key(s) {extra}")
    pair, u = raw.get("zones"), raw.get("U_W_per_K")
    if not (isinstance(pair, list) and len(pair) == 2 and all(p in names for p in pair) and pair[0] != pair[1]):
        raise ValueError(f"{where}.zones = {pair!r} must name two different zones of {list(names)}")
    if isinstance(u, bool) or not isinstance(u, int | float) or not (0 <= u <= MAX_WALL_CONDUCTANCE_W_PER_K):
        raise ValueError(
            f"{where}.U_W_per_K = {u!r} must be a conductance in 0 .. {MAX_WALL_CONDUCTANCE_W_PER_K:g} W/K"
        )
    return names.index(pair[0]), names.index(pair[1]), float(u)


def _count(fit: Mapping[str, Any], key: str) -> int:
    value = fit.get(key)
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f"fit.{key} = {value!r} must be a whole number >= 0")
    return value


def _per_zone_values(fit: Mapping[str, Any], key: str, names: Sequence[str], kind: type) -> list[Any]:
    values = fit.get(key)
    if not isinstance(values, Mapping) or sorted(values) != sorted(names):
        raise ValueError(f"fit.{key} must map each zone ({', '.join(names)}) to its value, got {values!r}")
    out = [values[n] for n in names]
    if kind is bool:
        ok = all(isinstance(v, bool) for v in out)
    else:
        ok = all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in out)
    if not ok:
        raise ValueError(f"fit.{key} = {dict(values)!r}: each value must be {'true or false' if kind is bool else 'a finite number'}")
    return [kind(v) for v in out]


# ---------------------------------------------------------------------------------------------
# The data


@dataclass(frozen=True, kw_only=True)
class _Data:
    """The fit's arrays; N rows, the last row's inputs unused (no room temperature after it)."""

    t_r: np.ndarray  # (N, Z) each zone's measured room temperature [C]
    heat: np.ndarray  # (N-1, A) each actuator's power times its heat per watt [W] (sign in b_u)
    exo: np.ndarray  # (N-1, 7) the exogenous inputs, EXOGENOUS_NAMES order
    solar: tuple[bool, ...]  # (Z,) the zone's sun is identified
    gains: bool  # I_g varies: its fractions to the air (and shares) are identified


def _column(frame: pd.DataFrame, name: str) -> np.ndarray:
    values = pd.to_numeric(frame[name], errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise InputError(
            f"{_PREFIX}: column {name!r} row {bad[0] + 1} has {str(frame[name].iloc[bad[0]]).strip()!r}, not a "
            "finite number; fill such rows (e.g. pandas: df.interpolate())"
        )
    return values


def _read_data(
    frame: pd.DataFrame,
    zones: Sequence[ZoneSpec],
    actuators: Sequence[ActuatorSpec],
    power_columns: Sequence[str],
    solar_inputs: Sequence[str | None],
) -> tuple[_Data, list[str]]:
    """The arrays of ``frame`` and the notes on what is not identified; InputError names a
    missing, non-numeric or negative column, temperatures not in Celsius, too few rows or
    power that never varies."""
    rooms = [zone_column("T_r", zones, z) for z in range(len(zones))]
    suns = sorted({s for s in solar_inputs if s is not None}, key=EXOGENOUS_NAMES.index)
    missing = [c for c in (*rooms, *power_columns, "T_a", *suns) if c not in frame.columns]
    if missing:
        raise InputError(
            f"{_PREFIX}: data lacks column(s) {missing}; have {', '.join(map(str, frame.columns))} "
            "(each zone's T_r[<zone>], each actuator's power column, T_a and each zone's irradiance)"
        )
    n = len(frame)
    if n < _MIN_ROWS:
        raise InputError(f"{_PREFIX}: needs at least {_MIN_ROWS} rows (a day at 30 min), got {n}")
    t_r = np.stack([_column(frame, c) for c in rooms], axis=1)
    t_a = _column(frame, "T_a")
    check_celsius({c: float(np.median(v)) for c, v in zip([*rooms, "T_a"], [*t_r.T, t_a], strict=True)}, _PREFIX)
    power = np.stack([_column(frame, c) for c in power_columns], axis=1)
    negative = [c for c, p in zip(power_columns, power.T, strict=True) if p.min() < 0]
    if negative:
        raise InputError(
            f"{_PREFIX}: power column(s) {negative} hold negative values; power is the electrical "
            "power [W] >= 0 (a cooling machine is an actuator with heats=False)"
        )
    if not np.any(np.std(power, axis=0) > 0):
        raise InputError(
            f"{_PREFIX}: every power column ({', '.join(power_columns)}) is constant, so the "
            "building's response is not excited; give data in which the power varies"
        )
    exo = np.zeros((n, len(EXOGENOUS_NAMES)))
    exo[:, 0] = t_a
    for name in [*suns, *(["I_g"] if "I_g" in frame.columns else [])]:
        exo[:, EXOGENOUS_NAMES.index(name)] = _column(frame, name)
    varies = np.std(exo, axis=0) > _MIN_STD
    solar = tuple(s is not None and bool(varies[EXOGENOUS_NAMES.index(s)]) for s in solar_inputs)
    notes = [
        f"{_PREFIX}: zone {zone.name!r}: {s} does not vary, so its solar aperture is not identified (0)"
        for zone, s, known in zip(zones, solar_inputs, solar, strict=True)
        if s is not None and not known
    ]
    heat = np.stack([a.gain(t_a) for a in actuators], axis=1) * power
    gains = bool(varies[EXOGENOUS_NAMES.index("I_g")])
    return _Data(t_r=t_r, heat=heat[:-1], exo=exo[:-1], solar=solar, gains=gains), notes


# ---------------------------------------------------------------------------------------------
# The model


def _simulate_rooms(
    a: np.ndarray, b: np.ndarray, capacities: np.ndarray, x0: np.ndarray, inputs: np.ndarray,
    dt_s: float, n_rooms: int,
) -> np.ndarray:
    """Free-run the exact ZOH of ``dx/dt = a x + b d`` from ``x0`` (n,) over ``inputs`` (N-1, m)
    held per interval -> (N-1, n_rooms) the first ``n_rooms`` states after each interval [C].

    ``a`` is ``C^-1 K`` with ``capacities`` C (n,) > 0 and K symmetric (an RC network), so
    ``S = C^(1/2) a C^(-1/2)`` is symmetric: ``S = Q diag(l) Q^T`` and ``a = V diag(l) V^-1``
    with ``V = C^(-1/2) Q``, ``V^-1 = Q^T C^(1/2)``. Mode i steps as
    ``z+ = e^(l dt) z + (e^(l dt) - 1)/l (V^-1 b d)_i``."""
    import scipy.signal  # here, not at the top: every command imports this module, few call this

    root = np.sqrt(capacities)
    s = root[:, None] * a / root[None, :]
    lam, q = scipy.linalg.eigh(0.5 * (s + s.T))
    v = q / root[:, None]  # (n, n) the modes' shapes
    v_inv = q.T * root[None, :]
    decay = np.exp(lam * dt_s)
    held = np.where(lam != 0.0, np.expm1(lam * dt_s) / np.where(lam != 0.0, lam, 1.0), dt_s)
    w = (inputs @ (v_inv @ b).T) * held  # (N-1, n) each mode's input per interval
    z0 = v_inv @ x0
    z = np.empty_like(w)
    for i in range(len(lam)):
        z[:, i] = scipy.signal.lfilter([1.0], [1.0, -decay[i]], w[:, i], zi=[decay[i] * z0[i]])[0]
    return z @ v[:n_rooms].T


def _capacities(params: MultiZoneParams) -> np.ndarray:
    """(2Z,) the capacities [J/K] in the state's order (the rooms, then the masses)."""
    return np.array([z.rc.c_r_j_per_k for z in params.zones] + [z.rc.c_m_j_per_k for z in params.zones])


def _log_wall_bounds() -> tuple[float, float]:
    return math.log(MIN_WALL_CONDUCTANCE_W_PER_K), math.log(MAX_WALL_CONDUCTANCE_W_PER_K) - 1e-9


def _guarded(residuals: Callable[[np.ndarray], np.ndarray], size: int) -> Callable[[np.ndarray], np.ndarray]:
    """``residuals`` with a parameter set the model refuses (rounding at a bound) or a
    non-finite simulation scored as a large constant error, as identify_rc scores them."""

    def safe(theta: np.ndarray) -> np.ndarray:
        try:
            res = residuals(theta)
        except InputError:
            return np.full(size, 1e3)
        return np.where(np.isfinite(res), res, 1e3)

    return safe


class _Building:
    """The joint fit's unknowns: each zone's 2R2C block (:class:`pinn_mpc.identify._Layout`'s
    names: log R and C, the sun, the gains' fraction to the air, ``T_m0``), the gain shares'
    logits of zones 2 .. Z (when identified, else ``shares``), the walls' log-conductances
    (one per pair of ``pairs``)."""

    def __init__(
        self,
        zones: Sequence[ZoneSpec],
        blocks: Sequence[_Layout],
        solar_inputs: Sequence[str | None],
        pairs: Sequence[tuple[int, int]],
        shares: np.ndarray | None,
    ) -> None:
        self.zones, self.blocks, self.pairs, self.shares = tuple(zones), tuple(blocks), tuple(pairs), shares
        self.suns = tuple(s or "G" for s in solar_inputs)  # no windows: aperture 0 on G
        ends = np.cumsum([len(b.names) for b in blocks])
        self.block_slices = [slice(int(e) - len(b.names), int(e)) for b, e in zip(blocks, ends, strict=True)]
        n_logits = len(zones) - 1 if shares is None else 0
        self.logit_slice = slice(int(ends[-1]), int(ends[-1]) + n_logits)
        self.wall_slice = slice(self.logit_slice.stop, self.logit_slice.stop + len(pairs))
        self.size = self.wall_slice.stop

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lows, highs = zip(*(b.bounds() for b in self.blocks), strict=True)
        n_logits, n_walls = self.logit_slice.stop - self.logit_slice.start, len(self.pairs)
        lo_u, hi_u = _log_wall_bounds()
        lower = np.concatenate([*lows, np.full(n_logits, -_LOGIT), np.full(n_walls, lo_u)])
        upper = np.concatenate([*highs, np.full(n_logits, _LOGIT), np.full(n_walls, hi_u)])
        return lower, upper

    def gain_shares(self, theta: np.ndarray) -> np.ndarray:
        """(Z,) the shares of I_g: ``softmax(0, logits)``, or the given ones."""
        if self.shares is not None:
            return self.shares
        logits = np.concatenate([[0.0], theta[self.logit_slice]])
        e = np.exp(logits - logits.max())
        return e / math.fsum(e)

    def walls(self, theta: np.ndarray) -> np.ndarray:
        """(Z, Z) the walls' conductances [W/K]."""
        u = np.zeros((len(self.zones), len(self.zones)))
        for (i, j), ln_u in zip(self.pairs, theta[self.wall_slice], strict=True):
            u[i, j] = u[j, i] = math.exp(ln_u)
        return u

    def params(self, theta: np.ndarray, walls: np.ndarray | None = None) -> MultiZoneParams:
        """The building of ``theta`` (with ``walls`` instead of its own, if given)."""
        zones = tuple(
            ZoneRC(zone=spec, rc=block.params(theta[sl]), gain_share=float(f), solar_input=sun)
            for spec, block, sl, f, sun in zip(
                self.zones, self.blocks, self.block_slices, self.gain_shares(theta), self.suns, strict=True
            )
        )
        return MultiZoneParams(
            zones=zones, wall_conductance_w_per_k=wall_tuples(self.walls(theta) if walls is None else walls)
        )

    def t_m0(self, theta: np.ndarray) -> np.ndarray:
        """(Z,) the masses' initial temperatures [C]."""
        return np.array([theta[sl][-1] for sl in self.block_slices])


def _fit_alone(
    z: int,
    data: _Data,
    building: _Building,
    actuators: Sequence[ActuatorSpec],
    neighbours: Sequence[int],
    dt_s: float,
) -> tuple[np.ndarray, int]:
    """Zone ``z`` alone, its ``neighbours``' measured air (the interval's mean of its two ends)
    an input through the walls: identify_rc's start grid, then a short refinement. Returns
    ``(theta, evaluations)``, theta its :class:`~pinn_mpc.identify._Layout` block, then ``ln q``
    (its share of I_g, not held to any sum; only when the building's shares are identified),
    then each wall's ``ln U``."""
    block, spec, sun = building.blocks[z], building.zones[z], building.suns[z]
    share = None if building.shares is None else float(building.shares[z])
    n_block, n_q = len(block.names), int(share is None)
    own = [k for k, a in enumerate(actuators) if a.zone == z]
    local = [dataclasses.replace(actuators[k], zone=0) for k in own]
    t_r = data.t_r[:, z]
    boundary = 0.5 * (data.t_r[:-1, neighbours] + data.t_r[1:, neighbours])  # (N-1, W)
    inputs = np.concatenate([data.heat[:, own], data.exo, boundary], axis=1)
    i_g, first_wall = len(own) + EXOGENOUS_NAMES.index("I_g"), len(own) + len(EXOGENOUS_NAMES)

    def residuals(theta: np.ndarray) -> np.ndarray:
        zone = ZoneRC(zone=spec, rc=block.params(theta[:n_block]), gain_share=1.0, solar_input=sun)
        alone = MultiZoneParams(zones=(zone,), wall_conductance_w_per_k=((0.0,),))
        mats = continuous_matrices(alone, local)
        u = np.exp(theta[n_block + n_q :])  # (W,) the walls [W/K]
        a = mats.a.copy()
        a[0, 0] -= u.sum() / zone.rc.c_r_j_per_k
        b = np.concatenate([mats.b_u, mats.b_d, np.zeros((2, len(neighbours)))], axis=1)
        b[0, first_wall:] = u / zone.rc.c_r_j_per_k
        b[:, i_g] *= math.exp(theta[n_block]) if share is None else share
        x0 = np.array([t_r[0], theta[n_block - 1]])
        return _simulate_rooms(a, b, _capacities(alone), x0, inputs, dt_s, 1)[:, 0] - t_r[1:]

    q0 = 1.0 / len(building.zones) if share is None else share
    balance = np.stack(
        [
            data.heat[:, own] @ np.array([a.sign for a in local]),
            data.exo[:, 0],
            data.exo[:, EXOGENOUS_NAMES.index(sun)],
            q0 * data.exo[:, EXOGENOUS_NAMES.index("I_g")],
        ],
        axis=1,
    )
    r_ra, c_tot, aperture = _energy_balance_guess(t_r, balance, dt_s, eta=1.0, solar=block.solar)
    lo_u, hi_u = _log_wall_bounds()
    lower, upper = block.bounds()
    lower = np.concatenate([lower, [math.log(1e-3)] * n_q, [lo_u] * len(neighbours)])
    upper = np.concatenate([upper, [math.log(2.0)] * n_q, [hi_u] * len(neighbours)])
    extra = [math.log(q0)] * n_q + [math.log(0.3 / r_ra)] * len(neighbours)
    starts = [
        np.clip(np.concatenate([s, extra]), lower + 1e-9, upper - 1e-9)
        for s in block.starts(r_ra=r_ra, c_tot=c_tot, aperture=aperture, t_m0=float(t_r[0]))
    ]
    safe = _guarded(residuals, len(t_r) - 1)
    best, evaluations = _best_start(safe, starts, (lower, upper))
    fit = scipy.optimize.least_squares(safe, best.x, bounds=(lower, upper), max_nfev=_ALONE_NFEV)
    return fit.x, evaluations + fit.nfev


def _checked_arguments(
    frame: Any,
    zones: Any,
    actuators: Any,
    power_columns: Any,
    solar_inputs: Any,
    dt_s: Any,
    adjacency: Any,
    gain_shares: Any,
) -> tuple[tuple[ZoneSpec, ...], tuple[ActuatorSpec, ...], np.ndarray, np.ndarray | None]:
    """The arguments as tuples and arrays, or a TypeError/ValueError naming the first misuse."""
    if not isinstance(frame, pd.DataFrame):
        raise TypeError(f"{_PREFIX}: frame must be a pandas DataFrame, got {type(frame).__name__}")
    if not isinstance(zones, Sequence) or not zones or not all(isinstance(z, ZoneSpec) for z in zones):
        raise TypeError(f"{_PREFIX}: zones must be a non-empty sequence of ZoneSpec, got {zones!r}")
    names = [z.name for z in zones]
    if len(set(names)) != len(names):
        raise ValueError(f"{_PREFIX}: zones {names} name a zone more than once; name each zone once")
    n = len(zones)
    if not isinstance(actuators, Sequence) or not all(isinstance(a, ActuatorSpec) for a in actuators):
        raise TypeError(f"{_PREFIX}: actuators must be a sequence of ActuatorSpec, got {actuators!r}")
    if not actuators:
        raise ValueError(
            f"{_PREFIX}: actuators is empty; give the building's actuators (their known heat per "
            "watt fixes the scale of every capacity)"
        )
    outside = [k for k, a in enumerate(actuators) if a.zone >= n]
    if outside:
        k = outside[0]
        raise ValueError(
            f"{_PREFIX}: actuators[{k}].zone = {actuators[k].zone} is out of range for the "
            f"{n} zone(s) ({', '.join(names)}); give a zone index 0 .. {n - 1}"
        )
    if isinstance(power_columns, str) or not isinstance(power_columns, Sequence) or not all(
        isinstance(c, str) for c in power_columns
    ):
        raise TypeError(f"{_PREFIX}: power_columns must be a sequence of column names, got {power_columns!r}")
    if len(power_columns) != len(actuators) or len(set(power_columns)) != len(power_columns):
        raise ValueError(
            f"{_PREFIX}: power_columns = {list(power_columns)} must name {len(actuators)} different "
            "column(s), one per actuator in the actuators' order"
        )
    if isinstance(solar_inputs, str) or not isinstance(solar_inputs, Sequence) or len(solar_inputs) != n:
        raise ValueError(
            f"{_PREFIX}: solar_inputs = {solar_inputs!r} must give each of the {n} zone(s) the "
            f"irradiance its windows take ({', '.join(SOLAR_INPUTS)}) or None (no windows)"
        )
    unknown = [s for s in solar_inputs if s is not None and s not in SOLAR_INPUTS]
    if unknown:
        raise ValueError(
            f"{_PREFIX}: solar_inputs names {unknown}; choose among {', '.join(SOLAR_INPUTS)} or None (no windows)"
        )
    if isinstance(dt_s, bool) or not (isinstance(dt_s, int | float) and DT_RANGE_S[0] <= dt_s <= DT_RANGE_S[1]):
        raise ValueError(
            f"{_PREFIX}: dt_s = {dt_s!r} must be the data's step in seconds, "
            f"{DT_RANGE_S[0]:g} .. {DT_RANGE_S[1]:g}"
        )
    touching = ~np.eye(n, dtype=bool) if adjacency is None else np.asarray(adjacency)
    if touching.shape != (n, n) or touching.dtype != bool:
        raise ValueError(
            f"{_PREFIX}: adjacency must be a ({n}, {n}) array of bools (True where two zones share "
            f"a wall), got {adjacency!r}"
        )
    if touching.diagonal().any() or not np.array_equal(touching, touching.T):
        raise ValueError(
            f"{_PREFIX}: adjacency = {touching.tolist()} must be symmetric with a False diagonal "
            "(a zone has no wall with itself)"
        )
    shares = None
    if gain_shares is not None:
        shares = np.asarray(gain_shares, dtype=float)
        if shares.shape != (n,) or not np.all((shares >= 0) & (shares <= 1)) or abs(math.fsum(shares) - 1) > 1e-9:
            raise ValueError(
                f"{_PREFIX}: gain_shares = {gain_shares!r} must be {n} shares in [0, 1] summing to 1, "
                "or None (identified)"
            )
    return tuple(zones), tuple(actuators), touching, shares


def identify_multizone(
    frame: pd.DataFrame,
    *,
    zones: Sequence[ZoneSpec],
    actuators: Sequence[ActuatorSpec],
    power_columns: Sequence[str],
    solar_inputs: Sequence[str | None],
    dt_s: float,
    adjacency: Sequence[Sequence[bool]] | np.ndarray | None = None,
    gain_shares: Sequence[float] | None = None,
) -> MultiZoneIdentifyResult:
    """Identify a multi-zone RC building from data, each zone's thermal mass hidden (module
    docstring).

    Parameters
    ----------
    frame
        One row per interval: each zone's room temperature at the interval's start
        (``T_r[<zone>]``, :func:`pinn_mpc.zones.zone_column`; ``T_r`` for one zone), each
        actuator's mean electrical power over the interval [W] (``power_columns``), ``T_a``
        [C], the irradiance each zone's windows take [W/m2] and, if any, ``I_g`` [W] (the
        building's internal gains). Other columns (a ``T_m``) are not used.
    zones
        The building's zones, in order.
    actuators
        Every actuator (its zone, heating or cooling, its heat per watt).
    power_columns
        The column of each actuator's power, in the actuators' order.
    solar_inputs
        Per zone, the irradiance column its windows take (``G`` or a facade's, e.g.
        ``G_south``), or None for a zone without windows (aperture 0).
    dt_s
        The data's step [s].
    adjacency
        (Z, Z) bools, True where two zones share an internal wall (symmetric, False on the
        diagonal); only those walls are fitted, the others are 0. Default: every pair.
    gain_shares
        Each zone's share of ``I_g`` (summing to 1), if known; None identifies them.

    Raises
    ------
    InputError
        Missing or non-numeric columns, temperatures not in Celsius, too few rows, negative or
        unexciting power, a fit that runs into the edge of a plausible R or C range or of the
        largest wall conductance.
    """
    zones, actuators, touching, shares = _checked_arguments(
        frame, zones, actuators, power_columns, solar_inputs, dt_s, adjacency, gain_shares
    )
    data, notes = _read_data(frame, zones, actuators, power_columns, solar_inputs)
    n_zones, n_rows = len(zones), len(frame)
    identified_shares = shares is None and data.gains and n_zones > 1
    if shares is None and not identified_shares:
        shares = np.full(n_zones, 1.0 / n_zones)  # I_g constant or absent: its split is not seen
    pairs = [(i, j) for i in range(n_zones) for j in range(i + 1, n_zones) if touching[i, j]]
    blocks = [_Layout(solar=data.solar[z], gains=data.gains, eta=1.0) for z in range(n_zones)]
    building = _Building(zones, blocks, solar_inputs, pairs, shares)

    theta0 = np.zeros(building.size)
    ln_q, ln_walls = np.zeros(n_zones), np.zeros((n_zones, n_zones))
    evaluations = 0
    for z in range(n_zones):
        neighbours = [int(w) for w in np.flatnonzero(touching[z])]
        theta, spent = _fit_alone(z, data, building, actuators, neighbours, dt_s)
        evaluations += spent
        n_block = len(blocks[z].names)
        theta0[building.block_slices[z]] = theta[:n_block]
        ln_q[z] = theta[n_block] if identified_shares else 0.0
        ln_walls[z, neighbours] = theta[n_block + identified_shares :]
    theta0[building.logit_slice] = ln_q[1:] - ln_q[0] if identified_shares else []
    theta0[building.wall_slice] = [0.5 * (ln_walls[i, j] + ln_walls[j, i]) for i, j in pairs]
    lower, upper = building.bounds()
    inputs = np.concatenate([data.heat, data.exo], axis=1)

    def residuals(theta: np.ndarray) -> np.ndarray:
        params = building.params(theta)
        mats = continuous_matrices(params, actuators)
        x0 = np.concatenate([data.t_r[0], building.t_m0(theta)])
        b = np.concatenate([mats.b_u, mats.b_d], axis=1)
        rooms = _simulate_rooms(mats.a, b, _capacities(params), x0, inputs, dt_s, n_zones)
        return (rooms - data.t_r[1:]).ravel()

    final = scipy.optimize.least_squares(
        _guarded(residuals, (n_rows - 1) * n_zones), np.clip(theta0, lower + 1e-9, upper - 1e-9),
        bounds=(lower, upper), xtol=1e-10, ftol=1e-12, max_nfev=_JOINT_NFEV,
    )
    evaluations += final.nfev
    if final.status == 0:
        notes.append(
            f"{_PREFIX}: the joint fit stopped after {_JOINT_NFEV} evaluations before converging; "
            "its values may be off where the data say little"
        )
    notes += _edge_notes(building, final.x)
    walls = _checked_walls(building, final.x, notes)
    rmse = np.sqrt(np.mean(np.square(final.fun.reshape(n_rows - 1, n_zones)), axis=0))
    return MultiZoneIdentifyResult(
        params=building.params(final.x, walls),
        rmse_c=tuple(float(r) for r in rmse),
        t_m0_c=tuple(float(t) for t in building.t_m0(final.x)),
        n_rows=n_rows,
        identified_solar=data.solar,
        identified_gain_shares=identified_shares,
        cost_evaluations=evaluations,
        notes=tuple(notes),
    )


def _edge_notes(building: _Building, theta: np.ndarray) -> list[str]:
    """Each zone's R and C checked against the edges of their plausible ranges as identify_rc
    checks them (:meth:`pinn_mpc.identify._Layout.check_inside`): the InputError of one at
    an edge, naming the zone; the notes of a mass at its largest capacity. A zone with walls
    to others whose ``R_ra`` ran to its largest plausible value is an inner zone (no envelope
    to the outdoor air, a core between storeys): kept, with a note."""
    notes = []
    touching = {z for pair in building.pairs for z in pair}
    for z, (spec, block, sl) in enumerate(zip(building.zones, building.blocks, building.block_slices, strict=True)):
        own = theta[sl].copy()
        k = block.names.index("ln_r_ra")
        upper = block.bounds()[1][k]
        if z in touching and own[k] >= upper - 1e-6:
            notes.append(
                f"{_PREFIX}: zone {spec.name!r}: R_ra ran to its largest plausible value "
                f"({math.exp(upper):g} K/W): the data see no heat to the outdoor air but through "
                "its walls to other zones (an inner zone); kept"
            )
            own[k] = upper - 1e-3  # checked as inside: the other values still are
        try:
            found = block.check_inside(own)
        except InputError as exc:
            raise InputError(f"{_PREFIX}: zone {spec.name!r}: {exc.marked.removeprefix('identify: ')}") from None
        notes += [f"{_PREFIX}: zone {spec.name!r}: {n.removeprefix('identify: ')}" for n in found]
    return notes


def _checked_walls(building: _Building, theta: np.ndarray, notes: list[str]) -> np.ndarray:
    """(Z, Z) the fitted walls [W/K], one at the smallest conductance searched set to 0 (a
    note added to ``notes``); InputError for one at the largest plausible conductance."""
    walls = building.walls(theta)
    lo_u, hi_u = _log_wall_bounds()
    for (i, j), ln_u in zip(building.pairs, theta[building.wall_slice], strict=True):
        pair = f"{building.zones[i].name}-{building.zones[j].name}"
        if ln_u >= hi_u - 1e-6:
            raise InputError(
                f"{_PREFIX}: the wall {pair} ran into the largest plausible conductance "
                f"({MAX_WALL_CONDUCTANCE_W_PER_K:g} W/K): the data do not tell the two zones apart; "
                "check that each T_r[<zone>] column is its own zone's, or take the two as one zone"
            )
        if ln_u <= lo_u + 1e-6:
            walls[i, j] = walls[j, i] = 0.0
            notes.append(
                f"{_PREFIX}: the wall {pair} fitted at the smallest conductance searched "
                f"({MIN_WALL_CONDUCTANCE_W_PER_K:g} W/K): the data see no heat through it; set to 0"
            )
    return walls
