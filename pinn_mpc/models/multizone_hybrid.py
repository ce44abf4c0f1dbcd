"""The hybrid of a building of several zones: ``train``'s model of such a building.

The physics is the multi-zone RC building identified from the training data
(:func:`pinn_mpc.identify_multizone.identify_multizone`: each zone's 2R2C, aperture and share of
the internal gains, and the conductance of every internal wall, each positive), so the heat each
zone exchanges with its neighbours is physics with a learned conductance. The learned part is
each zone's residual heat (:class:`pinn_mpc.models.zone_residual.ResidualHeat`): a small network
of the clock and the calendar (a workday or not), trained on the data's day-long windows, each rolled
out from the state a Kalman filter on the identified building estimates at its start. The
residual takes neither the plan nor the state, so a planner cannot exploit it: the predicted
temperatures rise with every heater's power and fall with every chiller's.

The residual is kept only where it predicts better: :func:`fit_multizone_hybrid` trains it on
the first three quarters of the data (:data:`pinn_mpc.models.arx.SELECTION_SHARE`) and
compares the mean |error| of the rooms over the planner's horizon from every start in the last
quarter, with and without it. Kept, it is trained again on all the data; dropped, the model is
the identified building alone, and :attr:`MultiZoneHybrid.selection` says so (``train`` prints
it). A planner over it (:class:`controllers.zone_sampling.ZoneSampling`) plans as over the RC
(:class:`pinn_mpc.models.multizone_rc.MultiZoneRCModel`) with the residual added, and falls back
on the QP MPC on its identified building.

On disk (:data:`MULTIZONE_DIRECTORY`) the model is one JSON file of numbers: the layout (each
zone, each actuator with its bounds and efficiency, each zone's windows), the identified building
in the multi-zone RC file's format, the residual network and the selection. Loading it checks
every number and runs nothing.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from pinn_mpc.actuator import Actuator, ActuatorSpec, actuator_columns
from pinn_mpc.errors import InputError
from pinn_mpc.identify_multizone import MultiZoneIdentifyResult, identify_multizone
from pinn_mpc.io import DirectoryLayout
from pinn_mpc.models.arx import SELECTION_SHARE
from pinn_mpc.models.multizone_rc import MultiZoneRCModel
from pinn_mpc.models.registry import DEFAULT_ARCH
from pinn_mpc.models.zone_residual import (
    CLOCK,
    DAY_TYPE,
    ResidualHeat,
    ResidualTraining,
    fit_residual,
)
from pinn_mpc.multizone import EXOGENOUS_NAMES, history_arrays
from pinn_mpc.observer import MultiZoneObserver
from pinn_mpc.zones import ZoneSpec

__all__ = [
    "FORMAT",
    "MULTIZONE_DIRECTORY",
    "MULTIZONE_FILE",
    "MultiZoneHybrid",
    "fit_multizone_hybrid",
    "held_out_error_c",
    "load_multizone",
    "read_actuator",
    "save_multizone",
]

#: The file a multi-zone model directory holds.
MULTIZONE_FILE = "multizone.json"
#: What ``train`` writes for a building of several zones.
MULTIZONE_DIRECTORY = DirectoryLayout(
    kind="multi-zone model directory", files=(MULTIZONE_FILE,), markers=(MULTIZONE_FILE,)
)
#: The file's format tag.
FORMAT = "pinn-mpc multi-zone hybrid 1"
#: The family's name (the one-zone hybrid's: the same model, per zone).
FAMILY = DEFAULT_ARCH
#: Each zone's residual bound, as a share of the heating power that acts on the zone (or of
#: :data:`_DEFAULT_SCALE_W` where none does).
_SCALE_SHARE = 0.5
_DEFAULT_SCALE_W = 1000.0
#: The residual's inputs: the clock and the calendar. The weather is the RC's: a network of
#: the weather extrapolates to the days it was not trained on (a colder week) and was found
#: to predict held-out days worse than the RC alone.
RESIDUAL_INPUTS = (CLOCK, DAY_TYPE)
#: The relative improvement of the held-out error the residual must bring to be kept.
_KEEP_GAIN = 0.02


class MultiZoneHybrid(MultiZoneRCModel):
    """The identified building plus each zone's residual heat (module docstring), as a planner
    model (:class:`~pinn_mpc.models.multizone_rc.MultiZoneRCModel`) and a fitted model
    (:class:`~pinn_mpc.models.rollout.FittedModel`): ``identified`` the building and its fit,
    ``solar_inputs`` each zone's windows' irradiance (None: no windows), ``selection`` the
    held-out errors with and without the residual and whether it was kept, ``training``
    the summary of the training data."""

    def __init__(
        self,
        identified: MultiZoneIdentifyResult,
        actuators: Sequence[ActuatorSpec],
        dt_s: float,
        *,
        residual: ResidualHeat | None,
        solar_inputs: Sequence[str | None],
        selection: dict[str, Any],
        training: dict[str, Any],
        **planner: Any,
    ) -> None:
        super().__init__(identified.params, actuators, dt_s, residual=residual, **planner)
        self.identified = identified
        self.solar_inputs = tuple(solar_inputs)
        self.selection = dict(selection)
        self.training = dict(training)

    @property
    def family(self) -> str:
        return FAMILY

    @property
    def identified_rc(self) -> dict[str, Any] | None:
        """None: a building of several zones has no one-zone RC; its RC is
        :attr:`identified` (the multi-zone RC file, ``export-rc``)."""
        return None

    @property
    def training_data(self) -> dict[str, Any]:
        return self.training

    #: The first row of a frame :meth:`predict_paths` predicts from: its filter starts at row 0.
    first_path_start = 0

    def predict_paths(self, frame: pd.DataFrame, starts: np.ndarray, horizon: int) -> np.ndarray:
        """(len(starts), horizon, Z) each zone's room [C] at the end of the ``horizon``
        intervals after each start row of ``frame`` (data of its building, as
        :func:`fit_multizone_hybrid` takes them): each from the state a Kalman filter on its
        identified building estimates from the rows up to that start, then on the data's
        delivered powers and weather, the residual heat added where it has one. Every start
        needs ``horizon`` rows after it."""
        starts = np.asarray(starts, dtype=int)
        if starts.size and (starts.min() < self.first_path_start or starts.max() + horizon > len(frame) - 1):
            raise ValueError(f"MultiZoneHybrid.predict_paths: starts must lie in 0 .. {len(frame) - 1 - horizon}")
        if "I_g" not in frame.columns:
            frame = frame.assign(I_g=0.0)
        rc = MultiZoneRCModel(self.identified.params, self.actuators, self.dt_s)
        residual = self.residual
        q = None if residual is None else residual.heat_w(frame_series(frame, residual.names))[:-1]
        return _Windows(rc, frame).paths_c(starts, horizon, q, rc.heat_input_matrix)

    def for_planning(self, **planner: Any) -> MultiZoneHybrid:
        """This model with the planner's settings (``backup_low_c``, ``backup_high_c``,
        ``process_std_c``, ``measurement_std_c`` of :class:`MultiZoneRCModel`)."""
        return MultiZoneHybrid(
            self.identified, self.actuators, self.dt_s, residual=self.residual, solar_inputs=self.solar_inputs,
            selection=self.selection, training=self.training, **planner,
        )

    def to_json(self) -> dict[str, Any]:
        """The model file's dict (module docstring)."""
        return {
            "format": FORMAT,
            "family": FAMILY,
            "dt_s": self.dt_s,
            "zones": [z.name for z in self.zones],
            "solar_inputs": list(self.solar_inputs),
            "actuators": [asdict(a) for a in self.actuators],
            "rc": self.identified.to_json(),
            "residual": None if self.residual is None else self.residual.to_json(),
            "selection": self.selection,
            "training_data": self.training,
        }


