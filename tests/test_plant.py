"""The 3R3C plant with an envelope node against the 2R2C it extends and its analytic steady state."""

import dataclasses
import json
from typing import Any

import numpy as np
import pytest

from pinn_mpc import physics
from pinn_mpc.errors import InputError
from pinn_mpc.plant import Plant, plant_matrices
from pinn_mpc.simulator import SimConfig, Simulator
from scenarios.inputs.scenario_file import get_scenario
from scenarios.plants.energyplus.settings import EnergyPlusSettings
from scenarios.plants.rc import RCSettings
from scenarios.plants.settings import PlantSettings
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.factory import build_controller

PARAMS = dataclasses.replace(
    physics.PAPER_HOUSEHOLD, solar_aperture_m2=3.0, solar_to_air_fraction=0.3, gain_to_air_fraction=0.5
)
WIDE = SimConfig(params=PARAMS, backup_low_c=-50.0, backup_high_c=80.0)
ENVELOPE = Plant(kind="3r3c", envelope_capacity_j_per_k=1.0e7, envelope_resistance_fraction=0.5)


def _trajectory(config: SimConfig, n: int = 96) -> np.ndarray:
    rng = np.random.default_rng(3)
    sim = Simulator(config, n_buildings=2)
    sim.reset(18.0, 17.0)
    out = []
    for _ in range(n):
        r = sim.step(rng.uniform(0, 5000, 2), rng.normal(5, 5, 2), rng.uniform(0, 500, 2), 300.0)
        out.append(r.t_r_sub_c)
    return np.concatenate(out, axis=1)


def test_vanishing_envelope_capacity_reduces_to_the_2r2c():
    # C_e at the plausible floor (1e4 J/K): the envelope settles in seconds, a quasi-static node
    # on the series resistance R_re + R_ea = R_ra
    # on the series resistance R_re + R_ea = R_ra; what is left scales with C_e (the heat it stores)
    two = _trajectory(WIDE)

    def gap(c_e: float) -> float:
        plant = dataclasses.replace(ENVELOPE, envelope_capacity_j_per_k=c_e)
        return float(np.abs(_trajectory(dataclasses.replace(WIDE, plant=plant)) - two).max())

    assert gap(1.0e4) < 0.02
    assert gap(1.0e4) < gap(1.0e5) / 5
    # with a real envelope the plant differs visibly: it is a mismatch, not rounding
    assert np.abs(_trajectory(dataclasses.replace(WIDE, plant=ENVELOPE)) - _trajectory(WIDE)).max() > 0.2


def test_vanishing_inner_resistance_lumps_the_envelope_with_the_room():
    # R_re -> 0: T_e = T_r, so C_e adds to the room air's capacity
    inner = dataclasses.replace(ENVELOPE, envelope_resistance_fraction=1.0 - 1e-7, envelope_capacity_j_per_k=2.0e6)
    lumped = dataclasses.replace(WIDE, params=dataclasses.replace(PARAMS, c_r_j_per_k=PARAMS.c_r_j_per_k + 2.0e6))
    np.testing.assert_allclose(
        _trajectory(dataclasses.replace(WIDE, plant=inner)), _trajectory(lumped), atol=0.01
    )


def test_steady_state_matches_the_analytic_solution():
    config = dataclasses.replace(WIDE, plant=ENVELOPE)
    sim = Simulator(config)
    sim.reset(10.0, 10.0)
    u, t_a, g, i_g = 3000.0, -2.0, 150.0, 400.0
    for _ in range(48 * 120):  # the mass mode (about 9 days) has died out to 1e-7 K
        sim.step(u, t_a, g, i_g)
    # Same UA as the 2R2C (R_re + R_ea = R_ra): T_r and T_m are its steady state, and the
    # envelope sits on the loss path at the share f of the drop from the room to outdoors.
    t_r, t_m = physics.steady_state(PARAMS, u_w=u, t_a_c=t_a, g_w_per_m2=g, i_g_w=i_g)
    expected = [t_r, t_m, t_a + 0.5 * (t_r - t_a)]
    np.testing.assert_allclose(sim.full_state[0], expected, atol=1e-6)
    a, b = plant_matrices(PARAMS, ENVELOPE)
    np.testing.assert_allclose(a @ np.array(expected) + b @ [u, t_a, g, i_g], 0.0, atol=1e-9)


def test_simulator_api_hides_the_envelope():
    sim = Simulator(dataclasses.replace(WIDE, plant=ENVELOPE), n_buildings=3)
    sim.reset(20.0, 19.0)
    assert sim.state.shape == (3, 2) and sim.full_state.shape == (3, 3)
    np.testing.assert_array_equal(sim.full_state[:, 2], 20.0)  # T_e starts at the room's
    warm_envelope = sim.step(0.0, 0.0).t_r_c
    sim.reset(20.0, 19.0, t_e_c=5.0)
    res = sim.step(0.0, 0.0)
    assert res.t_r_sub_c.shape == (3, 30)
    assert np.all(res.t_r_c < warm_envelope)  # a cold envelope cools the room faster


@pytest.mark.parametrize(
    ("change", "key"),
    [
        ({"kind": "4r4c"}, "Plant.kind"),
        ({"envelope_capacity_j_per_k": -1.0}, "Plant.envelope_capacity_j_per_k"),
        ({"envelope_resistance_fraction": 1.0}, "Plant.envelope_resistance_fraction"),
    ],
)
def test_bad_plant_settings_name_the_key(change: dict, key: str):
    with pytest.raises(InputError, match=key):
        dataclasses.replace(ENVELOPE, **change)


