"""``qp-mpc``: the RC MPC problem of :mod:`controllers.rc_mpc.problem` in cvxpy, solved by OSQP.

The problem is written once in cvxpy, DPP-parametrised (drift of the states, price, comfort
band, the price and bound of the delivered heat it plans, see the problem module), with the states lifted as variables so the constraint matrix stays sparse (the
clairvoyant uses the same class with the horizon of a whole run). cvxpy canonicalises it once;
since the parameters enter only the linear cost and the constraint bounds, the canonical data
are ``q = Mq theta + cq`` and ``(l, u) = Mb theta + cb`` with constant ``P`` and ``A``. Those
affine maps are read from cvxpy's parametrised program (``ParamConeProg``, the tensors
cvxpy's own DPP solve applies) and checked once against ``Problem.get_problem_data``; each step
then costs two sparse mat-vecs and a warm-started ``osqp.OSQP.update`` + ``solve``, without
cvxpy's per-solve canonicalisation overhead. If the check fails (a cvxpy version with another internal
layout) the controller uses plain ``Problem.solve(solver=OSQP, warm_start=True)`` instead.
"""

from __future__ import annotations

from typing import Any

import cvxpy as cp
import numpy as np
import osqp
import scipy.sparse as sp

from controllers.objective import HorizonObjective
from controllers.rc_mpc.problem import RCMPC, SolveResult, StageData

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
    """RC MPC in cvxpy + OSQP (by default with a Kalman observer for the hidden ``T_m``).

    ``solver_options`` update :data:`OSQP_OPTIONS` (e.g. ``{"max_iter": 1}`` stops OSQP
    before convergence, a real non-optimal status that exercises the fallback).
    """

    name = "qp-mpc"
    _osqp: osqp.OSQP | None

    def _build(self) -> None:
        self.solver_options = {**OSQP_OPTIONS, **self.solver_options}
        prob = self.problem
        h, dt_h = prob.horizon_steps, self.spec.dt_h
        ad, _ = prob.matrices
        b_u = prob.b_u_c_per_kw.reshape(2, 1)
        self._p = cp.Variable(h, name="heat_kw")  # delivered heat (problem module docstring)
        self._s = cp.Variable(h, name="slack_k")
        x = cp.Variable((2, h), name="state_c")
        self._drift = cp.Parameter((2, h), name="drift_c")
        self._price = cp.Parameter(h, name="heat_price_eur_per_kwh")
        self._p_max = cp.Parameter(h, name="heat_max_kw")
        self._t_min = cp.Parameter(h, name="t_min_c")
        self._t_max = cp.Parameter(h, name="t_max_c")
        previous = cp.hstack([np.zeros((2, 1)), x[:, :-1]]) if h > 1 else np.zeros((2, 1))
        constraints = [
            x == ad @ previous + b_u @ cp.reshape(self._p, (1, h), order="C") + self._drift,
            x[0, :] + self._s >= self._t_min,
            x[0, :] - self._s <= self._t_max,
            self._p >= 0.0,
            self._p <= self._p_max,
            self._s >= 0.0,
        ]
        objective = dt_h * (
            self._price @ self._p
            + self.spec.comfort_weight_eur_per_kh * cp.sum(self._s)
            + prob.regularisation_eur_per_kw2h * cp.sum_squares(self._p)
        )
        self._cvx = cp.Problem(cp.Minimize(objective), constraints)
        if not self._cvx.is_dpp():
            raise RuntimeError("qp-mpc problem is not DPP; it would be re-canonicalised each step")
        self._osqp = None
        values = self._parameter_values(_example_stage(prob.horizon_steps))
        for param in self._cvx.parameters():
            param.value = values[param.id]
        self._affine = _AffineOSQP.from_problem(self._cvx, self._p)

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._osqp = None  # a fresh solver: no warm start carried over, runs are reproducible

    def _parameter_values(self, stage: StageData) -> dict[int, np.ndarray]:
        """Values of the cvxpy parameters (by id) for a stage; x0 enters the first drift."""
        ad, _ = self.problem.matrices
        drift = stage.free_c.T.copy()
        drift[:, 0] += ad @ stage.x0_c
        return {
            self._drift.id: drift,
            self._price.id: stage.heat_price_eur_per_kwh,
            self._p_max.id: stage.heat_max_kw(self.problem.u_max_kw),
            self._t_min.id: stage.objective.t_min_c,
            self._t_max.id: stage.objective.t_max_c,
        }

    def _solve(self, stage: StageData) -> SolveResult:
        values = self._parameter_values(stage)
        if self._affine is None:
            heat = self._solve_cvxpy(values)
            return heat._replace(p_kw=stage.electrical_kw(heat.p_kw))
        # Hot path: no cvxpy parameter assignment (its value validation costs milliseconds).
        q, lower, upper = self._affine.data(values)
        if self._osqp is None:
            self._osqp = osqp.OSQP()
            self._osqp.setup(
                P=self._affine.p_upper, q=q, A=self._affine.a, l=lower, u=upper,
                **self.solver_options,
            )
        else:
            self._osqp.update(q=q, l=lower, u=upper)
        result = self._osqp.solve(raise_error=False)
        info = result.info
        if str(info.status) == "solved":
            # Receding horizon: start the next solve from this solution shifted by one step.
            self._osqp.warm_start(
                x=shift_blocks(result.x, self._affine.x_blocks),
                y=shift_blocks(result.y, self._affine.y_blocks),
            )
        return SolveResult(
            p_kw=stage.electrical_kw(np.asarray(result.x)[self._affine.p_slice]),
            status=str(info.status),
            iterations=int(info.iter),
            optimal=str(info.status) == "solved",
        )

    def _solve_cvxpy(self, values: dict[int, np.ndarray]) -> SolveResult:
        for param in self._cvx.parameters():
            param.value = values[param.id]
        self._cvx.solve(solver=cp.OSQP, warm_start=True, **self.solver_options)
        stats = self._cvx.solver_stats
        p = self._p.value
        return SolveResult(
            p_kw=np.full(self.problem.horizon_steps, np.nan) if p is None else np.asarray(p),
            status=str(self._cvx.status),
            iterations=int(stats.num_iters or 0) if stats is not None else 0,
            optimal=self._cvx.status == cp.OPTIMAL,
        )


