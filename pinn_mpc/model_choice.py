"""``train --arch auto`` (``train``'s default): the hybrid, the physics-informed ARX or the
consistent network on the ARX's structure, whichever predicts the building over the horizon a
planner uses it for.

The hybrid (:data:`pinn_mpc.models.registry.DEFAULT_ARCH`: a 2R2C physics block and a learned
residual) is the package's model for the buildings a 2R2C describes. A building whose dynamics
and unmeasured internal gains a 2R2C does not hold (EnergyPlus's reference buildings: a time
scale between air and mass, office schedules) is predicted several times better a day ahead
by the physics-informed ARX (:func:`pinn_mpc.models.arx.fit_physics_informed_arx`), and a learned
model that cannot predict its building cannot plan for it.

So :func:`choose_model` fits both on the first three quarters of the data
(:data:`pinn_mpc.models.arx.SELECTION_SHARE`) and lets each predict the last quarter over the
planner's horizon (:data:`PLANNER_HORIZON_S`, the 48 half-hours cem, random-shooting and the RC
MPC plan over by default): from every start in that quarter (the same starts for both, the
history before them measured) each rolls forward on the measured power and weather, and its
error is the mean |error| over every step of that horizon, the error a plan carries. A quarter
too short for the whole horizon from at least :data:`pinn_mpc.models.arx.SELECTION_HORIZON_S`
of starts shortens the horizon, to no less than that; shorter still keeps the hybrid without
a comparison. The physics-informed ARX is taken when its error is at most :data:`AUTO_RATIO`
times the hybrid's, and then fitted on all the data; otherwise the hybrid is trained on all of
it. The ratio keeps the hybrid, the model whose 2R2C the package exports, wherever the two
predict alike (on the 2R2C scenarios the hybrid errs as little or less). The last quarter is
the same season as the rest: it understates how much better the ARX extrapolates to the next
month on a building a 2R2C does not hold, hence a ratio of 3/4, not 1/2. Where the hybrid errs
more than :data:`ROUGH_MAE_C` on the held-out quarter, its 2R2C does not hold the data and there
is nothing to keep it for: the ARX is taken if it errs less at all.
Data the ARX cannot fit (a power that does not warm the room) keep the hybrid.
The networks roll out on the demanded power and the ARX on the delivered one (as ``evaluate``
does). Judged on the demand as well, the ARX lost 8 of the 11 robustness-grid data sets it
wins (``mismatch_household`` and ``winter_household`` with 60 days, whose actuators deliver
other than the data policy's random demands), and cem over the hybrid taken instead was 9-19 %
worse on ``mismatch_household`` (0.297 to 0.346 x the oracle on 30 days, seed 1) and within
0.2 % on ``winter_household``. The closed loop, not the error on the demand, decided it: the
choice keeps the delivered power.

Where the ARX is taken, the physically consistent network on its structure
(:data:`~pinn_mpc.models.registry.CONSISTENT_ARX`, ``pcnn-parx``: the ARX fitted as a positive
system, a network for the heat no controller changes) is trained on the same three quarters and
judged the same way, and taken, trained on all the data, where it errs less than the ARX. The
consistent PhysNet (``pcnn``) is not a candidate: it would add a network's training to every
building (``docs/concepts.md`` says what was measured).

Where even the chosen model errs more than :data:`ROUGH_MAE_C` on the held-out quarter,
:attr:`ModelChoice.caution` says so (``train`` prints it): neither candidate predicts this data
well, a planner over it (cem, random-shooting; ARX and network alike) makes rough plans and
leans on the MPC on the RC identified from the same data, and more days of data are the usual
remedy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from pinn_mpc.errors import InputError
from pinn_mpc.evaluation import recursive_paths
from pinn_mpc.models.arx import (
    SELECTION_HORIZON_S,
    SELECTION_SHARE,
    check_settles,
    fit_linear,
    fit_physics_informed_arx,
)
from pinn_mpc.models.registry import AUTO, CONSISTENT_ARX, DEFAULT_ARCH, PHYSICS_ARX
from pinn_mpc.training import TrainConfig, train_model

if TYPE_CHECKING:
    from collections.abc import Sequence

    from pinn_mpc.actuator import ActuatorSpec
    from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
    from pinn_mpc.models.multizone_arx import MultiZoneARX
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid
    from pinn_mpc.models.rollout import FittedModel
    from pinn_mpc.zones import ZoneSpec

__all__ = [
    "AUTO",
    "AUTO_RATIO",
    "HISTORY_ROWS",
    "PLANNER_HORIZON_S",
    "ROUGH_MAE_C",
    "ModelChoice",
    "choose_model",
    "choose_zone_model",
]

#: The physics-informed ARX replaces the hybrid when its held-out error is at most this
#: share of the hybrid's.
AUTO_RATIO = 0.75
#: Measured rows before the held-out quarter that both models may read as history (more than
#: any default depth or lag count).
HISTORY_ROWS = 64
#: The horizon [s] the candidates are judged over: the planners' default (48 half-hours,
#: :class:`controllers.base.ControlSpec`).
PLANNER_HORIZON_S = 24 * 3600.0
#: A chosen model whose held-out error [K] exceeds this draws a caution
#: (:attr:`ModelChoice.caution`).
ROUGH_MAE_C = 0.5


@dataclass(frozen=True, kw_only=True)
class ModelChoice:
    """What :func:`choose_model` chose: ``chosen`` (an architecture or baseline name), the
    ``model`` fitted on all the data, each candidate's ``held_out_mae_c`` [K] on the last
    quarter (the mean over steps 1 .. ``horizon_steps``; empty when there was no comparison),
    and ``why`` (one sentence); :attr:`horizon_h` is those steps in hours."""

    chosen: str
    model: FittedModel
    held_out_mae_c: dict[str, float]
    horizon_steps: int
    why: str

    @property
    def horizon_h(self) -> float:
        """The held-out horizon in hours (0 without a comparison)."""
        return self.horizon_steps * self.model.dt_s / 3600.0

    @property
    def caution(self) -> str | None:
        """One sentence when the chosen model's held-out error exceeds :data:`ROUGH_MAE_C`
        (None otherwise, and without a comparison)."""
        error = self.held_out_mae_c.get(self.chosen, math.nan)
        if not error > ROUGH_MAE_C:
            return None
        if self.model.identified_rc is None:
            lean = (
                "no RC could be identified from the data, so cem and random-shooting over it "
                "have no RC MPC to fall back on"
            )
        else:
            lean = (
                "cem and random-shooting over it will hand more decisions to the MPC on the RC "
                "identified from the same data"
            )
        return (
            f"the chosen {self.chosen} errs {error:.2f} C on average over the next {self.horizon_h:g} h "
            f"on the held-out quarter (more than {ROUGH_MAE_C} C): its plans will be rough and {lean}; "
            "more days of training data usually help"
        )


def _held_out(df: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame, np.ndarray, int] | None:
    """The first three quarters, the last quarter with :data:`HISTORY_ROWS` before it, the
    starts (rows of the second frame in the last quarter, a full horizon before its end) and
    the horizon (:data:`PLANNER_HORIZON_S`, shortened to leave
    :data:`~pinn_mpc.models.arx.SELECTION_HORIZON_S` of starts); None when the data is too
    short for a horizon of that length from that many starts."""
    dt_s = float(df.attrs.get("dt_s", 1800.0))
    least = max(1, round(SELECTION_HORIZON_S / dt_s))
    cut = len(df) - int(len(df) * SELECTION_SHARE)
    if cut <= 2 * HISTORY_ROWS:
        return None
    quarter = len(df) - cut
    horizon = min(max(1, round(PLANNER_HORIZON_S / dt_s)), quarter - least)
    if horizon < least:
        return None
    fitted = df.iloc[:cut].reset_index(drop=True)
    held_out = df.iloc[cut - HISTORY_ROWS :].reset_index(drop=True)
    fitted.attrs = dict(df.attrs)
    held_out.attrs = dict(df.attrs)
    starts = np.arange(HISTORY_ROWS, len(held_out) - horizon)
    return fitted, held_out, starts, horizon


def choose_model(df: pd.DataFrame, config: TrainConfig, *, progress: bool = False) -> ModelChoice:
    """The hybrid or the consistent ARX network (trained with ``config``) or the
    physics-informed ARX (``config.eta`` the actuator's sign) for the data ``df``, as the
    module docstring says."""
    split = _held_out(df)
    if split is None:
        model = train_model(df, arch=DEFAULT_ARCH, config=config, progress=progress)
        return ModelChoice(
            chosen=DEFAULT_ARCH, model=model, held_out_mae_c={}, horizon_steps=0,
            why="too little data to hold a quarter out for the comparison",
        )
    fitted, held_out, starts, horizon = split
    t_r = held_out["T_r"].to_numpy(dtype=float)
    truth = t_r[starts[:, None] + np.arange(1, horizon + 1)]  # (N, horizon)

    def network_error(arch: str) -> float:
        """The held-out error of the network ``arch`` trained on the first three quarters."""
        network = train_model(fitted, arch=arch, config=config, progress=progress)
        paths, network_starts = recursive_paths(network, held_out, horizon)
        rows = np.searchsorted(network_starts, starts)
        return float(np.mean(np.abs(paths.mean(axis=0)[rows] - truth)))

    errors = {DEFAULT_ARCH: network_error(DEFAULT_ARCH)}
    try:
        parx = fit_physics_informed_arx(fitted, eta=config.eta)
        check_settles(parx, PHYSICS_ARX.name)  # as fit_linear requires
    except InputError:
        errors[PHYSICS_ARX.name] = math.inf
    else:
        errors[PHYSICS_ARX.name] = float(
            np.mean(np.abs(parx.predict_path(held_out, horizon, starts) - truth))
        )
    hours = horizon * float(df.attrs.get("dt_s", 1800.0)) / 3600.0
    hybrid_rough = errors[DEFAULT_ARCH] > ROUGH_MAE_C and errors[PHYSICS_ARX.name] < errors[DEFAULT_ARCH]
    arx_wins = errors[PHYSICS_ARX.name] <= AUTO_RATIO * errors[DEFAULT_ARCH] or hybrid_rough
    if arx_wins:  # the consistent network on the ARX's structure competes with the ARX
        try:
            errors[CONSISTENT_ARX] = network_error(CONSISTENT_ARX)
        except InputError:
            errors[CONSISTENT_ARX] = math.inf
    order = (PHYSICS_ARX.name, DEFAULT_ARCH, CONSISTENT_ARX)
    said = f"mean error over {hours:g} h ahead on the last quarter: " + ", ".join(
        f"{name} {errors[name]:.3f} C" if math.isfinite(errors[name]) else f"{name} could not be fitted"
        for name in order if name in errors
    )
    if arx_wins:
        if errors[CONSISTENT_ARX] < errors[PHYSICS_ARX.name]:
            try:
                model = train_model(df, arch=CONSISTENT_ARX, config=config, progress=progress)
            except InputError as exc:  # its linear part does not settle on every day, on 3/4 it did
                said = f"{said}; {CONSISTENT_ARX} trained on all the data: {exc}"
            else:
                return ModelChoice(
                    chosen=CONSISTENT_ARX, model=model, held_out_mae_c=errors, horizon_steps=horizon, why=said
                )
        try:
            linear = fit_linear(PHYSICS_ARX.name, df, eta=config.eta)
        except InputError as exc:  # the fit on every day does not settle, that on 3/4 did
            said = f"{said}; {PHYSICS_ARX.name} refitted on all the data: {exc}"
        else:
            return ModelChoice(
                chosen=PHYSICS_ARX.name, model=linear, held_out_mae_c=errors,
                horizon_steps=horizon, why=said,
            )
    model = train_model(df, arch=DEFAULT_ARCH, config=config, progress=progress)
    return ModelChoice(
        chosen=DEFAULT_ARCH, model=model, held_out_mae_c=errors, horizon_steps=horizon, why=said
    )


def choose_zone_model(
    frame: pd.DataFrame,
    *,
    zones: Sequence[ZoneSpec],
    actuators: Sequence[ActuatorSpec],
    solar_inputs: Sequence[str | None],
    dt_s: float,
    seed: int = 0,
    adjacency: Sequence[Sequence[bool]] | np.ndarray | None = None,
) -> ModelChoice:
    """``train --arch auto`` on data of a building of several zones (its layout ``zones``,
    ``actuators``, ``solar_inputs``, step ``dt_s`` [s]): the multi-zone hybrid
    (:func:`pinn_mpc.models.multizone_hybrid.fit_multizone_hybrid`, its residual from
    ``seed``) or the multi-zone physics-informed ARX
    (:func:`pinn_mpc.models.multizone_arx.fit_multizone_arx`), chosen as :func:`choose_model`
    chooses for one zone: both fitted on the first three quarters, each judged by the rooms'
    mean |error| over the planner's horizon from every start in the last quarter (the hybrid
    from its Kalman state, the ARX from the measured lags), the ARX taken where it errs at
    most :data:`AUTO_RATIO` times the hybrid's (or less at all where the hybrid errs more than
    :data:`ROUGH_MAE_C`), and the chosen one fitted again on all the data."""
    from pinn_mpc.models.multizone_arx import fit_multizone_arx
    from pinn_mpc.models.multizone_hybrid import fit_multizone_hybrid, held_out_error_c
    from pinn_mpc.zones import zone_columns

    def hybrid_on(data: pd.DataFrame) -> MultiZoneHybrid:
        return fit_multizone_hybrid(
            data, zones=zones, actuators=actuators, solar_inputs=solar_inputs, dt_s=dt_s, seed=seed,
            adjacency=adjacency,
        )

    def arx_on(data: pd.DataFrame, identified: MultiZoneIdentifyResult | None = None) -> MultiZoneARX:
        return fit_multizone_arx(
            data, zones=zones, actuators=actuators, solar_inputs=solar_inputs, dt_s=dt_s, identified=identified,
            adjacency=adjacency,
        )

    n = len(frame)
    least = max(1, round(SELECTION_HORIZON_S / dt_s))
    cut = n - int(n * SELECTION_SHARE)
    horizon = min(max(1, round(PLANNER_HORIZON_S / dt_s)), n - cut - least)
    hybrid_name, arx_name = DEFAULT_ARCH, PHYSICS_ARX.name
    if horizon < least:
        return ModelChoice(
            chosen=hybrid_name, model=hybrid_on(frame), held_out_mae_c={},
            horizon_steps=0, why="too little data to hold a quarter out for the comparison",
        )
    fitted = frame.iloc[:cut].reset_index(drop=True)
    starts = np.arange(cut, n - horizon)
    hybrid = hybrid_on(fitted)
    errors = {hybrid_name: held_out_error_c(hybrid, frame, starts, horizon)}
    try:
        parx = arx_on(fitted, hybrid.identified)
    except InputError:
        errors[arx_name] = math.inf
    else:
        rooms = frame[list(zone_columns("T_r", zones))].to_numpy(dtype=float)
        truth = rooms[starts[:, None] + np.arange(1, horizon + 1)]  # (N, horizon, Z)
        errors[arx_name] = float(np.mean(np.abs(parx.predict_paths(frame, starts, horizon) - truth)))
    said = (
        f"the rooms' mean error over {horizon * dt_s / 3600.0:g} h ahead on the last quarter: "
        f"{arx_name} {errors[arx_name]:.3f} C, {hybrid_name} {errors[hybrid_name]:.3f} C"
    )
    hybrid_rough = errors[hybrid_name] > ROUGH_MAE_C and errors[arx_name] < errors[hybrid_name]
    if errors[arx_name] <= AUTO_RATIO * errors[hybrid_name] or hybrid_rough:
        try:
            model = arx_on(frame)
        except InputError as exc:  # the fit on every day does not settle, that on 3/4 did
            said = f"{said}; {arx_name} refitted on all the data: {exc}"
        else:
            return ModelChoice(chosen=arx_name, model=model, held_out_mae_c=errors, horizon_steps=horizon, why=said)
    return ModelChoice(
        chosen=hybrid_name, model=hybrid_on(frame), held_out_mae_c=errors,
        horizon_steps=horizon, why=said,
    )