@pytest.mark.parametrize("name", ["qp-mpc", "oracle"])
def test_mismatch_scenario_runs_closed_loop(name: str):
    scenario = get_scenario("mismatch_household")
    assert scenario.plant.kind == "3r3c"
    kwargs: dict[str, Any] = {"rc_params": scenario.sim.params} if name == "qp-mpc" else {}
    controller = build_controller(name, scenario, n_steps=48, **kwargs)
    result = run_closed_loop(scenario, controller, days=1, seed=2, warmup_steps=4)
    assert result.kpis["fallbacks"] == 0 and not result.errors
    assert result.trajectory["u"].between(0.0, scenario.sim.u_max_w).all()
    assert result.kpis["discomfort_kh"] < 5.0


def test_the_modelling_package_knows_only_the_rc_structures():
    """pinn_mpc's Plant is what its simulator integrates: an EnergyPlus kind is the plants
    layer's (PlantSettings with the kind's settings), and a scenario's SimConfig.plant follows
    its PlantSettings."""
    with pytest.raises(InputError, match="Plant.kind 'energyplus' is unknown; choose one of 2r2c, 3r3c"):
        Plant(kind="energyplus")
    assert PlantSettings().rc == Plant()
    envelope = RCSettings(
        envelope_capacity_j_per_k=ENVELOPE.envelope_capacity_j_per_k,
        envelope_resistance_fraction=ENVELOPE.envelope_resistance_fraction,
    )
    assert PlantSettings(kind="3r3c", settings=envelope).rc == ENVELOPE
    office = get_scenario("eplus_small_office")
    assert not office.plant.true_state and not office.plant.fleets
    assert office.plant.reference == "thermostat" and office.reference == "thermostat"
    assert office.sim.plant == Plant()  # the nominal 2R2C; the plant runs in EnergyPlus
    assert office.plant.settings == EnergyPlusSettings(
        building="small_office", weather="usa_il_chicago", heater_w=25000.0
    )
    assert office.plant.settings.weather_file == "usa_il_chicago"
    mismatch = get_scenario("mismatch_household")
    assert mismatch.sim.plant == ENVELOPE and mismatch.plant.true_state
    assert dataclasses.replace(mismatch, plant=PlantSettings()).sim.plant == Plant()
    with pytest.raises(ValueError, match="kind 'energyplus' takes EnergyPlusSettings, got RCSettings"):
        PlantSettings(kind="energyplus")
    with pytest.raises(InputError, match="plant kind 'mars' is unknown; choose one of 2r2c, 3r3c, energyplus"):
        PlantSettings(kind="mars")


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ({"kind": "2r2c", "weather": "usa_il_chicago"}, "weather belongs to another kind of plant, not '2r2c'"),
        ({"kind": "energyplus", "building": "small_office"}, "simulation.plant.weather: missing"),
        ({"kind": "energyplus", "building": "small_office", "weather": "usa_il_chicago", "heater_w": -1.0},
         r"simulation.plant.heater_w = -1.0 must be a power >= 0 W"),
        ({"kind": "energyplus", "building": "small_office", "weather": "usa_il_chicago",
          "envelope_resistance_fraction": 1.0},
         "envelope_resistance_fraction belongs to another kind of plant, not 'energyplus'"),
        ({"kind": "3r3c", "envelope_resistance_fraction": 1.0},
         "simulation.plant.envelope_resistance_fraction = 1.0 must lie strictly between 0 and 1"),
        ({"kind": "2r2c", "speed": 1.0}, r"simulation.plant.speed: unknown key; \[simulation.plant\] of kind"),
    ],
)
def test_a_plant_table_takes_the_fields_of_its_kind(table: dict, match: str, tmp_path):
    """A scenario file's [simulation.plant] holds its kind's fields; another kind's field at its
    default is what older exports wrote (every kind's fields), read as before."""
    from scenarios.inputs.scenario_file import scenario_to_toml

    text = scenario_to_toml(get_scenario("winter_household"))
    block = '[simulation.plant]\nkind = "2r2c"\nenvelope_capacity_j_per_k = 10000000.0\nenvelope_resistance_fraction = 0.5\n'
    assert block in text

    def with_plant(lines: str):
        path = tmp_path / "s.toml"
        path.write_text(text.replace(block, "[simulation.plant]\n" + lines))
        return path

    written = "".join(f"{k} = {json.dumps(v)}\n" for k, v in table.items())
    with pytest.raises(InputError, match=match):
        get_scenario(str(with_plant(written)))
    older = with_plant(block.split("\n", 1)[1] + 'building = ""\nweather = ""\nheater_w = 0.0\nzones = "merged"\n')
    assert get_scenario(str(older)).plant == get_scenario("winter_household").plant


def test_a_plant_is_given_once_with_its_scenario(tmp_path):
    """A scenario file's plant is [simulation.plant] only (a top-level [plant] is an unknown
    key), and a loop refuses a simulator structure its plant settings do not have."""
    from scenarios.inputs.scenario_file import scenario_to_toml
    from scenarios.inputs.series import ExogenousSeries
    from scenarios.running.engine import ClosedLoop

    mismatch = get_scenario("mismatch_household")
    path = tmp_path / "m.toml"
    path.write_text(scenario_to_toml(mismatch) + '\n[plant]\nkind = "3r3c"\n')
    with pytest.raises(InputError, match=r"plant: unknown key; \[top level\] takes name, description, "):
        get_scenario(str(path))
    series = ExogenousSeries.from_frame(mismatch.exogenous(days=1, seed=0, part="train"))
    with pytest.raises(ValueError, match="is not the simulator's structure of plant_settings"):
        ClosedLoop(mismatch.sim, series, spec=mismatch.control_spec(), initial_t_r_c=20.0,
                   initial_t_m_c=20.0, plant_settings=PlantSettings())
