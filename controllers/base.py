"""What every controller shares: observation, forecast, control spec, protocol, fallback.

Names follow the data format (``T_a``, ``G``, ``I_g``, ``price``, ``T_min``, ``T_max``, ``u``,
``u_phys``, ``time_of_day_h``) in the history, the last interval and the forecast alike, so a
model's exogenous input name is also the forecast's field and the last interval's field.
The objective every controller optimises is in :mod:`controllers.objective`.
"""

from __future__ import annotations

import contextlib
import math
import signal
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple, Protocol, runtime_checkable

import numpy as np

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.data import SITE_COLUMNS
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.zones import ONE_ZONE, ZoneSpec, zone_columns

if TYPE_CHECKING:
    from pinn_mpc.models.rollout import BatchDynamics
    from pinn_mpc.records import TrustReport

__all__ = [
    "EXOGENOUS_NAMES",
    "Controller",
    "ControlSpec",
    "Fallback",
    "Forecast",
    "LastInterval",
    "Observation",
    "PlanningController",
    "SolveStats",
    "fallback_power",
    "fallback_powers",
    "current_band_c",
    "first_values",
    "raise_if_interrupted",
    "solver_interrupts_held",
]

#: Exogenous inputs a model may take, in the data format's names (fields of Forecast and
#: LastInterval alike); the facades' irradiance and the wind speed
#: (:data:`pinn_mpc.data.SITE_COLUMNS`) only where the run has them (an EnergyPlus building's
#: weather file).
EXOGENOUS_NAMES = ("time_of_day_h", "T_a", "G", "I_g", "day_of_week", *SITE_COLUMNS)


class Forecast(NamedTuple):
    """Inputs for the next H control intervals, each an array (H,), named as in the data format."""

    time_of_day_h: np.ndarray  # start of each interval, hours since midnight
    T_a: np.ndarray  # outdoor temperature [C]
    G: np.ndarray  # global horizontal irradiance [W/m2]
    I_g: np.ndarray  # internal gains [W]
    price: np.ndarray  # [EUR/kWh]
    T_min: np.ndarray  # comfort band, lower [C]: (H,) for every zone, or (H, Z) each zone's
    T_max: np.ndarray  # comfort band, upper [C], as T_min
    # day of the week of each interval's start, 0 = Monday (NaN where the dates are unknown)
    day_of_week: np.ndarray | None = None
    # irradiance on the site's vertical south, east, west and north facades [W/m2], where the
    # run has it (pinn_mpc.solar)
    G_south: np.ndarray | None = None
    G_east: np.ndarray | None = None
    G_west: np.ndarray | None = None
    G_north: np.ndarray | None = None
    # wind speed at the weather station [m/s], where the run has it (the weather file's)
    wind: np.ndarray | None = None

    @property
    def horizon(self) -> int:
        return len(self.T_a)

    def exogenous(self, names: tuple[str, ...], h: int) -> dict[str, np.ndarray]:
        """Fresh arrays (h,) of the named series (names of :data:`EXOGENOUS_NAMES`)."""
        fields = self._asdict()
        if "day_of_week" in names and self.day_of_week is None:
            raise InputError("the forecast has no calendar (day_of_week) that the model needs")
        missing = [name for name in names if name in SITE_COLUMNS and fields[name] is None]
        if missing:
            raise InputError(
                f"the forecast has no facade irradiance or wind ({', '.join(missing)}) that the "
                "model needs: a model trained on an EnergyPlus building's data plans on its "
                "scenario"
            )
        return {name: np.array(fields[name][:h]) for name in names}


class LastInterval(NamedTuple):
    """The control interval that just ended: its inputs [data-format names and units]."""

    time_of_day_h: float  # its start
    T_a: float
    G: float
    I_g: float
    u: float  # demanded power [W]
    u_phys: float  # delivered power [W]
    day_of_week: float = math.nan  # of its start, 0 = Monday (NaN when the dates are unknown)
    # the facades' irradiance [W/m2] (NaN where the run has none)
    G_south: float = math.nan
    G_east: float = math.nan
    G_west: float = math.nan
    G_north: float = math.nan
    wind: float = math.nan  # wind speed [m/s] (NaN where the run has none)


