"""The RC MPC problem of :mod:`controllers.rc_mpc.problem` as OSQP data, for B buildings at once.

One implementation of the QP serves a single building (:class:`controllers.rc_mpc.osqp.QPMPC`,
B = 1) and a fleet (:class:`controllers.fleet.FleetQPMPC`, one block per building). Per
building the variables are, in this order, the delivered heat ``q_j`` [kW], the comfort slack
``s_j`` [K] and the states ``x_j = (T_r, T_m)`` [C] at the end of step j (time-major); the cost
is ``dt_h (price_j / COP_j) q_j + dt_h w s_j + dt_h rho q_j^2`` and the rows::

    x_j - Ad x_{j-1} - b_u q_j = drift_j       (2 per step; x_{-1} = 0, x0's response in drift_0)

then the inequalities in one of two layouts (:data:`SPLIT`, :data:`BOX`), the same problem:

- ``SPLIT``, one row per inequality, as cvxpy canonicalises the problem written with the states
  as variables (the test suite states it in cvxpy and checks the data equal, value for value)::

      -T_r,j - s_j <= -T_min,j,   T_r,j - s_j <= T_max,j,   -q_j <= -q_min,j,   q_j <= q_max,j,   -s_j <= 0

- ``BOX``, each variable's bounds in one two-sided row (OSQP's ``l <= A x <= u``)::

      T_min,j <= T_r,j + s_j,   T_r,j - s_j <= T_max,j,   q_min,j <= q_j <= q_max,j,   0 <= s_j

OSQP's iterates depend on the layout, and ``BOX`` converges in fewer of them on a fleet's
warm-started problems (at tight tolerances ``SPLIT`` may not converge at all), so the fleet
plans in ``BOX``; ``qp-mpc`` keeps ``SPLIT``, in which its recorded results were made.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from controllers.objective import HorizonObjective

__all__ = ["BOX", "SPLIT", "VARIABLES_PER_STEP", "Layout", "qp_matrices", "qp_vectors", "shift_steps"]

#: Variables of a building per step, block by block: heat, slack, the two states.
VARIABLES_PER_STEP = (1, 1, 2)


class Layout(NamedTuple):
    """A layout of the inequality rows (module docstring); ``rows_per_step`` the rows of a
    building per step, block by block (the dynamics' two first)."""

    name: str
    rows_per_step: tuple[int, ...]

    @property
    def rows(self) -> int:
        """Rows of a building per step."""
        return sum(self.rows_per_step)


#: One row per inequality: lower band, upper band, heat >= its lower bound, heat <= its upper
#: bound, slack >= 0.
SPLIT = Layout("split", (2, 1, 1, 1, 1, 1))
#: One two-sided row per bound: lower band, upper band, heat's range, slack >= 0.
BOX = Layout("box", (2, 1, 1, 1, 1))


def qp_matrices(
    ad: np.ndarray, b_u_c_per_kw: np.ndarray, h: int, p_diag: float, layout: Layout
) -> tuple[sp.csc_matrix, sp.csc_matrix]:
    """OSQP's ``P`` (upper triangle) and ``A`` of B buildings over ``h`` steps, block diagonal:
    ``ad`` (B, 2, 2) and ``b_u_c_per_kw`` (B, 2) [K/kW] each building's exact ZOH of the
    interval, ``p_diag`` the heat's diagonal of ``P`` (2 dt_h rho), ``layout`` the rows'."""
    b = ad.shape[0]
    n, m = 4 * h, layout.rows * h
    rows: list[np.ndarray] = []
    cols: list[np.ndarray] = []
    vals: list[np.ndarray] = []  # each (B, len) or broadcastable (1, len)

    def add(r: np.ndarray, c: np.ndarray, v: np.ndarray) -> None:
        rows.append(np.asarray(r))
        cols.append(np.asarray(c))
        vals.append(np.broadcast_to(v, (b, len(np.atleast_1d(r)))))

    j = np.arange(h)
    qi, si = j, h + j
    xi = 2 * h + 2 * j  # T_r of step j; T_m at +1
    ones = np.ones((1, h))
    for r in range(2):
        dyn = 2 * j + r
        add(dyn, xi + r, ones)
        add(dyn, qi, -np.repeat(b_u_c_per_kw[:, r : r + 1], h, axis=1))
        for c in range(2):
            add(dyn[1:], xi[:-1] + c, -np.repeat(ad[:, r, c : c + 1], h - 1, axis=1))
    sign = -1.0 if layout == SPLIT else 1.0  # SPLIT states the lower band as an upper one
    add(2 * h + j, xi, sign * ones)
    add(2 * h + j, si, sign * ones)
    add(3 * h + j, xi, ones)
    add(3 * h + j, si, -ones)
    if layout == SPLIT:
        add(4 * h + j, qi, -ones)
        add(5 * h + j, qi, ones)
        add(6 * h + j, si, -ones)
    else:
        add(4 * h + j, qi, ones)
        add(5 * h + j, si, ones)
    r0, c0 = np.concatenate(rows), np.concatenate(cols)
    v = np.concatenate(vals, axis=1)  # (B, nnz)
    offsets = np.arange(b)[:, None]
    a = sp.csc_matrix(
        (v.reshape(-1), ((r0 + m * offsets).reshape(-1), (c0 + n * offsets).reshape(-1))),
        shape=(b * m, b * n),
    )
    diag = np.zeros(n)
    diag[:h] = p_diag
    p_upper = sp.diags(np.tile(diag, b), format="csc")
    return p_upper, a


def qp_vectors(
    drift_c: np.ndarray,
    heat_price_eur_per_kwh: np.ndarray,
    heat_bounds_kw: tuple[np.ndarray, np.ndarray],
    objective: HorizonObjective,
    layout: Layout,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """OSQP's ``q`` (B, 4H), ``l`` and ``u`` (B, rows H) of B buildings: ``drift_c`` (B, H, 2)
    each step's state drift, x0's response in step 0 [C]; ``heat_price_eur_per_kwh`` (H,) or
    (B, H) the price of delivered heat; ``heat_bounds_kw`` its least and most, (H,) each (the
    actuator's bounds times the COP: ``StageData.heat_bounds_kw``); ``objective`` the band,
    the comfort weight and the interval; ``layout`` the rows'."""
    b, h, _ = drift_c.shape
    heat_min_kw, heat_max_kw = heat_bounds_kw
    dt_h = objective.dt_h
    q = np.zeros((b, 4 * h))
    q[:, :h] = dt_h * heat_price_eur_per_kwh
    q[:, h : 2 * h] = dt_h * objective.comfort_weight_eur_per_kh
    m = layout.rows * h
    lower = np.full((b, m), -np.inf)
    upper = np.zeros((b, m)) if layout == SPLIT else np.full((b, m), np.inf)
    lower[:, : 2 * h] = upper[:, : 2 * h] = drift_c.reshape(b, 2 * h)
    upper[:, 3 * h : 4 * h] = objective.t_max_c
    if layout == SPLIT:
        upper[:, 2 * h : 3 * h] = -objective.t_min_c
        upper[:, 4 * h : 5 * h] -= heat_min_kw  # 0 - q_min: a zero bound stays +0.0
        upper[:, 5 * h : 6 * h] = heat_max_kw
    else:
        lower[:, 2 * h : 3 * h] = objective.t_min_c
        lower[:, 4 * h : 5 * h] = heat_min_kw
        lower[:, 5 * h :] = 0.0
        upper[:, 4 * h : 5 * h] = heat_max_kw
    return q, lower, upper


def shift_steps(v: np.ndarray, per_step: Sequence[int], h: int) -> np.ndarray:
    """Each row of ``v`` (..., sum(per_step) h), blocks time-major with ``per_step`` values a
    step, shifted one step, the last step repeated: a receding horizon's warm start."""
    lead = v.shape[:-1]
    out, start = [], 0
    for k in per_step:
        block = v[..., start : start + k * h].reshape(*lead, h, k)
        out.append(np.concatenate([block[..., 1:, :], block[..., -1:, :]], axis=-2).reshape(*lead, k * h))
        start += k * h
    return np.concatenate(out, axis=-1)
