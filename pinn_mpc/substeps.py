"""The simulator's inner loop: minute substeps with the backup thermostat, compiled with numba.

One control interval of B buildings. Per building the 2x2 update and the backup rule of
:func:`pinn_mpc.simulator.backup_power` run in registers, substep after substep, so the interval
costs one pass over memory instead of some twenty numpy passes per substep (about twice the
throughput of the numpy loop it replaced; ``benchmarks/bench_simulator.py`` measures it).
The arithmetic is the numpy loop's, term by term, in float64.

Imported lazily by :class:`pinn_mpc.simulator.Simulator` so that modules which never step a
simulator do not pay numba's import. ``cache=True`` keeps the compiled kernel next to this
file (or in numba's user cache when that is read-only), so only the first process compiles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["integrate_interval"]


@njit(cache=True, nogil=True)
def _cycling_substeps(demand: float, lower_w: float, min_power_w: float, n_sub: int) -> int:
    """Substeps on at ``min_power_w`` for a demand between off (``lower_w``) and it, or -1
    (run at the demand)."""
    if lower_w < demand < min_power_w:
        return int(np.rint(demand / min_power_w * n_sub))
    return -1


@njit(cache=True, nogil=True, inline="always")
def _substep_power(
    j: int,
    demand: float,
    n_on: int,
    min_power_w: float,
    t_r_c: float,
    backup_low_c: float,
    backup_high_c: float,
    heating: bool,
    lower_w: float,
    upper_w: float,
) -> tuple[float, float]:
    """(the machine's demand in substep j, the power after the backup rule); ``lower_w`` and
    ``upper_w`` the actuator's bounds (off and full power)."""
    # Below the minimum modulation the machine cycles (on, then off) within the interval.
    if n_on >= 0:
        demand = min_power_w if j < n_on else lower_w
    # Paper Eq. backup (mirrored for a cooling machine), re-evaluated every substep.
    p = demand
    if t_r_c < backup_low_c:
        p = upper_w if heating else lower_w
    elif t_r_c > backup_high_c:
        p = lower_w if heating else upper_w
    return demand, p


@njit(cache=True, nogil=True)
def integrate_interval(
    x: np.ndarray,
    u: np.ndarray,
    exog: np.ndarray,
    ad: np.ndarray,
    bd: np.ndarray,
    gain: np.ndarray,
    min_power_w: float,
    lower_w: float,
    upper_w: float,
    backup_low_c: float,
    backup_high_c: float,
    heating: bool,
    delivered_w: np.ndarray,
    overridden: np.ndarray,
    t_r_sub_c: np.ndarray,
) -> None:
    """Advance ``x`` (B, 2) in place over ``t_r_sub_c.shape[1]`` substeps.

    ``u`` (B,) demand [W], already within the actuator's ``[lower_w, upper_w]``; ``exog`` (B, 3) ``(T_a, G, I_g)``;
    ``ad`` (P, 2, 2) and ``bd`` (P, 2, 4) the substep ZOH matrices, P = 1 (shared) or B (one
    per building); ``gain`` (B,) the actuator's heat per electrical watt this interval (1 for
    the ideal heater: ``b * 1.0`` is ``b`` exactly, so that path is unchanged); a demand in
    (0, ``min_power_w``) cycles: the machine runs at ``min_power_w`` for the first
    ``round(n u / min_power_w)`` substeps, then is off (:mod:`pinn_mpc.actuator`). Writes ``delivered_w`` (B,) the interval-mean power, ``overridden`` (B,)
    and ``t_r_sub_c`` (B, n) the room temperature at the end of each substep.
    """
    n_buildings = x.shape[0]
    n_sub = t_r_sub_c.shape[1]
    shared = ad.shape[0] == 1
    for i in range(n_buildings):
        q = 0 if shared else i
        a00, a01, a10, a11 = ad[q, 0, 0], ad[q, 0, 1], ad[q, 1, 0], ad[q, 1, 1]
        b0, b1 = bd[q, 0, 0] * gain[i], bd[q, 1, 0] * gain[i]
        # Exogenous inputs are held over the interval: their effect is one constant per state.
        d0 = bd[q, 0, 1] * exog[i, 0] + bd[q, 0, 2] * exog[i, 1] + bd[q, 0, 3] * exog[i, 2]
        d1 = bd[q, 1, 1] * exog[i, 0] + bd[q, 1, 2] * exog[i, 1] + bd[q, 1, 3] * exog[i, 2]
        x0, x1, demand = x[i, 0], x[i, 1], u[i]
        n_on = _cycling_substeps(demand, lower_w, min_power_w, n_sub)
        total, changed = 0.0, False
        for j in range(n_sub):
            demand, p = _substep_power(
                j, demand, n_on, min_power_w, x0, backup_low_c, backup_high_c, heating, lower_w, upper_w
            )
            changed = changed or p != demand
            total += p
            x0, x1 = a00 * x0 + a01 * x1 + b0 * p + d0, a10 * x0 + a11 * x1 + b1 * p + d1
            t_r_sub_c[i, j] = x0
        x[i, 0], x[i, 1] = x0, x1
        delivered_w[i] = total / n_sub
        overridden[i] = changed


@njit(cache=True, nogil=True)
def integrate_interval_n(
    x: np.ndarray,
    u: np.ndarray,
    exog: np.ndarray,
    ad: np.ndarray,
    bd: np.ndarray,
    gain: np.ndarray,
    min_power_w: float,
    lower_w: float,
    upper_w: float,
    backup_low_c: float,
    backup_high_c: float,
    heating: bool,
    delivered_w: np.ndarray,
    overridden: np.ndarray,
    t_r_sub_c: np.ndarray,
) -> None:
    """:func:`integrate_interval` for an n-state plant (``x`` (B, n), ``ad`` (P, n, n), ``bd``
    (P, n, 4); state 0 is the room air): the 3R3C of :mod:`pinn_mpc.plant`."""
    n_buildings, n = x.shape
    n_sub = t_r_sub_c.shape[1]
    shared = ad.shape[0] == 1
    d = np.empty(n)
    b = np.empty(n)
    cur = np.empty(n)
    nxt = np.empty(n)
    for i in range(n_buildings):
        q = 0 if shared else i
        for r in range(n):
            b[r] = bd[q, r, 0] * gain[i]
            d[r] = bd[q, r, 1] * exog[i, 0] + bd[q, r, 2] * exog[i, 1] + bd[q, r, 3] * exog[i, 2]
            cur[r] = x[i, r]
        demand = u[i]
        n_on = _cycling_substeps(demand, lower_w, min_power_w, n_sub)
        total, changed = 0.0, False
        for j in range(n_sub):
            demand, p = _substep_power(
                j, demand, n_on, min_power_w, cur[0], backup_low_c, backup_high_c, heating, lower_w, upper_w
            )
            changed = changed or p != demand
            total += p
            for r in range(n):
                acc = b[r] * p + d[r]
                for c in range(n):
                    acc += ad[q, r, c] * cur[c]
                nxt[r] = acc
            for r in range(n):
                cur[r] = nxt[r]
            t_r_sub_c[i, j] = cur[0]
        for r in range(n):
            x[i, r] = cur[r]
        delivered_w[i] = total / n_sub
        overridden[i] = changed
