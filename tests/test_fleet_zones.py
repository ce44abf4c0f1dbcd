"""Fleets of buildings of several zones (scenarios.fleets.zoned): the draw, each building as it
runs alone, the cap held by the coordination on each building's total over its actuators."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from controllers.coordination import Coordination, DualAscent
from controllers.rc_mpc.references import oracle_multizone
from controllers.thermostat import Thermostat
from pinn_mpc.errors import InputError
from pinn_mpc.multizone import draw_zoned_fleet
from pinn_mpc.simulator import FLEET_SCALED, draw_fleet
from pinn_mpc_cli.cli import main
from scenarios.fleets.aggregator import _run_batched, run_coordinated_fleet
from scenarios.fleets.fleet import draw_buildings, run_fleet_closed_loop
from scenarios.fleets.zoned import (
    ZoneFleetPlanner,
    with_building,
    zoned_controller,
    zoned_planner_factory,
)
from scenarios.inputs.scenario_file import get_scenario
from scenarios.inputs.zoned import TWO_ZONE_HOUSE
from scenarios.running.closed_loop import build_loop, prepare_run, run_closed_loop
from scenarios.running.datagen import generate
from tests.test_fleet_closed_loop import assert_same_plant_kpis

#: A cold test day of two_zone_house (seed 4: every building heats all day).
COLD_SEED = 4


def test_spread_zero_draws_copies_and_the_draw_is_log_normal_per_zone_and_wall():
    rng = np.random.default_rng(0)
    assert draw_zoned_fleet(TWO_ZONE_HOUSE, 3, spread=0.0, rng=rng) == (TWO_ZONE_HOUSE,) * 3
    spread, n = 0.25, 2000
    fleet = draw_zoned_fleet(TWO_ZONE_HOUSE, n, spread=spread, rng=np.random.default_rng(1))
    for z, base in enumerate(TWO_ZONE_HOUSE.zones):
        zones = [b.zones[z] for b in fleet]
        # What is not drawn stays the base zone's.
        assert {(x.zone, x.gain_share, x.solar_input) for x in zones} == {(base.zone, base.gain_share, base.solar_input)}
        assert {x.rc.solar_to_air_fraction for x in zones} == {base.rc.solar_to_air_fraction}
        logs = np.log([[getattr(x.rc, f) / getattr(base.rc, f) for f in FLEET_SCALED if getattr(base.rc, f) > 0] for x in zones])
        # log factors ~ N(0, spread^2), independent: sample moments within 4 standard errors.
        assert np.all(np.abs(logs.mean(axis=0)) < 4 * spread / np.sqrt(n))
        assert np.all(np.abs(logs.std(axis=0) / spread - 1) < 4 / np.sqrt(2 * n))
        assert np.all(np.abs(np.corrcoef(logs.T) - np.eye(logs.shape[1])) < 4 / np.sqrt(n))
    walls = np.array([b.walls for b in fleet])
    np.testing.assert_array_equal(walls, walls.transpose(0, 2, 1))
    assert np.all(walls[:, 0, 0] == 0) and np.all(walls[:, 1, 1] == 0)
    log_wall = np.log(walls[:, 0, 1] / TWO_ZONE_HOUSE.walls[0, 1])
    assert abs(log_wall.std() / spread - 1) < 4 / np.sqrt(2 * n)
    # Each zone is drawn as draw_fleet draws a one-zone building, from the same generator.
    again = np.random.default_rng(5)
    one = draw_zoned_fleet(TWO_ZONE_HOUSE, 1, spread=0.3, rng=np.random.default_rng(5))[0]
    assert one.zones[0].rc == draw_fleet(TWO_ZONE_HOUSE.zones[0].rc, 1, spread=0.3, rng=again)[0]
    assert one.zones[1].rc == draw_fleet(TWO_ZONE_HOUSE.zones[1].rc, 1, spread=0.3, rng=again)[0]
    with pytest.raises(InputError, match="spread"):
        draw_zoned_fleet(TWO_ZONE_HOUSE, 2, spread=1.5, rng=rng)


def _alone(scenario, params, name, *, days, seed):
    alone = with_building(scenario, params)
    n_steps = days * scenario.steps_per_day
    return run_closed_loop(alone, zoned_controller(name, alone, params, n_steps=n_steps), days=days, seed=seed)


@pytest.mark.parametrize(
    ("name", "controller"),
    [("two_zone_house", "thermostat"), ("two_zone_house", "oracle"), ("shoulder_office", "oracle"),
     ("two_zone_house", "qp-mpc"), ("two_zone_house", "cem")],
)
def test_uncapped_coordinated_fleet_runs_each_building_as_alone_to_1e9(name, controller):
    """The batched path (ZoneFleetPlanner under the coordination, no cap): every zone's
    measured room temperature of every building as the building's own run alone."""
    scenario, seed = get_scenario(name), COLD_SEED
    fleet = draw_buildings(scenario, 3, spread=0.3, seed=seed)
    assert len(set(fleet)) == 3
    run = prepare_run(scenario, days=1, seed=seed, warmup_steps=None, weather_part="test")
    spec = scenario.control_spec()
    planner = zoned_planner_factory(controller, scenario, n_steps=run.total - run.warmup)(fleet, spec)
    planner.reset(seed)
    warmup = [Thermostat(spec) for _ in fleet]
    for t in warmup:
        t.reset(seed)
    loop = build_loop(scenario, run, seed=seed, fleet=fleet)
    batched = _run_batched(
        loop, run, planner, Coordination(np.full(len(run.series), np.inf)), warmup,
        label="", progress=False, perfect=planner.knows_true_state,
    )
    assert batched.plans == run.total - run.warmup  # one plan a step without a cap
    for b, params in enumerate(fleet):
        single = _alone(scenario, params, controller, days=1, seed=seed)
        columns = [f"T_r[{z.name}]" for z in spec.zones]
        np.testing.assert_allclose(
            loop.record(b).t_r_c[run.counted], single.trajectory[columns].to_numpy(), rtol=0, atol=1e-9
        )
        actuators = [f"u[{a.name}]" for a in spec.actuators]
        np.testing.assert_allclose(
            loop.record(b).u_act_w[run.counted], single.trajectory[actuators].to_numpy(), rtol=0, atol=1e-9
        )


