"""Grey-box identification of 2R2C parameters from data in which ``T_m`` is hidden.

Output-error method: the exact zero-order-hold model (:func:`pinn_mpc.physics.discretise`) is
simulated over the whole data set from ``(T_r[0], T_m0)`` with the measured inputs held over
each interval (``u_phys``, the interval-mean delivered power, ``T_a`` and, when present, ``G``
and ``I_g``), and the simulated room temperature is fitted to the measured one by
:func:`scipy.optimize.least_squares` in log-parameters. Unknowns: ``R_ra, R_rm, C_r, C_m``,
the unknown initial ``T_m0`` and, when the columns exist and vary, the solar aperture, the
solar fraction to the air and the internal-gain fraction to the air. A ``T_m`` column, if any,
is ignored. ``eta`` is not identifiable (only ``eta/C_r`` is) and must be given.

Unmeasured internal gains: where the data have no varying ``I_g`` but span enough days of both
kinds (:func:`gain_schedule_applies`), a second fit also finds a schedule of internal gains
(:attr:`pinn_mpc.physics.RCParams.unmeasured_gains_w`, two-hour blocks of a workday and of a
weekend day or holiday, each >= 0) and their share to the air. The simulated room temperature is
linear in the gains, so for each R/C candidate the best schedule is a non-negative linear least
squares (variable projection): the nonlinear search keeps its size. The schedule is kept where
the Bayesian information criterion prefers it (its values count as parameters). Without it an office's
occupants, lights and equipment are read as sun through a large window.

Initial guess: the steady-state gain ``R_ra`` and the solar aperture come from a day-averaged
energy balance (a linear regression); the split into fast and slow parts is found by a few
short least-squares starts over a small grid of time constants, the best of which is refined.

The model ignores what happens inside an interval (e.g. a backup thermostat switching the
heater on for part of it), so the fit residual is not pure sensor noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd
import scipy.optimize

from pinn_mpc.data import day_of_week, frame_scheduled_gains_w, schedule_one_hot
from pinn_mpc.errors import InputError, InternalError, PinnMpcWarning, setting
from pinn_mpc.physics import (
    GAIN_BLOCK_H,
    GAIN_SCHEDULE_LENGTH,
    PLAUSIBLE_RANGES,
    RCParams,
    check_plausible,
    discretise,
)

__all__ = [
    "MIN_SCHEDULE_DAYS",
    "POOR_FIT_RMSE_C",
    "IdentifyResult",
    "check_power_sign",
    "frame_gains_w",
    "gain_schedule_applies",
    "identify_rc",
    "simulate_rc",
]

#: Below this standard deviation a G or I_g column counts as constant (not identifiable).
_MIN_STD = {"G": 1.0, "I_g": 1.0}
#: Grid of starting points: C_r as a fraction of the total capacity, R_rm as a fraction of R_ra.
_C_R_FRACTIONS = (0.02, 0.08, 0.3)
_R_RM_FRACTIONS = (0.1, 0.4)
#: The log-parameters of R and C, with their RCParams field and rc.json key.
_LOG_RC = {
    "ln_r_ra": ("r_ra_k_per_w", "R_ra_K_per_W"),
    "ln_r_rm": ("r_rm_k_per_w", "R_rm_K_per_W"),
    "ln_c_r": ("c_r_j_per_k", "C_r_J_per_K"),
    "ln_c_m": ("c_m_j_per_k", "C_m_J_per_K"),
}
#: Margin [log units] that keeps exp(bound) inside the plausible range despite rounding.
_EDGE = 1e-9
#: The output-error RMSE [C] above which an identified 2R2C does not describe the building.
#: Measured with `identify` on 14 and 30 days (seeds 0-2) of `simulate`'s data of each built-in
#: scenario: the 2R2C buildings 0.013-0.077 C, the 3R3C plant (mismatch_household) 0.24-0.27 C,
#: EnergyPlus's mid-rise apartment 0.29-0.50 C, its small office (five zones in one, unmeasured
#: gains) 1.34-1.71 C; with the unmeasured-gain schedule (below) the office 0.6-0.7 C and the
#: apartment 0.16-0.20 C on 14 and 17 January days (seeds 0-1).
POOR_FIT_RMSE_C = 1.0
#: Days of data (at least one workday and one weekend day or holiday among them) from which an
#: unmeasured-gain schedule is identified. Measured on EnergyPlus's small office, mid-rise
#: apartment, stand-alone retail and warehouse in January (fits on 3, 7, 14 and 17 days, the
#: next days' 6 h and 12 h Kalman-filtered predictions): with the schedule the error fell in
#: every case but one equal, from 3 days on (the office's 12 h error from 1.86 to 1.43 C on 3
#: days, from 1.61 to 0.81 C on 14).
MIN_SCHEDULE_DAYS = 3


@dataclass(frozen=True, kw_only=True)
class IdentifyResult:
    """Identified parameters and fit statistics."""

    params: RCParams
    rmse_c: float  # output-error RMSE of the simulated T_r over the data [C]
    n_rows: int
    t_m0_c: float  # identified initial thermal-mass temperature [C]
    identified_solar: bool
    identified_gains: bool
    n_starts: int
    cost_evaluations: int
    notes: tuple[str, ...] = ()  # what a user should know of the fit (a mass at its edge)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rmse_c) and self.rmse_c >= 0):
            raise InternalError(f"IdentifyResult.rmse_c must be finite and >= 0, got {self.rmse_c}")

    def poor_fit_note(self) -> PinnMpcWarning | None:
        """What to do about a fit whose RMSE exceeds :data:`POOR_FIT_RMSE_C` (None below it):
        the 2R2C does not describe the building, so an RC MPC on it plans on a poor model. A
        warning to give :func:`~pinn_mpc.errors.warn` (``str()`` is its text), since it names a
        setting (the command line names its flag)."""
        if self.rmse_c <= POOR_FIT_RMSE_C:
            return None
        return PinnMpcWarning(
            f"identify: the identified 2R2C reproduces the data with an rmse of "
            f"{self.rmse_c:.2f} C, above {POOR_FIT_RMSE_C:g} C (simulated buildings fit within "
            "0.3 C, EnergyPlus's apartment within 0.5 C): a 2R2C does not describe this "
            "building, and qp-mpc or casadi-mpc on it plan on a poor model. Check that the "
            f"columns are the room temperature and the heating power delivered ({setting('columns')}); "
            "give more days; or plan over a model that fits: `pinn-mpc train` (its default takes the "
            "physics-informed ARX where that predicts better), then qp-mpc or cem over it"
        )

    def fit_statistics(self) -> dict[str, Any]:
        return {
            "method": "output-error least squares, exact ZOH 2R2C, T_m hidden",
            "rmse_c": self.rmse_c,
            "n_rows": self.n_rows,
            "t_m0_c": self.t_m0_c,
            "identified_solar": self.identified_solar,
            "identified_gains": self.identified_gains,
            "unmeasured_gains": bool(self.params.unmeasured_gains_w),
            "n_starts": self.n_starts,
            "cost_evaluations": self.cost_evaluations,
            "notes": list(self.notes),
        }


def gain_schedule_applies(df: pd.DataFrame) -> bool:
    """Whether :func:`identify_rc` identifies an unmeasured-gain schedule from ``df`` (a frame in
    the data format): no varying ``I_g`` column, and :data:`MIN_SCHEDULE_DAYS` days with at least
    one workday and one weekend day or holiday."""
    if _varies(df, "I_g") or "time" not in df.columns:
        return False
    days = pd.to_datetime(df["time"]).dt.floor("D")
    dow = day_of_week(days.to_numpy(), df["holiday"].to_numpy() if "holiday" in df else None)
    kinds = pd.Series(dow >= 5).groupby(days.to_numpy()).max()
    return len(kinds) >= MIN_SCHEDULE_DAYS and int(kinds.sum()) >= 1 and int((~kinds).sum()) >= 1


def frame_gains_w(params: RCParams, df: pd.DataFrame) -> np.ndarray:
    """(N,) the internal gains [W] the RC ``params`` takes on each row of ``df`` (a frame in the
    data format): its ``I_g`` (0 without one) plus the unmeasured gains of the row's block."""
    return frame_scheduled_gains_w(df, params.unmeasured_gains_w)


