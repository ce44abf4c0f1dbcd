"""Buildings of several zones with heating and cooling through the closed loop: the
``multizone`` plant kind, the built-in ``two_zone_house`` and ``shoulder_office``, the engine's
actuator axis, the dual-setpoint thermostat per zone, data generation and the KPIs per zone,
each checked against the multi-zone simulator stepped directly or a hand computation."""


import numpy as np
import pytest

from controllers.base import ControlSpec, Forecast, Observation, fallback_powers
from controllers.thermostat import Thermostat
from pinn_mpc.actuator import Actuator, ActuatorSpec, actuator_columns
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.multizone import MultiZoneConfig, MultiZoneSimulator, steady_state
from scenarios import get_scenario
from scenarios.inputs.series import ExogenousSeries
from scenarios.inputs.zoned import TWO_ZONE_HOUSE, TWO_ZONE_HOUSE_ACTUATORS
from scenarios.plants.multizone import MultiZoneSettings
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.datagen import generate
from scenarios.running.engine import ClosedLoop
from scenarios.running.factory import build_controller
from scenarios.running.kpis import compute_kpis


def _loop(name: str, days: int = 2, seed: int = 0) -> tuple[ClosedLoop, ExogenousSeries]:
    scenario = get_scenario(name)
    frame = scenario.exogenous(days=days, seed=seed, part="test", lead_steps=48)
    series = ExogenousSeries.from_frame(frame)
    loop = ClosedLoop(
        scenario.sim, series, spec=scenario.control_spec(), initial_t_r_c=scenario.initial_t_r_c,
        initial_t_m_c=scenario.initial_t_m_c, plant_settings=scenario.plant, seed=seed,
    )
    return loop, series


def test_the_multizone_plant_in_the_loop_is_the_simulator_stepped_alone():
    scenario = get_scenario("two_zone_house")
    loop, series = _loop("two_zone_house")
    settings = scenario.plant.settings
    assert isinstance(settings, MultiZoneSettings)
    sim = MultiZoneSimulator(
        MultiZoneConfig(
            params=settings.building, actuators=settings.actuators, backup_low_c=16.0, backup_high_c=24.0
        ),
        seed=0,
    )
    sim.reset(scenario.initial_t_r_c, scenario.initial_t_m_c)
    rng = np.random.default_rng(3)
    for k in range(60):
        u = rng.uniform(0.0, 5000.0, size=2)
        loop.step(u)
        weather = {n: getattr(series, n)[k] for n in ("T_a", "G", "I_g", "G_south", "G_east", "G_west", "G_north")}
        alone = sim.step(u, weather)
        np.testing.assert_allclose(loop.measured()[0], alone.t_r_c[0], rtol=0, atol=1e-12)
    rec = loop.record()
    assert rec.t_r_c.shape == (60, 2) and rec.u_act_w.shape == (60, 2) and rec.u_phys_act_w.shape == (60, 2)
    np.testing.assert_allclose(rec.u_w, rec.u_act_w.sum(axis=1), rtol=1e-15)
    np.testing.assert_allclose(rec.u_phys_w, rec.u_phys_act_w.sum(axis=1), rtol=1e-15)
    obs = loop.observation()
    assert obs.zones == settings.building.zone_specs and np.isnan(obs.t_r_c)
    np.testing.assert_array_equal(obs.history["u[heat_north]"], rec.u_act_w[:, 1])
    np.testing.assert_array_equal(obs.history["u_phys"], rec.u_phys_w)
    np.testing.assert_allclose(obs.t_m_true_zones_c, sim.state[0, 2:], atol=1e-12)


def test_the_loop_refuses_a_demand_that_is_not_one_per_actuator():
    loop, _ = _loop("two_zone_house")
    with pytest.raises(InternalError, match=r"takes \(2,\) or \(1, 2\) demands, got shape \(\)"):
        loop.step(1000.0)


