"""A linear ARX model of the room temperature: the simplest strong baseline.

Physics-informed linear regression is the known-competitive baseline of building MPC: the next
room temperature as a linear function of the last ``lags`` room temperatures, delivered powers
and weather values, plus a weekly schedule standing in for unmeasured internal gains
(occupancy, equipment, lighting)::

    T_r,k+1 = sum_j a_j T_r,k-j + sum_j b_j u_phys,k-j + sum_j c_j T_a,k-j + sum_j d_j G,k-j
              [+ sum_f sum_j d_f,j G_f,k-j] [+ sum_j e_j I_g,k-j]
              + s(block of day of t_k, workday of t_k)

with ``j = 0 .. lags-1``, ``G_f`` the irradiance on each facade ``f`` where the data has it
(:mod:`pinn_mpc.solar`: what the windows of each side let in) and ``s`` one coefficient per
block of the day (2 hours unless the model says otherwise), separately for workdays
(Monday-Friday) and weekends. A building's holidays (the data's ``holiday`` column, the
forecast's day of the week 6) count as Sundays, as reference buildings run their
Sunday-or-holiday schedules on them.

The physics-informed variant (:func:`fit_physics_informed_arx`) adds what a building's
unmeasured occupancy does besides adding heat: ventilation and infiltration that follow the
occupancy schedule scale the heat loss, so each schedule block gets a second coefficient on the
indoor-outdoor difference, ``+ q(block) (T_r,k - T_a,k)``; and where the data has the wind
speed (``wind``, an EnergyPlus building's weather file), infiltration that the wind drives
(as the DOE reference buildings' does) adds ``+ c_w wind_k (T_r,k - T_a,k)``. It chooses by cross-validation
on its own training data whether to take the facades' irradiance instead of ``G``, then by
Akaike's information criterion of its one-step fit whether its schedule tells Saturdays
from Sundays (reference office and retail buildings run a Saturday schedule of their own; the
two are then pooled towards one weekend schedule as far as the same criterion says) and
the schedule's block length (1 or 2 hours: an office's hourly schedules against fewer
coefficients to fit). The fit must
say that more power warms the room (the sum of the power's coefficients positive, as a heater
does; negative for a cooling machine), or it is refused. It is fitted by least squares on the one-step error
(a tiny ridge keeps it well posed), has no hidden state and no network, and is linear in the
power, so it predicts any power plan by recursion. :func:`fit_arx` fits it,
:meth:`ARXModel.predict_t_r` predicts ``h`` steps ahead from given starts; it serves as the
reference every learned model of a comparison must beat (:mod:`scenarios.experiments.prediction`).
:meth:`ARXModel.rollout` is the planners' rollout interface, so ``cem`` and
``random-shooting`` plan over it (its schedule reads the forecast's day of the week).
Being linear in the lagged ``T_r`` and power, its horizon is an affine map of a power plan
(:meth:`ARXModel.prediction_matrices`), so ``qp-mpc`` plans on it as a QP
(:mod:`controllers.arx_mpc`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd
import torch

from pinn_mpc.data import WIND
from pinn_mpc.data import schedule_index as _schedule_index
from pinn_mpc.data import schedule_one_hot as _schedule
from pinn_mpc.errors import InputError, InternalError, setting
from pinn_mpc.features import check_interval
from pinn_mpc.io import DirectoryLayout
from pinn_mpc.models.registry import ARX, BASELINES, PHYSICS_ARX
from pinn_mpc.models.rollout import FittedModel, Rollout
from pinn_mpc.physics import params_from_summary
from pinn_mpc.solar import FACADE_COLUMNS

__all__ = [
    "AIC_RESOLUTION_C",
    "ARX_DIRECTORY",
    "ARX_FILE",
    "ARXModel",
    "BLOCK_CHOICES_H",
    "BLOCK_H",
    "DEFAULT_LAGS",
    "MEASURED_INPUTS",
    "MIN_LAGS",
    "POOL_CHOICES",
    "SELECTION_FOLDS",
    "SELECTION_HORIZON_S",
    "SELECTION_SHARE",
    "TooFewRowsError",
    "fit_arx",
    "fit_linear",
    "fit_physics_informed_arx",
    "is_arx_directory",
    "load_arx",
    "save_arx",
    "schedule_aic",
]

#: The file of an ARX model directory (``train --arch arx``): numbers only, no code.
ARX_FILE = "arx.json"
#: What ``train --arch arx`` writes.
ARX_DIRECTORY = DirectoryLayout(kind="ARX model directory", files=(ARX_FILE,), markers=(ARX_FILE,))

#: Lags of every input (4 h at 30-min intervals).
DEFAULT_LAGS = 8
#: The fewest lags the physics-informed ARX falls back to, halving :data:`DEFAULT_LAGS`, where
#: the data are too few for the default's coefficients (a few days, an online run's first
#: nights).
MIN_LAGS = 2
#: Length of one block of the daily schedule [h], unless a model says otherwise; the
#: schedule has one coefficient per block for workdays, then one per block for weekends.
BLOCK_H = 2.0
#: The block lengths [h] the physics-informed ARX chooses from (each divides the day).
BLOCK_CHOICES_H = (1.0, 2.0)
#: The largest coefficient magnitude a saved ARX model may hold (scaled units, :data:`_SCALE`):
#: fits give well under 10; a larger one is an edited or damaged file.
MAX_ABS_COEF = 1e3
#: The architecture setting, as a message that says how to make an ARX again names it.
_ARCH = setting("arch")
#: Ridge weight relative to each regressor's own sum of squares (keeps collinear lags well posed).
_RIDGE = 1e-9
#: The strengths of the pooling of Saturdays and Sundays (:func:`fit_arx`'s ``pool``) the
#: physics-informed ARX chooses from, with none, by Akaike's criterion on the fit's effective
#: number of coefficients (:func:`schedule_aic`).
POOL_CHOICES = (0.005, 0.01, 0.02, 0.05)
#: Scales that bring the inputs to order one: W -> kW, W/m2 -> 100 W/m2, W -> kW.
_SCALE = {
    "T_r": 1.0, "u_phys": 1e-3, "T_a": 1.0, "G": 1e-2, **dict.fromkeys(FACADE_COLUMNS, 1e-2),
    "I_g": 1e-3, WIND: 0.1,
}
#: The measured inputs a fit takes when the data has them, in this order after ``T_a``.
MEASURED_INPUTS = ("G", "I_g")
#: Order of every optional input in a model's columns (the facades' after ``G``).
_INPUT_ORDER = ("G", *FACADE_COLUMNS, "I_g")
#: Share of the training data a model choice holds out (:mod:`pinn_mpc.model_choice`), the
#: consecutive parts the physics-informed ARX's cross-validation cuts it into, and the horizon
#: [s] of the prediction both judge by (12 h, the comparison's 24 steps).
SELECTION_SHARE = 0.25
SELECTION_FOLDS = 4
SELECTION_HORIZON_S = 12 * 3600.0
#: One-step errors [K] below this (far below any room sensor's resolution) count as exact when
#: the physics-informed ARX compares schedules, so fits exact up to rounding compare by their
#: number of coefficients alone.
AIC_RESOLUTION_C = 1e-3


def _blocks(block_h: float) -> int:
    """Blocks of a day of ``block_h`` hours."""
    return int(round(24 / block_h))


def _n_coef(
    lags: int, n_columns: int, day_types: int, block_h: float, interaction: bool, wind: bool = False
) -> int:
    """Coefficients of an ARX model: its lags of every column, then its schedule (and as many
    interaction weights, if any), then the wind's weight (if any)."""
    return lags * n_columns + day_types * _blocks(block_h) * (2 if interaction else 1) + int(wind)


