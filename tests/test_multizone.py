"""The multi-zone RC building against analytic truth: each uncoupled zone is the 2R2C simulator,
two identical coupled zones are one, a coupled steady state solved by hand, the energy balance,
the coupling's symmetry, and the refusals."""

import dataclasses

import numpy as np
import pytest
import scipy.linalg

from pinn_mpc import physics
from pinn_mpc.actuator import Actuator, ActuatorSpec
from pinn_mpc.multizone import (
    EXOGENOUS_NAMES,
    MultiZoneConfig,
    MultiZoneParams,
    MultiZoneSimulator,
    ZoneRC,
    backup_power,
    continuous_matrices,
    discretise,
    steady_state,
    wall_tuples,
)
from pinn_mpc.physics import PAPER_HOUSEHOLD, RCParams
from pinn_mpc.simulator import SimConfig, Simulator
from pinn_mpc.zones import ZoneSpec

HEAT_PUMP = Actuator(kind="heat_pump", min_modulation=0.3)
#: A lighter building than the paper's (slow time constant about 12 h), so long runs are short.
LIGHT = RCParams(r_ra_k_per_w=5e-3, r_rm_k_per_w=1e-3, c_r_j_per_k=2e6, c_m_j_per_k=1e7)


def _zone(name: str, rc: RCParams, share: float, sun: str = "G") -> ZoneRC:
    return ZoneRC(zone=ZoneSpec(name), rc=rc, gain_share=share, solar_input=sun)


def _walls(n: int, pairs: dict[tuple[int, int], float]) -> np.ndarray:
    u = np.zeros((n, n))
    for (i, j), v in pairs.items():
        u[i, j] = u[j, i] = v
    return u


def _weather(rng: np.random.Generator) -> dict[str, float]:
    return {name: float(rng.uniform(*span)) for name, span in (
        ("T_a", (-8.0, 14.0)), ("G", (0.0, 400.0)), ("I_g", (0.0, 800.0)),
        ("G_south", (0.0, 600.0)), ("G_east", (0.0, 300.0)), ("G_west", (0.0, 300.0)),
        ("G_north", (0.0, 80.0)),
    )}


def _alone(rc: RCParams, spec: ActuatorSpec, low: float, high: float) -> Simulator:
    """The package's 2R2C simulator of one zone with its one actuator: the zone's heat per watt
    (+1 heating, -1 cooling) is the 2R2C's eta, the actuator's efficiency its actuator."""
    eta = spec.sign * 1.0
    return Simulator(SimConfig(
        params=dataclasses.replace(rc, eta=eta), u_max_w=spec.upper_w, actuator=spec.efficiency,
        backup_low_c=low, backup_high_c=high,
    ))


# Three zones: a heat pump (cycling below 30 % of its power) on a south zone, an ideal cooler on
# a sunny zone under G, a resistance heater on an east zone; each zone its own backup limits.
ZONES = (
    _zone("south", dataclasses.replace(LIGHT, solar_aperture_m2=6.0, solar_to_air_fraction=0.3), 0.5, "G_south"),
    _zone("glass", dataclasses.replace(LIGHT, c_m_j_per_k=2e7, solar_aperture_m2=20.0, gain_to_air_fraction=0.6), 0.3),
    _zone("east", dataclasses.replace(PAPER_HOUSEHOLD, solar_aperture_m2=3.0), 0.2, "G_east"),
)
ACTUATORS = (
    ActuatorSpec(upper_w=4000.0, zone=0, efficiency=HEAT_PUMP),
    ActuatorSpec(upper_w=3000.0, zone=1, heats=False),
    ActuatorSpec(upper_w=5000.0, zone=2),
)
LOW, HIGH = (19.0, 21.0, 18.0), (21.5, 23.0, 20.5)


