"""The one closed loop: plant, estimator, controller, in the do-mpc order.

Every closed loop of the package runs on :class:`ClosedLoop` (``closed-loop``, ``compare``,
``reproduce``, the Gymnasium env :class:`scenarios.running.gym_env.BuildingEnv`, the tests and the
benchmarks). Each control interval k::

    obs = loop.observation()           # the plant's measurement (sensor noise) and the past
    fc = loop.forecast()               # the exogenous inputs from k on (perfect or noisy)
    u = controller.act(obs, fc)        # the controller's estimator turns obs into a state
                                       # estimate, then it decides (timed; failure -> fallback)
    loop.step(u)                       # the plant advances one interval

:meth:`ClosedLoop.advance` does the four in one call. The observation carries the last
interval's demanded and delivered power and exogenous inputs (``Observation.last``) in the data
format's names, which the forecast shares.

The plant is a :class:`~scenarios.plants.base.LoopPlant` of the scenario's kind
(``plant_settings``, :func:`scenarios.plants.kinds.make_plant`):
:class:`~scenarios.plants.rc.RCPlant` (the minute-level 2R2C or 3R3C simulator with the
backup thermostat, driven by the exogenous series) for every RC scenario, or
:class:`~scenarios.plants.energyplus.plant.EnergyPlusPlant` for an EnergyPlus building, which
has its own weather and internal gains: the past a controller observes holds the interval means the plant
reports, the series only the inputs still to come. An EnergyPlus plant holds a thread and a
temporary directory: close the loop (:meth:`ClosedLoop.close`, or use it as a context manager).

A loop built with ``fleet`` (one :class:`~pinn_mpc.physics.RCParams` per building, e.g. from
:func:`pinn_mpc.simulator.draw_fleet`, or one :class:`~pinn_mpc.multizone.MultiZoneParams` on a
plant of several zones, :func:`pinn_mpc.multizone.draw_zoned_fleet`) runs many buildings under the same weather, prices and
forecasts: :meth:`ClosedLoop.advance_fleet` lets each building's own controller decide on its
own observation, then advances the whole fleet in one call of the batched simulator.

Forecast errors (:class:`ForecastErrors`) are made in one place, :meth:`ClosedLoop.forecast`:
the outdoor temperature and irradiance a controller sees carry an error that grows with lead
time, drawn afresh at every decision from a generator seeded by (run seed, interval), so every
controller of a run sees the same forecasts. A controller with perfect knowledge (its estimator
is :class:`controllers.estimators.TrueState`: ``oracle``, ``clairvoyant``) sees the truth.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any, NamedTuple, cast

import numpy as np

from controllers.base import Controller, ControlSpec, Forecast, Observation, fallback_powers
from pinn_mpc.actuator import ActuatorSpec, actuator_columns
from pinn_mpc.data import SITE_COLUMNS
from pinn_mpc.errors import InternalError
from pinn_mpc.simulator import SimConfig
from pinn_mpc.solar import FACADE_COLUMNS
from pinn_mpc.zones import ONE_ZONE, ZoneSpec, zone_columns
from scenarios.inputs.series import ExogenousSeries, ForecastErrors, lead_error_paths
from scenarios.plants.base import LoopPlant, PlantStep, TrueStatePlant
from scenarios.plants.kinds import FleetBuildings
from scenarios.plants.rc import rc_plant_settings
from scenarios.plants.settings import PlantSettings, make_plant

__all__ = [
    "ClosedLoop",
    "Decision",
    "FleetStep",
    "LoopRecord",
    "decide",
]

#: Streams of the forecast-error generator, so the errors are independent.
_T_A_STREAM, _G_STREAM, _WIND_STREAM = 0, 1, 2


class Decision(NamedTuple):
    """One interval of :meth:`ClosedLoop.advance`: what the controller saw and did."""

    k: int
    observation: Observation
    forecast: Forecast
    u_w: float  # demanded power applied [W] (a building of several actuators: their total)
    time_s: float  # decision time
    fallback: bool
    error: str | None  # a controller exception (the loop's fallback acted), else None
    plant: PlantStep
    u_act_w: np.ndarray | None = None  # (A,) each actuator's demand [W]; None: one actuator


class FleetStep(NamedTuple):
    """One interval of :meth:`ClosedLoop.advance_fleet`, arrays (B,) over the buildings."""

    k: int
    u_w: np.ndarray  # demanded power applied [W] ((B, A) with several actuators)
    decision_s: np.ndarray  # each controller's decision time [s]
    fallback: np.ndarray  # bool
    errors: tuple[tuple[int, str], ...]  # (building, controller exception) where the loop fell back
    controllers_s: float  # wall time of every building's observe, forecast and decide [s]
    plant_s: float  # wall time of the one batched plant step [s]
    plant: PlantStep


class LoopRecord(NamedTuple):
    """One building's intervals run so far: arrays (K,), a zone's (K, Z) (``t_r_sub_c``
    (K, S, Z)) over the building's ``zones``, an actuator's (K, A) over its ``actuators``;
    T_r and T_m at their start. ``u_w`` and ``u_phys_w`` are the building's total electrical
    power, each actuator's ``u_act_w`` and ``u_phys_act_w``."""

    t_r_c: np.ndarray  # (K, Z) measured
    t_m_c: np.ndarray  # (K, Z) true (hidden)
    u_w: np.ndarray
    u_phys_w: np.ndarray
    overridden: np.ndarray
    fallback: np.ndarray
    decision_s: np.ndarray
    t_r_sub_c: np.ndarray  # (K, S, Z) true room temperature at the end of each substep
    t_a_c: np.ndarray  # the interval means the plant reports
    g_w_per_m2: np.ndarray
    i_g_w: np.ndarray
    zones: tuple[ZoneSpec, ...] = ONE_ZONE
    u_act_w: np.ndarray | None = None  # (K, A) each actuator's demand [W]
    u_phys_act_w: np.ndarray | None = None  # (K, A) each actuator's delivered power [W]
    actuators: tuple[ActuatorSpec, ...] = ()


