"""Physical consistency of a planner model, measured: is every temperature it predicts
non-decreasing in each heating power (non-increasing in each cooling power) and in each
outdoor temperature of the horizon?

A draw takes a history from a data frame (a random start), a random plan and a random shift
of the forecast's outdoor temperature, then raises one power of the plan (or one outdoor
temperature of the forecast) at a random step and rolls the model out on both: the draw passes
when no predicted ``T_r`` moves against the physical sign by more than :data:`TOLERANCE_C`
(float32 round-off). The physically consistent architectures (``pcnn``, ``pcnn-parx``) pass
every draw by construction; the paper's networks do not (``benchmarks/consistency.py``
measures every family).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pandas as pd
import torch

from pinn_mpc.data import day_of_week
from pinn_mpc.features import time_of_day_h
from pinn_mpc.models.rollout import BatchDynamics

__all__ = ["TOLERANCE_C", "Draw", "check_draw", "draw", "history_at"]

#: A predicted T_r may move this far [K] against the physical sign (float32 round-off).
TOLERANCE_C = 1e-4


class Draw(NamedTuple):
    """One random draw: the start row, the plan (H,) [W], the forecast's T_a shift [K], the
    step raised, the power added [W] and the outdoor temperature added [K]."""

    start: int
    plan_w: np.ndarray
    t_a_shift_c: float
    step: int
    delta_w: float
    delta_c: float


def history_at(df: pd.DataFrame, start: int, horizon: int) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The history up to row ``start`` and the measured forecast of the next ``horizon``
    intervals, as :meth:`~pinn_mpc.models.rollout.BatchDynamics.rollout` takes them."""
    tod = time_of_day_h(df["time"])
    holiday = df["holiday"].to_numpy() if "holiday" in df else None
    dow = day_of_week(pd.to_datetime(df["time"]).to_numpy(), holiday)
    series = {c: df[c].to_numpy(dtype=float) for c in df.columns if c != "time"}
    series |= {"time_of_day_h": tod, "day_of_week": dow}
    history = {n: v[: start + 1] for n, v in series.items()}
    history["u_phys"] = series["u_phys"][:start]
    history["u"] = series["u"][:start] if "u" in series else history["u_phys"]
    exog = {n: v[start : start + horizon] for n, v in series.items()}
    return history, exog


def draw(
    rng: np.random.Generator, *, n_rows: int, first: int, horizon: int, u_max_w: float
) -> Draw:
    """A random draw: a start in ``first .. n_rows - horizon``, a plan uniform in 0 .. 0.8
    ``u_max_w``, a forecast shift uniform in -5 .. 5 K, a raise of 5-20 % of ``u_max_w`` and
    of 0.5-5 K at a uniform step."""
    return Draw(
        start=int(rng.integers(first, n_rows - horizon)),
        plan_w=rng.uniform(0.0, 0.8 * u_max_w, horizon),
        t_a_shift_c=float(rng.uniform(-5.0, 5.0)),
        step=int(rng.integers(0, horizon)),
        delta_w=float(rng.uniform(0.05, 0.2) * u_max_w),
        delta_c=float(rng.uniform(0.5, 5.0)),
    )


def check_draw(model: BatchDynamics, df: pd.DataFrame, d: Draw) -> tuple[bool, bool]:
    """(power passes, outdoor temperature passes) for draw ``d`` on ``model`` with the history
    of ``df``: every predicted T_r (ensemble mean) with the raised power at least the base's
    (at most for a cooling machine, ``model.eta`` < 0), and with the raised outdoor
    temperature at least the base's, for every member, up to :data:`TOLERANCE_C`."""
    horizon = d.plan_w.size
    history, exog = history_at(df, d.start, horizon)
    exog["T_a"] = exog["T_a"] + d.t_a_shift_c
    exog = {n: exog[n] for n in model.exog_names}
    raised = d.plan_w.copy()
    raised[d.step] += d.delta_w
    with torch.no_grad():
        plans = torch.as_tensor(np.stack([d.plan_w, raised]), dtype=torch.float32)
        t_r = model.rollout(history, plans, exog).t_r_c.double()
        warmer = dict(exog)
        warmer["T_a"] = exog["T_a"].copy()
        warmer["T_a"][d.step] += d.delta_c
        t_warm = model.rollout(history, plans[:1], warmer).t_r_c.double()
    sign = 1.0 if model.eta > 0 else -1.0
    power_ok = bool(torch.all(sign * (t_r[:, 1] - t_r[:, 0]) >= -TOLERANCE_C))
    t_a_ok = bool(torch.all(t_warm[:, 0] - t_r[:, 0] >= -TOLERANCE_C))
    return power_ok, t_a_ok