def _config(walls: np.ndarray, **kw) -> MultiZoneConfig:
    params = MultiZoneParams(zones=ZONES, wall_conductance_w_per_k=wall_tuples(walls))
    return MultiZoneConfig(params=params, actuators=ACTUATORS, backup_low_c=LOW, backup_high_c=HIGH, **kw)


def test_uncoupled_zones_are_each_the_2r2c_simulator_backup_thermostat_included():
    sim = MultiZoneSimulator(_config(np.zeros((3, 3))))
    alone = [_alone(z.rc, dataclasses.replace(a, zone=0), lo, hi)
             for z, a, lo, hi in zip(ZONES, ACTUATORS, LOW, HIGH, strict=True)]
    start_r, start_m = np.array([20.0, 24.0, 16.0]), np.array([19.0, 23.0, 16.5])
    sim.reset(start_r, start_m)
    for z, one in enumerate(alone):
        one.reset(start_r[z], start_m[z])
    rng = np.random.default_rng(3)
    overrides = np.zeros(3, dtype=int)
    for _ in range(96):
        demand = rng.uniform(0.0, 1.0, 3) * np.array([4000.0, 3000.0, 5000.0])
        weather = _weather(rng)
        res = sim.step(demand, weather)
        for z, one in enumerate(alone):
            sun = weather[ZONES[z].solar_input]
            ref = one.step(demand[z], weather["T_a"], sun, ZONES[z].gain_share * weather["I_g"])
            np.testing.assert_allclose(res.t_r_sub_c[0, :, z], ref.t_r_sub_c[0], rtol=0, atol=1e-10)
            assert res.t_m_c[0, z] == pytest.approx(ref.t_m_c[0], abs=1e-10)
            assert res.power_w[0, z] == pytest.approx(ref.u_phys_w[0], abs=1e-9)
            assert res.overridden[0, z] == ref.overridden[0]
        overrides += res.overridden[0]
    assert np.all(overrides > 0), f"the backup never acted in some zone: {overrides}"


def test_a_fleet_steps_each_building_as_it_steps_alone():
    walls = _walls(3, {(0, 1): 120.0, (1, 2): 60.0})
    cfg = _config(walls)
    other = MultiZoneParams(
        zones=tuple(dataclasses.replace(z, rc=dataclasses.replace(z.rc, c_r_j_per_k=3e6)) for z in ZONES),
        wall_conductance_w_per_k=2 * walls,
    )
    fleet = MultiZoneSimulator(cfg, fleet=[cfg.params, other])
    single = [MultiZoneSimulator(cfg), MultiZoneSimulator(dataclasses.replace(cfg, params=other))]
    fleet.reset(20.0, 19.0)
    for s in single:
        s.reset(20.0, 19.0)
    rng = np.random.default_rng(0)
    for _ in range(20):
        demand = rng.uniform(0.0, 3000.0, (2, 3))
        weather = _weather(rng)
        res = fleet.step(demand, weather)
        for b, s in enumerate(single):
            ref = s.step(demand[b], weather)
            np.testing.assert_allclose(res.t_r_sub_c[b], ref.t_r_sub_c[0], rtol=0, atol=1e-10)
            np.testing.assert_allclose(res.power_w[b], ref.power_w[0], rtol=0, atol=1e-9)


