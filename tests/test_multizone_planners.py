"""The sampling planners over zones x actuators (controllers.zone_sampling) and their model
(pinn_mpc.models.multizone_rc) against truth: the model is MultiZoneSimulator stepped once an
interval and the exact ZOH written out by hand, its long-run state the steady state solved
directly, its mass estimate the multi-zone Kalman estimator on the same observations; cem over
the true building within 3 % of the multi-zone oracle in closed loop, and so is qp-mpc with its
Kalman observer; plans of one actuator sample and compute as plans (H, 1); the shapes, the
bounds, the fallbacks and the command line."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from controllers.base import ControlSpec, Forecast, Observation, fallback_powers
from controllers.estimators import MultiZoneKalmanEstimator, observer_noise
from controllers.objective import ZoneObjective, zone_bands
from controllers.planners import CEMPlanner, RandomShootingPlanner
from controllers.rc_mpc.multizone import MultiZoneMPC
from controllers.rc_mpc.references import oracle_multizone
from controllers.sampling import CEM, RandomShooting
from pinn_mpc import multizone
from pinn_mpc.actuator import Actuator, ActuatorSpec
from pinn_mpc.errors import InputError
from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
from pinn_mpc.models.multizone_rc import MultiZoneRCModel
from pinn_mpc.models.rollout import Rollout
from pinn_mpc.multizone import MultiZoneParams, ZoneRC
from pinn_mpc.physics import PAPER_HOUSEHOLD, RCParams
from pinn_mpc.zones import ZoneSpec, zone_columns
from pinn_mpc_cli.cli import main
from scenarios import get_scenario
from scenarios.inputs.series import ExogenousSeries
from scenarios.plants.multizone import MultiZoneSettings
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.engine import ClosedLoop
from scenarios.running.factory import build_controller
from tests.test_multizone_mpc import _day  # the QP MPC tests' day of exogenous inputs

DT_S = 1800.0
HEAT_PUMP = Actuator(kind="heat_pump")
CHILLER = Actuator(kind="chiller", supply_temp_c=12.0, carnot_efficiency=0.3, cop_min=1.0, cop_max=6.0)


def _three_zones() -> tuple[MultiZoneParams, tuple[ActuatorSpec, ...]]:
    """Three zones in a row (walls of 150 and 80 W/K), the south one on the south facade; a heat
    pump and a chiller in the south zone, a heater with a floor of 200 W in the middle one, a
    heater in the north one."""
    light = RCParams(r_ra_k_per_w=5e-3, r_rm_k_per_w=1e-3, c_r_j_per_k=2e6, c_m_j_per_k=1e7)
    zones = (
        ZoneRC(zone=ZoneSpec("south"), rc=dataclasses.replace(light, solar_aperture_m2=6.0, solar_to_air_fraction=0.3),
               gain_share=0.5, solar_input="G_south"),
        ZoneRC(zone=ZoneSpec("mid"), rc=dataclasses.replace(light, c_m_j_per_k=2e7, gain_to_air_fraction=0.6), gain_share=0.3),
        ZoneRC(zone=ZoneSpec("north"), rc=dataclasses.replace(PAPER_HOUSEHOLD, solar_aperture_m2=1.0), gain_share=0.2),
    )
    walls = ((0.0, 150.0, 0.0), (150.0, 0.0, 80.0), (0.0, 80.0, 0.0))
    actuators = (
        ActuatorSpec(upper_w=4000.0, zone=0, name="pump", efficiency=HEAT_PUMP),
        ActuatorSpec(upper_w=3000.0, zone=0, name="chiller", heats=False, efficiency=CHILLER),
        ActuatorSpec(upper_w=2000.0, lower_w=200.0, zone=1, name="mid"),
        ActuatorSpec(upper_w=5000.0, zone=2, name="north"),
    )
    return MultiZoneParams(zones=zones, wall_conductance_w_per_k=walls), actuators


def _weather(h: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "T_a": rng.uniform(-5.0, 32.0, h),
        "G": rng.uniform(0.0, 600.0, h),
        "I_g": rng.uniform(0.0, 2000.0, h),
        "G_south": rng.uniform(0.0, 800.0, h),
    }


def _first_history(params: MultiZoneParams, t_r: np.ndarray, t_m: np.ndarray, weather: dict) -> dict[str, np.ndarray]:
    """The history of a building's first observation: its rooms and (simulated data) masses now."""
    history = {c: np.array([v]) for c, v in zip(zone_columns("T_r", params.zone_specs), t_r, strict=True)}
    history |= {c: np.array([v]) for c, v in zip(zone_columns("T_m", params.zone_specs), t_m, strict=True)}
    return history | {name: values[:1] for name, values in weather.items()}


