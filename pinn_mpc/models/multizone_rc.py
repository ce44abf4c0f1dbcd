"""The multi-zone RC building as a planner model: :class:`MultiZoneRCModel` declares the rollout
interface (:class:`pinn_mpc.models.rollout.BatchDynamics`) for a building of Z zones and A
actuators (:mod:`pinn_mpc.multizone`), so that the sampling planners plan over it as over the
one-zone 2R2C (:class:`pinn_mpc.models.rc.RCBatchModel`).

Each interval is the exact zero-order hold of the building (:func:`pinn_mpc.multizone.discretise`,
the matrices :class:`pinn_mpc.multizone.MultiZoneSimulator` steps), batched over the N plans in
torch. Each actuator's demand is clipped to its bounds, and its zone's backup thermostat is
evaluated on the room temperature at the start of the interval (the simulator's rule with one
substep an interval: a heater at full power below the zone's low limit and off above its high
limit, a cooler mirrored). A machine's minimum modulation is not modelled: below it the
simulator cycles the machine within the interval, whose mean power is the demand.

The state at the start of the horizon: each zone's room temperature is the one measured now
(the history's ``T_r[<zone>]``), each zone's thermal mass the estimate of a Kalman filter on the
same matrices run over the whole history (:class:`pinn_mpc.observer.MultiZoneObserver`: started
at the first row with each mass equal to its room, then each interval's delivered powers and
exogenous inputs and the rooms measured at its end). The filter's state is kept between calls,
so a history that extends the previous one costs only its new rows. Simulated data with each
zone's true mass temperature (``T_m[<zone>]``, as ``simulate`` writes it) give the masses
directly, as :class:`pinn_mpc.models.rc.RCBatchModel` takes the one zone's ``T_m``.

With a ``residual`` (:class:`pinn_mpc.models.zone_residual.ResidualHeat`, the multi-zone
hybrid's learned part) each zone's air also receives the residual heat the network gives for
each interval's clock, calendar and weather, in the filter and in the rollout alike.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import torch

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.models.rollout import BatchDynamics, Rollout
from pinn_mpc.models.zone_residual import ResidualHeat
from pinn_mpc.multizone import (
    EXOGENOUS_NAMES,
    MultiZoneConfig,
    MultiZoneParams,
    SystemMatrices,
    discretise,
    history_arrays,
    needed_inputs,
)
from pinn_mpc.observer import DEFAULT_MEASUREMENT_STD_C, MultiZoneObserver
from pinn_mpc.zones import ZoneSpec, zone_columns

__all__ = ["MultiZoneRCModel"]


class MultiZoneRCModel(BatchDynamics):
    """A building of several zones and actuators (``params``, ``actuators`` each on a zone of
    it) as a one-member planner model over control intervals of ``dt_s`` [s] (module
    docstring).

    ``rollout(history, u_w, exog)``: ``u_w`` (N, H, A) each actuator's demanded electrical
    power [W]; ``exog`` the forecast's series the building takes (:attr:`exog_names`: T_a, I_g
    and the irradiance each zone with windows takes). It returns each zone's room and mass
    temperature at the end of each interval, (1, N, H, Z) [C], and the building's total
    delivered electrical power (1, N, H) [W]. ``backup_low_c`` / ``backup_high_c`` [C] are the
    zones' backup-thermostat limits (one for every zone, or one per zone; the defaults are
    :class:`pinn_mpc.multizone.MultiZoneConfig`'s); ``process_std_c`` (room, mass) [C per
    interval] and ``measurement_std_c`` [C] the state filter's noises
    (:class:`pinn_mpc.observer.MultiZoneObserver`). ``eta`` is 1: the heat per watt is each
    actuator's (its sign and efficiency). ``residual``: each zone's learned residual heat
    (module docstring), whose inputs the history and the forecast then also hold."""

    n_members = 1
    depth = 0
    eta = 1.0
    affine_in_plan = False  # the backup thermostats' clipping

    def __init__(
        self,
        params: MultiZoneParams,
        actuators: Sequence[ActuatorSpec],
        dt_s: float,
        *,
        backup_low_c: float | tuple[float, ...] = 17.0,
        backup_high_c: float | tuple[float, ...] = 20.5,
        process_std_c: tuple[float, float] = (0.05, 0.01),
        measurement_std_c: float = DEFAULT_MEASUREMENT_STD_C,
        residual: ResidualHeat | None = None,
    ) -> None:
        if not isinstance(params, MultiZoneParams):
            raise TypeError(f"MultiZoneRCModel.params must be a MultiZoneParams, got {type(params).__name__}")
        # The simulator's configuration checks the actuators, the interval and the limits.
        config = MultiZoneConfig(
            params=params, actuators=tuple(actuators), dt_s=dt_s, substep_s=dt_s,
            backup_low_c=backup_low_c, backup_high_c=backup_high_c,
        )
        if not config.actuators:
            raise ValueError("MultiZoneRCModel.actuators: give at least one actuator (an ActuatorSpec on a zone)")
        if residual is not None and residual.n_zones != params.n_zones:
            raise ValueError(
                f"MultiZoneRCModel.residual gives {residual.n_zones} zone(s)' heat for a building of {params.n_zones}"
            )
        self.params, self.config, self.residual = params, config, residual
        self.matrices: SystemMatrices = discretise(params, config.actuators, dt_s)
        #: (2Z, Z) the ZOH of one watt held into each zone's air over an interval (the
        #: residual heat's input matrix).
        self.heat_input_matrix: np.ndarray = discretise(
            params, [ActuatorSpec(upper_w=1.0, zone=z) for z in range(params.n_zones)], dt_s
        ).b_u
        observed = self.matrices
        if residual is not None:  # the filter takes the residual heat as Z more heaters
            observed = observed._replace(b_u=np.concatenate([observed.b_u, self.heat_input_matrix], axis=1))
        self.observer = MultiZoneObserver(
            observed, process_std_c=process_std_c, measurement_std_c=measurement_std_c
        )
        self._rooms = zone_columns("T_r", params.zone_specs)
        self._masses = zone_columns("T_m", params.zone_specs)
        self._needed = needed_inputs(params)
        # The history the filter has folded in, (rooms (k+1, Z), powers (k, A), inputs (k+1, 7)).
        self._seen: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        low, high = config.backup_limits_c
        zone = np.array([a.zone for a in config.actuators])
        self._backup = {
            "zone": torch.as_tensor(zone),
            "heats": torch.tensor([a.heats for a in config.actuators]),
            "low_c": low[zone],
            "high_c": high[zone],
        }

    @property
    def dt_s(self) -> float:
        return self.config.dt_s

    @property
    def exog_names(self) -> tuple[str, ...]:
        """The forecast's series the building takes (:func:`pinn_mpc.multizone.needed_inputs`),
        then those only the residual takes."""
        extra = () if self.residual is None else tuple(n for n in self.residual.names if n not in self._needed)
        return (*self._needed, *extra)

    def residual_heat_w(self, series: Mapping[str, np.ndarray], rows: int) -> np.ndarray | None:
        """(rows, Z) each zone's residual heat [W] over the first ``rows`` values of ``series``
        (the residual's inputs by name), or None without a residual."""
        if self.residual is None:
            return None
        return self.residual.heat_w({n: np.asarray(series[n], dtype=float)[:rows] for n in self.residual.names})

    @property
    def actuators(self) -> tuple[ActuatorSpec, ...]:
        return self.config.actuators

    @property
    def zones(self) -> tuple[ZoneSpec, ...]:
        return self.params.zone_specs

    @property
    def zone_params(self) -> MultiZoneParams | None:
        return self.params

    def _gains(self, t_a_c: np.ndarray) -> np.ndarray:
        """(T, A) each actuator's heat per electrical watt at the outdoor temperatures (T,)."""
        return np.stack([a.gain(t_a_c) for a in self.config.actuators], axis=-1)

    def state_now(self, history: Mapping[str, np.ndarray]) -> np.ndarray:
        """(2Z,) the state now [C]: each zone's measured room temperature, then each zone's
        mass as the Kalman filter estimates it from the whole history, or as the history's
        ``T_m[<zone>]`` has it (module docstring)."""
        if all(c in history for c in (*self._rooms, *self._masses)):
            return np.array([float(np.asarray(history[c])[-1]) for c in (*self._rooms, *self._masses)])
        rooms, powers, inputs = history_arrays(history, self.params, self.config.actuators)
        start = 0
        seen = self._seen
        if seen is not None and len(seen[0]) <= len(rooms):
            n = len(seen[0])
            if (
                np.array_equal(seen[0], rooms[:n], equal_nan=True)
                and np.array_equal(seen[1], powers[: n - 1], equal_nan=True)
                and np.array_equal(seen[2], inputs[:n], equal_nan=True)
            ):
                start = n  # the rows folded in already
        if start == 0:
            self.observer.reset(rooms[0])
            start = 1
        if start < len(rooms):
            heat = powers[start - 1 :] * self._gains(inputs[start - 1 : -1, 0])
            if self.residual is not None:
                k = len(rooms)
                past = {n: np.asarray(history[n], dtype=float)[-k:][start - 1 : -1] for n in self.residual.names}
                heat = np.concatenate([heat, self.residual.heat_w(past)], axis=1)
            for i in range(start, len(rooms)):
                self.observer.step(heat[i - start], inputs[i - 1], rooms[i])
        self._seen = (rooms, powers, inputs)
        z_n = self.params.n_zones
        return np.concatenate([rooms[-1], self.observer.state[z_n:]])

    def rollout(
        self, history: dict[str, np.ndarray], u_w: torch.Tensor, exog: dict[str, np.ndarray]
    ) -> Rollout:
        """u_w (N, H, A) [W] -> each zone's T_r and T_m at the end of each interval, tensors
        (1, N, H, Z) [C], and the total delivered electrical power (1, N, H) [W]."""
        a_n, z_n = len(self.config.actuators), self.params.n_zones
        if u_w.dim() != 3 or u_w.shape[2] != a_n:
            raise ValueError(
                f"MultiZoneRCModel.rollout: u_w must be (N, H, {a_n}), one demand per actuator "
                f"({', '.join(a.name or str(i) for i, a in enumerate(self.config.actuators))}), "
                f"got {tuple(u_w.shape)}"
            )
        n, h, _ = u_w.shape
        dtype = u_w.dtype
        x0 = self.state_now(history)
        d = np.zeros((h, len(EXOGENOUS_NAMES)))
        for name in self._needed:
            d[:, EXOGENOUS_NAMES.index(name)] = np.asarray(exog[name], dtype=float)[:h]
        a, b_u, b_d = self.matrices
        a_t, b_u_t = torch.as_tensor(a.T, dtype=dtype), torch.as_tensor(b_u.T, dtype=dtype)
        q = self.residual_heat_w(exog, h)
        drift = torch.as_tensor(d @ b_d.T + (0.0 if q is None else q @ self.heat_input_matrix.T), dtype=dtype)  # (H, 2Z)
        gain = torch.as_tensor(self._gains(d[:, 0]), dtype=dtype)  # (H, A)
        lower = torch.tensor([s.lower_w for s in self.config.actuators], dtype=dtype)
        upper = torch.tensor([s.upper_w for s in self.config.actuators], dtype=dtype)
        backup = self._backup
        low_c = torch.as_tensor(backup["low_c"], dtype=dtype)
        high_c = torch.as_tensor(backup["high_c"], dtype=dtype)
        demand = torch.maximum(torch.minimum(u_w, upper), lower)  # (N, H, A)
        x = torch.as_tensor(x0, dtype=dtype).expand(n, 2 * z_n)
        states, powers = [], []
        for j in range(h):
            t = x[:, backup["zone"]]  # (N, A) each actuator's zone's room now
            too_cold, too_warm = t < low_c, t > high_c
            force_on = torch.where(backup["heats"], too_cold, too_warm)
            force_off = torch.where(backup["heats"], too_warm, too_cold)
            p = torch.where(force_on, upper, torch.where(force_off, lower, demand[:, j]))
            x = x @ a_t + (p * gain[j]) @ b_u_t + drift[j]
            states.append(x)
            powers.append(p.sum(dim=1))
        xs = torch.stack(states, dim=1)  # (N, H, 2Z)
        return Rollout(xs[None, :, :, :z_n], torch.stack(powers, dim=1)[None], xs[None, :, :, z_n:])
