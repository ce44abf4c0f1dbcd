"""2R2C building physics: parameters, coefficient form, state space, discretisation.

The single source of truth for the model of the paper (Eq. 2r2c)::

    C_r dT_r/dt = (T_a - T_r)/R_ra + (T_m - T_r)/R_rm + eta*u + alpha*A_sol*G + beta*I_g
    C_m dT_m/dt = (T_r - T_m)/R_rm + (1-alpha)*A_sol*G + (1-beta)*I_g

State ``x = (T_r, T_m)`` [C]; input ``d = (u [W], T_a [C], G [W/m2], I_g [W])``.
``eta`` is the heat delivered to the room air per watt of actuator power: positive for a
heater, negative (minus the COP) for a cooling machine.

Coefficient form (paper Eq. pinn-phy-block), all per second::

    a11 = 1/(C_r R_ra) + 1/(C_r R_rm)   a12 = 1/(C_r R_rm)   a21 = a22 = 1/(C_m R_rm)
    b = eta/C_r   c13 = 1/(C_r R_ra)
    c11 = alpha A_sol/C_r   c12 = beta/C_r   c21 = (1-alpha) A_sol/C_m   c22 = (1-beta)/C_m

Simulator, physics loss, grey-box identification and both RC MPCs build their matrices from
:func:`state_space_entries`, which works for floats, numpy arrays, torch tensors and CasADi
symbols alike.

The physically plausible ranges of everything that enters from outside (R/C values and eta in
:data:`PLAUSIBLE_RANGES`, actuator power :data:`MAX_POWER_W`, control interval
:data:`DT_RANGE_S`) are set here, once; :class:`RCParams` enforces its ranges on construction.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any, cast

import numpy as np
import scipy.linalg

from pinn_mpc.errors import InputError
from pinn_mpc.records import RcSummary

__all__ = [
    "DT_RANGE_S",
    "GAIN_BLOCK_H",
    "GAIN_SCHEDULE_LENGTH",
    "INPUT_NAMES",
    "MAX_POWER_W",
    "N_INPUTS",
    "N_STATES",
    "PAPER_HOUSEHOLD",
    "PLAUSIBLE_RANGES",
    "SUMMARY_KEYS",
    "Coefficients",
    "RCParams",
    "check_plausible",
    "continuous_matrices",
    "discretise",
    "discretise_euler",
    "from_coefficients",
    "gain_schedule_index",
    "params_from_summary",
    "rc_summary",
    "read_rc_json",
    "scheduled_gains_w",
    "state_space_entries",
    "steady_state",
    "step",
    "time_constants_h",
    "to_coefficients",
]

N_STATES = 2
N_INPUTS = 4
INPUT_NAMES = ("u", "T_a", "G", "I_g")


#: Physically plausible ranges (low, high, unit) of the RC values, the one place they are set.
#: Wide enough for everything from a walk-in cold room to a large building taken as one zone:
#:
#: - resistances 1e-8 .. 10 K/W: 10 K/W is a conductance of 0.1 W/K (a few m2 of 20 cm foam);
#:   1e-8 K/W is 1e8 W/K (air-to-mass over 1e6 m2 of surfaces at 10 W/(m2 K) is 1e7 W/K);
#: - capacities 1e4 .. 1e12 J/K: 1e4 J/K is the air of an 8 m3 room (1.2 kJ/(m3 K));
#:   1e12 J/K is above the concrete of a 1e6 m2 building (~7e8 kg at 0.9 kJ/(kg K));
#: - |eta| 0.1 .. 10: heat per W of actuator power, from a heater that reaches the room badly to
#:   beyond the best heat-pump COP (about 7); negative (minus the COP) for cooling;
#: - solar aperture 0 .. 1e5 m2: effective window area (area x g-value) of a very large building.
#:
#: Values outside come from wrong units (W vs kW, seconds vs hours) or a failed fit.
PLAUSIBLE_RANGES: dict[str, tuple[float, float, str]] = {
    "r_ra_k_per_w": (1e-8, 10.0, "K/W"),
    "r_rm_k_per_w": (1e-8, 10.0, "K/W"),
    "c_r_j_per_k": (1e4, 1e12, "J/K"),
    "c_m_j_per_k": (1e4, 1e12, "J/K"),
    "eta": (0.1, 10.0, "W/W"),  # the magnitude; the sign says heating (+) or cooling (-)
    "solar_aperture_m2": (0.0, 1e5, "m2"),
    "solar_to_air_fraction": (0.0, 1.0, "-"),
    "gain_to_air_fraction": (0.0, 1.0, "-"),
}
#: Largest actuator power [W] a data set may hold: 10 MW is the peak heating or cooling of a very
#: large building (1e5 m2 at 100 W/m2) taken as one zone. Above it the power column is in the
#: wrong unit (mW, or energy per interval in J) or holds a meter error.
MAX_POWER_W = 1.0e7
#: Plausible control interval [s]: 1 min (the simulator's substep) to 6 h. Outside it a time
#: column is usually in the wrong unit (a row index read as seconds, or hours, or ms).
DT_RANGE_S = (60.0, 6 * 3600.0)
#: Hours of a block of the unmeasured-gain schedule, and the schedule's length: a workday's
#: blocks, then a weekend day's or holiday's.
GAIN_BLOCK_H = 2.0
GAIN_SCHEDULE_LENGTH = 2 * round(24 / GAIN_BLOCK_H)


def gain_schedule_index(time_of_day_h: Any, day_of_week: Any | None) -> np.ndarray:
    """Each interval's block of :attr:`RCParams.unmeasured_gains_w`
    (:func:`pinn_mpc.data.schedule_index` of two day types and :data:`GAIN_BLOCK_H`): its
    two-hour block of the day, a weekend day's (``day_of_week`` 5 or 6, 0 = Monday; 6 for a
    holiday) after the workdays'. An unknown day (None or NaN) counts as a workday."""
    from pinn_mpc.data import schedule_index  # pinn_mpc.data imports this module

    hours = np.mod(np.asarray(time_of_day_h, dtype=float), 24.0)
    dow = np.zeros(hours.shape) if day_of_week is None else np.broadcast_to(
        np.nan_to_num(np.asarray(day_of_week, dtype=float), nan=0.0), hours.shape
    )
    return schedule_index(hours, dow, 2, GAIN_BLOCK_H)