def test_a_controller_returning_the_wrong_number_of_powers_falls_back_per_actuator():
    loop, _ = _loop("shoulder_office")

    class OnePower(Thermostat):
        def act(self, obs, forecast):
            return 100.0

    decision = loop.advance(OnePower(loop.spec))
    assert decision.fallback and "not 4 finite numbers" in decision.error
    assert decision.u_act_w.shape == (4,) and decision.u_w == pytest.approx(decision.u_act_w.sum())


def test_the_dual_setpoint_thermostat_heats_below_and_cools_above_each_zones_band():
    spec = get_scenario("shoulder_office").control_spec()
    names = [a.name for a in spec.actuators]
    assert names == ["heat_east", "cool_east", "heat_west", "cool_west"]
    thermostat = Thermostat(spec, proportional_band_k=0.0)  # on/off (tests/test_zoned_thermostat.py: modulating)
    thermostat.reset()
    forecast = Forecast(
        time_of_day_h=np.zeros(1), T_a=np.zeros(1), G=np.zeros(1), I_g=np.zeros(1), price=np.zeros(1),
        T_min=np.array([21.0]), T_max=np.array([24.0]),
    )

    def act(east: float, west: float) -> np.ndarray:
        obs = Observation.from_history(0, {"T_r[east]": np.array([east]), "T_r[west]": np.array([west])}, zones=spec.zones)
        return np.asarray(thermostat.act(obs, forecast))

    # a quarter of the band from each edge, 0.25 K of hysteresis either side: heat on below
    # 21.5, cool on above 23.5
    np.testing.assert_array_equal(act(21.4, 23.6), [3000.0, 0.0, 0.0, 1000.0])
    np.testing.assert_array_equal(act(21.7, 23.3), [3000.0, 0.0, 0.0, 1000.0])  # hysteresis holds
    np.testing.assert_array_equal(act(22.5, 22.5), [0.0, 0.0, 0.0, 0.0])
    obs = Observation.from_history(0, {"T_r[east]": np.array([20.0]), "T_r[west]": np.array([25.0])}, zones=spec.zones)
    np.testing.assert_array_equal(fallback_powers(obs, forecast, spec), [3000.0, 0.0, 0.0, 1000.0])


def test_the_kpis_carry_each_zone_and_their_sums_are_the_buildings():
    n, s = 4, 2
    sub = np.zeros((n, s, 2))
    sub[:, :, 0] = 19.0  # zone a 1 K too cold throughout
    sub[:, :, 1] = 25.0  # zone b 1 K too warm throughout
    power = np.array([[1000.0, 0.0, 500.0]] * n)
    zones = get_scenario("two_zone_house").control_spec().zones
    kpis = compute_kpis(
        u_phys_w=power.sum(axis=1), price_eur_per_kwh=np.full(n, 0.2), t_r_sub_c=sub,
        t_min_c=np.full(n, 20.0), t_max_c=np.full(n, 24.0), decision_s=np.zeros(n),
        overridden=np.zeros(n, bool), fallback=np.zeros(n, bool), dt_s=3600.0,
        comfort_weight_eur_per_kh=1.0, free_t_r_sub_c=sub, heating=None, zones=zones,
        u_phys_act_w=power, actuator_zones=(0, 1, 0),
    )
    south, north = kpis["zones"]["south"], kpis["zones"]["north"]
    assert south == {"discomfort_kh": 4.0, "discomfort_too_cold_kh": 4.0, "discomfort_too_warm_kh": 0.0, "energy_kwh": 6.0}
    assert north == {"discomfort_kh": 4.0, "discomfort_too_cold_kh": 0.0, "discomfort_too_warm_kh": 4.0, "energy_kwh": 0.0}
    assert kpis["discomfort_kh"] == 8.0 and kpis["energy_kwh"] == 6.0
    # heaters and coolers: no free run bounds the unavoidable part
    assert kpis["discomfort_unavoidable_kh"] is None and kpis["discomfort_avoidable_kh"] is None


