"""Training: vectorised ensembles are deterministic and equal to members trained alone."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
import torch

from pinn_mpc import physics
from pinn_mpc.errors import InputError
from pinn_mpc.evaluation import evaluate_model
from pinn_mpc.export import export_rc
from pinn_mpc.training import TrainConfig, train_model
from tests.model_data import household_data


def _weights(model) -> dict[str, torch.Tensor]:
    return {k: v.clone() for k, v in model.module.state_dict().items()}


def test_training_is_deterministic_given_the_seeds() -> None:
    df = household_data(3, 0)
    config = TrainConfig(n_seeds=2, epochs=2, depth=4)
    a = _weights(train_model(df, arch="physnet", config=config, progress=False))
    b = _weights(train_model(df, arch="physnet", config=config, progress=False))
    for name in a:
        torch.testing.assert_close(a[name], b[name], rtol=0, atol=0)
    c = _weights(
        train_model(
            df, arch="physnet", config=dataclasses.replace(config, first_seed=5), progress=False
        )
    )
    assert not torch.equal(a["net.encoder.0.weight"], c["net.encoder.0.weight"])


@pytest.mark.parametrize("arch", ["mlp", "physreg", "physnet", "hybrid"])
def test_vectorised_ensemble_equals_members_trained_alone(arch: str) -> None:
    df = household_data(3, 0)
    config = TrainConfig(n_seeds=3, first_seed=10, epochs=2, depth=4)
    together = _weights(train_model(df, arch=arch, config=config, progress=False))
    alone = _weights(
        train_model(
            df,
            arch=arch,
            config=dataclasses.replace(config, n_seeds=1, first_seed=11),
            progress=False,
        )
    )
    for name, value in alone.items():
        torch.testing.assert_close(together[name][1], value[0], rtol=1e-4, atol=1e-5)


def test_training_reduces_the_error_and_moves_the_physics() -> None:
    df = household_data(6, 0)
    config = TrainConfig(n_seeds=2, epochs=8, depth=8)
    model = train_model(df, arch="physreg", config=config, progress=False)
    one = model.predict_one_step(df)
    rows = one["row"]
    mae = np.mean(np.abs(one["T_r_next"].mean(0) - df["T_r"].to_numpy()[rows + 1]))
    persistence = np.mean(np.abs(df["T_r"].to_numpy()[rows] - df["T_r"].to_numpy()[rows + 1]))
    assert mae < 0.5 * persistence
    learned = model.physics_coefficients()
    prior = physics.to_coefficients(physics.PAPER_HOUSEHOLD)
    assert learned is not None and learned.a12 != prior.a12
    assert learned.a11 == pytest.approx(learned.a12 + learned.c13, rel=1e-6)


def test_bad_configuration_and_short_data_are_input_errors() -> None:
    with pytest.raises(ValueError, match="unknown recipe 'fast'"):
        TrainConfig(recipe="fast")
    with pytest.raises(ValueError, match="lam must be a finite number >= 0"):
        TrainConfig(lam=-1.0)
    with pytest.raises(ValueError, match="unknown architecture 'cnn'"):
        train_model(household_data(3, 0), arch="cnn", config=TrainConfig(), progress=False)
    with pytest.raises(InputError, match=r"has 40 rows, but depth 8 needs at least 42 rows"):
        train_model(
            household_data(3, 0).iloc[:40], arch="mlp", config=TrainConfig(), progress=False
        )


#: A prior 30-40 % off the true paper_household values.
POOR_PRIOR = physics.RCParams(
    r_ra_k_per_w=3.75e-3 * 1.4,
    r_rm_k_per_w=7.5e-4 * 0.7,
    c_r_j_per_k=4.0e6 * 1.3,
    c_m_j_per_k=4.0e7,
)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("arch", "prior"), [("physnet", None), ("physreg", None), ("physreg", POOR_PRIOR)]
)
def test_paper_household_accuracy_and_identified_rc(
    arch: str, prior: physics.RCParams | None
) -> None:
    """120 training days (seed 0), 5 test days (seed 1): the issue's acceptance thresholds."""
    train, test = household_data(120, 0), household_data(5, 1)
    config = TrainConfig(n_seeds=5, prior=prior, recipe="converged")
    model = train_model(train, arch=arch, config=config, progress=False)
    metrics = evaluate_model(model, test, [48])
    assert metrics["one_step"]["T_r_mae"] <= 0.05
    t_m_mae = metrics["one_step"]["T_m_mae"]
    assert t_m_mae is not None and t_m_mae <= 0.10
    assert metrics["horizons"]["48"]["T_r_mae"] <= 0.3
    persistence = metrics["persistence"]["horizons"]["48"]["T_r_mae"]
    assert metrics["horizons"]["48"]["T_r_mae"] < persistence
    rc = export_rc(model, source="test")
    truth = physics.PAPER_HOUSEHOLD
    assert rc["R_ra_K_per_W"] == pytest.approx(truth.r_ra_k_per_w, rel=0.15)
    assert rc["C_r_J_per_K"] == pytest.approx(truth.c_r_j_per_k, rel=0.15)
    assert rc["R_rm_K_per_W"] == pytest.approx(truth.r_rm_k_per_w, rel=0.25)
    assert rc["C_m_J_per_K"] == pytest.approx(truth.c_m_j_per_k, rel=0.25)


@pytest.mark.slow
@pytest.mark.parametrize("scenario_name", ["paper_household", "winter_household", "cold_storage"])
def test_hybrid_export_stays_physical(scenario_name: str) -> None:
    """The hybrid's physics block starts at the identification and stays there: R/C values and
    solar aperture within 10 % of the truth (PhysNet's drifted by up to 53 % on these), and
    its one-step T_r error is no worse than 0.1 C on other days."""
    from pinn_mpc.data import validate_timeseries
    from scenarios.inputs.scenario_file import get_scenario
    from scenarios.running.datagen import generate

    scenario = get_scenario(scenario_name)
    truth = scenario.sim.params

    def data(days: int, seed: int) -> pd.DataFrame:
        frame = generate(scenario, days=days, seed=seed, policy="random-level")
        return validate_timeseries(frame)

    config = TrainConfig(n_seeds=5, depth=16, eta=truth.eta)
    model = train_model(data(60, 0), arch="hybrid", config=config, progress=False)
    rc = physics.params_from_summary(export_rc(model, source="test"))
    for name in ("r_ra_k_per_w", "r_rm_k_per_w", "c_r_j_per_k", "c_m_j_per_k", "solar_aperture_m2"):
        assert getattr(rc, name) == pytest.approx(getattr(truth, name), rel=0.10, abs=1e-9), name
    metrics = evaluate_model(model, data(5, 1), [1])
    assert metrics["one_step"]["T_r_mae"] <= 0.1