def scheduled_gains_w(
    schedule_w: Sequence[float], i_g_w: Any, time_of_day_h: Any, day_of_week: Any | None
) -> np.ndarray:
    """The measured gains ``i_g_w`` [W] plus the unmeasured gains of ``schedule_w``
    (:attr:`RCParams.unmeasured_gains_w`'s layout; empty: none) in each interval's block
    (:func:`gain_schedule_index`); arrays of one shape."""
    measured = np.asarray(i_g_w, dtype=float)
    if not schedule_w:
        return measured
    return measured + np.asarray(schedule_w, dtype=float)[gain_schedule_index(time_of_day_h, day_of_week)]


def check_plausible(field: str, value: Any, *, name: str | None = None) -> float:
    """``value`` of RC field ``field`` as a float, or InputError naming it ``name`` (default the
    field) with the problem (not a number, negative, zero, outside) and the plausible range."""
    label = name or field
    lo, hi, unit = PLAUSIBLE_RANGES[field]
    if isinstance(value, bool):
        raise InputError(f"{label} is {value!r}, not a number [{unit}]")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{label} is {value!r}, not a number [{unit}]") from None
    span = f"plausible range {lo:g} .. {hi:g} {unit}"
    if field == "eta":
        span = f"{span} in magnitude, negative for cooling"
    if not math.isfinite(number):
        raise InputError(f"{label} is {number}, not a finite number; {span}")
    magnitude = abs(number) if field == "eta" else number
    if field == "eta" and number == 0:
        raise InputError(
            f"{label} is 0: the actuator would do nothing; give the heat per W of actuator "
            f"power (1 for a heater, -COP for a cooling machine), {span}"
        )
    if magnitude < 0:
        raise InputError(f"{label} is negative ({number:g} {unit}); it must lie in the {span}")
    if lo > 0 and magnitude == 0:
        raise InputError(f"{label} is 0; it must lie in the {span}")
    if not lo <= magnitude <= hi:
        raise InputError(
            f"{label} = {number:.4g} {unit} is outside the {span} (see "
            "pinn_mpc.physics.PLAUSIBLE_RANGES); check its units"
        )
    return number