# -- the model ---------------------------------------------------------------------------------


def test_the_model_is_the_simulator_stepped_once_an_interval():
    """With one substep an interval the simulator's backup acts on the rooms at the start of
    the interval, as the model's does: the same matrices give the same temperatures (the limits
    set so that the backup forces heaters and the chiller on and off in some intervals)."""
    params, actuators = _three_zones()
    limits = {"backup_low_c": (19.0, 18.0, 17.5), "backup_high_c": (21.0, 22.0, 20.5)}
    model = MultiZoneRCModel(params, actuators, DT_S, **limits)
    h, n = 40, 5
    weather = _weather(h, 1)
    t_r0, t_m0 = np.array([20.5, 18.5, 19.0]), np.array([19.0, 19.5, 18.0])
    rng = np.random.default_rng(2)
    # Demands beyond the bounds too: both clip them.
    plans = rng.uniform(-500.0, 6000.0, (n, h, len(actuators)))
    roll = model.rollout(_first_history(params, t_r0, t_m0, weather), torch.tensor(plans), weather)
    assert roll.t_r_c.shape == (1, n, h, 3) and roll.t_m_c is not None and roll.u_phys_w.shape == (1, n, h)
    config = multizone.MultiZoneConfig(params=params, actuators=actuators, dt_s=DT_S, substep_s=DT_S, **limits)
    sim = multizone.MultiZoneSimulator(config, n_buildings=n)
    sim.reset(t_r0, t_m0)
    overridden = np.zeros(len(actuators), dtype=bool)
    for j in range(h):
        step = sim.step(plans[:, j], {name: values[j] for name, values in weather.items()})
        overridden |= step.overridden.any(axis=0)
        np.testing.assert_allclose(roll.t_r_c[0, :, j].numpy(), step.t_r_c, rtol=0, atol=1e-9)
        np.testing.assert_allclose(roll.t_m_c[0, :, j].numpy(), step.t_m_c, rtol=0, atol=1e-9)
        np.testing.assert_allclose(roll.u_phys_w[0, :, j].numpy(), step.power_w.sum(axis=1), rtol=1e-12)
    assert overridden.all()  # every actuator's backup acted at least once: the rule is compared