def test_two_identical_coupled_zones_with_identical_inputs_stay_equal_and_are_the_one_zone_simulator():
    rc = dataclasses.replace(PAPER_HOUSEHOLD, solar_aperture_m2=4.0, solar_to_air_fraction=0.2)
    params = MultiZoneParams(
        zones=(_zone("a", rc, 0.5), _zone("b", rc, 0.5)), wall_conductance_w_per_k=_walls(2, {(0, 1): 300.0})
    )
    heaters = tuple(ActuatorSpec(upper_w=5000.0, zone=z) for z in (0, 1))
    sim = MultiZoneSimulator(MultiZoneConfig(params=params, actuators=heaters))
    one = _alone(rc, heaters[0], 17.0, 20.5)
    sim.reset(18.0, 17.5)
    one.reset(18.0, 17.5)
    rng = np.random.default_rng(1)
    overridden = 0
    for _ in range(96):
        u, weather = rng.uniform(0.0, 5000.0), _weather(rng)
        res = sim.step([u, u], weather)
        ref = one.step(u, weather["T_a"], weather["G"], 0.5 * weather["I_g"])
        np.testing.assert_allclose(res.t_r_sub_c[0, :, 0], res.t_r_sub_c[0, :, 1], rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.t_r_sub_c[0, :, 0], ref.t_r_sub_c[0], rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.t_m_c[0], ref.t_m_c[0], rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.power_w[0], ref.u_phys_w[0], rtol=0, atol=1e-9)
        assert list(res.overridden[0]) == [ref.overridden[0]] * 2
        overridden += int(ref.overridden[0])
    assert overridden > 0


def _two_zone_by_hand():
    """A south zone (heat pump, windows on G_south) and a north zone (no actuator, no windows)
    joined by a wall of 150 W/K, internal gains split 0.7 / 0.3, solved as a 2-node conductance
    network: at equilibrium each mass passes on what it receives, so each air node balances its
    zone's whole heat against the outdoor air and the wall's U (T_other - T_self)."""
    south = dataclasses.replace(LIGHT, solar_aperture_m2=5.0, solar_to_air_fraction=0.4, gain_to_air_fraction=0.5)
    north = dataclasses.replace(LIGHT, r_ra_k_per_w=8e-3, c_r_j_per_k=3e6)
    params = MultiZoneParams(
        zones=(_zone("south", south, 0.7, "G_south"), _zone("north", north, 0.3)),
        wall_conductance_w_per_k=_walls(2, {(0, 1): 150.0}),
    )
    actuators = (ActuatorSpec(upper_w=3000.0, zone=0, efficiency=Actuator(kind="heat_pump")),)
    p_w, t_a, sun, i_g, wall = 1200.0, 0.0, 250.0, 400.0, 150.0
    cop = 0.45 * 308.15 / 35.0  # 45 % of Carnot between 35 C supply and 0 C outdoor air
    q1 = cop * p_w + 5.0 * sun + 0.7 * i_g
    q2 = 0.3 * i_g
    g1, g2 = 1.0 / 5e-3, 1.0 / 8e-3
    # (g1 + U) T1 - U T2 = g1 T_a + q1;  -U T1 + (g2 + U) T2 = g2 T_a + q2  (Cramer)
    det = (g1 + wall) * (g2 + wall) - wall**2
    t1 = ((g1 * t_a + q1) * (g2 + wall) + wall * (g2 * t_a + q2)) / det
    t2 = ((g2 * t_a + q2) * (g1 + wall) + wall * (g1 * t_a + q1)) / det
    # Each mass sits above its air by what it receives times R_rm.
    m1 = t1 + 1e-3 * (0.6 * 5.0 * sun + 0.5 * 0.7 * i_g)
    m2 = t2  # the north zone's gains all reach its air (beta = 1)
    weather = {"T_a": t_a, "G_south": sun, "I_g": i_g}
    return params, actuators, p_w, weather, np.array([t1, t2]), np.array([m1, m2])


def test_steady_state_of_two_coupled_zones_is_the_conductance_network_solved_by_hand():
    params, actuators, p_w, weather, t_r, t_m = _two_zone_by_hand()
    assert t_r[0] - t_r[1] > 3.0  # the wall carries heat: a real check of the coupling
    got_r, got_m = steady_state(params, actuators, power_w=[p_w], weather=weather)
    np.testing.assert_allclose(got_r, t_r, rtol=1e-12)
    np.testing.assert_allclose(got_m, t_m, rtol=1e-12)
    sim = MultiZoneSimulator(MultiZoneConfig(params=params, actuators=actuators, backup_low_c=-50.0, backup_high_c=80.0))
    sim.reset(10.0, 10.0)
    for _ in range(30 * 48):  # 30 days, about 29 of the slowest time constant (25 h)
        res = sim.step([p_w], weather)
    np.testing.assert_allclose(res.t_r_c[0], t_r, rtol=0, atol=1e-8)
    np.testing.assert_allclose(res.t_m_c[0], t_m, rtol=0, atol=1e-8)
    assert not res.overridden.any() and res.power_w[0, 0] == p_w


