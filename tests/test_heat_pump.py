"""Heat-pump actuator: COP curve, simulator, KPIs on electrical power, RC MPC and planners on it;
and the default actuator/plant path against the numpy reference of the substep loop."""

import dataclasses

import numpy as np
import pytest

from controllers.rc_mpc.problem import RCProblem
from pinn_mpc import physics
from pinn_mpc.actuator import Actuator, ActuatorSpec
from pinn_mpc.errors import InputError
from pinn_mpc.models.rc import RCBatchModel
from pinn_mpc.simulator import SimConfig, Simulator, backup_power, draw_fleet
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.factory import build_controller

HP = Actuator(kind="heat_pump", supply_temp_c=35.0, carnot_efficiency=0.45, cop_min=1.0, cop_max=6.0)
WIDE = SimConfig(backup_low_c=-50.0, backup_high_c=80.0)


def test_cop_curve_at_known_points():
    # COP = 0.45 * 308.15 K / (308.15 K - T_a K): 35 K lift -> 3.962, 45 K -> 3.082, 25 K -> 5.547
    cop = HP.gain(np.array([0.0, -10.0, 10.0]))
    np.testing.assert_allclose(cop, [0.45 * 308.15 / 35, 0.45 * 308.15 / 45, 0.45 * 308.15 / 25])
    # above the supply temperature (no lift) and very warm air: the cap; very cold air: the floor
    assert HP.gain(40.0) == 6.0 and HP.gain(30.0) == 6.0
    weak = dataclasses.replace(HP, carnot_efficiency=0.2, cop_min=1.5)
    assert weak.gain(-30.0) == 1.5  # 0.2 * 308.15 / 65 = 0.95 < 1.5
    np.testing.assert_array_equal(Actuator().gain(np.array([-20.0, 0.0, 30.0])), 1.0)


@pytest.mark.parametrize(
    ("change", "key"),
    [
        ({"kind": "gas"}, "actuator.kind"),
        ({"supply_temp_c": 120.0}, "actuator.supply_temp_c"),
        ({"carnot_efficiency": 1.5}, "actuator.carnot_efficiency"),
        ({"cop_min": 5.0, "cop_max": 3.0}, "cop_min"),
        ({"min_modulation": 1.0}, "actuator.min_modulation"),
    ],
)
def test_bad_actuator_settings_name_the_key(change: dict, key: str):
    with pytest.raises(InputError, match=key):
        dataclasses.replace(HP, **change)


def test_heat_pump_cannot_cool():
    cooling = dataclasses.replace(physics.PAPER_HOUSEHOLD, eta=-2.5)
    with pytest.raises(InputError, match="heat_pump"):
        SimConfig(params=cooling, actuator=HP)


def _run(config: SimConfig, u: np.ndarray, t_a: np.ndarray, n_buildings: int = 2) -> np.ndarray:
    sim = Simulator(config, n_buildings=n_buildings, seed=0)
    sim.reset(18.0, 17.0)
    out = []
    for k in range(len(u)):
        r = sim.step(u[k], t_a[k], 100.0, 200.0)
        out.append(np.concatenate([r.t_r_sub_c.ravel(), r.t_m_c, r.u_phys_w]))
    return np.array(out)


def test_constant_cop_equals_the_ideal_heater_scaled():
    rng = np.random.default_rng(1)
    u, t_a = rng.uniform(0, 3000, (48, 2)), rng.uniform(-10, 15, (48, 2))
    fixed = dataclasses.replace(HP, cop_min=3.0, cop_max=3.0)
    heat_pump = _run(dataclasses.replace(WIDE, actuator=fixed), u, t_a)
    scaled = dataclasses.replace(WIDE, params=dataclasses.replace(WIDE.params, eta=3.0))
    np.testing.assert_allclose(heat_pump, _run(scaled, u, t_a), rtol=0, atol=1e-9)


def test_heat_pump_steady_state_is_the_2r2c_with_cop_times_power():
    config = dataclasses.replace(WIDE, actuator=HP)
    sim = Simulator(config)
    sim.reset(10.0, 10.0)
    for _ in range(48 * 60):
        res = sim.step(1000.0, 0.0)
    target = physics.steady_state(WIDE.params, u_w=1000.0 * 0.45 * 308.15 / 35, t_a_c=0.0)
    assert res.t_r_c[0] == pytest.approx(target[0], abs=1e-6)
    assert res.t_m_c[0] == pytest.approx(target[1], abs=1e-6)
    assert res.u_phys_w[0] == 1000.0  # electrical


def test_below_minimum_modulation_the_machine_cycles():
    config = dataclasses.replace(WIDE, u_max_w=4000.0, actuator=dataclasses.replace(HP, min_modulation=0.3))
    sim = Simulator(config, n_buildings=3)
    sim.reset(20.0, 20.0)
    # p_min = 1200 W: 600 W runs 15 of 30 minutes, 100 W 2.5 -> 2 (rint to even), 2000 W runs as is
    res = sim.step(np.array([600.0, 100.0, 2000.0]), 0.0)
    np.testing.assert_allclose(res.u_phys_w, [600.0, 1200.0 * 2 / 30, 2000.0])
    assert not res.overridden.any()
    # on then off: every minute of the first half cools the room less than any of the second
    slope = np.diff(res.t_r_sub_c[0])
    assert slope[:14].min() > slope[15:].max()


