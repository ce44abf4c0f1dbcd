"""How well each model of a comparison predicts the room temperature on the test days.

Every model is started at the same instants of a held-out data set (the test part of the
weather, the training data's random policy) and rolled ``horizon`` intervals ahead on the
measured inputs; the error of ``T_r`` at the end is the figure (24 steps = 12 h at 30 min,
and 1, 6 and 48 steps besides):

- a learned model: its own recursive rollout from its ``depth`` past intervals on the demanded
  power (:func:`pinn_mpc.evaluation.recursive_t_r`, ensemble mean);
- an RC parameter set: the state from a Kalman observer on the same parameters run over the
  measurements up to the start (as the RC MPCs estimate it, ``T_m`` hidden), then the exact
  2R2C on the delivered power (the heat pump's COP at each interval's T_a, as the RC MPC plans);
- a linear ARX baseline (:mod:`pinn_mpc.models.arx`): its own recursion on the delivered power.

On a mismatched plant this is where models differ before any control: the structural error of
a 2R2C against the 3R3C, and what a network trained on the same data makes of it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from controllers.estimators import RC_MPC_PROCESS_STD_C
from pinn_mpc.actuator import Actuator
from pinn_mpc.evaluation import recursive_t_r
from pinn_mpc.identify import frame_gains_w
from pinn_mpc.models import LearnedModel
from pinn_mpc.models.arx import ARXModel
from pinn_mpc.observer import KalmanObserver
from pinn_mpc.physics import RCParams, discretise
from scenarios.records import PredictionRow

__all__ = ["PREDICTION_HORIZON", "PREDICTION_HORIZONS", "prediction_errors", "rc_recursive_t_r"]

#: Steps ahead of the prediction error in the comparison report (12 h at 30-min intervals).
PREDICTION_HORIZON = 24
#: Every horizon the comparison reports (30 min, 3 h, 12 h, 24 h at 30-min intervals).
PREDICTION_HORIZONS = (1, 6, PREDICTION_HORIZON, 48)


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
            frame_gains_w(params, df),
        ],
        axis=1,
    )
    observer = KalmanObserver(params, dt_s, process_std_c=RC_MPC_PROCESS_STD_C)
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
    linear: Mapping[str, ARXModel] | None = None,
    horizons: tuple[int, ...] = PREDICTION_HORIZONS,
    horizon: int = PREDICTION_HORIZON,
) -> list[PredictionRow]:
    """One row per model: ``model``, ``kind``, ``T_r_mae_c`` and ``T_r_bias_c`` (prediction minus
    truth) of the ``horizon``-step prediction and ``T_r_mae_by_horizon_c`` (MAE by number of
    steps ahead, for each of ``horizons`` that the data holds), over the same starts for all
    models at each horizon (the learned models' first possible start on). ``linear`` are
    :class:`~pinn_mpc.models.arx.ARXModel` baselines, predicting on the delivered power."""
    t_r = df["T_r"].to_numpy(dtype=float)
    names = [*learned, *(linear or {}), *rc]
    kinds = {**dict.fromkeys(learned, "learned"), **dict.fromkeys(linear or {}, "linear"),
             **dict.fromkeys(rc, "RC")}
    errors: dict[str, dict[int, np.ndarray]] = {name: {} for name in names}
    for h in sorted({*horizons, horizon}):
        predictions: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for name, model in learned.items():
            pred, starts = recursive_t_r(model, df, h)
            predictions[name] = (pred.mean(axis=0), starts)
        first = max(
            [int(s[0]) for _, s in predictions.values()]
            + [m.lags - 1 for m in (linear or {}).values()]
            + [1]
        )
        common = np.arange(first, len(df) - h)
        if common.size == 0:
            continue
        for name, (pred, starts) in predictions.items():
            errors[name][h] = pred[np.searchsorted(starts, common)] - t_r[common + h]
        for name, arx in (linear or {}).items():
            errors[name][h] = arx.predict_t_r(df, h, common) - t_r[common + h]
        for name, params in rc.items():
            errors[name][h] = rc_recursive_t_r(params, df, h, common, actuator) - t_r[common + h]
    return [_row(name, kinds[name], errors[name], horizon) for name in names]


def _row(name: str, kind: str, errors: dict[int, np.ndarray], horizon: int) -> PredictionRow:
    main = errors.get(horizon, np.full(1, np.nan))
    return {
        "model": name,
        "kind": kind,
        "T_r_mae_c": float(np.mean(np.abs(main))),
        "T_r_bias_c": float(np.mean(main)),
        "n_starts": int(len(main)),
        "T_r_mae_by_horizon_c": {str(h): float(np.mean(np.abs(e))) for h, e in errors.items()},
    }