class Observation(NamedTuple):
    """What a controller sees at the start of interval k, of a building with the zones ``zones``
    (:mod:`pinn_mpc.zones`; one today).

    ``history`` holds the past in the data format's names: ``T_r`` (k+1,) measured room
    temperatures up to and including now (each zone's ``T_r[<zone>]`` in a building of several
    zones: :meth:`t_r_zones_c` reads them); ``u`` and ``u_phys`` (k,) demanded and delivered power
    of past intervals [W]; ``T_a``, ``G``, ``I_g``, ``time_of_day_h`` (k+1,) up to now, and
    ``day_of_week`` (k+1,, 0 = Monday) where the run has dates, and the facades' irradiance and
    the wind speed (:data:`pinn_mpc.data.SITE_COLUMNS`, (k+1,)) where the run has them.
    A building of several actuators (:attr:`ControlSpec.actuators`) also has each one's
    ``u[<name>]`` and ``u_phys[<name>]`` (k,) (:func:`pinn_mpc.actuator.actuator_columns`);
    ``u`` and ``u_phys`` are then the building's totals, on which the price is paid.
    ``last`` is the interval that just ended (None at the first step), so nobody reads it back
    out of ``history`` by index. ``t_m_true_c`` is the simulator's hidden thermal-mass
    temperature: only the true-state estimator (oracle) may use it. ``t_r_c`` and
    ``t_m_true_c`` are the one zone's; NaN in a building of several zones, whose zones
    :meth:`t_r_zones_c` gives.
    """

    k: int
    t_r_c: float
    history: dict[str, np.ndarray]
    t_m_true_c: float
    last: LastInterval | None = None
    zones: tuple[ZoneSpec, ...] = ONE_ZONE
    #: (Z,) each zone's hidden thermal-mass temperature [C] (the true-state estimator's only;
    #: NaN where unknown), None where the observation was made without it.
    t_m_true_zones_c: np.ndarray | None = None

    @classmethod
    def from_history(
        cls,
        k: int,
        history: dict[str, np.ndarray],
        t_m_true_c: float | np.ndarray = math.nan,
        *,
        zones: tuple[ZoneSpec, ...] = ONE_ZONE,
    ) -> Observation:
        """The observation of step k from a history as in the class docstring, of a building
        with ``zones`` (``t_m_true_c`` one value per zone, or one for all); ``last`` is read
        from it (``G``, ``I_g`` missing count as 0)."""
        columns = zone_columns("T_r", zones)
        t_r = np.asarray(history[columns[0]], dtype=float)
        t_m = np.broadcast_to(np.asarray(t_m_true_c, dtype=float), (len(zones),))
        one = len(zones) == 1
        last = None
        u_phys = np.asarray(history.get("u_phys", np.zeros(0)), dtype=float)
        if len(u_phys) >= 1 and len(t_r) >= 2:

            def before_now(name: str) -> float:  # value at the start of the last interval
                values = history.get(name)
                return 0.0 if values is None else float(values[-2])

            u = np.asarray(history.get("u", u_phys), dtype=float)  # one power column: u = u_phys
            last = LastInterval(
                time_of_day_h=before_now("time_of_day_h"),
                T_a=before_now("T_a"),
                G=before_now("G"),
                I_g=before_now("I_g"),
                u=float(u[-1]),
                u_phys=float(u_phys[-1]),
                day_of_week=before_now("day_of_week") if "day_of_week" in history else math.nan,
                **{name: before_now(name) for name in SITE_COLUMNS if name in history},
            )
        return cls(
            k=k, t_r_c=float(t_r[-1]) if one else math.nan, history=history,
            t_m_true_c=float(t_m[0]) if one else math.nan, last=last, zones=zones,
            t_m_true_zones_c=np.array(t_m),
        )

    def t_r_zones_c(self) -> np.ndarray:
        """(Z,) each zone's measured room temperature now [C], in the building's zones' order."""
        return np.array([self.history[c][-1] for c in zone_columns("T_r", self.zones)], dtype=float)


class SolveStats(NamedTuple):
    time_s: float
    status: str
    iterations: int
    fallback: bool


