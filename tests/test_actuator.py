"""The declared actuator (pinn_mpc.actuator.ActuatorSpec): its bounds, clip and on/off levels
against analytic cases, the checks of its fields, and the one actuator of today's buildings
(SimConfig.actuators, ControlSpec.actuators)."""

import dataclasses

import numpy as np
import pytest
import torch

from controllers.base import ControlSpec, Forecast, Observation, fallback_power
from pinn_mpc.actuator import Actuator, ActuatorSpec, CopCurve
from pinn_mpc.models.rc import RCBatchModel
from pinn_mpc.physics import PAPER_HOUSEHOLD, discretise
from pinn_mpc.simulator import SimConfig, backup_power
from scenarios.inputs.registry import COLD_ROOM
from scenarios.inputs.scenario_file import get_scenario

#: A heater that never runs below 500 W (a floor above zero, so that no bound can hide in 0).
FLOOR = ActuatorSpec(lower_w=500.0, upper_w=4000.0)


def test_clip_holds_a_power_within_the_bounds():
    asked = np.array([-1.0, 0.0, 499.9, 500.0, 2500.0, 4000.0, 4000.1, 1e9])
    np.testing.assert_array_equal(FLOOR.clip(asked), [500.0, 500.0, 500.0, 500.0, 2500.0, 4000.0, 4000.0, 4000.0])
    assert FLOOR.clip(-3.0) == 500.0 and FLOOR.clip(1234.5) == 1234.5
    # in kW, the QPs' unit: a plan of 0.1 kW and of 5 kW is the floor and the top in W
    np.testing.assert_array_equal(FLOOR.clip_kw(np.array([0.1, 2.0, 5.0])) * 1000.0, [500.0, 2000.0, 4000.0])
    assert (FLOOR.lower_kw, FLOOR.upper_kw, FLOOR.span_w) == (0.5, 4.0, 3500.0)


def test_on_off_and_fractions_of_the_range():
    assert FLOOR.on_off(True) == 4000.0 and FLOOR.on_off(False) == 500.0
    assert FLOOR.on_off(np.bool_(True)) == 4000.0
    np.testing.assert_array_equal(FLOOR.on_off(np.array([True, False, True])), [4000.0, 500.0, 4000.0])
    np.testing.assert_array_equal(
        FLOOR.at_fraction(np.array([-0.5, 0.0, 0.25, 1.0, 2.0])), [500.0, 500.0, 1375.0, 4000.0, 4000.0]
    )
    assert FLOOR.at_fraction(0.5) == 2250.0


def test_a_zero_floor_gives_the_numbers_the_bounds_written_out_gave():
    """With the lower bound 0 (every building today) each operation is, bit for bit, the
    expression it replaced (``np.clip(u, 0.0, u_max)``, ``f * u_max``, ...)."""
    u_max = 7342.123456789  # not a round number: kW and W differ in the last bits
    heater = ActuatorSpec(upper_w=u_max)
    rng = np.random.default_rng(0)
    u = rng.uniform(-2 * u_max, 2 * u_max, 1000)
    f = rng.random(1000)
    p_kw = u / 1000.0
    np.testing.assert_array_equal(heater.clip(u), np.clip(u, 0.0, u_max))
    np.testing.assert_array_equal(heater.clip_kw(p_kw) * 1000.0, np.clip(p_kw, 0.0, u_max / 1000.0) * 1000.0)
    np.testing.assert_array_equal(heater.at_fraction(f), f * u_max)
    np.testing.assert_array_equal(heater.at_fraction(f - 0.3), np.clip(f - 0.3, 0.0, 1.0) * u_max)
    assert heater.at_fraction(0.5) == 0.5 * u_max
    np.testing.assert_array_equal(heater.on_off(f < 0.5), np.where(f < 0.5, u_max, 0.0))