def test_a_fleet_of_cems_runs_each_building_as_alone():
    """cem on each building's own RC, seeded as alone."""
    scenario = get_scenario("two_zone_house")
    result = run_fleet_closed_loop(scenario, "cem", n_buildings=2, days=1, seed=COLD_SEED, spread=0.3)
    for b, params in enumerate(result.params):
        assert_same_plant_kpis(result.kpis[b], _alone(scenario, params, "cem", days=1, seed=COLD_SEED).kpis)


@pytest.mark.parametrize("controller", ["thermostat", "oracle"])
def test_fleet_of_zoned_buildings_reproduces_each_building_alone(controller):
    """The per-building path (each building's controller, one batched plant step)."""
    scenario = get_scenario("two_zone_house")
    result = run_fleet_closed_loop(scenario, controller, n_buildings=2, days=1, seed=COLD_SEED, spread=0.3)
    assert result.params == draw_buildings(scenario, 2, spread=0.3, seed=COLD_SEED)
    for b, params in enumerate(result.params):
        assert_same_plant_kpis(result.kpis[b], _alone(scenario, params, controller, days=1, seed=COLD_SEED).kpis)
    assert result.totals["energy_kwh"] == pytest.approx(sum(k["energy_kwh"] for k in result.kpis), rel=1e-12)