@dataclass(frozen=True, kw_only=True)
class ControlSpec:
    """Actuator and objective settings shared by all controllers of a run.

    ``actuators`` are the actuators the controllers set (:class:`pinn_mpc.actuator.ActuatorSpec`:
    each one's bounds, whether it heats or cools, its zone and its efficiency, such as a heat
    pump's COP curve, which an RC MPC plans with; named where there are several); a one-zone
    building has one, :attr:`actuator`. ``zones`` are the building's zones (:mod:`pinn_mpc.zones`;
    an actuator's ``zone`` is an index into them): the plant's (the closed loop checks it). The
    learned-model planners plan one zone with one actuator (:attr:`single`); the multi-zone
    controllers (the RC MPC over zones and actuators, the thermostat) any. Every power a controller decides is
    electrical and every bound of it is the actuator's. ``sensor_noise_std_c`` is the room sensor's noise as its data sheet
    states it (the Kalman observers take it as their measurement noise; 0 keeps their default)."""

    actuators: tuple[ActuatorSpec, ...]
    zones: tuple[ZoneSpec, ...] = ONE_ZONE
    dt_s: float = 1800.0
    horizon_steps: int = 48
    comfort_weight_eur_per_kh: float = 1.0
    sensor_noise_std_c: float = 0.0

    def __post_init__(self) -> None:
        if not (isinstance(self.actuators, tuple) and all(isinstance(a, ActuatorSpec) for a in self.actuators)):
            raise TypeError(f"ControlSpec.actuators must be a tuple of ActuatorSpec, got {self.actuators!r}")
        if not (isinstance(self.zones, tuple) and self.zones and all(isinstance(z, ZoneSpec) for z in self.zones)):
            raise TypeError(f"ControlSpec.zones must be a non-empty tuple of ZoneSpec, got {self.zones!r}")
        if not self.actuators:
            raise ValueError("ControlSpec.actuators: a building has at least one actuator, got none")
        outside = [a.zone for a in self.actuators if not 0 <= a.zone < len(self.zones)]
        if outside:
            raise ValueError(
                f"ControlSpec.actuators: zone index(es) {outside} outside the building's "
                f"{len(self.zones)} zone(s); an actuator's zone is an index into ControlSpec.zones"
            )
        names = [a.name for a in self.actuators]
        if len(self.actuators) > 1 and ("" in names or len(set(names)) != len(names)):
            raise ValueError(
                f"ControlSpec.actuators: a building of several actuators names each one, uniquely "
                f"(its data columns u[<name>]), got names {names}"
            )
        if self.horizon_steps < 1:
            raise ValueError(f"ControlSpec.horizon_steps must be >= 1, got {self.horizon_steps}")
        if not (math.isfinite(self.sensor_noise_std_c) and self.sensor_noise_std_c >= 0):
            raise ValueError(
                f"ControlSpec.sensor_noise_std_c must be finite and >= 0, got {self.sensor_noise_std_c!r}"
            )
        if not (self.comfort_weight_eur_per_kh >= 0):
            raise ValueError(
                f"ControlSpec.comfort_weight_eur_per_kh must be >= 0, got {self.comfort_weight_eur_per_kh}"
            )

    @property
    def n_actuators(self) -> int:
        """A, the number of actuators the controllers set."""
        return len(self.actuators)

    @property
    def single(self) -> bool:
        """Whether the building is one zone with one actuator: what every controller plans
        (the multi-zone controllers plan any)."""
        return len(self.actuators) == 1 and len(self.zones) == 1

    @property
    def actuator(self) -> ActuatorSpec:
        """The one actuator the controllers set (``actuators[0]``); a building of several has
        no one actuator (ValueError: a controller of one actuator was given it)."""
        if len(self.actuators) != 1:
            raise ValueError(
                f"ControlSpec.actuator: this building has {len(self.actuators)} actuators "
                f"({', '.join(a.name for a in self.actuators)}); a controller of one actuator "
                "cannot plan it (choose a multi-zone controller)"
            )
        return self.actuators[0]

    @property
    def u_max_w(self) -> float:
        """The one actuator's upper bound [W] (``actuator.upper_w``)."""
        return self.actuator.upper_w

    @property
    def heating(self) -> bool:
        """Whether the one actuator heats (``actuator.heats``); False: it cools."""
        return self.actuator.heats

    @property
    def dt_h(self) -> float:
        return self.dt_s / 3600.0


def check_heating(eta: float, spec: ControlSpec, *, what: str) -> None:
    """Every controller given a model or RC parameters checks, at construction, that they heat
    (eta > 0) when the scenario's actuator heats and cool (eta < 0) when it cools."""
    if (eta > 0) == spec.actuator.heats:
        return
    if spec.actuator.heats:
        raise InputError(
            f"{what}: eta={eta:g}, a cooling machine, but the scenario's actuator is a heater; "
            "use a model or RC file made for heating (eta > 0)"
        )
    raise InputError(
        f"{what}: eta={eta:g}, a heater, but the scenario's actuator is a cooling machine; "
        "use a model or RC file made for cooling (trained or identified on cooling data with "
        "eta = -COP, e.g. -2.5)"
    )


