"""The dual-setpoint thermostat per zone (issue 43): one mode per zone, changed only when the zone
leaves the dead band on the other side, and the modulating stage's incremental PI law, each
checked against a hand computation of the documented rule or the closed form of a loop whose
zone answers within one interval; the one-zone thermostat is the on/off rule it always was."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.base import ControlSpec, Forecast, Observation
from controllers.thermostat import Thermostat
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.zones import ZoneSpec
from scenarios import get_scenario
from scenarios.running.closed_loop import run_closed_loop

# The band 21-24 C: heating setpoint 21.75, cooling 23.25 (a quarter of the band from each
# edge); with 0.5 K of hysteresis a zone enters heating below 21.5 and cooling above 23.5.
BAND = (21.0, 24.0)
HEAT_C, COOL_C = 21.75, 23.25


def _office() -> ControlSpec:
    spec = get_scenario("shoulder_office").control_spec()
    assert [a.name for a in spec.actuators] == ["heat_east", "cool_east", "heat_west", "cool_west"]
    assert spec.dt_s == 1800.0
    return spec


def _forecast(band: tuple[float, float] = BAND) -> Forecast:
    zero = np.zeros(1)
    return Forecast(
        time_of_day_h=zero, T_a=zero, G=zero, I_g=zero, price=zero, T_min=np.array([band[0]]), T_max=np.array([band[1]])
    )


def _act(thermostat: Thermostat, east: float, west: float, band: tuple[float, float] = BAND) -> np.ndarray:
    spec = thermostat.spec
    history = {"T_r[east]": np.array([east]), "T_r[west]": np.array([west])}
    return np.asarray(thermostat.act(Observation.from_history(0, history, zones=spec.zones), _forecast(band)))


def test_the_on_off_stage_keeps_one_mode_per_zone_until_the_zone_leaves_the_dead_band():
    thermostat = Thermostat(_office(), proportional_band_k=0.0)
    thermostat.reset()
    np.testing.assert_array_equal(_act(thermostat, 21.4, 23.6), [3000.0, 0.0, 0.0, 1000.0])
    np.testing.assert_array_equal(thermostat.zone_modes, [1, -1])
    # east overshoots to 23.4, above the cooler's switch-off (23.0): the one-actuator rule would
    # keep a running cooler on there, but east heats and enters cooling only above 23.5
    np.testing.assert_array_equal(_act(thermostat, 23.4, 23.3), [0.0, 0.0, 0.0, 1000.0])
    np.testing.assert_array_equal(thermostat.zone_modes, [1, -1])
    np.testing.assert_array_equal(_act(thermostat, 23.6, 21.6), [0.0, 1000.0, 0.0, 0.0])
    np.testing.assert_array_equal(thermostat.zone_modes, [-1, -1])
    # west at 21.6 is below the heater's switch-off (22.0) but still in the dead band: it cools
    # (its cooler off), it does not heat
    np.testing.assert_array_equal(_act(thermostat, 23.1, 21.6), [0.0, 1000.0, 0.0, 0.0])  # hysteresis
    np.testing.assert_array_equal(_act(thermostat, 21.4, 21.4), [3000.0, 0.0, 3000.0, 0.0])
    np.testing.assert_array_equal(thermostat.zone_modes, [1, 1])
    thermostat.reset()
    np.testing.assert_array_equal(thermostat.zone_modes, [0, 0])
    np.testing.assert_array_equal(_act(thermostat, 22.5, 23.4), [0.0, 0.0, 0.0, 0.0])


def test_the_modulating_stage_is_the_incremental_pi_law_by_hand():
    band_k, integral_s = 30.0, 600.0
    thermostat = Thermostat(_office(), proportional_band_k=band_k, integral_time_s=integral_s)
    thermostat.reset()
    ratio = 1800.0 / integral_s  # dt / Ti = 3

    def fraction(error: float, last_error: float, last: float) -> float:
        return min(max(last + (error - last_error + ratio * error) / band_k, 0.0), 1.0)

    # heating starts from 0 with e_{-1} = 0; e = 21.75 - 21.4 = 0.35 K: 0.35 * 4 / 30 of 3 kW
    f1 = fraction(0.35, 0.0, 0.0)
    assert f1 == pytest.approx(1.4 / 30.0)
    np.testing.assert_allclose(_act(thermostat, 21.4, 22.5), [3000.0 * f1, 0.0, 0.0, 0.0], rtol=1e-12)
    f2 = fraction(0.15, 0.35, f1)  # the room at 21.6: e = 0.15 K
    np.testing.assert_allclose(_act(thermostat, 21.6, 22.5), [3000.0 * f2, 0.0, 0.0, 0.0], rtol=1e-12)
    assert f2 == pytest.approx(1.65 / 30.0)
    # 22.5 (e = -0.75): the law asks a negative fraction, the heater is off and stays heating
    np.testing.assert_allclose(_act(thermostat, 22.5, 22.5), [0.0, 0.0, 0.0, 0.0], atol=1e-12)
    assert fraction(-0.75, 0.15, f2) == 0.0 and thermostat.zone_modes[0] == 1
    # back at the setpoint (e = 0): the error's rise of 0.75 K alone moves it, from 0 (clipped)
    np.testing.assert_allclose(_act(thermostat, HEAT_C, 22.5)[0], 3000.0 * 0.75 / 30.0, rtol=1e-9)
    # saturated at 10 C, then at the setpoint: from full power, not from a wound-up 1.57
    assert (0.0 - 0.75 + ratio * 11.75) / 30.0 + 0.025 > 1.0
    np.testing.assert_allclose(_act(thermostat, 10.0, 22.5)[0], 3000.0)
    np.testing.assert_allclose(_act(thermostat, HEAT_C, 22.5)[0], 3000.0 * (1.0 - 11.75 / 30.0), rtol=1e-12)
    # cooling mirrors it on T_r - 23.25; the heater's state is dropped when east cools
    e = 23.75 - COOL_C
    np.testing.assert_allclose(_act(thermostat, 23.75, 22.5), [0.0, 1000.0 * e * 4.0 / 30.0, 0.0, 0.0], rtol=1e-12)
    np.testing.assert_array_equal(thermostat.zone_modes, [-1, 0])


def _instant_zone_loop(thermostat: Thermostat, base_c: float, swing_k: float, steps: int) -> np.ndarray:
    """A one-zone building with a heater and a cooler whose room answers within one interval:
    T_{k+1} = base_c + swing_k x (heater's fraction - cooler's fraction) at step k, as an
    EnergyPlus zone's air does; the rooms (steps + 1,) [C]."""
    t = [base_c]
    for _ in range(steps):
        history = {"T_r[room]": np.array([t[-1]]), "T_r[other]": np.array([22.5])}
        obs = Observation.from_history(0, history, zones=thermostat.spec.zones)
        powers = np.asarray(thermostat.act(obs, _forecast()))
        heat, cool = powers[0] / 3000.0, powers[1] / 3000.0
        t.append(base_c + swing_k * (heat - cool))
    return np.array(t)


