"""``qp-mpc`` of a multi-zone building: one QP over its zones and actuators, solved by OSQP.

The building is :class:`pinn_mpc.multizone.MultiZoneParams` (Z zones, each a 2R2C, their air
nodes joined by internal walls) with the A actuators of ``spec.actuators`` (each on its zone,
heating or cooling). Over H control intervals j = 0..H-1, with decision ``p[j, a]`` each
actuator's electrical power [kW] within its bounds and a comfort slack ``s[j, z] >= 0`` [K] per
zone::

    minimise   sum_j  price_j dt_h sum_a p[j,a]  +  comfort_weight dt_h sum_z s[j,z]  +  rho dt_h sum_a q[j,a]^2
    subject to x[j+1] = Ad x[j] + Bu (g[j] * 1000 p[j]) + Bd d[j]         (exact ZOH, multizone.discretise)
               T_min[j,z] - s[j,z] <= T_r,z[j+1] <= T_max[j,z] + s[j,z]

``x`` the rooms then the masses [C] (2Z,), ``d`` the exogenous inputs in the order of
:data:`pinn_mpc.multizone.EXOGENOUS_NAMES`, ``g[j, a]`` actuator a's heat per electrical watt
on the forecast outdoor temperature (:meth:`pinn_mpc.actuator.ActuatorSpec.gain`, 1 for the
ideal heater or cooler) and ``Bu``'s column a carries its sign (a cooler's is negative,
:func:`pinn_mpc.multizone.continuous_matrices`). The price is the building's: it applies to the
total electrical power. As in the one-zone QP (:mod:`controllers.rc_mpc.problem`) the solver's
variable is the delivered heat ``q[j, a] = g[j, a] p[j, a]`` [kW], so its matrices stay fixed
while the COP changes: the price of heat is ``price_j / g[j, a]``, its bounds ``g`` times the
actuator's, and the regulariser ``rho`` (which only makes the optimum unique) acts on ``q``;
for ideal machines ``q = p``.

The comfort term is the one-zone objective's (:class:`controllers.objective.HorizonObjective`)
zone by zone, summed over the zones as the closed-loop KPIs sum a building's discomfort: the
violation of each zone's band by its room temperature at the END of interval j, the band being
:func:`controllers.objective.planning_band` of the zone's forecast band (``T_min``/``T_max``
(H,) for every zone or (H, Z) each zone's). An open band (such as
:data:`controllers.objective.OPEN_BAND_C`, or infinite limits) never binds.

The QP keeps the states as variables (the sparse form), per step ``A`` heats, ``Z`` slacks and
``2Z`` states, and the rows of the dynamics (2Z a step), the band (Z below, Z above), the heats'
bounds (A) and the slacks' (Z), each two-sided (OSQP's ``l <= A x <= u``). The ZOH's ``Ad`` is
dense (every zone reaches every other within an interval), so a step's dynamics hold about
``(2Z)^2`` entries and the matrix about ``H (4 Z^2 + 2 Z A)``, while the condensed form (states
eliminated) holds ``H (H + 1) / 2`` dense blocks of ``Z x A``: with a heater and a cooler per
zone (A = 2Z) some ``(H + 1) / 8`` times as many, at every Z. OSQP's factorisation and
iterations follow the entries, so the sparse form is the faster one. ``P`` and ``A`` are
built once; each step updates ``q``, ``l``, ``u`` and warm-starts from the last solution
shifted one step. ``benchmarks/bench_multizone_mpc.py`` measures the decision time.

:class:`MultiZoneMPC` is the controller: its state estimate is the plant's true state
(``estimator="true"``, the oracle's: :func:`controllers.rc_mpc.references.oracle_multizone`) or
a Kalman observer of the building
(:class:`controllers.estimators.MultiZoneKalmanEstimator`). A decision that fails (an
exception, a status other than solved, a non-finite plan) falls back on the previous plan
shifted by the steps since it was made, else on :func:`controllers.base.fallback_powers`.
Its ``act`` is three steps a fleet's coordination (:mod:`controllers.coordination`) also calls
apart: :meth:`MultiZoneMPC.observe` (the estimate, once a step), :meth:`MultiZoneMPC.plan` (under
an extra price on the building's electrical energy, as often as the coordination asks) and
:meth:`MultiZoneMPC.commit` (the plan applied, its first row possibly settled on the cap).
``casadi-mpc`` (:mod:`controllers.rc_mpc.multizone_casadi`) is this controller with another
solver of the same problem (:class:`ZoneSolver`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import numpy as np
import osqp
import scipy.sparse as sp

from controllers.base import (
    ControlSpec,
    Fallback,
    PlanningController,
    SolveStats,
    fallback_powers,
    first_values,
    raise_if_interrupted,
    solver_interrupts_held,
)
from controllers.estimators import MultiZoneKalmanEstimator, StateEstimator
from controllers.objective import band_violation_k, energy_cost_eur, zone_bands
from controllers.rc_mpc.osqp import OSQP_OPTIONS
from controllers.rc_mpc.problem import DEFAULT_REGULARISATION
from controllers.rc_mpc.qp import shift_steps
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.multizone import (
    EXOGENOUS_NAMES,
    MultiZoneParams,
    SystemMatrices,
    discretise,
    needed_inputs,
)

if TYPE_CHECKING:
    from controllers.base import Forecast, Observation

__all__ = ["ESTIMATORS", "MultiZoneMPC", "MultiZoneProblem", "MultiZoneStage", "ZonePlan", "ZoneSolver", "ZonesQP"]

#: The state estimators :class:`MultiZoneMPC` plans from: the plant's true state, or a Kalman
#: observer of the building.
ESTIMATORS = ("true", "kalman")


class MultiZoneStage(NamedTuple):
    """Numeric data of one solve over H steps of Z zones and A actuators."""

    x0_c: np.ndarray  # (2Z,) initial state, the rooms then the masses [C]
    free_c: np.ndarray  # (H, 2Z) each step's state change from the exogenous inputs [C]
    price_eur_per_kwh: np.ndarray  # (H,) the price of the building's electrical energy
    t_min_c: np.ndarray  # (H, Z) the band each zone's room keeps at each step's end [C]
    t_max_c: np.ndarray  # (H, Z)
    cop: np.ndarray  # (H, A) each actuator's heat per electrical watt at each step


@dataclass(frozen=True, kw_only=True)
class MultiZoneProblem:
    """The problem's data (module docstring): the building ``params`` (its zones
    ``spec.zones``), its actuators and objective settings ``spec``, the horizon
    ``horizon_steps`` H and the regulariser rho [EUR/kW^2h]."""

    params: MultiZoneParams
    spec: ControlSpec
    horizon_steps: int
    regularisation_eur_per_kw2h: float = DEFAULT_REGULARISATION

    def __post_init__(self) -> None:
        if not isinstance(self.params, MultiZoneParams):
            raise TypeError(f"MultiZoneProblem.params must be a MultiZoneParams, got {type(self.params).__name__}")
        if not isinstance(self.spec, ControlSpec):
            raise TypeError(f"MultiZoneProblem.spec must be a ControlSpec, got {type(self.spec).__name__}")
        if self.params.zone_specs != self.spec.zones:
            raise ValueError(
                f"MultiZoneProblem: the building's zones ({', '.join(z.name for z in self.params.zone_specs)}) "
                f"differ from spec.zones ({', '.join(z.name for z in self.spec.zones)}); give the "
                "ControlSpec the building's zones, in its order"
            )
        h = self.horizon_steps
        if isinstance(h, bool) or not isinstance(h, int) or h < 1:
            raise ValueError(f"MultiZoneProblem.horizon_steps must be a whole number >= 1, got {h!r}")
        rho = self.regularisation_eur_per_kw2h
        if not (isinstance(rho, int | float) and math.isfinite(rho) and rho > 0):
            raise ValueError(f"regularisation_eur_per_kw2h must be > 0 (it makes the optimum unique), got {rho!r}")

    @property
    def n_zones(self) -> int:
        return self.params.n_zones

    @property
    def n_actuators(self) -> int:
        return len(self.spec.actuators)

    @cached_property
    def matrices(self) -> SystemMatrices:
        """The exact ZOH of the control interval (:func:`pinn_mpc.multizone.discretise`)."""
        return discretise(self.params, self.spec.actuators, self.spec.dt_s)

    @cached_property
    def b_q_c_per_kw(self) -> np.ndarray:
        """(2Z, A) state change per kW of each actuator's heat held over one interval [K/kW],
        its sign included (a cooler's lowers the temperatures)."""
        return self.matrices.b_u * 1000.0

    @cached_property
    def needed(self) -> tuple[str, ...]:
        """The exogenous inputs the building takes (:func:`pinn_mpc.multizone.needed_inputs`)."""
        return needed_inputs(self.params)

    def exogenous(self, forecast: Forecast) -> np.ndarray:
        """(H, 7) the forecast's exogenous inputs in :data:`EXOGENOUS_NAMES` order (a shorter
        forecast repeats its last value); an input the building does not take and the forecast
        does not have is 0. An InputError names one it takes and the forecast lacks."""
        h = self.horizon_steps
        fields = forecast._asdict()
        d = np.zeros((h, len(EXOGENOUS_NAMES)))
        for i, name in enumerate(EXOGENOUS_NAMES):
            values = fields[name]
            if values is None:
                if name in self.needed:
                    raise InputError(
                        f"the forecast has no {name}, which the building's zones take (their "
                        f"solar_input); run it on a scenario whose weather has the facades' "
                        f"irradiance, or give the zones solar_input 'G'"
                    )
                continue
            d[:, i] = first_values(values, h)
        return d

    def bands(self, forecast: Forecast) -> tuple[np.ndarray, np.ndarray]:
        """(H, Z) each zone's band at each step's end [C] (:func:`controllers.objective.zone_bands`
        of the zone's forecast band, which is (H',) for every zone or (H', Z) each zone's)."""
        return zone_bands(forecast, self.spec.zones, self.horizon_steps)

    def stage(self, x0_c: np.ndarray, forecast: Forecast) -> MultiZoneStage:
        """Numeric data for a solve from state ``x0_c`` (2Z,) [C] and the forecast."""
        d = self.exogenous(forecast)
        x0 = np.asarray(x0_c, dtype=float).reshape(-1)
        if x0.shape != (2 * self.n_zones,) or not np.all(np.isfinite(x0)):
            raise FloatingPointError(f"state estimate is not {2 * self.n_zones} finite temperatures: {x0}")
        t_min, t_max = self.bands(forecast)
        cop = np.stack([a.gain(d[:, 0]) for a in self.spec.actuators], axis=1)
        return MultiZoneStage(
            x0_c=x0,
            free_c=d @ self.matrices.b_d.T,
            price_eur_per_kwh=first_values(forecast.price, self.horizon_steps),
            t_min_c=t_min,
            t_max_c=t_max,
            cop=cop,
        )

    def rollout(self, stage: MultiZoneStage, p_kw: np.ndarray) -> np.ndarray:
        """(H, 2Z) the states at the end of each interval [C] under electrical plan ``p_kw``
        (H, A) [kW]."""
        ad = self.matrices.a
        heat = np.asarray(p_kw, dtype=float) * stage.cop
        x = stage.x0_c
        out = np.empty((len(heat), 2 * self.n_zones))
        for j in range(len(heat)):
            x = ad @ x + self.b_q_c_per_kw @ heat[j] + stage.free_c[j]
            out[j] = x
        return out

    def objective(self, stage: MultiZoneStage, p_kw: np.ndarray) -> float:
        """The objective of electrical plan ``p_kw`` (H, A) [kW] without the regulariser
        [EUR]: the energy's price plus each zone's band violation at each step's end."""
        p_kw = np.asarray(p_kw, dtype=float)
        t_r = self.rollout(stage, p_kw)[:, : self.n_zones]
        dt_h = self.spec.dt_h
        energy = energy_cost_eur(p_kw.sum(axis=1) * 1000.0, stage.price_eur_per_kwh, dt_h)
        violation = band_violation_k(t_r, stage.t_min_c, stage.t_max_c)
        return float(np.sum(energy) + self.spec.comfort_weight_eur_per_kh * dt_h * np.sum(violation))


class ZoneSolver(Protocol):
    """What :class:`MultiZoneMPC` asks of its solver: ``solve`` returns the heats (H, A) [kW]
    (NaN unless solved), the status (``"solved"`` when the optimum was found, else the
    solver's word) and the iterations; ``reset`` forgets the warm start."""

    @property
    def n_variables(self) -> int: ...

    def reset(self) -> None: ...

    def solve(self, stage: MultiZoneStage) -> tuple[np.ndarray, str, int]: ...

    def predicted_states_c(self) -> np.ndarray: ...


class ZonesQP:
    """The problem's OSQP data and its warm-started solver (module docstring).

    Variables, block after block, each time-major: the heats ``q[j, a]`` [kW] (H A), the
    slacks ``s[j, z]`` [K] (H Z), the states ``x[j]`` at the end of step j [C] (H 2Z). Rows,
    likewise: the dynamics (H 2Z), each zone's band from below and from above (H Z each), the
    heats' bounds (H A), the slacks' (H Z)."""

    def __init__(self, problem: MultiZoneProblem, solver_options: dict[str, Any]) -> None:
        self.problem, self.solver_options = problem, solver_options
        h, z_n, a_n = problem.horizon_steps, problem.n_zones, problem.n_actuators
        self.h, self.z_n, self.a_n = h, z_n, a_n
        self.per_step = (a_n, z_n, 2 * z_n)
        self.rows_per_step = (2 * z_n, z_n, z_n, a_n, z_n)
        self._p_upper, self._a = self._matrices()
        self.reset()

    @property
    def n_variables(self) -> int:
        return self.h * sum(self.per_step)

    @property
    def n_rows(self) -> int:
        return self.h * sum(self.rows_per_step)

    def _matrices(self) -> tuple[sp.csc_matrix, sp.csc_matrix]:
        """OSQP's ``P`` (upper triangle) and ``A``."""
        prob = self.problem
        h, z_n, a_n = self.h, self.z_n, self.a_n
        n_x = 2 * z_n
        q0, s0, x0 = 0, h * a_n, h * (a_n + z_n)
        ad, b_q = prob.matrices.a, prob.b_q_c_per_kw
        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []
        vals: list[np.ndarray] = []

        def add(r: np.ndarray, c: np.ndarray, v: np.ndarray | float) -> None:
            r, c = np.broadcast_arrays(np.asarray(r), np.asarray(c))
            rows.append(r.reshape(-1))
            cols.append(c.reshape(-1))
            vals.append(np.broadcast_to(np.asarray(v, dtype=float), r.shape).reshape(-1))

        j = np.arange(h)[:, None]  # (H, 1)
        state = np.arange(n_x)[None, :]  # (1, 2Z)
        # Dynamics: x[j] - Ad x[j-1] - Bq q[j] = drift[j] (x[-1]'s response in drift[0]).
        dyn = j * n_x + state  # (H, 2Z) row of state i at step j
        add(dyn, x0 + dyn, 1.0)
        bi, ba = np.nonzero(b_q)
        add(j * n_x + bi, q0 + j * a_n + ba, -b_q[bi, ba])
        ai, ak = np.nonzero(ad)
        add(j[1:] * n_x + ai, x0 + (j[1:] - 1) * n_x + ak, -ad[ai, ak])
        # The band, each zone's room from below (T_r + s) and from above (T_r - s).
        zone = np.arange(z_n)[None, :]
        below, above = h * n_x + j * z_n + zone, h * (n_x + z_n) + j * z_n + zone
        room, slack = x0 + j * n_x + zone, s0 + j * z_n + zone
        add(below, room, 1.0)
        add(below, slack, 1.0)
        add(above, room, 1.0)
        add(above, slack, -1.0)
        # The heats' and the slacks' bounds.
        heat = np.arange(h * a_n)
        add(h * (n_x + 2 * z_n) + heat, q0 + heat, 1.0)
        slacks = np.arange(h * z_n)
        add(h * (n_x + 2 * z_n + a_n) + slacks, s0 + slacks, 1.0)
        a = sp.csc_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(self.n_rows, self.n_variables),
        )
        diag = np.zeros(self.n_variables)
        diag[: h * a_n] = 2.0 * prob.spec.dt_h * prob.regularisation_eur_per_kw2h
        return sp.diags(diag, format="csc"), a

    def vectors(self, stage: MultiZoneStage) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """OSQP's ``q``, ``l``, ``u`` of a stage."""
        prob = self.problem
        h, z_n, a_n = self.h, self.z_n, self.a_n
        dt_h = prob.spec.dt_h
        q = np.zeros(self.n_variables)
        q[: h * a_n] = (dt_h * stage.price_eur_per_kwh[:, None] / stage.cop).reshape(-1)
        q[h * a_n : h * (a_n + z_n)] = dt_h * prob.spec.comfort_weight_eur_per_kh
        drift = stage.free_c.copy()
        drift[0] += prob.matrices.a @ stage.x0_c
        lower_kw = np.array([a.lower_kw for a in prob.spec.actuators])
        upper_kw = np.array([a.upper_kw for a in prob.spec.actuators])
        inf_rows = (np.full(h * z_n, np.inf),)
        lower = np.concatenate([
            drift.reshape(-1), stage.t_min_c.reshape(-1), -inf_rows[0],
            (stage.cop * lower_kw).reshape(-1), np.zeros(h * z_n),
        ])
        upper = np.concatenate([
            drift.reshape(-1), inf_rows[0], stage.t_max_c.reshape(-1),
            (stage.cop * upper_kw).reshape(-1), inf_rows[0],
        ])
        return q, lower, upper

    def reset(self) -> None:
        """Forget the solver (no warm start carried over) and its solution."""
        self._solver: osqp.OSQP | None = None
        self.last_x = np.full(self.n_variables, np.nan)

    def solve(self, stage: MultiZoneStage) -> tuple[np.ndarray, str, int]:
        """Solve from the last solution shifted one step; returns the heats (H, A) [kW] (NaN
        unless solved), OSQP's status and its iterations."""
        q, lower, upper = self.vectors(stage)
        with solver_interrupts_held():
            if self._solver is None:
                self._solver = osqp.OSQP()
                self._solver.setup(P=self._p_upper, A=self._a, q=q, l=lower, u=upper, **self.solver_options)
            else:
                self._solver.update(q=q, l=lower, u=upper)
            result = self._solver.solve(raise_error=False)
        status = str(result.info.status)
        raise_if_interrupted(status)
        x, y = np.asarray(result.x, dtype=float), np.asarray(result.y, dtype=float)
        heat = np.full((self.h, self.a_n), np.nan)
        if status == "solved" and np.all(np.isfinite(x)):
            heat = x[: self.h * self.a_n].reshape(self.h, self.a_n)
            # Receding horizon: the next solve starts from this solution shifted one step.
            self._solver.warm_start(x=shift_steps(x, self.per_step, self.h), y=shift_steps(y, self.rows_per_step, self.h))
        self.last_x = x
        return heat, status, int(result.info.iter)

    def predicted_states_c(self) -> np.ndarray:
        """(H, 2Z) the states of the last solve's solution [C] (the plan's own prediction)."""
        start = self.h * (self.a_n + self.z_n)
        return self.last_x[start:].reshape(self.h, 2 * self.z_n)