def first_values(values: np.ndarray, n: int) -> np.ndarray:
    """A fresh array of the first n values (n,), the last one repeated when there are fewer."""
    a = np.asarray(values, dtype=float).reshape(-1)
    if a.size == 0:
        raise InternalError("forecast array is empty; the controller needs at least one step")
    if a.size >= n:
        return a[:n].copy()
    return np.concatenate([a, np.full(n - a.size, a[-1])])


@runtime_checkable
class Controller(Protocol):
    """``reset`` then ``act`` once per control interval; ``act`` returns demanded electrical
    power [W]: a number for a building's one actuator, (A,) one per actuator of several
    (:attr:`ControlSpec.actuators`' order).

    What the loop asks of it besides: ``knows_true_state`` (its decisions start from the
    plant's true state, as the oracle's and the clairvoyant's do: it needs a plant with one,
    and gets perfect forecasts), ``model`` (the learned or ARX model it plans over, None for
    none) and ``trust_report`` (how often it did not trust that model, None for a controller
    without one)."""

    name: str

    def reset(self, seed: int | None = None) -> None: ...

    def act(self, obs: Observation, forecast: Forecast) -> float | np.ndarray: ...

    @property
    def last_plan(self) -> np.ndarray | None: ...

    @property
    def last_stats(self) -> SolveStats: ...

    @property
    def knows_true_state(self) -> bool: ...

    @property
    def model(self) -> BatchDynamics | None: ...

    @property
    def trust_report(self) -> TrustReport | None: ...


def fallback_power(obs: Observation, forecast: Forecast, spec: ControlSpec) -> float:
    """The documented safe action when a solver fails or a model output is not finite.

    A band-keeping rule on the measured room temperature: the actuator's full power when the
    room is in the lower (heating) or upper (cooling) quarter of the band or beyond it,
    otherwise off (its lower bound). Without a band (an empty forecast) it is off: the backup
    thermostat still guards the room.
    """
    actuator = spec.actuator
    if len(forecast.T_min) == 0 or len(forecast.T_max) == 0:
        return actuator.lower_w
    return _band_rule(actuator, obs.t_r_c, float(forecast.T_min[0]), float(forecast.T_max[0]))


def _band_rule(actuator: ActuatorSpec, t_r_c: float, t_min_c: float, t_max_c: float) -> float:
    """The fallback's rule for one actuator on its zone's room temperature and band: full power
    in the band's lower (a heater) or upper (a cooler) quarter or beyond it, else off."""
    quarter = 0.25 * (t_max_c - t_min_c)
    if actuator.heats:
        return actuator.on_off(t_r_c < t_min_c + quarter)
    return actuator.on_off(t_r_c > t_max_c - quarter)


def fallback_powers(obs: Observation, forecast: Forecast, spec: ControlSpec) -> np.ndarray:
    """(A,) :func:`fallback_power`'s rule for each actuator of a building (of any number of
    zones and actuators): a heater at full power when its zone's measured room temperature is
    in the lower quarter of the zone's band or below it, a cooler in the upper quarter or
    above, each otherwise off (its lower bound). Without a band every actuator is off."""
    if spec.single:
        return np.array([fallback_power(obs, forecast, spec)])
    if len(forecast.T_min) == 0 or len(forecast.T_max) == 0:
        return np.array([a.lower_w for a in spec.actuators], dtype=float)
    t_r = obs.t_r_zones_c()
    t_min, t_max = current_band_c(forecast, len(spec.zones))
    return np.array([
        _band_rule(a, float(t_r[a.zone]), float(t_min[a.zone]), float(t_max[a.zone])) for a in spec.actuators
    ])


def current_band_c(forecast: Forecast, n_zones: int) -> tuple[np.ndarray, np.ndarray]:
    """(T_min (Z,), T_max (Z,)) each zone's comfort band of the forecast's first interval [C]
    (the forecast's band is (H,) for every zone or (H, Z) each zone's)."""
    low, high = (np.broadcast_to(np.asarray(b, dtype=float)[0], (n_zones,)) for b in (forecast.T_min, forecast.T_max))
    return low, high


#: The statuses of a solver that caught a Ctrl-C itself (OSQP; IPOPT through CasADi), lower case.
INTERRUPTED_STATUSES = frozenset({"interrupted", "user_requested_stop", "user requested stop"})