def _room_spec() -> ControlSpec:
    return ControlSpec(
        actuators=(
            ActuatorSpec(upper_w=3000.0, zone=0, name="heat"),
            ActuatorSpec(upper_w=3000.0, zone=0, heats=False, name="cool"),
        ),
        zones=(ZoneSpec("room"), ZoneSpec("other")),
    )


@pytest.mark.parametrize(("base_c", "setpoint_c"), [(16.0, HEAT_C), (28.0, COOL_C)])
def test_a_zone_that_answers_within_an_interval_settles_at_the_setpoint_where_on_off_chatters(base_c, setpoint_c):
    # With the room T = base + G f (G = 7 K, about the swing of an EnergyPlus perimeter zone at
    # full power) the PI law's error obeys e_{k+1} = (1 - a - a r) e_k + a e_{k-1}, a = G/P =
    # 7/30, r = dt/Ti = 3: the roots of z^2 - (1 - 4a) z - a, 0.52 and -0.45, lie inside the
    # unit circle, so the room settles at the setpoint (on the fraction |setpoint - base| / G).
    swing = 7.0
    a = swing / 30.0
    roots = np.roots([1.0, -(1.0 - 4.0 * a), -a])
    assert np.abs(roots).max() < 0.55
    modulating = Thermostat(_room_spec())
    assert (modulating.proportional_band_k, modulating.integral_time_s) == (30.0, 600.0)
    t = _instant_zone_loop(modulating, base_c, swing, 40)
    np.testing.assert_allclose(t[-1], setpoint_c, atol=1e-6)
    assert np.abs(t[-3:] - setpoint_c).max() < 1e-5
    heat_first = base_c < setpoint_c
    np.testing.assert_array_equal(modulating.zone_modes, [1 if heat_first else -1, 0])
    # on/off: full power and off in turn, by the whole swing or more, never settling
    on_off = Thermostat(_room_spec(), proportional_band_k=0.0)
    t = _instant_zone_loop(on_off, base_c, swing, 40)
    assert np.ptp(t[-10:]) >= swing


