"""What the planner models of a building of several zones that run from the measured history
(no state filter) share: the physics-informed ARX (:mod:`pinn_mpc.models.multizone_arx`) and
the paper's networks (:mod:`pinn_mpc.models.multizone_paper`).

:class:`LaggedZoneModel` holds the building's layout (the multi-zone RC identified from the
same data, the actuators, each zone's windows' irradiance, whether the internal gains are
read), says what the planners ask of a :class:`~pinn_mpc.models.rollout.BatchDynamics` of
several zones, and applies a plan as the RC of several zones does
(:class:`~pinn_mpc.models.multizone_rc.MultiZoneRCModel`): each actuator's demand clipped to
its bounds, and its zone's backup thermostat evaluated on the room at the interval's start (a
heater at full power below the zone's low limit and off above its high limit, a cooler
mirrored).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch

from pinn_mpc.actuator import ActuatorSpec, actuator_columns
from pinn_mpc.errors import InputError
from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
from pinn_mpc.models.rollout import BatchDynamics
from pinn_mpc.multizone import EXOGENOUS_NAMES, MultiZoneConfig, MultiZoneParams
from pinn_mpc.zones import ZoneSpec, zone_columns

__all__ = ["LaggedZoneModel", "PlanBounds"]


class PlanBounds:
    """A plan (N, H, A) [W] clipped to its actuators' bounds (``demand``), the bounds
    ``lower``, ``upper`` (A,), float64."""

    def __init__(self, u_w: torch.Tensor, actuators: Sequence[ActuatorSpec]) -> None:
        self.lower = torch.tensor([a.lower_w for a in actuators], dtype=torch.float64)
        self.upper = torch.tensor([a.upper_w for a in actuators], dtype=torch.float64)
        self.demand = torch.maximum(torch.minimum(u_w.detach().to(torch.float64), self.upper), self.lower)


class LaggedZoneModel(BatchDynamics):
    """A planner model of the building ``identified`` (its layout and the multi-zone RC of the
    same data: the fallback QP's building, ``export-rc``'s) run from the measured history:
    ``actuators`` each on one of its zones, ``dt_s`` [s] its interval, ``solar_inputs`` each
    zone's windows' irradiance (None: no windows), ``uses_gains`` whether it reads I_g,
    ``training`` the summary of its data; ``backup_low_c`` / ``backup_high_c`` [C] the zones'
    backup-thermostat limits, as :class:`MultiZoneRCModel` takes them."""

    n_members = 1
    eta = 1.0
    affine_in_plan = False  # the backup thermostats' clipping

    def __init__(
        self,
        identified: MultiZoneIdentifyResult,
        actuators: Sequence[ActuatorSpec],
        dt_s: float,
        *,
        solar_inputs: Sequence[str | None],
        uses_gains: bool,
        training: dict[str, Any],
        backup_low_c: float | tuple[float, ...] = 17.0,
        backup_high_c: float | tuple[float, ...] = 20.5,
    ) -> None:
        params = identified.params
        self.config = MultiZoneConfig(
            params=params, actuators=tuple(actuators), dt_s=dt_s, substep_s=dt_s,
            backup_low_c=backup_low_c, backup_high_c=backup_high_c,
        )
        z_n = params.n_zones
        if len(solar_inputs) != z_n or not all(s is None or s in EXOGENOUS_NAMES for s in solar_inputs):
            raise ValueError(f"{type(self).__name__}.solar_inputs: give each of the {z_n} zones an irradiance name or None")
        self.identified = identified
        self.solar_inputs, self.uses_gains, self.training = tuple(solar_inputs), bool(uses_gains), dict(training)
        low, high = self.config.backup_limits_c
        zone = np.array([a.zone for a in self.config.actuators])
        self._zone_of = torch.as_tensor(zone)
        self._heats = torch.tensor([a.heats for a in self.config.actuators])
        self._low_c, self._high_c = low[zone], high[zone]  # (A,) each actuator's zone's limits [C]

    @property
    def identified_rc(self) -> dict[str, Any] | None:
        """None: its RC is :attr:`identified` (the multi-zone RC file, ``export-rc``)."""
        return None

    @property
    def training_data(self) -> dict[str, Any]:
        return self.training

    @property
    def dt_s(self) -> float:
        return self.config.dt_s

    @property
    def actuators(self) -> tuple[ActuatorSpec, ...]:
        return self.config.actuators

    @property
    def zones(self) -> tuple[ZoneSpec, ...]:
        return self.identified.params.zone_specs

    @property
    def zone_params(self) -> MultiZoneParams | None:
        return self.identified.params

    @property
    def exog_names(self) -> tuple[str, ...]:
        """T_a, the zones' irradiance, I_g if it reads it, and the clock and calendar."""
        solar = tuple(n for n in EXOGENOUS_NAMES if n in self.solar_inputs)
        return ("T_a", *solar, *(("I_g",) if self.uses_gains else ()), "time_of_day_h", "day_of_week")

    def plan_bounds(self, u_w: torch.Tensor) -> PlanBounds:
        """The plan ``u_w`` (N, H, A) [W] clipped to the actuators' bounds; a ValueError
        naming the actuators where it is not (N, H, A)."""
        a_n = len(self.actuators)
        if u_w.dim() != 3 or u_w.shape[2] != a_n:
            raise ValueError(
                f"{type(self).__name__}.rollout: u_w must be (N, H, {a_n}), one demand per actuator "
                f"({', '.join(a.name or str(i) for i, a in enumerate(self.actuators))}), got {tuple(u_w.shape)}"
            )
        return PlanBounds(u_w, self.actuators)

    def backup_forces(self, rooms_c: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(force_on, force_off), each (N, A) bool: the actuators each zone's backup thermostat
        forces to full power or off at the rooms ``rooms_c`` (N, Z) [C]."""
        t = rooms_c[:, self._zone_of]  # (N, A) each actuator's zone's room now
        cold = t < torch.as_tensor(self._low_c, dtype=t.dtype)
        warm = t > torch.as_tensor(self._high_c, dtype=t.dtype)
        return torch.where(self._heats, cold, warm), torch.where(self._heats, warm, cold)

    def delivered_w(self, rooms_c: torch.Tensor, plan: PlanBounds, step: int) -> torch.Tensor:
        """(N, A) each actuator's power [W] in interval ``step`` of ``plan``: its demand, or what
        its zone's backup thermostat forces at the rooms ``rooms_c`` (N, Z) [C] at its start."""
        force_on, force_off = self.backup_forces(rooms_c)
        return torch.where(force_on, plan.upper, torch.where(force_off, plan.lower, plan.demand[:, step]))

    def check_history(self, history: Mapping[str, Any]) -> tuple[tuple[str, ...], tuple[str, ...], list[str]]:
        """The names of each zone's room, each actuator's delivered power and the weather
        series of :attr:`exog_names` (all but the clock) in the data format; InputError
        naming those ``history`` lacks."""
        rooms, powers = zone_columns("T_r", self.zones), actuator_columns("u_phys", self.actuators)
        weather = [x for x in self.exog_names if x not in ("time_of_day_h", "day_of_week")]
        missing = [x for x in (*rooms, *powers, *weather) if x not in history]
        if missing:
            raise InputError(f"{type(self).__name__}: the history lacks {', '.join(missing)}; give the building's observations")
        return rooms, powers, weather
