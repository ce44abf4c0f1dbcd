"""The BOPTEST least-discomfort reference (benchmarks/boptest_least_discomfort.py): its ARX fit,
its prediction as an affine map of the modulation and its linear programme, against truths
built here (the emulator runs are the benchmark's, minutes long, and not run by the suite)."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.boptest_least_discomfort import (
    NA,
    NB,
    Run,
    discomfort_lp,
    fit,
    prediction,
    rollouts,
)


def _true_theta(rng: np.random.Generator) -> np.ndarray:
    """A stable ARX: the room's lags sum to 0.9, inputs with small gains, an offset."""
    a = np.array([0.6, 0.2, 0.07, 0.03])[:NA]
    b = rng.normal(0, 0.05, (5, NB))
    return np.concatenate([a, b.ravel(), [1.5]])


def _run(theta: np.ndarray, rng: np.random.Generator, n: int = 600) -> Run:
    """n intervals of random inputs, the room stepped by the ARX itself (no noise)."""
    u = rng.uniform(0, 1, n + 1)
    cols = {"To": rng.uniform(-5, 15, n + 1), "irr": rng.uniform(0, 500, n + 1),
            "gains": rng.uniform(0, 300, n + 1), "lo": np.full(n + 1, 21.0), "hi": np.full(n + 1, 24.0)}
    run = Run(T=np.full(n + 1, 20.0), u=u, **cols)
    X = run.inputs()
    first = max(NA, NB)
    for k in range(first, n):
        run.T[k + 1] = rollouts(theta, run.T, X, np.array([k]), 1)[0, 0]
    return run


def test_the_fit_recovers_the_arx_that_made_the_data() -> None:
    rng = np.random.default_rng(0)
    theta = _true_theta(rng)
    estimated = fit([_run(theta, rng), _run(theta, rng)], h=8)
    assert estimated == pytest.approx(theta, abs=1e-6)


def test_the_prediction_is_the_rollout_as_an_affine_map_of_the_modulation() -> None:
    rng = np.random.default_rng(1)
    theta = _true_theta(rng)
    run = _run(theta, rng)
    now, h = 100, 48
    c, M = prediction(theta, run.T, run.inputs(), now, h)
    for _ in range(3):  # any modulation ahead: c + M u is the ARX rolled out under it
        u = rng.uniform(0, 1, h)
        X = run.inputs()
        X[now:now + h, 0], X[now:now + h, 1] = u, u * X[now:now + h, 2]
        assert c + M @ u == pytest.approx(rollouts(theta, run.T, X, np.array([now]), h)[0], abs=1e-9)


def test_the_programme_keeps_a_reachable_band_and_spends_least() -> None:
    # one interval per step, T = c + u (a heater of 1 K per step at full signal): the band
    # [21, 24] from c = 20.5 needs u = 0.5 exactly (energy breaks the tie downwards); from
    # c = 19 the best is full power, 1 K below the band
    problem, par, u = discomfort_lp(2)
    par["M"].value = np.eye(2)
    par["lo"].value, par["hi"].value = np.full(2, 21.0), np.full(2, 24.0)
    par["c"].value = np.array([20.5, 19.0])
    problem.solve()
    assert u.value == pytest.approx([0.5, 1.0], abs=1e-6)
    assert problem.value == pytest.approx(1.0 + 1e-3 * 1.5, abs=1e-6)