@pytest.mark.parametrize("controller", ["thermostat", "oracle"])
def test_a_binding_cap_holds_at_every_interval(controller):
    scenario = get_scenario("two_zone_house")
    kwargs = {"n_buildings": 6, "days": 1, "seed": COLD_SEED, "spread": 0.3}
    free = run_coordinated_fleet(scenario, controller, **kwargs)
    peak_kw = free.aggregate_u_phys_w.max() / 1000.0
    mean_kw = free.aggregate_u_phys_w.mean() / 1000.0
    cap_kw = mean_kw + 0.5 * (peak_kw - mean_kw)  # under the uncapped peak, over its mean
    capped = run_coordinated_fleet(scenario, controller, cap_kw=cap_kw, **kwargs)
    assert capped.cap is not None and capped.cap["intervals"] == 48
    assert capped.cap["intervals_over"] == 0
    assert capped.aggregate_u_phys_w.max() <= cap_kw * 1000.0 * (1 + 1e-9)
    assert capped.cap["curtailed_steps"] + (controller == "oracle") > 0  # the cap acted
    assert capped.totals["backup_overrides"] == 0
    # The same buildings and the same plant: only the decisions differ.
    assert capped.params == free.params
    assert np.any(np.abs(capped.aggregate_u_phys_w - free.aggregate_u_phys_w) > 1.0)


@pytest.mark.slow
def test_capped_cems_follow_the_price_and_hold_the_cap():
    """A sampler plans each price on a copy of itself: under a binding cap the coordination's
    plans (a bracket of prices, the first actions settled between them) keep more of the comfort
    than the plain dual ascent's (one plan a step, its first actions scaled down when over)."""
    scenario = get_scenario("two_zone_house")
    kwargs = {"n_buildings": 4, "days": 1, "seed": COLD_SEED, "spread": 0.3}
    free = run_coordinated_fleet(scenario, "cem", **kwargs)
    cap_kw = 0.5 * (free.aggregate_u_phys_w.mean() + free.aggregate_u_phys_w.max()) / 1000.0
    capped = run_coordinated_fleet(scenario, "cem", cap_kw=cap_kw, **kwargs)
    curtailed = run_coordinated_fleet(
        scenario, "cem", cap_kw=cap_kw, dual=DualAscent(iterations=1, secant=False, interpolate=False), **kwargs
    )
    for result in (capped, curtailed):
        assert result.cap is not None and result.cap["intervals_over"] == 0
    assert capped.info["plans_per_step"] > 1.5
    assert capped.totals["discomfort_kh"] < curtailed.totals["discomfort_kh"]


def test_a_capped_building_whose_solver_fails_falls_back_and_is_counted():
    scenario = get_scenario("two_zone_house")

    def planner(fleet, spec):
        # OSQP stopped after one iteration: a real non-optimal status (MultiZoneMPC's documented option).
        return ZoneFleetPlanner(
            [oracle_multizone(p, spec, solver_options={"max_iter": 1} if i == 1 else None) for i, p in enumerate(fleet)],
            spec,
        )

    result = run_coordinated_fleet(scenario, planner, n_buildings=3, days=1, seed=COLD_SEED, cap_kw=9.0)
    assert [k["fallbacks"] for k in result.kpis] == [0, 48, 0]
    assert result.cap is not None and result.cap["intervals_over"] == 0
    assert result.errors == ()  # the controller's own fallback acted, nothing raised


def test_a_cap_settles_every_actuator_within_its_bounds_on_the_building_total():
    """One coordinated step of oracles under a cap: the first actions' total is on the cap,
    each building's actuators sum to its planned total, each within its own bounds."""
    scenario = get_scenario("shoulder_office")
    spec = scenario.control_spec()
    fleet = draw_buildings(scenario, 4, spread=0.3, seed=1)
    run = prepare_run(scenario, days=1, seed=1, warmup_steps=0, weather_part="test")
    loop = build_loop(scenario, run, seed=1, fleet=fleet)
    for t_r in (15.0, 19.0):  # cold rooms: every building heats
        loop.reset(t_r, t_r)
        planner = zoned_planner_factory("oracle", scenario, n_steps=48)(fleet, spec)
        planner.reset(0)
        planner.observe(
            [loop.observation(perfect=True, building=b) for b in range(4)], loop.forecast(perfect=True)
        )
        uncapped = planner.plan()
        np.testing.assert_allclose(uncapped.actuator_w.sum(axis=2), uncapped.power_w, rtol=0, atol=1e-9)
        cap_w = 0.6 * uncapped.power_w[:, 0].sum()
        step = Coordination(np.full(len(run.series), cap_w)).step(planner, loop.start)
        u = step.decision.u_w  # (B, A)
        assert u.shape == (4, spec.n_actuators)
        assert u.sum() == pytest.approx(cap_w, rel=1e-9)
        lower = np.array([a.lower_w for a in spec.actuators])
        upper = np.array([a.upper_w for a in spec.actuators])
        assert np.all(u >= lower - 1e-9) and np.all(u <= upper + 1e-9)