def _reference_interval(x, u, exog, ad, bd, cfg, n_sub):
    """The numpy substep loop the compiled kernel replaced (its arithmetic, term by term)."""
    x0, x1 = x[:, 0].copy(), x[:, 1].copy()
    d0 = bd[0, 1] * exog[:, 0] + bd[0, 2] * exog[:, 1] + bd[0, 3] * exog[:, 2]
    d1 = bd[1, 1] * exog[:, 0] + bd[1, 2] * exog[:, 1] + bd[1, 3] * exog[:, 2]
    total, subs = np.zeros(len(u)), []
    for _ in range(n_sub):
        p = backup_power(x0, u, cfg)
        total += p
        x0, x1 = (
            ad[0, 0] * x0 + ad[0, 1] * x1 + bd[0, 0] * p + d0,
            ad[1, 0] * x0 + ad[1, 1] * x1 + bd[1, 0] * p + d1,
        )
        subs.append(x0)
    return np.stack([x0, x1], axis=1), total / n_sub, np.stack(subs, axis=1)


@pytest.mark.parametrize("name", ["paper_household", "winter_household", "cold_storage"])
def test_default_actuator_and_plant_are_bit_identical_to_the_reference_loop(name: str):
    cfg = get_scenario(name).sim
    assert cfg.actuator == Actuator() and cfg.plant.kind == "2r2c"
    rng = np.random.default_rng(7)
    sim = Simulator(cfg, n_buildings=4, seed=0)
    sim.reset(cfg.backup_low_c + 1.0, cfg.backup_low_c + 2.0)
    # the substep matrices of the batched matrix exponential (fleet_matrices), as the kernel uses
    ad, bd = sim._ad[0], sim._bd[0]
    x = sim.full_state
    for _ in range(96):
        u = rng.uniform(0, cfg.u_max_w, 4)
        exog = np.stack([rng.normal(5, 10, 4), rng.uniform(0, 600, 4), rng.uniform(0, 600, 4)], axis=1)
        res = sim.step(u, exog[:, 0], exog[:, 1], exog[:, 2])
        x, mean_p, subs = _reference_interval(x, u, exog, ad, bd, cfg, cfg.n_substeps)
        np.testing.assert_array_equal(sim.full_state, x)
        np.testing.assert_array_equal(res.u_phys_w, mean_p)
        np.testing.assert_array_equal(res.t_r_sub_c, subs)


def test_fleet_with_heat_pump_steps_each_building_with_its_cop():
    cfg = dataclasses.replace(WIDE, actuator=HP)
    fleet = draw_fleet(cfg.params, 2, spread=0.0, rng=np.random.default_rng(0))
    sim = Simulator(cfg, fleet=fleet)
    sim.reset(18.0, 18.0)
    res = sim.step(1000.0, np.array([-10.0, 10.0]))
    warmer_air_more_heat = res.t_r_c[1] - res.t_r_c[0]
    assert warmer_air_more_heat > 0


def test_rc_problem_plans_on_the_cop_of_the_forecast():
    scenario = get_scenario("heat_pump_household")
    spec = scenario.control_spec()
    problem = RCProblem(params=scenario.sim.params, spec=spec, horizon_steps=4)
    frame = scenario.exogenous(days=1, seed=0, part="test", lead_steps=4)
    from scenarios.inputs.series import ExogenousSeries

    forecast = ExogenousSeries.from_frame(frame).forecast(0)
    stage = problem.stage(np.array([20.0, 20.0]), forecast)
    np.testing.assert_allclose(stage.cop, HP.gain(forecast.T_a[:4]))
    # one kW electrical for one step moves T_r by COP_0 times the heater's response
    moved = problem.rollout(stage, np.array([1.0, 0, 0, 0]))[0, 0] - problem.rollout(stage, np.zeros(4))[0, 0]
    assert moved == pytest.approx(stage.cop[0] * problem.b_u_c_per_kw[0])
    least, most = stage.heat_bounds_kw(ActuatorSpec(upper_w=4000.0, efficiency=HP))
    np.testing.assert_allclose(stage.electrical_kw(least), 0.0)
    np.testing.assert_allclose(stage.electrical_kw(most), 4.0)


@pytest.mark.parametrize("name", ["qp-mpc", "casadi-mpc", "cem", "oracle"])
def test_heat_pump_closed_loop_stays_in_bounds(name: str):
    scenario = get_scenario("heat_pump_household")
    spec = scenario.control_spec()
    kwargs: dict = {}
    if name == "cem":
        model = RCBatchModel(
            scenario.sim.params, dt_s=spec.dt_s, actuator=spec.actuator,
            backup_low_c=scenario.sim.backup_low_c, backup_high_c=scenario.sim.backup_high_c,
        )
        kwargs = {"model": model, "planner_options": {"n_samples": 64}}
    if name in ("qp-mpc", "casadi-mpc"):
        kwargs = {"rc_params": scenario.sim.params}
    controller = build_controller(name, scenario, n_steps=48, **kwargs)
    result = run_closed_loop(scenario, controller, days=1, seed=2, warmup_steps=4)
    traj = result.trajectory
    assert traj["u"].between(0.0, spec.u_max_w).all()
    assert result.kpis["fallbacks"] == 0 and not result.errors
    # energy and cost are electrical: the demand integrated, not COP times it
    dt_h = spec.dt_h
    assert result.kpis["energy_kwh"] == pytest.approx(traj["u_phys"].sum() * dt_h / 1000.0)
    cost = float((traj["u_phys"] * traj["price"]).sum() * dt_h / 1000.0)
    assert result.kpis["cost_eur"] == pytest.approx(cost)
    # a model of the heat pump keeps the room near the band (the thermostat misses by hours)
    assert result.kpis["discomfort_kh"] < 1.0
