"""Polish a sampled plan by sequential linear programming on the same model.

Sampling planners find the right shape of a plan but leave it loose: the elites of a few hundred
noisy sequences keep the room a fraction of a kelvin above the lower comfort bound, which costs a
few percent of energy.
The objective is piecewise linear in the model's predictions, and the models here are smooth in
the demanded power, so one linearisation around the sampled plan and one LP close that gap:

1. **Linearise** with finite differences in one batch: the plan and H copies of it with one step
   moved by ``delta_w`` are rolled out together (all members, one :meth:`rollout` call), which
   gives the sensitivities of the predicted ``T_r`` and ``u_phys`` of every member to every
   step's demand.
2. **LP**: minimise the ensemble-mean objective of the linearised predictions (price x delivered
   energy + comfort weight x band violation, the violation as a slack per member and step) over
   the demand within its bounds and a trust region of ``trust_frac`` x range around the plan.
   Solved with HiGHS (:func:`scipy.optimize.linprog`).
3. **Accept** only on the true model: the LP plan and steps of ``line_search`` towards it are
   rolled out in one batch and scored with the controller's own objective; the best is kept only
   if it beats the sampled plan. So the polish never makes a plan worse on the model.

This is sequential linear programming (successive linearisation MPC) applied to the learned
model; it needs no gradients of the network, only batched rollouts.

A learned model's rollout costs a fixed time per horizon step plus a smaller part per plan, so
the polish rides along with the planner's own objective calls (:class:`PiggybackPolish`): the
probes around the warm start join the planner's first batch, the line-search plans its second;
only what is left over after the planner's last call costs a rollout of its own. With CEM's two
iterations, polishing adds no rollout at all.

:class:`ZonePolish` is the same over plans of several actuators (H, A) and predictions of
several zones: every step of every actuator probed, the LP's rows each zone's temperature at
each step (:func:`solve_lp` with R = H x Z rows and P = H x A columns). A model that gives its
response to the plan (:meth:`pinn_mpc.models.rollout.BatchDynamics.linear_response`: the
multi-zone RC's matrices, exact where no backup thermostat switches) is not probed: the LP
keeps the states as variables (:func:`solve_state_lp`, the same optimum with a sparse matrix),
and a plan of more than :data:`MAX_LP_PLAN` steps x actuators is solved as a QP by OSQP,
warm-started from one decision to the next (:class:`StateQP`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.optimize
import scipy.sparse as sp
import torch

from controllers.base import solver_interrupts_held
from controllers.objective import HorizonObjective

if TYPE_CHECKING:
    from pinn_mpc.models.rollout import LinearResponse

__all__ = [
    "MAX_LP_PLAN",
    "POLISH_REGULARISATION_EUR_PER_KW2H",
    "PiggybackPolish",
    "PlanProblem",
    "PolishSettings",
    "RolloutFn",
    "StateQP",
    "ZonePolish",
    "jacobians",
    "probes",
    "solve_lp",
    "solve_state_lp",
    "zone_probes",
]

#: Rollout of N demand plans (N, H) [W] -> (T_r (M, N, H) [C], u_phys (M, N, H) [W]).
RolloutFn = Callable[[torch.Tensor], tuple[torch.Tensor, torch.Tensor]]
#: The polish LP over a model's response: (response, plan (H, A), W per plan unit (A,), problem,
#: trust) -> the new plan (H, A), or None (:func:`solve_state_lp`, :meth:`StateQP.solve`).
StateSolver = Callable[["LinearResponse", np.ndarray, np.ndarray, "PlanProblem", float], "np.ndarray | None"]


@dataclass(frozen=True, kw_only=True)
class PolishSettings:
    """Settings of the LP polish (see the module docstring)."""

    iters: int = 1
    probe_stride: int = 4
    delta_frac: float = 0.02
    trust_frac: float = 1.0
    line_search: Sequence[float] = (1.0, 0.5, 0.25)

    def __post_init__(self) -> None:
        if self.iters < 0:
            raise ValueError(f"polish iters must be >= 0, got {self.iters}")
        if self.probe_stride < 1:
            raise ValueError(f"polish probe_stride must be >= 1, got {self.probe_stride}")
        if not 0.0 < self.delta_frac <= 0.5:
            raise ValueError(f"polish delta_frac must lie in (0, 0.5], got {self.delta_frac}")
        if not self.trust_frac > 0:
            raise ValueError(f"polish trust_frac must be > 0, got {self.trust_frac}")
        if not all(0.0 < a <= 1.0 for a in self.line_search) or not self.line_search:
            raise ValueError(f"polish line_search steps must lie in (0, 1], got {self.line_search}")


@dataclass(frozen=True, kw_only=True)
class PlanProblem:
    """What the LP needs: the horizon objective and the plan's bounds (the demand's [W]; the
    fractions of each actuator's range, 0 and 1, of a plan of several actuators with the zones'
    objective)."""

    objective: HorizonObjective
    lower: float
    upper: float


def probes(
    u0: torch.Tensor, delta_w: float, upper: float, stride: int = 1
) -> tuple[torch.Tensor, torch.Tensor]:
    """``u0`` (H,) and copies with one step moved by ``delta_w`` (down where up would leave
    ``upper``), every ``stride``-th step: the batch (1 + ceil(H/stride), H) and the signed
    steps (H,) (zero where not probed)."""
    h = u0.shape[0]
    step = torch.where(u0 + delta_w <= upper, delta_w, -delta_w).to(u0.dtype)
    probed = torch.arange(0, h, stride)
    step = torch.zeros_like(step).index_copy_(0, probed, step[probed])
    batch = u0.expand(len(probed) + 1, h).clone()
    batch[1:] += torch.diag(step)[probed]
    return batch, step


def jacobians(
    t_r: torch.Tensor, u_phys: torch.Tensor, step: torch.Tensor
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Predictions (M, 1+P, H) of a :func:`probes` batch -> ``t0``, ``p0`` (M, H) at ``u0`` and
    ``jr``, ``jp`` (M, H, H): d(prediction at step j) / d(demand at step i), [K/W] and [W/W].

    A step i between probed steps takes the response of the nearest probed step p <= i shifted
    by i - p (the impulse response of a slowly varying system; exact for a linear
    time-invariant model, whatever the stride).
    """
    t = t_r.double().numpy()
    p = u_phys.double().numpy()
    d = step.double().numpy()
    probed = np.flatnonzero(d)
    m, h = t.shape[0], t.shape[2]
    # Responses (M, P, H) of the probed steps, per watt.
    resp_t = (t[:, 1:, :] - t[:, :1, :]) / d[probed][None, :, None]
    resp_p = (p[:, 1:, :] - p[:, :1, :]) / d[probed][None, :, None]
    jr = np.zeros((m, h, h))
    jp = np.zeros((m, h, h))
    owner = np.searchsorted(probed, np.arange(h), side="right") - 1  # probe index per step
    for i in range(h):
        q, lag = owner[i], i - probed[owner[i]]
        jr[:, i:, i] = resp_t[:, q, probed[q] : h - lag]
        jp[:, i:, i] = resp_p[:, q, probed[q] : h - lag]
    return t[:, 0, :], p[:, 0, :], jr, jp


def _constraint_matrix(jr_kw: np.ndarray) -> sp.csr_matrix:
    """``[[-J, -I], [J, -I]]`` in CSR for the sensitivities ``jr_kw`` (R, H) [K/kW]: rows
    ``t_min - T <= s`` then ``T - t_max <= s``. The nonzeros of J (it is lower triangular)
    and the slack's -1 last in each row, built directly: scipy's hstack/vstack of the same
    blocks give this matrix but cost a millisecond per decision."""
    r, h = jr_kw.shape
    aug = np.concatenate([jr_kw, np.ones((r, 1))], axis=1)  # the slack's column last
    keep = aug != 0
    keep[:, h] = True
    rows, cols = np.nonzero(keep)  # row-major: sorted by row, then column
    slack = cols == h
    j = aug[rows, cols]
    indptr = np.concatenate([[0], np.cumsum(keep.sum(axis=1))])
    cols = np.where(slack, h + rows, cols)
    return sp.csr_matrix(
        (
            np.concatenate([np.where(slack, -1.0, -j), np.where(slack, -1.0, j)]),
            np.concatenate([cols, cols]),
            np.concatenate([indptr, indptr[1:] + len(rows)]),
        ),
        shape=(2 * r, h + r),
    )


def solve_lp(
    t0: np.ndarray,
    jr: np.ndarray,
    jp: np.ndarray,
    u0: np.ndarray,
    problem: PlanProblem,
    trust_w: float,
    *,
    unit: float = 1000.0,
) -> np.ndarray | None:
    """The LP of the module docstring; the new plan (P,), or None if HiGHS fails.

    ``t0`` (M, R) the predicted temperatures at the plan ``u0`` (P,): one zone's (R = P = H,
    the plan in W), or each zone's step by step (R = H x Z, :class:`ZonePolish`); ``jr`` (M, R,
    P) their sensitivities to the plan, ``jp`` (M, H, P) the delivered power's [W per plan
    unit]; the bands are the objective's, flattened to R. Variables: the change of the plan in
    units of ``unit`` (kW of a plan in W) (P,) and one violation slack per member and row.
    The energy term is linear in the change, so the predicted power at ``u0`` drops out.
    """
    m, r = t0.shape
    n_plan = u0.shape[0]
    obj = problem.objective
    energy = obj.price_eur_per_kwh * obj.dt_h  # EUR per kW over each interval
    c_du = np.einsum("j,mji->i", energy, jp) / m * (unit / 1000.0)  # d(mean cost)/d(du in units)
    c_s = np.full(m * r, obj.comfort_weight_eur_per_kh * obj.dt_h / m)
    a_ub = _constraint_matrix((jr * unit).reshape(m * r, n_plan))
    t_flat = t0.reshape(-1)
    t_min, t_max = obj.t_min_c.reshape(-1)[:r], obj.t_max_c.reshape(-1)[:r]
    b_ub = np.concatenate([t_flat - np.tile(t_min, m), np.tile(t_max, m) - t_flat])
    lo = np.maximum(problem.lower - u0, -trust_w) / unit
    hi = np.minimum(problem.upper - u0, trust_w) / unit
    bounds = np.concatenate([np.stack([lo, hi], 1), np.tile([0.0, np.inf], (m * r, 1))])
    with solver_interrupts_held():
        res = scipy.optimize.linprog(
            np.concatenate([c_du, c_s]), A_ub=a_ub, b_ub=b_ub, bounds=bounds, method="highs"
        )
    if res.status != 0 or res.x is None:
        return None
    return np.clip(u0 + res.x[:n_plan] * unit, problem.lower, problem.upper)


def solve_state_lp(
    response: LinearResponse, u0: np.ndarray, scale_w: np.ndarray, problem: PlanProblem, trust: float
) -> np.ndarray | None:
    """The LP of :func:`solve_lp` for a plan of several actuators ``u0`` (H, A) (in the plan's
    units, ``scale_w`` (A,) W per unit) over a model's :class:`~pinn_mpc.models.rollout.LinearResponse`
    at it, with the states as variables instead of the dense sensitivities: the change of the
    plan (H, A), the state's change after each interval (H, S), free, tied to it by the
    response's recursion (equality rows), and a violation slack per zone and step. The same
    optimum as :func:`solve_lp` on the response's :meth:`~pinn_mpc.models.rollout.LinearResponse.jacobians`
    (the states eliminated), with a constraint matrix of O(H (S^2 + S A)) nonzeros instead of
    O(H^2 Z A). The new plan (H, A), or None if HiGHS fails."""
    h, a_n = u0.shape
    z_n, s_n = response.t_r_c.shape[1], response.a.shape[0]
    obj = problem.objective
    n_u, n_x = h * a_n, h * s_n
    energy = np.broadcast_to(obj.price_eur_per_kwh * obj.dt_h, (h,))  # EUR per kW over each interval
    c_u = (energy[:, None] * response.power * scale_w / 1000.0).reshape(-1)
    c_s = np.full(h * z_n, obj.comfort_weight_eur_per_kh * obj.dt_h)
    b = response.b * scale_w  # (H, S, A) per plan unit
    # Equalities: dx_j - a dx_(j-1) - b_j du_j = 0, row j S + s.
    eq_rows = np.arange(n_x).reshape(h, s_n)
    rows_b = np.broadcast_to(eq_rows[:, :, None], (h, s_n, a_n))
    cols_b = np.broadcast_to((np.arange(n_u).reshape(h, 1, a_n)), (h, s_n, a_n))
    rows_a = np.broadcast_to(eq_rows[1:, :, None], (h - 1, s_n, s_n))
    cols_a = n_u + np.broadcast_to(np.arange(n_x - s_n).reshape(h - 1, 1, s_n), (h - 1, s_n, s_n))
    a_eq = sp.csr_matrix(
        (
            np.concatenate([-b.reshape(-1), np.ones(n_x), np.broadcast_to(-response.a, (h - 1, s_n, s_n)).reshape(-1)]),
            (
                np.concatenate([rows_b.reshape(-1), np.arange(n_x), rows_a.reshape(-1)]),
                np.concatenate([cols_b.reshape(-1), n_u + np.arange(n_x), cols_a.reshape(-1)]),
            ),
        ),
        shape=(n_x, n_u + n_x + h * z_n),
    )
    a_eq.eliminate_zeros()  # zones without walls between them: a block-diagonal transition
    # Comfort: t_min - t0 - dx_j[room] <= s and dx_j[room] + t0 - t_max <= s, row (j, z).
    r = np.arange(h * z_n)
    room_cols = n_u + (np.arange(h)[:, None] * s_n + response.rooms[None, :]).reshape(-1)
    slack_cols = n_u + n_x + r
    a_ub = sp.csr_matrix(
        (
            np.concatenate([-np.ones(h * z_n), -np.ones(h * z_n), np.ones(h * z_n), -np.ones(h * z_n)]),
            (np.concatenate([r, r, h * z_n + r, h * z_n + r]), np.concatenate([room_cols, slack_cols, room_cols, slack_cols])),
        ),
        shape=(2 * h * z_n, n_u + n_x + h * z_n),
    )
    t0 = response.t_r_c.reshape(-1)
    b_ub = np.concatenate([t0 - obj.t_min_c.reshape(-1), obj.t_max_c.reshape(-1) - t0])
    flat = u0.reshape(-1)
    bounds = np.concatenate([
        np.stack([np.maximum(problem.lower - flat, -trust), np.minimum(problem.upper - flat, trust)], 1),
        np.tile([-np.inf, np.inf], (n_x, 1)),
        np.tile([0.0, np.inf], (h * z_n, 1)),
    ])
    with solver_interrupts_held():
        res = scipy.optimize.linprog(
            np.concatenate([c_u, np.zeros(n_x), c_s]), A_ub=a_ub, b_ub=b_ub, A_eq=a_eq,
            b_eq=np.zeros(n_x), bounds=bounds, method="highs",
        )
    if res.status != 0 or res.x is None:
        return None
    return np.clip(flat + res.x[:n_u], problem.lower, problem.upper).reshape(h, a_n)


#: The largest plan (steps x actuators) whose polish LP HiGHS solves (:func:`solve_state_lp`);
#: a larger one is solved as a QP by OSQP, warm-started (:class:`StateQP`). HiGHS's time grows
#: about as the plan's square (a building of 15 zones and 30 actuators over 48 steps: 1,440
#: columns), OSQP's with its nonzeros, its factorisation kept from decision to decision.
MAX_LP_PLAN = 192
#: The polish QP's regulariser [EUR per (kW of heat)^2 h] (the multi-zone QP MPC's default): it
#: makes the optimum unique and costs a millionth of a euro per kW moved.
POLISH_REGULARISATION_EUR_PER_KW2H = 1e-4
#: OSQP's statuses whose solution the polish takes: its line search keeps a plan only where it
#: beats the sampled one on the model, so a solution stopped at the iteration limit is a
#: direction as good as the iterations got.
QP_USABLE = ("solved", "solved inaccurate", "maximum iterations reached")
#: OSQP's settings of the polish: the QP MPC's (:data:`controllers.rc_mpc.osqp.OSQP_OPTIONS`)
#: with at most :data:`POLISH_MAX_ITER` iterations, the decision's time bound.
POLISH_MAX_ITER = 200


def _state_sources(
    a: np.ndarray, b_heat: np.ndarray, h: int, a_n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which of a state-space system's states (``dx_j = a dx_(j-1) + b_heat dq_j``) are
    variables of :class:`StateQP`'s QP, and what every state of every step stands for there:
    ``free`` (F,) the states that are variables, then ``col`` (H, S) the QP column each state
    of each step is (its own for a free state; -1 for none) and ``coef`` (H, S) its factor. A
    state whose row of ``a`` is a single 1 and of ``b_heat`` zero delays another by one step
    (it is that state's column one step earlier, none before the first); one whose row of ``a``
    is zero and of ``b_heat`` a single value copies that actuator's heat variable of the step
    (times 1000 x the value, the QP's heat being in kW)."""
    s_n = a.shape[0]
    in_a, in_b = a != 0, b_heat != 0
    origin, heat = np.argmax(in_a, axis=1), np.argmax(in_b, axis=1)  # each row's first nonzero
    delay = (in_a.sum(1) == 1) & (a[np.arange(s_n), origin] == 1.0) & ~in_b.any(1)
    copy = ~in_a.any(1) & (in_b.sum(1) == 1)
    free = np.flatnonzero(~(delay | copy))
    col = np.full((h, s_n), -1, dtype=np.int64)
    coef = np.zeros((h, s_n))
    delayed, origin = np.flatnonzero(delay), origin[delay]
    copied, heat = np.flatnonzero(copy), heat[copy]
    n_u = h * a_n
    for j in range(h):
        col[j, free], coef[j, free] = n_u + j * len(free) + np.arange(len(free)), 1.0
        if j:
            col[j, delayed], coef[j, delayed] = col[j - 1, origin], coef[j - 1, origin]
        col[j, copied], coef[j, copied] = j * a_n + heat, 1000.0 * b_heat[copied, heat]
    return free, col, coef


class StateQP:
    """The LP of :func:`solve_state_lp` as a QP solved by OSQP, for a plan too large for HiGHS
    (:data:`MAX_LP_PLAN`), kept across a controller's decisions. The variables are the change
    of each actuator's heat (H, A) [kW] (its demand's change times its heat per W, so the
    matrix does not move with the COP: the price of heat is the price over it, and an actuator
    the backup forces has bounds 0), the state's change (H, S) but for the states that only
    delay another or copy a heat (:func:`_state_sources`: an ARX's lagged rooms and heats, which
    are earlier steps' rooms and this step's heats: of the medium office ARX's 150 states, its 15
    rooms) and the slacks (H, Z); the
    regulariser :data:`POLISH_REGULARISATION_EUR_PER_KW2H` on the heat's change. The matrix is
    built and factorised once per horizon and building; each solve updates the vectors and
    starts from no change, with the last solve's duals shifted one step, and stops after
    ``warm_max_iter`` iterations (the first solve after a setup after ``options``' ``max_iter``).
    ``options`` update :data:`controllers.rc_mpc.osqp.OSQP_OPTIONS`."""

    def __init__(self, options: dict[str, object] | None = None, *, warm_max_iter: int = POLISH_MAX_ITER) -> None:
        from controllers.rc_mpc.osqp import OSQP_OPTIONS

        if warm_max_iter < 1:
            raise ValueError(f"StateQP.warm_max_iter must be >= 1 (OSQP's iterations), got {warm_max_iter!r}")
        self.options = {**OSQP_OPTIONS, **(options or {})}
        self.warm_max_iter = warm_max_iter
        self.reset()

    def reset(self) -> None:
        """Forget the solver, its matrices and its last duals."""
        self._solver: Any = None
        self._key: tuple[int, bytes, bytes, bytes] | None = None
        self._y: np.ndarray | None = None
        self.last_info: Any = None  # OSQP's info of the last solve
        #: Values a step of the variables (heat, states, slacks) and of the rows (dynamics,
        #: below, above, heat bounds, slack bounds): the warm start's shift.
        self._per_step: tuple[tuple[int, ...], tuple[int, ...]] = ((), ())

    def _setup(
        self,
        response: LinearResponse,
        sources: tuple[np.ndarray, np.ndarray, np.ndarray],
        h: int,
        dt_h: float,
        q: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
    ) -> None:
        """Build the QP's matrices of ``response``'s building over ``h`` steps and set OSQP up.
        A state that only delays another by an interval (the lagged rooms of an ARX) or copies
        one actuator's heat (its lagged heats) is no variable of its own but the one it
        repeats (``sources``, :func:`_state_sources`'s over ``h`` steps): the same QP, its KKT
        system a fraction of the size."""
        import osqp

        a_n, z_n = response.b_heat.shape[1], response.rooms.shape[0]
        free, source_col, source_coef = sources
        f_n = len(free)
        n_u, n_x, n_s = h * a_n, h * f_n, h * z_n
        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []
        vals: list[np.ndarray] = []

        def add(r: np.ndarray, c: np.ndarray, v: np.ndarray | float) -> None:
            r, c, v = np.broadcast_arrays(r, c, v)
            keep = (c >= 0) & (v != 0)
            rows.append(r[keep].reshape(-1))
            cols.append(c[keep].reshape(-1))
            vals.append(v[keep].reshape(-1).astype(float))

        steps = np.arange(h)
        eq = steps[:, None] * f_n + np.arange(f_n)  # (H, F) the rows of dx_j - a dx_(j-1) - B dq_j = 0
        add(eq, n_u + eq, 1.0)
        heat_cols = steps[:, None, None] * a_n + np.arange(a_n)  # (H, 1, A)
        add(eq[:, :, None], heat_cols, -1000.0 * response.b_heat[free][None])
        # dx_(j-1)'s every state, each the column it stands for (-1: none, before the first step)
        add(eq[1:, :, None], source_col[:-1, None, :], -response.a[free][None] * source_coef[:-1, None, :])
        band = n_x + steps[:, None] * z_n + np.arange(z_n)  # (H, Z) below, then above at + n_s
        room, room_coef = source_col[:, response.rooms], source_coef[:, response.rooms]
        slack = n_u + n_x + steps[:, None] * z_n + np.arange(z_n)
        add(band, room, room_coef)
        add(band, slack, 1.0)
        add(band + n_s, room, room_coef)
        add(band + n_s, slack, -1.0)
        add(n_x + 2 * n_s + np.arange(n_u), np.arange(n_u), 1.0)
        add(n_x + 2 * n_s + n_u + np.arange(n_s), n_u + n_x + np.arange(n_s), 1.0)
        n = n_u + n_x + n_s
        a_mat = sp.csc_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n_x + 3 * n_s + n_u, n)
        )
        a_mat.eliminate_zeros()  # zones without walls between them: a block-diagonal transition
        diag = np.zeros(n)
        diag[:n_u] = 2.0 * dt_h * POLISH_REGULARISATION_EUR_PER_KW2H
        self._solver = osqp.OSQP()
        self._solver.setup(P=sp.diags(diag, format="csc"), A=a_mat, q=q, l=lower, u=upper, **self.options)
        self._per_step = ((a_n, f_n, z_n), (f_n, z_n, z_n, a_n, z_n))

    def solve(
        self, response: LinearResponse, u0: np.ndarray, scale_w: np.ndarray, problem: PlanProblem, trust: float
    ) -> np.ndarray | None:
        """The polished plan (H, A) in ``u0``'s units (:func:`solve_state_lp`'s arguments), or
        None when OSQP does not solve it."""
        from controllers.rc_mpc.qp import shift_steps

        h, a_n = u0.shape
        key = (h, response.a.tobytes(), response.b_heat.tobytes(), response.rooms.tobytes())
        fresh = self._solver is None or key != self._key  # a new building or horizon: set up again
        sources = _state_sources(response.a, response.b_heat, h, a_n) if fresh else None
        z_n = response.t_r_c.shape[1]
        s_n = len(sources[0]) if sources is not None else self._per_step[0][1]  # the QP's states a step
        obj = problem.objective
        follows = response.heat_per_w > 0
        heat = np.where(follows, response.heat_per_w, 1.0)  # (H, A) heat per W, 1 where it does not follow
        energy = np.broadcast_to(obj.price_eur_per_kwh * obj.dt_h, (h,))  # EUR per kW over each interval
        q = np.concatenate([
            (energy[:, None] * response.power / heat).reshape(-1),
            np.zeros(h * s_n),
            np.full(h * z_n, obj.comfort_weight_eur_per_kh * obj.dt_h),
        ])
        per_kw = np.where(follows, heat * scale_w / 1000.0, 0.0)  # (H, A) kW of heat per plan unit
        lo = np.maximum(problem.lower - u0, -trust) * per_kw
        hi = np.minimum(problem.upper - u0, trust) * per_kw
        t0 = response.t_r_c.reshape(-1)
        inf = np.full(h * z_n, np.inf)
        lower = np.concatenate([np.zeros(h * s_n), obj.t_min_c.reshape(-1) - t0, -inf, lo.reshape(-1), np.zeros(h * z_n)])
        upper = np.concatenate([np.zeros(h * s_n), inf, obj.t_max_c.reshape(-1) - t0, hi.reshape(-1), inf])
        with solver_interrupts_held():
            if sources is not None:
                self._setup(response, sources, h, float(np.mean(obj.dt_h)), q, lower, upper)
                self._key = key
            else:
                self._solver.update(q=q, l=lower, u=upper)
                self._solver.update_settings(max_iter=self.warm_max_iter)
                x0 = np.zeros(len(q))
                if self._y is not None:
                    self._solver.warm_start(x=x0, y=shift_steps(self._y, self._per_step[1], h))
                else:
                    self._solver.warm_start(x=x0)
            result = self._solver.solve(raise_error=False)
        x, y = np.asarray(result.x, dtype=float), np.asarray(result.y, dtype=float)
        self.last_info = result.info
        if str(result.info.status) not in QP_USABLE or not np.all(np.isfinite(x)):
            self._y = None
            return None
        self._y = y
        du = np.where(follows, x[: h * a_n].reshape(h, a_n) / np.where(follows, per_kw, 1.0), 0.0)
        return np.clip(u0 + du, problem.lower, problem.upper)


class PiggybackPolish:
    """Polish riding on a planner's objective calls (see the module docstring).

    Use :meth:`objective` in place of the plain objective, then :meth:`finish` for the best
    polished plan. ``rollout(u_w)`` gives predictions (M, N, H) and ``score(t_r, u_phys)``
    their costs (N,); ``x0`` (H,) is the plan to linearise around first (the warm start).
    """

    def __init__(
        self,
        rollout: RolloutFn,
        score: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
        problem: PlanProblem,
        settings: PolishSettings,
        x0: torch.Tensor,
    ):
        self.rollout, self.score, self.problem, self.settings = rollout, score, problem, settings
        self.span = problem.upper - problem.lower
        self.best: tuple[torch.Tensor, float] | None = None  # best polish plan and its cost
        self.lps = 0
        self._rounds = settings.iters
        self._pending: torch.Tensor | None = None
        self._step: torch.Tensor | None = None  # set while the pending batch is probes
        if self._rounds > 0:
            self._queue_probes(x0)

    def _queue_probes(self, u0: torch.Tensor) -> None:
        self._rounds -= 1
        self._pending, self._step = self._probes(u0)

    def _probes(self, u0: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The batch that linearises the model around ``u0`` and its signed steps (:func:`probes`)."""
        delta = self.settings.delta_frac * self.span
        return probes(u0, delta, self.problem.upper, self.settings.probe_stride)

    def _target(
        self, batch: torch.Tensor, t_r: torch.Tensor, u_phys: torch.Tensor, step: torch.Tensor
    ) -> np.ndarray | None:
        """The LP's plan from the predictions of the probe batch (None if the LP failed)."""
        t0, _p0, jr, jp = jacobians(t_r, u_phys, step)
        u0 = batch[0].double().numpy()
        return solve_lp(t0, jr, jp, u0, self.problem, self.settings.trust_frac * self.span)

    def objective(self, u_w: torch.Tensor) -> torch.Tensor:
        """Costs (N,) of the planner's batch; pending polish plans are rolled out with it."""
        extra = self._pending
        if extra is None:
            return self.score(*self.rollout(u_w))
        n = u_w.shape[0]
        t_r, u_phys = self.rollout(torch.cat([u_w, extra]))
        costs = self.score(t_r, u_phys)
        self._take(extra, t_r[:, n:], u_phys[:, n:], costs[n:])
        return costs[:n]

    def finish(self) -> tuple[torch.Tensor, float] | None:
        """Roll out what is still pending; the best polish plan and cost (None if none)."""
        while self._pending is not None:
            extra = self._pending
            t_r, u_phys = self.rollout(extra)
            self._take(extra, t_r, u_phys, self.score(t_r, u_phys))
        return self.best

    def _take(
        self, batch: torch.Tensor, t_r: torch.Tensor, u_phys: torch.Tensor, costs: torch.Tensor
    ) -> None:
        self._pending = None
        costs = costs.double()
        self._consider(batch, costs)
        if self._step is None:  # a line search was evaluated: probe around the best again
            if self._rounds > 0 and self.best is not None:
                self._queue_probes(self.best[0])
            return
        step, self._step = self._step, None
        self._search(batch[0], self._target(batch, t_r, u_phys, step))

    def _search(self, u0: torch.Tensor, target: np.ndarray | None, *, with_u0: bool = False) -> None:
        """Queue the line search from ``u0`` towards the LP's plan ``target`` (nothing when the
        LP failed), ``u0`` itself first where ``with_u0``."""
        if target is None:
            return
        self.lps += 1
        alphas = torch.tensor(self.settings.line_search, dtype=u0.dtype).reshape(-1, *[1] * u0.dim())
        direction = torch.as_tensor(target, dtype=u0.dtype) - u0
        lo, hi = self.problem.lower, self.problem.upper
        self._pending = (u0 + alphas * direction).clamp(lo, hi)
        if with_u0:
            self._pending = torch.cat([u0[None], self._pending])

    def _consider(self, batch: torch.Tensor, costs: torch.Tensor) -> None:
        finite = torch.where(torch.isfinite(costs), costs, torch.full_like(costs, float("inf")))
        i = int(torch.argmin(finite))
        if bool(torch.isfinite(finite[i])) and (self.best is None or float(finite[i]) < self.best[1]):
            self.best = (batch[i].clone(), float(finite[i]))


def zone_probes(u0: torch.Tensor, delta: float, upper: float) -> tuple[torch.Tensor, torch.Tensor]:
    """``u0`` (H, A) and a copy with each step of each actuator moved by ``delta`` (down where
    up would leave ``upper``): the batch (1 + H A, H, A), probe ``1 + j A + a`` moving step j
    of actuator a, and the signed steps (H, A)."""
    h, a = u0.shape
    step = torch.where(u0 + delta <= upper, delta, -delta).to(u0.dtype)
    batch = u0.expand(1 + h * a, h, a).clone()
    batch[1:] += torch.diag(step.reshape(-1)).reshape(h * a, h, a)
    return batch, step


class ZonePolish(PiggybackPolish):
    """:class:`PiggybackPolish` of plans of several actuators (H, A) over predictions of
    several zones (T_r (M, N, H, Z), the building's total delivered power (M, N, H)), with
    the zones' objective (:class:`controllers.objective.ZoneObjective`) and the plan in units
    of ``problem``'s bounds (the planners' fractions of each actuator's range). Every step of
    every actuator is probed (``probe_stride`` does not apply: a model with a time-varying
    COP is linearised exactly only so); the LP is :func:`solve_lp` with each zone's
    temperature at each step a row and each step of each actuator a column.

    A model that gives its response to the plan (``linearise``: a plan (H, A) in the plan's
    units -> its :class:`pinn_mpc.models.rollout.LinearResponse` [per W], or None) is not
    probed where it gives one: the LP is ``solve_state`` (:func:`solve_state_lp`, or a
    :class:`StateQP`'s ``solve``) on that response (``scale_w`` (A,): W per plan unit of each
    actuator), solved at once, and its line search, the plan it linearised around first, rides
    along with the planner's next batch."""

    def __init__(
        self,
        rollout: RolloutFn,
        score: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
        problem: PlanProblem,
        settings: PolishSettings,
        x0: torch.Tensor,
        *,
        linearise: Callable[[torch.Tensor], LinearResponse | None] | None = None,
        scale_w: np.ndarray | None = None,
        solve_state: StateSolver | None = None,
    ):
        if (linearise is None) != (scale_w is None):
            raise ValueError("ZonePolish: give linearise and scale_w together (the W per plan unit of each actuator)")
        self.linearise, self.scale_w = linearise, scale_w
        self.solve_state: StateSolver = solve_state_lp if solve_state is None else solve_state
        super().__init__(rollout, score, problem, settings, x0)

    def _queue_probes(self, u0: torch.Tensor) -> None:
        if self.linearise is None or self.scale_w is None:
            super()._queue_probes(u0)
            return
        response = self.linearise(u0)
        if response is None:  # not given at this plan: probe it
            super()._queue_probes(u0)
            return
        self._rounds -= 1
        self._pending = self._step = None
        plan = self.solve_state(
            response, u0.double().numpy(), self.scale_w, self.problem, self.settings.trust_frac * self.span
        )
        self._search(u0, plan, with_u0=True)

    def _probes(self, u0: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return zone_probes(u0, self.settings.delta_frac * self.span, self.problem.upper)

    def _target(
        self, batch: torch.Tensor, t_r: torch.Tensor, u_phys: torch.Tensor, step: torch.Tensor
    ) -> np.ndarray | None:
        t = t_r.double().numpy()  # (M, 1 + P, H, Z)
        p = u_phys.double().numpy()  # (M, 1 + P, H)
        d = step.double().numpy().reshape(-1)  # (P,)
        m, _, h, z_n = t.shape
        jr = np.moveaxis((t[:, 1:] - t[:, :1]) / d[None, :, None, None], 1, -1)  # (M, H, Z, P)
        jp = np.moveaxis((p[:, 1:] - p[:, :1]) / d[None, :, None], 1, -1)  # (M, H, P)
        u0 = batch[0].double().numpy()
        plan = solve_lp(
            t[:, 0].reshape(m, h * z_n), jr.reshape(m, h * z_n, -1), jp, u0.reshape(-1), self.problem,
            self.settings.trust_frac * self.span, unit=1.0,
        )
        return None if plan is None else plan.reshape(u0.shape)
