"""The centralised reference of a capped fleet: how much discomfort a cap MUST cost.

:func:`fleet_reference` poses the whole fleet's day as ONE convex problem, with every
building's exact RC model, its true state after the run's warm-up and perfect forecasts (the
series the plant runs on), the objective of every building's ``qp-mpc``
(:mod:`controllers.rc_mpc.problem`: energy cost + comfort weight x band violation at the end of
each interval + the tiny regulariser, each building's heater limits), and the coupling
constraint of the cap::

    sum_b p_b,j <= C_j        (every capped interval j)

It is solved over the counted intervals plus the forecast lead the closed loop's last plan
sees (so that the day's end is not a free coast), and its plan is then run open loop on the
plant (the same run, warm-up and minute substeps as :func:`scenarios.fleets.aggregator.
run_coordinated_fleet`), so its KPIs are measured as a closed loop's are. Run capped and
uncapped on the same fleet and day, the difference of discomfort is the least any
coordination of those buildings can achieve under that objective (no receding horizon, no
estimator, no forecast error, no distributed price); ``comfort_weight_eur_per_kh`` set very
large gives instead the least discomfort the cap allows at any energy cost.

:func:`solve_fleet_reference` is the problem on raw arrays (what the tests check against the
2R2C's analytic free response).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from controllers.rc_mpc.problem import DEFAULT_REGULARISATION
from controllers.thermostat import Thermostat
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InternalError
from pinn_mpc.physics import RCParams
from pinn_mpc.simulator import fleet_matrices
from scenarios.fleets.aggregator import cap_account, cap_series, parse_cap_window
from scenarios.inputs.registry import Scenario
from scenarios.records import CapAccount, Kpis
from scenarios.running.closed_loop import build_loop, counted_kpis, free_records, prepare_run

__all__ = ["FleetReference", "ReferencePlan", "fleet_reference", "solve_fleet_reference"]


@dataclass(frozen=True, kw_only=True)
class ReferencePlan:
    """The optimum of :func:`solve_fleet_reference` over N intervals: ``power_w`` (B, N)
    electrical power [W], ``t_r_c`` / ``t_m_c`` (B, N) the states at the end of each interval
    [C], ``violation_k`` (B, N) the band violation there [K], ``cap_price_eur_per_kwh`` (N,)
    the cap's shadow price (the coupling constraint's dual per kWh; 0 where uncapped),
    ``objective_eur`` the optimum, ``status`` the solver's."""

    power_w: np.ndarray
    t_r_c: np.ndarray
    t_m_c: np.ndarray
    violation_k: np.ndarray
    cap_price_eur_per_kwh: np.ndarray
    objective_eur: float
    status: str