def decide(
    controller: Controller, obs: Observation, forecast: Forecast, spec: ControlSpec
) -> tuple[float | np.ndarray, float, bool, str | None]:
    """Call ``act`` once, timed: (demand [W] in bounds, decision time [s], fallback used, error).

    The demand is a number for a building's one actuator, (A,) one per actuator of several
    (each within its own bounds). A controller that raises or returns anything else than that
    many finite numbers does not end the run: the loop acts with
    :func:`controllers.base.fallback_powers` and reports the error.
    """
    error = None
    n = spec.n_actuators
    start = time.perf_counter()
    try:
        action = np.asarray(controller.act(obs, forecast), dtype=float).reshape(-1)
        if action.size != n or not np.all(np.isfinite(action)):
            what = "one finite number" if n == 1 else f"{n} finite numbers (one per actuator)"
            error = f"act returned {action!r}, not {what}"
    except Exception as exc:  # a controller failure must not end the run: fall back, count it
        error = f"{type(exc).__name__}: {exc}"
    elapsed = time.perf_counter() - start
    if error is not None:
        safe = fallback_powers(obs, forecast, spec)
        return (float(safe[0]) if n == 1 else safe), elapsed, True, error
    try:
        own_fallback = bool(controller.last_stats.fallback)
    except Exception as exc:
        own_fallback, error = True, f"last_stats: {type(exc).__name__}: {exc}"
    if n == 1:
        return float(spec.actuators[0].clip(float(action[0]))), elapsed, own_fallback, error
    clipped = np.array([a.clip(float(v)) for a, v in zip(spec.actuators, action, strict=True)])
    return clipped, elapsed, own_fallback, error