def test_one_zone_matrices_are_the_2r2c_and_the_coupling_is_symmetric():
    rc = dataclasses.replace(PAPER_HOUSEHOLD, solar_aperture_m2=7.0, solar_to_air_fraction=0.3, gain_to_air_fraction=0.8)
    one = MultiZoneParams(zones=(_zone("room", rc, 1.0),), wall_conductance_w_per_k=[[0.0]])
    mats = continuous_matrices(one, (ActuatorSpec(upper_w=5000.0),))
    a, b = physics.continuous_matrices(rc)
    np.testing.assert_allclose(mats.a, a, rtol=1e-15)
    np.testing.assert_allclose(mats.b_u[:, 0], b[:, 0], rtol=1e-15)
    np.testing.assert_allclose(mats.b_d[:, :3], b[:, 1:], rtol=1e-15)  # (T_a, G, I_g)
    assert not mats.b_d[:, 3:].any()
    ad, bd = physics.discretise(rc, 1800.0)
    zoh = discretise(one, (ActuatorSpec(upper_w=5000.0),), 1800.0)
    np.testing.assert_allclose(zoh.a, ad, rtol=1e-12)
    np.testing.assert_allclose(zoh.b_u[:, 0], bd[:, 0], rtol=1e-12)
    np.testing.assert_allclose(zoh.b_d[:, :3], bd[:, 1:], rtol=1e-12)

    params = _config(_walls(3, {(0, 1): 120.0, (1, 2): 60.0, (0, 2): 10.0})).params
    mats = continuous_matrices(params, ACTUATORS)
    capacities = np.array([z.rc.c_r_j_per_k for z in ZONES] + [z.rc.c_m_j_per_k for z in ZONES])
    flows = capacities[:, None] * mats.a  # W/K between nodes: reciprocal in an RC network
    np.testing.assert_allclose(flows, flows.T, rtol=1e-14)
    assert flows[0, 1] == pytest.approx(120.0) and flows[1, 2] == pytest.approx(60.0)
    # Each row of flows sums to minus the node's conductance to the outdoor air.
    np.testing.assert_allclose(flows.sum(axis=1), [-1.0 / z.rc.r_ra_k_per_w for z in ZONES] + [0.0] * 3, atol=1e-9)


def test_swapping_two_zones_swaps_their_temperatures():
    walls = _walls(3, {(0, 1): 120.0, (1, 2): 60.0})
    cfg = _config(walls)
    order = [2, 0, 1]
    swapped = MultiZoneConfig(
        params=MultiZoneParams(zones=tuple(ZONES[i] for i in order), wall_conductance_w_per_k=walls[np.ix_(order, order)]),
        actuators=tuple(dataclasses.replace(ACTUATORS[i], zone=order.index(ACTUATORS[i].zone)) for i in order),
        backup_low_c=tuple(LOW[i] for i in order), backup_high_c=tuple(HIGH[i] for i in order),
    )
    sims = MultiZoneSimulator(cfg), MultiZoneSimulator(swapped)
    start = np.array([20.0, 22.0, 18.0])
    sims[0].reset(start, start - 1.0)
    sims[1].reset(start[order], start[order] - 1.0)
    rng = np.random.default_rng(5)
    for _ in range(24):
        demand, weather = rng.uniform(0.0, 3000.0, 3), _weather(rng)
        a, b = sims[0].step(demand, weather), sims[1].step(demand[order], weather)
        np.testing.assert_allclose(b.t_r_sub_c[0], a.t_r_sub_c[0][:, order], rtol=0, atol=1e-10)
        np.testing.assert_array_equal(b.overridden[0], a.overridden[0][order])


