"""One EnergyPlus simulation in a thread of its own, handed over every control interval.

:class:`EnergyPlusRun` runs a :class:`~scenarios.plants.energyplus.model.PreparedModel` and
hands over every control interval through two queues: the controller's power goes in, the room
temperature at the end of the interval and the interval's means come out. The heater's power is
set through the API's ``OtherEquipment`` / ``Power Level`` actuator at every zone timestep (6
per hour), where a backup thermostat may override it. Every wait has a timeout; an error in
EnergyPlus (its first severe message) or in a callback ends the run and reaches the caller;
:meth:`EnergyPlusRun.close` stops the thread and removes the run's temporary directory, on
errors and Ctrl-C too. :func:`held_run` runs a building whose room an ideal thermostat holds.

EnergyPlus's own pitfalls handled here: its ``current_time`` follows the shortened system
timestep, so the clock is built from day of year, hour and zone timestep; handles exist only
once the API reports data ready, and variables are requested before the run; an exception in a
callback would be swallowed by ctypes and deadlock the run, so callbacks catch everything;
callbacks stay registered in pyenergyplus's global list, so each run removes its own; the
EPW's direct solar is beam normal (global horizontal = beam x sin(altitude) + diffuse); the run
period's year is chosen so that weekdays match the weather file's.
"""

from __future__ import annotations

import calendar
import copy
import datetime as dt
import json
import math
import queue
import shutil
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InputError, InternalError
from scenarios.plants.energyplus.files import (
    first_severe,
    require_energyplus,
    resolve_weather,
    weather_year,
)
from scenarios.plants.energyplus.model import PreparedModel

__all__ = ["EnergyPlusRun", "IntervalMeans", "held_run", "unlimited_power_w"]

SECONDS_PER_DAY = 86400
DEFAULT_TIMEOUT_S = 300.0
#: Gain of the holding thermostat (:class:`EnergyPlusRun` ``hold_c``) per m2 of floor.
HOLD_GAIN_W_PER_K_M2 = 10.0


@dataclass(frozen=True)
class IntervalMeans:
    """One control interval of a run: the room at its end and the means over it."""

    t_r_c: float  # zone air temperature at the end of the interval [C]
    t_r_sub_c: np.ndarray  # (S,) zone air temperature at the end of each zone timestep [C]
    u_phys_w: float  # the heater's mean heating rate as EnergyPlus reports it [W]
    t_a_c: float  # outdoor dry-bulb [C]
    g_w_per_m2: float  # global horizontal irradiance [W/m2]
    i_g_w: float  # the building's own sensible internal gains (the heater's excluded) [W]
    overridden: bool  # the backup thermostat changed the power in some zone timestep
    # A run of several actuators on zones kept (:class:`scenarios.plants.energyplus.zoned.ZonedRun`);
    # None in a run of the building's one actuator:
    t_r_zones_c: np.ndarray | None = None  # (Z,) each zone's air temperature at the end [C]
    t_r_zones_sub_c: np.ndarray | None = None  # (S, Z) each zone's at the end of each zone timestep [C]
    u_phys_act_w: np.ndarray | None = None  # (A,) each actuator's mean electrical power [W]


_STOP = object()


