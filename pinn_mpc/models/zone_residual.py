"""The learned part of the multi-zone hybrid: each zone's residual heat, a small network of its
inputs (the hybrid gives it the clock and the calendar).

:class:`ResidualHeat` maps the exogenous inputs of an interval (its time of day, whether its
day is a workday, and any other series it was given, scaled) to the heat [W] each zone's air
receives beyond what the RC building explains: unmeasured occupancy and equipment
schedules. It depends on neither the plan nor the state, so the hybrid's predicted
temperatures stay non-decreasing in every heating power and non-increasing in every cooling
power (the RC's), whatever the network learned: a planner cannot exploit it.

The network is one hidden layer of ``tanh`` units; its output is bounded, each zone's heat
``scale_w x tanh(.)``. It is kept as numbers (JSON), evaluated in numpy when planning and
in torch when trained (:func:`fit_residual`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from pinn_mpc.errors import InputError

__all__ = ["CLOCK", "DAY_TYPE", "HIDDEN", "ResidualHeat", "ResidualTraining", "fit_residual", "residual_inputs"]

#: The time-of-day input (hours since midnight), encoded as the daily phase's sine and cosine.
CLOCK = "time_of_day_h"
#: The calendar input (0 = Monday), encoded as one flag: a weekend day or holiday (the data's
#: Sunday-or-holiday, :func:`pinn_mpc.data.day_of_week`), whose schedules differ from a
#: workday's.
DAY_TYPE = "day_of_week"
#: Hidden units of the residual network.
HIDDEN = 16


def _encode(inputs: Mapping[str, np.ndarray], names: Sequence[str], mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """(T, F) the network's features of ``inputs`` (one (T,) array per name of ``names``)."""
    columns: list[np.ndarray] = []
    scaled = 0
    for name in names:
        values = np.asarray(inputs[name], dtype=float)
        if name == CLOCK:
            phase = 2.0 * math.pi * values / 24.0
            columns += [np.sin(phase), np.cos(phase)]
        elif name == DAY_TYPE:
            columns.append((np.nan_to_num(values, nan=0.0) >= 5).astype(float))
        else:
            columns.append((values - mean[scaled]) / std[scaled])
            scaled += 1
    return np.stack(columns, axis=1)


def residual_inputs(names: Sequence[str]) -> tuple[str, ...]:
    """The series among ``names`` that are scaled (all but the clock and the calendar)."""
    return tuple(n for n in names if n not in (CLOCK, DAY_TYPE))


@dataclass(frozen=True, kw_only=True)
class ResidualHeat:
    """Each zone's residual heat [W] from an interval's exogenous inputs (module docstring).

    ``names``: the inputs, in data-format names (:data:`CLOCK`, :data:`DAY_TYPE`, ``T_a``,
    ``G``, a facade's, ``I_g``); ``mean`` / ``std`` the scaling of those other than the clock
    and the calendar; ``w1`` (F, HIDDEN), ``b1`` (HIDDEN,), ``w2`` (HIDDEN, Z), ``b2`` (Z,)
    the network; ``scale_w`` (Z,) each zone's bound [W]."""

    names: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    w1: np.ndarray
    b1: np.ndarray
    w2: np.ndarray
    b2: np.ndarray
    scale_w: np.ndarray

    def __post_init__(self) -> None:
        n_scaled = len(residual_inputs(self.names))
        n_features = sum(2 if n == CLOCK else 1 for n in self.names)
        shapes = {
            "mean": (n_scaled,), "std": (n_scaled,), "w1": (n_features, None), "b1": (None,),
            "w2": (None, None), "b2": (None,), "scale_w": (None,),
        }
        for field, shape in shapes.items():
            value = np.asarray(getattr(self, field), dtype=float)
            if value.ndim != len(shape) or any(s is not None and s != v for s, v in zip(shape, value.shape, strict=True)):
                raise ValueError(f"ResidualHeat.{field} has shape {value.shape}, expected {shape} (None: any)")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"ResidualHeat.{field} holds a value that is not finite")
        hidden, zones = np.shape(self.w2)
        if np.shape(self.w1)[1] != hidden or np.shape(self.b1) != (hidden,):
            raise ValueError(f"ResidualHeat: w1 {np.shape(self.w1)} and b1 {np.shape(self.b1)} do not match w2 {np.shape(self.w2)}")
        if np.shape(self.b2) != (zones,) or np.shape(self.scale_w) != (zones,):
            raise ValueError(f"ResidualHeat: b2 {np.shape(self.b2)} and scale_w {np.shape(self.scale_w)} must be ({zones},)")
        if np.any(np.asarray(self.std) <= 0) or np.any(np.asarray(self.scale_w) < 0):
            raise ValueError("ResidualHeat: std must be > 0 and scale_w >= 0")

    @property
    def n_zones(self) -> int:
        return int(np.shape(self.w2)[1])

    def heat_w(self, inputs: Mapping[str, np.ndarray]) -> np.ndarray:
        """(T, Z) each zone's residual heat [W] at the inputs (one (T,) array per name)."""
        x = _encode(inputs, self.names, np.asarray(self.mean), np.asarray(self.std))
        hidden = np.tanh(x @ self.w1 + self.b1)
        return np.asarray(self.scale_w) * np.tanh(hidden @ self.w2 + self.b2)

    def to_json(self) -> dict[str, Any]:
        """The network as JSON numbers."""
        return {
            "inputs": list(self.names),
            "mean": np.asarray(self.mean).tolist(), "std": np.asarray(self.std).tolist(),
            "w1": np.asarray(self.w1).tolist(), "b1": np.asarray(self.b1).tolist(),
            "w2": np.asarray(self.w2).tolist(), "b2": np.asarray(self.b2).tolist(),
            "scale_W": np.asarray(self.scale_w).tolist(),
        }

    @classmethod
    def from_json(cls, data: Any, *, source: str) -> ResidualHeat:
        """:meth:`to_json`'s dict back, checked; InputError naming ``source`` otherwise."""
        keys = ("inputs", "mean", "std", "w1", "b1", "w2", "b2", "scale_W")
        if not isinstance(data, dict) or any(k not in data for k in keys):
            raise InputError(f"{source}: the residual network needs the keys {', '.join(keys)}")
        names = data["inputs"]
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise InputError(f"{source}: residual inputs must be a list of names")
        try:
            arrays = {k: np.asarray(data[k], dtype=float) for k in keys[1:]}
            return cls(
                names=tuple(names), mean=arrays["mean"], std=arrays["std"], w1=arrays["w1"], b1=arrays["b1"],
                w2=arrays["w2"], b2=arrays["b2"], scale_w=arrays["scale_W"],
            )
        except (TypeError, ValueError) as exc:
            raise InputError(f"{source}: the residual network is malformed ({exc})") from None