def test_the_lowest_power_is_the_efficiencys_share_of_the_top():
    heat_pump = ActuatorSpec(upper_w=4000.0, efficiency=Actuator(kind="heat_pump", min_modulation=0.3))
    assert heat_pump.min_power_w == pytest.approx(1200.0) and not heat_pump.is_ideal
    np.testing.assert_array_equal(heat_pump.gain(np.array([0.0, 10.0])), heat_pump.efficiency.gain(np.array([0.0, 10.0])))
    assert ActuatorSpec(upper_w=4000.0).min_power_w == 0.0
    assert FLOOR.sign == 1.0 and ActuatorSpec(upper_w=1.0, heats=False).sign == -1.0


@pytest.mark.parametrize(
    ("fields", "error", "match"),
    [
        ({"upper_w": 0.0}, ValueError, r"0 <= lower_w < upper_w .* got lower_w=0.0, upper_w=0.0"),
        ({"upper_w": 100.0, "lower_w": 100.0}, ValueError, "0 <= lower_w < upper_w"),
        ({"upper_w": 100.0, "lower_w": -5.0}, ValueError, r"cooling is an actuator of its own"),
        ({"upper_w": float("nan")}, ValueError, "must be finite numbers"),
        ({"upper_w": True}, ValueError, "must be finite numbers"),
        ({"upper_w": 100.0, "heats": 1}, TypeError, r"heats must be True \(heats\) or False"),
        ({"upper_w": 100.0, "zone": -1}, ValueError, "zone must be a zone index >= 0"),
        ({"upper_w": 100.0, "heats": False, "efficiency": Actuator(kind="heat_pump")}, ValueError,
         "a heat_pump efficiency heats"),
    ],
)
def test_an_actuator_that_cannot_be_is_refused(fields, error, match):
    with pytest.raises(error, match=match):
        ActuatorSpec(**fields)


def test_todays_buildings_declare_one_actuator_from_the_scenario():
    cooling = SimConfig(params=COLD_ROOM, u_max_w=2500.0, backup_low_c=0.0, backup_high_c=8.0)
    assert cooling.actuators == (ActuatorSpec(upper_w=2500.0, heats=False),)
    scenario = get_scenario("heat_pump_household")
    (heat_pump,) = scenario.sim.actuators
    assert heat_pump.upper_w == scenario.sim.u_max_w and heat_pump.lower_w == 0.0 and heat_pump.heats
    assert heat_pump.efficiency == scenario.sim.actuator and heat_pump.zone == 0
    spec = scenario.control_spec()
    assert spec.actuators == scenario.sim.actuators and spec.actuator is spec.actuators[0]
    assert spec.u_max_w == heat_pump.upper_w and spec.heating
    assert not get_scenario("cold_storage").control_spec().heating


def test_a_control_spec_holds_named_actuators_on_its_zones() -> None:
    with pytest.raises(ValueError, match=r"names each one, uniquely .* got names \['', ''\]"):
        ControlSpec(actuators=(FLOOR, FLOOR))
    with pytest.raises(ValueError, match=r"zone index\(es\) \[1\] outside"):
        ControlSpec(actuators=(dataclasses.replace(FLOOR, zone=1),))
    with pytest.raises(ValueError, match="at least one actuator, got none"):
        ControlSpec(actuators=())
    with pytest.raises(ValueError, match="ActuatorSpec.name must be letters"):
        dataclasses.replace(FLOOR, name="a[b]")
    both = ControlSpec(actuators=(dataclasses.replace(FLOOR, name="heat"), ActuatorSpec(upper_w=2000.0, heats=False, name="cool")))
    assert both.n_actuators == 2 and not both.single
    with pytest.raises(TypeError, match="a tuple of ActuatorSpec"):
        ControlSpec(actuators=[FLOOR])  # type: ignore[arg-type]


