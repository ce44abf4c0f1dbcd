"""The shared horizon objective: numpy and torch agree and match a hand computation."""

import numpy as np
import pytest
import torch

from controllers.base import ControlSpec, Forecast
from controllers.objective import (
    OPEN_BAND_C,
    HorizonObjective,
    band_violation_k,
    energy_cost_eur,
    planning_band,
)
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InternalError

SPEC = ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0),), dt_s=1800.0, comfort_weight_eur_per_kh=2.0)


def _forecast() -> Forecast:
    n = 4
    return Forecast(
        time_of_day_h=np.arange(n) * 0.5,
        T_a=np.zeros(n),
        G=np.zeros(n),
        I_g=np.zeros(n),
        price=np.array([0.1, 0.2, 0.3, 0.4]),
        T_min=np.array([18.0, 20.0, 20.0, 17.0]),
        T_max=np.array([24.0, 23.0, 22.0, 24.0]),
    )


def test_hand_computed_objective_in_numpy_and_torch():
    objective = HorizonObjective.from_forecast(_forecast(), SPEC, 3)
    # The end of interval j must lie in the bands of intervals j and j+1.
    np.testing.assert_array_equal(objective.t_min_c, [20.0, 20.0, 20.0])
    np.testing.assert_array_equal(objective.t_max_c, [23.0, 22.0, 22.0])
    u = np.array([2000.0, 0.0, 4000.0])
    t_r = np.array([19.5, 22.5, 21.0])
    # energy: 2 kW x 0.5 h x 0.1 + 0 + 4 kW x 0.5 h x 0.3 = 0.1 + 0.6; comfort: 2 x 0.5 x (0.5 + 0.5)
    expected = 0.1 + 0.6 + 2.0 * 0.5 * (0.5 + 0.5)
    assert float(objective.cost(u, t_r)) == pytest.approx(expected, rel=1e-12)
    batch = np.stack([u, u[::-1]])
    temps = np.stack([t_r, t_r[::-1]])
    in_torch = objective.cost_torch(torch.tensor(batch), torch.tensor(temps)).numpy()
    np.testing.assert_allclose(in_torch, objective.cost(batch, temps), rtol=1e-12)
    in_float32 = objective.cost_torch(
        torch.tensor(batch, dtype=torch.float32), torch.tensor(temps, dtype=torch.float32)
    )
    assert in_float32.dtype == torch.float32
    np.testing.assert_allclose(in_float32.numpy(), objective.cost(batch, temps), rtol=1e-6)


def test_primitives_and_the_shorter_forecast():
    assert band_violation_k(np.array([17.0, 21.0, 25.0]), 18.0, 24.0).tolist() == [1.0, 0.0, 1.0]
    assert energy_cost_eur(1000.0, 0.25, 2.0) == pytest.approx(0.5)
    lower, upper = planning_band(_forecast(), 6)  # the last band is repeated
    assert lower.tolist() == [20.0, 20.0, 20.0, 17.0, 17.0, 17.0]
    assert upper.tolist() == [23.0, 22.0, 22.0, 24.0, 24.0, 24.0]


def test_until_frees_the_steps_after_the_run_end():
    objective = HorizonObjective.from_forecast(_forecast(), SPEC, 4)
    cut = objective.until(2)
    assert cut.price_eur_per_kwh.tolist() == [0.1, 0.2, 0.0, 0.0]
    assert cut.t_min_c[2:].tolist() == [OPEN_BAND_C[0]] * 2
    assert objective.price_eur_per_kwh[2] == 0.3  # the original is untouched
    assert objective.until(4) is objective
    with pytest.raises(InternalError, match="one shape"):
        HorizonObjective(
            price_eur_per_kwh=np.zeros(3),
            t_min_c=np.zeros(2),
            t_max_c=np.zeros(3),
            dt_h=0.5,
            comfort_weight_eur_per_kh=1.0,
        )


def test_tightened_narrows_the_band_and_meets_in_the_middle():
    objective = HorizonObjective.from_forecast(_forecast(), SPEC, 4)  # bands 20-23, 20-22, ...
    narrow = objective.tightened(0.25)
    assert narrow.t_min_c.tolist() == [20.25, 20.25, 20.25, 17.25]
    assert narrow.t_max_c.tolist() == [22.75, 21.75, 21.75, 23.75]
    # A margin wider than half the 2 K band leaves the middle; price and weights unchanged.
    middle = objective.tightened(1.5)
    assert middle.t_min_c.tolist() == [21.5, 21.0, 21.0, 18.5]
    assert middle.t_max_c.tolist() == [21.5, 21.0, 21.0, 22.5]
    assert middle.price_eur_per_kwh.tolist() == objective.price_eur_per_kwh.tolist()
    assert objective.tightened(0.0) is objective