def _heat_scale_w(zones: Sequence[ZoneSpec], actuators: Sequence[ActuatorSpec]) -> np.ndarray:
    """(Z,) each zone's residual bound [W] (:data:`_SCALE_SHARE`)."""
    scale = np.zeros(len(zones))
    for a in actuators:
        if a.heats:
            scale[a.zone] += a.upper_w
    return _SCALE_SHARE * np.where(scale > 0, scale, _DEFAULT_SCALE_W)




def frame_series(frame: pd.DataFrame, names: Sequence[str]) -> dict[str, np.ndarray]:
    """The series ``names`` of every row of ``frame``: the clock (:data:`CLOCK`) and the
    calendar (:data:`DAY_TYPE`, the ``holiday`` column's days as Sundays) from its ``time``,
    the others its columns."""
    from pinn_mpc.data import day_of_week
    from pinn_mpc.features import time_of_day_h

    out: dict[str, np.ndarray] = {}
    if "time" not in frame.columns:
        raise InputError("train: data of several zones need a time column (the residual's clock and calendar)")
    times = pd.to_datetime(frame["time"])
    for name in names:
        if name == CLOCK:
            out[name] = time_of_day_h(times)
        elif name == DAY_TYPE:
            holiday = frame["holiday"].to_numpy(dtype=float) if "holiday" in frame.columns else None
            out[name] = day_of_week(times.to_numpy(), holiday)
        else:
            out[name] = pd.to_numeric(frame[name], errors="coerce").to_numpy(dtype=float)
    return out