def test_energy_balance_over_an_interval_heat_in_is_stored_plus_lost():
    """Over one interval without the backup acting: the actuators' heat (sign x COP x power),
    the sun on each zone's aperture and the internal gains equal the capacities' stored heat
    plus the loss to the outdoor air, the integral of (T_r - T_a)/R_ra; the walls only move
    heat between zones. The integral of the state is exact: the ZOH of the state augmented by
    its own integral."""
    cfg = dataclasses.replace(_config(_walls(3, {(0, 1): 120.0, (1, 2): 60.0})), backup_low_c=-50.0, backup_high_c=80.0)
    sim = MultiZoneSimulator(cfg)
    x0_r, x0_m = np.array([20.0, 24.0, 17.0]), np.array([19.0, 22.0, 18.0])
    sim.reset(x0_r, x0_m)
    weather = dict(zip(EXOGENOUS_NAMES, (2.0, 150.0, 600.0, 420.0, 90.0, 40.0, 10.0), strict=True))
    power = np.array([2500.0, 1800.0, 3000.0])
    res = sim.step(power, weather)
    assert not res.overridden.any()
    h = cfg.dt_s
    cop = 0.45 * 308.15 / (35.0 - 2.0)
    heat_w = cop * 2500.0 - 1800.0 + 3000.0
    heat_w += 6.0 * weather["G_south"] + 20.0 * weather["G"] + 3.0 * weather["G_east"] + weather["I_g"]
    x0 = np.concatenate([x0_r, x0_m])
    x1 = np.concatenate([res.t_r_c[0], res.t_m_c[0]])
    caps = np.array([z.rc.c_r_j_per_k for z in ZONES] + [z.rc.c_m_j_per_k for z in ZONES])
    stored_j = float(caps @ (x1 - x0))
    mats = continuous_matrices(cfg.params, cfg.actuators)
    d = np.array([weather[n] for n in EXOGENOUS_NAMES])
    gains = np.array([cop, 1.0, 1.0])
    forcing = mats.b_u @ (gains * power) + mats.b_d @ d
    n = len(x0)
    m = np.zeros((2 * n + 1, 2 * n + 1))  # (x, its integral, 1)
    m[:n, :n], m[:n, -1], m[n : 2 * n, :n] = mats.a, forcing, np.eye(n)
    integral = (scipy.linalg.expm(m * h) @ np.concatenate([x0, np.zeros(n), [1.0]]))[n : 2 * n]
    lost_j = sum((integral[z] - weather["T_a"] * h) / zone.rc.r_ra_k_per_w for z, zone in enumerate(ZONES))
    assert abs(heat_w * h - stored_j - lost_j) < 1e-9 * heat_w * h
    assert abs(stored_j) > 0.1 * heat_w * h  # a balance with something stored


def test_a_dual_setpoint_zone_heats_below_its_band_and_cools_above_it():
    rc = LIGHT
    params = MultiZoneParams(zones=(_zone("office", rc, 1.0),), wall_conductance_w_per_k=[[0.0]])
    both = (ActuatorSpec(upper_w=3000.0), ActuatorSpec(upper_w=2000.0, lower_w=200.0, heats=False))
    cfg = MultiZoneConfig(params=params, actuators=both, backup_low_c=19.0, backup_high_c=24.0)
    t = np.array([[18.0], [21.0], [25.0]])
    demand = np.full((3, 2), 1000.0)
    np.testing.assert_array_equal(
        backup_power(t, demand, cfg), [[3000.0, 200.0], [1000.0, 1000.0], [0.0, 2000.0]]
    )
    sim = MultiZoneSimulator(cfg, n_buildings=2)
    sim.reset(np.array([[15.0], [28.0]]), np.array([[15.0], [28.0]]))
    res = sim.step([500.0, 500.0], {"T_a": 20.0, "I_g": 0.0})
    # cold building: the heater was forced on and the cooler off; warm: the other way round
    assert res.power_w[0, 0] > 500.0 and res.power_w[0, 1] < 500.0
    assert res.power_w[1, 0] < 500.0 and res.power_w[1, 1] > 500.0
    assert res.overridden.all()
    assert res.t_r_sub_c.shape == (2, 30, 1)
    assert res.t_r_c[0, 0] > 15.0 and res.t_r_c[1, 0] < 28.0