@dataclass(frozen=True, kw_only=True)
class RCParams:
    """Physical 2R2C parameters, SI units in the names, each within :data:`PLAUSIBLE_RANGES`."""

    r_ra_k_per_w: float
    r_rm_k_per_w: float
    c_r_j_per_k: float
    c_m_j_per_k: float
    eta: float = 1.0
    solar_aperture_m2: float = 0.0
    solar_to_air_fraction: float = 0.0
    gain_to_air_fraction: float = 1.0
    #: Unmeasured internal gains [W] by the hour (:func:`gain_schedule_index`): empty, or one
    #: value per two-hour block of a workday, then of a weekend day or holiday. Identified from
    #: data without an ``I_g`` column (occupants, lights, equipment); a model's, not a plant's.
    unmeasured_gains_w: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name != "unmeasured_gains_w":
                check_plausible(f.name, getattr(self, f.name), name=f"RCParams.{f.name}")
        gains = tuple(float(g) for g in self.unmeasured_gains_w)
        if gains and (
            len(gains) != GAIN_SCHEDULE_LENGTH
            or not all(math.isfinite(g) and 0.0 <= g <= MAX_POWER_W for g in gains)
        ):
            raise InputError(
                f"RCParams.unmeasured_gains_w: expected {GAIN_SCHEDULE_LENGTH} gains in "
                f"0 .. {MAX_POWER_W:g} W (two-hour blocks of a workday, then of a weekend day), "
                f"got {len(gains)} values"
            )
        object.__setattr__(self, "unmeasured_gains_w", gains)

    def gains_w(
        self, i_g_w: Any, time_of_day_h: Any, day_of_week: Any | None
    ) -> np.ndarray:
        """The internal gains the model takes [W]: the measured ``i_g_w`` plus the unmeasured
        gains of each interval's block (:func:`gain_schedule_index`); arrays of one shape.
        Where the calendar is unknown (``day_of_week`` None or NaN) a workday's."""
        return scheduled_gains_w(self.unmeasured_gains_w, i_g_w, time_of_day_h, day_of_week)

    def without_unmeasured_gains(self) -> RCParams:
        """The same building with no unmeasured-gain schedule (what a plant simulates)."""
        return replace(self, unmeasured_gains_w=())

    @property
    def heating(self) -> bool:
        """True when the actuator heats (eta > 0), False for cooling."""
        return self.eta > 0

    def to_dict(self) -> dict[str, Any]:
        """The fields by name; the unmeasured gains only where there are some (as a list)."""
        out: dict[str, Any] = asdict(self)
        if self.unmeasured_gains_w:
            out["unmeasured_gains_w"] = list(self.unmeasured_gains_w)
        else:
            del out["unmeasured_gains_w"]
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RCParams:
        names = {f.name for f in fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise InputError(f"unknown RC parameter(s) {sorted(unknown)}; expected {sorted(names)}")
        gains = data.get("unmeasured_gains_w", ())
        values = {k: check_plausible(k, v) for k, v in data.items() if k != "unmeasured_gains_w"}
        return cls(**values, unmeasured_gains_w=tuple(gains))


@dataclass(frozen=True, kw_only=True)
class Coefficients:
    """The paper's coefficient form, per second (b in K/(W s)). Fields may be any scalar type."""

    a11: Any
    a12: Any
    a21: Any
    a22: Any
    b: Any
    c13: Any
    c11: Any = 0.0
    c12: Any = 0.0
    c21: Any = 0.0
    c22: Any = 0.0

    def to_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}