def test_the_backup_and_the_fallback_force_the_actuators_bounds():
    config = SimConfig()
    t_r = np.array([16.0, 19.0, 21.0])  # below the backup's 17 C, between, above its 20.5 C
    np.testing.assert_array_equal(backup_power(t_r, np.full(3, 1234.0), config), [5000.0, 1234.0, 0.0])
    spec = ControlSpec(actuators=(FLOOR,))
    band = Forecast(*(np.full(1, v) for v in (0.0, 5.0, 0.0, 0.0, 0.1, 20.0, 24.0)))
    history = {"T_r": np.array([19.0])}
    assert fallback_power(Observation.from_history(0, history), band, spec) == 4000.0  # below the lower quarter
    history = {"T_r": np.array([22.0])}
    assert fallback_power(Observation.from_history(0, history), band, spec) == 500.0  # off is the floor
    empty = band._replace(T_min=np.zeros(0), T_max=np.zeros(0))
    assert fallback_power(Observation.from_history(0, history), empty, spec) == 500.0


def test_the_substep_kernel_forces_the_actuators_bounds():
    """A room above the backup's band gets the actuator's off power (its floor), one below it
    the full power, in every substep: the interval mean is that bound exactly."""
    from pinn_mpc.substeps import integrate_interval

    ad, bd = (m[None] for m in discretise(PAPER_HOUSEHOLD, 60.0))
    x = np.array([[25.0, 25.0], [10.0, 10.0]])  # too warm, too cold (backup 17 .. 20.5 C)
    delivered, overridden, t_r = np.empty(2), np.empty(2, dtype=bool), np.empty((2, 30))
    integrate_interval(
        x, np.array([2000.0, 2000.0]), np.zeros((2, 3)), ad, bd, np.ones(2), 0.0, 500.0, 4000.0,
        17.0, 20.5, True, delivered, overridden, t_r,
    )
    np.testing.assert_array_equal(delivered, [500.0, 4000.0])
    assert overridden.all()


def test_the_rc_model_forces_its_actuators_bounds_and_heats_as_its_parameters():
    model = RCBatchModel(PAPER_HOUSEHOLD, dt_s=1800.0, actuator=FLOOR)
    history = {"T_r": np.array([25.0, 25.0]), "T_m": np.array([25.0, 25.0]), "u_phys": np.array([0.0])}
    exog = {"T_a": np.full(2, 5.0), "G": np.zeros(2), "I_g": np.zeros(2)}
    roll = model.rollout(history, torch.full((1, 2), 2000.0), exog)
    assert float(roll.u_phys_w[0, 0, 0]) == 500.0  # too warm for the backup: off, at the floor
    with pytest.raises(ValueError, match="the actuator cools but params.eta = 1"):
        RCBatchModel(PAPER_HOUSEHOLD, dt_s=1800.0, actuator=ActuatorSpec(upper_w=1.0, heats=False))


@pytest.mark.parametrize(
    ("cop", "increasing", "expected"),
    [
        # Pool-adjacent violators: each violating run replaced by its mean.
        ((3.0, 2.5, 4.0, 3.9), True, (2.75, 2.75, 3.95, 3.95)),
        ((3.0, 2.5, 4.0, 3.9), False, (3.35, 3.35, 3.35, 3.35)),
        ((5.0, 4.0, 3.0, 4.5), True, (4.0, 4.0, 4.0, 4.5)),
        ((2.0, 3.0, 3.0, 6.0), True, (2.0, 3.0, 3.0, 6.0)),
    ],
)
def test_a_cop_curve_made_monotone_is_the_least_squares_monotone_curve(cop, increasing, expected):
    """The monotone curve nearest in least squares over the knots (the isotonic regression,
    worked by hand), and a curve that already is monotone unchanged (the same object)."""
    curve = CopCurve(t_a_c=(-10.0, 0.0, 10.0, 20.0), cop=cop)
    out = curve.monotone(increasing=increasing)
    np.testing.assert_allclose(out.cop, expected, rtol=0, atol=1e-12)
    assert out.t_a_c == curve.t_a_c
    grid = np.linspace(-30.0, 40.0, 701)
    steps = np.diff(out(grid)) * (1.0 if increasing else -1.0)
    assert steps.min() >= -1e-12
    assert out.monotone(increasing=increasing) is out
