"""The trust guard of the sampling planners over a building of several zones
(:mod:`controllers.zone_sampling`, :class:`controllers.trust.ZoneTrust`): the zones' comfort
margin default, each zone's margin from its filtered replay error, the replay of the fallback
RC against the exact ZOH, and the hand-over to the QP on the model's multi-zone RC when the
model is wrong."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from controllers.estimators import MultiZoneKalmanEstimator, observer_noise
from controllers.objective import ZoneObjective
from controllers.sampling import CEM, Guard, RandomShooting
from controllers.trust import TrustSettings, ZoneRCReplay, ZoneTrust
from controllers.zone_sampling import (
    ZONE_COMFORT_MARGIN_K,
    ZONE_CREDIBLE_RC_K,
    ZONE_LAGGED_MARGIN_K,
    ZoneGuard,
    zone_comfort_margin_k,
)
from pinn_mpc.models.multizone_rc import MultiZoneRCModel
from pinn_mpc.multizone import MultiZoneParams
from scenarios import get_scenario
from scenarios.plants.multizone import MultiZoneSettings
from scenarios.records import RunKpis
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.factory import build_controller
from tests.test_multizone_planners import _building, _loop


def _planner_model(name: str, params: MultiZoneParams) -> MultiZoneRCModel:
    """A multi-zone RC model of ``params`` with the scenario ``name``'s backup limits and
    observer noises (what the CLI plans over)."""
    scenario = get_scenario(name)
    settings = scenario.plant.settings
    assert isinstance(settings, MultiZoneSettings)
    spec = scenario.control_spec()
    low, high = settings.backup_limits(scenario.sim.backup_low_c, scenario.sim.backup_high_c)
    process, measurement = observer_noise(spec)
    return MultiZoneRCModel(
        params, spec.actuators, spec.dt_s, backup_low_c=low, backup_high_c=high,
        process_std_c=process, measurement_std_c=measurement,
    )


class _WrongModel(MultiZoneRCModel):
    """A multi-zone RC model of wrong parameters that falls back on the true building (as a
    learned model carries the RC identified from its data)."""

    def __init__(self, model: MultiZoneRCModel, fallback: MultiZoneParams) -> None:
        self.__dict__.update(model.__dict__)
        self._fallback = fallback

    @property
    def zone_params(self) -> MultiZoneParams:
        return self._fallback


def _scaled(params: MultiZoneParams, field: str, factor: float) -> MultiZoneParams:
    zones = tuple(dataclasses.replace(z, rc=dataclasses.replace(z.rc, **{field: getattr(z.rc, field) * factor})) for z in params.zones)
    return dataclasses.replace(params, zones=zones)


# -- the comfort margin's default -----------------------------------------------------------------


@pytest.mark.parametrize("planner", [CEM, RandomShooting])
def test_the_zones_margin_default_is_the_same_from_the_cli_and_the_python_api(planner):
    name = "shoulder_office"
    building, spec = _building(name)
    model = _planner_model(name, building)
    direct = planner(model, spec)
    cli = build_controller(
        "cem" if planner is CEM else "random-shooting", get_scenario(name), zone_params=building, n_steps=48
    )
    assert direct.comfort_margin_k == cli.comfort_margin_k == zone_comfort_margin_k(model) == ZONE_COMFORT_MARGIN_K
    assert planner(model, spec, comfort_margin_k=0.2).comfort_margin_k == 0.2
    with pytest.raises(ValueError, match=r"comfort_margin_k must lie in \[0, 1\) K \(or None: the default\), got -0.1"):
        planner(model, spec, comfort_margin_k=-0.1)


def test_a_model_from_measured_lags_takes_the_lagged_margin_and_one_zone_keeps_its_own():
    name = "shoulder_office"
    building, _ = _building(name)

    class _Lagged(MultiZoneRCModel):
        estimates_state = False

    lagged = _Lagged(building, _planner_model(name, building).actuators, 1800.0)
    assert zone_comfort_margin_k(lagged) == ZONE_LAGGED_MARGIN_K > 0
    from pinn_mpc.actuator import ActuatorSpec
    from pinn_mpc.models.rc import RCBatchModel
    from pinn_mpc.physics import PAPER_HOUSEHOLD

    one = get_scenario("winter_household")
    model = RCBatchModel(PAPER_HOUSEHOLD, dt_s=one.control_spec().dt_s, actuator=ActuatorSpec(upper_w=one.sim.u_max_w))
    assert CEM(model, one.control_spec()).comfort_margin_k == 0.01
    with pytest.raises(ValueError, match="a ZoneGuard watches a model of several zones; this scenario has one zone"):
        CEM(model, one.control_spec(), guard=ZoneGuard())
    building_spec = _building(name)[1]
    with pytest.raises(ValueError, match="not a guard's one-zone RC; leave guard out or give a controllers.zone_sampling.ZoneGuard"):
        CEM(_planner_model(name, building), building_spec, guard=Guard(rc=PAPER_HOUSEHOLD))


# -- each zone's margin from its error ------------------------------------------------------------


def test_each_zones_margin_is_its_filtered_replay_error_times_the_factor_between_base_and_max():
    settings = TrustSettings(
        filter_gain=0.3, margin_factor=2.0, max_margin_k=1.0, margin_from_replay=True, error_alone_k=0.4
    )
    trust = ZoneTrust(settings, ["a", "b", "c"], 1000.0)
    errors = np.array([[0.2, 1.0, 0.05], [-0.6, -0.9, np.nan], [0.4, 1.1, -0.05]])
    for row in errors:
        trust.observe(row, np.full(3, np.nan))
    # by hand: the first |error|, then f += 0.3 (|e| - f); NaN is left out
    a = 0.2 + 0.3 * (0.6 - 0.2)
    a = a + 0.3 * (0.4 - a)  # 0.344
    b = 1.0 + 0.3 * (0.9 - 1.0)
    b = b + 0.3 * (1.1 - b)  # 1.009
    np.testing.assert_allclose([m.state.replay_k for m in trust.zones], [a, b, 0.05], rtol=1e-12)
    np.testing.assert_allclose(trust.margins_k(0.3), [2 * a, 1.0, 0.3], rtol=1e-12)  # factor, max, base
    np.testing.assert_allclose(trust.margins_k(0.0), [2 * a, 1.0, 0.1], rtol=1e-12)
    # The verdict is the building's, on the zones' mean |error| (rows with a NaN left out):
    # without the RC's, the model is distrusted alone above error_alone_k (0.4 K).
    building = (0.2 + 1.0 + 0.05) / 3
    building += 0.3 * ((0.4 + 1.1 + 0.05) / 3 - building)  # 0.4467
    assert trust.building.state.replay_k == pytest.approx(building, rel=1e-12)
    assert trust.reason() == "prediction error (most in b)"
    # the RC errs 0.6 K in every zone: the model's 0.7 x 0.4467 K is not above twice that
    trust.observe(np.zeros(3), np.array([0.6, -0.6, 0.6]))
    assert trust.building.state.replay_rc_k == pytest.approx(0.6, rel=1e-12)
    assert trust.reason() is None
    trust.observe(np.array([4.0, 4.0, 4.0]), np.array([0.6, -0.6, 0.6]))  # 1.42 K > 2 x 0.6 K
    assert trust.reason() == "prediction error above the RC's (most in b)"


def test_the_planner_narrows_each_zones_band_by_its_own_margin():
    objective = ZoneObjective(
        price_eur_per_kwh=np.full(2, 0.3), t_min_c=np.full((2, 2), 20.0), t_max_c=np.full((2, 2), 24.0),
        dt_h=0.5, comfort_weight_eur_per_kh=5.0,
    )
    narrowed = objective.tightened_zones(np.array([0.25, 3.0]))
    np.testing.assert_array_equal(narrowed.t_min_c, [[20.25, 22.0]] * 2)  # the second to its middle
    np.testing.assert_array_equal(narrowed.t_max_c, [[23.75, 22.0]] * 2)
    assert objective.tightened_zones(np.zeros(2)) is objective


# -- the fallback RC's replay ---------------------------------------------------------------------


def test_the_rc_replayed_from_the_true_state_is_the_plant_and_from_its_observer_close_to_it():
    """On the multi-zone RC plant (shoulder_office, no sensor noise) the building's exact ZOH
    from the true state of 6 intervals ago under the delivered powers is the measured rooms
    now; from the Kalman observer's estimate it is within a few hundredths of a kelvin once
    the observer has settled."""
    building, spec = _building("shoulder_office")
    exact = ZoneRCReplay(building, spec, 6)
    observed = ZoneRCReplay(building, spec, 6)
    estimator = MultiZoneKalmanEstimator(building, spec)
    loop, _ = _loop("shoulder_office", 1, 0)
    rng = np.random.default_rng(3)
    checked = 0
    for k in range(40):
        obs = loop.observation()
        state = estimator.update(obs)
        if k >= 10:
            np.testing.assert_allclose(exact.errors_k(obs.k, obs.history, 6), 0.0, atol=1e-9)
            assert np.abs(observed.errors_k(obs.k, obs.history, 6)).max() < 0.05
            checked += 1
        exact.record(obs.k, np.concatenate([obs.t_r_zones_c(), obs.t_m_true_zones_c]))
        observed.record(obs.k, state)
        loop.step(rng.uniform(0.0, 1.0, 4) * [3000.0, 1000.0, 3000.0, 1000.0])
    assert checked == 30
    assert np.isnan(exact.errors_k(loop.observation().k, loop.observation().history, 60)).all()  # none recorded


# -- the hand-over ----------------------------------------------------------------------------------


def _day(name: str, model: MultiZoneRCModel, guard: ZoneGuard | None = None) -> tuple[CEM, RunKpis]:
    scenario = get_scenario(name)
    cem = CEM(model, scenario.control_spec(), guard=ZoneGuard(hand_over=True) if guard is None else guard)
    result = run_closed_loop(scenario, cem, days=1, seed=1)
    assert not result.errors
    return cem, result.kpis


@pytest.mark.parametrize("name", ["two_zone_house", "shoulder_office"])
def test_the_true_building_as_model_makes_every_decision(name):
    building, _ = _building(name)
    cem, kpis = _day(name, _WrongModel(_planner_model(name, building), building))
    assert kpis["own_decisions_share"] == 1.0 and kpis["fallbacks"] == 0
    report = cem.trust_report
    assert report is not None and report["model_fallback"] and report["model_fallback_switches"] == 0
    assert report["model_replay_error_k"] is not None and report["model_replay_error_k"] < 1e-6


def test_a_model_with_three_times_the_air_to_mass_resistance_hands_over_to_the_qp_on_the_true_building():
    """On two_zone_house the wrong model's zones' mean replay error reaches 2.3 K against the
    true RC's 0 (1 K and twice the RC's are the limits): the QP on the true building takes
    over, and the day costs less than with the wrong model deciding throughout."""
    name = "two_zone_house"
    building, _ = _building(name)
    wrong = _WrongModel(_planner_model(name, _scaled(building, "r_rm_k_per_w", 3.0)), building)
    cem, kpis = _day(name, wrong)
    report = cem.trust_report
    assert report is not None and report["model_fallback_switches"] >= 1
    assert any(r.startswith("prediction error above the RC's (most in ") for r in report["model_fallback_reasons"])
    assert kpis["own_decisions_share"] < 0.8 and kpis["fallbacks"] == report["model_fallback_steps"]
    # watched but not handed over: the model decides throughout, and the day costs more
    _, kept = _day(name, wrong, ZoneGuard(hand_over=False))
    assert kept["own_decisions_share"] == 1.0
    assert kpis["objective"] < kept["objective"]


def test_by_default_the_guard_hands_over_beside_a_credible_rc_only():
    """The default guard (``ZoneGuard()``, hand_over None) on two_zone_house: beside the true
    building, which replays the past exactly, the wrong model (3 x the air-to-mass resistance)
    hands over early enough that the day costs at most 1 % more than with the true building as
    model (it costs 39 % more when the model keeps every decision), the reason naming the
    credible RC; beside an RC of 4 x the rooms' capacity, whose replays err past
    :data:`ZONE_CREDIBLE_RC_K`, the model decides every interval (the guard on EnergyPlus, whose
    identified RC is no better)."""
    name = "two_zone_house"
    building, _ = _building(name)
    wrong_params = _scaled(building, "r_rm_k_per_w", 3.0)
    cem, kpis = _day(name, _WrongModel(_planner_model(name, wrong_params), building), ZoneGuard())
    report = cem.trust_report
    assert report is not None and report["model_fallback"] and report["model_fallback_switches"] >= 1
    assert any(r.startswith("prediction error above a credible RC's (most in ") for r in report["model_fallback_reasons"])
    assert kpis["own_decisions_share"] < 0.5
    _, best = _day(name, _WrongModel(_planner_model(name, building), building), ZoneGuard())
    _, kept = _day(name, _WrongModel(_planner_model(name, wrong_params), building), ZoneGuard(hand_over=False))
    assert kpis["objective"] < 1.01 * best["objective"] < 1.01 * kept["objective"]
    wrong_rc = _scaled(building, "c_r_j_per_k", 4.0)
    beside_wrong, alone = _day(name, _WrongModel(_planner_model(name, wrong_params), wrong_rc), ZoneGuard())
    report = beside_wrong.trust_report
    assert report is not None and report["rc_replay_error_k"] is not None
    assert report["rc_replay_error_k"] > ZONE_CREDIBLE_RC_K
    assert alone["own_decisions_share"] == 1.0 and report["model_fallback_switches"] == 0
    assert alone["objective"] == pytest.approx(kept["objective"], rel=1e-9)  # as if never handing over


def test_the_zone_guards_settings_are_checked() -> None:
    with pytest.raises(TypeError, match="hand_over must be None, True or False"):
        ZoneGuard(hand_over="yes")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="credible_rc_k must be a positive number of kelvin"):
        ZoneGuard(credible_rc_k=0.0)
