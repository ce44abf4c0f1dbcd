"""Evaluation metrics against values computed by hand, and RC export."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from pinn_mpc import physics
from pinn_mpc.errors import InputError
from pinn_mpc.evaluation import evaluate_model, recursive_t_r
from pinn_mpc.export import export_rc
from pinn_mpc.models import LearnedModel
from pinn_mpc.training import TrainConfig, train_model
from tests.model_data import household_data


@pytest.fixture(scope="module", params=["physreg", "mlp"])
def model(request: pytest.FixtureRequest) -> LearnedModel:
    config = TrainConfig(n_seeds=3, epochs=3, depth=4)
    return train_model(household_data(4, 0), arch=request.param, config=config, progress=False)


def test_metrics_match_hand_computation(model: LearnedModel) -> None:
    df = household_data(2, 1)
    metrics = evaluate_model(model, df, [1, 3])
    one = model.predict_one_step(df)
    rows = one["row"]
    t_r = df["T_r"].to_numpy()
    assert metrics["one_step"]["T_r_mae"] == pytest.approx(
        np.mean(np.abs(one["T_r_next"].mean(0) - t_r[rows + 1]))
    )
    if model.arch == "mlp":
        assert metrics["one_step"]["T_m_mae"] is None
    else:
        assert metrics["one_step"]["T_m_mae"] == pytest.approx(
            np.mean(np.abs(one["T_m"].mean(0) - df["T_m"].to_numpy()[rows]))
        )
    # One recursive step is the one-step prediction.
    assert metrics["horizons"]["1"]["T_r_mae"] == pytest.approx(
        metrics["one_step"]["T_r_mae"], abs=1e-6
    )
    pred, starts = recursive_t_r(model, df, 3)
    assert starts[0] == model.depth + 1 and starts[-1] == len(df) - 4
    per_member = np.mean(np.abs(pred - t_r[starts + 3]), axis=1)
    assert metrics["horizons"]["3"]["T_r_mae_std"] == pytest.approx(np.std(per_member))
    assert metrics["persistence"]["horizons"]["3"]["T_r_mae"] == pytest.approx(
        np.mean(np.abs(t_r[starts] - t_r[starts + 3]))
    )


def test_no_t_m_column_gives_null(model: LearnedModel) -> None:
    df = household_data(2, 1).drop(columns=["T_m"])
    assert evaluate_model(model, df, [2])["one_step"]["T_m_mae"] is None


def test_horizon_longer_than_data(model: LearnedModel) -> None:
    df = household_data(1, 1).iloc[:20]
    with pytest.raises(InputError, match="horizon 48 need at least 54 rows"):
        evaluate_model(model, df, [48])


def test_export_rc(model: LearnedModel) -> None:
    if model.arch == "mlp":
        with pytest.raises(InputError, match="no physics block"):
            export_rc(model, source="test")
        return
    rc = export_rc(model, source="test")
    coef = model.physics_coefficients()
    assert coef is not None
    back = physics.to_coefficients(physics.params_from_summary(rc))
    for name in ("a12", "a21", "b", "c13"):
        assert getattr(back, name) == pytest.approx(getattr(coef, name), rel=1e-9)
    assert rc["source"] == "test" and len(rc["member_coefficients_per_s"]) == 3
    assert rc["time_constants_h"]["slow"] > rc["time_constants_h"]["fast"] > 0


def test_export_of_an_implausible_learned_rc_is_refused() -> None:
    config = TrainConfig(n_seeds=1, epochs=1, depth=4)
    model = train_model(household_data(4, 0), arch="physreg", config=config, progress=False)
    assert model.module.physics is not None
    with torch.no_grad():  # a21 = 1/(C_m R_rm) = 1e-12 /s: C_m near 1e15 J/K
        model.module.physics.log_a21.fill_(math.log(1e-12))
    with pytest.raises(InputError, match="learned 2R2C is not physical .*C_m_J_per_K = .* outside"):
        export_rc(model, source="test")
