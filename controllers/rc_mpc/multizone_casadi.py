"""``casadi-mpc`` of a multi-zone building: :class:`controllers.rc_mpc.multizone.MultiZoneMPC`'s
problem written once in CasADi and solved by ``casadi.qpsol``.

The problem is the module docstring's of :mod:`controllers.rc_mpc.multizone` (the same
objective, bounds, slack per zone and step, comfort at the end of each interval, each
actuator's gain on the forecast ``T_a`` and a cooler's sign in ``Bu``), and so is the
controller: :class:`MultiZoneCasadiMPC` is a :class:`~controllers.rc_mpc.multizone.MultiZoneMPC`
(its estimators, its fallback on the previous plan shifted else
:func:`controllers.base.fallback_powers`, its stats and its observe / plan / commit steps)
whose solver is :class:`ZonesCasadi`. Only the solve differs.

The decision is, as qp-mpc's, the delivered heat ``q`` (H, A) [kW], the slacks ``s`` (H, Z)
[K] and the states ``x`` (H, 2Z) [C], written as CasADi matrices (A x H, Z x H, 2Z x H) and
their dynamics and band as matrix expressions: ``x - Ad [x0, x[:-1]] - Bq q`` (its rows equal
to each step's drift, the first holding ``Ad x0``), ``T_r + s >= T_min``, ``T_r - s <= T_max``.
The price of heat (``price / g``) is a parameter; the drift, band and the heats' bounds
(``g`` times the actuator's) enter as bounds. Everything a step changes is a number, so the
``qpsol`` function is built once (and again on ``reset``) and each solve warm-starts from the
last solution and multipliers shifted one step.

Why the sparse form and OSQP: the ZOH's ``Ad`` is dense, so the condensed form (states
eliminated, as the one-zone :mod:`controllers.rc_mpc.casadi`) holds ``H (H + 1) / 2`` dense
``Z x A`` blocks; qpOASES, the one-zone plugin, is a dense active-set solver whose work grows
with the square of the decisions (H (A + Z)) and with the active-set changes, which grow with
them: measured on the benchmark's building it is already about a hundred times slower than
OSQP at 5 zones and H = 48, and unusable on the medium office (H = 96, A = 30); its sparse
mode needs the HSL linear solvers, which CasADi does not ship. qrqp, CasADi's sparse
active-set solver, was slower still from a cold start and reported success at plans well
above the optimum (on the two-zone case of ``tests/test_multizone_casadi.py`` an objective a
quarter above OSQP's and qp-mpc's). OSQP on the sparse form factorises once per ``rho`` and
its iterations follow the matrix's entries, as qp-mpc's (:mod:`controllers.rc_mpc.multizone`);
with qp-mpc's settings (:data:`controllers.rc_mpc.osqp.OSQP_OPTIONS`) it finds qp-mpc's plans.
CasADi hands OSQP the matrices again on every call (a factorisation each solve, where qp-mpc
updates only the vectors), so it is slower than qp-mpc by about that factorisation. The
expressions are CasADi's ``MX`` (matrix operations): the scalar ``SX`` graph of the same problem
took seconds to differentiate at 15 zones. ``benchmarks/bench_multizone_mpc.py`` measures the
decision time beside qp-mpc's.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from controllers.base import ControlSpec, raise_if_interrupted, solver_interrupts_held
from controllers.estimators import StateEstimator
from controllers.rc_mpc.multizone import MultiZoneMPC, MultiZoneProblem, MultiZoneStage, ZoneSolver
from controllers.rc_mpc.osqp import OSQP_OPTIONS
from controllers.rc_mpc.qp import shift_steps
from pinn_mpc.errors import InternalError
from pinn_mpc.multizone import MultiZoneParams

__all__ = ["CASADI_OSQP_OPTIONS", "MultiZoneCasadiMPC", "ZonesCasadi"]

#: The options of CasADi's ``qpsol`` OSQP plugin: qp-mpc's settings
#: (:data:`controllers.rc_mpc.osqp.OSQP_OPTIONS`, under the names of the OSQP CasADi ships),
#: warm-started on the primal and the dual.
CASADI_OSQP_OPTIONS: dict[str, Any] = {
    "osqp": {("polish" if key == "polishing" else key): value for key, value in OSQP_OPTIONS.items()},
    "warm_start_primal": True,
    "warm_start_dual": True,
}


class ZonesCasadi:
    """The problem of ``problem`` in CasADi (module docstring) and its ``qpsol`` OSQP solver.

    Variables, block after block, each time-major: the heats ``q[j, a]`` [kW] (H A), the
    slacks ``s[j, z]`` [K] (H Z), the states ``x[j]`` at the end of step j [C] (H 2Z).
    Constraints: the dynamics (H 2Z), each zone's band from below and from above (H Z each).
    ``solver_options`` update :data:`CASADI_OSQP_OPTIONS`, a dict value merging into the
    default's (``{"osqp": {"max_iter": 1}}`` stops OSQP before it converges)."""

    def __init__(self, problem: MultiZoneProblem, solver_options: dict[str, Any]) -> None:
        self.problem = problem
        options = dict(CASADI_OSQP_OPTIONS)
        for key, value in solver_options.items():
            options[key] = {**options.get(key, {}), **value} if isinstance(value, dict) else value
        options["error_on_fail"] = False
        self.options = options
        h, z_n, a_n = problem.horizon_steps, problem.n_zones, problem.n_actuators
        self.h, self.z_n, self.a_n = h, z_n, a_n
        self.per_step = (a_n, z_n, 2 * z_n)
        self.rows_per_step = (2 * z_n, z_n, z_n)
        self._qp = self._expressions()
        self._solver: ca.Function | None = None
        self._solved_since_reset = False
        self.reset()

    @property
    def n_variables(self) -> int:
        return self.h * sum(self.per_step)

    def _expressions(self) -> dict[str, ca.MX]:
        """The QP of ``qpsol``: decision ``x``, parameter ``p`` (the price of heat, H A),
        objective ``f`` and constraints ``g``."""
        prob = self.problem
        h, z_n, a_n = self.h, self.z_n, self.a_n
        spec = prob.spec
        q = ca.MX.sym("heat_kw", a_n, h)
        s = ca.MX.sym("slack_k", z_n, h)
        x = ca.MX.sym("state_c", 2 * z_n, h)
        price = ca.MX.sym("heat_price_eur_per_kwh", a_n, h)
        before = ca.horzcat(ca.MX.zeros(2 * z_n, 1), x[:, : h - 1])  # x[j-1]; x0's response is in the bounds
        dynamics = x - ca.mtimes(ca.DM(prob.matrices.a), before) - ca.mtimes(ca.DM(prob.b_q_c_per_kw), q)
        rooms = x[:z_n, :]
        f = spec.dt_h * (
            ca.dot(price, q)
            + spec.comfort_weight_eur_per_kh * ca.sum1(ca.vec(s))
            + prob.regularisation_eur_per_kw2h * ca.sumsqr(q)
        )
        return {
            "x": ca.vertcat(ca.vec(q), ca.vec(s), ca.vec(x)),
            "p": ca.vec(price),
            "f": f,
            "g": ca.vertcat(ca.vec(dynamics), ca.vec(rooms + s), ca.vec(rooms - s)),
        }

    def arguments(self, stage: MultiZoneStage) -> dict[str, np.ndarray]:
        """The solver's numbers of a stage: ``p``, ``lbx``, ``ubx``, ``lbg``, ``ubg``."""
        prob = self.problem
        h, z_n = self.h, self.z_n
        drift = stage.free_c.copy()  # (H, 2Z)
        drift[0] += prob.matrices.a @ stage.x0_c
        lower_kw = np.array([a.lower_kw for a in prob.spec.actuators])
        upper_kw = np.array([a.upper_kw for a in prob.spec.actuators])
        inf_slacks, inf_states = np.full(h * z_n, np.inf), np.full(2 * h * z_n, np.inf)
        return {
            "p": (stage.price_eur_per_kwh[:, None] / stage.cop).reshape(-1),
            "lbx": np.concatenate([(stage.cop * lower_kw).reshape(-1), np.zeros(h * z_n), -inf_states]),
            "ubx": np.concatenate([(stage.cop * upper_kw).reshape(-1), inf_slacks, inf_states]),
            "lbg": np.concatenate([drift.reshape(-1), stage.t_min_c.reshape(-1), -inf_slacks]),
            "ubg": np.concatenate([drift.reshape(-1), inf_slacks, stage.t_max_c.reshape(-1)]),
        }

    def reset(self) -> None:
        """A fresh solver (OSQP keeps its state inside the CasADi function; one that has not
        solved yet is kept) and no warm start."""
        if self._solver is None or self._solved_since_reset:
            self._solver = ca.qpsol("casadi_zones", "osqp", self._qp, self.options)
        self._solved_since_reset = False
        self._warm: dict[str, np.ndarray] = {}
        self.last_x = np.full(self.n_variables, np.nan)

    def solve(self, stage: MultiZoneStage) -> tuple[np.ndarray, str, int]:
        """Solve from the last solution shifted one step; returns the heats (H, A) [kW] (NaN
        unless solved), ``"solved"`` or OSQP's status, and its iterations (0: CasADi's OSQP
        plugin does not report them)."""
        args = {**self.arguments(stage), **self._warm}
        if self._solver is None:
            raise InternalError("ZonesCasadi.solve: no solver (reset() makes it)")
        self._solved_since_reset = True
        with solver_interrupts_held():
            sol = self._solver(**args)
            # Every call into CasADi may hold its own SIGINT handler while it runs: all within.
            stats = self._solver.stats()
            x = np.asarray(sol["x"], dtype=float).reshape(-1)
            lam_x = np.asarray(sol["lam_x"], dtype=float).reshape(-1)
            lam_g = np.asarray(sol["lam_g"], dtype=float).reshape(-1)
        word = str(stats.get("return_status", "unknown"))
        raise_if_interrupted(word)
        heat = np.full((self.h, self.a_n), np.nan)
        solved = bool(stats.get("success", False)) and bool(np.all(np.isfinite(x)))
        if solved:
            heat = x[: self.h * self.a_n].reshape(self.h, self.a_n)
            # Receding horizon: the next solve starts from this solution shifted one step.
            self._warm = {
                "x0": shift_steps(x, self.per_step, self.h),
                "lam_x0": shift_steps(lam_x, self.per_step, self.h),
                "lam_g0": shift_steps(lam_g, self.rows_per_step, self.h),
            }
        self.last_x = x
        return heat, "solved" if solved else word, max(int(stats.get("iter_count", 0) or 0), 0)

    def predicted_states_c(self) -> np.ndarray:
        """(H, 2Z) the states of the last solve's solution [C] (the plan's own prediction)."""
        start = self.h * (self.a_n + self.z_n)
        return self.last_x[start:].reshape(self.h, 2 * self.z_n)


class MultiZoneCasadiMPC(MultiZoneMPC):
    """``casadi-mpc`` of a multi-zone building: :class:`MultiZoneMPC` solving its problem with
    ``casadi.qpsol`` (module docstring, :class:`ZonesCasadi`). The keywords are
    :class:`MultiZoneMPC`'s, but ``solver_options`` update :data:`CASADI_OSQP_OPTIONS`
    (``{"osqp": {"max_iter": 1}}`` stops OSQP before it converges, which exercises the
    fallback) and ``name`` is ``"casadi-mpc"`` unless given."""

    def __init__(
        self,
        params: MultiZoneParams,
        spec: ControlSpec,
        *,
        estimator: str | StateEstimator = "kalman",
        name: str = "casadi-mpc",
        **options: Any,
    ) -> None:
        super().__init__(params, spec, estimator=estimator, name=name, **options)

    def _new_solver(self, solver_options: dict[str, Any] | None) -> ZoneSolver:
        self.solver_options = dict(solver_options or {})
        return ZonesCasadi(self.problem, self.solver_options)
