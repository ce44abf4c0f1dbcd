"""``casadi-mpc``: the RC MPC problem of :mod:`controllers.rc_mpc.problem` in CasADi.

The problem is written once symbolically and handed to ``casadi.qpsol``, in condensed form:
the decision is (power, slack), the room temperature at the end of interval j is
``free[j] + (S p)[j]`` where ``S p`` is the symbolic rollout of ``Ad``, ``Bd`` (from
:func:`pinn_mpc.physics.discretise`) from a zero state and ``free`` the response to the
initial state and the exogenous inputs, computed each step by ``RCProblem.rollout``. The price
is a CasADi parameter; the free response and the comfort band enter as constraint bounds. Each
step only numbers change and the solver is warm-started from the previous solution shifted by
one step (qp-mpc keeps the states as variables instead, so the two formulations cross-check).

The QP plugin defaults to ``qpoases`` (ships with CasADi; an exact active-set solver, reliable
on this nearly-linear problem; dense, hence the condensed form). Alternatives measured on the
household problem at H=48: ``qrqp`` is faster but, warm-started with an inconsistent active
set, reported success at a suboptimal point; ``osqp`` needs tight tolerances (slow) on this
near-LP; ``highs`` collides with the ``highspy`` wheel cvxpy loads (two HiGHS libraries in one
process crash it), so it is not the default. qpOASES prints a copyright banner from C when a
solver is created and first run; that output is sent to /dev/null.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from typing import Any

import casadi as ca
import numpy as np

from controllers.base import ControlSpec, raise_if_interrupted, solver_interrupts_held
from controllers.rc_mpc.problem import RCMPC, SolveResult, StageData
from pinn_mpc.errors import InternalError
from pinn_mpc.physics import RCParams

__all__ = ["PLUGIN_OPTIONS", "CasadiMPC"]

#: Per-plugin defaults (silenced output).
PLUGIN_OPTIONS: dict[str, dict[str, Any]] = {
    "highs": {"highs": {"output_flag": False}},
    "osqp": {"osqp": {"verbose": False, "eps_abs": 1e-7, "eps_rel": 1e-7, "polish": True}},
    "qrqp": {"print_iter": False, "print_header": False, "print_info": False},
    "proxqp": {},
    "daqp": {},
    "qpoases": {"printLevel": "none"},
}


class CasadiMPC(RCMPC):
    """RC MPC via ``casadi.qpsol`` (by default with a Kalman observer for the hidden ``T_m``).

    ``plugin`` picks the QP solver; ``solver_options`` update its defaults (e.g. for
    ``qpoases`` ``{"nWSR": 1}`` allows one working-set change, so the solve stops before the
    optimum: a real failure that exercises the fallback).
    """

    name = "casadi-mpc"

    def __init__(
        self, params: RCParams, spec: ControlSpec, *, plugin: str = "qpoases", **options: Any
    ) -> None:
        """``options``: the keywords of :class:`controllers.rc_mpc.problem.RCMPC`."""
        if plugin not in PLUGIN_OPTIONS or not ca.has_conic(plugin):
            raise ValueError(
                f"CasadiMPC: QP plugin {plugin!r} is not available; use one of "
                f"{[p for p in PLUGIN_OPTIONS if ca.has_conic(p)]}"
            )
        self.plugin = plugin
        self._qp: dict[str, Any] | None = None  # built by _build(), after the first reset()
        super().__init__(params, spec, **options)

    def _build(self) -> None:
        options = dict(PLUGIN_OPTIONS[self.plugin])
        for key, value in self.solver_options.items():
            options[key] = {**options.get(key, {}), **value} if isinstance(value, dict) else value
        options["error_on_fail"] = False
        prob = self.problem
        h, dt_h = prob.horizon_steps, self.spec.dt_h
        ad, _ = prob.matrices
        b_u = prob.b_u_c_per_kw
        p = ca.SX.sym("heat_kw", h)
        s = ca.SX.sym("slack_k", h)
        price = ca.SX.sym("price_eur_per_kwh", h)
        ad_ca, bu_ca = ca.DM(ad), ca.DM(b_u)
        # Condensed: T_r[j+1] = free[j] + (S p)[j]; the rollout from a zero state gives S p,
        # the free response (initial state and exogenous inputs) enters the bounds each step.
        x = ca.SX.zeros(2, 1)
        forced = []
        for j in range(h):
            x = ca.mtimes(ad_ca, x) + bu_ca * p[j]
            forced.append(x[0])
        t_r_forced = ca.vertcat(*forced)
        f = dt_h * (
            ca.dot(price, p)
            + self.spec.comfort_weight_eur_per_kh * ca.sum1(s)
            + prob.regularisation_eur_per_kw2h * ca.sumsqr(p)
        )
        qp = {
            "x": ca.vertcat(p, s),
            "p": price,
            "f": f,
            "g": ca.vertcat(t_r_forced + s, t_r_forced - s),
        }
        self._qp, self._options = qp, options
        self._new_solver()
        self._slack_bounds = np.zeros(h), np.full(h, np.inf)
        self._warm: dict[str, np.ndarray] | None = None

    def _new_solver(self) -> None:
        """A fresh solver: qpOASES keeps a hot-start memory inside the CasADi function."""
        if self._qp is None:
            raise InternalError("CasadiMPC: a solver asked for before its problem was built")
        with _quiet_c_stdout():
            self._solver = ca.qpsol("casadi_mpc", self.plugin, self._qp, self._options)
        self._first_call = True

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._warm = None
        if self._qp is not None:  # reset() runs once before _build()
            self._new_solver()

    def _solve(self, stage: StageData) -> SolveResult:
        h = self.problem.horizon_steps
        free = self.problem.rollout(stage, np.zeros(h))[:, 0]
        inf = np.full(h, np.inf)
        heat_min, heat_max = stage.heat_bounds_kw(self.spec.actuator)
        slack_min, slack_max = self._slack_bounds
        args: dict[str, Any] = {
            # The decision is the delivered heat (problem module docstring).
            "p": stage.heat_price_eur_per_kwh,
            "lbx": np.concatenate([heat_min, slack_min]),
            "ubx": np.concatenate([heat_max, slack_max]),
            "lbg": np.concatenate([stage.objective.t_min_c - free, -inf]),
            "ubg": np.concatenate([inf, stage.objective.t_max_c - free]),
        }
        if self._warm is not None:
            args.update(self._warm)
        with solver_interrupts_held():
            if self._first_call:
                with _quiet_c_stdout():
                    sol = self._solver(**args)
                self._first_call = False
            else:
                sol = self._solver(**args)
            # Every call into CasADi (the stats, its matrices' conversions) may hold its own
            # SIGINT handler while it runs: all of them within.
            stats = self._solver.stats()
            w = np.asarray(sol["x"]).reshape(-1)
            lam_x = np.asarray(sol["lam_x"]).reshape(-1)
            lam_g = np.asarray(sol["lam_g"]).reshape(-1)
        raise_if_interrupted(str(stats.get("return_status", "")))
        optimal = bool(stats.get("success", False))
        if optimal:
            self._warm = {"x0": _shift(w, h), "lam_x0": _shift(lam_x, h), "lam_g0": _shift(lam_g, h)}
        return SolveResult(
            p_kw=stage.electrical_kw(w[:h]),
            status=str(stats.get("return_status", "unknown")),
            iterations=int(stats.get("iter_count", stats.get("n_iter", 0)) or 0),
            optimal=optimal,
        )


def _shift(v: np.ndarray, h: int) -> np.ndarray:
    """Shift each length-h block of v one step forward, repeating the last value."""
    blocks = v.reshape(-1, h)
    return np.concatenate([blocks[:, 1:], blocks[:, -1:]], axis=1).reshape(-1)


@contextlib.contextmanager
def _quiet_c_stdout() -> Iterator[None]:
    """Send what C code writes to file descriptor 1 to /dev/null for the duration."""
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no usable fd 1 (e.g. a closed stdout): nothing to silence
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