@dataclass(frozen=True, kw_only=True)
class ResidualTraining:
    """How :func:`fit_residual` trains: ``epochs`` of full-batch Adam at ``learning_rate``,
    windows of ``horizon`` intervals starting every ``stride``, and ``penalty`` times the mean
    squared heat in units of ``scale_w`` added to the mean squared room error [K2]."""

    epochs: int = 200
    learning_rate: float = 0.01
    horizon: int = 48
    stride: int = 8
    penalty: float = 0.01


def fit_residual(
    *,
    names: Sequence[str],
    inputs: Mapping[str, np.ndarray],
    forced: np.ndarray,
    starts_x: np.ndarray,
    starts: np.ndarray,
    rooms: np.ndarray,
    a: np.ndarray,
    b_q: np.ndarray,
    scale_w: np.ndarray,
    settings: ResidualTraining,
    seed: int,
) -> ResidualHeat:
    """Train the residual network on windows of the data.

    ``inputs``: the exogenous series (T,) of every row; ``forced`` (T-1, 2Z) the RC's input
    term of each interval (its actuators' heat and the weather, through the ZOH matrices);
    ``starts`` (W,) the windows' first rows and ``starts_x`` (W, 2Z) the state estimated
    there; ``rooms`` (T, Z) the measured rooms; ``a`` (2Z, 2Z) and ``b_q`` (2Z, Z) the ZOH
    of the building and of a watt into each zone's air; ``scale_w`` (Z,) each zone's bound
    [W]. Each window is rolled out ``settings.horizon`` intervals (fewer at the data's end),
    the residual added to every interval; the loss is the windows' mean squared room error
    plus the penalty (:class:`ResidualTraining`)."""
    scaled = residual_inputs(names)
    mean = np.array([float(np.mean(inputs[n])) for n in scaled])
    std = np.array([max(float(np.std(inputs[n])), 1e-6) for n in scaled])
    x_all = torch.as_tensor(_encode(inputs, names, mean, std)[:-1], dtype=torch.float64)  # (T-1, F)
    z_n = rooms.shape[1]
    h = settings.horizon
    t_last = len(forced)
    steps = np.clip(starts[:, None] + np.arange(h)[None, :], 0, t_last - 1)  # (W, H)
    valid = torch.as_tensor((starts[:, None] + np.arange(h)[None, :]) < t_last, dtype=torch.float64)
    target = torch.as_tensor(rooms[np.minimum(steps + 1, len(rooms) - 1)], dtype=torch.float64)  # (W, H, Z)
    forced_t = torch.as_tensor(forced, dtype=torch.float64)
    a_t = torch.as_tensor(a.T, dtype=torch.float64)
    b_t = torch.as_tensor(b_q.T, dtype=torch.float64)
    x0 = torch.as_tensor(starts_x, dtype=torch.float64)
    steps_t = torch.as_tensor(steps)
    scale = torch.as_tensor(scale_w, dtype=torch.float64)
    generator = torch.Generator().manual_seed(int(seed))
    w1 = torch.nn.Parameter(torch.randn(x_all.shape[1], HIDDEN, generator=generator, dtype=torch.float64) / math.sqrt(x_all.shape[1]))
    b1 = torch.nn.Parameter(torch.zeros(HIDDEN, dtype=torch.float64))
    w2 = torch.nn.Parameter(torch.zeros(HIDDEN, z_n, dtype=torch.float64))  # starts at no residual
    b2 = torch.nn.Parameter(torch.zeros(z_n, dtype=torch.float64))
    optimiser = torch.optim.Adam([w1, b1, w2, b2], lr=settings.learning_rate)
    n_valid = valid.sum() * z_n
    for _ in range(settings.epochs):
        optimiser.zero_grad()
        q = scale * torch.tanh(torch.tanh(x_all @ w1 + b1) @ w2 + b2)  # (T-1, Z)
        drive = forced_t + q @ b_t  # (T-1, 2Z)
        x = x0
        errors = []
        for j in range(h):
            x = x @ a_t + drive[steps_t[:, j]]
            errors.append(x[:, :z_n] - target[:, j])
        err = torch.stack(errors, dim=1) * valid[..., None]  # (W, H, Z)
        loss = (err**2).sum() / n_valid + settings.penalty * torch.mean((q / scale) ** 2)
        loss.backward()
        optimiser.step()
    return ResidualHeat(
        names=tuple(names), mean=mean, std=std, w1=w1.detach().numpy().copy(), b1=b1.detach().numpy().copy(),
        w2=w2.detach().numpy().copy(), b2=b2.detach().numpy().copy(), scale_w=np.asarray(scale_w, dtype=float),
    )