#: The paper's household ("paper_household"), from its published code.
PAPER_HOUSEHOLD = RCParams(
    r_ra_k_per_w=3.75e-3,
    r_rm_k_per_w=7.5e-4,
    c_r_j_per_k=4.0e6,
    c_m_j_per_k=1.0 / (2.0e-5 * 7.5e-4),  # a21 = 2e-5 /s
)


def to_coefficients(p: RCParams) -> Coefficients:
    """R/C values -> the paper's coefficients."""
    a12 = 1.0 / (p.c_r_j_per_k * p.r_rm_k_per_w)
    c13 = 1.0 / (p.c_r_j_per_k * p.r_ra_k_per_w)
    a21 = 1.0 / (p.c_m_j_per_k * p.r_rm_k_per_w)
    return Coefficients(
        a11=a12 + c13,
        a12=a12,
        a21=a21,
        a22=a21,
        b=p.eta / p.c_r_j_per_k,
        c13=c13,
        c11=p.solar_to_air_fraction * p.solar_aperture_m2 / p.c_r_j_per_k,
        c12=p.gain_to_air_fraction / p.c_r_j_per_k,
        c21=(1.0 - p.solar_to_air_fraction) * p.solar_aperture_m2 / p.c_m_j_per_k,
        c22=(1.0 - p.gain_to_air_fraction) / p.c_m_j_per_k,
    )


def from_coefficients(c: Coefficients, *, eta: float = 1.0) -> RCParams:
    """The paper's coefficients -> R/C values.

    ``b = eta/C_r`` does not separate eta from C_r, so eta must be given (1 for an
    electric heater, the COP for a heat pump, minus the COP for a cooling machine).
    ``a11`` is redundant with ``a12 + c13`` and ``a22`` with ``a21``; when learned
    independently they may disagree slightly, and ``a12``, ``c13``, ``a21`` are used.
    """
    values = {k: float(v) for k, v in c.to_dict().items()}
    for name in ("a12", "a21", "c13"):
        if not (math.isfinite(values[name]) and values[name] > 0):
            raise ValueError(
                f"coefficient {name} must be positive to map to R/C, got {values[name]}"
            )
    if not math.isfinite(values["b"]) or values["b"] == 0 or (values["b"] > 0) != (eta > 0):
        raise ValueError(f"coefficient b={values['b']} must be non-zero with the sign of eta={eta}")
    c_r = eta / values["b"]
    r_ra = 1.0 / (c_r * values["c13"])
    r_rm = 1.0 / (c_r * values["a12"])
    c_m = 1.0 / (r_rm * values["a21"])
    solar_air = values["c11"] * c_r
    solar_mass = values["c21"] * c_m
    aperture = max(solar_air + solar_mass, 0.0)
    alpha = min(max(solar_air / aperture, 0.0), 1.0) if aperture > 0 else 0.0
    gain_air, gain_mass = values["c12"] * c_r, values["c22"] * c_m
    gains = gain_air + gain_mass
    beta = min(max(gain_air / gains, 0.0), 1.0) if gains > 0 else 1.0
    # Through the summary keys, so an implausible result is named as export-rc would write it.
    return params_from_summary(
        {
            "R_ra_K_per_W": r_ra,
            "R_rm_K_per_W": r_rm,
            "C_r_J_per_K": c_r,
            "C_m_J_per_K": c_m,
            "eta": eta,
            "solar_aperture_m2": aperture,
            "solar_to_air_fraction": alpha,
            "gain_to_air_fraction": beta,
        }
    )