@contextlib.contextmanager
def solver_interrupts_held() -> Iterator[None]:
    """Within: Ctrl-C (SIGINT) is held back from this thread and the threads it starts, and
    raised as :class:`KeyboardInterrupt` when the block ends.

    Solvers written in C (OSQP, IPOPT) install their own SIGINT handler while they solve: a
    Ctrl-C then stops the solve with a status such as ``interrupted`` (which a controller
    would take for a failure and count as a fallback) or is lost (it arrived after the
    solver's last check), and Python never sees it. Held back, the signal waits until the
    solver has restored Python's handler, which then raises. Solves take milliseconds, so the
    interrupt is not noticeably late. Solvers running in several threads at once can leave
    their own handler installed (each restores the handler it found, which may be another's),
    so in the main thread Python's handler is installed again before the signal is let
    through.
    """
    if not hasattr(signal, "pthread_sigmask"):  # no POSIX signal masks (Windows)
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        handler = signal.getsignal(signal.SIGINT)
        if handler is not None and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def raise_if_interrupted(status: str) -> None:
    """Raise :class:`KeyboardInterrupt` when a solver's ``status`` says it caught a Ctrl-C
    (one that reached it although :func:`solver_interrupts_held` holds them back, e.g. sent
    to another thread): an interruption ends the run, it is never a solver failure."""
    if status.strip().lower() in INTERRUPTED_STATUSES:
        raise KeyboardInterrupt(f"the solver was interrupted (status {status!r})")


class Fallback:
    """The one fallback path of every controller, and the plan it falls back on.

    A controller hands each successful plan to :meth:`planned`; when a decision fails it calls
    :meth:`act`, which returns the previous plan shifted by the steps since it was made (when
    ``reuse_plan`` and the plan is not exhausted), else :func:`fallback_power`, and counts the
    event in ``n_events``. Without ``reuse_plan`` a failure also forgets the plan (a sampling
    controller then warm-starts from scratch).
    """

    def __init__(self, spec: ControlSpec, *, reuse_plan: bool) -> None:
        self.spec, self.reuse_plan = spec, reuse_plan
        self.reset()

    def reset(self) -> None:
        self.plan_w: np.ndarray | None = None
        self.n_events = 0
        self._age = 0

    def planned(self, plan_w: np.ndarray) -> None:
        self.plan_w, self._age = plan_w, 0

    def act(self, obs: Observation, forecast: Forecast) -> float:
        self.n_events += 1
        if self.reuse_plan and self.plan_w is not None and self._age + 1 < len(self.plan_w):
            self._age += 1
            return float(self.plan_w[self._age])
        self.plan_w = None
        return fallback_power(obs, forecast, self.spec)


class PlanningController:
    """What a planning controller shares: its plan is the one its :class:`Fallback` keeps, its
    stats those of the last decision. Subclasses set ``fallback``, ``_stats`` and ``model``."""

    name = "planning"
    fallback: Fallback
    _stats: SolveStats
    @property
    def knows_true_state(self) -> bool:
        """Whether its decisions start from the plant's true state (:class:`Controller`)."""
        return False

    @property
    def trust_report(self) -> TrustReport | None:
        """How often it did not trust its model (:class:`Controller`); None: it has none."""
        return None

    @property
    def last_plan(self) -> np.ndarray | None:
        """(H,) planned power [W] of the last successful decision; None before or after a
        fallback that had no plan left."""
        plan = self.fallback.plan_w
        return None if plan is None else plan.copy()

    @property
    def last_stats(self) -> SolveStats:
        return self._stats

    @property
    def n_fallbacks(self) -> int:
        """Fallback events since ``reset``."""
        return self.fallback.n_events

    def _failed(
        self, obs: Observation, forecast: Forecast, start_s: float, status: str, iterations: int
    ) -> float:
        """The action after a failed decision that began at ``start_s`` (``perf_counter``):
        the fallback's, recorded in the stats with ``status``."""
        action = self.fallback.act(obs, forecast)
        self._stats = SolveStats(
            time_s=time.perf_counter() - start_s, status=status, iterations=iterations, fallback=True
        )
        return action

    def _succeeded(self, plan_w: np.ndarray, start_s: float, status: str, iterations: int) -> float:
        """The first action of a plan (H,) [W] that a decision begun at ``start_s`` made; the
        plan is kept for the fallback."""
        self.fallback.planned(plan_w)
        self._stats = SolveStats(
            time_s=time.perf_counter() - start_s, status=status, iterations=iterations, fallback=False
        )
        return float(plan_w[0])
