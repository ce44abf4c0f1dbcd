"""Feature windows of the paper (Table notation-equ) and their scaling.

For sample ``i`` and depth ``k``::

    x_f   = (T_r,i-k .. T_r,i-1,  u_phys,i-k-1 .. u_phys,i-2)  [+ T_a,i-k .. T_a,i-1, ...]
    x_obs = (T_r,i,  u_phys,i-1)
    w     = (time of day t_i, T_a,i [, G_i, G_south,i .. G_north,i, I_g,i when the data has them])
    u_i   = demanded power;  targets T_r,i+1, u_phys,i  (and T_m,i for evaluation only)

Beyond the paper, ``x_f`` also holds the past k values of each exogenous input other than
time of day: T_m,i-1 follows from T_r,i-1 -> T_r,i only with T_a,i-1 known, so without that
history the hidden state is not determined by the inputs when the weather varies.

Sample ``i`` needs rows ``i-k-1 .. i+1``, so a frame of ``n`` rows gives ``n - k - 2``
samples. The scaled feature vector is laid out so that a recursive rollout only shifts
windows (see :class:`FeatureConfig` for the index sets)::

    [T_r,i-k .. T_r,i] [u_phys,i-k-1 .. u_phys,i-1] [T_a,i-k .. T_a,i] ([G ..] [facades ..]
    [I_g ..]) [u_i]
    [sin, cos of the daily phase of t_i]

each window k+1 long. All temperatures (T_r, T_m) share one scale, all powers (u, u_phys)
another; T_a, G, the facades' irradiance (:mod:`pinn_mpc.solar`) and I_g are standardised
each.

Two inputs only the architectures that declare them get (:class:`FeatureConfig`'s
``calendar`` and :data:`OPTIONAL_EXOG`): the calendar, four columns after the time of day
(workday, Saturday, Sunday or holiday as a one-hot, then the hour of the day / 24, unscaled),
for schedules of unmeasured gains; and the wind speed, a window like the other series.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from pinn_mpc.data import WIND, day_of_week, frame_scheduled_gains_w
from pinn_mpc.errors import InputError, setting
from pinn_mpc.physics import DT_RANGE_S, scheduled_gains_w
from pinn_mpc.solar import FACADE_COLUMNS

__all__ = [
    "CALENDAR_COLUMNS",
    "EXOG_COLUMNS",
    "MAX_DEPTH",
    "OPTIONAL_EXOG",
    "MIN_TRAIN_SAMPLES",
    "FeatureConfig",
    "Standard",
    "Windows",
    "check_interval",
    "exog_names_for",
    "fit_feature_config",
    "format_interval",
    "make_windows",
    "time_of_day_h",
    "whole_number",
    "with_scheduled_gains",
]

#: Exogenous inputs a model can use, in this order, with the data column each comes from.
EXOG_COLUMNS = {
    "time_of_day_h": "time", "T_a": "T_a", "G": "G", **{c: c for c in FACADE_COLUMNS},
    "I_g": "I_g", WIND: WIND,
}
#: Exogenous inputs a model gets only where its architecture asks for them (and the data has
#: them): the wind speed.
OPTIONAL_EXOG = (WIND,)
#: The calendar's columns (:attr:`FeatureConfig.calendar`): day type one-hot, hour / 24.
CALENDAR_COLUMNS = 4
#: Samples a training set must have at least.
MIN_TRAIN_SAMPLES = 32
#: Largest history depth (intervals): 3 weeks at 30 min, far beyond the paper's 8; it bounds
#: what a model.json can make the loader allocate.
MAX_DEPTH = 1008


def whole_number(value: Any, name: str) -> int:
    """``value`` as an int if it is a whole number (JSON may write 8 as 8.0), else InputError."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not float(value).is_integer():
        raise ValueError(f"{name} must be a whole number, got {value!r}")
    return int(value)