@dataclass(frozen=True, kw_only=True, slots=True)
class ARXModel(FittedModel):
    """A fitted ARX model (module docstring).

    ``columns`` the lagged inputs in order (``T_r`` first, then ``u_phys``, ``T_a``, weather,
    gains); ``lags`` per input; ``coef`` (lags * len(columns) + schedule columns [+ as many
    interaction columns],) in scaled units; ``dt_s`` the interval it steps; ``train_mae_c`` its
    one-step MAE on the training data; ``day_types`` 2 (workdays, weekends) or 3 (workdays,
    Saturdays, Sundays); ``interaction`` whether each schedule block also weighs
    ``T_r,k - T_a,k`` (the physics-informed variant, module docstring); ``block_h`` the length
    of the schedule's blocks [h]; ``wind`` whether the last coefficient weighs
    ``wind_k (T_r,k - T_a,k)`` (wind-driven infiltration). A planner's
    :class:`~pinn_mpc.models.rollout.BatchDynamics`, affine in the plan
    (:meth:`prediction_matrices`), and a :class:`~pinn_mpc.models.rollout.FittedModel`
    (:attr:`family`: ``parx`` with ``interaction``, else ``arx``). Slotted: the fields shadow
    the protocol's properties.
    """

    affine_in_plan: ClassVar[bool] = True

    columns: tuple[str, ...]
    lags: int
    coef: np.ndarray
    dt_s: float
    train_mae_c: float
    day_types: int = 2
    interaction: bool = False
    block_h: float = BLOCK_H
    wind: bool = False
    identified_rc: dict[str, Any] | None = None
    training_data: dict[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def family(self) -> str:
        """``parx`` (the physics-informed variant, :attr:`interaction`) or ``arx``."""
        return PHYSICS_ARX.name if self.interaction else ARX.name

    @property
    def n_schedule(self) -> int:
        """Coefficients of the schedule (and as many of its interaction, if any)."""
        return self.day_types * _blocks(self.block_h)

    def settling_radius(self) -> float:
        """The largest magnitude of the room temperature's poles over the schedule's blocks
        (the lags of ``T_r``, plus each block's interaction weight on the latest): below 1 the
        model's room temperature settles after a change, at or above 1 it never does."""
        n_col = len(self.columns)
        a = self.coef[0 : self.lags * n_col : n_col]
        radius = 0.0
        for q in np.unique(self._interaction_coef()):
            poly = np.concatenate([[1.0], -a])
            poly[1] -= q
            radius = max(radius, float(np.max(np.abs(np.roots(poly)), initial=0.0)))
        return radius

    def _interaction_coef(self) -> np.ndarray:
        start = self.lags * len(self.columns) + self.n_schedule
        return self.coef[start : start + self.n_schedule] if self.interaction else np.zeros(self.n_schedule)

    @property
    def _wind_coef(self) -> float:
        """The weight of ``wind_k (T_r,k - T_a,k)`` in scaled units (0 without the term)."""
        return float(self.coef[-1]) if self.wind else 0.0

    def _wind(self, df: pd.DataFrame) -> np.ndarray:
        """(N,) the data's scaled wind speed (zeros for a model without the term)."""
        if not self.wind:
            return np.zeros(len(df))
        if WIND not in df:
            raise InputError(f"ARX model: the data lacks column {WIND!r}, which the model weighs")
        return df[WIND].to_numpy(dtype=float) * _SCALE[WIND]

    def offset_response(self, horizon_steps: int, wind_m_s: float = 0.0) -> float:
        """The largest ``T_r`` deviation, over every start in a week of the schedule, that the
        room's own dynamics leave ``horizon_steps`` later from a history 1 K warmer (every
        lagged ``T_r``; inputs and wind at ``wind_m_s`` unchanged). A real room left alone
        settles towards the outdoor temperature, so at most 1; a fit whose schedule makes the
        room amplify its own deviations predicts runaway temperatures."""
        n_lag = self.lags * len(self.columns)
        a_tr = self.coef[0:n_lag:len(self.columns)]
        steps = max(1, round(7 * 86400.0 / self.dt_s))
        t = np.arange(steps) * self.dt_s / 3600.0  # from a Monday midnight [h]
        index = _schedule_index(t % 24.0, (t // 24.0).astype(int), self.day_types, self.block_h)
        loss = self._interaction_coef()[index] + wind_m_s * _SCALE[WIND] * self._wind_coef
        history = np.ones((steps, self.lags))  # one row per start of the week
        with np.errstate(over="ignore", invalid="ignore"):
            for j in range(horizon_steps):
                t_next = history @ a_tr + np.roll(loss, -j) * history[:, 0]
                history = np.concatenate([t_next[:, None], history[:, :-1]], axis=1)
        worst = float(np.max(np.abs(history[:, 0])))
        return worst if math.isfinite(worst) else math.inf

    def _regressors(self, values: np.ndarray, k: np.ndarray) -> np.ndarray:
        """(len(k), lags * columns) of the scaled inputs at rows k, k-1, .., k-lags+1."""
        parts = [values[k - j] for j in range(self.lags)]  # each (len(k), columns)
        return np.stack(parts, axis=1).reshape(len(k), -1)  # lag-major: j * columns + c

    def _inputs(self, df: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        missing = [c for c in self.columns if c not in df]
        if missing:
            raise InputError(f"ARX model: the data lacks column(s) {', '.join(missing)}")
        values = np.stack(
            [df[c].to_numpy(dtype=float) * _SCALE[c] for c in self.columns], axis=1
        )
        return values, _schedule(df, self.day_types, self.block_h)

    def predict_t_r(
        self, df: pd.DataFrame, horizon: int, starts: np.ndarray, *, planned: bool = False
    ) -> np.ndarray:
        """``T_r`` [C] at ``starts + horizon`` (N,): the model's own recursion from the
        measured ``T_r`` up to each start, on the data's delivered power and weather
        (``planned``: the power from each start on is the demanded ``u``, as a planner gives
        it and as a network's rollout takes it; the history's is the delivered).
        Every start must have ``lags - 1`` rows before it; data at another interval than the
        model's (``df.attrs["dt_s"]``) is refused (InputError)."""
        if horizon < 1:
            raise InternalError(f"ARX model: a prediction needs a horizon of at least 1 step, got {horizon}")
        return self.predict_path(df, horizon, starts, planned=planned)[:, -1]

    def horizon_mae(self, df: pd.DataFrame, horizon: int, *, planned: bool = False) -> float | None:
        """The mean absolute error [K] of :meth:`predict_t_r` ``horizon`` steps ahead on
        ``df`` (``planned`` as there), from every start its lags allow (``evaluate``'s figure,
        on the delivered power); None where ``df`` is too short for any."""
        starts = np.arange(self.lags - 1, len(df) - horizon)
        if not starts.size:
            return None
        truth = df["T_r"].to_numpy(dtype=float)[starts + horizon]
        return float(np.mean(np.abs(self.predict_t_r(df, horizon, starts, planned=planned) - truth)))

    def predict_path(
        self, df: pd.DataFrame, horizon: int, starts: np.ndarray, *, planned: bool = False
    ) -> np.ndarray:
        """``T_r`` [C] at ``starts + 1`` .. ``starts + horizon`` (N, horizon): the recursion of
        :meth:`predict_t_r` (``planned`` as there), every step of it."""
        if "dt_s" in df.attrs:
            check_interval(self.dt_s, float(df.attrs["dt_s"]), what="the data has")
        starts = np.asarray(starts, dtype=int)
        if starts.size and (starts.min() < self.lags - 1 or starts.max() + horizon > len(df) - 1):
            raise InternalError(
                f"ARX model: starts must lie in {self.lags - 1} .. {len(df) - 1 - horizon}"
            )
        values, sched = self._inputs(df)
        demand = df["u"].to_numpy(dtype=float) * _SCALE["u_phys"] if planned else None
        wind = self._wind(df) * self._wind_coef
        n_lag = self.lags * len(self.columns)
        a_tr = self.coef[0:n_lag:len(self.columns)]  # weights of T_r,k-j
        s_coef = self.coef[n_lag : n_lag + self.n_schedule]
        q_coef = self._interaction_coef()
        # Own predictions replace measured T_r once the recursion passes the start.
        t_hist = np.stack([values[starts - j, 0] for j in range(self.lags)], axis=1)  # (N, lags)
        path = np.empty((starts.size, horizon))
        for step in range(horizon):
            k = starts + step
            reg = self._regressors(values, k)
            if demand is not None:  # the power from the start on: the demand
                for j in range(self.lags):
                    ahead = k - j >= starts
                    reg[ahead, j * len(self.columns) + 1] = demand[(k - j)[ahead]]
            other = reg @ self.coef[:n_lag] - reg[:, 0::len(self.columns)] @ a_tr
            t_next = (
                other + t_hist @ a_tr + sched[k] @ s_coef
                + (sched[k] @ q_coef + wind[k]) * (t_hist[:, 0] - values[k, 2])
            )
            t_hist = np.concatenate([t_next[:, None], t_hist[:, :-1]], axis=1)
            path[:, step] = t_next
        return path / _SCALE["T_r"]

    # -- the planners' rollout interface (pinn_mpc.models.rollout.BatchDynamics) --------
    @property
    def n_members(self) -> int:
        return 1

    @property
    def eta(self) -> float:
        """+1 when more power warms the room in the fit (heating), -1 when it cools."""
        return 1.0 if float(np.sum(self.coef[1 : self.lags * len(self.columns) : len(self.columns)])) > 0 else -1.0

    @property
    def depth(self) -> int:
        return self.lags

    @property
    def exog_names(self) -> tuple[str, ...]:
        return ("time_of_day_h", "day_of_week", *self.columns[2:], *((WIND,) if self.wind else ()))

    def prediction_matrices(
        self, history: dict[str, np.ndarray], exog: dict[str, np.ndarray], h: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """The horizon's ``T_r`` as an affine map of a power plan: ``T_r = free + gain @ u``.

        ``u`` (h,) [W] the delivered power of the next ``h`` intervals; ``T_r`` (h,) [C] at the
        end of each. ``history`` and ``exog`` as :meth:`rollout` takes them. The recursion is
        linear in the lagged ``T_r`` and power and the rest (weather, schedule, and the
        schedule's ``T_r - T_a`` interaction, whose weight is known from the dates, as the
        wind's is from the forecast's wind speed) is given, so ``free`` (h,) is the prediction under a zero plan and ``gain`` (h, h) [K/W] is
        lower triangular (a power acts on the temperatures after it)."""
        n_col, lags = len(self.columns), self.lags
        dow = np.asarray(exog["day_of_week"], dtype=float)[:h]
        if len(dow) < h or not np.all(np.isfinite(dow)):
            raise InputError("ARX model: its schedule needs the forecast's dates (day_of_week)")
        t_r_past = np.asarray(history["T_r"], dtype=float)
        if len(t_r_past) < lags:
            raise InternalError(f"ARX model: needs {lags} past values of T_r")
        coef = self.coef
        # Every lagged input but T_r over rows k-lags+1 .. k+h-1 (the past, then the horizon):
        # its terms go into ``free``, the planned power's into ``gain``.
        free = np.zeros(h)
        gain = np.zeros((h, h))
        for c, name in enumerate(self.columns[1:], start=1):
            past = np.asarray(history[name], dtype=float)
            if name != "u_phys":  # the weather history ends with now's row: exog[name][0]
                past = past[:-1]
            if len(past) < lags - 1:
                raise InternalError(f"ARX model: needs {lags - 1} past intervals of {name}")
            past = past[len(past) - (lags - 1):] * _SCALE[name]
            ahead = (
                np.zeros(h) if name == "u_phys"
                else np.asarray(exog[name], dtype=float)[:h] * _SCALE[name]
            )
            seq = np.concatenate([past, ahead])
            for j in range(lags):
                free += coef[j * n_col + c] * seq[lags - 1 - j : lags - 1 - j + h]
                if name == "u_phys":
                    gain += coef[j * n_col + c] * _SCALE[name] * np.eye(h, k=-j)
        index = _schedule_index(
            np.asarray(exog["time_of_day_h"], dtype=float)[:h], dow, self.day_types, self.block_h
        )
        free += coef[lags * n_col : lags * n_col + self.n_schedule][index]
        q = self._interaction_coef()[index]  # (h,)
        if self.wind:
            speed = np.asarray(exog.get(WIND, []), dtype=float)[:h]
            if len(speed) < h or not np.all(np.isfinite(speed)):
                raise InputError(f"ARX model: its wind term needs the forecast's {WIND!r}")
            q = q + self._wind_coef * speed * _SCALE[WIND]
        t_a = np.asarray(exog["T_a"], dtype=float)[:h] * _SCALE["T_a"]
        a_tr = coef[0 : lags * n_col : n_col]
        # The recursion on both parts: the past T_r enter ``free``, the plan none of them.
        t_hist = t_r_past[::-1][:lags] * _SCALE["T_r"]
        g_hist = np.zeros((lags, h))
        out_free, out_gain = np.empty(h), np.empty((h, h))
        for step in range(h):
            out_free[step] = free[step] + a_tr @ t_hist + q[step] * (t_hist[0] - t_a[step])
            out_gain[step] = gain[step] + a_tr @ g_hist + q[step] * g_hist[0]
            t_hist = np.concatenate([out_free[step : step + 1], t_hist[:-1]])
            g_hist = np.concatenate([out_gain[step : step + 1], g_hist[:-1]])
        return out_free / _SCALE["T_r"], out_gain / _SCALE["T_r"]

    def rollout(
        self, history: dict[str, np.ndarray], u_w: torch.Tensor, exog: dict[str, np.ndarray]
    ) -> Rollout:
        """The recursion for N plans ``u_w`` (N, H) [W] from ``history`` (data-format names,
        ``T_r`` up to now, ``u_phys`` of past intervals, weather up to now) with ``exog`` (H,)
        per :attr:`exog_names`; the delivered power is the plan. Tensors (1, N, H) (T_r of the
        one zone (1, N, H, 1)), by the affine map of :meth:`prediction_matrices`."""
        u = u_w.detach().to(torch.float64)
        free, gain = self.prediction_matrices(history, exog, u.shape[1])
        t_r = torch.as_tensor(free) + u @ torch.as_tensor(gain).T
        return Rollout.of_one_zone(t_r[None], u.clamp(min=0.0)[None], None)

    def to_dict(self) -> dict[str, Any]:
        """The model as JSON-ready data (numbers only)."""
        return {
            "kind": ARX.name,
            "columns": list(self.columns),
            "lags": self.lags,
            "coef": [float(c) for c in self.coef],
            "dt_s": self.dt_s,
            "block_h": self.block_h,
            "day_types": self.day_types,
            "interaction": self.interaction,
            "wind": self.wind,
            "train_mae_c": self.train_mae_c,
            **({"identified_rc": self.identified_rc} if self.identified_rc is not None else {}),
            **({"training_data": self.training_data} if self.training_data else {}),
        }


def fit_arx(
    df: pd.DataFrame,
    *,
    lags: int = DEFAULT_LAGS,
    day_types: int = 2,
    interaction: bool = False,
    inputs: tuple[str, ...] = MEASURED_INPUTS,
    block_h: float = BLOCK_H,
    rows: np.ndarray | None = None,
    wind: bool = False,
    pool: float = 0.0,
) -> ARXModel:
    """Least-squares ARX fit of ``df`` (data format: ``time``, ``T_r``, ``u_phys``, ``T_a``,
    optional ``G``, the facades' irradiance (:data:`pinn_mpc.solar.FACADE_COLUMNS`) and ``I_g``;
    consecutive rows at ``df.attrs["dt_s"]``); ``day_types`` and ``interaction`` as
    :class:`ARXModel` has them; ``inputs`` the optional inputs it takes where the data has
    them (by default the measured ones, :data:`MEASURED_INPUTS`); ``block_h`` the length [h] of
    the schedule's blocks (it must divide the day). ``rows``: fit only the steps from these
    rows to the next (each at least ``lags - 1``, before the last; default all of them).
    ``wind``: also weigh ``wind_k (T_r,k - T_a,k)`` (the data must have ``wind``).

    ``pool`` (with 3 ``day_types``): Saturdays and Sundays share a weekend schedule, each with
    its own deviation from it, and the deviations (of the schedule and, with ``interaction``, of
    the indoor-outdoor weights) are held towards zero by a ridge of ``pool`` times each one's
    own sum of squares: what the days of one type show and the other's do not is kept where
    many rows say it, and shrunk where a few rows of two or three days would otherwise be fitted
    exactly. The model is the same ARX of 3 day types (each one's coefficients the weekend's
    plus its deviation); ``pool`` 0 is the plain least squares."""
    return _fit(df, lags=lags, day_types=day_types, interaction=interaction, inputs=inputs,
                block_h=block_h, rows=rows, wind=wind, pool=pool, effective_dof=False)[0]


def _fit(
    df: pd.DataFrame, *, lags: int, day_types: int, interaction: bool, inputs: tuple[str, ...],
    block_h: float, rows: np.ndarray | None, wind: bool, pool: float, effective_dof: bool,
) -> tuple[ARXModel, float | None]:
    """:func:`fit_arx`, and with ``effective_dof`` the fit's effective number of coefficients
    (the trace of its hat matrix: the number of coefficients for a least-squares fit, fewer for
    a pooled one), else None."""
    if lags < 1:
        raise ValueError(f"ARX model: lags must be >= 1, got {lags}")
    if day_types not in (2, 3):
        raise ValueError(f"ARX model: day_types must be 2 or 3, got {day_types}")
    if not (math.isfinite(pool) and pool >= 0):
        raise ValueError(f"ARX model: pool must be a non-negative number, got {pool}")
    if not _valid_block(block_h):
        raise ValueError(f"ARX model: block_h must divide the day into whole hours' blocks, got {block_h}")
    unknown = set(inputs) - set(_INPUT_ORDER)
    if unknown:
        raise ValueError(f"ARX model: unknown input(s) {sorted(unknown)}; known {list(_INPUT_ORDER)}")
    columns = ("T_r", "u_phys", "T_a", *(c for c in _INPUT_ORDER if c in inputs and c in df))
    model = ARXModel(
        columns=columns, lags=lags, coef=np.zeros(0), dt_s=float(df.attrs.get("dt_s", 1800.0)),
        train_mae_c=0.0, day_types=day_types, interaction=interaction, block_h=float(block_h),
        wind=wind,
    )
    n_coef = _n_coef(lags, len(columns), day_types, block_h, interaction, wind)
    k = np.arange(lags - 1, len(df) - 1) if rows is None else np.asarray(rows, dtype=int)
    if len(k) < 2 * n_coef:
        raise TooFewRowsError(
            f"ARX model: {len(k) + lags} rows are too few to fit {lags} lags of {len(columns)} "
            "inputs; give more days of data"
        )
    values, sched = model._inputs(df)
    pooled = pool > 0 and day_types == 3
    # Pooled, each schedule's columns [workday, Saturday, Sunday] become [workday, weekend,
    # Saturday's deviation, Sunday's deviation]: a weekend row sets the weekend's and its own.
    design = _pooled_schedule(sched) if pooled else sched
    parts = [model._regressors(values, k), design[k]]
    if interaction:
        parts.append(design[k] * (values[k, 0] - values[k, 2])[:, None])
    if wind:
        parts.append((model._wind(df)[k] * (values[k, 0] - values[k, 2]))[:, None])
    x = np.concatenate(parts, axis=1)
    y = values[k + 1, 0]
    gram = x.T @ x
    penalty = _RIDGE * (np.diag(gram) + 1e-12)
    n_lag, n_design = lags * len(columns), design.shape[1]
    if pooled:
        for first in (n_lag, *((n_lag + n_design,) if interaction else ())):
            deviations = slice(first + n_design // 2, first + n_design)
            penalty[deviations] += pool * np.diag(gram)[deviations]
    system = gram + np.diag(penalty)
    solved = np.linalg.solve(system, x.T @ y)
    mae = float(np.mean(np.abs(x @ solved - y))) / _SCALE["T_r"]
    coef = _unpooled(solved, n_lag, n_design, interaction) if pooled else solved
    dof = float(np.trace(np.linalg.solve(system, gram))) if effective_dof else None  # the hat matrix's trace
    return dataclasses.replace(model, coef=coef, train_mae_c=mae), dof


def _pooled_schedule(sched: np.ndarray) -> np.ndarray:
    """The one-hot schedule of 3 day types, (N, 3 blocks), as the columns of a pooled fit
    (:func:`fit_arx`'s ``pool``), (N, 4 blocks): workday, weekend, Saturday's deviation,
    Sunday's deviation."""
    workday, saturday, sunday = np.split(sched, 3, axis=1)
    return np.concatenate([workday, saturday + sunday, saturday, sunday], axis=1)


def _unpooled(solved: np.ndarray, n_lag: int, n_design: int, interaction: bool) -> np.ndarray:
    """The coefficients of 3 day types from a pooled fit's (:func:`_pooled_schedule`): each
    weekend day's the weekend's plus its deviation; the lags' and the wind's as they are."""
    out, at = [solved[:n_lag]], n_lag
    for _ in range(2 if interaction else 1):
        workday, weekend, saturday, sunday = np.split(solved[at : at + n_design], 4)
        out += [workday, weekend + saturday, weekend + sunday]
        at += n_design
    return np.concatenate([*out, solved[at:]])


class TooFewRowsError(InputError):
    """The data hold too few rows for the ARX's coefficients (:func:`fit_arx`)."""


def fit_physics_informed_arx(
    df: pd.DataFrame, *, lags: int = DEFAULT_LAGS, eta: float = 1.0
) -> ARXModel:
    """The physics-informed ARX (module docstring): workday and weekend (or workday, Saturday
    and Sunday) schedules, each block also weighing the indoor-outdoor difference; InputError
    when the fit's power acts against the sign of ``eta`` (> 0 a heater: more power must warm
    the room; < 0 a cooling machine: it must cool), as then the data do not identify the
    actuator; where the data clearly say the other sign, first, naming the ``eta`` that fits
    (:func:`pinn_mpc.identify.check_power_sign`, as identify and the networks say it).

    Where the data has the facades' irradiance (:data:`pinn_mpc.solar.FACADE_COLUMNS`), the
    fit chooses whether to take it instead of ``G`` by blocked cross-validation over every
    schedule: the data cut into :data:`SELECTION_FOLDS` consecutive parts, each predicted
    :data:`SELECTION_HORIZON_S` ahead by the fit on the steps of the others. Of the choices
    whose mean error over the parts is within one standard error of the best's (the
    one-standard-error rule), the smallest schedule's inputs are taken, the facades rather
    than ``G`` where both are within. The facades are what a building's windows see: a month
    of one season's data hardly tells them from ``G``, but the next month's higher sun does,
    and with both ``G`` and the facades a fit weighs them against each other and
    extrapolates poorly. A choice that cannot be fitted on every part is not taken; if none
    can, the measured inputs alone.

    With those inputs, the schedule's block length (:data:`BLOCK_CHOICES_H`) and whether
    Saturdays get a schedule of their own are chosen by Akaike's information criterion of the
    fit on all the data, ``n log(MSE) + 2 k`` over its ``n`` one-step errors and ``k``
    coefficients (:func:`schedule_aic`; the criterion aimed at prediction, where Schwarz's ``k
    log(n)`` keeps a reference office's Saturdays out of two weeks' fits that predict the next
    month worse without them), among the schedules whose room left alone settles: a history 1
    K warmer leaves at most 1 K :data:`SELECTION_HORIZON_S` later, from every start in a week
    (:meth:`ARXModel.offset_response`, at the data's mean wind; all of them if none does), and
    of those with no more coefficients than the data can fit. Hourly blocks follow an office's
    hourly schedules and a Saturday schedule a reference office's or store's, but each doubles
    or adds half the schedule's coefficients. Cross-validation cannot judge a Saturday
    schedule on two weeks of data: a part that holds out one of the two Saturdays leaves its
    blocks fitted on one day, and that part's predictions run away (tens to hundreds of
    kelvin), while the fit on both Saturdays predicts the next month well. With one Saturday
    in the data its blocks can fit that day with a room that does not settle, whose
    predictions run away just the same: the settling requirement rules it out. A schedule that
    tells Saturdays from Sundays is then fitted with the two pooled towards one weekend
    schedule (:func:`fit_arx`'s ``pool``) as strongly as Akaike's criterion on the fit's
    effective number of coefficients says (:data:`POOL_CHOICES`, or not at all), among the
    fits whose room settles: two weeks hold two Sundays, an online run's first weeks a Sunday
    of its warm-up and a cold snap's, and the plain least squares follows their few rows
    exactly and mispredicts the next such nights by kelvins. Where the data
    has the wind speed, every choice takes the wind's term: one coefficient whose use a month
    of the same season's wind hardly shows, but a building's infiltration follows the wind
    (the DOE reference buildings' does)."""
    from pinn_mpc.identify import check_power_sign

    check_power_sign(df, eta, what=PHYSICS_ARX.name)
    n_lags = lags
    while True:
        try:
            return _physics_informed_fit(df, lags=n_lags, eta=eta)
        except TooFewRowsError:  # no schedule fits so many lags: halve them, down to MIN_LAGS
            if n_lags // 2 < MIN_LAGS:
                raise
            n_lags //= 2


def _physics_informed_fit(df: pd.DataFrame, *, lags: int, eta: float) -> ARXModel:
    """:func:`fit_physics_informed_arx` with ``lags`` lags; TooFewRowsError where no schedule
    can be fitted with so many."""
    facades = ("I_g", *FACADE_COLUMNS) if all(c in df for c in FACADE_COLUMNS) else None
    wind = WIND in df
    choices = [
        (inputs, block_h, day_types)
        for inputs in (MEASURED_INPUTS, *((facades,) if facades else ()))
        for block_h in (BLOCK_H, *(b for b in BLOCK_CHOICES_H if b != BLOCK_H))
        for day_types in (3, 2)
    ]
    scores = [_cross_validated_error(df, i, lags, b, d, wind) for i, b, d in choices]
    best = int(np.argmin([mean for mean, _ in scores]))
    limit = scores[best][0] + scores[best][1]
    within = [c for c, (mean, _) in zip(choices, scores, strict=True) if mean <= limit] or [choices[0]]

    def simplest(choice: tuple[tuple[str, ...], float, int]) -> tuple[int, bool]:
        inputs, block_h, day_types = choice
        return day_types * _blocks(block_h), inputs != facades

    inputs = min(within, key=simplest)[0]
    fits, failures = [], []
    for block_h in (BLOCK_H, *(b for b in BLOCK_CHOICES_H if b != BLOCK_H)):
        for day_types in (3, 2):
            try:
                fits.append(fit_arx(
                    df, lags=lags, day_types=day_types, interaction=True, inputs=inputs,
                    block_h=block_h, wind=wind,
                ))
            except (InputError, np.linalg.LinAlgError) as exc:  # e.g. too few rows for it
                failures.append(exc)
    if not fits:
        raise failures[-1] if isinstance(failures[-1], InputError) else InputError(
            f"physics-informed ARX: no schedule could be fitted on the data ({failures[-1]})"
        )
    wind_m_s = float(df[WIND].mean()) if wind else 0.0
    horizon = max(1, round(SELECTION_HORIZON_S / float(df.attrs.get("dt_s", 1800.0))))
    settling = [fit for fit in fits if fit.offset_response(horizon, wind_m_s) <= 1.0]
    model = min(settling or fits, key=lambda fit: schedule_aic(fit, df))
    if model.day_types == 3:  # how far to pool Saturdays and Sundays (POOL_CHOICES)
        pooled = [
            _fit(df, lags=lags, day_types=3, interaction=True, inputs=inputs, block_h=model.block_h,
                 rows=None, wind=wind, pool=pool, effective_dof=True)
            for pool in (0.0, *POOL_CHOICES)
        ]
        settles = max(1.0, model.offset_response(horizon, wind_m_s))
        model = min(
            ((fit, dof) for fit, dof in pooled if fit.offset_response(horizon, wind_m_s) <= settles),
            key=lambda fit_dof: schedule_aic(fit_dof[0], df, dof=fit_dof[1]),
        )[0]
    n_col = len(model.columns)
    if float(np.sum(model.coef[1 : lags * n_col : n_col])) * float(np.sign(eta)) <= 0:
        raise InputError(
            f"physics-informed ARX: the fit says more power {'cools' if eta > 0 else 'warms'} "
            "the room; the data do not identify the actuator (give data with the power varied, "
            "e.g. simulated with the random-level or closed-loop policy)"
        )
    return model


def schedule_aic(model: ARXModel, df: pd.DataFrame, *, dof: float | None = None) -> float:
    """Akaike's information criterion of ``model``'s fit of ``df`` (the data it was fitted
    on): ``n log(MSE) + 2 k`` over its ``n`` one-step errors of ``T_r`` (the MSE at least
    :data:`AIC_RESOLUTION_C` squared) and its ``k`` coefficients, or ``dof``, a pooled fit's
    effective number of them; lower is better."""
    steps = np.arange(model.lags - 1, len(df) - 1)
    errors = model.predict_t_r(df, 1, steps) - df["T_r"].to_numpy(dtype=float)[steps + 1]
    mse = max(float(np.mean(np.square(errors))), AIC_RESOLUTION_C**2)
    return steps.size * math.log(mse) + 2.0 * (model.coef.size if dof is None else dof)


def _cross_validated_error(
    df: pd.DataFrame, inputs: tuple[str, ...], lags: int, block_h: float, day_types: int,
    wind: bool = False,
) -> tuple[float, float]:
    """The mean and standard error [K] over :data:`SELECTION_FOLDS` consecutive parts of
    ``df`` of the MAE of the physics-informed ARX with ``inputs``, schedule blocks of
    ``block_h`` hours, ``day_types`` and the wind's term if ``wind``, predicting the part :data:`SELECTION_HORIZON_S` ahead
    from every start in it (its history measured), fitted on the steps whose rows lie outside
    it; (inf, 0) when a part cannot be fitted or is shorter than the horizon."""
    dt_s = float(df.attrs.get("dt_s", 1800.0))
    horizon = max(1, round(SELECTION_HORIZON_S / dt_s))
    n = len(df)
    edges = np.linspace(0, n, SELECTION_FOLDS + 1).astype(int)
    truth = df["T_r"].to_numpy(dtype=float)
    steps = np.arange(lags - 1, n - 1)  # the step from row k to k + 1 reads rows k-lags+1 .. k+1
    errors = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        starts = np.arange(max(lo, lags - 1), hi - horizon)
        if starts.size == 0:
            return math.inf, 0.0
        outside = (steps + 1 < lo) | (steps - lags + 1 >= hi)
        try:
            model = fit_arx(
                df, lags=lags, day_types=day_types, interaction=True, inputs=inputs,
                block_h=block_h, rows=steps[outside], wind=wind,
            )
        except (InputError, np.linalg.LinAlgError):
            return math.inf, 0.0
        errors.append(float(np.mean(np.abs(model.predict_t_r(df, horizon, starts) - truth[starts + horizon]))))
    mean = float(np.mean(errors))
    return (mean, float(np.std(errors, ddof=1) / math.sqrt(len(errors)))) if math.isfinite(mean) else (math.inf, 0.0)


def fit_linear(name: str, df: pd.DataFrame, *, eta: float = 1.0) -> ARXModel:
    """The linear baseline ``name`` (the registry's ARX or physics-informed ARX) fitted on
    ``df``; ``eta`` the actuator's sign, as :func:`fit_physics_informed_arx` takes it. The
    model carries what a planner over it falls back on, as a trained network does: the RC
    identified from ``df`` (:func:`pinn_mpc.identify.identify_rc` with ``eta``; None where the
    identification fails) and ``df``'s summary (its input ranges)."""
    from pinn_mpc.identify import check_power_sign, identify_rc
    from pinn_mpc.physics import rc_summary
    from pinn_mpc.training import data_summary

    check_power_sign(df, eta, what=name)  # planners take the actuator's sign from eta
    if name == ARX.name:
        model = fit_arx(df)
    elif name == PHYSICS_ARX.name:
        model = fit_physics_informed_arx(df, eta=eta)
    else:
        raise ValueError(f"{name!r} is not a linear baseline; choose {ARX.name} or {PHYSICS_ARX.name}")
    check_settles(model, name)
    try:
        identified = identify_rc(df, eta=eta)
    except InputError:
        rc = None
    else:
        rc = {
            **rc_summary(identified.params, source="identify (training data)"),
            "fit": identified.fit_statistics(),
        }
    return dataclasses.replace(model, identified_rc=rc, training_data=data_summary(df))


def is_arx_directory(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` is a directory holding an ARX model (:data:`ARX_FILE`)."""
    return (Path(path) / ARX_FILE).is_file()


def save_arx(model: ARXModel, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` as ``path/arx.json`` (the directory is created); the file written."""
    from pinn_mpc.io import atomic_write_json

    out = Path(path) / ARX_FILE
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out, model.to_dict())
    return out


def load_arx(path: str | os.PathLike[str]) -> ARXModel:
    """Read ``path/arx.json``: numbers checked against the layout they must have (reading
    never runs code from the file); InputError naming the file otherwise."""
    file = Path(path) / ARX_FILE
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
        columns = tuple(str(c) for c in data["columns"])
        lags = int(data["lags"])
        coef = np.asarray(data["coef"], dtype=float)
        dt_s = float(data["dt_s"])
        block_h = float(data.get("block_h", BLOCK_H))
        day_types = int(data.get("day_types", 2))
        interaction = data.get("interaction", False)
        wind = data.get("wind", False)
        identified_rc = data.get("identified_rc")
        training_data = data.get("training_data", {})
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{file}: not a readable ARX model ({exc}); train it again ({_ARCH} arx)") from None
    if not _valid_block(block_h):
        raise InputError(f"{file}: not a valid ARX model (block_h {block_h:g} does not divide the day)")
    expected = _n_coef(lags, len(columns), day_types, block_h, interaction is True, wind is True)
    if (
        day_types not in (2, 3)
        or not isinstance(interaction, bool)
        or not isinstance(wind, bool)
        or data.get("kind") != ARX.name
        or columns[:3] != ("T_r", "u_phys", "T_a")
        or not set(columns) <= set(_SCALE)
        or not 1 <= lags <= 1000
        or coef.shape != (expected,)
        or not np.all(np.isfinite(coef))
        or not 0 < dt_s <= 86400
    ):
        raise InputError(
            f"{file}: not a valid ARX model (kind, columns, lags, {expected} finite coefficients, "
            f"interval); train it again ({_ARCH} arx)"
        )
    if not isinstance(training_data, dict):
        raise InputError(f"{file}: not a valid ARX model (training_data is not an object)")
    largest = float(np.max(np.abs(coef)))
    if largest > MAX_ABS_COEF:
        raise InputError(
            f"{file}: not a plausible ARX model (a coefficient of {largest:g}, where a fit gives at "
            f"most {MAX_ABS_COEF:g} in its scaled units): it was edited or damaged; train it again "
            f"({_ARCH} arx)"
        )
    if identified_rc is not None:
        if not isinstance(identified_rc, dict):
            raise InputError(f"{file}: not a valid ARX model (identified_rc is not an object)")
        try:
            params_from_summary(identified_rc)
        except InputError as exc:
            raise InputError(f"{file}: identified_rc: {exc.marked}") from None
    model = ARXModel(
        columns=columns, lags=lags, coef=coef, dt_s=dt_s,
        train_mae_c=float(data.get("train_mae_c", float("nan"))),
        day_types=day_types, interaction=bool(interaction), block_h=block_h, wind=bool(wind),
        identified_rc=identified_rc, training_data=training_data,
    )
    # The room's own dynamics over a week of the schedule, as the fit judges them: a fitted
    # room settles (a block may amplify for an hour, the week does not; fit_linear writes no
    # other); a tampered one runs away.
    offset_k = week_offset_k(model)
    if not offset_k <= RUNAWAY_OFFSET_K:
        raise InputError(
            f"{file}: not a plausible ARX model (its room temperature never settles: a history "
            f"1 K warmer is {offset_k:.3g} K warmer a week later, where a "
            f"building's settles): it was edited or damaged; train it again ({_ARCH} arx)"
        )
    return model


#: The largest deviation a week after a 1 K warmer history that a loaded ARX may keep: a
#: fitted room settles towards the outdoor temperature (well under 1 K); one whose dynamics
#: amplify their own deviations grows without bound.
RUNAWAY_OFFSET_K = 1.0


def check_settles(model: ARXModel, name: str) -> None:
    """InputError where ``model`` (the fit of baseline ``name`` on some data) lets its room
    run away within a week: what :func:`load_arx` would refuse as damaged, said now of the
    data rather than later of the file."""
    offset_k = week_offset_k(model)
    if not offset_k <= RUNAWAY_OFFSET_K:
        raise InputError(
            f"{BASELINES[name].label}: no fit on these data lets the room settle (a history 1 K "
            f"warmer is {offset_k:.3g} K warmer a week later, where a building's settles), so "
            "its predictions would run away; give more days of data, or train another family "
            f"({_ARCH} hybrid)"
        )


def week_offset_k(model: ARXModel) -> float:
    """How much warmer ``model``'s room is a week after a history 1 K warmer, at the worst
    start of its schedule and no wind (:meth:`ARXModel.offset_response`): at most
    :data:`RUNAWAY_OFFSET_K` for a room that settles, which is what :func:`load_arx` reads."""
    return model.offset_response(max(1, round(7 * 86400.0 / model.dt_s)))


def _valid_block(block_h: float) -> bool:
    """Whether ``block_h`` [h] is a whole number of hours that divides the day."""
    return float(block_h).is_integer() and 1 <= block_h <= 24 and 24 % int(block_h) == 0