def test_measurements_carry_seeded_noise_per_zone():
    cfg = dataclasses.replace(_config(np.zeros((3, 3))), noise_std_c=0.5)
    sim = MultiZoneSimulator(cfg, n_buildings=4000, seed=7)
    sim.reset(20.0, 19.0)
    first = sim.measure()
    assert first.shape == (4000, 3)
    noise = first - 20.0
    np.testing.assert_allclose(noise.std(axis=0), 0.5, rtol=0.05)
    assert abs(np.corrcoef(noise.T)[0, 1]) < 0.05  # independent per zone
    sim.reset(20.0, 19.0, seed=7)
    np.testing.assert_array_equal(sim.measure(), first)
    np.testing.assert_array_equal(MultiZoneSimulator(_config(np.zeros((3, 3)))).measure(), np.zeros((1, 3)))


def _params(walls, zones=ZONES) -> MultiZoneParams:
    return MultiZoneParams(zones=zones, wall_conductance_w_per_k=walls)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: _params(_walls(3, {(0, 1): -5.0})), r"wall_conductance_w_per_k\[0, 1\] \(south-glass\) = -5 W/K is negative"),
        (lambda: _params(np.zeros((2, 2))), r"has shape \(2, 2\), but the building has 3 zone\(s\) \(south, glass, east\); give a \(3, 3\) array"),
        (lambda: _params(np.diag([0.0, 1.0, 0.0])), r"\[1, 1\] \(glass-glass\) = 1 W/K: a zone has no wall with itself"),
        (lambda: _params(np.triu(np.ones((3, 3)), 1)), r"\[0, 1\] \(south-glass\) = 1 W/K but \[1, 0\] = 0 W/K.*make the array symmetric"),
        (lambda: _params(_walls(3, {(0, 2): np.inf})), r"\[0, 2\] \(south-east\) is inf, not a finite conductance"),
        (lambda: _params(_walls(3, {(0, 2): 5e9})), r"above the plausible 1e\+08 W/K; give it in W/K"),
        (lambda: _params(np.zeros((3, 3)), ZONES[:2] + (dataclasses.replace(ZONES[2], gain_share=0.5),)), r"gain shares sum to 1\.3 .*must sum to 1"),
        (lambda: _params(np.zeros((3, 3)), (ZONES[0], ZONES[1], dataclasses.replace(ZONES[2], zone=ZoneSpec("south")))), r"\['south'\] appear more than once"),
        (lambda: _zone("x", dataclasses.replace(LIGHT, eta=-2.5), 1.0), r"ZoneRC\('x'\)\.rc\.eta = -2\.5: a zone's heat per watt is its actuators'"),
        (lambda: _zone("x", LIGHT, 1.0, "G_up"), r"solar_input = 'G_up' is unknown; choose one of G, G_south"),
        (lambda: _zone("x", LIGHT, 1.2), r"gain_share = 1\.2 must lie in \[0, 1\]"),
        (lambda: MultiZoneConfig(params=_params(np.zeros((3, 3))), actuators=(ActuatorSpec(upper_w=1.0, zone=3),)), r"actuators\[0\]\.zone = 3 is out of range: the building has 3 zone\(s\) \(south, glass, east\), indices 0 \.\. 2"),
        (lambda: continuous_matrices(_params(np.zeros((3, 3))), (ActuatorSpec(upper_w=1.0, zone=5),)), r"actuators\[0\]\.zone = 5 is out of range"),
        (lambda: _config(np.zeros((3, 3)), substep_s=7.0), r"dt_s = 1800\.0 must be a whole multiple of substep_s = 7\.0"),
        (lambda: dataclasses.replace(_config(np.zeros((3, 3))), backup_high_c=(25.0, 20.0, 25.0)), r"backup limits of zone 'glass' must satisfy low < high, got 21 / 20"),
        (lambda: dataclasses.replace(_config(np.zeros((3, 3))), backup_low_c=(17.0, 18.0)), r"backup_low_c = \(17\.0, 18\.0\) must be a number or 3 finite numbers"),
    ],
)
def test_misuse_is_refused_in_one_line_naming_it(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_a_step_or_a_reset_of_the_wrong_shape_and_a_fleet_of_other_zones_are_refused():
    cfg = _config(np.zeros((3, 3)))
    sim = MultiZoneSimulator(cfg, n_buildings=2)
    weather = {"T_a": 0.0, "I_g": 0.0, "G": 0.0, "G_south": 0.0, "G_east": 0.0}
    with pytest.raises(ValueError, match=r"power_w has shape \(2, 2\); give one power per actuator, \(3,\) or \(2, 3\)"):
        sim.step(np.zeros((2, 2)), weather)
    with pytest.raises(ValueError, match=r"weather lacks \['G_east'\]: the building needs T_a, G, I_g, G_south, G_east"):
        sim.step(np.zeros(3), {k: v for k, v in weather.items() if k != "G_east"})
    with pytest.raises(ValueError, match=r"unknown input\(s\) \['T_out'\]"):
        sim.step(np.zeros(3), {**weather, "T_out": 1.0})
    with pytest.raises(ValueError, match=r"weather\['T_a'\] has shape \(3,\); give a number or \(2,\)"):
        sim.step(np.zeros(3), {**weather, "T_a": np.zeros(3)})
    with pytest.raises(ValueError, match=r"reset: t_m_c has shape \(2,\); give finite numbers, a number, \(3,\) or \(2, 3\)"):
        sim.reset(20.0, np.array([19.0, 18.0]))
    renamed = _params(np.zeros((3, 3)), (ZONES[0], ZONES[1], dataclasses.replace(ZONES[2], zone=ZoneSpec("west"))))
    with pytest.raises(ValueError, match=r"fleet building\(s\) \[1\] have other zones than config.params \(south, glass, east\)"):
        MultiZoneSimulator(cfg, fleet=[cfg.params, renamed])


def test_a_building_without_actuators_floats_as_the_2r2c_with_its_heater_off():
    params = MultiZoneParams(zones=(_zone("attic", LIGHT, 1.0),), wall_conductance_w_per_k=[[0.0]])
    sim = MultiZoneSimulator(MultiZoneConfig(params=params, actuators=()), n_buildings=2)
    one = _alone(LIGHT, ActuatorSpec(upper_w=1000.0), -50.0, 80.0)
    sim.reset(21.0, 20.0)
    one.reset(21.0, 20.0)
    res = sim.step([], {"T_a": -3.0, "I_g": 250.0})
    ref = one.step(0.0, -3.0, 0.0, 250.0)
    assert res.power_w.shape == res.overridden.shape == (2, 0)
    np.testing.assert_allclose(res.t_r_sub_c[:, :, 0], np.repeat(ref.t_r_sub_c, 2, axis=0), rtol=0, atol=1e-10)
    np.testing.assert_allclose(
        steady_state(params, (), power_w=[], weather={"T_a": -3.0, "I_g": 250.0})[0], [-3.0 + 250.0 * 5e-3]
    )
