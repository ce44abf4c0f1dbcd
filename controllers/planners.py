"""Sampling optimisers over action sequences: random shooting and the cross-entropy method.

Both share one shape (as in mbrl-lib), so a controller can swap them::

    result = planner.optimize(objective, x0, generator)

``objective`` maps a batch of action sequences, a tensor (N, H) [W], to costs (N,); it is called
once per iteration with the whole batch, so a model rolls every candidate out together.
``x0`` (H,) is the warm start (normally the previous plan shifted by one step); it is always
evaluated as one of the candidates, so a planner never returns a plan worse than its warm start.
All randomness comes from the ``torch.Generator`` passed in; the planners hold no state.

Actions are either continuous in ``[lower, upper]`` or, with ``binary=True``, on/off: exactly
``lower`` or ``upper``. Non-finite costs rank last (they never become elites or the result).

A plan of several actuators is (H, A) (the batch (N, H, A)): each actuator's sequence is
sampled as one actuator's is (its own noise, coloured along the horizon; CEM's mean and
standard deviation per step and actuator), all within the one box ``[lower, upper]`` (a
controller of actuators of different bounds plans their fractions of range, in [0, 1]).
With one actuator (plans (H,)) the draws and the results are those of plans (H, 1).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple, Protocol

import torch

from pinn_mpc import torch_generator  # noqa: F401  (copies and pickles of the planners' generators keep None's count)
from pinn_mpc.errors import InternalError

__all__ = [
    "BatchObjective",
    "CEMPlanner",
    "Objective",
    "PlanResult",
    "Planner",
    "RandomShootingPlanner",
    "colored_noise",
    "colored_noise_batch",
    "move_blocks",
]

#: Costs (N,) of a batch of action sequences (N, H).
Objective = Callable[[torch.Tensor], torch.Tensor]
#: Costs (B, N) of B buildings' batches of action sequences (B, N, H).
BatchObjective = Callable[[torch.Tensor], torch.Tensor]


class PlanResult(NamedTuple):
    """Best sequence found: ``plan`` (H,) and its ``cost``; ``n_evaluated`` sequences in total."""

    plan: torch.Tensor
    cost: float
    iterations: int
    n_evaluated: int


class Planner(Protocol):
    @property
    def n_samples(self) -> int: ...  # sequences per objective call

    @property
    def binary(self) -> bool: ...

    def optimize(
        self, objective: Objective, x0: torch.Tensor, generator: torch.Generator
    ) -> PlanResult: ...


def _check_common(name: str, lower: float, upper: float, n_samples: int) -> None:
    if not (math.isfinite(lower) and math.isfinite(upper) and lower < upper):
        raise ValueError(f"{name} bounds must be finite with lower < upper, got {lower}, {upper}")
    if n_samples < 2:
        raise ValueError(f"{name}.n_samples must be >= 2, got {n_samples}")


def _check_beta(name: str, beta: float) -> None:
    if not 0.0 <= beta <= 4.0:
        raise ValueError(f"{name}.noise_beta must be in [0, 4] (0 white, 2 pink), got {beta}")


def _evaluate(objective: Objective, candidates: torch.Tensor) -> torch.Tensor:
    """Costs (N,) with non-finite values replaced by +inf so they rank last."""
    return _evaluate_batch(lambda u: objective(u[0])[None], candidates[None])[0]


def _evaluate_batch(objective: BatchObjective, candidates: torch.Tensor) -> torch.Tensor:
    """Costs (B, N) of candidates (B, N, H), non-finite values replaced by +inf."""
    costs = objective(candidates).reshape(candidates.shape[0], -1).to(torch.float64)
    if costs.shape[1] != candidates.shape[1]:
        raise ValueError(
            f"objective returned {costs.shape[1]} costs for {candidates.shape[1]} candidates"
        )
    return torch.where(torch.isfinite(costs), costs, torch.full_like(costs, math.inf))


def colored_noise(
    n: int, h: int, beta: float, generator: torch.Generator, dtype: torch.dtype
) -> torch.Tensor:
    """Standard normal noise (n, h) with power spectrum ~ 1/f^beta along the horizon.

    ``beta=0`` is white noise; larger values correlate neighbouring steps (iCEM, Pinneri et
    al. 2020), which explores slow changes of power (pre-heating, coasting) far better than
    independent steps. Every entry has unit variance. The one-building case of
    :func:`colored_noise_batch`.
    """
    return colored_noise_batch(n, h, beta, (generator,), dtype)[0]


def colored_noise_batch(
    n: int, h: int, beta: float, generators: Sequence[torch.Generator], dtype: torch.dtype
) -> torch.Tensor:
    """:func:`colored_noise` of each of B generators, (B, n, h): the white noise drawn
    generator by generator (each building's own numbers), coloured in one batched FFT."""
    white = torch.stack([torch.randn((n, h), generator=g, dtype=dtype) for g in generators])
    if beta == 0 or h < 2:
        return white
    freqs = torch.fft.rfftfreq(h, dtype=dtype)
    scale = torch.ones_like(freqs)
    scale[1:] = freqs[1:] ** (-beta / 2)
    scale[0] = scale[1]
    # A circular convolution of white noise with kernel irfft(scale): variance sum(kernel^2).
    kernel_norm = torch.linalg.vector_norm(torch.fft.irfft(scale, n=h))
    return torch.fft.irfft(torch.fft.rfft(white, dim=-1) * scale, n=h, dim=-1) / kernel_norm


def _plan_noise(
    n: int, h: int, rest: tuple[int, ...], beta: float, generators: Sequence[torch.Generator], dtype: torch.dtype
) -> torch.Tensor:
    """:func:`colored_noise_batch` (B, n, h) of plans with trailing axes ``rest`` (the
    actuators): (B, n, h, *rest), each actuator's own numbers, coloured along the horizon."""
    if not rest:
        return colored_noise_batch(n, h, beta, generators, dtype)
    noise = colored_noise_batch(n * math.prod(rest), h, beta, generators, dtype)
    return noise.reshape(len(generators), n, *rest, h).movedim(-1, 2)


def _snap(x: torch.Tensor, lower: float, upper: float) -> torch.Tensor:
    """Round to the nearer of ``lower`` / ``upper`` (on/off actions)."""
    return torch.where(x >= 0.5 * (lower + upper), upper, lower).to(x.dtype)


def move_blocks(h: int) -> torch.Tensor:
    """Block index of each of ``h`` steps (h,), blocks of 1, 1, 2, 2, 4, 4, ... steps: a plan
    constant per block is fine near now and coarse far ahead (move blocking), so 48 steps take
    10 numbers."""
    index: list[int] = []
    size = 1
    while len(index) < h:
        for _ in range(2):
            index += [index[-1] + 1 if index else 0] * size
        size *= 2
    return torch.tensor(index[:h])


@dataclass(frozen=True, kw_only=True)
class RandomShootingPlanner:
    """Sample ``n_samples`` sequences once; keep the best (fair coin flips when binary).

    Continuous actions come from two low-dimensional families, because independent uniform
    steps almost never hold a room at a band edge (on the exact 2R2C, 128 of them end 25 % above
    the optimum in closed loop, 4096 still 10 %):

    - ``local_frac`` of them around the warm start (the previous plan, shifted): correlated
      noise (``noise_beta``, see :func:`colored_noise`) at each scale of ``local_std_fracs`` x
      range, in equal shares. In receding horizon this turns one batch per decision into a
      search that continues from decision to decision, as MPPI's warm start does.
    - the rest uniform per :func:`move_blocks` block (10 numbers for 48 steps): the global
      search that finds a new shape when the warm start is far off (a cold start, a new price
      or comfort period).

    The warm start itself is the first sample. The default budget equals CEM's default
    (64 samples x 2 iterations), so the two compare at equal model cost.
    """

    lower: float
    upper: float
    n_samples: int = 128
    binary: bool = False
    local_frac: float = 0.85
    local_std_fracs: tuple[float, ...] = (0.01, 0.05, 0.2)
    noise_beta: float = 1.5

    def __post_init__(self) -> None:
        _check_common("RandomShootingPlanner", self.lower, self.upper, self.n_samples)
        if not 0.0 <= self.local_frac <= 1.0:
            raise ValueError(
                f"RandomShootingPlanner.local_frac must lie in [0, 1], got {self.local_frac}"
            )
        if not self.local_std_fracs or not all(
            0.0 < f and math.isfinite(f) for f in self.local_std_fracs
        ):
            raise ValueError(
                "RandomShootingPlanner.local_std_fracs must be positive fractions of the range, "
                f"got {self.local_std_fracs}"
            )
        _check_beta("RandomShootingPlanner", self.noise_beta)

    def optimize(
        self, objective: Objective, x0: torch.Tensor, generator: torch.Generator
    ) -> PlanResult:
        """x0 (H,) or (H, A) [W] -> the best of ``n_samples`` candidates (one objective call)."""
        h, dtype, rest = x0.shape[0], x0.dtype, tuple(x0.shape[1:])
        if self.binary:
            r = torch.rand((self.n_samples, h, *rest), generator=generator, dtype=dtype)
            samples = torch.where(r < 0.5, self.upper, self.lower).to(dtype)
            samples[0] = _snap(x0, self.lower, self.upper)
        else:
            span = self.upper - self.lower
            n_local = round(self.local_frac * (self.n_samples - 1))
            shares = [len(c) for c in torch.arange(n_local).tensor_split(len(self.local_std_fracs))]
            parts = [x0[None]]
            for frac, n in zip(self.local_std_fracs, shares, strict=True):
                if n == 0:
                    continue
                noise = _plan_noise(n, h, rest, self.noise_beta, (generator,), dtype)[0]
                parts.append(x0 + frac * span * noise)
            blocks = move_blocks(h)
            levels = torch.rand(
                (self.n_samples - 1 - n_local, int(blocks[-1]) + 1, *rest), generator=generator, dtype=dtype
            )
            parts.append(self.lower + span * levels[:, blocks])
            samples = torch.cat(parts).clamp(self.lower, self.upper)
        costs = _evaluate(objective, samples)
        best = int(torch.argmin(costs))
        return PlanResult(samples[best].clone(), float(costs[best]), 1, self.n_samples)


@dataclass(frozen=True, kw_only=True)
class CEMPlanner:
    """Cross-entropy method, warm-started and elitist.

    Continuous actions: a Gaussian per step (mean from ``x0``, std ``init_std_frac`` x range),
    samples clipped to the bounds (clipping puts mass on the bounds, where optima of
    energy/comfort problems often lie). Binary actions: a Bernoulli per step, started halfway
    between 1/2 and the warm start's fraction of full power (0.25 off, 0.75 on, 0.5 at half
    power, the controllers' cold start). Each iteration refits the distribution to the
    ``elite_frac`` best samples with smoothing ``alpha`` (the weight kept on the old
    distribution, mbrl-lib's convention). The current mean (continuous) and the best sequence so
    far are re-evaluated among the samples, so the returned cost never increases with iterations.
    """

    lower: float
    upper: float
    n_samples: int = 64
    n_iters: int = 2
    elite_frac: float = 0.03
    alpha: float = 0.1
    init_std_frac: float = 0.3
    noise_beta: float = 2.0
    binary: bool = False

    def __post_init__(self) -> None:
        _check_common("CEMPlanner", self.lower, self.upper, self.n_samples)
        if self.n_iters < 1:
            raise ValueError(f"CEMPlanner.n_iters must be >= 1, got {self.n_iters}")
        if not (0.0 < self.elite_frac <= 1.0):
            raise ValueError(f"CEMPlanner.elite_frac must lie in (0, 1], got {self.elite_frac}")
        if not (0.0 <= self.alpha < 1.0):
            raise ValueError(f"CEMPlanner.alpha must lie in [0, 1), got {self.alpha}")
        if not (self.init_std_frac > 0 and math.isfinite(self.init_std_frac)):
            raise ValueError(f"CEMPlanner.init_std_frac must be > 0, got {self.init_std_frac}")
        _check_beta("CEMPlanner", self.noise_beta)

    @property
    def n_elites(self) -> int:
        """``elite_frac`` of the samples, at least 2 (a spread needs two points)."""
        return max(2, math.ceil(self.elite_frac * self.n_samples))

    def optimize(
        self, objective: Objective, x0: torch.Tensor, generator: torch.Generator
    ) -> PlanResult:
        """x0 (H,) or (H, A) [W] -> best sequence after ``n_iters`` objective calls of
        ``n_samples`` each: the one-building case of :meth:`optimize_batch`."""
        plans, costs = self.optimize_batch(lambda u: objective(u[0])[None], x0[None], (generator,))
        return PlanResult(plans[0], float(costs[0]), self.n_iters, self.n_iters * self.n_samples)

    def optimize_batch(
        self,
        objective: BatchObjective,
        x0: torch.Tensor,
        generators: Sequence[torch.Generator],
        candidates: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """CEM for B buildings at once: ``objective`` maps plans (B, N, H) to costs (B, N);
        ``x0`` (B, H) the warm starts (plans (B, N, H, A) and warm starts (B, H, A) of several
        actuators); building b draws its samples from ``generators[b]``
        alone, so its plan does not depend on the others'. ``candidates`` (B, C, H) are
        scored in the first iteration in place of C of the samples (e.g. another planner's
        plans: the best of them is kept if nothing sampled beats it; continuous actions only).
        Returns (plans (B, H), costs (B,) float64)."""
        b, h = x0.shape[:2]
        rest = tuple(x0.shape[2:])  # (A,) for plans of several actuators
        dtype, n, span = x0.dtype, self.n_samples, self.upper - self.lower
        if len(generators) != b:
            raise InternalError(f"CEMPlanner: {len(generators)} generators for {b} warm starts")
        if candidates is not None and (
            self.binary or candidates.shape[0] != b or candidates.shape[2] != h or candidates.shape[1] > n - 2
        ):
            raise InternalError(
                f"CEMPlanner: candidates must be (B, at most N - 2, H) of continuous actions, got {tuple(candidates.shape)}"
            )
        if self.binary:
            best = _snap(x0, self.lower, self.upper)
            on = ((x0 - self.lower) / span).clamp(0.0, 1.0)
            mean = 0.25 + 0.5 * on  # probability of "on"
            std = torch.zeros_like(mean)
        else:
            best = x0.clamp(self.lower, self.upper)
            mean = best.clone()
            std = torch.full_like(mean, self.init_std_frac * span)
        best_cost = torch.full((b,), math.inf, dtype=torch.float64)
        rows = torch.arange(b)
        for it in range(self.n_iters):
            if self.binary:
                r = torch.stack([torch.rand((n, h, *rest), generator=g, dtype=dtype) for g in generators])
                samples = torch.where(r < mean[:, None], self.upper, self.lower).to(dtype)
                samples[:, 0] = best
            else:
                noise = _plan_noise(n, h, rest, self.noise_beta, generators, dtype)
                samples = (mean[:, None] + std[:, None] * noise).clamp(self.lower, self.upper)
                samples[:, 0] = best
                samples[:, 1] = mean
                if candidates is not None and it == 0:
                    samples[:, 2 : 2 + candidates.shape[1]] = candidates.to(dtype).clamp(self.lower, self.upper)
            costs = _evaluate_batch(objective, samples)
            order = torch.argsort(costs, dim=1)
            top = costs[rows, order[:, 0]]
            better = top <= best_cost
            best_cost = torch.where(better, top, best_cost)
            best = torch.where(better.reshape(b, *[1] * (x0.dim() - 1)), samples[rows, order[:, 0]], best)
            elites = samples[rows[:, None], order[:, : self.n_elites]]  # (B, E, H, *A)
            if self.binary:
                freq = (elites - self.lower) / span
                mean = self.alpha * mean + (1 - self.alpha) * freq.mean(dim=1)
            else:
                mean = self.alpha * mean + (1 - self.alpha) * elites.mean(dim=1)
                std = self.alpha * std + (1 - self.alpha) * elites.std(dim=1)
        return best, best_cost
