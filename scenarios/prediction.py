"""How well each model of a comparison predicts the room temperature on the test days.

Every model is started at the same instants of a held-out data set (the test part of the
weather, the training data's random policy) and rolled ``horizon`` intervals ahead on the
measured inputs; the error of ``T_r`` at the end is the figure (24 steps = 12 h at 30 min):

- a learned model: its own recursive rollout from its ``depth`` past intervals on the demanded
  power (:func:`pinn_mpc.evaluation.recursive_t_r`, ensemble mean);
- an RC parameter set: the state from a Kalman observer on the same parameters run over the
  measurements up to the start (as the RC MPCs estimate it, ``T_m`` hidden), then the exact
  2R2C on the delivered power (the heat pump's COP at each interval's T_a, as the RC MPC plans).

On a mismatched plant this is where models differ before any control: the structural error of
a 2R2C against the 3R3C, and what a network trained on the same data makes of it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from pinn_mpc.actuator import Actuator
from pinn_mpc.evaluation import recursive_t_r
from pinn_mpc.models import LearnedModel
from pinn_mpc.observer import KalmanObserver
from pinn_mpc.physics import RCParams, discretise

__all__ = ["PREDICTION_HORIZON", "prediction_errors", "rc_recursive_t_r"]

#: Steps ahead of the prediction error in the comparison report (12 h at 30-min intervals).
PREDICTION_HORIZON = 24


def rc_recursive_t_r(
    params: RCParams, df: pd.DataFrame, horizon: int, starts: np.ndarray, actuator: Actuator
) -> np.ndarray:
    """Predicted ``T_r`` at ``starts + horizon`` (N,) [C] of the 2R2C ``params`` (module docstring)."""
    dt_s = float(df.attrs["dt_s"])
    t_r = df["T_r"].to_numpy(dtype=float)
    t_a = df["T_a"].to_numpy(dtype=float)
    zeros = np.zeros(len(df))
    d = np.stack(
        [
            df["u_phys"].to_numpy(dtype=float) * actuator.gain(t_a),
            t_a,
            df["G"].to_numpy(dtype=float) if "G" in df else zeros,
            df["I_g"].to_numpy(dtype=float) if "I_g" in df else zeros,
        ],
        axis=1,
    )
    observer = KalmanObserver(params, dt_s)
    observer.reset(t_r[0])
    estimates = np.empty((len(df), 2))
    estimates[0] = observer.state[0]
    for i in range(1, int(starts.max()) + 1):
        observer.predict(*d[i - 1])
        observer.update(t_r[i])
        estimates[i] = observer.state[0]
    ad, bd = discretise(params, dt_s)
    x = estimates[starts]
    for j in range(horizon):
        x = x @ ad.T + d[starts + j] @ bd.T
    return x[:, 0]


def prediction_errors(
    df: pd.DataFrame,
    *,
    learned: Mapping[str, LearnedModel],
    rc: Mapping[str, RCParams],
    actuator: Actuator,
    horizon: int = PREDICTION_HORIZON,
) -> list[dict[str, Any]]:
    """One row per model: ``model``, ``kind``, ``T_r_mae_c`` and ``T_r_bias_c`` (prediction minus
    truth) of the ``horizon``-step prediction, over the same starts for all (the learned
    models' first possible start on)."""
    t_r = df["T_r"].to_numpy(dtype=float)
    predictions: dict[str, tuple[str, np.ndarray, np.ndarray]] = {}
    for name, model in learned.items():
        pred, starts = recursive_t_r(model, df, horizon)
        predictions[name] = ("learned", pred.mean(axis=0), starts)
    first = max((int(s[0]) for _, _, s in predictions.values()), default=1)
    common = np.arange(first, len(df) - horizon)
    rows = []
    for name, (kind, pred, starts) in predictions.items():
        pred = pred[np.searchsorted(starts, common)]
        rows.append(_row(name, kind, pred, t_r[common + horizon]))
    for name, params in rc.items():
        pred = rc_recursive_t_r(params, df, horizon, common, actuator)
        rows.append(_row(name, "RC", pred, t_r[common + horizon]))
    return rows


def _row(name: str, kind: str, pred: np.ndarray, truth: np.ndarray) -> dict[str, Any]:
    error = pred - truth
    return {
        "model": name,
        "kind": kind,
        "T_r_mae_c": float(np.mean(np.abs(error))),
        "T_r_bias_c": float(np.mean(error)),
        "n_starts": int(len(error)),
    }
