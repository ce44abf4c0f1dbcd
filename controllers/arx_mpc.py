"""``qp-mpc`` over an ARX model (:mod:`pinn_mpc.models.arx`): the QP MPC of the linear baseline.

The ARX is linear in its lagged ``T_r`` and power; everything else in it (weather, the weekly
schedule, the physics-informed variant's schedule x ``(T_r - T_a)`` weight) is known over the
horizon from the forecast and its dates. So the horizon's room temperatures are an affine
function of the planned powers, ``T_r = free + gain @ p`` (:meth:`pinn_mpc.models.arx.ARXModel.
prediction_matrices`, rebuilt at every decision), and the objective of every planner
(:class:`controllers.objective.HorizonObjective`: energy cost + comfort weight x band
violation, heater bounds) is, as in :class:`controllers.rc_mpc.osqp.QPMPC`, the QP::

    minimise   dt_h (price @ p + comfort_weight sum(s) + rho |p|^2)
    subject to T_min - s <= free + gain @ p <= T_max + s,   p_min <= p <= p_max,   s >= 0

with ``[p_min, p_max]`` the actuator's bounds (``spec.actuator``), solved by OSQP directly
(variables ``p`` [kW] and ``s`` [K], the constraint matrix dense lower triangular in ``gain``;
its values are updated only when ``gain`` changes, which with the physics-informed ARX's
schedule-dependent heat loss is at every schedule block edge). The regulariser ``rho`` only
makes the optimum unique, as in the RC problem.

No state observer: the ARX's state is its measured history (the last ``lags`` room
temperatures, powers and weather values), which every observation holds. Offset-free as the
sampling planners are: :class:`controllers.estimators.OffsetFilter` filters the error of the
model's one-step prediction of the interval that just ended into an offset added to every
predicted ``T_r`` (``offset_gain``, 0.5 as ``cem`` uses). The power is electrical, as the
ARX was fitted on the data's ``u_phys`` (with a heat pump its COP is in the coefficients).

Fallback (never an exception out of ``act``): a history shorter than the model's lags, a solver
status other than solved, a non-finite plan or any other error acts through
:class:`controllers.base.Fallback` with the previous plan; ``last_stats.fallback`` is True and
``n_fallbacks`` counts the events since ``reset``, as for ``QPMPC``.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp

from controllers.base import (
    ControlSpec,
    Fallback,
    Forecast,
    Observation,
    PlanningController,
    SolveStats,
    check_heating,
    first_values,
    raise_if_interrupted,
    solver_interrupts_held,
)
from controllers.estimators import OffsetFilter
from controllers.objective import HorizonObjective
from controllers.rc_mpc.osqp import OSQP_OPTIONS
from controllers.rc_mpc.problem import DEFAULT_REGULARISATION
from controllers.rc_mpc.qp import shift_steps
from pinn_mpc.errors import InputError
from pinn_mpc.features import check_interval
from pinn_mpc.models.arx import ARXModel

__all__ = ["ARXQPMPC"]


class ARXQPMPC(PlanningController):
    """QP MPC over an :class:`~pinn_mpc.models.arx.ARXModel` (module docstring).

    ``solver_options`` update :data:`controllers.rc_mpc.osqp.OSQP_OPTIONS`; ``offset_gain``
    as :class:`controllers.estimators.OffsetFilter` (0 plans on the model alone).
    """

    name = "qp-mpc"

    def __init__(
        self,
        model: ARXModel,
        spec: ControlSpec,
        *,
        horizon_steps: int | None = None,
        offset_gain: float = 0.5,
        comfort_margin_k: float = 0.0,
        regularisation_eur_per_kw2h: float = DEFAULT_REGULARISATION,
        solver_options: dict[str, Any] | None = None,
        name: str | None = None,
    ) -> None:
        check_heating(model.eta, spec, what="the ARX model")
        check_interval(model.dt_s, spec.dt_s, what="the scenario's control interval is")
        self.horizon_steps = spec.horizon_steps if horizon_steps is None else horizon_steps
        if self.horizon_steps < 1:
            raise ValueError(f"ARXQPMPC.horizon_steps must be >= 1, got {self.horizon_steps}")
        if not (np.isfinite(regularisation_eur_per_kw2h) and regularisation_eur_per_kw2h > 0):
            raise ValueError(
                "regularisation_eur_per_kw2h must be > 0 (uniqueness), "
                f"got {regularisation_eur_per_kw2h!r}"
            )
        if name is not None:
            self.name = name
        self.model, self.spec = model, spec
        self.rho = regularisation_eur_per_kw2h
        if not (0 <= comfort_margin_k < 1):
            raise ValueError(f"ARXQPMPC.comfort_margin_k must lie in [0, 1) K, got {comfort_margin_k}")
        self.comfort_margin_k = comfort_margin_k
        self.solver_options = {**OSQP_OPTIONS, **(solver_options or {})}
        self.estimator = OffsetFilter(model, offset_gain)
        self.fallback = Fallback(spec, reuse_plan=True)
        self._pattern = _Pattern(self.horizon_steps)
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        """Forget the offset, the previous plan, the solver and its warm start (no randomness)."""
        self.estimator.reset()
        self.fallback.reset()
        self._osqp: osqp.OSQP | None = None
        self._gain_kw: np.ndarray | None = None
        self._stats = SolveStats(time_s=0.0, status="not run", iterations=0, fallback=False)
        self.last_prediction_c = np.full(self.horizon_steps, np.nan)

    def act(self, obs: Observation, forecast: Forecast) -> float:
        start = time.perf_counter()
        status, iterations = "error", 0
        try:
            offset = self.estimator.update(obs)
            objective = HorizonObjective.from_forecast(
                forecast, self.spec, self.horizon_steps
            ).tightened(self.comfort_margin_k)
            free, gain = self.prediction(obs, forecast)
            p, status, iterations = self._solve(objective, free + offset, gain * 1000.0)
            if status != "solved":
                raise RuntimeError(f"solver status {status!r}")
            if not np.all(np.isfinite(p)):
                raise FloatingPointError("solver returned a non-finite plan")
        except Exception as exc:  # any failure acts through the fallback, never raises
            return self._failed(obs, forecast, start, f"{status}: {type(exc).__name__}: {exc}", iterations)
        plan_w = self.spec.actuator.clip_kw(p) * 1000.0
        self.last_prediction_c = free + offset + gain @ plan_w
        return self._succeeded(plan_w, start, status, iterations)

    def prediction(self, obs: Observation, forecast: Forecast) -> tuple[np.ndarray, np.ndarray]:
        """The affine map ``T_r = free + gain @ u`` (h,), (h, h) [C, K/W] of the horizon from
        this observation (offset not included)."""
        h = self.horizon_steps
        names = self.model.exog_names
        if "day_of_week" in names and forecast.day_of_week is None:
            raise InputError("the forecast has no calendar (day_of_week) that the ARX needs")
        fields = forecast._asdict()
        exog = {name: first_values(fields[name], h) for name in names}
        return self.model.prediction_matrices(obs.history, exog, h)

    def _solve(
        self, objective: HorizonObjective, free: np.ndarray, gain_kw: np.ndarray
    ) -> tuple[np.ndarray, str, int]:
        """OSQP on ``z = (p [kW], s [K])``: the plan (h,) [kW], the status and iterations."""
        h, dt_h = self.horizon_steps, self.spec.dt_h
        inf = np.full(h, np.inf)
        q = dt_h * np.concatenate(
            [objective.price_eur_per_kwh, np.full(h, self.spec.comfort_weight_eur_per_kh)]
        )
        actuator = self.spec.actuator
        lower = np.concatenate([objective.t_min_c - free, -inf, np.full(h, actuator.lower_kw), np.zeros(h)])
        upper = np.concatenate([inf, objective.t_max_c - free, np.full(h, actuator.upper_kw), inf])
        if not np.all(np.isfinite(np.concatenate([q, free, gain_kw.ravel(), objective.t_min_c, objective.t_max_c]))):
            raise FloatingPointError("non-finite QP data (forecast or model)")
        values = self._pattern.values(gain_kw)
        if self._osqp is None:
            self._osqp = osqp.OSQP()
            p_diag = np.concatenate([np.full(h, 2.0 * dt_h * self.rho), np.zeros(h)])
            self._osqp.setup(
                P=sp.csc_matrix(sp.diags(p_diag)), q=q, A=self._pattern.matrix(values),
                l=lower, u=upper, **self.solver_options,
            )
        else:
            self._osqp.update(q=q, l=lower, u=upper)
            if self._gain_kw is None or not np.array_equal(gain_kw, self._gain_kw):
                self._osqp.update(Ax=values)
        self._gain_kw = gain_kw
        with solver_interrupts_held():
            result = self._osqp.solve(raise_error=False)
        status = str(result.info.status)
        raise_if_interrupted(status)
        if status == "solved":  # receding horizon: start the next solve shifted by one step
            self._osqp.warm_start(
                x=shift_steps(np.asarray(result.x), (1, 1), h), y=shift_steps(np.asarray(result.y), (1,) * 4, h)
            )
        return np.asarray(result.x)[:h], status, int(result.info.iter)


class _Pattern:
    """The fixed sparsity of the QP's constraint matrix (CSC, explicit zeros kept)::

        [[gain,  I],    T_r + s >= T_min
         [gain, -I],    T_r - s <= T_max
         [I,     0],    p_min <= p <= p_max   (the actuator's bounds)
         [0,     I]]    s >= 0

    ``gain`` lower triangular, so its structure is fixed and only its values change."""

    def __init__(self, h: int) -> None:
        eye, zero, tril = np.eye(h), np.zeros((h, h)), np.tril(np.ones((h, h)))
        mask = sp.csc_matrix(np.block([[tril, eye], [tril, eye], [eye, zero], [zero, eye]]))
        self.h, self.indices, self.indptr = h, mask.indices, mask.indptr
        self.columns = np.repeat(np.arange(2 * h), np.diff(mask.indptr))

    def values(self, gain_kw: np.ndarray) -> np.ndarray:
        """The matrix's nonzero values in CSC order for ``gain_kw`` (h, h) [K/kW]."""
        eye, zero = np.eye(self.h), np.zeros((self.h, self.h))
        dense = np.block([[gain_kw, eye], [gain_kw, -eye], [eye, zero], [zero, eye]])
        return dense[self.indices, self.columns]

    def matrix(self, values: np.ndarray) -> sp.csc_matrix:
        return sp.csc_matrix((values, self.indices, self.indptr), shape=(4 * self.h, 2 * self.h))