class _Windows:
    """The data's arrays for training and judging the residual: the RC's forcing of each
    interval, the Kalman states, the measured rooms."""

    def __init__(self, model: MultiZoneRCModel, frame: pd.DataFrame) -> None:
        history = {c: frame[c].to_numpy(dtype=float) for c in frame.columns if c != "time"}
        for c in actuator_columns("u_phys", model.actuators):  # the history's past intervals: all but the last row's
            history[c] = history[c][:-1]
        rooms, powers, inputs = history_arrays(history, model.params, model.actuators)
        gains = np.stack([a.gain(inputs[:-1, 0]) for a in model.actuators], axis=1)
        a, b_u, b_d = model.matrices
        self.rooms = rooms
        self.forced = (powers * gains) @ b_u.T + inputs[:-1] @ b_d.T  # (T-1, 2Z)
        observer = MultiZoneObserver(model.matrices)
        states = [observer.reset(rooms[0])]
        for i in range(1, len(rooms)):
            states.append(observer.step(powers[i - 1] * gains[i - 1], inputs[i - 1], rooms[i]))
        self.states = np.array(states)  # (T, 2Z) the filter's state after each row
        self.a = a

    def paths_c(self, starts: np.ndarray, horizon: int, q: np.ndarray | None, b_q: np.ndarray) -> np.ndarray:
        """(len(starts), horizon, Z) the rooms [C] at the end of each of the ``horizon``
        intervals after each start, from the filter's state there, the residual heat ``q``
        (T-1, Z) added (None: the RC alone)."""
        drive = self.forced if q is None else self.forced + q @ b_q.T
        z_n = self.rooms.shape[1]
        x = self.states[starts]
        paths = []
        for j in range(horizon):
            x = x @ self.a.T + drive[starts + j]
            paths.append(x[:, :z_n])
        return np.stack(paths, axis=1)

    def mean_error_c(self, starts: np.ndarray, horizon: int, q: np.ndarray | None, b_q: np.ndarray) -> float:
        """The rooms' mean |error| over ``horizon`` intervals from each start, the residual
        heat ``q`` (T-1, Z) added (None: the RC alone)."""
        truth = self.rooms[starts[:, None] + np.arange(1, horizon + 1)]
        return float(np.mean(np.abs(self.paths_c(starts, horizon, q, b_q) - truth)))


