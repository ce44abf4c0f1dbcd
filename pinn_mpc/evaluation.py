"""Accuracy of a learned model on data: one-step and recursive multi-step errors.

- one step: MAE of the ensemble-mean T_r,i+1, u_phys,i and (when the data has it) T_m,i.
- h steps: from every start i with enough data, roll the model forward recursively over the
  measured demand u and exogenous inputs (paper section 5.2), and compare T_r,i+h; MAE of the
  ensemble mean and the standard deviation of the members' MAEs.
- persistence: T_r,i+h predicted as T_r,i, over the same starts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
import torch

from pinn_mpc.data import validate_timeseries
from pinn_mpc.errors import InputError, setting
from pinn_mpc.features import check_interval
from pinn_mpc.models import LearnedModel
from pinn_mpc.records import EvaluationMetrics, HorizonErrors

if TYPE_CHECKING:
    from pinn_mpc.models.multizone_arx import MultiZoneARX
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid
    from pinn_mpc.models.multizone_paper import MultiZonePaperModel

__all__ = ["evaluate_model", "evaluate_zone_model", "recursive_paths", "recursive_t_r", "t_r_ahead"]


def _mae(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean(np.abs(a - b)))


def recursive_t_r(
    model: LearnedModel, df: pd.DataFrame, horizon: int
) -> tuple[np.ndarray, np.ndarray]:
    """Recursive predictions of T_r,i+h for every possible start i.

    Returns ``(pred (M, N) [C], starts (N,) row indices i)``; raises InputError when the frame
    is too short for one start.
    """
    paths, starts = recursive_paths(model, df, horizon)
    return paths[..., horizon - 1], starts


def t_r_ahead(
    model: Any, df: pd.DataFrame, horizon: int, first: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """T_r,i+h of a learned model (its ensemble mean, :func:`recursive_t_r`) or of an ARX
    (its own rollout) from every start i >= ``first`` that keeps i+h inside ``df``, over the
    measured demand and exogenous inputs.

    Returns ``(pred (N,) [C], starts (N,) row indices i)``.
    """
    from pinn_mpc.models.arx import ARXModel

    if isinstance(model, ARXModel):
        starts = np.arange(first, len(df) - horizon)
        return model.predict_path(df, horizon, starts)[:, -1], starts
    paths, starts = recursive_t_r(model, df, horizon)
    keep = starts >= first
    return paths.mean(axis=0)[keep], starts[keep]


def recursive_paths(
    model: LearnedModel, df: pd.DataFrame, horizon: int
) -> tuple[np.ndarray, np.ndarray]:
    """Recursive predictions of T_r,i+1 .. T_r,i+h for every possible start i, each member's
    rollout over the measured demand and exogenous inputs.

    Returns ``(paths (M, N, h) [C], starts (N,) row indices i)``; raises InputError when the
    frame is too short for one start.
    """
    k, f = model.depth, model.features
    df = f.complete_frame(df)
    n = len(df)
    starts = np.arange(k + 1, n - horizon)
    if len(starts) == 0:
        raise InputError(
            f"evaluation data has {n} rows; depth {k} and horizon {horizon} need at least "
            f"{k + 2 + horizon} rows; give more data ({setting('days', python='more days')}), or "
            f"smaller horizons ({setting('horizons')})"
        )
    t_r = (df["T_r"].to_numpy(dtype=float) - f.temperature.mean) / f.temperature.std
    u_phys = (df["u_phys"].to_numpy(dtype=float) - f.power.mean) / f.power.std
    u = (df["u"].to_numpy(dtype=float) - f.power.mean) / f.power.std
    exog = f.scale_exog({name: df[name].to_numpy(dtype=float) for name in f.exog_series})
    tod = f.clock_of(df)
    back = np.arange(-k, 1)
    ahead = np.arange(horizon)
    t_win = t_r[starts[:, None] + back]
    p_win = u_phys[starts[:, None] + back - 1]
    e_seq = exog[:, starts[:, None] + np.arange(-k, horizon)].transpose(1, 0, 2)  # (N, n_e, k+H)
    roll = model.rollout_scaled(
        torch.from_numpy(t_win.astype(np.float32)),
        torch.from_numpy(p_win.astype(np.float32)),
        torch.from_numpy(np.ascontiguousarray(e_seq, dtype=np.float32)),
        torch.from_numpy(u[starts[:, None] + ahead].astype(np.float32)),
        torch.from_numpy(tod[starts[:, None] + ahead]),
    )
    return roll.t_r_c[..., 0].numpy().astype(float), starts  # the model's one zone


def evaluate_model(
    model: LearnedModel, df: pd.DataFrame, horizons: Sequence[int]
) -> EvaluationMetrics:
    """Metrics (:class:`pinn_mpc.records.EvaluationMetrics`): ``one_step`` {T_r_mae, u_phys_mae, T_m_mae (None without T_m)},
    ``horizons`` {"h": {T_r_mae, T_r_mae_std}}, ``persistence`` {"horizons": {"h": {T_r_mae}}}.
    MAEs in C (u_phys in W) of the ensemble mean; ``T_r_mae_std`` is the std over members."""
    if not horizons or min(horizons) < 1:
        raise ValueError(f"horizons must be whole numbers >= 1, got {list(horizons)}")
    df = validate_timeseries(df, source="evaluation data")
    check_interval(model.dt_s, df.attrs["dt_s"], what="the evaluation data has")
    one = model.predict_one_step(df)
    rows = np.asarray(one["row"])
    t_r = df["T_r"].to_numpy(dtype=float)
    t_r_next = one["T_r_next"]
    u_phys = one["u_phys"]
    t_m_mae = None
    if one["T_m"] is not None and "T_m" in df.columns:
        t_m_mae = _mae(one["T_m"].mean(axis=0), df["T_m"].to_numpy(dtype=float)[rows])
    out: EvaluationMetrics = {
        "one_step": {
            "T_r_mae": _mae(t_r_next.mean(axis=0), t_r[rows + 1]),
            "u_phys_mae": _mae(u_phys.mean(axis=0), df["u_phys"].to_numpy(dtype=float)[rows]),
            "T_m_mae": t_m_mae,
        },
        "horizons": {},
        "persistence": {"horizons": {}},
    }
    for h in sorted(set(int(v) for v in horizons)):
        pred, starts = recursive_t_r(model, df, h)
        truth = t_r[starts + h]
        members = np.mean(np.abs(pred - truth), axis=1)
        out["horizons"][str(h)] = {
            "T_r_mae": _mae(pred.mean(axis=0), truth),
            "T_r_mae_std": float(np.std(members)),
        }
        out["persistence"]["horizons"][str(h)] = {"T_r_mae": _mae(t_r[starts], truth)}
    return out


def evaluate_zone_model(
    model: MultiZoneHybrid | MultiZoneARX | MultiZonePaperModel, df: pd.DataFrame, horizons: Sequence[int]
) -> EvaluationMetrics:
    """Metrics of a model of several zones on data of its building ``df`` (the data format
    of several zones, each actuator's delivered power ``u_phys[<actuator>]``): for each
    horizon h in ``horizons`` [intervals], each zone's room MAE [K] h intervals ahead, rolled
    out from every start with h rows after it on the data's delivered powers and weather
    (``predict_paths`` of the model: the hybrid from its Kalman state, the ARX and the paper's
    networks from the measured lags), their mean, and persistence (each room at i+h predicted as at i) over the
    same starts; ``one_step`` is horizon 1. InputError where the data are not the model's
    building's (other zones, a missing power column, another interval) or too short."""
    from pinn_mpc.actuator import actuator_columns
    from pinn_mpc.zones import zone_columns, zones_in

    if not horizons or min(horizons) < 1:
        raise ValueError(f"horizons must be whole numbers >= 1, got {list(horizons)}")
    names = [z.name for z in model.zones]
    theirs = [z.name for z in zones_in(df.columns)]
    if theirs != names:
        raise InputError(
            f"evaluation data hold the zones {', '.join(theirs)}, the model was trained on {', '.join(names)}; "
            "give data of the model's building"
        )
    missing = [c for c in actuator_columns("u_phys", model.actuators) if c not in df.columns]
    if missing:
        raise InputError(
            f"evaluation data have no column {', '.join(missing)}; data of a building of several "
            "actuators give each one's delivered power, u_phys[<actuator>]"
        )
    check_interval(model.dt_s, df.attrs["dt_s"], what="the evaluation data has")
    rooms = df[list(zone_columns("T_r", model.zones))].to_numpy(dtype=float)  # (T, Z)
    first, n = model.first_path_start, len(df)

    def errors(pred: np.ndarray, truth: np.ndarray) -> HorizonErrors:
        per_zone = np.mean(np.abs(pred - truth), axis=0)
        return {"T_r_mae": float(np.mean(per_zone)), "zones": dict(zip(names, map(float, per_zone), strict=True))}

    out: EvaluationMetrics = {"one_step": {"T_r_mae": math.nan}, "horizons": {}, "persistence": {"horizons": {}}}  # one_step set below
    for h in sorted({int(v) for v in horizons}):
        starts = np.arange(first, n - h)
        if starts.size == 0:
            raise InputError(
                f"evaluation data have {n} rows; the model's {first} rows of history and horizon {h} "
                f"need at least {first + h + 1}; give more data or smaller horizons ({setting('horizons')})"
            )
        truth = rooms[starts + h]
        out["horizons"][str(h)] = errors(model.predict_paths(df, starts, h)[:, -1], truth)
        out["persistence"]["horizons"][str(h)] = errors(rooms[starts], truth)
    one = out["horizons"].get("1")
    if one is None:  # horizon 1 not asked for
        one = errors(model.predict_paths(df, np.arange(first, n - 1), 1)[:, -1], rooms[first + 1 :])
    out["one_step"] = {"T_r_mae": one["T_r_mae"], "zones": one.get("zones", {})}
    return out
