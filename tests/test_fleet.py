"""Fleet simulation: per-building parameters, batched discretisation, the compiled substep loop."""

import dataclasses

import numpy as np
import pytest
import scipy.linalg

from pinn_mpc import physics
from pinn_mpc.errors import InputError
from pinn_mpc.simulator import (
    FLEET_SCALED,
    SimConfig,
    Simulator,
    backup_power,
    draw_fleet,
    fleet_matrices,
)
from scenarios.inputs.scenario_file import get_scenario


def reference_interval(x, u, t_a, g, i_g, config, params):
    """The simulator's physics written plainly with numpy: ZOH substeps (the exponential of the
    augmented matrix, as the simulator computes it), backup every substep."""
    a, b = physics.continuous_matrices(params)
    m = np.zeros((6, 6))
    m[:2, :2], m[:2, 2:] = a * config.substep_s, b * config.substep_s
    e = scipy.linalg.expm(m)
    ad, bd = e[:2, :2], e[:2, 2:]
    cfg = dataclasses.replace(config, params=params)
    delivered, changed, subs = 0.0, False, []
    for _ in range(config.n_substeps):
        p = float(backup_power(np.array([x[0]]), np.array([u]), cfg)[0])
        changed |= p != u
        delivered += p
        x = ad @ x + bd @ np.array([p, t_a, g, i_g])
        subs.append(x[0])
    return x, delivered / config.n_substeps, changed, np.array(subs)


@pytest.mark.parametrize("name", ["winter_household", "cold_storage"])
def test_fleet_matches_reference_and_single_buildings_to_1e12(name):
    scenario = get_scenario(name)
    config = scenario.sim
    fleet = draw_fleet(config.params, 5, spread=0.3, rng=np.random.default_rng(1))
    rng = np.random.default_rng(2)
    n_steps = 24
    # Full-power demands push buildings across the backup limits, so the rule is exercised.
    u = rng.choice([0.0, 0.5 * config.u_max_w, config.u_max_w], size=(n_steps, 5))
    exo = scenario.exogenous(days=1, seed=0, part="train")
    t_a, g, i_g = (exo[c].to_numpy()[:n_steps] for c in ("T_a", "G", "I_g"))
    sim = Simulator(config, fleet=fleet)
    sim.reset(scenario.initial_t_r_c, scenario.initial_t_m_c)
    fleet_out = [sim.step(u[k], t_a[k], g[k], i_g[k]) for k in range(n_steps)]
    overrides = 0
    for b, params in enumerate(fleet):
        single = Simulator(dataclasses.replace(config, params=params))
        single.reset(scenario.initial_t_r_c, scenario.initial_t_m_c)
        x = np.array([scenario.initial_t_r_c, scenario.initial_t_m_c])
        for k in range(n_steps):
            one = single.step(u[k, b], t_a[k], g[k], i_g[k])
            x, u_phys, changed, subs = reference_interval(
                x, u[k, b], t_a[k], g[k], i_g[k], config, params
            )
            got = fleet_out[k]
            np.testing.assert_allclose(got.t_r_sub_c[b], one.t_r_sub_c[0], rtol=0, atol=1e-12)
            np.testing.assert_allclose(got.t_r_sub_c[b], subs, rtol=0, atol=1e-12)
            np.testing.assert_allclose([got.t_r_c[b], got.t_m_c[b]], x, rtol=0, atol=1e-12)
            assert got.u_phys_w[b] == pytest.approx(u_phys, abs=1e-9)
            assert got.u_phys_w[b] == pytest.approx(one.u_phys_w[0], abs=1e-9)
            assert got.overridden[b] == changed == one.overridden[0]
            overrides += int(changed)
    assert overrides > 0, "the backup never acted: the test does not exercise it"


def test_fleet_matrices_equal_discretise_building_by_building():
    fleet = draw_fleet(physics.PAPER_HOUSEHOLD, 4, spread=0.5, rng=np.random.default_rng(0))
    ad, bd = fleet_matrices(fleet, 60.0)
    assert ad.shape == (4, 2, 2) and bd.shape == (4, 2, 4)
    for i, p in enumerate(fleet):
        ad_i, bd_i = physics.discretise(p, 60.0)
        np.testing.assert_allclose(ad[i], ad_i, rtol=1e-13, atol=0)
        np.testing.assert_allclose(bd[i], bd_i, rtol=1e-13, atol=0)


def test_draw_fleet_spread_and_zero_spread():
    base = dataclasses.replace(physics.PAPER_HOUSEHOLD, solar_aperture_m2=3.0)
    same = draw_fleet(base, 3, spread=0.0, rng=np.random.default_rng(0))
    assert same == (base, base, base)
    fleet = draw_fleet(base, 4000, spread=0.2, rng=np.random.default_rng(0))
    for name in FLEET_SCALED:
        log_ratio = np.log([getattr(p, name) / getattr(base, name) for p in fleet])
        # log-normal factors: mean 0 and std 0.2 within sampling error (4000 draws)
        assert abs(log_ratio.mean()) < 0.02
        assert log_ratio.std() == pytest.approx(0.2, rel=0.05)
    assert {p.eta for p in fleet} == {base.eta}


def test_fleet_errors_name_the_problem():
    rng = np.random.default_rng(0)
    with pytest.raises(InputError, match="spread must lie in"):
        draw_fleet(physics.PAPER_HOUSEHOLD, 3, spread=-0.1, rng=rng)
    with pytest.raises(ValueError, match="n_buildings must be"):
        draw_fleet(physics.PAPER_HOUSEHOLD, 0, spread=0.1, rng=rng)
    fleet = draw_fleet(physics.PAPER_HOUSEHOLD, 3, spread=0.1, rng=rng)
    with pytest.raises(ValueError, match="n_buildings=2 but the fleet has 3"):
        Simulator(SimConfig(), n_buildings=2, fleet=fleet)
    cooling = dataclasses.replace(physics.PAPER_HOUSEHOLD, eta=-2.5)
    with pytest.raises(InputError, match=r"building\(s\) \[1\] have an actuator of the other sign"):
        Simulator(SimConfig(), fleet=[fleet[0], cooling])