def _example_stage(h: int) -> StageData:
    """Generic parameter values (all entries distinct) for building and checking the maps."""
    ramp = np.linspace(0.0, 1.0, h)
    return StageData(
        x0_c=np.array([19.0, 18.0]),
        free_c=np.stack([0.1 + 0.05 * ramp, 0.02 - 0.01 * ramp], axis=1),
        objective=HorizonObjective(
            price_eur_per_kwh=0.2 + 0.1 * ramp,
            t_min_c=19.0 + ramp,
            t_max_c=23.0 - ramp,
            dt_h=0.5,
            comfort_weight_eur_per_kh=1.0,
        ),
        cop=2.0 + ramp,
    )


class _AffineOSQP:
    """OSQP data of a DPP problem as affine maps of its parameters (see the module docstring)."""

    def __init__(
        self,
        *,
        param_cols: list[tuple[cp.Parameter, int]],
        n_theta: int,
        q_map: sp.csr_array,
        b_map: sp.csr_array,
        n_zero: int,
        p_upper: sp.csc_matrix,
        a: sp.csc_matrix,
        p_slice: slice,
        x_blocks: list[tuple[int, int]],
        y_blocks: list[tuple[int, int]],
    ) -> None:
        self.param_cols, self.n_theta = param_cols, n_theta
        self.q_map, self.b_map, self.n_zero = q_map, b_map, n_zero
        self.p_upper, self.a, self.p_slice = p_upper, a, p_slice
        self.x_blocks, self.y_blocks = x_blocks, y_blocks

    @classmethod
    def from_problem(cls, problem: cp.Problem, variable: cp.Variable) -> _AffineOSQP | None:
        """Read the maps from cvxpy's parametrised program; None if they do not check out."""
        try:
            data, _, _ = problem.get_problem_data(cp.OSQP)
            pp = data[cp.settings.PARAM_PROB]
            n = int(data["n_var"])
            m = pp.A.shape[0] // (n + 1)
            # Rows of the flattened [A | b] (column-major) that hold b: the last column.
            b_map = sp.csr_array(pp.A)[m * n : m * (n + 1)]
            params = {p.id: p for p in problem.parameters()}
            param_cols = [(params[i], c) for i, c in pp.param_id_to_col.items() if i in params]
            start = pp.var_id_to_col[variable.id]
            h = variable.size
            variables = sorted(pp.variables, key=lambda v: pp.var_id_to_col[v.id])
            # (size, values per step) of each variable / constraint block, for warm-start shifts
            x_blocks = [(v.size, v.size // h) for v in variables]
            y_blocks = [(c.size, c.size // h) for c in pp.constraints]
            affine = cls(
                param_cols=param_cols,
                n_theta=pp.total_param_size + 1,
                q_map=sp.csr_array(pp.q)[:n],
                b_map=b_map,
                n_zero=int(pp.cone_dims.zero),
                p_upper=sp.csc_matrix(sp.triu(data["P"], format="csc")),
                a=sp.csc_matrix(sp.vstack([data["A"], data["F"]], format="csc")),
                p_slice=slice(start, start + variable.size),
                x_blocks=x_blocks,
                y_blocks=y_blocks,
            )
            q, lower, upper = affine.data({p.id: p.value for p in problem.parameters()})
            eq, ineq = data["b"], data["G"]
            ok = (
                np.allclose(q, data["q"], rtol=1e-12, atol=1e-12)
                and np.allclose(lower[: len(eq)], eq, rtol=1e-12, atol=1e-12)
                and np.allclose(upper, np.concatenate([eq, ineq]), rtol=1e-12, atol=1e-12)
                and np.all(np.isneginf(lower[len(eq) :]))
            )
        except (AttributeError, KeyError, IndexError, ValueError, TypeError):
            return None
        return affine if ok else None

    def data(self, values: dict[int, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``q`` (n,), ``l`` and ``u`` (m,) for parameter values given by parameter id."""
        theta = np.zeros(self.n_theta)
        theta[-1] = 1.0
        for param, col in self.param_cols:
            theta[col : col + param.size] = np.asarray(values[param.id], dtype=float).reshape(
                -1, order="F"
            )
        q = self.q_map @ theta
        offset = self.b_map @ theta  # cone form: A x + b in (zero cone, nonnegative cone)
        eq = -offset[: self.n_zero]
        ineq = offset[self.n_zero :]
        lower = np.concatenate([eq, np.full(ineq.shape, -np.inf)])
        upper = np.concatenate([eq, ineq])
        return q, lower, upper


def shift_blocks(v: np.ndarray, blocks: list[tuple[int, int]]) -> np.ndarray:
    """Shift each block (time-major, ``per_step`` values per step) one step, repeating the last."""
    out, start = [], 0
    for size, per_step in blocks:
        block = np.asarray(v[start : start + size]).reshape(-1, max(per_step, 1))
        out.append(np.concatenate([block[1:], block[-1:]]).reshape(-1))
        start += size
    return np.concatenate(out) if start == len(v) else np.asarray(v)