def test_in_closed_loop_no_zone_heats_and_cools_at_once_and_modes_change_only_outside_the_dead_band() -> None:
    scenario = get_scenario("shoulder_office")
    spec = scenario.control_spec()
    seen: list[tuple[np.ndarray, float, float, np.ndarray]] = []

    class Recorded(Thermostat):
        def act(self, obs: Observation, forecast: Forecast) -> float | np.ndarray:
            powers = np.asarray(super().act(obs, forecast))
            seen.append((obs.t_r_zones_c(), float(forecast.T_min[0]), float(forecast.T_max[0]), self.zone_modes))
            return powers

    result = run_closed_loop(scenario, Recorded(spec), days=7, seed=0)
    demand = result.trajectory[[f"u[{a.name}]" for a in spec.actuators]].to_numpy()  # (N, A)
    heating = demand[:, [0, 2]] > 0.0  # east, west
    cooling = demand[:, [1, 3]] > 0.0
    assert heating.any() and cooling.any()  # the test week needs both
    assert not (heating & cooling).any()
    changes = 0
    for (t_r, t_min, t_max, mode), (_, _, _, before) in zip(seen[1:], seen[:-1], strict=True):
        quarter = 0.25 * (t_max - t_min)
        heat_on, cool_on = t_min + quarter - 0.25, t_max - quarter + 0.25
        for z in range(2):
            if mode[z] != before[z]:
                changes += 1
                assert (mode[z] == 1 and t_r[z] < heat_on) or (mode[z] == -1 and t_r[z] > cool_on)
    assert changes >= 2


def test_the_one_zone_thermostat_stays_on_off():
    spec = get_scenario("winter_household").control_spec()
    thermostat = Thermostat(spec, proportional_band_k=30.0)
    obs = Observation.from_history(0, {"T_r": np.array([20.0])})
    assert thermostat.act(obs, _forecast((20.0, 22.0))) == spec.actuator.upper_w  # below 20.25


@pytest.mark.parametrize(("field", "value"), [
    ("proportional_band_k", -1.0), ("proportional_band_k", float("inf")), ("integral_time_s", 0.0),
    ("integral_time_s", float("nan")),
])
def test_misuse_names_the_field_and_the_value(field, value):
    with pytest.raises(ValueError, match=rf"Thermostat {field} must be .* got {value!r}"):
        Thermostat(_office(), **{field: value})


def test_the_on_off_stage_is_each_actuators_one_actuator_rule():
    # With the thresholds a quarter of the band in and 0.5 K of hysteresis, a heater is off
    # wherever its zone's cooler switches on and the reverse, so the mode changes nothing of the
    # on/off stage: each actuator runs Thermostat.switch on its zone, as before issue 43.
    spec = _office()
    thermostat = Thermostat(spec, proportional_band_k=0.0)
    rng = np.random.default_rng(7)
    on = np.zeros(4, dtype=bool)
    for k in range(400):
        band = (21.0, 24.0) if (k // 24) % 2 else (16.0, 28.0)
        t_r = rng.uniform(band[0] - 2.0, band[1] + 2.0, size=2) if k % 5 == 0 else rng.uniform(20.5, 24.5, size=2)
        for i, a in enumerate(spec.actuators):
            on[i] = thermostat.switch(t_r[a.zone : a.zone + 1], on[i : i + 1], *band, heats=a.heats)[0]
        expected = [a.on_off(bool(o)) for a, o in zip(spec.actuators, on, strict=True)]
        np.testing.assert_array_equal(_act(thermostat, *t_r, band=band), expected)