def solve_fleet_reference(
    ad: np.ndarray,
    bd: np.ndarray,
    x0_c: np.ndarray,
    exogenous: np.ndarray,
    *,
    price_eur_per_kwh: np.ndarray,
    t_min_c: np.ndarray,
    t_max_c: np.ndarray,
    actuator: ActuatorSpec,
    dt_h: float,
    comfort_weight_eur_per_kh: float,
    cap_w: np.ndarray | None = None,
    cop: np.ndarray | None = None,
    regularisation_eur_per_kw2h: float = DEFAULT_REGULARISATION,
    solver: str = "CLARABEL",
) -> ReferencePlan:
    """One convex problem over B buildings and N intervals (module docstring).

    ``ad`` (B, 2, 2), ``bd`` (B, 2, 4) the exact ZOH matrices (inputs: heat [W], T_a, G, I_g),
    ``x0_c`` (B, 2) the states at the start, ``exogenous`` (N, 3) T_a, G, I_g; price and band
    (N,) (the band the state at the END of each interval must keep); ``actuator`` every
    building's (its bounds those of each building's power); ``cap_w`` (N,) the cap on
    the sum of the buildings' electrical power, ``inf`` where there is none (None: no cap; 0
    allowed); ``cop`` (N,) heat per electrical watt (default 1)."""
    import cvxpy as cp

    b, n = x0_c.shape[0], len(price_eur_per_kwh)
    if ad.shape != (b, 2, 2) or bd.shape != (b, 2, 4) or exogenous.shape != (n, 3):
        raise InternalError("solve_fleet_reference: ad (B,2,2), bd (B,2,4), x0 (B,2), exogenous (N,3)")
    cop_j = np.ones(n) if cop is None else np.asarray(cop, dtype=float)
    cap = np.full(n, np.inf) if cap_w is None else np.asarray(cap_w, dtype=float)
    if cap.shape != (n,) or np.any(np.isnan(cap)) or np.any(cap < 0):
        raise InternalError("solve_fleet_reference: the cap must be N values >= 0 (inf: none)")
    drift = np.einsum("jc,brc->brj", exogenous, bd[:, :, 1:])  # (B, 2, N) [C]
    gain = bd[:, :, 0][:, :, None] * 1000.0 * cop_j[None, None, :]  # (B, 2, N) [K per kW]
    p = cp.Variable((b, n))  # electrical power [kW]
    s = cp.Variable((b, n), nonneg=True)  # band violation [K]
    x = [cp.Variable((b, n)), cp.Variable((b, n))]  # T_r, T_m at the end of each interval
    constraints = [p >= actuator.lower_kw, p <= actuator.upper_kw]
    for r in range(2):
        first = np.einsum("bc,bc->b", ad[:, r, :], x0_c)[:, None]  # (B, 1)
        constraints.append(x[r][:, :1] == first + cp.multiply(gain[:, r, :1], p[:, :1]) + drift[:, r, :1])
        if n > 1:
            constraints.append(
                x[r][:, 1:]
                == cp.multiply(np.repeat(ad[:, r, 0:1], n - 1, axis=1), x[0][:, :-1])
                + cp.multiply(np.repeat(ad[:, r, 1:2], n - 1, axis=1), x[1][:, :-1])
                + cp.multiply(gain[:, r, 1:], p[:, 1:])
                + drift[:, r, 1:]
            )
    constraints += [x[0] + s >= t_min_c[None, :], x[0] - s <= t_max_c[None, :]]
    capped = np.flatnonzero(np.isfinite(cap))
    coupling = None
    if len(capped):
        coupling = cp.sum(p[:, capped], axis=0) <= cap[capped] / 1000.0
        constraints.append(coupling)
    heat = cp.multiply(np.broadcast_to(cop_j, (b, n)), p)
    objective = (
        dt_h * cp.sum(p @ price_eur_per_kwh)
        + dt_h * comfort_weight_eur_per_kh * cp.sum(s)
        + dt_h * regularisation_eur_per_kw2h * cp.sum_squares(heat)
    )
    problem = cp.Problem(cp.Minimize(objective), constraints)
    problem.solve(solver=solver)
    if problem.status not in ("optimal", "optimal_inaccurate") or p.value is None:
        raise InternalError(f"the fleet reference did not solve: {problem.status}")
    shadow = np.zeros(n)
    if coupling is not None and coupling.dual_value is not None:
        shadow[capped] = np.asarray(coupling.dual_value, dtype=float) / dt_h
    t_r, t_m = np.asarray(x[0].value), np.asarray(x[1].value)
    violation = np.maximum(t_min_c - t_r, 0.0) + np.maximum(t_r - t_max_c, 0.0)
    return ReferencePlan(
        power_w=actuator.clip_kw(np.asarray(p.value)) * 1000.0,
        t_r_c=t_r,
        t_m_c=t_m,
        violation_k=violation,
        cap_price_eur_per_kwh=shadow,
        objective_eur=float(problem.value),
        status=str(problem.status),
    )


@dataclass(frozen=True, kw_only=True)
class FleetReference:
    """The reference run of a fleet (:func:`fleet_reference`): ``plan`` over the counted
    intervals and the lead, ``kpis`` each building's KPIs of the plan run open loop on the
    plant (counted intervals), ``model_discomfort_kh`` (B,) the plan's own band violation at
    the interval ends over the counted intervals [K h], ``aggregate_w`` (K,) the plant's
    delivered aggregate, ``cap`` its account (None uncapped), ``counted`` K."""

    plan: ReferencePlan
    kpis: tuple[Kpis, ...]
    model_discomfort_kh: np.ndarray
    aggregate_w: np.ndarray
    cap: CapAccount | None
    counted: int

    @property
    def discomfort_kh(self) -> np.ndarray:
        """(B,) each building's measured discomfort (plant, minute substeps) [K h]."""
        return np.array([k["discomfort_kh"] for k in self.kpis])

    @property
    def energy_kwh(self) -> np.ndarray:
        return np.array([k["energy_kwh"] for k in self.kpis])