class _PlanFallback(Fallback):
    """:class:`controllers.base.Fallback` of a plan of several actuators (H, A):
    :meth:`act_all` returns the previous plan shifted by the steps since it was made, else
    :func:`controllers.base.fallback_powers` (A,)."""

    def __init__(self, spec: ControlSpec) -> None:
        super().__init__(spec, reuse_plan=True)

    def act_all(self, obs: Observation, forecast: Forecast) -> np.ndarray:
        self.n_events += 1
        if self.plan_w is None or self._age + 1 >= len(self.plan_w):
            self.plan_w = None
            return fallback_powers(obs, forecast, self.spec)
        self._age += 1
        return self.plan_w[self._age].copy()


class ZonePlan(NamedTuple):
    """A plan of :meth:`MultiZoneMPC.plan`: each actuator's electrical power [W] (H, A), None
    when the step could not plan (no estimate, no solution); the solver's word and its
    iterations."""

    power_w: np.ndarray | None
    status: str
    iterations: int


class _Observed(NamedTuple):
    """What :meth:`MultiZoneMPC.observe` kept for the step's plans and its commit."""

    obs: Observation
    forecast: Forecast
    stage: MultiZoneStage | None  # None: the estimate failed (``error`` says how)
    error: str | None
    start_s: float


class _TrueZones:
    """The plant's true state (the oracle's): the measured rooms and the hidden masses."""

    def reset(self) -> None:
        pass

    def update(self, obs: Observation) -> np.ndarray:
        t_m = obs.t_m_true_zones_c
        t_r = obs.t_r_zones_c()
        if t_m is None or np.shape(t_m) != t_r.shape or not np.all(np.isfinite(t_m)):
            raise ValueError(
                f"the true-state estimator needs each zone's true thermal-mass temperature, got "
                f"obs.t_m_true_zones_c={t_m}; use it only against a simulator (estimator='kalman' "
                "otherwise)"
            )
        return np.concatenate([t_r, np.asarray(t_m, dtype=float)])