def format_interval(dt_s: float) -> str:
    """``1800 s (30 min)``: an interval for messages."""
    return f"{dt_s:g} s ({dt_s / 60:g} min)"


def check_interval(model_dt_s: float, dt_s: float, *, what: str) -> None:
    """A model predicts one step of the interval it was trained at: refuse any other."""
    if abs(model_dt_s - dt_s) > 1e-6:
        raise InputError(
            f"the model was trained at {format_interval(model_dt_s)} intervals but {what} "
            f"{format_interval(dt_s)}; train a model on data at that interval (or resample)"
        )


def exog_names_for(df: pd.DataFrame, optional: tuple[str, ...] = ()) -> tuple[str, ...]:
    """Exogenous inputs of a model trained on ``df``: time of day, T_a (+ G, the facades'
    irradiance, I_g if present, and those of ``optional`` (:data:`OPTIONAL_EXOG`) present)."""
    return ("time_of_day_h", "T_a") + tuple(
        c for c in list(EXOG_COLUMNS)[2:]
        if c in df.columns and (c not in OPTIONAL_EXOG or c in optional)
    )


def day_type(day_of_week_: np.ndarray) -> np.ndarray:
    """(n, 3) one-hot of workday (Monday-Friday), Saturday, Sunday or holiday from the day of
    the week (n,) (0 = Monday, 6 = Sunday or a holiday)."""
    dow = np.asarray(day_of_week_, dtype=float)
    if not np.all(np.isfinite(dow)):
        raise InputError("the model reads the calendar (day_of_week), which these inputs lack")
    index = np.clip(dow.astype(int) - 4, 0, 2)
    return np.eye(3, dtype=np.float32)[index]


def time_of_day_h(time: pd.Series) -> np.ndarray:
    """(n,) hours since midnight [h] of a datetime64 column."""
    t = pd.to_datetime(time)
    return ((t - t.dt.normalize()).dt.total_seconds() / 3600.0).to_numpy(dtype=float)


@dataclass(frozen=True, kw_only=True)
class Standard:
    """``scaled = (value - mean) / std``; std is at least 1e-6 of the unit (constant columns)."""

    mean: float
    std: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mean) and math.isfinite(self.std) and self.std > 0):
            raise ValueError(
                f"scaling must be finite with std > 0, got mean={self.mean}, std={self.std}"
            )

    @classmethod
    def fit(cls, values: np.ndarray) -> Standard:
        std = float(np.std(values))
        return cls(mean=float(np.mean(values)), std=std if std > 1e-6 else 1.0)

    def to_dict(self) -> dict[str, float]:
        return {"mean": self.mean, "std": self.std}