class EnergyPlusRun:
    """One EnergyPlus simulation of a :class:`PreparedModel`, stepped one interval at a time.

    :meth:`start` begins a run at 00:00 of ``start_day`` (day of the year, 1 = 1 January) for
    ``days`` days (at most a year, into the next year too: the weather file's typical year
    repeats); EnergyPlus's warm-up days hold the room near ``warmup_setpoint_c`` and the
    call returns the room temperature then. :meth:`step` holds a heater power for one control
    interval (``dt_s``), within the bounds of ``actuator`` (the heater or chiller, heating
    where ``heat_per_w > 0``), and returns its :class:`IntervalMeans`. A backup thermostat
    (full power below ``backup_c[0]``, off above ``backup_c[1]``; mirrored for a chiller) acts
    per zone timestep. ``heat_per_w`` is the heat per watt of power (1: the ideal electric heater;
    minus a COP: an ideal chiller, whose equipment extracts heat, a negative
    ``OtherEquipment`` power); the reported power is the heat delivered divided by it. With
    ``hold_c`` set, the power asked is ignored and an ideal thermostat (integral control per
    zone timestep, as in the warm-up) holds T_r at ``hold_c``: :func:`size_heater` measures
    the power that takes. Use it as a context manager, or call :meth:`close`.
    """

    def __init__(
        self,
        prepared: PreparedModel,
        *,
        weather: str,
        actuator: ActuatorSpec,
        dt_s: float = 1800.0,
        backup_c: tuple[float, float] | None = None,
        warmup_setpoint_c: float = 20.5,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        heat_per_w: float = 1.0,
        hold_c: float | None = None,
    ) -> None:
        require_energyplus()
        if not (math.isfinite(heat_per_w) and heat_per_w != 0):
            raise ValueError(f"EnergyPlusRun: heat_per_w must be a nonzero number, got {heat_per_w!r}")
        if actuator.heats != (heat_per_w > 0):
            raise ValueError(
                f"EnergyPlusRun: heat_per_w = {heat_per_w:g} but the actuator "
                f"{'heats' if actuator.heats else 'cools'}; give a heater a positive heat per watt, "
                "a chiller a negative one"
            )
        self.prepared = prepared
        self.heat_per_w = float(heat_per_w)
        self.hold_c = hold_c
        #: The holding thermostat's gain: W per K of error per zone timestep (per m2 of floor).
        self.hold_gain_w_per_k = HOLD_GAIN_W_PER_K_M2 * prepared.floor_m2 / abs(self.heat_per_w)
        self.epw = resolve_weather(weather)
        self.year = weather_year(self.epw)
        self.actuator, self.dt_s = actuator, int(dt_s)
        step_s = 3600 // prepared.timesteps_per_hour
        if self.dt_s % step_s or SECONDS_PER_DAY % self.dt_s:
            valid = [s for s in range(step_s, 4 * 3600 + 1, step_s) if SECONDS_PER_DAY % s == 0]
            raise InputError(
                f"EnergyPlus: the control interval [simulation] dt_s = {dt_s:g} s must be a whole "
                f"number of its {step_s} s timesteps and divide the day; set dt_s to one of "
                f"{', '.join(str(s) for s in valid)} (s)"
            )
        self.backup_c = backup_c
        self.warmup_setpoint_c = warmup_setpoint_c
        self.timeout_s = timeout_s
        self._thread: threading.Thread | None = None
        self._state: Any = None
        self._callbacks: list[Any] = []
        self._tmp: Path | None = None
        self._done = True
        self._start_day = 1

    # ---- the caller's side --------------------------------------------------------------

    def start(self, start_day: int, days: int, *, year: int | None = None) -> float:
        """Start a fresh run (closing one in progress); the room temperature at its start.

        ``year`` (a non-leap year, and so the next one when the run crosses 31 December) sets
        the calendar, so the building's weekday schedules follow the caller's dates; by default
        the year whose weekdays match the weather file.
        """
        first = self._start(start_day, days, year=year)
        assert isinstance(first, float)
        return first

    def _start(self, start_day: int, days: int, *, year: int | None) -> Any:
        """:meth:`start`: what the run hands over at its start (:meth:`_first`)."""
        from pyenergyplus import runtime as ep_runtime
        from pyenergyplus.api import EnergyPlusAPI

        self.close()
        if not (1 <= start_day <= 365 and 1 <= days <= 365):
            raise InputError(
                f"EnergyPlus runs at most a year from a day of the year: {days} day(s) from day "
                f"{start_day}; use 1 .. 365 of each"
            )
        run_year = self.year if year is None else int(year)
        crosses = start_day + days - 1 > 365
        for y in (run_year, run_year + 1) if crosses else (run_year,):
            if calendar.isleap(y):
                raise InputError(
                    f"EnergyPlus runs on a typical (365-day) weather year, so a run cannot be "
                    f"dated in the leap year {y}; date the series in non-leap years"
                )
        begin = dt.date(run_year, 1, 1) + dt.timedelta(days=start_day - 1)
        end = begin + dt.timedelta(days=days - 1)
        self._start_day = start_day
        model = copy.deepcopy(self.prepared.model)
        model["RunPeriod"] = {
            "PINN-MPC Run": {
                "begin_month": begin.month, "begin_day_of_month": begin.day, "begin_year": run_year,
                "end_month": end.month, "end_day_of_month": end.day, "end_year": end.year,
                "use_weather_file_holidays_and_special_days": "No",
                "use_weather_file_daylight_saving_period": "No",
                "apply_weekend_holiday_rule": "No",
                "use_weather_file_rain_indicators": "Yes",
                "use_weather_file_snow_indicators": "Yes",
            }
        }
        self._tmp = Path(tempfile.mkdtemp(prefix="pinn-mpc-eplus-"))
        path = self._tmp / "model.epJSON"
        path.write_text(json.dumps(model), encoding="utf-8")
        self._end_s = (start_day + days - 1) * SECONDS_PER_DAY
        self.api = api = EnergyPlusAPI()
        self._state = state = api.state_manager.new_state()
        api.runtime.set_console_output_status(state, False)
        self._handles: dict[str, Any] | None = None
        self._u: Any = self._off()
        self._last_t_r: float | None = None
        self._acc = self._new_acc()
        self._stopping = False
        self._done = False
        self._error: BaseException | None = None
        self._act_q: queue.Queue[Any] = queue.Queue(maxsize=1)
        self._obs_q: queue.Queue[tuple[str, Any]] = queue.Queue()
        for name, key in self._variables():
            api.exchange.request_variable(state, name, key)
        n_before = len(ep_runtime.all_callbacks)
        api.runtime.callback_begin_zone_timestep_after_init_heat_balance(state, self._on_begin)
        api.runtime.callback_end_zone_timestep_after_zone_reporting(state, self._on_end)
        self._callbacks = ep_runtime.all_callbacks[n_before:]
        args = ["-d", str(self._tmp), "-w", str(self.epw), str(path)]
        self._thread = threading.Thread(target=self._run, args=(args,), name="energyplus", daemon=True)
        self._thread.start()
        return self._receive_or_close()

    def step(self, u_w: Any) -> IntervalMeans:
        """Hold heater power ``u_w`` [W] (clipped to the actuator's bounds) for one control interval."""
        if self._done or self._thread is None:
            raise InternalError("EnergyPlusRun.step: no run in progress (start one, or the run has ended)")
        self._act_q.put(self._clipped(u_w), timeout=self.timeout_s)
        result = self._receive_or_close()
        assert isinstance(result, IntervalMeans)
        return result

    @property
    def running(self) -> bool:
        return self._thread is not None

    def close(self) -> None:
        """Stop a run in progress (EnergyPlus stops at its next zone timestep), wait for its
        thread, free its state and remove its temporary directory."""
        thread, self._thread = self._thread, None
        try:
            if thread is not None:
                if thread.is_alive():
                    self._stopping = True
                    try:
                        self._act_q.put_nowait(_STOP)
                    except queue.Full:
                        pass
                thread.join(timeout=self.timeout_s)
                if thread.is_alive():
                    raise RuntimeError(f"EnergyPlus did not stop within {self.timeout_s:g} s")
        finally:
            self._done = True
            if self._state is not None and (thread is None or not thread.is_alive()):
                from pyenergyplus import runtime as ep_runtime

                self.api.state_manager.delete_state(self._state)
                self._state = None
                for cb in self._callbacks:
                    if cb in ep_runtime.all_callbacks:
                        ep_runtime.all_callbacks.remove(cb)
                self._callbacks = []
            if self._tmp is not None:
                shutil.rmtree(self._tmp, ignore_errors=True)
                self._tmp = None

    def __enter__(self) -> EnergyPlusRun:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _receive_or_close(self) -> Any:
        """:meth:`_receive`; on any error or interrupt the run is closed first."""
        try:
            return self._receive()
        except BaseException:
            self.close()
            raise

    def _receive(self) -> Any:
        try:
            kind, payload = self._obs_q.get(timeout=self.timeout_s)
        except queue.Empty:
            raise RuntimeError(
                f"EnergyPlus sent nothing for {self.timeout_s:g} s; the run was stopped"
            ) from None
        if kind == "error":
            self._done = True
            raise payload
        if kind == "done":
            self._done = True
            raise InternalError("EnergyPlusRun.step: the run has ended (start a longer one)")
        return payload

    # ---- the EnergyPlus thread ----------------------------------------------------------

    _GAIN_VARIABLES = (
        "Zone Total Internal Convective Heating Rate",
        "Zone Total Internal Radiant Heating Rate",
        "Zone Total Internal Visible Radiation Heating Rate",
    )

    def _variables(self) -> list[tuple[str, str]]:
        env = "Environment"
        variables = [
            ("Site Outdoor Air Drybulb Temperature", env),
            ("Site Direct Solar Radiation Rate per Area", env),
            ("Site Diffuse Solar Radiation Rate per Area", env),
            ("Site Solar Altitude Angle", env),
        ]
        for zone, heater in zip(self.prepared.zones, self.prepared.heaters, strict=True):
            variables += [("Zone Mean Air Temperature", zone)]
            variables += [(name, zone) for name in self._GAIN_VARIABLES]
            variables += [("Other Equipment Total Heating Rate", heater)]
        return variables

    def _run(self, args: list[str]) -> None:
        rc: int | None = None
        try:
            rc = self.api.runtime.run_energyplus(self._state, args)
        except BaseException as exc:  # reported to the caller
            self._error = self._error or exc
        if self._stopping and self._error is None:
            return
        if self._error is not None:
            self._obs_q.put(("error", self._error))
        elif rc != 0 or self._handles is None:
            first = first_severe(Path(args[1]) / "eplusout.err")
            self._obs_q.put((
                "error",
                InputError(
                    f"EnergyPlus could not run {self.prepared.source}: "
                    f"{first or f'it returned {rc} without a severe message'}"
                ),
            ))
        else:
            self._obs_q.put(("done", None))

    def _equipment(self) -> tuple[str, ...]:
        """The ``OtherEquipment`` objects whose power the run sets: the heaters."""
        return self.prepared.heaters

    def _get_handles(self, state: Any) -> dict[str, Any]:
        ex = self.api.exchange
        var = {(n, k): ex.get_variable_handle(state, n, k) for n, k in self._variables()}
        act = [ex.get_actuator_handle(state, "OtherEquipment", "Power Level", h) for h in self._equipment()]
        missing = [f"{n} of {k}" for (n, k), v in var.items() if v < 0]
        missing += [f"actuator of {h}" for h, a in zip(self._equipment(), act, strict=True) if a < 0]
        if missing:
            raise RuntimeError(f"EnergyPlus has no handle for {missing}")
        return {"var": var, "act": act}

    def _read(self, state: Any) -> dict[str, Any]:
        assert self._handles is not None
        ex, var, prepared = self.api.exchange, self._handles["var"], self.prepared

        def g(name: str, key: str = "Environment") -> float:
            return float(ex.get_variable_value(state, var[(name, key)]))

        alt = g("Site Solar Altitude Angle")
        ghi = g("Site Direct Solar Radiation Rate per Area") * max(0.0, math.sin(math.radians(alt))) + g(
            "Site Diffuse Solar Radiation Rate per Area"
        )
        # Per zone instance; a zone multiplier repeats both the heat and the gains.
        mult = prepared.multipliers
        heat = sum(m * g("Other Equipment Total Heating Rate", h) for h, m in zip(prepared.heaters, mult, strict=True))
        gains = sum(
            m * sum(g(n, zone) for n in self._GAIN_VARIABLES) for zone, m in zip(prepared.zones, mult, strict=True)
        )
        t_r = sum(w * g("Zone Mean Air Temperature", z) for z, w in zip(prepared.zones, prepared.weights, strict=True))
        return {
            "T_r": t_r,
            "T_a": g("Site Outdoor Air Drybulb Temperature"),
            "G": ghi,
            "u_phys": heat / self.heat_per_w,
            "I_g": gains - heat,
        }

    def _seconds(self, state: Any) -> int:
        """Seconds from 1 January 00:00 of the run's first year to the start of this zone
        timestep (from the day, the hour and the zone timestep's number, not the system
        timestep's clock; a day of the year before the run's first is in the next year)."""
        ex = self.api.exchange
        step_s = 3600 // self.prepared.timesteps_per_hour
        n = ex.zone_time_step_number(state) - 1
        day = ex.day_of_year(state)
        if day < self._start_day:
            day += 365
        return int((day - 1) * SECONDS_PER_DAY + ex.hour(state) * 3600 + n * step_s)

    def _new_acc(self) -> dict[str, Any]:
        return {"n": 0, "T_a": 0.0, "G": 0.0, "u_phys": 0.0, "I_g": 0.0, "T_r": [], "overridden": False}

    def _accumulate(self, r: dict[str, Any]) -> None:
        """Add one zone timestep's reading (:meth:`_read`) to the interval."""
        acc = self._acc
        acc["n"] += 1
        for key in ("T_a", "G", "u_phys", "I_g"):
            acc[key] += r[key]
        acc["T_r"].append(r["T_r"])

    def _observed(self, r: dict[str, Any]) -> None:
        """Keep what the next zone timestep's control acts on (the room at this one's end)."""
        self._last_t_r = r["T_r"]

    def _first(self) -> Any:
        """The room temperature handed over when the run starts."""
        return float(self._last_t_r)  # type: ignore[arg-type]

    # ---- the one actuator's control (a run of several overrides these) -----------------

    def _off(self) -> Any:
        """The power before any is asked: the actuator's lower bound."""
        return self.actuator.lower_w

    def _clipped(self, u_w: Any) -> Any:
        """The power asked within the actuator's bounds."""
        return float(self.actuator.clip(float(u_w)))

    def _demand(self, msg: Any) -> Any:
        """The power the controller's message asks for."""
        return float(msg)

    def _warm_up(self, state: Any) -> None:
        """A warm-up zone timestep: integral control to the warm-up setpoint."""
        gain = 0.1 * self.actuator.span_w if self.hold_c is None else self.hold_gain_w_per_k
        self._integral_control(self.warmup_setpoint_c, gain)
        self._set_heater(state, self._u)

    def _hold(self, state: Any) -> None:
        """The holding thermostat's zone timestep (``hold_c``)."""
        assert self.hold_c is not None
        self._integral_control(self.hold_c, self.hold_gain_w_per_k)

    def _switch_off(self, state: Any) -> None:
        """Nothing heats any more (the run is stopping)."""
        self._set_heater(state, 0.0)

    def _apply(self, state: Any) -> None:
        """Set the power asked (``self._u``) for this zone timestep, the backup thermostat's
        override (full power below ``backup_c[0]``, off above ``backup_c[1]``, mirrored for a
        chiller) applied on the room at the last one's end."""
        u = self._u
        if self.backup_c is not None and self._last_t_r is not None:
            low, high = self.backup_c
            force_on, force_off = (
                (self._last_t_r < low, self._last_t_r > high)
                if self.heat_per_w > 0
                else (self._last_t_r > high, self._last_t_r < low)
            )
            if force_on:
                u = self.actuator.upper_w
            elif force_off:
                u = self.actuator.lower_w
            if u != self._u:
                self._acc["overridden"] = True
        self._set_heater(state, u)

    def _means(self) -> IntervalMeans:
        acc, n = self._acc, max(self._acc["n"], 1)
        self._acc = self._new_acc()
        return IntervalMeans(
            t_r_c=float(acc["T_r"][-1]),
            t_r_sub_c=np.asarray(acc["T_r"], dtype=float),
            u_phys_w=acc["u_phys"] / n,
            t_a_c=acc["T_a"] / n,
            g_w_per_m2=acc["G"] / n,
            i_g_w=acc["I_g"] / n,
            overridden=bool(acc["overridden"]),
        )

    def _set_heater(self, state: Any, u: float) -> None:
        """Power ``u`` [W] to the building: its heat split over the zones by floor area."""
        assert self._handles is not None
        prepared, heat = self.prepared, u * self.heat_per_w
        for act, w, m in zip(self._handles["act"], prepared.weights, prepared.multipliers, strict=True):
            self.api.exchange.set_actuator_value(state, act, heat * w / m)

    def _integral_control(self, setpoint_c: float, gain_w_per_k: float) -> None:
        """The warm-up's thermostat: the power moves by ``gain_w_per_k`` per K of error per
        zone timestep (towards more power below the setpoint for a heater, above for a chiller)."""
        if self._last_t_r is not None:
            error = setpoint_c - self._last_t_r if self.heat_per_w > 0 else self._last_t_r - setpoint_c
            u = self._u + gain_w_per_k * error
            self._u = float(self.actuator.clip(u))

    def _on_begin(self, state: Any) -> None:
        """Begin of a zone timestep: set the heater; at an interval boundary hand over and
        wait for the next power."""
        try:
            if self._stopping or self._error is not None:
                return
            ex = self.api.exchange
            if self._handles is None:
                if not ex.api_data_fully_ready(state):
                    return
                self._handles = self._get_handles(state)
            if ex.warmup_flag(state):  # integral control to the warm-up setpoint
                self._warm_up(state)
                return
            if self._seconds(state) % self.dt_s == 0:
                if self._last_t_r is None:
                    self._observed(self._read(state))
                first = self._first()
                self._obs_q.put(("obs", first if self._acc["n"] == 0 else self._means()))
                try:
                    msg = self._act_q.get(timeout=self.timeout_s)
                except queue.Empty:
                    msg = _STOP
                if msg is _STOP:
                    self._stopping = True
                    self._switch_off(state)
                    self.api.runtime.stop_simulation(state)
                    return
                if self.hold_c is None:
                    self._u = self._demand(msg)
            if self.hold_c is not None:
                self._hold(state)
            self._apply(state)
        except BaseException as exc:  # a callback must not raise into EnergyPlus
            self._fail(state, exc)

    def _on_end(self, state: Any) -> None:
        """End of a zone timestep: read the zone and the weather, add them to the interval."""
        try:
            if self._handles is None or self._stopping or self._error is not None:
                return
            r = self._read(state)
            self._observed(r)
            if self.api.exchange.warmup_flag(state):
                return
            self._accumulate(r)
            if self._seconds(state) + 3600 // self.prepared.timesteps_per_hour >= self._end_s:
                self._obs_q.put(("obs", self._means()))
        except BaseException as exc:  # a callback must not raise into EnergyPlus
            self._fail(state, exc)

    def _fail(self, state: Any, exc: BaseException) -> None:
        self._error = exc
        self._stopping = True
        self.api.runtime.stop_simulation(state)
        self._obs_q.put(("error", exc))



def unlimited_power_w(prepared: PreparedModel, heat_per_w: float) -> float:
    """A power no building of this floor area needs (1 kW/m2 of heat): a thermostat with it
    holds its setpoint unconstrained."""
    return 1000.0 * prepared.floor_m2 / abs(heat_per_w)


def held_run(
    prepared: PreparedModel, weather: str, setpoint_c: float, heat_per_w: float, dt_s: float,
    start_day: int, days: int, year: int | None,
) -> list[IntervalMeans]:
    """Every interval of a run whose room an ideal thermostat holds at ``setpoint_c``."""
    with EnergyPlusRun(
        prepared, weather=weather, dt_s=dt_s,
        actuator=ActuatorSpec(upper_w=unlimited_power_w(prepared, heat_per_w), heats=heat_per_w > 0),
        heat_per_w=heat_per_w, warmup_setpoint_c=setpoint_c, hold_c=setpoint_c,
    ) as run:
        run.start(start_day, days, year=year)
        return [run.step(0.0) for _ in range(days * SECONDS_PER_DAY // int(dt_s))]

