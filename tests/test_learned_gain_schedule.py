"""The hybrid and pcnn take the unmeasured gains' schedule of the RC identified from their data:
on a 2R2C office whose gains the data do not hold, their 2R2C reads the identified schedule as
I_g, in training, on frames and in the closed loop's rollouts alike, and predicts the office as
the same model given the true gains does."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
import torch

from pinn_mpc import TrainConfig, fit, load, save
from pinn_mpc.data import validate_timeseries
from pinn_mpc.evaluation import recursive_paths
from pinn_mpc.export import export_rc
from pinn_mpc.features import FeatureConfig
from pinn_mpc.identify import identify_rc, simulate_rc
from pinn_mpc.models.hybrid import Hybrid
from pinn_mpc.models.learned import LearnedModel
from pinn_mpc.models.pcnn import Pcnn
from pinn_mpc.physics import PAPER_HOUSEHOLD, discretise, params_from_summary

PLANT = dataclasses.replace(PAPER_HOUSEHOLD, solar_aperture_m2=3.0, gain_to_air_fraction=0.6)
DAYS, TEST_DAYS, H = 21, 7, 24
CONFIG = TrainConfig(n_seeds=2, epochs=30, depth=8)


def _office_gains_w(times: pd.DatetimeIndex) -> np.ndarray:
    """900 W on workdays 08-18 h, 150 W otherwise."""
    hours = times.hour + times.minute / 60.0
    return np.where((times.day_of_week < 5) & (hours >= 8) & (hours < 18), 900.0, 150.0)


@pytest.fixture(scope="module")
def office() -> pd.DataFrame:
    """28 days from a Monday of the 2R2C office, its gains in a column ``true_I_g`` the
    models are not given."""
    rng = np.random.default_rng(5)
    n = (DAYS + TEST_DAYS) * 48
    times = pd.date_range("2024-01-01", periods=n, freq="30min")
    hours = np.arange(n) * 0.5
    t_a = 2.0 + 4.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0) + 0.3 * np.cumsum(rng.normal(0, 0.2, n))
    g = 400.0 * rng.uniform(0.2, 1.0, DAYS + TEST_DAYS).repeat(48) * np.clip(np.sin(2 * np.pi * (hours - 6.0) / 24.0), 0.0, None)
    u = np.where(rng.random(n) < 0.5, 5000.0, 0.0) * rng.uniform(0.3, 1.0, n)
    gains = _office_gains_w(times)
    ad, bd = discretise(PLANT, 1800.0)
    x = simulate_rc(ad, bd, np.array([19.0, 18.0]), np.stack([u, t_a, g, gains], axis=1)[:-1])
    frame = pd.DataFrame({"time": times, "T_r": x[:, 0], "u": u, "u_phys": u, "T_a": t_a, "G": g})
    frame = validate_timeseries(frame)
    frame["true_I_g"] = gains
    return frame


def _parts(office: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    train = office.iloc[: DAYS * 48].drop(columns="true_I_g").reset_index(drop=True)
    test = office.iloc[DAYS * 48 - 24 :].drop(columns="true_I_g").reset_index(drop=True)
    return train, test


def _error_c(model, frame: pd.DataFrame) -> float:
    paths, starts = recursive_paths(model, frame, H)
    truth = frame["T_r"].to_numpy()[starts[:, None] + np.arange(1, H + 1)]
    return float(np.mean(np.abs(paths.mean(axis=0) - truth)))


ARCHITECTURES = {"hybrid": Hybrid, "pcnn": Pcnn}


def _fit(df: pd.DataFrame, arch: str) -> LearnedModel:
    model = fit(df, arch=arch, config=CONFIG).model
    assert isinstance(model, LearnedModel)
    return model


@pytest.fixture(scope="module", params=sorted(ARCHITECTURES))
def scheduled(office: pd.DataFrame, request):
    train, _ = _parts(office)
    return _fit(train, request.param)


def test_the_model_reads_the_identified_schedule_and_predicts_as_with_the_true_gains(office, scheduled, monkeypatch) -> None:
    train, test = _parts(office)
    arch = scheduled.arch
    identified = identify_rc(train)
    assert scheduled.features.gain_schedule_w == identified.params.unmeasured_gains_w
    assert len(scheduled.features.gain_schedule_w) == 24
    # the reference: the same hybrid given the true gains as a measured column
    given = office.rename(columns={"true_I_g": "I_g"})
    told = _fit(given.iloc[: DAYS * 48].reset_index(drop=True), arch)
    assert told.features.gain_schedule_w == ()
    told_error = _error_c(told, given.iloc[DAYS * 48 - 24 :].reset_index(drop=True))
    # the model as it was: no schedule, its network left to learn the gains
    monkeypatch.setattr(ARCHITECTURES[arch], "gain_schedule", False)
    plain = _fit(train, arch)
    assert plain.features.gain_schedule_w == ()
    errors = {"scheduled": _error_c(scheduled, test), "true gains": told_error, "plain": _error_c(plain, test)}
    assert errors["scheduled"] < 1.5 * errors["true gains"] + 0.05, errors
    assert errors["scheduled"] < 0.5 * errors["plain"], errors
    print(arch, errors)


def test_a_closed_loop_rollout_adds_the_schedule_as_a_frame_does(office, scheduled) -> None:
    """The rollout from a controller's history (I_g 0 where the plant measures none, the
    calendar given) is the prediction on the frame, which has no I_g column."""
    _, test = _parts(office)
    paths, starts = recursive_paths(scheduled, test, H)
    j = 241  # Friday 17:00: the history holds a workday's gains, the horizon its end and Saturday
    i = int(starts[j])
    assert pd.Timestamp(test["time"].iloc[i]) == pd.Timestamp("2024-01-26 17:00")
    dow = pd.to_datetime(test["time"]).dt.day_of_week.to_numpy(float)
    tod = (pd.to_datetime(test["time"]).dt.hour + pd.to_datetime(test["time"]).dt.minute / 60.0).to_numpy(float)
    past = slice(0, i + 1)
    history = {
        "T_r": test["T_r"].to_numpy()[past], "u_phys": test["u_phys"].to_numpy()[:i],  # to the last interval
        "T_a": test["T_a"].to_numpy()[past], "G": test["G"].to_numpy()[past], "I_g": np.zeros(i + 1),
        "time_of_day_h": tod[past], "day_of_week": dow[past],
    }
    ahead = slice(i, i + H)
    exog = {
        "time_of_day_h": tod[ahead], "T_a": test["T_a"].to_numpy()[ahead], "G": test["G"].to_numpy()[ahead],
        "I_g": np.zeros(H), "day_of_week": dow[ahead],
    }
    assert "day_of_week" in scheduled.exog_names
    u = torch.tensor(test["u"].to_numpy()[ahead][None], dtype=torch.float32)
    with torch.no_grad():
        roll = scheduled.rollout(history, u, exog)
    np.testing.assert_allclose(roll.t_r_c[:, 0, :, 0].numpy(), paths[:, j, :], atol=2e-3)


def test_the_schedule_is_saved_with_the_model(office, scheduled, tmp_path) -> None:
    _, test = _parts(office)
    save(scheduled, tmp_path / "model")
    loaded = load(tmp_path / "model")
    assert isinstance(loaded, LearnedModel)
    assert loaded.features.gain_schedule_w == scheduled.features.gain_schedule_w
    np.testing.assert_allclose(recursive_paths(loaded, test, H)[0], recursive_paths(scheduled, test, H)[0], atol=1e-5)
    assert FeatureConfig.from_dict(scheduled.features.to_dict()) == scheduled.features


def test_export_rc_writes_the_schedule_the_hybrid_reads(scheduled) -> None:
    out = export_rc(scheduled, source="test")
    assert out["unmeasured_gains_W"] == list(scheduled.features.gain_schedule_w)
    assert params_from_summary(out).unmeasured_gains_w == scheduled.features.gain_schedule_w