def test_a_closed_loop_on_each_zoned_scenario_reports_each_zone_and_the_oracle_beats_the_thermostat():
    for name in ("two_zone_house", "shoulder_office"):
        scenario = get_scenario(name)
        results = {
            c: run_closed_loop(scenario, build_controller(c, scenario, n_steps=96), days=2, seed=1)
            for c in ("thermostat", "oracle")
        }
        for result in results.values():
            kpis = result.kpis
            assert set(kpis["zones"]) == {z.name for z in scenario.control_spec().zones}
            assert sum(z["discomfort_kh"] for z in kpis["zones"].values()) == pytest.approx(kpis["discomfort_kh"])
            assert sum(z["energy_kwh"] for z in kpis["zones"].values()) == pytest.approx(kpis["energy_kwh"])
            assert kpis["fallbacks"] == 0
            for column in actuator_columns("u_phys", scenario.control_spec().actuators):
                assert column in result.trajectory
        assert results["oracle"].kpis["objective"] < results["thermostat"].kpis["objective"]
    # heating only: the free run still bounds the too-warm discomfort zone by zone
    house = run_closed_loop(get_scenario("two_zone_house"), build_controller("oracle", get_scenario("two_zone_house"), n_steps=96), days=2, seed=1)
    assert house.kpis["discomfort_unavoidable_kh"] is not None


def test_the_one_zone_controllers_refuse_a_zoned_building_in_one_line():
    scenario = get_scenario("two_zone_house")
    with pytest.raises(InputError, match=r"'clairvoyant' plans one zone with one actuator; scenario 'two_zone_house' has 2 zones \(south, north\) and 2 actuators: choose thermostat or oracle or qp-mpc or casadi-mpc or cem or random-shooting"):
        build_controller("clairvoyant", scenario, n_steps=48)


def test_cem_given_both_a_model_and_an_rc_names_itself_in_one_line(tmp_path):
    """cem over zones plans on a model or on a multi-zone RC file; both given is refused naming
    cem (not another controller), before either is read."""
    from scenarios.running.factory import make_controller

    with pytest.raises(InputError, match=r"^cem plans on either RC parameters \(rc_path\) or a model \(model_dir\), not both$"):
        make_controller(
            "cem", get_scenario("two_zone_house"), model_dir=tmp_path / "m", rc_path=tmp_path / "rc.json", n_steps=48
        )


def test_generated_data_of_a_zoned_building_holds_each_zone_and_actuator():
    scenario = get_scenario("shoulder_office")
    frame = generate(scenario, days=2, seed=0, policy="random-level")
    for column in ("T_r[east]", "T_r[west]", "u[heat_east]", "u_phys[cool_west]", "G_east", "G_west"):
        assert column in frame
    np.testing.assert_allclose(frame["u"], frame.filter(regex=r"^u\[").sum(axis=1))
    levels = frame["u[cool_east]"].to_numpy()
    assert levels.min() >= 0 and levels.max() <= 1000.0 and len(np.unique(levels)) > 50
    tracked = generate(scenario, days=7, seed=0, policy="closed-loop")
    # each zone tracks its own setpoints in the band widened by 1 K: the rooms stay near it
    # (the backup's 14/30 C untouched) and the zones' own setpoints part them at times
    rooms = tracked[["T_r[east]", "T_r[west]"]].to_numpy()
    assert rooms.min() > 14.5 and rooms.max() < 29.5
    assert np.max(np.abs(rooms[:, 0] - rooms[:, 1])) > 1.0
    assert (tracked["u[heat_east]"] > 0).any() and (tracked["u[cool_east]"] > 0).any()