class MultiZoneMPC(PlanningController):
    """The QP MPC of a multi-zone building (module docstring): ``act`` returns each
    actuator's electrical power [W], (A,) in ``spec.actuators``' order (a number for a building
    of one actuator), the first step of a plan (H, A) kept in :attr:`last_plan` (None before a
    decision, or after a fallback that had no plan left); :attr:`n_fallbacks` counts the
    fallbacks since ``reset``.

    ``params`` is the building (its zones ``spec.zones``); ``estimator`` ``"true"`` (the
    plant's true state, :attr:`knows_true_state`), ``"kalman"``
    (:class:`~controllers.estimators.MultiZoneKalmanEstimator` with the spec's sensor noise)
    or an estimator object whose ``update(obs)`` returns the state (2Z,) (a planner's own
    observer, whose fallback this MPC is);
    ``horizon_steps`` H (``spec.horizon_steps`` unless given); ``regularisation_eur_per_kw2h``
    rho; ``solver_options`` update :data:`controllers.rc_mpc.osqp.OSQP_OPTIONS` (e.g.
    ``{"max_iter": 1}`` stops OSQP before it converges, which exercises the fallback).
    """

    #: It plans on RC parameters, over no learned model (the protocol's).
    model = None
    fallback: _PlanFallback

    def __init__(
        self,
        params: MultiZoneParams,
        spec: ControlSpec,
        *,
        estimator: str | StateEstimator = "kalman",
        name: str = "qp-mpc",
        horizon_steps: int | None = None,
        regularisation_eur_per_kw2h: float = DEFAULT_REGULARISATION,
        solver_options: dict[str, Any] | None = None,
    ) -> None:
        if isinstance(estimator, str) and estimator not in ESTIMATORS:
            raise ValueError(
                f"MultiZoneMPC.estimator = {estimator!r} is unknown; choose 'true' (the plant's "
                "true state, the oracle's) or 'kalman' (a Kalman observer of the building), or "
                "give an estimator object (reset(), update(obs) -> the state (2Z,))"
            )
        if not isinstance(name, str) or not name:
            raise ValueError(f"MultiZoneMPC.name must be a non-empty string, got {name!r}")
        self.name = name
        self.params, self.spec = params, spec
        self.problem = MultiZoneProblem(
            params=params,
            spec=spec,
            horizon_steps=spec.horizon_steps if horizon_steps is None else horizon_steps,
            regularisation_eur_per_kw2h=regularisation_eur_per_kw2h,
        )
        self.qp: ZoneSolver = self._new_solver(solver_options)
        if isinstance(estimator, str):
            estimator = _TrueZones() if estimator == "true" else MultiZoneKalmanEstimator(params, spec)
        self.estimator: StateEstimator = estimator
        self.fallback = _PlanFallback(spec)
        self.reset()

    def _new_solver(self, solver_options: dict[str, Any] | None) -> ZoneSolver:
        """The problem's solver (OSQP on :class:`ZonesQP`; a subclass its own), its options
        ``solver_options`` updating the defaults, kept as :attr:`solver_options`."""
        self.solver_options = {**OSQP_OPTIONS, **(solver_options or {})}
        return ZonesQP(self.problem, self.solver_options)

    @property
    def knows_true_state(self) -> bool:
        """Whether it plans from the plant's true state (the oracle)."""
        return isinstance(self.estimator, _TrueZones)

    def reset(self, seed: int | None = None) -> None:
        """Forget the estimator's state, the plan, the counters and the solver's warm start
        (no randomness used, so ``seed`` changes nothing)."""
        self.estimator.reset()
        self.fallback.reset()
        self.qp.reset()
        self._stats = SolveStats(time_s=0.0, status="not run", iterations=0, fallback=False)
        self.state_estimate_c = np.full(2 * self.problem.n_zones, np.nan)
        self._step: _Observed | None = None

    def act(self, obs: Observation, forecast: Forecast) -> float | np.ndarray:
        self.observe(obs, forecast)
        return self._one_or_all(self.commit(self.plan()))

    def observe(self, obs: Observation, forecast: Forecast) -> None:
        """The first part of :meth:`act`: estimate the state from ``obs`` and make the step's
        problem data from ``forecast``, once a step. A forecast that does not fit the building
        raises (a mistake to report); a failed estimate is kept for :meth:`plan` to report and
        :meth:`commit` to fall back on."""
        start = time.perf_counter()
        self.problem.bands(forecast)
        self.problem.exogenous(forecast)
        stage, error = None, None
        try:
            self.state_estimate_c = np.full(2 * self.problem.n_zones, np.nan)
            self.state_estimate_c = self.estimator.update(obs)
            stage = self.problem.stage(self.state_estimate_c, forecast)
        except Exception as exc:  # any failure acts through the fallback, never raises
            error = f"error: {type(exc).__name__}: {exc}"
        self._step = _Observed(obs=obs, forecast=forecast, stage=stage, error=error, start_s=start)

    def plan(self, extra_price_eur_per_kwh: np.ndarray | None = None) -> ZonePlan:
        """The step's plan (after :meth:`observe`) under the forecast price plus
        ``extra_price_eur_per_kwh`` (H,) [EUR/kWh] on the building's electrical energy (a
        fleet's coordination price; None: none); it changes no estimate or fallback, so it may
        be called many times a step (each solve warm-starts the next)."""
        step = self._step
        if step is None:
            raise InternalError("MultiZoneMPC.plan: call observe() first")
        if step.stage is None:
            return ZonePlan(power_w=None, status=step.error or "error", iterations=0)
        stage = step.stage
        if extra_price_eur_per_kwh is not None:
            extra = np.asarray(extra_price_eur_per_kwh, dtype=float)
            if extra.shape != stage.price_eur_per_kwh.shape or not np.all(np.isfinite(extra)):
                raise ValueError(
                    f"MultiZoneMPC.plan: extra_price_eur_per_kwh must be {len(stage.price_eur_per_kwh)} "
                    f"finite prices [EUR/kWh] (one per step of the horizon), got shape {extra.shape}"
                )
            stage = stage._replace(price_eur_per_kwh=stage.price_eur_per_kwh + extra)
        status, iterations = "error", 0
        try:
            heat, status, iterations = self.qp.solve(stage)
            if status != "solved":
                raise RuntimeError(f"solver status {status!r}")
            p_kw = heat / stage.cop
            if not np.all(np.isfinite(p_kw)):
                raise FloatingPointError("solver returned a non-finite plan")
        except Exception as exc:  # any failure acts through the fallback, never raises
            return ZonePlan(power_w=None, status=f"{status}: {type(exc).__name__}: {exc}", iterations=iterations)
        plan_w = np.stack([a.clip_kw(p_kw[:, i]) for i, a in enumerate(self.spec.actuators)], axis=1) * 1000.0
        return ZonePlan(power_w=plan_w, status=status, iterations=iterations)

    def commit(self, plan: ZonePlan) -> np.ndarray:
        """Apply ``plan`` (of this step's :meth:`plan`; its first row may have been settled
        otherwise, e.g. on a fleet's cap): each actuator's power [W] (A,), its first row, or
        the fallback's when it has none; kept as :attr:`last_plan`, counted in the stats."""
        step = self._step
        if step is None:
            raise InternalError("MultiZoneMPC.commit: call observe() first")
        self._step = None
        failed = plan.power_w is None
        if plan.power_w is None:
            action = self.fallback.act_all(step.obs, step.forecast)
        else:
            self.fallback.planned(plan.power_w)
            action = plan.power_w[0].copy()
        self._stats = SolveStats(
            time_s=time.perf_counter() - step.start_s, status=plan.status, iterations=plan.iterations,
            fallback=failed,
        )
        return action

    def _one_or_all(self, powers_w: np.ndarray) -> float | np.ndarray:
        """A building's one actuator's power as a number, several actuators' as (A,)."""
        return float(powers_w[0]) if len(powers_w) == 1 else powers_w