def test_the_model_is_the_zero_order_hold_written_out():
    """Without the backup acting, x+ = Ad x + Bu (COP p) + Bd d, by hand on discretise's
    matrices, with each actuator's heat per watt at the interval's outdoor temperature."""
    params, actuators = _three_zones()
    model = MultiZoneRCModel(params, actuators, DT_S, backup_low_c=-50.0, backup_high_c=80.0)
    h = 30
    weather = _weather(h, 3)
    t_r0, t_m0 = np.array([21.0, 20.0, 19.5]), np.array([20.0, 20.5, 19.0])
    plan = np.random.default_rng(4).uniform(0.0, 1.0, (h, 4)) * [4000.0, 3000.0, 1800.0, 5000.0] + [0, 0, 200.0, 0]
    roll = model.rollout(_first_history(params, t_r0, t_m0, weather), torch.tensor(plan[None]), weather)
    a, b_u, b_d = multizone.discretise(params, actuators, DT_S)
    x = np.concatenate([t_r0, t_m0])
    for j in range(h):
        d = np.array([weather.get(name, np.zeros(h))[j] for name in multizone.EXOGENOUS_NAMES])
        cop = np.array([s.efficiency.gain(d[0]) for s in actuators])
        x = a @ x + b_u @ (cop * plan[j]) + b_d @ d
        np.testing.assert_allclose(roll.t_r_c[0, 0, j].numpy(), x[:3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(roll.u_phys_w[0, 0].numpy(), plan.sum(axis=1), rtol=1e-12)


def test_the_model_held_at_constant_inputs_reaches_the_steady_state():
    params, actuators = _three_zones()
    model = MultiZoneRCModel(params, actuators, DT_S, backup_low_c=-50.0, backup_high_c=80.0)
    power = np.array([1500.0, 400.0, 900.0, 2500.0])
    weather = {"T_a": 4.0, "I_g": 600.0, "G": 90.0, "G_south": 150.0}
    h = 60 * 48  # 60 days: the slowest mode (the north zone's mass) has decayed a million-fold
    series = {name: np.full(h, v) for name, v in weather.items()}
    roll = model.rollout(
        _first_history(params, np.full(3, 10.0), np.full(3, 30.0), series),
        torch.tensor(np.broadcast_to(power, (1, h, 4)).copy()), series,
    )
    t_r, t_m = multizone.steady_state(params, actuators, power_w=power, weather=weather)
    np.testing.assert_allclose(roll.t_r_c[0, 0, -1].numpy(), t_r, atol=1e-6)
    np.testing.assert_allclose(roll.t_m_c[0, 0, -1].numpy(), t_m, atol=1e-6)


def _building(name: str) -> tuple[MultiZoneParams, ControlSpec]:
    """A zoned scenario's building and control spec."""
    scenario = get_scenario(name)
    settings = scenario.plant.settings
    assert isinstance(settings, MultiZoneSettings)
    return settings.building, scenario.control_spec()


def _loop(name: str, days: int, seed: int) -> tuple[ClosedLoop, ExogenousSeries]:
    scenario = get_scenario(name)
    frame = scenario.exogenous(days=days, seed=seed, part="test", lead_steps=48)
    series = ExogenousSeries.from_frame(frame)
    loop = ClosedLoop(
        scenario.sim, series, spec=scenario.control_spec(), initial_t_r_c=scenario.initial_t_r_c,
        initial_t_m_c=19.0, plant_settings=scenario.plant, seed=seed,
    )
    return loop, series


def test_the_models_masses_are_the_kalman_estimators_on_the_same_observations():
    """Folded in row by row, from the start of each history or on from the last call, the
    model's filter is MultiZoneKalmanEstimator's; it finds the true masses (2 K off the rooms at
    the start) within a day."""
    building, spec = _building("shoulder_office")
    process, measurement = observer_noise(spec)
    model = MultiZoneRCModel(building, spec.actuators, spec.dt_s, process_std_c=process, measurement_std_c=measurement)
    fresh = MultiZoneRCModel(building, spec.actuators, spec.dt_s, process_std_c=process, measurement_std_c=measurement)
    estimator = MultiZoneKalmanEstimator(building, spec)
    loop, _ = _loop("shoulder_office", 1, 0)
    rng = np.random.default_rng(0)
    error = np.nan
    for k in range(48):
        obs = loop.observation()
        state = model.state_now(obs.history)
        expected = estimator.update(obs)
        np.testing.assert_allclose(state[2:], expected[2:], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(state[:2], obs.t_r_zones_c())
        if k % 7 == 3:  # a history of its own from the start now and then
            np.testing.assert_allclose(fresh.state_now(obs.history), state, rtol=0, atol=1e-12)
        error = np.abs(state[2:] - obs.t_m_true_zones_c).max()
        if k == 0:
            assert error > 1.5
        loop.step(rng.uniform(0.0, 1.0, 4) * [3000.0, 1000.0, 3000.0, 1000.0])
    assert error < 0.1


def test_the_model_refuses_what_it_cannot_plan():
    params, actuators = _three_zones()
    model = MultiZoneRCModel(params, actuators, DT_S)
    weather = _weather(5, 0)
    history = _first_history(params, np.full(3, 20.0), np.full(3, 20.0), weather)
    with pytest.raises(ValueError, match=r"u_w must be \(N, H, 4\), one demand per actuator \(pump, chiller, mid, north\), got \(2, 5\)"):
        model.rollout(history, torch.zeros(2, 5), weather)
    lacking = {k: v for k, v in history.items() if k not in ("T_m[mid]", "G_south")}
    with pytest.raises(InputError, match=r"the history lacks \['G_south'\]"):
        model.rollout(lacking, torch.zeros(1, 5, 4), weather)
    with pytest.raises(ValueError, match="out of range"):
        MultiZoneRCModel(params, (*actuators, ActuatorSpec(upper_w=1.0, zone=3, name="x")), DT_S)


# -- the planners over plans (H, A) --------------------------------------------------------------


@pytest.mark.parametrize("planner", [CEMPlanner(lower=0.0, upper=3.0), RandomShootingPlanner(lower=0.0, upper=3.0)],
                         ids=["cem", "random-shooting"])
def test_plans_of_one_actuator_are_plans_of_an_actuator_axis_of_one(planner):
    """The one-actuator planners' draws and results are those of plans (H, 1): adding the axis
    changes nothing of what they compute."""
    target = torch.linspace(0.5, 2.5, 12)

    def cost(u: torch.Tensor) -> torch.Tensor:
        u = u if u.dim() == 2 else u[..., 0]
        return ((u - target) ** 2).sum(dim=1)

    x0 = torch.full((12,), 1.0)
    one = planner.optimize(cost, x0, torch.Generator().manual_seed(5))
    axis = planner.optimize(cost, x0[:, None], torch.Generator().manual_seed(5))
    assert axis.plan.shape == (12, 1)
    assert torch.equal(one.plan, axis.plan[:, 0]) and one.cost == axis.cost


def test_cem_over_actuators_keeps_each_ones_own_sequence():
    """Two actuators with opposite targets: CEM's mean and spread are per step and actuator."""
    target = torch.stack([torch.linspace(0.1, 0.9, 16), torch.linspace(0.9, 0.1, 16)], dim=1)
    planner = CEMPlanner(lower=0.0, upper=1.0, n_samples=256, n_iters=20, elite_frac=0.05, noise_beta=0.0)
    result = planner.optimize(lambda u: ((u - target) ** 2).sum(dim=(1, 2)), torch.full((16, 2), 0.5), torch.Generator().manual_seed(0))
    assert result.plan.shape == (16, 2)
    assert float((result.plan - target).abs().max()) < 0.1


# -- the controllers -----------------------------------------------------------------------------


def _spec(params: MultiZoneParams, actuators: tuple[ActuatorSpec, ...], **kw) -> ControlSpec:
    return ControlSpec(actuators=actuators, zones=params.zone_specs, comfort_weight_eur_per_kh=5.0, **kw)


def _spring_day(h: int) -> dict[str, np.ndarray]:
    """The QP MPC tests' day (:func:`tests.test_multizone_mpc._day`) in spring: nights near 10
    C, sunny afternoons near 24 C, so that the south zone's heat pump and chiller both work."""
    return _day(h, t_a_mean=14.0, swing=10.0, sun=500.0)


def _obs(params: MultiZoneParams, t_r: np.ndarray, series: dict) -> Observation:
    history = {c: np.array([v]) for c, v in zip(zone_columns("T_r", params.zone_specs), t_r, strict=True)}
    history |= {name: series[name][:1] for name in ("T_a", "G", "I_g", "G_south", "time_of_day_h")}
    return Observation.from_history(0, history, zones=params.zone_specs)


@pytest.mark.parametrize("planner", [CEM, RandomShooting], ids=["cem", "random-shooting"])
def test_a_plan_over_zones_is_one_power_per_actuator_within_its_bounds(planner):
    params, actuators = _three_zones()
    spec = _spec(params, actuators, horizon_steps=24)
    series = _spring_day(40)
    controller = planner(MultiZoneRCModel(params, actuators, DT_S, backup_low_c=12.0, backup_high_c=30.0), spec)
    controller.reset(seed=0)
    action = controller.act(_obs(params, np.array([19.0, 18.0, 24.5]), series), Forecast(**series))
    plan = controller.last_plan
    assert isinstance(action, np.ndarray) and action.shape == (4,) and plan is not None and plan.shape == (24, 4)
    assert not controller.last_stats.fallback and controller.n_fallbacks == 0
    lower, upper = np.array([a.lower_w for a in actuators]), np.array([a.upper_w for a in actuators])
    assert np.all(plan >= lower - 1e-3) and np.all(plan <= upper + 1e-3)
    np.testing.assert_allclose(action, plan[0])
    report = controller.trust_report  # the guard over zones (tests/test_zone_guard.py)
    assert report is not None and report["model_fallback_steps"] == 0 and np.isfinite(controller.last_cost_eur)


def test_cem_over_zones_finds_the_optimum_of_its_model():
    """One decision: the plan's cost on the model within 0.5 % of the QP's optimum on the same
    building, state and forecast (the QP's regulariser is negligible at its default)."""
    params, actuators = _three_zones()
    spec = _spec(params, actuators, horizon_steps=24)
    series = _spring_day(40)
    fc = Forecast(**series)
    t_r, t_m = np.array([19.0, 18.0, 24.5]), np.array([19.5, 18.5, 23.0])
    model = MultiZoneRCModel(params, actuators, DT_S, backup_low_c=12.0, backup_high_c=30.0)
    cem = CEM(model, spec, comfort_margin_k=0.0)
    cem.reset(seed=0)
    obs = _obs(params, t_r, series)
    obs = obs._replace(history=obs.history | {c: np.array([v]) for c, v in zip(zone_columns("T_m", params.zone_specs), t_m, strict=True)},
                       t_m_true_zones_c=t_m)
    cem.act(obs, fc)
    qp = oracle_multizone(params, spec, solver_options={"eps_abs": 1e-8, "eps_rel": 1e-8, "max_iter": 400000})
    qp.act(obs, fc)
    assert cem.last_plan is not None and qp.last_plan is not None
    objective = ZoneObjective.from_forecast(fc, spec, 24)
    history = obs.history
    costs = []
    for plan in (cem.last_plan, qp.last_plan):
        roll = model.rollout(history, torch.tensor(plan[None]), fc.exogenous(model.exog_names, 24))
        costs.append(float(objective.cost(roll.u_phys_w[0, 0].numpy(), roll.t_r_c[0, 0].numpy())))
    assert costs[1] > 1.0  # something to pay for
    assert costs[0] <= 1.005 * costs[1]


class _NaNModel(MultiZoneRCModel):
    """The building's model with a fault: every predicted temperature NaN."""

    def rollout(self, history, u_w, exog) -> Rollout:
        roll = super().rollout(history, u_w, exog)
        return roll._replace(t_r_c=roll.t_r_c * float("nan"))


class _WithoutRC(MultiZoneRCModel):
    """A model of the building's zones without an RC building to fall back on."""

    @property
    def zone_params(self) -> None:
        return None


def test_a_failed_plan_falls_back_on_the_qp_of_the_models_building_and_is_counted():
    building, spec = _building("shoulder_office")
    cem = CEM(_NaNModel(building, spec.actuators, spec.dt_s), spec)
    cem.reset(seed=0)
    qp = MultiZoneMPC(building, spec, estimator="kalman")
    loop, _ = _loop("shoulder_office", 1, 1)
    for _ in range(6):
        obs, fc = loop.observation(), loop.forecast()
        action = cem.act(obs, fc)
        assert cem.last_stats.fallback and "multi-zone QP fallback: non-finite model output" in cem.last_stats.status
        assert cem.last_plan is None
        np.testing.assert_array_equal(action, qp.act(obs, fc))
        loop.step(action)
    assert cem.n_fallbacks == 6 and qp.n_fallbacks == 0


def test_without_an_rc_building_a_failure_falls_back_on_the_band_rule():
    building, spec = _building("shoulder_office")
    cem = CEM(_WithoutRC(building, spec.actuators, spec.dt_s), spec)
    loop, _ = _loop("shoulder_office", 1, 1)
    obs, fc = loop.observation(), loop.forecast()
    cem.act(obs, fc)  # a plan to forget
    assert cem.last_plan is not None
    loop.step(cem.act(obs, fc))
    obs = loop.observation()
    broken = obs._replace(history={k: v for k, v in obs.history.items() if k != "u_phys[heat_west]"})
    action = cem.act(broken, fc)
    assert cem.last_stats.fallback and "band rule fallback: model error: InputError" in cem.last_stats.status
    np.testing.assert_array_equal(action, fallback_powers(broken, fc, spec))
    assert cem.last_plan is None and cem.n_fallbacks == 1


def test_an_observation_the_observer_cannot_read_falls_back_past_the_qp_on_the_band_rule():
    """The QP plans from the planner's observer: when that cannot fold the observation in, the
    QP has no state and falls back in turn (no plan of its own yet: the band rule)."""
    building, spec = _building("shoulder_office")
    cem = CEM(MultiZoneRCModel(building, spec.actuators, spec.dt_s), spec)
    loop, _ = _loop("shoulder_office", 1, 1)
    obs, fc = loop.observation(), loop.forecast()
    loop.step(cem.act(obs, fc))
    obs = loop.observation()
    broken = obs._replace(history={k: v for k, v in obs.history.items() if k != "u_phys[heat_west]"})
    action = cem.act(broken, fc)
    assert cem.last_stats.fallback and "multi-zone QP fallback: model error: InputError" in cem.last_stats.status
    assert cem.zone_qp is not None and cem.zone_qp.n_fallbacks == 1
    np.testing.assert_array_equal(action, fallback_powers(broken, fc, spec))


def test_a_planner_over_zones_refuses_a_model_of_other_zones_or_actuators():
    building, spec = _building("shoulder_office")
    with pytest.raises(ValueError, match=r"CEM: the model's zones \(east, west\) and actuators \(heat_east, cool_east\) differ"):
        CEM(MultiZoneRCModel(building, spec.actuators[:2], spec.dt_s), spec)
    from pinn_mpc.models.rc import RCBatchModel

    one = RCBatchModel(PAPER_HOUSEHOLD, dt_s=DT_S, actuator=ActuatorSpec(upper_w=5000.0))
    with pytest.raises(ValueError, match="the model plans one zone's one actuator; give a model of the building's zones"):
        RandomShooting(one, spec)
    with pytest.raises(ValueError, match="CEM.binary: on/off plans are one actuator's"):
        CEM(MultiZoneRCModel(building, spec.actuators, spec.dt_s), spec, binary=True)
    one_spec = ControlSpec(actuators=(ActuatorSpec(upper_w=5000.0),))
    one_zone = MultiZoneParams(zones=(ZoneRC(zone=ZoneSpec("room"), rc=PAPER_HOUSEHOLD, gain_share=1.0),),
                               wall_conductance_w_per_k=((0.0,),))
    with pytest.raises(ValueError, match="the scenario has one zone with one actuator; give a model of one zone"):
        CEM(MultiZoneRCModel(one_zone, one_spec.actuators, DT_S), one_spec)


def test_zone_bands_take_one_band_for_every_zone_or_one_per_zone():
    series = _spring_day(10)
    zones = (ZoneSpec("a"), ZoneSpec("b"))
    fc = Forecast(**series)
    lower, upper = zone_bands(fc, zones, 8)
    # the end of interval j keeps the bands of j and j + 1
    np.testing.assert_array_equal(lower[:, 0], np.maximum(series["T_min"][:8], series["T_min"][1:9]))
    np.testing.assert_array_equal(lower[:, 1], lower[:, 0])
    per_zone = fc._replace(T_min=np.stack([series["T_min"], series["T_min"] - 1.0], axis=1))
    np.testing.assert_array_equal(zone_bands(per_zone, zones, 8)[0][:, 1], lower[:, 0] - 1.0)
    with pytest.raises(ValueError, match=r"forecast.T_min has shape \(10, 3\); give \(H,\) for every zone or \(H, 2\)"):
        zone_bands(fc._replace(T_min=np.zeros((10, 3))), zones, 8)


# -- closed loop against the oracle ---------------------------------------------------------------


def _ratio(name: str, controller: str, seed: int, days: int = 3) -> float:
    scenario = get_scenario(name)
    building, _ = _building(name)
    oracle = run_closed_loop(scenario, build_controller("oracle", scenario, n_steps=days * 48), days=days, seed=seed)
    built = build_controller(controller, scenario, zone_params=building, n_steps=days * 48)
    result = run_closed_loop(scenario, built, days=days, seed=seed)
    assert result.kpis["fallbacks"] == 0 and not result.errors
    assert oracle.kpis["objective"] > 0.3  # something to pay for
    return result.kpis["objective"] / oracle.kpis["objective"]


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", ["two_zone_house", "shoulder_office"])
def test_cem_over_the_true_building_is_within_three_percent_of_the_oracle(name, seed):
    assert _ratio(name, "cem", seed) <= 1.03


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", ["two_zone_house", "shoulder_office"])
def test_qp_mpc_on_the_true_building_with_its_observer_is_within_three_percent_of_the_oracle(name, seed):
    assert _ratio(name, "qp-mpc", seed) <= 1.03


# -- the command line -----------------------------------------------------------------------------


def _rc_file(path: Path, params: MultiZoneParams) -> Path:
    n = params.n_zones
    result = MultiZoneIdentifyResult(
        params=params, rmse_c=(0.0,) * n, t_m0_c=(20.0,) * n, n_rows=48, identified_solar=(True,) * n,
        identified_gain_shares=True, cost_evaluations=1,
    )
    path.write_text(json.dumps(result.to_json()), encoding="utf-8")
    return path


def test_closed_loop_plans_a_zoned_scenario_over_a_multizone_rc_file(tmp_path, capsys):
    from scenarios.inputs.zoned import SHOULDER_OFFICE

    rc = _rc_file(tmp_path / "rc.json", SHOULDER_OFFICE)
    for controller in ("cem", "random-shooting", "qp-mpc"):
        out = tmp_path / f"{controller}.json"
        argv = ["closed-loop", "--scenario", "shoulder_office", "--controller", controller, "--rc", str(rc),
                "--days", "1", "--json", str(out)]
        assert main(argv) == 0, capsys.readouterr().err
        kpis = json.loads(out.read_text(encoding="utf-8"))
        assert kpis["controller"] == controller and kpis["fallbacks"] == 0 and set(kpis["zones"]) == {"east", "west"}
    capsys.readouterr()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--controller", "cem", "--model", "model_dir"],
         "controller 'cem' plans a trained model (--model) of one zone; scenario 'two_zone_house' has 2 zones"),
        (["--controller", "cem"], "controller 'cem' on a building of several zones plans on a multi-zone RC file or model"),
        (["--controller", "oracle", "--rc", "{house}"], "--rc is not used by controller 'oracle'; only qp-mpc, casadi-mpc, random-shooting, cem"),
        (["--controller", "cem", "--rc", "{one_zone}"], "is not a multi-zone RC file (format None"),
        (["--controller", "qp-mpc", "--rc", "{office}"], "is a building of the zones east, west, but scenario 'two_zone_house' has south, north"),
    ],
    ids=["model", "no-rc", "oracle-rc", "one-zone-rc", "other-zones"],
)
def test_closed_loop_refuses_what_does_not_plan_a_zoned_building_in_one_line(tmp_path, capsys, argv, message):
    from scenarios.inputs.zoned import SHOULDER_OFFICE, TWO_ZONE_HOUSE

    files = {
        "house": _rc_file(tmp_path / "house.json", TWO_ZONE_HOUSE),
        "office": _rc_file(tmp_path / "office.json", SHOULDER_OFFICE),
        "one_zone": tmp_path / "rc.json",
    }
    files["one_zone"].write_text(json.dumps({"R_ra_K_per_W": 0.003}), encoding="utf-8")
    from pinn_mpc.fitted import save
    from pinn_mpc.models.arx import fit_linear
    from scenarios import get_scenario
    from scenarios.running.datagen import generate

    save(fit_linear("arx", generate(get_scenario("winter_household"), days=4, seed=0), eta=1.0), tmp_path / "model_dir")
    argv = [a.format(**{k: str(v) for k, v in files.items()}).replace("model_dir", str(tmp_path / "model_dir")) for a in argv]
    assert main(["closed-loop", "--scenario", "two_zone_house", "--days", "1", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err

