"""``qp-mpc``: the RC MPC problem of :mod:`controllers.rc_mpc.problem`, solved by OSQP.

:class:`QPBlocks` solves the problem's OSQP data (:mod:`controllers.rc_mpc.qp`) of B buildings,
in blocks of buildings, each block its own warm-started OSQP solver: ``P`` and ``A`` built
once, ``q``, ``l`` and ``u`` each step, then ``osqp.OSQP.update`` + ``solve``, and the solution
shifted one step as the next step's warm start. :class:`QPMPC` is its one-building case, in
the ``SPLIT`` layout (one row per inequality: value for value cvxpy's canonical form of the
problem, in which this controller's results were made); a fleet's
(:class:`controllers.fleet.FleetQPMPC`) is the same solver with a block per building. The
states are variables, so the clairvoyant, which uses the same class with the horizon of a
whole run, keeps a sparse constraint matrix.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any, NamedTuple

import numpy as np
import osqp

from controllers.base import raise_if_interrupted, solver_interrupts_held
from controllers.rc_mpc.problem import RCMPC, SolveResult, StageData
from controllers.rc_mpc.qp import (
    SPLIT,
    VARIABLES_PER_STEP,
    Layout,
    qp_matrices,
    qp_vectors,
    shift_steps,
)

__all__ = ["CANDIDATE_OPTIONS", "OSQP_OPTIONS", "QPMPC", "BlocksSolution", "QPBlocks"]

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

#: OSQP settings of a candidate plan (:meth:`QPBlocks.solve` with ``fast``): a plan that a
#: sampling planner scores among its samples needs no exact optimum, and at these tolerances a
#: warm-started building solves in about 75 iterations instead of 150 (a few in 100 need
#: thousands at the default ones).
CANDIDATE_OPTIONS: dict[str, Any] = {"eps_abs": 1e-2, "eps_rel": 1e-2, "polishing": False, "max_iter": 200}


class BlocksSolution(NamedTuple):
    """A solve of B buildings: ``x`` (B, 4H) each building's variables (NaN where its block
    was not solved), ``solved`` (B,), the ``statuses`` of the blocks solved, the most
    ``iterations`` of any block."""

    x: np.ndarray
    solved: np.ndarray
    statuses: set[str]
    iterations: int


class QPBlocks:
    """The OSQP solves of B buildings' RC MPC problems (module docstring).

    ``ad`` (B, 2, 2) and ``b_u_c_per_kw`` (B, 2) each building's ZOH, ``h`` the horizon,
    ``p_diag`` the heat's diagonal of ``P`` (2 dt_h rho), ``layout`` the rows';
    ``solver_options`` OSQP's settings; ``block_size`` buildings per solver, ``threads`` the
    threads the blocks' solves are dealt out to (OSQP releases the GIL while it solves).
    """

    def __init__(
        self,
        ad: np.ndarray,
        b_u_c_per_kw: np.ndarray,
        h: int,
        p_diag: float,
        layout: Layout,
        solver_options: dict[str, Any],
        *,
        block_size: int = 1,
        threads: int = 1,
    ) -> None:
        b = ad.shape[0]
        if not (isinstance(block_size, int) and block_size >= 1):
            raise ValueError(f"block_size must be a whole number >= 1, got {block_size!r}")
        if not (isinstance(threads, int) and threads >= 1):
            raise ValueError(f"threads must be a whole number >= 1, got {threads!r}")
        self.h, self.layout, self.solver_options, self.threads = h, layout, solver_options, threads
        self.n_buildings = b
        self.blocks = [slice(i, min(i + block_size, b)) for i in range(0, b, block_size)]
        self._matrices = [qp_matrices(ad[s], b_u_c_per_kw[s], h, p_diag, layout) for s in self.blocks]
        self.reset()

    def reset(self) -> None:
        """Forget the solvers (so no warm start is carried over) and their solutions."""
        n = len(self.blocks)
        self._solvers: list[osqp.OSQP | None] = [None] * n
        self._fast = [False] * n
        self._solutions: list[tuple[np.ndarray, np.ndarray] | None] = [None] * n
        self._status: list[str] = [""] * n

    def solve(
        self,
        q: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        *,
        only: np.ndarray | None = None,
        fast: bool = False,
    ) -> BlocksSolution:
        """Solve the blocks for OSQP's ``q``, ``l``, ``u`` (B, ...) of :func:`qp_vectors`
        (``only`` (B,) bool: the blocks of these buildings only), each from its last solution
        (or the warm start :meth:`shift` set); ``fast``: to :data:`CANDIDATE_OPTIONS`."""
        todo = [j for j, block in enumerate(self.blocks) if only is None or np.any(only[block])]

        def solve(j: int) -> tuple[str, int]:
            block = self.blocks[j]
            data = {"q": q[block].reshape(-1), "l": lower[block].reshape(-1), "u": upper[block].reshape(-1)}
            solver = self._solvers[j]
            if solver is None:
                solver = self._solvers[j] = osqp.OSQP()
                p_upper, a = self._matrices[j]
                solver.setup(P=p_upper, A=a, **data, **self.solver_options)
            else:
                solver.update(**data)
            if fast != self._fast[j]:
                settings = CANDIDATE_OPTIONS if fast else {k: self.solver_options[k] for k in CANDIDATE_OPTIONS}
                solver.update_settings(**settings)
                self._fast[j] = fast
            result = solver.solve(raise_error=False)
            self._solutions[j] = (np.asarray(result.x, dtype=float), np.asarray(result.y, dtype=float))
            self._status[j] = str(result.info.status)
            return self._status[j], int(result.info.iter)

        # The threads are started with Ctrl-C held back, so they hold it back too.
        threads = min(self.threads, len(todo))
        with solver_interrupts_held():
            if threads > 1:
                with ThreadPoolExecutor(threads) as pool:
                    parts = list(pool.map(lambda js: [solve(j) for j in js], [todo[i::threads] for i in range(threads)]))
                results = [parts[i % threads][i // threads] for i in range(len(todo))]
            else:
                results = [solve(j) for j in todo]
        for status, _ in results:
            raise_if_interrupted(status)
        x = np.full((self.n_buildings, 4 * self.h), np.nan)
        solved = np.zeros(self.n_buildings, dtype=bool)
        for j, (status, _) in zip(todo, results, strict=True):
            if status == "solved":
                block = self.blocks[j]
                solution = self._solutions[j]
                assert solution is not None  # solve() stored it
                x[block] = solution[0].reshape(-1, 4 * self.h)
                solved[block] = True
        iterations = max((it for _, it in results), default=0)
        return BlocksSolution(x, solved, {status for status, _ in results}, iterations)

    def shift(self, *, solved_only: bool = False) -> None:
        """Each block's last solution, shifted one step, as its solver's warm start (receding
        horizon): a block not solved for some steps starts from its solution shifted by as
        many steps. ``solved_only``: only the blocks whose last solve was solved (the others
        start from where their solver stopped)."""
        for j, (block, solver, solution) in enumerate(zip(self.blocks, self._solvers, self._solutions, strict=True)):
            if solver is None or solution is None or not np.all(np.isfinite(solution[0])):
                continue
            if solved_only and self._status[j] != "solved":
                continue
            n = block.stop - block.start
            x, y = solution
            shifted = (
                shift_steps(x.reshape(n, -1), VARIABLES_PER_STEP, self.h).reshape(-1),
                shift_steps(y.reshape(n, -1), self.layout.rows_per_step, self.h).reshape(-1),
            )
            self._solutions[j] = shifted
            solver.warm_start(x=shifted[0], y=shifted[1])


class QPMPC(RCMPC):
    """RC MPC with OSQP (by default with a Kalman observer for the hidden ``T_m``).

    ``solver_options`` update :data:`OSQP_OPTIONS` (e.g. ``{"max_iter": 1}`` stops OSQP
    before convergence, a real non-optimal status that exercises the fallback).
    """

    name = "qp-mpc"
    _solver: QPBlocks | None = None

    def _build(self) -> None:
        self.solver_options = {**OSQP_OPTIONS, **self.solver_options}
        prob = self.problem
        ad, _ = prob.matrices
        p_diag = 2.0 * self.spec.dt_h * prob.regularisation_eur_per_kw2h
        self._solver = QPBlocks(
            ad[None], prob.b_u_c_per_kw[None], prob.horizon_steps, p_diag, SPLIT, self.solver_options
        )

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        if self._solver is not None:  # a fresh solver: no warm start carried over, runs are reproducible
            self._solver.reset()

    def _solve(self, stage: StageData) -> SolveResult:
        h = self.problem.horizon_steps
        ad, _ = self.problem.matrices
        drift = stage.free_c.copy()
        drift[0] += ad @ stage.x0_c
        q, lower, upper = qp_vectors(
            drift[None], stage.heat_price_eur_per_kwh, stage.heat_bounds_kw(self.spec.actuator), stage.objective, SPLIT
        )
        assert self._solver is not None  # _build() made it
        solution = self._solver.solve(q, lower, upper)
        # Receding horizon: start the next solve from this solution shifted by one step.
        self._solver.shift(solved_only=True)
        (status,) = solution.statuses
        return SolveResult(
            p_kw=stage.electrical_kw(solution.x[0, :h]),
            status=status,
            iterations=solution.iterations,
            optimal=bool(solution.solved[0]),
        )