def state_space_entries(c: Coefficients) -> tuple[list[list[Any]], list[list[Any]]]:
    """Entries of the continuous-time ``A`` (2x2) and ``B`` (2x4), as nested lists.

    Works for any scalar type (float, numpy, torch, CasADi): stack them with the
    backend's own function. Input order is ``(u, T_a, G, I_g)``.
    """
    zero = 0.0 * c.b
    a = [[-c.a11, c.a12], [c.a21, -c.a22]]
    b = [[c.b, c.c13, c.c11, c.c12], [zero, zero, c.c21, c.c22]]
    return a, b


def continuous_matrices(p: RCParams | Coefficients) -> tuple[np.ndarray, np.ndarray]:
    """Continuous ``A`` (2, 2) [1/s] and ``B`` (2, 4) for ``dx/dt = A x + B d``."""
    coef = to_coefficients(p) if isinstance(p, RCParams) else p
    a, b = state_space_entries(coef)
    return np.array(a, dtype=float), np.array(b, dtype=float)


def discretise(p: RCParams | Coefficients, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation: ``x[k+1] = Ad x[k] + Bd d[k]``, d held over dt_s.

    An RC network's ``A`` has two real, negative, distinct eigenvalues l1, l2, so by
    Cayley-Hamilton ``exp(A t) = c0(t) I + c1(t) A`` with ``c1 = (e1 - e2) / (l1 - l2)``,
    ``c0 = (l1 e2 - l2 e1) / (l1 - l2)``, ``ei = exp(li t)``, and ``Bd`` is the integral of it
    over the interval times ``B``: closed forms, no matrix exponential (which, run through a
    multi-threaded BLAS on a busy machine, made identification 20 times slower). Eigenvalues
    too close for the closed form fall back on the exponential of the augmented matrix.
    """
    if not (math.isfinite(dt_s) and dt_s > 0):
        raise ValueError(f"dt_s must be a positive number of seconds, got {dt_s!r}")
    a, b = continuous_matrices(p)
    half_trace = 0.5 * (a[0, 0] + a[1, 1])
    det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    gap_sq = half_trace * half_trace - det
    if det > 0 and gap_sq > (_MIN_EIGEN_GAP * half_trace) ** 2:
        gap = math.sqrt(gap_sq)
        l1, l2 = half_trace + gap, half_trace - gap
        e1, e2 = math.exp(l1 * dt_s), math.exp(l2 * dt_s)
        i1, i2 = math.expm1(l1 * dt_s) / l1, math.expm1(l2 * dt_s) / l2  # integrals of ei
        c0, c1 = (l1 * e2 - l2 * e1) / (2 * gap), (e1 - e2) / (2 * gap)
        k0, k1 = (l1 * i2 - l2 * i1) / (2 * gap), (i1 - i2) / (2 * gap)
        eye = np.eye(N_STATES)
        return c0 * eye + c1 * a, (k0 * eye + k1 * a) @ b
    m = np.zeros((N_STATES + N_INPUTS, N_STATES + N_INPUTS))
    m[:N_STATES, :N_STATES] = a * dt_s
    m[:N_STATES, N_STATES:] = b * dt_s
    e = scipy.linalg.expm(m)
    return e[:N_STATES, :N_STATES], e[:N_STATES, N_STATES:]


#: Smallest relative gap between the eigenvalues of A for the closed-form discretisation.
_MIN_EIGEN_GAP = 1e-4


def discretise_euler(p: RCParams | Coefficients, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The paper's explicit (forward) Euler: ``Ad = I + A dt``, ``Bd = B dt``."""
    a, b = continuous_matrices(p)
    return np.eye(N_STATES) + a * dt_s, b * dt_s


def step(x: np.ndarray, d: np.ndarray, ad: np.ndarray, bd: np.ndarray) -> np.ndarray:
    """One discrete step for a batch: x (B, 2) [C], d (B, 4) -> (B, 2)."""
    return x @ ad.T + d @ bd.T


def steady_state(
    p: RCParams, *, u_w: float, t_a_c: float, g_w_per_m2: float = 0.0, i_g_w: float = 0.0
) -> np.ndarray:
    """Equilibrium ``(T_r, T_m)`` [C] for constant inputs: solves ``A x + B d = 0``."""
    a, b = continuous_matrices(p)
    d = np.array([u_w, t_a_c, g_w_per_m2, i_g_w], dtype=float)
    return np.linalg.solve(a, -b @ d)


def time_constants_h(p: RCParams | Coefficients) -> tuple[float, float]:
    """The two time constants (fast, slow) in hours, ``-1/eigenvalue`` of A."""
    a, _ = continuous_matrices(p)
    eig = np.sort(np.real(np.linalg.eigvals(a)))
    slow, fast = -1.0 / eig[1] / 3600.0, -1.0 / eig[0] / 3600.0
    return float(fast), float(slow)


#: rc_summary keys -> RCParams fields.
SUMMARY_KEYS = {
    "R_ra_K_per_W": "r_ra_k_per_w",
    "R_rm_K_per_W": "r_rm_k_per_w",
    "C_r_J_per_K": "c_r_j_per_k",
    "C_m_J_per_K": "c_m_j_per_k",
    "eta": "eta",
    "solar_aperture_m2": "solar_aperture_m2",
    "solar_to_air_fraction": "solar_to_air_fraction",
    "gain_to_air_fraction": "gain_to_air_fraction",
}


def rc_summary(p: RCParams, *, source: str) -> RcSummary:
    """The RC JSON schema shared by ``export-rc`` and ``identify``
    (:class:`pinn_mpc.records.RcSummary`)."""
    coef = to_coefficients(p)
    fast, slow = time_constants_h(p)
    summary = {
        **{key: getattr(p, field) for key, field in SUMMARY_KEYS.items()},
        **({"unmeasured_gains_W": list(p.unmeasured_gains_w)} if p.unmeasured_gains_w else {}),
        "coefficients_per_s": coef.to_dict(),
        "time_constants_h": {"fast": fast, "slow": slow},
        "source": source,
    }
    return cast(RcSummary, summary)  # the parameters by SUMMARY_KEYS


def params_from_summary(data: Mapping[str, Any]) -> RCParams:
    """Inverse of :func:`rc_summary` (the keys it needs); an InputError names the JSON key as
    written and its problem (missing, not a number, negative, outside the plausible range)."""
    required = list(SUMMARY_KEYS)[:4]
    missing = [k for k in required if k not in data]
    if missing:
        raise InputError(f"RC JSON lacks key(s) {missing}; expected the schema of export-rc")
    values = {
        field: check_plausible(field, data[key], name=key)
        for key, field in SUMMARY_KEYS.items()
        if key in data
    }
    gains = data.get("unmeasured_gains_W", [])
    if not isinstance(gains, list) or not all(
        isinstance(g, int | float) and not isinstance(g, bool) for g in gains
    ):
        raise InputError(f"unmeasured_gains_W: expected a list of numbers [W], got {gains!r}")
    return RCParams(**values, unmeasured_gains_w=tuple(gains))


def read_rc_json(path: str | os.PathLike[str]) -> tuple[RCParams, dict[str, Any]]:
    """The parameters of the RC JSON at ``path`` (written by ``identify`` / ``export-rc``,
    :func:`pinn_mpc.artifacts.read_rc`) and the JSON object they were read from."""
    source = Path(path)
    if not source.is_file():
        raise InputError(
            f"{source}: no such RC file; write one with `pinn-mpc identify` or `pinn-mpc export-rc`"
        )
    try:
        data = json.loads(source.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(
            f"{source}: not valid JSON ({exc}); expected the RC JSON of identify or export-rc"
        ) from exc
    if not isinstance(data, dict):
        raise InputError(
            f"{source}: expected a JSON object of RC parameters, got {type(data).__name__}"
        )
    try:
        return params_from_summary(data), data
    except InputError as exc:
        raise InputError(f"{source}: {exc.marked}") from exc
