"""Physical consistency (issue 44): the consistent architectures predict every T_r
non-decreasing in each heating power (non-increasing in each cooling power) and in each
outdoor temperature, for random histories, plans and forecasts; the check catches a network
that does not (the paper's MLP)."""

from __future__ import annotations

import functools

import numpy as np
import pandas as pd
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from pinn_mpc.artifacts import load_model, save_model
from pinn_mpc.consistency import check_draw, draw
from pinn_mpc.data import validate_timeseries
from pinn_mpc.models.learned import LearnedModel
from pinn_mpc.models.positive_arx import TOLERANCE, _responses, fit_positive_arx, impulse_kernels
from pinn_mpc.training import TrainConfig, train_model
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate

HORIZON = 48


@functools.lru_cache(maxsize=4)
def _data(name: str) -> pd.DataFrame:
    scenario = get_scenario(name)
    return validate_timeseries(generate(scenario, days=14, seed=0, policy=scenario.data_policy), source=name)


@functools.lru_cache(maxsize=8)
def _model(name: str, arch: str) -> LearnedModel:
    eta = get_scenario(name).sim.params.eta
    return train_model(_data(name), arch=arch, config=TrainConfig(n_seeds=2, epochs=10, eta=eta), progress=False)


def _passes(name: str, arch: str, seed: int) -> tuple[bool, bool]:
    df = _data(name)
    rng = np.random.default_rng(seed)
    d = draw(rng, n_rows=len(df), first=64, horizon=HORIZON, u_max_w=float(df["u_phys"].max()))
    return check_draw(_model(name, arch), df, d)


@pytest.mark.parametrize("name", ["winter_household", "cold_storage"])
@pytest.mark.parametrize("arch", ["pcnn", "pcnn-parx"])
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_consistent_families_pass_every_draw(name: str, arch: str, seed: int) -> None:
    assert _passes(name, arch, seed) == (True, True)


def test_the_check_catches_the_mlp() -> None:
    results = [_passes("winter_household", "mlp", seed) for seed in range(60)]
    assert not all(p and t for p, t in results)


def test_positive_arx_responses_are_non_negative() -> None:
    """Every certified impulse response of the fit (each power, each outdoor temperature, every
    phase of the day) is non-negative, and the recursion's own kernel is."""
    df = _data("winter_household")
    fit = fit_positive_arx(df, eta=1.0)
    per_day = 48
    q_phase = fit.q[(np.arange(per_day) * 0.5 // fit.block_h).astype(int)]
    kernels = impulse_kernels(fit.a, q_phase, 7 * per_day)
    assert kernels.min() >= 0.0
    u_mat, _ = _responses(kernels, np.zeros(per_day), fit.lags, 7 * per_day)
    a_mat, a_off = _responses(kernels, -q_phase, fit.lags, 7 * per_day)
    assert (u_mat @ fit.b).min() >= -TOLERANCE * 1e-3  # K/W: the bound is per kW
    assert (a_mat @ fit.c + a_off).min() >= -TOLERANCE


@pytest.mark.parametrize("arch", ["pcnn", "pcnn-parx"])
def test_saved_and_loaded_model_rolls_out_the_same(arch: str, tmp_path) -> None:
    model = _model("winter_household", arch)
    save_model(model, tmp_path / "m")
    loaded = load_model(tmp_path / "m")
    df = _data("winter_household")
    rng = np.random.default_rng(1)
    d = draw(rng, n_rows=len(df), first=64, horizon=HORIZON, u_max_w=float(df["u_phys"].max()))
    from pinn_mpc.consistency import history_at

    history, exog = history_at(df, d.start, HORIZON)
    plan = torch.as_tensor(d.plan_w[None], dtype=torch.float32)
    a = model.rollout(history, plan, {n: exog[n] for n in model.exog_names}).t_r_c
    b = loaded.rollout(history, plan, {n: exog[n] for n in loaded.exog_names}).t_r_c
    assert torch.allclose(a, b)


def test_a_rollout_loss_trains_on_less_data_than_its_rollout() -> None:
    """One day of data holds fewer samples than a training rollout's 48 steps: the chunk is
    the samples there are, and the model trains."""
    from tests.model_data import household_data

    model = train_model(household_data(1, seed=0), arch="pcnn", config=TrainConfig(n_seeds=1, epochs=2), progress=False)
    assert np.isfinite(model.record.final_loss["reg"])
