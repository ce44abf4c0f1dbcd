"""``qp-mpc``: the RC MPC problem of :mod:`controllers.rc_mpc.problem`, solved by OSQP.

The problem's OSQP data are those of :mod:`controllers.rc_mpc.qp` for one building, the
one-building case of the fleet's (:class:`controllers.fleet.FleetQPMPC`), in its ``SPLIT``
layout (one row per inequality: value for value cvxpy's canonical form of the problem, in
which this controller's results were made): ``P`` and ``A`` built once, ``q``, ``l`` and ``u``
each step from the stage (the states' drift, the price and bound of the delivered heat, the
comfort band), then a warm-started ``osqp.OSQP.update`` + ``solve``. The states are variables,
so the clairvoyant, which uses the same class with the horizon of a whole run, keeps a sparse
constraint matrix.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import osqp

from controllers.base import raise_if_interrupted, solver_interrupts_held
from controllers.rc_mpc.problem import RCMPC, SolveResult, StageData
from controllers.rc_mpc.qp import (
    SPLIT,
    VARIABLES_PER_STEP,
    qp_matrices,
    qp_vectors,
    shift_steps,
)

__all__ = ["OSQP_OPTIONS", "QPMPC"]

#: OSQP settings. The problem is nearly an LP, where ADMM needs many iterations for tight
#: tolerances; moderate tolerances plus polishing (which recovers the exact active set) give
#: the first action within a few W of an exact active-set solver at a fraction of the time.
OSQP_OPTIONS: dict[str, Any] = {
    "eps_abs": 1e-3,
    "eps_rel": 1e-3,
    "max_iter": 10000,
    "polishing": True,
    "verbose": False,
}


class QPMPC(RCMPC):
    """RC MPC with OSQP (by default with a Kalman observer for the hidden ``T_m``).

    ``solver_options`` update :data:`OSQP_OPTIONS` (e.g. ``{"max_iter": 1}`` stops OSQP
    before convergence, a real non-optimal status that exercises the fallback).
    """

    name = "qp-mpc"
    _osqp: osqp.OSQP | None

    def _build(self) -> None:
        self.solver_options = {**OSQP_OPTIONS, **self.solver_options}
        prob = self.problem
        ad, _ = prob.matrices
        p_diag = 2.0 * self.spec.dt_h * prob.regularisation_eur_per_kw2h
        self._p_upper, self._a = qp_matrices(
            ad[None], prob.b_u_c_per_kw[None], prob.horizon_steps, p_diag, SPLIT
        )
        self._osqp = None

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._osqp = None  # a fresh solver: no warm start carried over, runs are reproducible

    def _solve(self, stage: StageData) -> SolveResult:
        h = self.problem.horizon_steps
        ad, _ = self.problem.matrices
        drift = stage.free_c.copy()
        drift[0] += ad @ stage.x0_c
        q, lower, upper = (
            v[0]
            for v in qp_vectors(
                drift[None], stage.heat_price_eur_per_kwh, stage.heat_max_kw(self.problem.u_max_kw), stage.objective, SPLIT
            )
        )
        if self._osqp is None:
            self._osqp = osqp.OSQP()
            self._osqp.setup(P=self._p_upper, q=q, A=self._a, l=lower, u=upper, **self.solver_options)
        else:
            self._osqp.update(q=q, l=lower, u=upper)
        with solver_interrupts_held():
            result = self._osqp.solve(raise_error=False)
        info = result.info
        raise_if_interrupted(str(info.status))
        if str(info.status) == "solved":
            # Receding horizon: start the next solve from this solution shifted by one step.
            self._osqp.warm_start(
                x=shift_steps(np.asarray(result.x), VARIABLES_PER_STEP, h),
                y=shift_steps(np.asarray(result.y), SPLIT.rows_per_step, h),
            )
        return SolveResult(
            p_kw=stage.electrical_kw(np.asarray(result.x)[:h]),
            status=str(info.status),
            iterations=int(info.iter),
            optimal=str(info.status) == "solved",
        )