def _schedule_one_hot(df: pd.DataFrame) -> np.ndarray:
    """(N, GAIN_SCHEDULE_LENGTH) one-hot of each row's block of the gain schedule."""
    return schedule_one_hot(df, 2, GAIN_BLOCK_H)


def _gain_responses(ad: np.ndarray, bd: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """(N, K) the room temperature's response [K] from a zero start to 1 kW of internal gains in
    each block of ``basis`` (N, K) (:func:`simulate_rc`'s modal form, all blocks at once)."""
    import scipy.signal

    lam, v = np.linalg.eig(ad)
    lam, v = np.real(lam), np.real(v)
    modal = np.linalg.inv(v) @ bd[:, 3] * 1000.0
    out = np.zeros_like(basis)
    for i in range(2):
        out += v[0, i] * scipy.signal.lfilter([1.0], [1.0, -lam[i]], basis * modal[i], axis=0)
    return out


def simulate_rc(
    ad: np.ndarray, bd: np.ndarray, x0: np.ndarray, d: np.ndarray
) -> np.ndarray:
    """Free-run ``x[k+1] = Ad x[k] + Bd d[k]``: x0 (2,), d (N, 4) -> states (N+1, 2) [C].

    Uses the modal form (the eigenvalues of an RC network's ``Ad`` are real, distinct and in
    (0, 1)), so each mode is a first-order recursion run by :func:`scipy.signal.lfilter`.
    """
    import scipy.signal  # here, not at the top: every command imports this module, few call this

    lam, v = np.linalg.eig(ad)
    lam, v = np.real(lam), np.real(v)
    v_inv = np.linalg.inv(v)
    w = (d @ bd.T) @ v_inv.T  # (N, 2) modal inputs
    z0 = v_inv @ x0
    n = d.shape[0]
    powers = lam[None, :] ** np.arange(n + 1)[:, None]  # (N+1, 2)
    z = powers * z0[None, :]
    for i in range(2):
        z[1:, i] += scipy.signal.lfilter([1.0], [1.0, -lam[i]], w[:, i])
    return z @ v.T


class _Layout:
    """Which unknowns the parameter vector holds, and the map to RCParams."""

    def __init__(self, *, solar: bool, gains: bool, eta: float) -> None:
        self.solar, self.gains, self.eta = solar, gains, eta
        self.names = ["ln_r_ra", "ln_r_rm", "ln_c_r", "ln_c_m"]
        if solar:
            self.names += ["ln_aperture", "solar_to_air"]
        if gains:
            self.names += ["gain_to_air"]
        self.names += ["t_m0"]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """R and C search only their plausible ranges (:data:`physics.PLAUSIBLE_RANGES`)."""
        lo = {"solar_to_air": 0.0, "gain_to_air": 0.0, "t_m0": -60.0, "ln_aperture": -12.0}
        hi = {"solar_to_air": 1.0, "gain_to_air": 1.0, "t_m0": 90.0, "ln_aperture": 8.0}
        for name, (field, _) in _LOG_RC.items():
            low, high, _unit = PLAUSIBLE_RANGES[field]
            lo[name], hi[name] = math.log(low) + _EDGE, math.log(high) - _EDGE
        lower = np.array([lo[n] for n in self.names])
        upper = np.array([hi[n] for n in self.names])
        return lower, upper

    def check_inside(self, theta: np.ndarray) -> tuple[str, ...]:
        """A fit that ends on the edge of a plausible range wanted a value beyond it: refuse,
        except for a thermal mass at its largest capacity, the one edge with a physical
        meaning (the mass is slower than the data show: its temperature stays at its start
        over the data's span); that fit is kept and a note returned."""
        lower, upper = self.bounds()
        notes: list[str] = []
        for i, name in enumerate(self.names):
            if name not in _LOG_RC or lower[i] + 1e-6 < theta[i] < upper[i] - 1e-6:
                continue
            field, key = _LOG_RC[name]
            low, high, unit = PLAUSIBLE_RANGES[field]
            if name == "ln_c_m" and theta[i] >= upper[i] - 1e-6:
                notes.append(
                    f"identify: the thermal mass ran to its largest plausible capacity "
                    f"({high:g} {unit}): over these data its temperature barely moves from its "
                    "start, so the mass acts as a fixed-temperature boundary; more days, or data "
                    "that move the building's temperature for longer, would resolve it"
                )
                continue
            raise InputError(
                f"identify: the fit ran into the edge of the plausible range of {key} "
                f"({low:g} .. {high:g} {unit}) at {math.exp(theta[i]):.4g} {unit}: the data do "
                "not determine the building; check the units of power (W) and time, and that "
                "the power varies enough over several days"
            )
        return tuple(notes)

    def params(self, theta: np.ndarray) -> RCParams:
        v = dict(zip(self.names, theta, strict=True))
        return RCParams(
            r_ra_k_per_w=math.exp(v["ln_r_ra"]),
            r_rm_k_per_w=math.exp(v["ln_r_rm"]),
            c_r_j_per_k=math.exp(v["ln_c_r"]),
            c_m_j_per_k=math.exp(v["ln_c_m"]),
            eta=self.eta,
            solar_aperture_m2=math.exp(v["ln_aperture"]) if self.solar else 0.0,
            solar_to_air_fraction=float(v["solar_to_air"]) if self.solar else 0.0,
            gain_to_air_fraction=float(v["gain_to_air"]) if self.gains else 1.0,
        )

    def starts(self, *, r_ra: float, c_tot: float, aperture: float, t_m0: float) -> list[np.ndarray]:
        """The grid of starting points around an energy balance's ``R_ra`` [K/W], total
        capacity ``c_tot`` [J/K] and ``aperture`` [m2]: C_r a fraction of the capacity
        (:data:`_C_R_FRACTIONS`), R_rm a fraction of R_ra (:data:`_R_RM_FRACTIONS`), half of
        the sun and the gains to the air, the mass at ``t_m0`` [C]; each inside the bounds."""
        lower, upper = self.bounds()
        starts = []
        for f_c in _C_R_FRACTIONS:
            for f_r in _R_RM_FRACTIONS:
                theta = [math.log(r_ra), math.log(f_r * r_ra), math.log(f_c * c_tot),
                         math.log((1 - f_c) * c_tot)]
                theta += [math.log(aperture), 0.5] if self.solar else []
                theta += [0.5] if self.gains else []
                theta += [t_m0]
                starts.append(np.clip(np.array(theta), lower + 1e-9, upper - 1e-9))
        return starts


def _best_start(
    residuals: Any, starts: list[np.ndarray], bounds: tuple[np.ndarray, np.ndarray]
) -> tuple[Any, int]:
    """The best of a few short least-squares runs (15 evaluations each) of ``residuals`` from
    ``starts``: ``(scipy's result, evaluations spent)``."""
    evaluations = 0
    best: Any = None
    for theta0 in starts:
        fit = scipy.optimize.least_squares(residuals, theta0, bounds=bounds, max_nfev=15)
        evaluations += fit.nfev
        if best is None or fit.cost < best.cost:
            best = fit
    return best, evaluations


def _varies(df: pd.DataFrame, column: str) -> bool:
    return column in df.columns and float(df[column].std()) > _MIN_STD[column]


def _energy_balance_guess(
    t_r: np.ndarray, d: np.ndarray, dt_s: float, *, eta: float, solar: bool
) -> tuple[float, float, float]:
    """Day-averaged balance ``eta u + A G + I_g = (T_r - T_a)/R_ra + C_tot dT_r/dt`` -> (R_ra, A, C_tot)."""
    per_day = max(int(round(86400.0 / dt_s)), 1)
    n_days = (len(d)) // per_day
    if n_days < 3:
        per_day = max(len(d) // 6, 1)
        n_days = len(d) // per_day
    m = n_days * per_day

    def day(a: np.ndarray) -> np.ndarray:
        return a[:m].reshape(n_days, per_day).mean(axis=1)

    heat = eta * day(d[:, 0]) + day(d[:, 3])
    loss = day(t_r[:-1]) - day(d[:, 1])
    rate = (t_r[per_day : m + 1 : per_day] - t_r[0:m:per_day]) / (per_day * dt_s)
    columns = [loss, rate] + ([-day(d[:, 2])] if solar else [])
    coef, *_ = np.linalg.lstsq(np.stack(columns, axis=1), heat, rcond=None)
    r_ra = 1.0 / coef[0] if coef[0] > 0 else 0.01
    c_tot = coef[1] if coef[1] > 0 else 3600.0 * 50.0 / r_ra  # a 50 h time constant
    aperture = coef[2] if solar and coef[2] > 0 else 1.0
    return float(r_ra), float(c_tot), float(aperture)


def _heat(df: pd.DataFrame) -> np.ndarray:
    """The power the building receives per unit of eta [W]: ``u_phys``, times ``cop`` if given."""
    heat = df["u_phys"].to_numpy(float)
    return heat * df["cop"].to_numpy(float) if "cop" in df.columns else heat


#: |t| of the power's effect on the next room temperature above which its sign is certain.
_SIGN_T_STAT = 5.0


def _disturbances(df: pd.DataFrame) -> np.ndarray:
    """(N-1, 4) each interval's heat per unit of eta [W], T_a [C], G [W/m2] and I_g [W] (zeros
    for a column the data lack), the last row's left out."""
    zeros = np.zeros(len(df))
    return np.stack(
        [
            _heat(df),
            df["T_a"].to_numpy(float),
            df["G"].to_numpy(float) if "G" in df.columns else zeros,
            df["I_g"].to_numpy(float) if "I_g" in df.columns else zeros,
        ],
        axis=1,
    )[:-1]


def check_power_sign(df: pd.DataFrame, eta: float, *, what: str = "identify") -> None:
    """Refuse an ``eta`` whose sign contradicts the data (a frame in the data format): regress
    each step's change of T_r on the power, the outdoor-room difference, G, I_g and a constant;
    a clearly positive power coefficient means the actuator heats, a clearly negative one that
    it cools. The InputError starts with ``what`` (the model being fitted) and names the eta
    that fits; every model fitted on power checks it, so all say the same."""
    t_r = df["T_r"].to_numpy(float)
    d = _disturbances(df)
    columns = [d[:, 0], d[:, 1] - t_r[:-1], np.ones(len(d))]
    columns += [d[:, k] for k in (2, 3) if np.std(d[:, k]) > 0]
    x = np.stack(columns, axis=1)
    y = np.diff(t_r)
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    dof = len(y) - x.shape[1]
    if dof < 1:
        return
    sigma2 = float(np.sum(np.square(y - x @ coef))) / dof
    cov = sigma2 * np.linalg.pinv(x.T @ x)
    t_stat = coef[0] / math.sqrt(max(float(cov[0, 0]), 1e-300))
    if t_stat * eta < 0 and abs(t_stat) > _SIGN_T_STAT:
        heats = t_stat > 0
        raise InputError(
            f"{what}: eta = {eta:g} says the actuator {'cools' if eta < 0 else 'heats'}, but "
            f"in the data more power {'warms' if heats else 'cools'} the room (t = {t_stat:.0f}); "
            + (
                f"for a heater leave {setting('eta')} out (1) or give the heat per W (> 0)"
                if heats
                else f"for a cooling machine give {setting('eta')} -COP, e.g. {setting('eta')} -2.5"
            )
        )


class _Problem:
    """One data set's output-error fit (:func:`identify_rc`), with or without a gain schedule."""

    def __init__(self, df: pd.DataFrame, dt_s: float, *, eta: float, solar: bool, gains: bool) -> None:
        self.dt_s, self.eta, self.solar, self.gains = dt_s, eta, solar, gains
        self.d = _disturbances(df)
        self.t_r = df["T_r"].to_numpy(float)

    def fit(self, basis: np.ndarray | None) -> IdentifyResult:
        """The fit; with ``basis`` ((N-1, K) each interval's block, one-hot) also the
        unmeasured-gain schedule."""
        dt_s, d, t_r, n_rows = self.dt_s, self.d, self.t_r, len(self.t_r)
        layout = _Layout(solar=self.solar, gains=self.gains or basis is not None, eta=self.eta)
        lower, upper = layout.bounds()

        def fit_of(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """The residuals of ``theta`` [K] and its best gain schedule [kW] (empty without one)."""
            p = layout.params(theta)
            ad, bd = discretise(p, dt_s)
            x = simulate_rc(ad, bd, np.array([t_r[0], theta[-1]]), d)
            res = x[1:, 0] - t_r[1:]
            if basis is None or not np.all(np.isfinite(res)):
                return res, np.zeros(0)
            responses = _gain_responses(ad, bd, basis)
            schedule_kw, _ = scipy.optimize.nnls(responses, -res)
            return res + responses @ schedule_kw, schedule_kw

        def residuals(theta: np.ndarray) -> np.ndarray:
            try:
                res, _ = fit_of(theta)
            except (InputError, np.linalg.LinAlgError, RuntimeError):
                return np.full(n_rows - 1, 1e3)
            return np.where(np.isfinite(res), res, 1e3)

        r_ra, c_tot, aperture = _energy_balance_guess(t_r, d, dt_s, eta=self.eta, solar=self.solar)
        starts = layout.starts(r_ra=r_ra, c_tot=c_tot, aperture=aperture, t_m0=float(t_r[0]))
        best, evaluations = _best_start(residuals, starts, (lower, upper))
        final = scipy.optimize.least_squares(
            residuals, best.x, bounds=(lower, upper), xtol=1e-10, ftol=1e-12, max_nfev=400
        )
        evaluations += final.nfev
        notes = layout.check_inside(final.x)
        params = layout.params(final.x)
        if basis is not None:
            _, schedule_kw = fit_of(final.x)
            params = replace(params, unmeasured_gains_w=tuple(float(g) * 1000.0 for g in schedule_kw))
        return IdentifyResult(
            params=params,
            rmse_c=float(np.sqrt(np.mean(np.square(final.fun)))),
            n_rows=n_rows,
            t_m0_c=float(final.x[-1]),
            identified_solar=self.solar,
            identified_gains=self.gains,
            n_starts=len(starts),
            cost_evaluations=evaluations,
            notes=notes,
        )


def identify_rc(
    df: pd.DataFrame, *, eta: float = 1.0, unmeasured_gains: bool = True
) -> IdentifyResult:
    """Identify 2R2C parameters from data, with the mass temperature hidden.

    Parameters
    ----------
    df
        A validated frame (columns time, T_r, u_phys, T_a, [G, I_g, cop]);
        ``df.attrs['dt_s']`` (set by :func:`pinn_mpc.data.validate_timeseries`) is the step.
        A ``T_m`` column is never used; a ``cop`` column (a heat pump's heat per electrical
        watt) makes the input the delivered heat ``cop`` x ``u_phys``.
    eta
        Heat per W of actuator power: 1 for an electric heater, minus the COP for a cooling
        machine. One whose sign the data contradict is refused.
    unmeasured_gains
        Identify a schedule of unmeasured internal gains where the data allow it
        (:func:`gain_schedule_applies`) and keep it where the information criterion prefers it
        (the module docstring). False for an RC that only seeds a learned model's physics.

    Returns
    -------
    IdentifyResult
        The parameters and the fit.

    Raises
    ------
    InputError
        Missing columns, several buildings, too few rows, unexcited or contradicting data.
    """
    eta = check_plausible("eta", eta, name=f"identify: {setting('eta')}")
    missing = [c for c in ("T_r", "u_phys", "T_a") if c not in df.columns]
    if missing:
        raise InputError(f"identify: data lacks column(s) {missing}; see the data format")
    if "building" in df.columns and df["building"].nunique() > 1:
        raise InputError(
            f"identify: data holds {df['building'].nunique()} buildings (column 'building'); "
            "identify one building at a time (keep the rows of one building)"
        )
    dt_s = float(df.attrs.get("dt_s", 0.0))
    if not dt_s > 0:
        raise ValueError("identify: the frame has no attrs['dt_s']; read it with read_timeseries")
    n_rows = len(df)
    if n_rows < 48:
        raise InputError(f"identify: needs at least 48 rows (a day at 30 min), got {n_rows}")
    if float(df["u_phys"].std()) == 0.0:
        raise InputError("identify: u_phys is constant, so the building's response is not excited")
    solar, gains = _varies(df, "G"), _varies(df, "I_g")
    check_power_sign(df, eta)
    problem = _Problem(df, dt_s, eta=eta, solar=solar, gains=gains)
    if not (unmeasured_gains and gain_schedule_applies(df)):
        return problem.fit(None)
    basis = _schedule_one_hot(df)[:-1]  # each interval's block
    try:
        plain = problem.fit(None)
    except InputError:
        return problem.fit(basis)  # raises where neither fits
    try:
        scheduled = problem.fit(basis)
    except InputError:
        return plain
    return scheduled if _schedule_pays(plain, scheduled) else plain


# A 10 % cut of the RMSE as the rule kept a schedule of noise on 3 days of paper_household (no
# gains at all: cuts of 12-26 %, the RC's 12 h prediction error doubled); the criterion keeps
# none there (3-60 days, seeds 0-2) and keeps the EnergyPlus buildings' (see the CHANGELOG).
def _schedule_pays(plain: IdentifyResult, scheduled: IdentifyResult) -> bool:
    """Whether the fit with the gain schedule is the better model by the Bayesian information
    criterion, ``n ln(RSS) + k ln(n)``: the schedule's values and its share to the air count
    as its ``k``, so a few days of noise do not buy one."""
    n = plain.n_rows - 1
    k = GAIN_SCHEDULE_LENGTH + int(not plain.identified_gains)
    rss_ratio = (scheduled.rmse_c / max(plain.rmse_c, 1e-300)) ** 2
    return n * math.log(max(rss_ratio, 1e-300)) + k * math.log(n) < 0.0