def test_a_chiller_efficiency_is_the_carnot_eer_fraction_and_cools_only():
    chiller = Actuator(kind="chiller", supply_temp_c=12.0, carnot_efficiency=0.3, cop_min=1.0, cop_max=6.0)
    # EER = 0.3 * 285.15 / (T_a - 12)
    np.testing.assert_allclose(chiller.gain([30.0, 35.0]), [0.3 * 285.15 / 18.0, 0.3 * 285.15 / 23.0])
    assert chiller.gain(10.0) == 6.0 and chiller.gain(20.0) == 6.0
    with pytest.raises(ValueError, match="a chiller efficiency cools"):
        ActuatorSpec(upper_w=1000.0, efficiency=chiller)
    with pytest.raises(InputError, match="supply_temp_c = 35"):
        Actuator(kind="chiller", supply_temp_c=35.0)


def test_the_lumped_building_is_the_zones_merged_with_the_same_steady_state():
    lumped = TWO_ZONE_HOUSE.lumped()
    # Constant inputs, both heaters at 2 kW, no sun: the two halves are alike but for their
    # windows, so both zones sit at T_a + 4 kW x R_ra of the merged house (UA adds up).
    t_r, t_m = steady_state(
        TWO_ZONE_HOUSE, TWO_ZONE_HOUSE_ACTUATORS, power_w=[2000.0, 2000.0],
        weather={"T_a": 0.0, "I_g": 0.0, "G_south": 0.0},
    )
    np.testing.assert_allclose(t_r, 4000.0 * lumped.r_ra_k_per_w, rtol=1e-12)
    np.testing.assert_allclose(t_m, t_r, rtol=1e-12)
    assert lumped.r_ra_k_per_w == pytest.approx(1.0 / sum(1.0 / z.rc.r_ra_k_per_w for z in TWO_ZONE_HOUSE.zones))
    assert lumped.c_r_j_per_k == pytest.approx(sum(z.rc.c_r_j_per_k for z in TWO_ZONE_HOUSE.zones))


def test_a_zoned_plant_needs_named_actuators_on_its_zones():
    with pytest.raises(InputError, match="each with its own name"):
        MultiZoneSettings(building=TWO_ZONE_HOUSE, actuators=(ActuatorSpec(upper_w=1000.0),))
    with pytest.raises(InputError, match="multizone plant: .*zone"):
        MultiZoneSettings(building=TWO_ZONE_HOUSE, actuators=(ActuatorSpec(upper_w=1000.0, zone=5, name="x"),))
    spec = get_scenario("two_zone_house").control_spec()
    assert isinstance(spec, ControlSpec) and spec.n_actuators == 2 and not spec.single


def test_a_plant_with_only_the_one_zone_true_state_still_gives_the_oracle_its_mass():
    """A plant kind written before the zone axis gives ``true_state`` (B, 2) only: the loop
    reads its one zone's mass from it."""
    from scenarios.plants.rc import RCPlant

    scenario = get_scenario("winter_household")
    series = ExogenousSeries.from_frame(scenario.exogenous(days=1, seed=0, part="test", lead_steps=48))
    inner = RCPlant(scenario.sim, t_a_c=series.T_a, g_w_per_m2=series.G, i_g_w=series.I_g, seed=0, fleet=None)

    class OneZoneOnly:
        has_true_state, zones, n_buildings, n_substeps = True, inner.zones, 1, inner.n_substeps

        def reset(self, t_r_c, t_m_c, *, start, seed):
            inner.reset(t_r_c, t_m_c, start=start, seed=seed)

        def measure(self):
            return inner.measure()

        def true_state(self):
            return inner.true_state()

        def step(self, u_w, row):
            return inner.step(u_w, row)

        def close(self):
            inner.close()

    loop = ClosedLoop(
        scenario.sim, series, spec=scenario.control_spec(), initial_t_r_c=20.0, initial_t_m_c=18.5,
        plant=OneZoneOnly(),
    )
    assert loop.observation().t_m_true_c == 18.5
    loop.step(1000.0)
    assert loop.observation().t_m_true_c == pytest.approx(float(inner.true_state()[0, 1]))