class ClosedLoop:
    """One simulated building (or a fleet) driven by an exogenous series, stepped one interval
    at a time.

    ``seed`` seeds the plant's sensor noise; ``forecast_seed`` the forecast errors
    (``forecast_errors``, see :class:`ForecastErrors`), which depend only on it and the row.
    ``expected_gains_w`` (N,) is what a controller sees of the gains when they are not known
    (required then). ``measured_gains``: the past gains a controller observes are the plant's
    interval means (an EnergyPlus building's measured gains) instead of the series' rows.
    ``plant_settings`` is the plant's kind and settings (a scenario's ``plant``; None: the RC
    simulator of ``config.plant``), ``plant`` a plant already made. :meth:`reset` starts an
    episode at row ``start`` of the series; ``k`` counts its intervals. ``fleet`` gives B buildings their own parameters (the backup rule
    and the actuator of ``config`` apply to all; see :class:`Simulator`); they share
    the series, the forecasts and the initial state; without a fleet, ``n_buildings`` of
    ``config``'s building do (data generation). Methods that concern one building take
    its index ``building`` (default 0, the only one without a fleet).
    """

    def __init__(
        self,
        config: SimConfig,
        exogenous: ExogenousSeries,
        *,
        spec: ControlSpec,
        initial_t_r_c: float,
        initial_t_m_c: float,
        seed: int | None = 0,
        forecast_errors: ForecastErrors = ForecastErrors(),
        forecast_seed: int | list[int] = 0,
        expected_gains_w: np.ndarray | None = None,
        fleet: FleetBuildings | None = None,
        plant: LoopPlant | None = None,
        plant_settings: PlantSettings | None = None,
        measured_gains: bool = False,
        n_buildings: int = 1,
    ) -> None:
        inputs = exogenous.forecast(0)._replace(day_of_week=None)  # NaN without dates
        if not np.all(np.isfinite(np.column_stack([a for a in inputs if a is not None]))):
            raise ValueError("exogenous series has non-finite values")
        seen_gains_w = exogenous.I_g
        if not forecast_errors.gains_known:
            if expected_gains_w is None or len(expected_gains_w) != len(exogenous):
                raise InternalError(
                    "ClosedLoop: gains_known = false needs expected_gains_w, one value per row"
                )
            seen_gains_w = np.asarray(expected_gains_w, dtype=float)
        self.config, self.exogenous, self.spec = config, exogenous, spec
        self.forecast_errors = forecast_errors
        self._forecast_seed = [forecast_seed] if isinstance(forecast_seed, int) else list(forecast_seed)
        self._seen_gains_w = seen_gains_w
        self.measured_gains = measured_gains
        self.initial_state_c = (float(initial_t_r_c), float(initial_t_m_c))
        if plant_settings is None:  # the RC simulator of config.plant
            plant_settings = rc_plant_settings(config.plant)
        elif plant_settings.rc != config.plant:
            raise ValueError(
                f"ClosedLoop: config.plant {config.plant} is not the simulator's structure of "
                f"plant_settings (kind {plant_settings.kind!r}); give a scenario's sim with its plant"
            )
        self.plant = plant if plant is not None else make_plant(
            config, plant_settings, t_a_c=exogenous.T_a, g_w_per_m2=exogenous.G, i_g_w=exogenous.I_g,
            times=exogenous.times, seed=seed, fleet=fleet, n_buildings=n_buildings,
            facades={n: getattr(exogenous, n) for n in FACADE_COLUMNS} if exogenous.has_facades else None,
        )
        self.n_buildings = self.plant.n_buildings
        self.zones: tuple[ZoneSpec, ...] = self.plant.zones
        if spec.zones != self.zones:
            self.plant.close()
            raise ValueError(
                f"ClosedLoop: the control spec's zones {[z.name for z in spec.zones]} are not the "
                f"plant's {[z.name for z in self.zones]}"
            )
        try:
            self.reset()
        except BaseException:
            self.plant.close()
            raise

    def true_state(self) -> np.ndarray:
        """(B, 2) the plant's true room and mass temperatures now [C] (a plant with a true
        state only: for references that plan on the truth, tests and diagnostics)."""
        if not self.plant.has_true_state:
            raise InternalError("ClosedLoop.true_state: this loop's plant has no true state")
        return cast(TrueStatePlant, self.plant).true_state()

    def close(self) -> None:
        """Free the plant (an EnergyPlus run's thread and temporary directory)."""
        self.plant.close()

    def __enter__(self) -> ClosedLoop:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def reset(
        self,
        t_r_c: float | None = None,
        t_m_c: float | None = None,
        *,
        start: int = 0,
        seed: int | None = None,
    ) -> None:
        """Start an episode at row ``start`` from state (T_r, T_m) [C] (default the initial
        state); ``seed`` reseeds the sensor noise (None keeps the generator running)."""
        if not 0 <= start < len(self.exogenous):
            raise InternalError(f"ClosedLoop.reset: start={start} must lie in [0, {len(self.exogenous) - 1}]")
        t_r = self.initial_state_c[0] if t_r_c is None else t_r_c
        t_m = self.initial_state_c[1] if t_m_c is None else t_m_c
        self.plant.reset(t_r, t_m, start=start, seed=seed)
        self.start, self.k = start, 0
        n, b, z = len(self.exogenous) - start, self.n_buildings, len(self.zones)
        # Interval-major (K, B), a zone's (K, B, Z): one row per interval holds the whole fleet.
        self._t_r = np.zeros((n + 1, b, z))
        self._t_m = np.zeros((n + 1, b, z))
        self._measured_k = -1
        self._u = np.zeros((n, b))  # the building's total electrical power
        self._u_phys = np.zeros((n, b))
        self._u_act = np.zeros((n, b, self.spec.n_actuators))  # each actuator's
        self._u_phys_act = np.zeros((n, b, self.spec.n_actuators))
        self._overridden = np.zeros((n, b), dtype=bool)
        self._fallback = np.zeros((n, b), dtype=bool)
        self._decision_s = np.zeros((n, b))
        self._t_r_sub = np.zeros((n, b, self.plant.n_substeps, z))
        self._means = np.zeros((n, b, 3))  # T_a, G, I_g as the plant had them

    @property
    def steps_left(self) -> int:
        return len(self._u) - self.k

    def _check_building(self, building: int) -> None:
        if not 0 <= building < self.n_buildings:
            raise InternalError(
                f"ClosedLoop: building={building} must lie in [0, {self.n_buildings - 1}]"
            )

    def measure(self, building: int = 0) -> np.ndarray:
        """(Z,) the measured room temperature of each zone of ``building`` now [C] (one sensor
        reading of every zone of every building per interval)."""
        self._check_building(building)
        if self._measured_k != self.k:
            self._t_r[self.k] = self.plant.measure()
            self._t_m[self.k] = self._true_masses() if self.plant.has_true_state else math.nan
            self._measured_k = self.k
        return self._t_r[self.k, building].copy()

    def _true_masses(self) -> np.ndarray:
        """(B, Z) each zone's true thermal-mass temperature now [C]; a one-zone plant that
        gives only ``true_state`` (B, 2) (a plant kind written before the zone axis) is read as
        its one zone."""
        plant = cast(TrueStatePlant, self.plant)
        if hasattr(plant, "true_zone_states"):
            return plant.true_zone_states()[:, 1, :]
        return plant.true_state()[:, 1:2]

    def observed_gains_w(self, building: int = 0) -> np.ndarray:
        """(k,) the internal gains [W] of the intervals run so far as ``building``'s controller
        observed them (:meth:`observation`'s past ``I_g``): the plant's with measured gains,
        else the series' (the expected ones where ``gains_known = false``), not the gains the
        plant had where the controllers are not given them."""
        self._check_building(building)
        k = self.k
        if self.measured_gains:
            return self._means[:k, building, 2].copy()
        return np.array(self._seen_gains_w[self.start : self.start + k], dtype=float)

    def measured(self) -> np.ndarray:
        """(B, Z) every building's measured room temperatures now [C] (:meth:`measure`)."""
        self.measure()
        return self._t_r[self.k].copy()

    def observation(self, *, perfect: bool = False, building: int = 0, at: int | None = None) -> Observation:
        """What ``building``'s controller sees now (or saw at an earlier step ``at``, its
        measurement as it was then): copies of the past (data-format names), the last interval
        and the true T_m (for the true-state estimator only). Unknown gains (``gains_known =
        false``) are the expected ones unless ``perfect``."""
        k = self._step_at(at)
        if k == self.k:
            self.measure(building)
        rows = slice(self.start, self.start + k + 1)
        exo = self.exogenous
        gains = exo.I_g if perfect else self._seen_gains_w
        past_gains = (
            np.append(self._means[:k, building, 2], gains[self.start + k])
            if self.measured_gains
            else np.array(gains[rows])
        )
        # Copies: a controller may keep or change what it is given without touching the run.
        # The past as the plant had it (for the RC plant, the series' rows), the current row
        # from the series.
        history = {
            "T_a": np.append(self._means[:k, building, 0], exo.T_a[self.start + k]),
            "G": np.append(self._means[:k, building, 1], exo.G[self.start + k]),
            "I_g": past_gains,
            "time_of_day_h": np.array(exo.time_of_day_h[rows]),
            "day_of_week": np.array(exo.day_of_week)[rows],
            **{
                column: np.array(self._t_r[: k + 1, building, z])
                for z, column in enumerate(zone_columns("T_r", self.zones))
            },
            "u": np.array(self._u[:k, building]),
            "u_phys": np.array(self._u_phys[:k, building]),
        }
        if self.spec.n_actuators > 1:  # each actuator's too, beside the building's totals
            for series, values in (("u", self._u_act), ("u_phys", self._u_phys_act)):
                for a, column in enumerate(actuator_columns(series, self.spec.actuators)):
                    history[column] = np.array(values[:k, building, a])
        for name in SITE_COLUMNS:  # the weather file's, as the plant had it, where the run has it
            if getattr(exo, name) is not None:
                history[name] = np.array(getattr(exo, name)[rows])
        return Observation.from_history(k, history, self._t_m[k, building], zones=self.zones)

    def forecast(self, *, perfect: bool = False, at: int | None = None) -> Forecast:
        """The exogenous inputs from now (or from an earlier step ``at``) to the end of the
        series, with the errors of :class:`ForecastErrors` unless ``perfect``. The errors depend
        only on the forecast seed and the row, so repeated calls and every controller get the
        same forecast."""
        row = self.start + self._step_at(at)
        forecast = self.exogenous.forecast(row)
        errors = self.forecast_errors
        if perfect or errors.perfect:
            return forecast
        if not errors.gains_known:
            forecast.I_g[:] = self._seen_gains_w[row:]
        n = forecast.horizon
        streams = (
            (_T_A_STREAM, errors.t_a_error_std_c),
            (_G_STREAM, errors.g_error_rel_std),
            (_WIND_STREAM, errors.wind_error_rel_std),
        )
        for stream, std in streams:
            if std == 0:
                continue
            rng = np.random.default_rng([*self._forecast_seed, row, stream])
            e = lead_error_paths(
                rng, n_paths=1, n_leads=n, std_at_24h=std,
                correlation_h=errors.error_correlation_h, dt_s=self.config.dt_s,
            )[0]
            if stream == _T_A_STREAM:
                forecast.T_a[:] += e
                continue
            if stream == _WIND_STREAM:
                if forecast.wind is not None:
                    forecast.wind[:] *= np.maximum(1.0 + e, 0.0)
                continue
            # One error of the sky's brightness: the facades' irradiance shares G's.
            for name in ("G", *FACADE_COLUMNS):
                series = getattr(forecast, name)
                if series is not None:
                    series[:] *= np.maximum(1.0 + e, 0.0)
        return forecast

    def _step_at(self, at: int | None) -> int:
        """The step ``at`` (None: now), which must not lie ahead of now."""
        if at is None:
            return self.k
        if not 0 <= at <= self.k:
            raise InternalError(f"ClosedLoop: step {at} is not in 0 .. {self.k} (steps so far)")
        return at

    def last_means(self, building: int = 0) -> tuple[float, float, float]:
        """``T_a`` [C], ``G`` [W/m2] and ``I_g`` [W] of the interval just stepped, as the plant
        had them (EnergyPlus's own weather and the building's actual internal gains; the
        series' row on the RC plant)."""
        if self.k == 0:
            raise InternalError("ClosedLoop.last_means: no interval has been stepped since reset()")
        t_a, g, i_g = self._means[self.k - 1, building]
        return float(t_a), float(g), float(i_g)

    def step(
        self,
        u_w: float | np.ndarray,
        *,
        decision_s: float | np.ndarray = 0.0,
        fallback: bool | np.ndarray = False,
    ) -> PlantStep:
        """Apply demand ``u_w`` [W] over the current interval (a number, or (B,) one per
        building; with several actuators (A,) for every building or (B, A); likewise
        ``decision_s`` and ``fallback`` (B,)); the plant's step."""
        if self.steps_left <= 0:
            raise InternalError("ClosedLoop.step: the exogenous series is exhausted; call reset()")
        self.measure()
        k, row = self.k, self.start + self.k
        n_act = self.spec.n_actuators
        if n_act == 1:
            stepped = self.plant.step(u_w, row)
            self._u[k] = u_w
            self._u_act[k, :, 0] = u_w
        else:
            given = np.asarray(u_w, dtype=float)
            if given.shape not in ((n_act,), (self.n_buildings, n_act)):
                raise InternalError(
                    f"ClosedLoop.step: a building of {n_act} actuators takes ({n_act},) or "
                    f"({self.n_buildings}, {n_act}) demands, got shape {given.shape}"
                )
            demand = np.broadcast_to(given, (self.n_buildings, n_act))
            stepped = self.plant.step(np.array(demand), row)
            self._u[k] = demand.sum(axis=1)
            self._u_act[k] = demand
        self._means[k] = np.column_stack([stepped.t_a_c, stepped.g_w_per_m2, stepped.i_g_w])
        self._decision_s[k], self._fallback[k] = decision_s, fallback
        self._u_phys[k] = stepped.u_phys_w
        self._u_phys_act[k] = stepped.actuator_powers_w()
        self._overridden[k] = stepped.overridden
        self._t_r_sub[k] = stepped.t_r_sub_c
        self.k += 1
        return stepped

    def advance(self, controller: Controller) -> Decision:
        """One interval: observe, forecast, decide (:func:`decide`), step. A controller with
        the true-state estimator has perfect knowledge: it gets perfect forecasts too."""
        if self.n_buildings != 1:
            raise InternalError(
                f"ClosedLoop.advance drives one building, this loop has {self.n_buildings}; "
                "use advance_fleet with one controller per building"
            )
        perfect = _perfect_knowledge(controller)
        if perfect and not self.plant.has_true_state:
            raise ValueError(_NO_TRUE_STATE)
        obs = self.observation(perfect=perfect)
        forecast = self.forecast(perfect=perfect)
        u, time_s, fallback, error = decide(controller, obs, forecast, self.spec)
        plant = self.step(u, decision_s=time_s, fallback=fallback)
        if isinstance(u, np.ndarray):  # several actuators: their total, and each one's
            return Decision(obs.k, obs, forecast, float(u.sum()), time_s, fallback, error, plant, u)
        return Decision(obs.k, obs, forecast, u, time_s, fallback, error, plant)

    def advance_fleet(self, controllers: Sequence[Controller]) -> FleetStep:
        """One interval of every building: building b's controller ``controllers[b]`` observes
        its building and decides (:func:`decide`, so a failure falls back and is reported, in
        building order), then one batched plant step advances all buildings. Each controller
        gets its own copy of the forecast (perfect for the true-state estimator, as in
        :meth:`advance`)."""
        b = self.n_buildings
        if len(controllers) != b:
            raise InternalError(
                f"ClosedLoop.advance_fleet: {len(controllers)} controllers for {b} buildings; "
                "give one controller per building"
            )
        start = time.perf_counter()
        forecasts: dict[bool, Forecast] = {}
        n_act = self.spec.n_actuators
        u = np.zeros(b) if n_act == 1 else np.zeros((b, n_act))
        decision_s, fallback = np.zeros(b), np.zeros(b, dtype=bool)
        errors = []
        for i, controller in enumerate(controllers):
            perfect = _perfect_knowledge(controller)
            if perfect not in forecasts:
                forecasts[perfect] = self.forecast(perfect=perfect)
            shared = forecasts[perfect]  # each controller gets copies
            forecast = shared._replace(
                **{n: np.array(v) for n, v in shared._asdict().items() if v is not None}
            )
            obs = self.observation(perfect=perfect, building=i)
            u[i], decision_s[i], fallback[i], error = decide(controller, obs, forecast, self.spec)
            if error is not None:
                errors.append((i, error))
        decided = time.perf_counter()
        k = self.k
        plant = self.step(u, decision_s=decision_s, fallback=fallback)
        return FleetStep(
            k, u, decision_s, fallback, tuple(errors),
            controllers_s=decided - start, plant_s=time.perf_counter() - decided, plant=plant,
        )

    def record(self, building: int = 0) -> LoopRecord:
        """Copies of the intervals run so far of ``building``."""
        self._check_building(building)
        k, i = self.k, building
        return LoopRecord(
            t_r_c=self._t_r[:k, i].copy(),
            t_m_c=self._t_m[:k, i].copy(),
            u_w=self._u[:k, i].copy(),
            u_phys_w=self._u_phys[:k, i].copy(),
            overridden=self._overridden[:k, i].copy(),
            fallback=self._fallback[:k, i].copy(),
            decision_s=self._decision_s[:k, i].copy(),
            t_r_sub_c=self._t_r_sub[:k, i].copy(),
            t_a_c=self._means[:k, i, 0].copy(),
            g_w_per_m2=self._means[:k, i, 1].copy(),
            i_g_w=self._means[:k, i, 2].copy(),
            zones=self.zones,
            u_act_w=self._u_act[:k, i].copy(),
            u_phys_act_w=self._u_phys_act[:k, i].copy(),
            actuators=self.spec.actuators,
        )

    def aggregate_u_phys_w(self) -> np.ndarray:
        """(K,) delivered power summed over the buildings, per interval run so far [W]."""
        return self._u_phys[: self.k].sum(axis=1)


_NO_TRUE_STATE = (
    "this plant has no true state to know (an EnergyPlus building): the oracle and the "
    "clairvoyant do not apply; compare against the thermostat instead"
)


def _perfect_knowledge(controller: Controller) -> bool:
    """A controller with the true-state estimator knows everything: perfect forecasts too."""
    return controller.knows_true_state