@dataclass(frozen=True, kw_only=True)
class FeatureConfig:
    """Depth, exogenous inputs, step and the scaling fitted on the training data."""

    depth: int
    exog_names: tuple[str, ...]
    dt_s: float
    temperature: Standard  # T_r, T_m windows and outputs [C]
    power: Standard  # u_phys windows, u, u_phys output [W]
    delta_t_r: Standard  # T_r,i+1 - T_r,i, the regression target [K]
    exog: dict[str, Standard] = field(default_factory=dict)  # T_a, G, I_g
    calendar: bool = False  # the calendar's columns after the time of day (module docstring)
    # The unmeasured gains [W] the model adds to I_g by block of the day and day type (the
    # RC's schedule, :attr:`pinn_mpc.physics.RCParams.unmeasured_gains_w`); empty: none.
    gain_schedule_w: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if not 1 <= self.depth <= MAX_DEPTH:
            raise ValueError(f"depth must be 1 .. {MAX_DEPTH} intervals, got {self.depth}")
        lo, hi = DT_RANGE_S
        if not (math.isfinite(self.dt_s) and lo <= self.dt_s <= hi):
            raise ValueError(
                f"dt_s must be a control interval of {lo:g} .. {hi:g} s, got {self.dt_s!r}"
            )
        if self.exog_names[:2] != ("time_of_day_h", "T_a"):
            raise ValueError(
                f"exog_names must start with time_of_day_h, T_a, got {self.exog_names}"
            )
        unknown = set(self.exog_names) - set(EXOG_COLUMNS)
        if unknown:
            raise ValueError(
                f"unknown exogenous input(s) {sorted(unknown)}; known {list(EXOG_COLUMNS)}"
            )
        missing = [n for n in self.exog_names[1:] if n not in self.exog]
        if missing:
            raise ValueError(f"feature config lacks scaling for {missing}")

    @property
    def exog_series(self) -> tuple[str, ...]:
        """Exogenous inputs with a history window (all but time of day)."""
        return self.exog_names[1:]

    @property
    def n_features(self) -> int:
        return (2 + len(self.exog_series)) * (self.depth + 1) + 1 + 2 + self.n_calendar

    @property
    def n_calendar(self) -> int:
        """Columns of the calendar (0 without it)."""
        return CALENDAR_COLUMNS if self.calendar else 0

    @property
    def model_exog_names(self) -> tuple[str, ...]:
        """What a forecast must give a model of these features: :attr:`exog_names`, and
        ``day_of_week`` with the calendar."""
        return self.exog_names + (("day_of_week",) if self.calendar or self.gain_schedule_w else ())

    def gains_w(self, i_g_w: Any, time_of_day_h: Any, day_of_week_: Any | None) -> np.ndarray:
        """The internal gains the model reads [W]: the measured ``i_g_w`` plus
        :attr:`gain_schedule_w`'s gains of each interval's block (a workday's where the day is
        unknown)."""
        return scheduled_gains_w(self.gain_schedule_w, i_g_w, time_of_day_h, day_of_week_)

    def complete_frame(self, df: pd.DataFrame) -> pd.DataFrame:
        """``df`` with its ``I_g`` as the model reads it (:meth:`gains_w`): itself without a
        gain schedule."""
        if not self.gain_schedule_w:
            return df
        return with_scheduled_gains(df, self.gain_schedule_w)

    @property
    def u_index(self) -> int:
        """Index of the demanded power u_i."""
        return (2 + len(self.exog_series)) * (self.depth + 1)

    def window_start(self, j: int) -> int:
        """Index where window j starts: 0 T_r, 1 u_phys, 2.. the exogenous series."""
        return j * (self.depth + 1)

    def x_f_index(self) -> list[int]:
        """Indices of x_f: the first k values of every window."""
        n_win = 2 + len(self.exog_series)
        return [self.window_start(j) + p for j in range(n_win) for p in range(self.depth)]

    def now_index(self) -> list[int]:
        """Indices of x_obs, u_i and w_i: the last value of every window, u, time of day."""
        n_win = 2 + len(self.exog_series)
        last = [self.window_start(j) + self.depth for j in range(n_win)]
        return last + [self.u_index, self.u_index + 1, self.u_index + 2]

    @property
    def min_rows(self) -> int:
        """Rows needed for one sample."""
        return self.depth + 3

    def scale_exog(self, exog: dict[str, np.ndarray]) -> np.ndarray:
        """Exogenous series, each (n,) -> standardised (n_series, n), float32."""
        out = [
            (np.asarray(exog[n], dtype=float) - self.exog[n].mean) / self.exog[n].std
            for n in self.exog_series
        ]
        return np.asarray(out, dtype=np.float32).reshape(len(self.exog_series), -1)

    @staticmethod
    def encode_time(time_of_day_h: np.ndarray) -> np.ndarray:
        """Hours since midnight (n,) -> (n, 2) sin, cos of the daily phase, float32."""
        phase = 2.0 * np.pi * np.asarray(time_of_day_h, dtype=float) / 24.0
        return np.stack([np.sin(phase), np.cos(phase)], axis=-1).astype(np.float32)

    def encode_clock(
        self, time_of_day_h: np.ndarray, day_of_week_: np.ndarray | None = None
    ) -> np.ndarray:
        """(n, 2 + :attr:`n_calendar`): :meth:`encode_time`, then with the calendar the day
        type (:func:`day_type`) and the hour / 24; ``day_of_week_`` (n,) is needed then."""
        tod = self.encode_time(time_of_day_h)
        if not self.calendar:
            return tod
        if day_of_week_ is None:
            raise InputError("the model reads the calendar (day_of_week), which these inputs lack")
        hour = (np.asarray(time_of_day_h, dtype=np.float32) / 24.0)[:, None]
        return np.concatenate([tod, day_type(day_of_week_), hour], axis=1).astype(np.float32)

    def clock_of(self, df: pd.DataFrame) -> np.ndarray:
        """:meth:`encode_clock` of every row of a frame (its ``time``, and ``holiday`` where
        it has one)."""
        dow = None
        if self.calendar:
            holiday = df["holiday"].to_numpy() if "holiday" in df else None
            dow = day_of_week(pd.to_datetime(df["time"]).to_numpy(), holiday)
        return self.encode_clock(time_of_day_h(df["time"]), dow)

    def to_dict(self) -> dict[str, Any]:
        return {
            "depth": self.depth,
            "exog_names": list(self.exog_names),
            "dt_s": self.dt_s,
            "temperature": self.temperature.to_dict(),
            "power": self.power.to_dict(),
            "delta_t_r": self.delta_t_r.to_dict(),
            "exog": {k: v.to_dict() for k, v in self.exog.items()},
            **({"calendar": True} if self.calendar else {}),
            **({"gain_schedule_w": list(self.gain_schedule_w)} if self.gain_schedule_w else {}),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FeatureConfig:
        return cls(
            depth=whole_number(data["depth"], "depth"),
            exog_names=tuple(data["exog_names"]),
            dt_s=float(data["dt_s"]),
            temperature=Standard(**data["temperature"]),
            power=Standard(**data["power"]),
            delta_t_r=Standard(**data["delta_t_r"]),
            exog={k: Standard(**v) for k, v in data["exog"].items()},
            calendar=data.get("calendar", False) is True,
            gain_schedule_w=tuple(float(g) for g in data.get("gain_schedule_w", ())),
        )


class Windows(NamedTuple):
    """Samples of a frame, scaled. S samples, F features."""

    x: np.ndarray  # (S, F) float32 scaled features
    t_r: np.ndarray  # (n,) measured T_r of all rows [C]
    u_phys: np.ndarray  # (n,) delivered power of all rows [W]
    exog_raw: np.ndarray  # (n, 3) T_a [C], G [W/m2], I_g [W] of all rows (0 when absent)
    t_m: np.ndarray | None  # (n,) T_m of all rows [C] when the data has it
    rows: np.ndarray  # (S,) row index i of each sample

    @property
    def t_r_next(self) -> np.ndarray:
        """(S,) target T_r,i+1 [C]."""
        return self.t_r[self.rows + 1]

    @property
    def u_phys_now(self) -> np.ndarray:
        """(S,) target u_phys,i [W]."""
        return self.u_phys[self.rows]


def _check_rows(df: pd.DataFrame, depth: int, min_samples: int, what: str) -> None:
    need = depth + 2 + min_samples
    if len(df) < need:
        raise InputError(
            f"{what}: data has {len(df)} rows, but depth {depth} needs at least {need} rows "
            f"({min_samples} sample(s) of depth+3 consecutive rows); "
            f"give more data ({setting('train_days', python='more training days')}), or a smaller "
            f"{setting('depth')}"
        )


def with_scheduled_gains(df: pd.DataFrame, schedule_w: Sequence[float]) -> pd.DataFrame:
    """A copy of ``df`` (its ``attrs`` kept) whose ``I_g`` is its measured gains plus those of
    the unmeasured-gain schedule ``schedule_w`` (:func:`pinn_mpc.data.frame_scheduled_gains_w`)."""
    out = df.assign(I_g=frame_scheduled_gains_w(df, schedule_w))
    out.attrs = dict(df.attrs)
    return out


def fit_feature_config(
    df: pd.DataFrame, *, depth: int, calendar: bool = False, optional: tuple[str, ...] = ()
) -> FeatureConfig:
    """Fit the scaling on training data (validated frame with ``attrs['dt_s']``); with
    ``calendar`` (where the data has dates) the calendar's columns, and the inputs of
    ``optional`` (:data:`OPTIONAL_EXOG`) the data has."""
    if not 1 <= depth <= MAX_DEPTH:
        raise InputError(f"depth must be 1 .. {MAX_DEPTH} intervals, got {depth}")
    _check_rows(df, depth, MIN_TRAIN_SAMPLES, "training")
    names = exog_names_for(df, optional)
    t_r = df["T_r"].to_numpy(dtype=float)
    dt_s = float(df.attrs.get("dt_s", 0.0)) or _infer_dt_s(df)
    return FeatureConfig(
        depth=depth,
        exog_names=names,
        dt_s=dt_s,
        temperature=Standard.fit(t_r),
        power=Standard.fit(df["u_phys"].to_numpy(dtype=float)),
        delta_t_r=Standard.fit(np.diff(t_r)),
        exog={n: Standard.fit(df[n].to_numpy(dtype=float)) for n in names[1:]},
        calendar=calendar and pd.api.types.is_datetime64_any_dtype(df["time"]),
    )


def _infer_dt_s(df: pd.DataFrame) -> float:
    steps = np.diff(pd.to_datetime(df["time"]).to_numpy().astype("datetime64[ns]").astype(np.int64))
    return float(np.median(steps)) / 1e9


def make_windows(df: pd.DataFrame, cfg: FeatureConfig, *, min_samples: int = 1) -> Windows:
    """All samples of a frame as scaled feature rows; raises InputError when too short."""
    missing = [
        EXOG_COLUMNS[n] for n in cfg.exog_names
        if EXOG_COLUMNS[n] not in df.columns and not (n == "I_g" and cfg.gain_schedule_w)
    ]
    missing += [c for c in ("T_r", "u_phys") if c not in df.columns]
    if missing:
        raise InputError(
            f"data lacks column(s) {missing} that the model was trained with "
            f"(exogenous inputs {list(cfg.exog_names)}); add them or map them with {setting('columns')}"
        )
    _check_rows(df, cfg.depth, min_samples, "features")
    df = cfg.complete_frame(df)
    k = cfg.depth
    n = len(df)
    t_r = df["T_r"].to_numpy(dtype=float)
    u_phys = df["u_phys"].to_numpy(dtype=float)
    u = df["u"].to_numpy(dtype=float) if "u" in df.columns else u_phys
    rows = np.arange(k + 1, n - 1)
    t_r_s = (t_r - cfg.temperature.mean) / cfg.temperature.std
    p_s = (u_phys - cfg.power.mean) / cfg.power.std
    u_s = (u - cfg.power.mean) / cfg.power.std
    offsets = np.arange(-k, 1)
    e_s = cfg.scale_exog({name: df[name].to_numpy(dtype=float) for name in cfg.exog_series})
    parts = [t_r_s[rows[:, None] + offsets], p_s[rows[:, None] + offsets - 1]]
    parts += [series[rows[:, None] + offsets] for series in e_s]
    parts += [u_s[rows, None], cfg.clock_of(df)[rows]]
    x = np.concatenate(parts, axis=1).astype(np.float32)
    raw = np.stack(
        [
            df[c].to_numpy(dtype=float) if c in df.columns else np.zeros(n)
            for c in ("T_a", "G", "I_g")
        ],
        axis=1,
    )
    t_m = df["T_m"].to_numpy(dtype=float) if "T_m" in df.columns else None
    return Windows(x=x, t_r=t_r, u_phys=u_phys, exog_raw=raw, t_m=t_m, rows=rows)