def test_plants_refuse_the_other_kind_of_fleet_in_one_line():
    zoned, one_zone = get_scenario("two_zone_house"), get_scenario("winter_household")
    run = prepare_run(zoned, days=1, seed=0, warmup_steps=0, weather_part="test")
    rc_fleet = draw_fleet(one_zone.sim.params, 2, spread=0.1, rng=np.random.default_rng(0))
    with pytest.raises(InputError, match="building 0 is a RCParams: draw it with pinn_mpc.multizone.draw_zoned_fleet"):
        build_loop(zoned, run, seed=0, fleet=rc_fleet)
    office = get_scenario("shoulder_office").plant.settings.building
    with pytest.raises(InputError, match="other zones than config.params"):
        build_loop(zoned, run, seed=0, fleet=[office])
    one_run = prepare_run(one_zone, days=1, seed=0, warmup_steps=0, weather_part="test")
    with pytest.raises(InputError, match="one-zone buildings"):
        build_loop(one_zone, one_run, seed=0, fleet=[TWO_ZONE_HOUSE])
    with pytest.raises(InputError, match="simulated one building at a time"):
        generate(zoned, days=1, seed=0, n_buildings=2)


def test_with_building_swaps_the_plant_building_and_its_lumped_view():
    scenario = get_scenario("two_zone_house")
    drawn = draw_buildings(scenario, 1, spread=0.3, seed=0)[0]
    swapped = with_building(scenario, drawn)
    assert swapped.plant.settings.building == drawn
    assert swapped.sim.params == drawn.lumped()
    assert dataclasses.replace(swapped, plant=scenario.plant, sim=scenario.sim) == scenario
    with pytest.raises(ValueError, match="zones"):
        with_building(scenario, get_scenario("shoulder_office").plant.settings.building)


def _cli(*extra):
    return main([
        "closed-loop", "--scenario", "two_zone_house", "--days", "1", "--seed", str(COLD_SEED), *extra,
    ])


def test_cli_capped_zoned_fleet_writes_its_cap_account(tmp_path, capsys):
    path = tmp_path / "fleet.json"
    assert _cli("--controller", "thermostat", "--buildings", "3", "--cap-kw", "9", "--json", str(path)) == 0
    out = capsys.readouterr().out
    assert "thermostat x 3 buildings" in out and "cap 9 kW (all day): 0 of 48 capped intervals over it" in out
    data = json.loads(path.read_text())
    assert data["cap"]["intervals_over"] == 0 and max(data["aggregate"]["power_kw"]) <= 9.0 + 1e-6
    drawn = draw_buildings(get_scenario("two_zone_house"), 3, spread=0.2, seed=COLD_SEED)
    assert [b["params"] for b in data["buildings"]] == [json.loads(json.dumps(dataclasses.asdict(p))) for p in drawn]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet.fleet.png", "fleet.json"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--controller", "clairvoyant", "--buildings", "2", "--cap-kw", "5"], "plans one zone with one actuator"),
        (["--controller", "clairvoyant", "--buildings", "2"], "plans one zone with one actuator"),
        (["--controller", "cem", "--buildings", "2", "--model", "m"], "--model does not apply to a fleet of scenario two_zone_house"),
        (["--controller", "thermostat", "--buildings", "2", "--rc", "rc.json"], "--rc is not used by controller"),
        (["--controller", "oracle", "--buildings", "2", "--csv", "t.csv"], "--csv does not apply to a fleet"),
    ],
)
def test_cli_zoned_fleet_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    assert _cli(*args, "--json", str(tmp_path / "k.json")) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []
