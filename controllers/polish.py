"""Polish a sampled plan by sequential linear programming on the same model.

Sampling planners find the right shape of a plan but leave it loose: the elites of a few hundred
noisy sequences keep the room a fraction of a kelvin above the lower comfort bound, which costs a
few percent of energy (on the exact 2R2C, CEM alone settles about 4 % above the LP optimum).
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
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.sparse as sp
import torch

from pinn_mpc.errors import InputError

#: Rollout of N demand plans (N, H) [W] -> (T_r (M, N, H) [C], u_phys (M, N, H) [W]).
RolloutFn = Callable[[torch.Tensor], tuple[torch.Tensor, torch.Tensor]]


@dataclass(frozen=True, kw_only=True)
class PolishSettings:
    """Settings of the LP polish (see the module docstring)."""

    iters: int = 1
    delta_frac: float = 0.02
    trust_frac: float = 1.0
    line_search: Sequence[float] = (1.0, 0.5, 0.25)

    def __post_init__(self) -> None:
        if self.iters < 0:
            raise InputError(f"polish iters must be >= 0, got {self.iters}")
        if not 0.0 < self.delta_frac <= 0.5:
            raise InputError(f"polish delta_frac must lie in (0, 0.5], got {self.delta_frac}")
        if not self.trust_frac > 0:
            raise InputError(f"polish trust_frac must be > 0, got {self.trust_frac}")
        if not all(0.0 < a <= 1.0 for a in self.line_search) or not self.line_search:
            raise InputError(f"polish line_search steps must lie in (0, 1], got {self.line_search}")


@dataclass(frozen=True, kw_only=True)
class PlanProblem:
    """What the LP needs of the objective, arrays (H,): price [EUR/kWh], band [C]; scalars."""

    price: np.ndarray
    t_min: np.ndarray
    t_max: np.ndarray
    dt_h: float
    weight: float
    lower: float
    upper: float


def linearise(
    rollout: RolloutFn, u0: torch.Tensor, delta_w: float, upper: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Predictions at ``u0`` (H,) and their sensitivities, one batched rollout of H+1 plans.

    Returns ``t0``, ``p0`` (M, H) and ``jr``, ``jp`` (M, H, H): d(prediction at step j) /
    d(demand at step i) in [K/W] and [W/W]. Each step moves up by ``delta_w``, or down where that
    would leave the bound ``upper``.
    """
    h = u0.shape[0]
    step = torch.where(u0 + delta_w <= upper, delta_w, -delta_w).to(u0.dtype)
    batch = u0.expand(h + 1, h).clone()
    batch[1:] += torch.diag(step)
    t_r, u_phys = rollout(batch)
    t = t_r.double().numpy()
    p = u_phys.double().numpy()
    d = step.double().numpy()
    # (M, H+1, H): row 0 the base plan, row 1+i the plan with step i moved.
    jr = np.swapaxes((t[:, 1:, :] - t[:, :1, :]) / d[None, :, None], 1, 2)
    jp = np.swapaxes((p[:, 1:, :] - p[:, :1, :]) / d[None, :, None], 1, 2)
    return t[:, 0, :], p[:, 0, :], jr, jp


def solve_lp(
    t0: np.ndarray,
    p0: np.ndarray,
    jr: np.ndarray,
    jp: np.ndarray,
    u0: np.ndarray,
    problem: PlanProblem,
    trust_w: float,
) -> np.ndarray | None:
    """The LP of the module docstring; the new plan (H,) [W], or None if HiGHS fails.

    Variables: the change of demand in kW (H,) and one violation slack per member and step.
    """
    m, h = t0.shape
    kw = 1000.0
    energy = problem.price * problem.dt_h  # EUR per kW over each interval
    c_du = np.einsum("j,mji->i", energy, jp) / m  # d(mean cost)/d(du in kW)
    c_s = np.full(m * h, problem.weight * problem.dt_h / m)
    jr_kw = (jr * kw).reshape(m * h, h)
    eye = sp.identity(m * h, format="csr")
    a_ub = sp.vstack(
        [
            sp.hstack([sp.csr_matrix(-jr_kw), -eye]),  # t_min - T <= s
            sp.hstack([sp.csr_matrix(jr_kw), -eye]),  # T - t_max <= s
        ],
        format="csr",
    )
    t_flat = t0.reshape(-1)
    b_ub = np.concatenate(
        [t_flat - np.tile(problem.t_min[:h], m), np.tile(problem.t_max[:h], m) - t_flat]
    )
    lo = np.maximum(problem.lower - u0, -trust_w) / kw
    hi = np.minimum(problem.upper - u0, trust_w) / kw
    bounds = np.concatenate([np.stack([lo, hi], 1), np.tile([0.0, np.inf], (m * h, 1))])
    res = scipy.optimize.linprog(
        np.concatenate([c_du, c_s]), A_ub=a_ub, b_ub=b_ub, bounds=bounds, method="highs"
    )
    if res.status != 0 or res.x is None:
        return None
    return np.clip(u0 + res.x[:h] * kw, problem.lower, problem.upper)


def polish(
    rollout: RolloutFn,
    score: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
    plan: torch.Tensor,
    cost: float,
    problem: PlanProblem,
    settings: PolishSettings,
) -> tuple[torch.Tensor, float, int]:
    """Improve ``plan`` (H,) of objective ``cost``: returns (plan, cost, LPs solved).

    ``score(t_r, u_phys)`` maps predictions (M, N, H) to costs (N,) (the controller's objective).
    """
    span = problem.upper - problem.lower
    solved = 0
    for _ in range(settings.iters):
        t0, p0, jr, jp = linearise(rollout, plan, settings.delta_frac * span, problem.upper)
        u0 = plan.double().numpy()
        target = solve_lp(t0, p0, jr, jp, u0, problem, settings.trust_frac * span)
        if target is None:
            break
        solved += 1
        steps = torch.tensor(settings.line_search, dtype=plan.dtype)[:, None]
        direction = torch.as_tensor(target, dtype=plan.dtype) - plan
        candidates = (plan + steps * direction).clamp(problem.lower, problem.upper)
        costs = score(*rollout(candidates)).double()
        best = int(torch.argmin(costs))
        if not (torch.isfinite(costs[best]) and float(costs[best]) < cost):
            break
        plan, cost = candidates[best].clone(), float(costs[best])
    return plan, cost, solved
