"""An EnergyPlus run of a building whose zones are kept and each controlled on its own.

:class:`ZonedRun` is :class:`~scenarios.plants.energyplus.run.EnergyPlusRun` (the thread, the
queues, the clock, the timeouts, the weather and gains it reads) for a model prepared with
``zones = "controlled"`` (a heater and a chiller object in every zone) and several actuators
(:class:`pinn_mpc.actuator.ActuatorSpec`, each on its zone: a heater on the zone's heater
object, a cooler on its chiller object). It takes one electrical power per actuator every
control interval; at every zone timestep an actuator's object gets ``sign x gain(T_a) x u``
watts of heat (``gain`` its efficiency at EnergyPlus's outdoor dry-bulb of that timestep:
1 for the ideal heater, the EER for a chiller; a cooler's heat negative), and the power
reported is the heat EnergyPlus reports for the object divided by the same. A backup
thermostat per actuator acts on its own zone's air temperature; the warm-up (and, with
``hold_c``, the whole run) holds every zone at the setpoint by integral control of its heat.
:func:`held_zones_run` is such a holding run, whose powers size the zones' equipment.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from pinn_mpc.actuator import Actuator, ActuatorSpec
from pinn_mpc.errors import InternalError
from scenarios.plants.energyplus.model import PreparedModel
from scenarios.plants.energyplus.run import (
    DEFAULT_TIMEOUT_S,
    HOLD_GAIN_W_PER_K_M2,
    SECONDS_PER_DAY,
    EnergyPlusRun,
    IntervalMeans,
)

__all__ = ["ZonedRun", "held_zones_run"]

_T_A = ("Site Outdoor Air Drybulb Temperature", "Environment")
_HEAT_RATE = "Other Equipment Total Heating Rate"


class ZonedRun(EnergyPlusRun):
    """One EnergyPlus simulation of a building of several zones with ``actuators`` of their
    own (module docstring), stepped one interval at a time: :meth:`start` as
    :class:`~scenarios.plants.energyplus.run.EnergyPlusRun`'s (returning each zone's air
    temperature (Z,) [C]), :meth:`step` holds (A,) electrical powers [W] (each clipped to its
    actuator's bounds) and returns the :class:`IntervalMeans` with each zone's temperatures
    and each actuator's power. The base's one-actuator fields (``actuator``, ``heat_per_w``)
    are the first actuator's and unused."""

    def __init__(
        self,
        prepared: PreparedModel,
        *,
        weather: str,
        actuators: Sequence[ActuatorSpec],
        dt_s: float = 1800.0,
        backup_c: tuple[float, float] | None = None,
        warmup_setpoint_c: float = 20.5,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        hold_c: float | None = None,
    ) -> None:
        actuators = tuple(actuators)
        if not prepared.chillers:
            raise ValueError(
                f"ZonedRun: {prepared.source} was prepared without a chiller per zone; prepare it "
                "with zones = 'controlled'"
            )
        if not actuators:
            raise ValueError("ZonedRun: give one or more actuators (ActuatorSpec, each on a zone)")
        n_zones = len(prepared.zones)
        objects: list[int] = []  # each actuator's index in _equipment(): heaters, then chillers
        for a in actuators:
            if not 0 <= a.zone < n_zones:
                raise ValueError(f"ZonedRun: actuator {a.name!r} is on zone {a.zone}, but the building has {n_zones} zones")
            if a.efficiency.min_modulation:
                raise ValueError(
                    f"ZonedRun: actuator {a.name!r} has min_modulation = {a.efficiency.min_modulation:g}; "
                    "the zones' ideal equipment runs at any power: give 0"
                )
            index = a.zone if a.heats else n_zones + a.zone
            if index in objects:
                raise ValueError(
                    f"ZonedRun: two {'heaters' if a.heats else 'coolers'} on zone {a.zone} "
                    f"({prepared.zones[a.zone]}); give each zone one of each at most"
                )
            objects.append(index)
        super().__init__(
            prepared, weather=weather, actuator=actuators[0], dt_s=dt_s, backup_c=backup_c,
            warmup_setpoint_c=warmup_setpoint_c, timeout_s=timeout_s,
            heat_per_w=actuators[0].sign, hold_c=hold_c,
        )
        self.actuators = actuators
        self._objects = np.array(objects)
        self._zone_of = np.array([a.zone for a in actuators])
        self._sign = np.array([a.sign for a in actuators])
        self._lower = np.array([a.lower_w for a in actuators])
        self._upper = np.array([a.upper_w for a in actuators])
        mult = np.asarray(prepared.multipliers, dtype=float)
        self._mult = np.concatenate([mult, mult])  # each object's zone's multiplier
        #: Each zone's holding gain: W of heat per K of error per zone timestep.
        self._zone_gain = HOLD_GAIN_W_PER_K_M2 * np.asarray(prepared.zone_floor_m2) * mult
        self._last_t_z: np.ndarray | None = None
        self._q = np.zeros(n_zones)  # each zone's heat under integral control [W]

    def start(self, start_day: int, days: int, *, year: int | None = None) -> np.ndarray:  # type: ignore[override]
        """Start a fresh run (:meth:`EnergyPlusRun.start`); each zone's air temperature at its
        start (Z,) [C]."""
        self._q = np.zeros(len(self.prepared.zones))
        self._last_t_z = None
        return np.asarray(self._start(start_day, days, year=year), dtype=float)

    def _equipment(self) -> tuple[str, ...]:
        return self.prepared.heaters + self.prepared.chillers

    def _variables(self) -> list[tuple[str, str]]:
        variables = super()._variables()
        return variables + [(_HEAT_RATE, chiller) for chiller in self.prepared.chillers]

    def _gains(self, t_a_c: float) -> np.ndarray:
        """(A,) each actuator's heat per electrical watt at outdoor temperature ``t_a_c``."""
        return np.array([float(a.gain(t_a_c)) for a in self.actuators])

    def _outdoor_c(self, state: Any) -> float:
        assert self._handles is not None
        return float(self.api.exchange.get_variable_value(state, self._handles["var"][_T_A]))

    def _read(self, state: Any) -> dict[str, Any]:
        assert self._handles is not None
        ex, var, prepared = self.api.exchange, self._handles["var"], self.prepared

        def g(name: str, key: str) -> float:
            return float(ex.get_variable_value(state, var[(name, key)]))

        reading = super()._read(state)  # the weather, the floor-area mean T_r and the gains
        t_z = np.array([g("Zone Mean Air Temperature", z) for z in prepared.zones])
        # Per zone instance; a zone multiplier repeats the heat (and the gains, as the base's).
        heat = self._mult * np.array([g(_HEAT_RATE, o) for o in self._equipment()])
        heaters_heat = heat[: len(prepared.zones)].sum()
        u_act = heat[self._objects] / (self._sign * self._gains(reading["T_a"]))
        reading.update(
            T_zones=t_z, u_act=u_act, u_phys=float(u_act.sum()),
            I_g=reading["I_g"] + heaters_heat - heat.sum(),  # the chillers' heat excluded too
        )
        return reading

    def _new_acc(self) -> dict[str, Any]:
        return {**super()._new_acc(), "u_act": np.zeros(len(self.actuators)), "T_z": []}

    def _accumulate(self, r: dict[str, Any]) -> None:
        super()._accumulate(r)
        self._acc["u_act"] += r["u_act"]
        self._acc["T_z"].append(r["T_zones"])

    def _observed(self, r: dict[str, Any]) -> None:
        super()._observed(r)
        self._last_t_z = r["T_zones"]

    def _first(self) -> Any:
        return np.array(self._last_t_z, dtype=float)

    def _means(self) -> IntervalMeans:
        acc, n = self._acc, max(self._acc["n"], 1)
        zones = np.array(acc["T_z"], dtype=float).reshape(-1, len(self.prepared.zones))
        return dataclasses.replace(
            super()._means(), t_r_zones_c=zones[-1].copy(), t_r_zones_sub_c=zones,
            u_phys_act_w=acc["u_act"] / n,
        )

    # ---- the actuators' control -----------------------------------------------------------

    def _off(self) -> Any:
        return self._lower.copy()

    def _clipped(self, u_w: Any) -> Any:
        u = np.asarray(u_w, dtype=float).reshape(-1)
        if u.shape != self._lower.shape or not np.all(np.isfinite(u)):
            raise InternalError(
                f"ZonedRun.step: one finite power per actuator ({len(self.actuators)}), got {u_w!r}"
            )
        return np.clip(u, self._lower, self._upper)

    def _demand(self, msg: Any) -> Any:
        return np.array(msg, dtype=float)

    def _warm_up(self, state: Any) -> None:
        self._zone_control(state, self.warmup_setpoint_c)
        self._set_powers(state, self._u)

    def _hold(self, state: Any) -> None:
        assert self.hold_c is not None
        self._zone_control(state, self.hold_c)

    def _zone_control(self, state: Any, setpoint_c: float) -> None:
        """Each zone's heat moves by its holding gain per K of error (setpoint minus the zone's
        air at the last timestep's end), within what its heater can give and its cooler take
        at this timestep's outdoor air; the heater gives the positive part, the cooler takes
        the negative part."""
        if self._last_t_z is None:
            return
        gains = self._gains(self._outdoor_c(state))
        capacity = np.zeros((2, len(self._q)))  # heat the heaters can give, the coolers take
        np.add.at(capacity, ((self._sign < 0).astype(int), self._zone_of), self._upper * gains)
        self._q = np.clip(self._q + self._zone_gain * (setpoint_c - self._last_t_z), -capacity[1], capacity[0])
        q = self._q[self._zone_of]  # (A,) each actuator's zone's
        heat = np.where(self._sign > 0, np.maximum(q, 0.0), np.maximum(-q, 0.0))
        self._u = np.clip(heat / gains, self._lower, self._upper)

    def _switch_off(self, state: Any) -> None:
        self._set_objects(state, np.zeros(len(self._mult)))

    def _apply(self, state: Any) -> None:
        """The powers asked, each actuator's backup thermostat on its zone's air at the last
        timestep's end: a heater full below ``backup_c[0]`` and off above ``backup_c[1]``, a
        cooler full above ``backup_c[1]`` and off below ``backup_c[0]``."""
        u = self._u
        if self.backup_c is not None and self._last_t_z is not None:
            low, high = self.backup_c
            t = self._last_t_z[self._zone_of]
            heats = self._sign > 0
            on = np.where(heats, t < low, t > high)
            off = np.where(heats, t > high, t < low)
            u = np.where(on, self._upper, np.where(off, self._lower, u))
            if np.any(u != self._u):
                self._acc["overridden"] = True
        self._set_powers(state, u)

    def _set_powers(self, state: Any, u: np.ndarray) -> None:
        """(A,) electrical powers [W]: each actuator's heat (its efficiency at this timestep's
        outdoor air, signed) to its zone's object."""
        heat = np.zeros(len(self._mult))
        np.add.at(heat, self._objects, self._sign * self._gains(self._outdoor_c(state)) * u)
        self._set_objects(state, heat)

    def _set_objects(self, state: Any, heat: np.ndarray) -> None:
        """Every heater's and chiller's object its heat [W] (per zone instance)."""
        assert self._handles is not None
        for act, q, m in zip(self._handles["act"], heat, self._mult, strict=True):
            self.api.exchange.set_actuator_value(state, act, float(q / m))


def held_zones_run(
    prepared: PreparedModel, weather: str, setpoint_c: float, *, heats: bool, efficiency: Actuator,
    dt_s: float, start_day: int, days: int, year: int | None,
) -> list[IntervalMeans]:
    """Every interval of a run whose zones an ideal thermostat each holds at ``setpoint_c``:
    from below with a heater per zone (``heats``), from above with a cooler of ``efficiency``,
    each of a power no zone needs (1 kW of heat per m2 of its floor)."""
    cop = 1.0 if efficiency.kind == "ideal" else efficiency.cop_min
    actuators = tuple(
        ActuatorSpec(upper_w=1000.0 * floor * m / cop, zone=z, heats=heats, efficiency=efficiency, name=f"zone_{z}")
        for z, (floor, m) in enumerate(zip(prepared.zone_floor_m2, prepared.multipliers, strict=True))
    )
    with ZonedRun(
        prepared, weather=weather, actuators=actuators, dt_s=dt_s, warmup_setpoint_c=setpoint_c,
        hold_c=setpoint_c,
    ) as run:
        run.start(start_day, days, year=year)
        off = np.zeros(len(actuators))
        return [run.step(off) for _ in range(days * SECONDS_PER_DAY // int(dt_s))]
