"""The physics-informed ARX of a building of several zones: one linear equation per zone.

Each zone's room temperature at the end of an interval is a linear function of what the
building's physics says it depends on::

    T_z,k+1 = sum_l a_z,l T_z,k-l                      (its own L lags, a >= 0)
              + sum_{j != z} c_z,j T_j,k               (every other zone now, c >= 0)
              + sum_l b_z,l sum_{i on z} q_i,k-l      (its own actuators' net heat, b >= 0)
              + sum_l o_z,l T_a,k-l + sum_l s_z,l S_z,k-l [+ sum_l g_z,l I_g,k-l]
              + schedule_z(block of day of t_k, workday of t_k)

with ``q_i = u_phys,i x gain_i(T_a) x sign_i`` the heat an actuator delivers [kW] (its
electrical power, its efficiency at the outdoor temperature, + heating, - cooling; a zone's
actuators share their weights, since a watt a heater gives and a watt a chiller takes move the
zone's air alike, which is how the package's plants and its RC models deliver them: fitted
apart, a chiller run mostly while the data's tracking fights a warm disturbance takes a weight
too weak, the bias of identifying inside a feedback loop), ``S_z``
the irradiance the zone's windows take (:func:`scenarios.experiments.compare.zone_solar_inputs`;
none for a zone without windows), ``I_g`` the internal gains where the data has them, and the
schedule one intercept per hour of the day (:data:`BLOCK_H`), separately for workdays and
weekends (:mod:`pinn_mpc.models.arx`'s calendar: holidays count as Sundays), standing in for the
unmeasured occupancy, equipment and lighting. The signs are physics: heat into a zone warms
it and a warmer neighbour warms it, and with its own lags' weights also at least 0 the
recursion is a positive system: every zone's predicted temperature rises with every heater's
power and falls with every chiller's at every step (a planner cannot exploit a dip that no
building has). Each zone's equation is fitted by bounded least squares
(:func:`scipy.optimize.lsq_linear`) on the one-step error, columns scaled to unit RMS and a
tiny ridge keeping collinear lags well posed.

A fit whose room temperatures, left alone, do not settle (the spectral radius of the
companion matrix of the lagged temperatures of every zone at least 1) is refused: its
predictions would run away over a planner's horizon. Lags, fixed: :data:`DEFAULT_LAGS` of each
room (4 hours at half-hour intervals, the one-zone ARX's :data:`pinn_mpc.models.arx.DEFAULT_LAGS`),
:data:`DEFAULT_POWER_LAGS` of each heat and :data:`WEATHER_LAGS` of the weather. Of 1 to 8
room lags and 1 to 3 heat lags, held-out day-ahead checks on 14 days of data of EnergyPlus's
small office and of the two-zone RC house were best with the most room lags, and a second or
third heat lag changed them by hundredths of a kelvin (the numbers are in the report of issue
43, not here).

As a planner model (:class:`~pinn_mpc.models.rollout.BatchDynamics`, the interface of
:class:`~pinn_mpc.models.multizone_rc.MultiZoneRCModel`) it takes plans (N, H, A) of each
actuator's electrical power, clips them to each actuator's bounds and applies each zone's
backup thermostat as the RC model does (evaluated on the room at each interval's start); it
starts from the measured lags (no state estimate). With the backups it is not affine in the
plan. It carries the multi-zone RC identified from the same data
(:class:`~pinn_mpc.identify_multizone.MultiZoneIdentifyResult`): the building a planner over
it falls back on (its QP MPC) and the RC ``export-rc`` writes.

On disk (:data:`MULTIZONE_ARX_DIRECTORY`) the model is one JSON file of numbers: the layout,
the coefficients, the identified RC; loading it checks every number and that the model
settles, and runs nothing.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch

from pinn_mpc.actuator import ActuatorSpec, actuator_columns
from pinn_mpc.errors import InputError, setting
from pinn_mpc.identify_multizone import MultiZoneIdentifyResult, identify_multizone
from pinn_mpc.io import DirectoryLayout
from pinn_mpc.models.arx import _schedule_index
from pinn_mpc.models.lagged_zones import LaggedZoneModel
from pinn_mpc.models.registry import PHYSICS_ARX
from pinn_mpc.models.rollout import LinearResponse, Rollout
from pinn_mpc.zones import ZoneSpec, zone_columns

__all__ = [
    "DEFAULT_LAGS",
    "DEFAULT_POWER_LAGS",
    "FORMAT",
    "MULTIZONE_ARX_DIRECTORY",
    "MULTIZONE_ARX_FILE",
    "WEATHER_LAGS",
    "MultiZoneARX",
    "ZoneCoefficients",
    "fit_multizone_arx",
    "load_multizone_arx",
    "save_multizone_arx",
]

#: The file of a multi-zone ARX's model directory.
MULTIZONE_ARX_FILE = "multizone_arx.json"
#: What ``train`` writes for a building of several zones when it takes the ARX.
MULTIZONE_ARX_DIRECTORY = DirectoryLayout(
    kind="multi-zone ARX model directory", files=(MULTIZONE_ARX_FILE,), markers=(MULTIZONE_ARX_FILE,)
)
#: The file's format tag.
FORMAT = "pinn-mpc multi-zone parx 1"
#: Lags of each zone's own room temperature, of each actuator's heat, of the weather.
DEFAULT_LAGS = 8
DEFAULT_POWER_LAGS = 2
WEATHER_LAGS = 2
#: The schedule a fit takes: blocks of BLOCK_H hours, workdays then weekends. An hour, not the
#: one-zone ARX's two: an office's occupancy, lights and ventilation switch on the hour, and a
#: two-hour block smears the evening's step over the hour before it. A saved model's schedule
#: says its own block (:attr:`ZoneCoefficients.block_h`).
BLOCK_H = 1.0
DAY_TYPES = 2
#: Scales that bring the inputs to order one: heat W -> kW, irradiance W/m2 -> 100 W/m2,
#: internal gains W -> kW.
_HEAT_SCALE = 1e-3
_SOLAR_SCALE = 1e-2
_GAINS_SCALE = 1e-3
#: Ridge weight relative to each (unit-RMS) column's sum of squares.
_RIDGE = 1e-8
#: The largest coefficient magnitude a saved model may hold (scaled units): fits give well
#: under 10; a larger one is an edited or damaged file.
MAX_ABS_COEF = 1e3


def _blocks(block_h: float = BLOCK_H) -> int:
    return int(round(24 / block_h))


class ZoneCoefficients:
    """Every zone's equation (module docstring), in scaled units: ``own`` (Z, L) each zone's
    weights of its own lags; ``coupling`` (Z, Z) of every other zone's room now (zero
    diagonal, >= 0); ``heat`` (Z, A, Lu) of each actuator's heat lags [K/kW] (zero for an
    actuator on another zone, >= 0); ``outdoor`` (Z, Lw) of T_a's lags; ``solar`` (Z, Lw) of
    the zone's irradiance [K per 100 W/m2] (zero without windows); ``gains`` (Z, Lw) of I_g
    [K/kW] (zero without); ``schedule`` (Z, blocks x day types) the intercepts [C]."""

    def __init__(
        self, *, own: np.ndarray, coupling: np.ndarray, heat: np.ndarray, outdoor: np.ndarray,
        solar: np.ndarray, gains: np.ndarray, schedule: np.ndarray,
    ) -> None:
        z_n = own.shape[0] if own.ndim == 2 else -1
        if heat.ndim != 3:
            raise ValueError(f"ZoneCoefficients.heat: must be (zones, actuators, lags), got {heat.shape}")
        shapes = {
            "own": (own, (z_n, own.shape[1])), "coupling": (coupling, (z_n, z_n)),
            "heat": (heat, (z_n, heat.shape[1], heat.shape[2])),
            "outdoor": (outdoor, (z_n, WEATHER_LAGS)), "solar": (solar, (z_n, WEATHER_LAGS)),
            "gains": (gains, (z_n, WEATHER_LAGS)),
            "schedule": (schedule, (z_n, schedule.shape[1] if schedule.ndim == 2 else -1)),
        }
        for name, (value, shape) in shapes.items():
            if value.shape != shape or not np.all(np.isfinite(value)):
                raise ValueError(f"ZoneCoefficients.{name}: must be {shape} finite numbers, got {value.shape}")
        blocks, rest = divmod(schedule.shape[1], DAY_TYPES)
        if rest or blocks < 1 or 24 % blocks:
            raise ValueError(
                f"ZoneCoefficients.schedule: must hold {DAY_TYPES} day types x a number of blocks that divides "
                f"24 hours, got {schedule.shape[1]} intercepts"
            )
        if own.shape[1] < 1 or heat.shape[2] < 1:
            raise ValueError("ZoneCoefficients: own and heat need at least one lag each")
        if np.any(np.diag(coupling) != 0) or np.any(coupling < 0) or np.any(heat < 0) or np.any(own < 0):
            raise ValueError(
                "ZoneCoefficients: own, coupling (zero diagonal) and heat must be >= 0 (a warmer past, a "
                "warmer neighbour and more heat warm a zone); fit them with fit_multizone_arx"
            )
        self.own, self.coupling, self.heat = own, coupling, heat
        self.outdoor, self.solar, self.gains, self.schedule = outdoor, solar, gains, schedule

    @property
    def lags(self) -> int:
        return int(self.own.shape[1])

    @property
    def block_h(self) -> float:
        """The hours of each block of :attr:`schedule`."""
        return 24.0 / (self.schedule.shape[1] // DAY_TYPES)

    @property
    def power_lags(self) -> int:
        return int(self.heat.shape[2])

    def companion(self) -> np.ndarray:
        """(Z L, Z L) the map of the lagged rooms of every zone (latest first, zone-minor) from
        one interval to the next, everything else held at zero."""
        z_n, lags = self.own.shape
        m = np.zeros((z_n * lags, z_n * lags))
        for z in range(z_n):
            for lag in range(lags):
                m[z, lag * z_n + z] = self.own[z, lag]
            m[z, :z_n] += self.coupling[z]
        for lag in range(1, lags):
            m[lag * z_n : (lag + 1) * z_n, (lag - 1) * z_n : lag * z_n] = np.eye(z_n)
        return m

    def settling_radius(self) -> float:
        """The spectral radius of :meth:`companion`: below 1 the rooms settle after a change."""
        return float(np.max(np.abs(np.linalg.eigvals(self.companion()))))

    def to_json(self) -> dict[str, Any]:
        return {name: getattr(self, name).tolist() for name in _COEFFICIENTS}


_COEFFICIENTS = ("own", "coupling", "heat", "outdoor", "solar", "gains", "schedule")


class MultiZoneARX(LaggedZoneModel):
    """The physics-informed ARX of every zone (module docstring), as a planner model and a
    fitted model (:class:`~pinn_mpc.models.rollout.FittedModel`, family ``parx``):
    ``coefficients`` its equations, ``actuators`` each on a zone of ``identified``'s building,
    ``solar_inputs`` each zone's windows' irradiance (None: no windows), ``uses_gains``
    whether it reads I_g, ``dt_s`` [s] its interval, ``identified`` the multi-zone RC of the
    same data (the fallback QP's building, ``export-rc``'s), ``selection`` what its fit
    measured, ``training`` the summary of its data. ``backup_low_c`` / ``backup_high_c`` [C]
    the zones' backup-thermostat limits, as :class:`MultiZoneRCModel` takes them."""

    def __init__(
        self,
        coefficients: ZoneCoefficients,
        identified: MultiZoneIdentifyResult,
        actuators: Sequence[ActuatorSpec],
        dt_s: float,
        *,
        solar_inputs: Sequence[str | None],
        uses_gains: bool,
        selection: dict[str, Any],
        training: dict[str, Any],
        backup_low_c: float | tuple[float, ...] = 17.0,
        backup_high_c: float | tuple[float, ...] = 20.5,
    ) -> None:
        super().__init__(
            identified, actuators, dt_s, solar_inputs=solar_inputs, uses_gains=uses_gains, training=training,
            backup_low_c=backup_low_c, backup_high_c=backup_high_c,
        )
        z_n, a_n = identified.params.n_zones, len(self.actuators)
        if coefficients.own.shape[0] != z_n or coefficients.heat.shape[1] != a_n:
            raise ValueError(
                f"MultiZoneARX.coefficients: {coefficients.own.shape[0]} zone(s) and {coefficients.heat.shape[1]} "
                f"actuator(s), the building has {z_n} and {a_n}"
            )
        for i, a in enumerate(self.actuators):
            if np.any(np.delete(coefficients.heat[:, i], a.zone, axis=0) != 0):
                raise ValueError(f"MultiZoneARX.coefficients.heat: actuator {i + 1} acts on zone {a.zone} only")
        self.coefficients, self.selection = coefficients, dict(selection)

    # -- what it is ------------------------------------------------------------------------
    @property
    def family(self) -> str:
        return PHYSICS_ARX.name

    @property
    def depth(self) -> int:
        """Its longest lag (intervals of history it reads)."""
        return max(self.coefficients.lags, self.coefficients.power_lags, WEATHER_LAGS)

    def for_planning(
        self,
        *,
        backup_low_c: float | tuple[float, ...],
        backup_high_c: float | tuple[float, ...],
        process_std_c: tuple[float, float] | None = None,
        measurement_std_c: float | None = None,
    ) -> MultiZoneARX:
        """This model with the planner's backup limits [C] (as :class:`MultiZoneRCModel` takes
        them); ``process_std_c`` and ``measurement_std_c``, a state filter's noises, do not
        apply: it starts from the measured lags."""
        return MultiZoneARX(
            self.coefficients, self.identified, self.actuators, self.dt_s, solar_inputs=self.solar_inputs,
            uses_gains=self.uses_gains, selection=self.selection, training=self.training,
            backup_low_c=backup_low_c, backup_high_c=backup_high_c,
        )

    # -- the recursion -----------------------------------------------------------------------
    def _gains(self, t_a_c: np.ndarray) -> np.ndarray:
        """(..., A) each actuator's signed heat per electrical watt, scaled [kW/W]."""
        return np.stack([a.gain(t_a_c) * a.sign * _HEAT_SCALE for a in self.actuators], axis=-1)

    def _exogenous_drift(self, series: Mapping[str, np.ndarray], rows: np.ndarray) -> np.ndarray:
        """(len(rows), Z) the weather's, gains' and schedule's part of each zone's next room
        temperature at each row ``k`` of ``series`` (each name of :attr:`exog_names`, rows
        ``k - WEATHER_LAGS + 1`` .. ``k`` present)."""
        c = self.coefficients
        t_a = np.asarray(series["T_a"], dtype=float)
        drift = np.zeros((len(rows), len(self.zones)))
        for lag in range(WEATHER_LAGS):
            drift += t_a[rows - lag, None] * c.outdoor[:, lag]
            if self.uses_gains:
                drift += np.asarray(series["I_g"], dtype=float)[rows - lag, None] * _GAINS_SCALE * c.gains[:, lag]
            for z, name in enumerate(self.solar_inputs):
                if name is not None:
                    drift[:, z] += np.asarray(series[name], dtype=float)[rows - lag] * _SOLAR_SCALE * c.solar[z, lag]
        index = _schedule_index(
            np.asarray(series["time_of_day_h"], dtype=float)[rows],
            np.asarray(series["day_of_week"], dtype=float)[rows], DAY_TYPES, c.block_h,
        )
        return drift + c.schedule[:, index].T

    def _step(
        self, rooms: torch.Tensor, heats: torch.Tensor, drift: torch.Tensor
    ) -> torch.Tensor:
        """(N, Z) the rooms at the end of the interval from ``rooms`` (N, L, Z) the lagged rooms
        (latest first), ``heats`` (N, Lu, A) the lagged scaled heats (this interval's first)
        and ``drift`` (N, Z) or (Z,)."""
        c = self._torch
        return (
            (rooms * c["own"]).sum(1) + rooms[:, 0] @ c["coupling"]
            + heats.reshape(len(heats), -1) @ c["heat"] + drift
        )

    @functools.cached_property
    def _torch(self) -> dict[str, torch.Tensor]:
        """The equations' weights as :meth:`_step` applies them (built once: the coefficients
        are fixed): ``own`` (L, Z), ``coupling`` (Z, Z) transposed, ``heat`` (Lu A, Z), lag-major."""
        c = self.coefficients
        lags = c.heat.shape[2]
        return {
            "own": torch.as_tensor(c.own.T.copy(), dtype=torch.float64),
            "coupling": torch.as_tensor(c.coupling.T.copy(), dtype=torch.float64),
            "heat": torch.as_tensor(c.heat.transpose(2, 1, 0).reshape(lags * c.heat.shape[1], -1).copy(), dtype=torch.float64),
        }

    @property
    def first_path_start(self) -> int:
        """The first row of a frame :meth:`predict_paths` predicts from: its lags' rows."""
        return self.depth - 1

    def predict_paths(self, frame: pd.DataFrame, starts: np.ndarray, horizon: int) -> np.ndarray:
        """(len(starts), horizon, Z) each zone's room [C] at the end of the ``horizon``
        intervals after each start row of ``frame`` (data format, as :func:`fit_multizone_arx`
        takes it): the recursion from the measured rooms up to each start, on the data's
        delivered powers (no backups: the data's powers were delivered) and weather."""
        starts = np.asarray(starts, dtype=int)
        lo = self.first_path_start
        if starts.size and (starts.min() < lo or starts.max() + horizon > len(frame) - 1):
            raise ValueError(f"MultiZoneARX.predict_paths: starts must lie in {lo} .. {len(frame) - 1 - horizon}")
        rooms_all, heat_all, series = self._frame_arrays(frame)
        c = self.coefficients
        rooms = torch.as_tensor(np.stack([rooms_all[starts - lag] for lag in range(c.lags)], axis=1))
        paths = []
        for j in range(horizon):
            k = starts + j
            heats = torch.as_tensor(np.stack([heat_all[k - lag] for lag in range(c.power_lags)], axis=1))
            drift = torch.as_tensor(self._exogenous_drift(series, k))
            new = self._step(rooms, heats, drift)
            rooms = torch.cat([new[:, None], rooms[:, :-1]], dim=1)
            paths.append(new)
        return torch.stack(paths, dim=1).numpy()

    def _frame_arrays(self, frame: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """The data's rooms (T, Z) [C], scaled signed heats (T, A) and :attr:`exog_names` series."""
        rooms, powers, series = _frame_arrays(frame, self.zones, self.actuators, self.exog_names)
        return rooms, powers * self._gains(series["T_a"]), series

    def rollout(
        self, history: dict[str, np.ndarray], u_w: torch.Tensor, exog: dict[str, np.ndarray]
    ) -> Rollout:
        """u_w (N, H, A) [W] each actuator's demanded electrical power -> each zone's T_r at the
        end of each interval (1, N, H, Z) [C] and the building's total delivered electrical power
        (1, N, H) [W], float64. ``history``: each zone's ``T_r[<zone>]`` up to now, each
        actuator's delivered ``u_phys[<name>]`` of the past intervals, the weather of
        :attr:`exog_names` up to now; ``exog`` (>= H,) per :attr:`exog_names` from now."""
        a_n, z_n = len(self.actuators), len(self.zones)
        plan = self.plan_bounds(u_w)
        n, h, _ = u_w.shape
        c = self.coefficients
        lags, power_lags = c.lags, c.power_lags
        room_names, power_names, weather = self.check_history(history)
        rooms_past = np.stack([np.asarray(history[x], dtype=float) for x in room_names], axis=1)  # (k+1, Z)
        past_rows = power_lags - 1
        need = max(lags, past_rows + 1, WEATHER_LAGS)
        if len(rooms_past) < need:
            raise InputError(f"MultiZoneARX: needs {need} rows of history, got {len(rooms_past)}")
        # Each series from WEATHER_LAGS - 1 rows before now through the horizon (now = exog's first).
        series = {
            x: np.concatenate([np.asarray(history[x], dtype=float)[-WEATHER_LAGS:-1], np.asarray(exog[x], dtype=float)[:h]])
            for x in weather
        }
        series |= {x: np.concatenate([np.zeros(WEATHER_LAGS - 1), np.asarray(exog[x], dtype=float)[:h]])
                   for x in ("time_of_day_h", "day_of_week")}
        drift = torch.as_tensor(self._exogenous_drift(series, np.arange(h) + WEATHER_LAGS - 1))  # (H, Z)
        gain = torch.as_tensor(self._gains(series["T_a"][WEATHER_LAGS - 1 :]))  # (H, A)
        heats_past = np.zeros((past_rows, a_n))  # latest first
        if past_rows:
            t_a_past = np.asarray(history["T_a"], dtype=float)[-past_rows - 1 : -1][::-1]
            p_past = np.stack([np.asarray(history[x], dtype=float)[-past_rows:][::-1] for x in power_names], axis=1)
            heats_past = p_past * self._gains(t_a_past)
        rooms = torch.as_tensor(rooms_past[::-1][:lags].copy()).expand(n, lags, z_n)
        heat_lags = torch.as_tensor(heats_past.copy()).expand(n, past_rows, a_n)
        out, powers = [], []
        for j in range(h):
            p = self.delivered_w(rooms[:, 0], plan, j)
            heats = torch.cat([(p * gain[j])[:, None], heat_lags], dim=1)
            new = self._step(rooms, heats, drift[j])
            rooms = torch.cat([new[:, None], rooms[:, :-1]], dim=1)
            heat_lags = heats[:, : power_lags - 1]
            out.append(new)
            powers.append(p.sum(dim=1))
        return Rollout(torch.stack(out, dim=1)[None], torch.stack(powers, dim=1)[None], None)

    def linear_response(
        self, history: Mapping[str, np.ndarray], u_w: np.ndarray, exog: Mapping[str, np.ndarray]
    ) -> LinearResponse:
        """The rollout of one plan ``u_w`` (H, A) [W] (:meth:`rollout`'s) and its exact
        response to a change of the plan (:class:`~pinn_mpc.models.rollout.LinearResponse`):
        the equations are linear in the heats, so the state is every zone's lagged rooms
        (latest first, zone-minor, :meth:`ZoneCoefficients.companion`'s order) and each
        actuator's lagged heats after this interval's (scaled, signed, as the equations take
        them), each actuator's heat per watt in each interval its efficiency at the forecast
        outdoor temperature (its sign in ``b_heat``, as the RC's), 0 where the rollout's
        backup thermostat forces the actuator or the demand lies outside its bounds (its power
        then does not follow the demand)."""
        plan = np.asarray(u_w, dtype=float)
        a_n, z_n = len(self.actuators), len(self.zones)
        if plan.ndim != 2 or plan.shape[1] != a_n:
            raise ValueError(f"MultiZoneARX.linear_response: u_w must be (H, {a_n}), one demand per actuator, got {plan.shape}")
        roll = self.rollout(dict(history), torch.as_tensor(plan[None]), dict(exog))
        rooms = roll.t_r_c[0, 0].numpy()  # (H, Z)
        now = np.array([float(np.asarray(history[x], dtype=float)[-1]) for x in zone_columns("T_r", self.zones)])
        force_on, force_off = self.backup_forces(torch.as_tensor(np.vstack([now, rooms[:-1]])))  # at each start
        bounds = self.plan_bounds(torch.as_tensor(plan[None]))
        inside = (plan >= bounds.lower.numpy()) & (plan <= bounds.upper.numpy())
        follows = (~(force_on | force_off).numpy() & inside).astype(float)
        t_a = np.asarray(exog["T_a"], dtype=float)[: len(plan)]
        heat_per_w = np.stack([s.gain(t_a) for s in self.actuators], axis=-1)  # (H, A) >= 0, as the rollout's
        signed = np.array([s.sign * _HEAT_SCALE for s in self.actuators])  # (A,) a heat's scaled, signed unit per W
        c = self.coefficients
        lags, rest = c.lags, c.power_lags - 1
        s_n = lags * z_n + rest * a_n
        a = np.zeros((s_n, s_n))
        a[: lags * z_n, : lags * z_n] = c.companion()
        for m in range(rest):  # the lagged heats' part of the new rooms, and their shift
            a[:z_n, lags * z_n + m * a_n : lags * z_n + (m + 1) * a_n] = c.heat[:, :, m + 1]
            if m:
                a[lags * z_n + m * a_n : lags * z_n + (m + 1) * a_n, lags * z_n + (m - 1) * a_n : lags * z_n + m * a_n] = np.eye(a_n)
        b_heat = np.zeros((s_n, a_n))  # per W of heat, its sign in it
        b_heat[:z_n] = c.heat[:, :, 0] * signed
        if rest:
            b_heat[lags * z_n : lags * z_n + a_n] = np.diag(signed)
        return LinearResponse(
            t_r_c=rooms, u_phys_w=roll.u_phys_w[0, 0].numpy(), a=a, b_heat=b_heat, heat_per_w=heat_per_w * follows,
            rooms=np.arange(z_n), power=follows,
        )

    def to_json(self) -> dict[str, Any]:
        """The model file's dict (module docstring)."""
        return {
            "format": FORMAT,
            "family": self.family,
            "dt_s": self.dt_s,
            "zones": [z.name for z in self.zones],
            "solar_inputs": list(self.solar_inputs),
            "uses_gains": self.uses_gains,
            "actuators": [asdict(a) for a in self.actuators],
            "coefficients": self.coefficients.to_json(),
            "rc": self.identified.to_json(),
            "selection": self.selection,
            "training_data": self.training,
        }


def _frame_arrays(
    frame: pd.DataFrame, zones: Sequence[ZoneSpec], actuators: Sequence[ActuatorSpec], names: Sequence[str]
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The data's rooms (T, Z) [C], delivered powers (T, A) [W] and the series ``names``
    (the clock and calendar from its ``time`` and ``holiday``); InputError naming what it lacks."""
    from pinn_mpc.models.multizone_hybrid import frame_series

    columns = [*zone_columns("T_r", zones), *actuator_columns("u_phys", actuators), "time"]
    columns += [n for n in names if n not in ("time_of_day_h", "day_of_week")]
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise InputError(f"multi-zone ARX: the data lack the column(s) {', '.join(missing)}; give the building's data")
    rooms = np.stack([frame[c].to_numpy(dtype=float) for c in zone_columns("T_r", zones)], axis=1)
    powers = np.stack([frame[c].to_numpy(dtype=float) for c in actuator_columns("u_phys", actuators)], axis=1)
    return rooms, powers, frame_series(frame, (*names, "time_of_day_h", "day_of_week"))


def fit_multizone_arx(
    frame: pd.DataFrame,
    *,
    zones: Sequence[ZoneSpec],
    actuators: Sequence[ActuatorSpec],
    solar_inputs: Sequence[str | None],
    dt_s: float,
    lags: int = DEFAULT_LAGS,
    power_lags: int = DEFAULT_POWER_LAGS,
    identified: MultiZoneIdentifyResult | None = None,
    adjacency: Sequence[Sequence[bool]] | np.ndarray | None = None,
    block_h: float = BLOCK_H,
) -> MultiZoneARX:
    """Fit the multi-zone physics-informed ARX on ``frame`` (module docstring): the building of
    ``zones`` and ``actuators``, each zone's windows taking its ``solar_inputs`` (None: no
    windows), at the data's step ``dt_s`` [s]; ``lags`` of each room and ``power_lags`` of each
    heat; its schedule in blocks of ``block_h`` hours (a divisor of 24). ``identified``: the
    multi-zone RC it carries (identified from ``frame`` if None, its walls those ``adjacency``
    allows: :func:`~pinn_mpc.identify_multizone.identify_multizone`'s). InputError where the
    data are too few or the fit does not settle."""
    from scipy.optimize import lsq_linear

    from pinn_mpc.training import data_summary

    if lags < 1 or power_lags < 1:
        raise ValueError(f"fit_multizone_arx: lags and power_lags must be >= 1, got {lags} and {power_lags}")
    if not (isinstance(block_h, int | float) and block_h > 0 and math.isclose(24 / block_h, round(24 / block_h))):
        raise ValueError(f"fit_multizone_arx: block_h must divide 24 hours, got {block_h!r}")
    if identified is None:
        identified = identify_multizone(
            frame if "I_g" in frame.columns else frame.assign(I_g=0.0), zones=zones, actuators=actuators,
            power_columns=actuator_columns("u_phys", actuators), solar_inputs=solar_inputs, dt_s=dt_s,
            adjacency=adjacency,
        )
    uses_gains = "I_g" in frame.columns and bool(np.any(frame["I_g"].to_numpy(dtype=float) != 0))
    z_n, a_n = len(zones), len(actuators)
    blank = ZoneCoefficients(
        own=np.zeros((z_n, lags)), coupling=np.zeros((z_n, z_n)), heat=np.zeros((z_n, a_n, power_lags)),
        outdoor=np.zeros((z_n, WEATHER_LAGS)), solar=np.zeros((z_n, WEATHER_LAGS)),
        gains=np.zeros((z_n, WEATHER_LAGS)), schedule=np.zeros((z_n, DAY_TYPES * _blocks(block_h))),
    )
    model = MultiZoneARX(
        blank, identified, actuators, dt_s, solar_inputs=solar_inputs, uses_gains=uses_gains, selection={},
        training={},
    )
    rooms, heat, series = model._frame_arrays(frame)
    k = np.arange(model.depth - 1, len(frame) - 1)
    finite = np.all(np.isfinite(rooms[k + 1]), axis=1)
    k = k[finite]
    index = _schedule_index(series["time_of_day_h"][k], series["day_of_week"][k], DAY_TYPES, block_h)
    sched = np.zeros((len(k), DAY_TYPES * _blocks(block_h)))
    sched[np.arange(len(k)), index] = 1.0
    seen = sched.any(axis=0)
    coef = {name: np.array(getattr(blank, name)) for name in _COEFFICIENTS}
    one_step = []
    for z in range(z_n):
        own_z = [a_i for a_i, a in enumerate(actuators) if a.zone == z]
        others = [j for j in range(z_n) if j != z]
        parts = [rooms[k - lag, z][:, None] for lag in range(lags)]
        parts += [rooms[k][:, others]]
        n_heat = 1 if own_z else 0  # heat is heat: the zone's actuators' summed, one weight per lag
        parts += [heat[k - lag][:, own_z].sum(axis=1, keepdims=True)[:, :n_heat] for lag in range(power_lags)]
        parts += [series["T_a"][k - lag][:, None] for lag in range(WEATHER_LAGS)]
        name = solar_inputs[z]
        if name is not None:
            parts += [series[name][k - lag][:, None] * _SOLAR_SCALE for lag in range(WEATHER_LAGS)]
        if uses_gains:
            parts += [series["I_g"][k - lag][:, None] * _GAINS_SCALE for lag in range(WEATHER_LAGS)]
        parts += [sched[:, seen]]
        x = np.concatenate(parts, axis=1)
        y = rooms[k + 1, z]
        if not np.all(np.isfinite(x)):
            raise InputError("multi-zone ARX: the data have missing values in the rows it fits; fill or drop them")
        if len(k) < 2 * x.shape[1]:
            raise InputError(
                f"multi-zone ARX: {len(frame)} rows are too few to fit {x.shape[1]} coefficients per zone; "
                "give more days of data"
            )
        n_pos = len(others) + power_lags * n_heat
        lower = np.full(x.shape[1], -np.inf)
        lower[: lags + n_pos] = 0.0
        rms = np.sqrt(np.mean(x**2, axis=0))
        rms[rms == 0] = 1.0
        xs = x / rms
        ridge = math.sqrt(_RIDGE * len(k))
        xa = np.concatenate([xs, ridge * np.eye(x.shape[1])])
        ya = np.concatenate([y, np.zeros(x.shape[1])])
        w = lsq_linear(xa, ya, bounds=(lower, np.full(x.shape[1], np.inf)), method="bvls").x / rms
        w[: lags + n_pos] = np.maximum(w[: lags + n_pos], 0.0)  # BVLS may leave a bound at -1e-20
        one_step.append(float(np.mean(np.abs(x @ w - y))))
        i = 0
        coef["own"][z] = w[i : i + lags]
        i += lags
        coef["coupling"][z, others] = w[i : i + len(others)]
        i += len(others)
        for lag in range(power_lags):
            coef["heat"][z, own_z, lag] = w[i : i + n_heat].sum()
            i += n_heat
        coef["outdoor"][z] = w[i : i + WEATHER_LAGS]
        i += WEATHER_LAGS
        if name is not None:
            coef["solar"][z] = w[i : i + WEATHER_LAGS]
            i += WEATHER_LAGS
        if uses_gains:
            coef["gains"][z] = w[i : i + WEATHER_LAGS]
            i += WEATHER_LAGS
        schedule = np.full(sched.shape[1], float(np.mean(w[i:])))  # a block the data lack: the mean
        schedule[seen] = w[i:]
        coef["schedule"][z] = schedule
    coefficients = ZoneCoefficients(**coef)
    radius = coefficients.settling_radius()
    if not radius < 1.0:
        raise InputError(
            f"multi-zone ARX: the fit's rooms never settle (spectral radius {radius:.4f} >= 1), so its "
            "predictions would run away; give more days of data, or train the hybrid (" + setting("arch") + " hybrid)"
        )
    selection = {
        "lags": lags, "power_lags": power_lags, "weather_lags": WEATHER_LAGS, "block_h": float(block_h),
        "one_step_mae_c": one_step, "settling_radius": radius,
    }
    return MultiZoneARX(
        coefficients, identified, actuators, dt_s, solar_inputs=solar_inputs, uses_gains=uses_gains,
        selection=selection, training=data_summary(frame) | {"dt_s": float(dt_s)},
    )


def save_multizone_arx(model: MultiZoneARX, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` as ``path/multizone_arx.json`` (the directory is created); the file written."""
    from pinn_mpc.models.multizone_hybrid import write_zone_model_file

    return write_zone_model_file(model.to_json(), path, MULTIZONE_ARX_FILE)


def load_multizone_arx(path: str | os.PathLike[str]) -> MultiZoneARX:
    """Read ``path/multizone_arx.json``: every number checked, and that the model settles
    (reading runs nothing from the file); InputError naming the file otherwise."""
    from pinn_mpc.models.multizone_hybrid import read_zone_model_file

    file = Path(path) / MULTIZONE_ARX_FILE
    again = "train it again"
    data, identified, actuators, dt_s = read_zone_model_file(file, FORMAT, "multi-zone ARX")
    raw = data.get("coefficients")
    if not isinstance(raw, dict) or set(raw) != set(_COEFFICIENTS):
        raise InputError(f"{file}: coefficients must be an object of {', '.join(_COEFFICIENTS)}; {again}")
    arrays: dict[str, np.ndarray] = {}
    for name in _COEFFICIENTS:
        try:
            value = np.asarray(raw[name], dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"{file}: coefficients.{name} must be an array of numbers; {again}") from None
        if value.size and not float(np.max(np.abs(value))) <= MAX_ABS_COEF:
            raise InputError(
                f"{file}: coefficients.{name} holds a value beyond {MAX_ABS_COEF:g} (or not finite), where a fit "
                f"gives well under 10: it was edited or damaged; {again}"
            )
        arrays[name] = value
    solar, uses_gains = data.get("solar_inputs"), data.get("uses_gains")
    if not isinstance(solar, list) or not isinstance(uses_gains, bool):
        raise InputError(f"{file}: solar_inputs must be a list and uses_gains true or false; {again}")
    selection, training = data.get("selection", {}), data.get("training_data", {})
    if not isinstance(selection, dict) or not isinstance(training, dict):
        raise InputError(f"{file}: selection and training_data must be objects; {again}")
    try:
        coefficients = ZoneCoefficients(**arrays)
        model = MultiZoneARX(
            coefficients, identified, actuators, float(dt_s), solar_inputs=solar, uses_gains=uses_gains,
            selection=selection, training=training,
        )
    except ValueError as exc:
        raise InputError(f"{file}: {exc}; {again}") from None
    radius = coefficients.settling_radius()
    if not radius < 1.0:
        raise InputError(
            f"{file}: its rooms never settle (spectral radius {radius:.4g} >= 1, where a fit's is below 1): "
            f"it was edited or damaged; {again}"
        )
    return model