def fleet_reference(
    scenario: Scenario,
    fleet: Sequence[RCParams],
    *,
    days: int,
    seed: int,
    cap_kw: float | None = None,
    cap_window: str | None = None,
    warmup_steps: int | None = None,
    weather_part: str = "test",
    comfort_weight_eur_per_kh: float | None = None,
    lead: bool = True,
    solver: str = "CLARABEL",
) -> FleetReference:
    """The centralised optimum of ``fleet`` on ``scenario``'s run (module docstring): the same
    run as :func:`scenarios.fleets.aggregator.run_coordinated_fleet` (its warm-up under each
    building's thermostat, its counted days, its cap rule), planned in one problem from the
    true state at the first counted interval, then run open loop on the plant.
    ``comfort_weight_eur_per_kh`` replaces the scenario's comfort weight (e.g. 1e3: the least
    discomfort at any energy cost). ``lead`` False plans the counted intervals alone (no forecast
    lead: the least objective of those intervals, which no closed loop on the same plant beats
    but for what the minute substeps see between the interval ends)."""
    if cap_kw is None and cap_window is not None:
        raise InternalError("fleet_reference: a cap window needs a cap")
    run = prepare_run(scenario, days=days, seed=seed, warmup_steps=warmup_steps, weather_part=weather_part)
    spec = scenario.control_spec()
    loop = build_loop(scenario, run, seed=seed, fleet=fleet)
    thermostats = [Thermostat(spec) for _ in fleet]
    for t in thermostats:
        t.reset(seed)
    for _ in range(run.warmup):
        loop.advance_fleet(thermostats)
    series = run.series
    rows = slice(run.warmup, len(series) if lead else run.total)  # counted (and the last plan's lead)
    window = parse_cap_window(cap_window) if cap_window is not None else None
    cap = (
        cap_series(series.time_of_day_h, cap_kw, window, run.warmup)
        if cap_kw is not None
        else np.full(len(series), np.inf)
    )
    t_min, t_max = np.asarray(series.T_min, float), np.asarray(series.T_max, float)
    # The band at each interval's end is that of the interval and of the next (planning_band).
    after = slice(rows.start + 1, rows.stop + 1)
    lower = np.maximum(t_min[rows], np.append(t_min[after], t_min[-1])[: rows.stop - rows.start])
    upper = np.minimum(t_max[rows], np.append(t_max[after], t_max[-1])[: rows.stop - rows.start])
    exog = np.column_stack([np.asarray(series.T_a, float)[rows], np.asarray(series.G, float)[rows],
                            np.asarray(series.I_g, float)[rows]])
    ad, bd = fleet_matrices(fleet, spec.dt_s)
    x0 = loop.true_state()
    plan = solve_fleet_reference(
        ad, bd, x0, exog,
        price_eur_per_kwh=np.asarray(series.price, float)[rows],
        t_min_c=lower, t_max_c=upper,
        actuator=spec.actuator, dt_h=spec.dt_h,
        comfort_weight_eur_per_kh=(
            spec.comfort_weight_eur_per_kh if comfort_weight_eur_per_kh is None else comfort_weight_eur_per_kh
        ),
        cap_w=cap[rows],
        cop=np.asarray(spec.actuator.gain(exog[:, 0]), dtype=float),
        solver=solver,
    )
    k_counted = run.total - run.warmup
    b = len(fleet)
    for j in range(k_counted):
        loop.step(plan.power_w[:, j], decision_s=np.zeros(b), fallback=np.zeros(b, dtype=bool))
    free = free_records(scenario, run, seed=seed, fleet=fleet)
    kpis = tuple(counted_kpis(scenario, run, loop.record(i), free[i]) for i in range(b))
    aggregate = loop.aggregate_u_phys_w()[run.counted]
    account = None
    if cap_kw is not None:
        account = cap_account(aggregate, cap[run.counted], dt_s=scenario.sim.dt_s, window=cap_window)
        account["kw"] = float(cap_kw)
    return FleetReference(
        plan=plan,
        kpis=kpis,
        model_discomfort_kh=plan.violation_k[:, :k_counted].sum(axis=1) * spec.dt_h,
        aggregate_w=aggregate,
        cap=account,
        counted=k_counted,
    )
