"""The linear MPC problem on RC parameters, shared by ``casadi-mpc``, ``qp-mpc`` and ``oracle``.

Over H control intervals j = 0..H-1, with decision power ``p_j`` [kW] in ``[0, u_max]`` and
comfort slack ``s_j >= 0`` [K]::

    minimise   sum_j  price_j dt_h p_j  +  comfort_weight dt_h s_j  +  rho dt_h p_j^2
    subject to x[j+1] = Ad x[j] + Bd (1000 p_j, T_a,j, G_j, I_g,j)      (exact ZOH, physics.discretise)
               T_min,j - s_j <= T_r[j+1] <= T_max,j + s_j

The first two terms are :func:`controllers.base.plan_cost` with ``s`` as the band violation.
The third, ``rho = regularisation_eur_per_kw2h`` (default 1e-5 EUR per kW^2 h), only makes the
optimum unique (the LP is often degenerate, e.g. under a flat price); at 5 kW for a whole day it
adds 0.006 EUR, so the objective moves by well under 0.1 % in practice. The backup thermostat of
the simulator is not modelled: the MPC plans as if its demand is always delivered.

Forecast arrays may be longer than H (the first H are used) or shorter (the last value is
repeated). Steps after ``n_active`` (the clairvoyant's run end) have zero price and a band so
wide it never binds, so the regulariser turns the heater off there.

:class:`RCMPCBase` is the controller shell both solvers share: state estimation (a Kalman
observer fed from ``obs.history``), timing, status checks and the fallback.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from controllers.base import (
    ControlSpec,
    Forecast,
    Observation,
    SolveStats,
    check_heating,
    fallback_power,
    first_values,
    planning_band,
)
from pinn_mpc.errors import InputError
from pinn_mpc.observer import KalmanObserver
from pinn_mpc.physics import RCParams, discretise

#: Comfort band used after the run end (clairvoyant): never binds.
OPEN_BAND_C = (-100.0, 200.0)
DEFAULT_REGULARISATION = 1e-4


class StageData(NamedTuple):
    """Numeric data of one solve, all (H,) unless noted; powers in kW."""

    x0_c: np.ndarray  # (2,) initial (T_r, T_m) [C]
    free_c: np.ndarray  # (H, 2) state drift per step from exogenous inputs [C]
    price_eur_per_kwh: np.ndarray
    t_min_c: np.ndarray
    t_max_c: np.ndarray


@dataclass(frozen=True, kw_only=True)
class RCProblem:
    """Problem data for horizon ``horizon_steps``; the matrices come from physics.discretise."""

    params: RCParams
    spec: ControlSpec
    horizon_steps: int
    regularisation_eur_per_kw2h: float = DEFAULT_REGULARISATION

    def __post_init__(self) -> None:
        if self.horizon_steps < 1:
            raise InputError(f"RCProblem.horizon_steps must be >= 1, got {self.horizon_steps}")
        rho = self.regularisation_eur_per_kw2h
        if not (math.isfinite(rho) and rho > 0):
            raise InputError(f"regularisation_eur_per_kw2h must be > 0 (uniqueness), got {rho!r}")
        check_heating(self.params.eta, self.spec, what="the RC parameters")

    @cached_property
    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """``Ad`` (2, 2) and ``Bd`` (2, 4) of the control interval."""
        return discretise(self.params, self.spec.dt_s)

    @cached_property
    def b_u_c_per_kw(self) -> np.ndarray:
        """(2,) state change per kW held over one interval [K/kW]."""
        return self.matrices[1][:, 0] * 1000.0

    @property
    def u_max_kw(self) -> float:
        return self.spec.u_max_w / 1000.0

    def stage(self, x0_c: np.ndarray, forecast: Forecast, *, n_active: int | None = None) -> StageData:
        """Numeric data for a solve from state x0 (2,) and the forecast."""
        h = self.horizon_steps
        _, bd = self.matrices
        exog = np.stack(
            [first_values(a, h) for a in (forecast.t_a_c, forecast.g_w_per_m2, forecast.i_g_w)], axis=1
        )
        price = first_values(forecast.price_eur_per_kwh, h)
        t_min, t_max = planning_band(forecast, h)
        if n_active is not None and n_active < h:
            price[n_active:] = 0.0
            t_min[n_active:], t_max[n_active:] = OPEN_BAND_C
        x0 = np.asarray(x0_c, dtype=float).reshape(2)
        if not np.all(np.isfinite(x0)):
            raise FloatingPointError(f"state estimate is not finite: {x0}")
        return StageData(
            x0_c=x0, free_c=exog @ bd[:, 1:].T, price_eur_per_kwh=price, t_min_c=t_min, t_max_c=t_max
        )

    def rollout(self, stage: StageData, p_kw: np.ndarray) -> np.ndarray:
        """States at the end of each interval (H, 2) [C] for plan p (H,) [kW]."""
        ad, _ = self.matrices
        b_u = self.b_u_c_per_kw
        x = stage.x0_c
        out = np.empty((len(p_kw), 2))
        for j, p in enumerate(p_kw):
            x = ad @ x + b_u * p + stage.free_c[j]
            out[j] = x
        return out

    def objective(self, stage: StageData, p_kw: np.ndarray) -> float:
        """Objective of plan p (H,) [kW] without the regulariser [EUR] (= plan_cost)."""
        t_r = self.rollout(stage, p_kw)[:, 0]
        violation = np.maximum(stage.t_min_c - t_r, 0.0) + np.maximum(t_r - stage.t_max_c, 0.0)
        dt_h = self.spec.dt_h
        energy = float(np.sum(stage.price_eur_per_kwh * p_kw)) * dt_h
        return energy + self.spec.comfort_weight_eur_per_kh * dt_h * float(np.sum(violation))


class SolveResult(NamedTuple):
    p_kw: np.ndarray  # (H,) planned power [kW]
    status: str
    iterations: int
    optimal: bool


class RCMPCBase:
    """Shared controller shell: observer, timing, checks, fallback.

    Subclasses give ``_build`` (called once at the end of ``__init__``) and ``_solve``;
    ``solver_options`` are handed to the solver (their meaning is the subclass's).

    Fallback (on an exception in the solve, a non-optimal status or a non-finite plan): act on
    the previous plan shifted by the number of steps since it was made, if one exists and is
    not exhausted, else :func:`controllers.base.fallback_power`. ``last_stats.fallback`` is
    then True and ``n_fallbacks`` counts the events since ``reset``.
    """

    name = "rc-mpc"

    def __init__(
        self,
        params: RCParams,
        spec: ControlSpec,
        *,
        horizon_steps: int | None = None,
        regularisation_eur_per_kw2h: float = DEFAULT_REGULARISATION,
        observer_options: dict[str, Any] | None = None,
        solver_options: dict[str, Any] | None = None,
    ) -> None:
        self.params = params
        self.spec = spec
        self.solver_options = dict(solver_options or {})
        self.problem = RCProblem(
            params=params,
            spec=spec,
            horizon_steps=spec.horizon_steps if horizon_steps is None else horizon_steps,
            regularisation_eur_per_kw2h=regularisation_eur_per_kw2h,
        )
        self.observer = KalmanObserver(params, spec.dt_s, **(observer_options or {}))
        self.reset()
        self._build()

    # -- protocol -------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> None:
        """Forget the observer state, the previous plan and the counters (no randomness used)."""
        self._k_seen: int | None = None
        self._plan_w: np.ndarray | None = None
        self._plan_age = 0
        self._stats = SolveStats(time_s=0.0, status="not run", iterations=0, fallback=False)
        self.n_fallbacks = 0
        self.state_estimate_c = np.full(2, np.nan)

    @property
    def last_plan(self) -> np.ndarray | None:
        """(H,) planned power [W] of the last successful solve, or None."""
        return None if self._plan_w is None else self._plan_w.copy()

    @property
    def last_stats(self) -> SolveStats:
        return self._stats

    def act(self, obs: Observation, forecast: Forecast) -> float:
        start = time.perf_counter()
        self.state_estimate_c = self._estimate_state(obs)
        status, iterations = "error", 0
        try:
            stage = self.problem.stage(self.state_estimate_c, forecast, n_active=self._n_active(obs))
            result = self._solve(stage)
            status, iterations = result.status, result.iterations
            p = np.asarray(result.p_kw, dtype=float)
            if not result.optimal or p.shape != (self.problem.horizon_steps,):
                raise RuntimeError(f"solver status {status!r}")
            if not np.all(np.isfinite(p)):
                raise FloatingPointError("solver returned a non-finite plan")
        except Exception as exc:  # any solver failure acts through the fallback, never raises
            action = self._fallback(obs, forecast)
            self.n_fallbacks += 1
            self._stats = SolveStats(
                time_s=time.perf_counter() - start,
                status=f"{status}: {type(exc).__name__}: {exc}",
                iterations=iterations,
                fallback=True,
            )
            return action
        self._plan_w = np.clip(p, 0.0, self.problem.u_max_kw) * 1000.0
        self._plan_age = 0
        self._stats = SolveStats(
            time_s=time.perf_counter() - start, status=status, iterations=iterations, fallback=False
        )
        return float(self._plan_w[0])

    # -- hooks ----------------------------------------------------------------------------
    def _build(self) -> None:
        """Build the solver once (``self.problem``, ``self.solver_options`` are set)."""
        raise NotImplementedError

    def _solve(self, stage: StageData) -> SolveResult:
        raise NotImplementedError

    def _n_active(self, obs: Observation) -> int | None:
        return None

    def _estimate_state(self, obs: Observation) -> np.ndarray:
        """Feed the observer every interval since the previous call from ``obs.history``.

        ``history`` arrays end at step k (``T_r``, exogenous) or k-1 (``u_phys``), so step i is
        read from the end. A first call, a jump back in k or too short a history restart the
        observer at the measured ``T_r`` with ``T_m`` guessed equal to it.
        """
        hist, k = obs.history, obs.k

        def at(name: str, i: int, last: int) -> float:
            values = hist.get(name)
            return 0.0 if values is None else float(values[len(values) - 1 - (last - i)])

        first = k + 1 if self._k_seen is None else self._k_seen + 1
        n_new = k - first + 1
        if self._k_seen is None or n_new < 0 or n_new > min(len(hist["T_r"]) - 1, len(hist["u_phys"])):
            self.observer.reset(obs.t_r_c)
        else:
            for i in range(first, k + 1):
                self.observer.predict(
                    at("u_phys", i - 1, k - 1),
                    at("T_a", i - 1, k),
                    at("G", i - 1, k),
                    at("I_g", i - 1, k),
                )
                self.observer.update(at("T_r", i, k))
        self._k_seen = k
        return self.observer.state[0]

    def _fallback(self, obs: Observation, forecast: Forecast) -> float:
        if self._plan_w is not None and self._plan_age + 1 < len(self._plan_w):
            self._plan_age += 1
            return float(self._plan_w[self._plan_age])
        self._plan_w = None
        return float(fallback_power(obs, forecast, self.spec))
