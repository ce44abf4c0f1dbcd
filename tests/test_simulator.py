"""Simulator against the exact 2R2C solution and the paper's backup rule."""

import numpy as np
import pytest

from pinn_mpc import physics
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.simulator import SimConfig, Simulator, backup_power

WIDE = SimConfig(backup_low_c=-50.0, backup_high_c=80.0)


def test_interval_without_backup_is_exact_zoh():
    sim = Simulator(WIDE, n_buildings=3)
    sim.reset(np.array([17.0, 19.0, 21.0]), np.array([16.0, 18.0, 22.0]))
    u = np.array([0.0, 2500.0, 5000.0])
    res = sim.step(u, 7.5)
    ad, bd = physics.discretise(WIDE.params, 1800.0)
    x0 = np.array([[17.0, 16.0], [19.0, 18.0], [21.0, 22.0]])
    d = np.stack([u, np.full(3, 7.5), np.zeros(3), np.zeros(3)], axis=1)
    expected = physics.step(x0, d, ad, bd)
    np.testing.assert_allclose(np.stack([res.t_r_c, res.t_m_c], axis=1), expected, atol=1e-10)
    np.testing.assert_allclose(res.u_phys_w, u)
    assert not res.overridden.any()
    assert res.t_r_sub_c.shape == (3, 30)
    assert res.t_r_sub_c[:, -1] == pytest.approx(res.t_r_c)


def test_long_run_reaches_steady_state():
    sim = Simulator(WIDE)
    sim.reset(10.0, 10.0)
    for _ in range(48 * 60):
        res = sim.step(2000.0, 3.0)
    target = physics.steady_state(WIDE.params, u_w=2000.0, t_a_c=3.0)
    assert res.t_r_c[0] == pytest.approx(target[0], abs=1e-6)
    assert res.t_m_c[0] == pytest.approx(target[1], abs=1e-6)


def test_backup_rule_heating_and_cooling():
    cfg = SimConfig(backup_low_c=17.0, backup_high_c=20.5)
    t = np.array([16.0, 18.0, 21.0])
    np.testing.assert_array_equal(backup_power(t, np.full(3, 1000.0), cfg), [5000.0, 1000.0, 0.0])
    cooling = SimConfig(
        params=physics.RCParams(
            r_ra_k_per_w=1e-2, r_rm_k_per_w=1e-3, c_r_j_per_k=1e6, c_m_j_per_k=1e7, eta=-2.5
        ),
        u_max_w=3000.0,
        backup_low_c=0.0,
        backup_high_c=8.0,
    )
    t = np.array([-1.0, 4.0, 9.0])
    np.testing.assert_array_equal(backup_power(t, np.full(3, 500.0), cooling), [0.0, 500.0, 3000.0])


def test_backup_caps_room_temperature_and_lowers_delivered_power():
    cfg = SimConfig()
    sim = Simulator(cfg)
    sim.reset(20.0, 20.0)
    overridden = 0
    for _ in range(48):
        res = sim.step(5000.0, 15.0)
        assert res.t_r_sub_c.max() <= cfg.backup_high_c + 0.1
        overridden += int(res.overridden[0])
    assert overridden > 0
    assert res.u_phys_w[0] < 5000.0


def test_batched_equals_one_by_one_and_is_deterministic():
    rng = np.random.default_rng(3)
    u = rng.choice([0.0, 5000.0], size=(20, 4))
    t_a = rng.uniform(5, 25, size=(20, 4))
    batch = Simulator(SimConfig(), n_buildings=4)
    batch.reset(17.0, 17.0)
    out_b = [batch.step(u[k], t_a[k]) for k in range(20)]
    for b in range(4):
        one = Simulator(SimConfig())
        one.reset(17.0, 17.0)
        for k in range(20):
            r = one.step(u[k, b], t_a[k, b])
            assert r.t_r_c[0] == out_b[k].t_r_c[b]
            assert r.u_phys_w[0] == out_b[k].u_phys_w[b]


def test_noise_is_seeded():
    cfg = SimConfig(noise_std_c=0.1)
    a, b, c = Simulator(cfg, seed=1), Simulator(cfg, seed=1), Simulator(cfg, seed=2)
    for s in (a, b, c):
        s.reset(18.0, 18.0)
    assert a.measure() == pytest.approx(b.measure())
    assert a.measure()[0] != c.measure()[0]
    assert Simulator(SimConfig(), seed=1).measure()[0] == 0.0


def test_config_errors_name_the_problem():
    with pytest.raises(InputError, match="whole multiple"):
        SimConfig(dt_s=1000.0, substep_s=300.0)
    with pytest.raises(InputError, match="low < high"):
        SimConfig(backup_low_c=21.0, backup_high_c=20.0)
    with pytest.raises(InternalError, match="non-finite"):
        Simulator(SimConfig()).step(np.nan, 10.0)