def fit_multizone_hybrid(
    frame: pd.DataFrame,
    *,
    zones: Sequence[ZoneSpec],
    actuators: Sequence[ActuatorSpec],
    solar_inputs: Sequence[str | None],
    dt_s: float,
    seed: int = 0,
    settings: ResidualTraining | None = None,
    adjacency: Sequence[Sequence[bool]] | np.ndarray | None = None,
) -> MultiZoneHybrid:
    """Fit the multi-zone hybrid on ``frame`` (module docstring): the building of ``zones``
    and ``actuators`` identified, each zone's windows taking its ``solar_inputs`` (None: no
    windows), at the data's step ``dt_s`` [s]; the residual trained from ``seed`` with
    ``settings`` (:class:`ResidualTraining`'s defaults if None); ``adjacency`` the zones whose
    walls are fitted (:func:`~pinn_mpc.identify_multizone.identify_multizone`'s; None: every
    pair). InputError where the data cannot be fitted (as
    :func:`~pinn_mpc.identify_multizone.identify_multizone` says)."""
    from pinn_mpc.training import data_summary

    settings = ResidualTraining() if settings is None else settings
    if "I_g" not in frame.columns:  # no measured internal gains: the residual learns them
        frame = frame.assign(I_g=0.0)
    identified = identify_multizone(
        frame, zones=zones, actuators=actuators, power_columns=actuator_columns("u_phys", actuators),
        solar_inputs=solar_inputs, dt_s=dt_s, adjacency=adjacency,
    )
    rc = MultiZoneRCModel(identified.params, actuators, dt_s)
    names = RESIDUAL_INPUTS
    series = frame_series(frame, names)
    windows = _Windows(rc, frame)
    scale = _heat_scale_w(zones, actuators)
    n = len(frame)
    h = min(settings.horizon, max(1, n // 8))
    split = int(round((1.0 - SELECTION_SHARE) * n))  # the last quarter held out

    def trained(rows: int) -> ResidualHeat:
        starts = np.arange(0, max(1, rows - 1 - h), settings.stride)
        return fit_residual(
            names=names, inputs={k: v[:rows] for k, v in series.items()}, forced=windows.forced[: rows - 1],
            starts_x=windows.states[starts], starts=starts, rooms=windows.rooms[:rows], a=windows.a,
            b_q=rc.heat_input_matrix, scale_w=scale, settings=settings, seed=seed,
        )

    held_out = np.arange(split, n - 1 - h)
    selection: dict[str, Any] = {"horizon_steps": h, "kept": False}
    residual: ResidualHeat | None = None
    if len(held_out) >= 1 and split - 1 - h >= 1:
        candidate = trained(split)
        q = candidate.heat_w(series)[:-1]
        without = windows.mean_error_c(held_out, h, None, rc.heat_input_matrix)
        with_ = windows.mean_error_c(held_out, h, q, rc.heat_input_matrix)
        kept = with_ < (1.0 - _KEEP_GAIN) * without
        selection |= {"held_out_mae_c": {"rc": without, "with_residual": with_}, "kept": bool(kept)}
        if kept:
            residual = trained(n)
    else:
        selection["why"] = "too few rows to judge a residual on held-out data"
    summary = data_summary(frame) | {"dt_s": float(dt_s)}
    return MultiZoneHybrid(
        identified, actuators, dt_s, residual=residual, solar_inputs=solar_inputs, selection=selection,
        training=summary,
    )


def held_out_error_c(model: MultiZoneHybrid, frame: pd.DataFrame, starts: np.ndarray, horizon: int) -> float:
    """The rooms' mean |error| [K] of ``model`` over the ``horizon`` intervals after each of
    the rows ``starts`` of ``frame`` (:meth:`MultiZoneHybrid.predict_paths`' predictions)."""
    from pinn_mpc.zones import zone_columns

    starts = np.asarray(starts, dtype=int)
    rooms = frame[list(zone_columns("T_r", model.zones))].to_numpy(dtype=float)
    truth = rooms[starts[:, None] + np.arange(1, horizon + 1)]
    return float(np.mean(np.abs(model.predict_paths(frame, starts, horizon) - truth)))


def save_multizone(model: MultiZoneHybrid, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` as ``path/multizone.json`` (the directory is created); the file written."""
    return write_zone_model_file(model.to_json(), path, MULTIZONE_FILE)


def write_zone_model_file(data: dict[str, Any], path: str | os.PathLike[str], name: str) -> Path:
    """Write the model file ``data`` of a building of several zones as ``path/name`` (the
    directory is created); the file written (:func:`read_zone_model_file` reads it)."""
    from pinn_mpc.io import atomic_write_json

    out = Path(path) / name
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out, data)
    return out


def read_actuator(raw: Any, file: Path, index: int) -> ActuatorSpec:
    """Actuator ``index`` of a model file ``file``, checked (InputError naming the file)."""
    if not isinstance(raw, dict) or not isinstance(raw.get("efficiency"), dict):
        raise InputError(f"{file}: actuator {index + 1} must be an object with its efficiency; train it again")
    try:
        return ActuatorSpec(**{**raw, "efficiency": Actuator(**raw["efficiency"])})
    except (TypeError, ValueError) as exc:
        raise InputError(f"{file}: actuator {index + 1}: {exc}; train it again") from None


class ZoneModelFile(NamedTuple):
    """What every model file of a building of several zones holds: its dict as read, the
    identified building, the actuators and the control interval [s]."""

    data: dict[str, Any]
    identified: MultiZoneIdentifyResult
    actuators: list[ActuatorSpec]
    dt_s: float


def read_zone_model_file(file: Path, format_tag: str, what: str) -> ZoneModelFile:
    """Read a model file of a building of several zones (``format_tag``, ``what`` it is in a
    message: "multi-zone model"): its JSON, the identified building (``rc``), the actuators
    and ``dt_s``, each checked; InputError of one line naming ``file`` otherwise. Reading runs
    nothing from the file."""
    again = "train it again"
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{file}: not a readable {what} ({exc}); {again}") from None
    if not isinstance(data, dict) or data.get("format") != format_tag:
        got = data.get("format") if isinstance(data, dict) else None
        raise InputError(f"{file}: not a {what} (format {got!r}, not {format_tag!r}); {again}")
    rc = data.get("rc")
    if not isinstance(rc, dict):
        raise InputError(f"{file}: rc must be the identified building (an object); {again}")
    identified = MultiZoneIdentifyResult.from_json(rc, source=f"{file} (rc)")
    raw_actuators = data.get("actuators")
    if not isinstance(raw_actuators, list) or not raw_actuators:
        raise InputError(f"{file}: actuators must be a non-empty list; {again}")
    actuators = [read_actuator(raw, file, i) for i, raw in enumerate(raw_actuators)]
    dt_s = data.get("dt_s")
    if isinstance(dt_s, bool) or not isinstance(dt_s, int | float) or not math.isfinite(dt_s) or dt_s <= 0:
        raise InputError(f"{file}: dt_s must be a positive number of seconds; {again}")
    return ZoneModelFile(data=data, identified=identified, actuators=actuators, dt_s=float(dt_s))


def load_multizone(path: str | os.PathLike[str]) -> MultiZoneHybrid:
    """Read ``path/multizone.json``: every number checked (reading runs nothing from the file);
    InputError naming the file otherwise."""
    file = Path(path) / MULTIZONE_FILE
    data, identified, actuators, dt_s = read_zone_model_file(file, FORMAT, "multi-zone model")
    solar = data.get("solar_inputs")
    n_zones = identified.params.n_zones
    if (
        not isinstance(solar, list) or len(solar) != n_zones
        or not all(s is None or s in EXOGENOUS_NAMES for s in solar)
    ):
        raise InputError(f"{file}: solar_inputs must give each of the {n_zones} zones an irradiance name or null")
    residual = None if data.get("residual") is None else ResidualHeat.from_json(data["residual"], source=str(file))
    selection, training = data.get("selection", {}), data.get("training_data", {})
    if not isinstance(selection, dict) or not isinstance(training, dict):
        raise InputError(f"{file}: selection and training_data must be objects; train it again")
    try:
        return MultiZoneHybrid(
            identified, actuators, float(dt_s), residual=residual, solar_inputs=solar, selection=selection,
            training=training,
        )
    except ValueError as exc:
        raise InputError(f"{file}: {exc}; train it again") from None
