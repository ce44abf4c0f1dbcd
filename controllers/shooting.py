"""Random shooting and CEM controllers over batched dynamics models (learned or physical).

Every ``act`` builds an objective over candidate demand sequences (N, H) [W] and hands it to a
planner of :mod:`controllers.planners`. The objective rolls all candidates and all ensemble
members out in one :meth:`BatchDynamics.rollout` call under ``torch.no_grad`` and scores them
with exactly :func:`controllers.base.plan_cost`: price x delivered energy + comfort weight x band
violation x dt_h, where *delivered* is the model's predicted ``u_phys`` (so the planner knows
the backup thermostat will override it) and the temperature is the predicted ``T_r`` at the end
of each interval.

Three defaults matter in closed loop (measured on winter_household, see the issue notes):

- ``ensemble="mean"``: the members' mean prediction is scored (a seed ensemble as one point
  predictor). ``"members"`` scores each member and averages the costs, plus ``risk_weight`` x
  their std: it plans for every member, so the members' spread (a few tenths of a kelvin)
  becomes a comfort margin paid for in energy.
- ``offset_gain=0.5``: offset-free MPC. Each decision first predicts the interval that just
  ended from the history one interval earlier and the power actually delivered; the error
  against the measured ``T_r`` is filtered into an offset added to every predicted ``T_r``.
  It removes the slowly varying bias a learned model has in closed-loop operating points.
- CEM polishes its plan with one LP on the linearised model (:mod:`controllers.polish`),
  which takes a plan the last few percent to the optimum of the model; random shooting does
  not (``polish_iters``), so it stays the plain sampling baseline.

The plan is warm-started from the previous plan shifted by one step (its last action
repeated); the first plan starts from half power.

Fallback (never an exception out of ``act``): when the history is shorter than the model needs
(``depth + 1`` past intervals), when the model returns a non-finite value, or when anything
else fails, the controller returns :func:`controllers.base.fallback_power` (the band-keeping
rule on the measured room temperature), sets ``last_stats.fallback=True`` with the reason in
``status``, clears ``last_plan`` and restarts the next warm start from scratch.

Speed: a rollout is a few small tensor ops per horizon step for the whole batch, so its time
is mostly a fixed cost per step and grows slowly with the number of candidates; iterations
are what cost. On a shared 2-core machine one intra-op thread is fastest
(``torch.set_num_threads(1)`` in the caller).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import NamedTuple, Protocol

import numpy as np
import torch

from controllers.base import (
    ControlSpec,
    Forecast,
    Observation,
    SolveStats,
    check_heating,
    fallback_power,
    planning_band,
)
from controllers.planners import CEMPlanner, Planner, RandomShootingPlanner
from controllers.polish import PiggybackPolish, PlanProblem, PolishSettings, RolloutFn
from pinn_mpc.errors import InputError
from pinn_mpc.features import check_interval
from pinn_mpc.physics import RCParams, discretise

#: How ensemble members enter the objective: "mean" scores the members' average prediction (a
#: seed ensemble as one point predictor); "members" averages the members' costs (plus
#: ``risk_weight`` x their std), which plans for every member and so hedges against their spread.
ENSEMBLE_MODES = ("mean", "members")

#: Model exogenous input name -> Forecast field.
FORECAST_FIELDS = {
    "time_of_day_h": "time_of_day_h",
    "T_a": "t_a_c",
    "G": "g_w_per_m2",
    "I_g": "i_g_w",
}


class RolloutLike(Protocol):
    """Predictions for M members x N candidates x H intervals."""

    @property
    def t_r_c(self) -> torch.Tensor: ...  # (M, N, H) room temperature at interval ends [C]

    @property
    def u_phys_w(self) -> torch.Tensor: ...  # (M, N, H) delivered power [W]


class BatchDynamics(Protocol):
    """What a planner needs of a model (pinn_mpc's LearnedModel and :class:`RCBatchModel`).

    ``rollout(history, u_w, exog)``: ``history`` as in :class:`controllers.base.Observation`,
    ``u_w`` (N, H) demanded power [W], ``exog`` one array (H,) per name in ``exog_names``.
    The model needs ``depth + 1`` past intervals of history. ``eta`` (heat per W of actuator
    power, < 0 cooling) and ``dt_s`` (the interval it steps) must match the scenario's.
    """

    @property
    def n_members(self) -> int: ...

    @property
    def eta(self) -> float: ...

    @property
    def dt_s(self) -> float: ...

    @property
    def depth(self) -> int: ...

    @property
    def exog_names(self) -> tuple[str, ...]: ...

    def rollout(
        self, history: dict[str, np.ndarray], u_w: torch.Tensor, exog: dict[str, np.ndarray]
    ) -> RolloutLike: ...


class _Rollout:
    """Concrete rollout of :class:`RCBatchModel`: tensors (1, N, H)."""

    def __init__(self, t_r_c: torch.Tensor, u_phys_w: torch.Tensor, t_m_c: torch.Tensor):
        self.t_r_c, self.u_phys_w, self.t_m_c = t_r_c, u_phys_w, t_m_c


class RCBatchModel:
    """The 2R2C physics as a one-member batch model (exact ZOH over each control interval).

    The backup thermostat is approximated per interval by clipping on the room temperature at
    the start of the interval (full power below ``backup_low_c``, off above ``backup_high_c``
    for a heater; mirrored for cooling). The hidden ``T_m`` now is taken from ``history['T_m']``
    when present (simulated data), else reconstructed from the last interval by inverting the
    T_r row of the discrete model (exact for noise-free data without a backup override).
    """

    n_members = 1
    depth = 0
    exog_names = ("T_a", "G", "I_g")

    def __init__(
        self,
        params: RCParams,
        *,
        dt_s: float,
        u_max_w: float,
        backup_low_c: float = 17.0,
        backup_high_c: float = 20.5,
    ):
        if not (np.isfinite(u_max_w) and u_max_w > 0):
            raise InputError(f"RCBatchModel.u_max_w must be positive, got {u_max_w!r}")
        if not backup_low_c < backup_high_c:
            raise InputError(
                f"RCBatchModel backup limits need low < high, got {backup_low_c}, {backup_high_c}"
            )
        self.params = params
        self.u_max_w, self.dt_s = u_max_w, dt_s
        self.backup_low_c, self.backup_high_c = backup_low_c, backup_high_c
        self.ad, self.bd = discretise(params, dt_s)

    @property
    def eta(self) -> float:
        return self.params.eta

    def state_now(self, history: dict[str, np.ndarray]) -> tuple[float, float]:
        """Current ``(T_r, T_m)`` [C] from the history (see the class docstring)."""
        t_r = np.asarray(history["T_r"], dtype=float)
        if "T_m" in history:
            return float(t_r[-1]), float(np.asarray(history["T_m"])[-1])
        zeros = np.zeros_like(t_r)
        d = np.array(
            [
                np.asarray(history["u_phys"], dtype=float)[-1],
                np.asarray(history["T_a"], dtype=float)[-2],
                np.asarray(history.get("G", zeros), dtype=float)[-2],
                np.asarray(history.get("I_g", zeros), dtype=float)[-2],
            ]
        )
        (a00, a01), (a10, a11) = self.ad
        t_m_prev = (t_r[-1] - a00 * t_r[-2] - self.bd[0] @ d) / a01
        return float(t_r[-1]), float(a10 * t_r[-2] + a11 * t_m_prev + self.bd[1] @ d)

    def rollout(
        self, history: dict[str, np.ndarray], u_w: torch.Tensor, exog: dict[str, np.ndarray]
    ) -> _Rollout:
        """u_w (N, H) [W] -> tensors (1, N, H) of end-of-interval T_r, T_m and delivered power."""
        n, h = u_w.shape
        t_r0, t_m0 = self.state_now(history)
        d = np.stack([np.asarray(exog[k], dtype=float)[:h] for k in self.exog_names], axis=1)
        drift = torch.as_tensor(d @ self.bd[:, 1:].T, dtype=u_w.dtype)  # (H, 2)
        (a00, a01), (a10, a11) = self.ad.tolist()
        b0, b1 = self.bd[:, 0].tolist()
        t_r = torch.full((n,), t_r0, dtype=u_w.dtype)
        t_m = torch.full((n,), t_m0, dtype=u_w.dtype)
        on, off = (self.backup_low_c, self.backup_high_c)
        out_r, out_m, out_u = [], [], []
        for j in range(h):
            force_on, force_off = (t_r < on, t_r > off)
            if not self.params.heating:
                force_on, force_off = force_off, force_on
            p = torch.where(force_on, self.u_max_w, torch.where(force_off, 0.0, u_w[:, j]))
            t_r, t_m = (
                a00 * t_r + a01 * t_m + b0 * p + drift[j, 0],
                a10 * t_r + a11 * t_m + b1 * p + drift[j, 1],
            )
            out_r.append(t_r)
            out_m.append(t_m)
            out_u.append(p)
        return _Rollout(
            torch.stack(out_r, 1)[None], torch.stack(out_u, 1)[None], torch.stack(out_m, 1)[None]
        )


class _Options(NamedTuple):
    """How a sampling controller scores and refines plans (see the module docstring); on/off
    actions are never polished (the LP plan is continuous)."""

    risk_weight: float
    ensemble: str
    offset_gain: float
    polish_iters: int


class _NonFiniteModelOutput(Exception):
    pass


class _SamplingController:
    """Shared ``reset``/``act`` of the sampling controllers (see the module docstring)."""

    name = "sampling"

    def __init__(
        self,
        model: BatchDynamics,
        spec: ControlSpec,
        planner: Planner,
        options: _Options,
    ):
        risk_weight, ensemble, offset_gain = options.risk_weight, options.ensemble, options.offset_gain
        check_heating(model.eta, spec, what="the model")
        check_interval(model.dt_s, spec.dt_s, what="the scenario's control interval is")
        for name in model.exog_names:
            if name not in FORECAST_FIELDS:
                raise InputError(
                    f"{type(self).__name__}: model exogenous input {name!r} has no forecast; "
                    f"known inputs are {sorted(FORECAST_FIELDS)}"
                )
        if not (risk_weight >= 0 and np.isfinite(risk_weight)):
            raise InputError(f"{type(self).__name__}.risk_weight must be >= 0, got {risk_weight}")
        self.model, self.spec, self.planner, self.risk_weight = model, spec, planner, risk_weight
        self.polish = PolishSettings(iters=options.polish_iters)
        if ensemble not in ENSEMBLE_MODES:
            raise InputError(
                f"{type(self).__name__}.ensemble must be one of {', '.join(ENSEMBLE_MODES)}, "
                f"got {ensemble!r}"
            )
        self.ensemble = ensemble
        if risk_weight > 0 and ensemble != "members":
            raise InputError(
                f"{type(self).__name__}.risk_weight needs ensemble='members' (the spread of the "
                f"members' costs); got risk_weight={risk_weight} with ensemble={ensemble!r}"
            )
        if not 0.0 <= offset_gain <= 1.0:
            raise InputError(
                f"{type(self).__name__}.offset_gain must lie in [0, 1], got {offset_gain}"
            )
        self.offset_gain = offset_gain
        self._plan: np.ndarray | None = None
        self.last_cost_eur = float("nan")  # planned objective of the last plan [EUR]
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        """Forget the warm start; reseed the sampling generator (entropy when ``seed`` is None)."""
        self._generator = torch.Generator()
        if seed is None:
            self._generator.seed()
        else:
            self._generator.manual_seed(seed)
        self._plan = None
        self._offset = 0.0
        self._stats = SolveStats(time_s=0.0, status="reset", iterations=0, fallback=False)

    @property
    def last_plan(self) -> np.ndarray | None:
        """(H,) demanded power of the last plan [W]; None after a fallback."""
        return None if self._plan is None else self._plan.copy()

    @property
    def last_stats(self) -> SolveStats:
        return self._stats

    def act(self, obs: Observation, forecast: Forecast) -> float:
        """Demanded power for the coming interval [W], in ``[0, u_max_w]``."""
        start = time.perf_counter()
        try:
            if len(obs.history["u_phys"]) < self.model.depth + 1:
                return self._fallback(obs, forecast, start, "short history")
            plan, cost, iterations = self._solve(obs, forecast)
        except _NonFiniteModelOutput:
            return self._fallback(obs, forecast, start, "non-finite model output")
        except Exception as exc:  # a failed solve must not stop a closed-loop run
            return self._fallback(obs, forecast, start, f"error {type(exc).__name__}: {exc}")
        self._plan, self.last_cost_eur = plan, cost
        self._stats = SolveStats(
            time_s=time.perf_counter() - start, status="ok", iterations=iterations, fallback=False
        )
        return float(np.clip(plan[0], 0.0, self.spec.u_max_w))

    def _fallback(self, obs: Observation, forecast: Forecast, start: float, reason: str) -> float:
        self._plan, self.last_cost_eur = None, float("nan")
        try:
            action = fallback_power(obs, forecast, self.spec)
        except Exception:  # e.g. an empty forecast: off is safe behind the backup thermostat
            action = 0.0
        self._stats = SolveStats(
            time_s=time.perf_counter() - start,
            status=f"fallback: {reason}",
            iterations=0,
            fallback=True,
        )
        return action

    def _warm_start(self, h: int) -> torch.Tensor:
        if self._plan is None:
            x0 = np.full(h, 0.5 * self.spec.u_max_w)
        else:
            shifted = np.append(self._plan[1:], self._plan[-1])
            x0 = np.pad(shifted, (0, max(h - len(shifted), 0)), mode="edge")[:h]
        return torch.as_tensor(x0, dtype=torch.float32)

    def _solve(self, obs: Observation, forecast: Forecast) -> tuple[np.ndarray, float, int]:
        h = min(self.spec.horizon_steps, forecast.horizon)
        if h < 1:
            raise InputError("the forecast is empty")
        offset = self._update_offset(obs.history)
        rollout, score, problem = self._objective(obs.history, forecast, h, offset)

        x0 = self._warm_start(h)
        polisher = PiggybackPolish(rollout, score, problem, self.polish, x0)
        result = self.planner.optimize(polisher.objective, x0, self._generator)
        plan, cost = result.plan, result.cost
        polished = polisher.finish()
        if polished is not None and polished[1] < cost:
            plan, cost = polished
        if not np.isfinite(cost):
            raise _NonFiniteModelOutput
        return plan.numpy().astype(float), cost, result.iterations + polisher.lps

    def _update_offset(self, history: dict[str, np.ndarray]) -> float:
        """The output-disturbance estimate [K] after the newest measurement (0 when off).

        The model predicts the interval that just ended from the history one interval ago and
        the power actually delivered; the error against the measured ``T_r`` is filtered with
        gain ``offset_gain`` into an offset added to every predicted ``T_r`` (offset-free MPC).
        """
        if self.offset_gain == 0 or len(history["u_phys"]) < self.model.depth + 2:
            return self._offset
        past = {name: np.asarray(values)[:-1] for name, values in history.items()}
        last = {name: np.asarray(history[name])[-2:-1] for name in self.model.exog_names}
        u_w = torch.tensor([[float(history["u_phys"][-1])]], dtype=torch.float32)
        with torch.no_grad():
            predicted = float(self.model.rollout(past, u_w, last).t_r_c[..., 0].mean())
        error = float(history["T_r"][-1]) - predicted
        if np.isfinite(error):
            self._offset += self.offset_gain * (error - self._offset)
        return self._offset

    def _objective(
        self, history: dict[str, np.ndarray], forecast: Forecast, h: int, offset: float = 0.0
    ) -> tuple[RolloutFn, Callable[[torch.Tensor, torch.Tensor], torch.Tensor], PlanProblem]:
        """The model's rollout, the objective of its predictions and the data of both."""
        exog = {
            k: np.array(getattr(forecast, FORECAST_FIELDS[k])[:h]) for k in self.model.exog_names
        }
        dtype = torch.float32
        price_np = np.asarray(forecast.price_eur_per_kwh[:h], dtype=float)
        lower, upper = planning_band(forecast, h)
        price = torch.tensor(price_np, dtype=dtype)
        t_min = torch.tensor(lower, dtype=dtype)
        t_max = torch.tensor(upper, dtype=dtype)
        dt_h, weight = self.spec.dt_h, self.spec.comfort_weight_eur_per_kh
        problem = PlanProblem(
            price=price_np,
            t_min=lower,
            t_max=upper,
            dt_h=dt_h,
            weight=weight,
            lower=0.0,
            upper=self.spec.u_max_w,
        )

        def rollout(u_w: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
            with torch.no_grad():
                roll = self.model.rollout(history, u_w, exog)
                t_r, u_phys = roll.t_r_c.to(dtype), roll.u_phys_w.to(dtype)
            if not (bool(torch.isfinite(t_r).all()) and bool(torch.isfinite(u_phys).all())):
                raise _NonFiniteModelOutput
            if self.ensemble == "mean":
                return t_r.mean(0, keepdim=True) + offset, u_phys.mean(0, keepdim=True)
            return t_r + offset, u_phys

        def score(t_r: torch.Tensor, u_phys: torch.Tensor) -> torch.Tensor:
            violation = torch.relu(t_min - t_r) + torch.relu(t_r - t_max)
            step_cost = u_phys * (dt_h / 1000.0) * price + weight * dt_h * violation
            cost = step_cost.sum(dim=-1)  # (M, N)
            if self.risk_weight > 0 and cost.shape[0] > 1:
                return cost.mean(0) + self.risk_weight * cost.std(0, correction=0)
            return cost.mean(0)

        return rollout, score, problem


_RS = RandomShootingPlanner(lower=0.0, upper=1.0)  # the defaults, defined once in the planners
_CEM = CEMPlanner(lower=0.0, upper=1.0)


class RandomShooting(_SamplingController):
    """Random shooting over a model: ``n_samples`` sequences scored once, the best one applied."""

    name = "random-shooting"

    def __init__(
        self,
        model: BatchDynamics,
        spec: ControlSpec,
        *,
        n_samples: int = _RS.n_samples,
        binary: bool = False,
        risk_weight: float = 0.0,
        polish_iters: int = 0,
        ensemble: str = "mean",
        offset_gain: float = 0.5,
    ):
        planner = RandomShootingPlanner(
            lower=0.0, upper=spec.u_max_w, n_samples=n_samples, binary=binary
        )
        options = _Options(risk_weight, ensemble, offset_gain, 0 if binary else polish_iters)
        super().__init__(model, spec, planner, options)


class CEM(_SamplingController):
    """Cross-entropy method over a model (see :class:`controllers.planners.CEMPlanner`).

    Defaults (64 samples x 2 iterations, 3 % elites, initial std 0.3 x range, pink noise
    ``noise_beta=2``, one LP polish) are set by decision time: a learned model's rollout costs
    mostly a fixed time per horizon step, so iterations are expensive and samples cheap, and
    the polish rides along in the two batches (``benchmarks/bench_planners.py``: 56 ms median
    over a 10-member depth-16 physnet). The sampling finds the shape of the plan, the polish
    its last percent: on the exact 2R2C, sampling alone settles about 4-5 % above the optimum,
    with the polish at it.
    """

    name = "cem"

    def __init__(
        self,
        model: BatchDynamics,
        spec: ControlSpec,
        *,
        n_samples: int = _CEM.n_samples,
        n_iters: int = _CEM.n_iters,
        elite_frac: float = _CEM.elite_frac,
        alpha: float = _CEM.alpha,
        init_std_frac: float = _CEM.init_std_frac,
        noise_beta: float = _CEM.noise_beta,
        binary: bool = False,
        risk_weight: float = 0.0,
        polish_iters: int = 1,
        ensemble: str = "mean",
        offset_gain: float = 0.5,
    ):
        planner = CEMPlanner(
            lower=0.0,
            upper=spec.u_max_w,
            n_samples=n_samples,
            n_iters=n_iters,
            elite_frac=elite_frac,
            alpha=alpha,
            init_std_frac=init_std_frac,
            noise_beta=noise_beta,
            binary=binary,
        )
        options = _Options(risk_weight, ensemble, offset_gain, 0 if binary else polish_iters)
        super().__init__(model, spec, planner, options)
