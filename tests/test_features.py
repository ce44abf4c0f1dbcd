"""Feature windows (paper Table notation-equ) against the raw columns."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.errors import InputError
from pinn_mpc.features import fit_feature_config, make_windows, time_of_day_h
from tests.model_data import household_data


def test_window_layout_matches_the_definition() -> None:
    df = household_data(2, 3)
    cfg = fit_feature_config(df, depth=4)
    win = make_windows(df, cfg)
    k = 4
    assert cfg.exog_names == ("time_of_day_h", "T_a")
    assert win.x.shape == (len(df) - k - 2, cfg.n_features)
    s = 10
    i = int(win.rows[s])
    assert i == s + k + 1
    x = win.x[s].astype(float)
    t, p, a = cfg.temperature, cfg.power, cfg.exog["T_a"]
    t_r, u_phys, t_a = (df[c].to_numpy() for c in ("T_r", "u_phys", "T_a"))
    np.testing.assert_allclose(x[: k + 1] * t.std + t.mean, t_r[i - k : i + 1], atol=1e-4)
    np.testing.assert_allclose(
        x[k + 1 : 2 * k + 2] * p.std + p.mean, u_phys[i - k - 1 : i], atol=0.5
    )
    np.testing.assert_allclose(
        x[2 * k + 2 : 3 * k + 3] * a.std + a.mean, t_a[i - k : i + 1], atol=1e-4
    )
    assert x[cfg.u_index] * p.std + p.mean == pytest.approx(df["u"].iloc[i], abs=0.5)
    hour = time_of_day_h(df["time"])[i]
    np.testing.assert_allclose(
        x[-2:], [np.sin(hour * np.pi / 12), np.cos(hour * np.pi / 12)], atol=1e-6
    )
    assert win.t_r_next[s] == t_r[i + 1] and win.u_phys_now[s] == u_phys[i]
    # x_f is the first k of every window; x_obs, u, w the last of each plus u and time.
    assert cfg.x_f_index()[:k] == list(range(k))
    assert cfg.now_index()[:2] == [k, 2 * k + 1]


def test_scaling_is_fitted_on_training_data_and_stored() -> None:
    df = household_data(2, 3)
    cfg = fit_feature_config(df, depth=8)
    assert cfg.temperature.mean == pytest.approx(df["T_r"].mean())
    assert cfg.power.std == pytest.approx(df["u_phys"].std(ddof=0))
    again = type(cfg).from_dict(cfg.to_dict())
    assert again == cfg


def test_solar_and_gains_columns_become_exogenous_inputs() -> None:
    df = household_data(2, 3)
    df["G"] = np.linspace(0, 500, len(df))
    df["I_g"] = 100.0  # constant: its scale falls back to 1
    cfg = fit_feature_config(df, depth=8)
    assert cfg.exog_names == ("time_of_day_h", "T_a", "G", "I_g")
    assert cfg.exog["I_g"].std == 1.0
    assert (
        make_windows(df, cfg).x.shape[1] == cfg.n_features == 5 * 9 + 3
    )  # T_r, u_phys, T_a, G, I_g windows


def test_too_short_data_says_how_many_rows_are_needed() -> None:
    df = household_data(1, 0).iloc[:30]
    with pytest.raises(InputError, match=r"has 30 rows, but depth 8 needs at least 42 rows"):
        fit_feature_config(df, depth=8)
    cfg = fit_feature_config(household_data(1, 0), depth=8)
    with pytest.raises(InputError, match=r"has 10 rows, but depth 8 needs at least 11 rows"):
        make_windows(df.iloc[:10], cfg)


def test_missing_exogenous_column_is_named() -> None:
    df = household_data(1, 0)
    df["G"] = 1.0
    cfg = fit_feature_config(df, depth=8)
    with pytest.raises(InputError, match=r"lacks column\(s\) \['G'\]"):
        make_windows(pd.DataFrame(df.drop(columns=["G"])), cfg)
