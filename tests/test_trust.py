"""Learned-model control that knows when its model is wrong: the trust monitor, the RC
fallback a trained model carries, the COP curve, and the model-vs-scenario checks."""

from __future__ import annotations

import copy
import dataclasses
import json
import math
from typing import Any

import numpy as np
import pytest
import torch

from controllers.sampling import CEM
from controllers.trust import TrustMonitor, TrustSettings
from pinn_mpc.actuator import Actuator, CopCurve
from pinn_mpc.errors import InputError
from pinn_mpc.identify import identify_rc
from pinn_mpc.training import TrainConfig, data_warnings, train_model
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.datagen import generate
from scenarios.running.factory import build_controller, check_model_fits, model_guard

HP = Actuator(kind="heat_pump")


def test_monitor_switches_after_a_large_error_and_recovers_after_calm_steps() -> None:
    settings = TrustSettings(
        error_floor_k=0.2, error_ratio=1.5, filter_gain=1.0, recover_steps=3, recover_ratio=1.0
    )
    m = TrustMonitor(settings, u_range_w=5000.0)
    m.observe(0.05, 100.0, 0.1, 0.05)
    assert m.reason(0.1) is None and m.decide(None)
    m.observe(0.0, 0.0, 0.5, 0.4)  # past the floor, but the RC errs about as much
    assert m.reason(0.1) is None
    m.observe(0.0, 0.0, 0.5, 0.1)  # past the floor and 1.5 x the RC's error
    assert m.reason(0.1) == "prediction error above the RC's"
    assert not m.decide(m.reason(0.1))
    m.observe(0.0, 0.0, 0.0, 0.0)
    verdicts = [m.decide(m.reason(0.1)) for _ in range(3)]
    assert verdicts == [False, False, True]  # back after recover_steps calm decisions
    s = m.state
    assert (s.switches, s.fallback_steps) == (1, 3)
    m.observe(0.0, 2000.0)  # 40 % of the range: the delivered power is mispredicted
    assert m.reason(0.1) == "delivered power error"
    m.observe(0.0, 0.0)
    assert m.reason(0.8) == "ensemble disagreement"
    assert m.reason(float("nan")) == "ensemble disagreement"


@pytest.mark.parametrize("below_rc", [True, False])
def test_a_model_whose_replay_error_falls_below_the_rcs_drives_again_at_once_where_asked(below_rc: bool) -> None:
    """With ``recover_below_rc`` the first calm decision where the model replays better than
    the RC hands back to the model; a calm decision where it still replays worse does not,
    and without the setting the recovery waits its ``recover_steps``."""
    settings = TrustSettings(filter_gain=1.0, recover_steps=4, recover_below_rc=below_rc)
    m = TrustMonitor(settings, u_range_w=1.0)
    m.observe(0.0, 0.0, 1.2, 0.3)  # 4 x the RC's error: distrusted
    assert not m.decide(m.reason())
    m.observe(0.0, 0.0, 0.5, 0.3)  # within the limits (below 2 x), but worse than the RC
    assert m.reason() is None and not m.decide(None)
    m.observe(0.0, 0.0, 0.2, 0.3)  # better than the RC
    assert m.decide(m.reason()) is below_rc
    verdicts = [m.decide(None) for _ in range(2)]
    assert verdicts == ([True, True] if below_rc else [False, True])  # 4 calm decisions
    assert m.state.fallback_steps == (2 if below_rc else 4)


def test_with_a_larger_recover_ratio_a_model_within_that_ratio_of_the_rcs_error_drives_again() -> None:
    """``recover_ratio`` 1.5: a calm decision where the model replays 0.4 K against the RC's 0.3
    (1.33 x) hands back; with ratio 1 it does not."""
    for ratio, back in ((1.5, True), (1.0, False)):
        m = TrustMonitor(TrustSettings(filter_gain=1.0, recover_steps=4, recover_ratio=ratio), u_range_w=1.0)
        m.observe(0.0, 0.0, 1.2, 0.3)
        assert not m.decide(m.reason())
        m.observe(0.0, 0.0, 0.4, 0.3)
        assert m.reason() is None and m.decide(None) is back


def test_monitor_narrows_the_band_by_its_filtered_error_within_limits() -> None:
    m = TrustMonitor(TrustSettings(filter_gain=1.0, max_margin_k=0.2), u_range_w=1.0)
    assert m.margin_k(0.01) == 0.01
    m.observe(0.05, float("nan"))
    assert m.margin_k(0.01) == pytest.approx(0.05)
    m.observe(3.0, float("nan"))
    assert m.margin_k(0.01) == 0.2


def test_monitor_narrows_the_band_by_its_replay_error_where_asked_and_larger() -> None:
    """A model right one step ahead but 0.15 K off over the replayed hours plans 0.15 K inside
    with ``margin_from_replay``, 0.02 K without."""
    for from_replay, expected in ((True, 0.15), (False, 0.02)):
        m = TrustMonitor(TrustSettings(filter_gain=1.0, margin_from_replay=from_replay), u_range_w=1.0)
        m.observe(0.02, float("nan"), replay_k=0.15)
        assert m.margin_k(0.01) == pytest.approx(expected)
        m.observe(0.3, float("nan"), replay_k=0.15)
        assert m.margin_k(0.01) == pytest.approx(0.3)


def test_the_fallback_plans_inside_the_band_by_the_rcs_replay_error_where_asked() -> None:
    """With ``margin_from_replay`` the fallback RC MPC's margin is the RC's filtered replay
    error (0 before the RC is replayed, at most ``max_margin_k``); without it, 0."""
    for from_replay in (True, False):
        m = TrustMonitor(TrustSettings(filter_gain=1.0, margin_from_replay=from_replay), u_range_w=1.0)
        assert m.fallback_margin_k() == 0.0
        m.observe(0.02, float("nan"), replay_k=0.4, replay_rc_k=-0.15)
        assert m.fallback_margin_k() == pytest.approx(0.15 if from_replay else 0.0)
        m.observe(0.02, float("nan"), replay_k=0.4, replay_rc_k=0.9)
        assert m.fallback_margin_k() == pytest.approx(0.5 if from_replay else 0.0)


@pytest.mark.parametrize(
    "bad",
    [
        {"error_floor_k": 0.0}, {"filter_gain": 1.5}, {"recover_steps": 0}, {"replay_steps": 0},
        {"recover_ratio": 2.0}, {"recover_ratio": 0.0},
    ],
)
def test_trust_settings_are_checked(bad: dict) -> None:
    with pytest.raises(ValueError, match=next(iter(bad))):
        TrustSettings(**bad)


def test_cop_curve_fit_recovers_the_actuator_within_the_data_and_holds_outside() -> None:
    t_a = np.linspace(-10.0, 12.0, 500)
    curve = CopCurve.fit(t_a, HP.gain(t_a))
    assert curve is not None
    inside = np.linspace(-9.0, 11.0, 41)
    np.testing.assert_allclose(curve(inside), HP.gain(inside), rtol=0.02)
    assert curve(30.0) == pytest.approx(float(curve(12.0)))  # constant past the data
    assert CopCurve.fit(t_a, np.ones_like(t_a)) is None  # a resistance heater has no curve
    assert CopCurve.from_dict(json.loads(json.dumps(curve.to_dict()))) == curve


def test_identify_on_heat_pump_data_recovers_the_building() -> None:
    """With the data's cop column, identification works on the delivered heat: the building's
    R and C, not the electrical gain's mix of both."""
    scenario = get_scenario("heat_pump_household")
    data = generate(scenario, days=20, seed=3, policy="random-level")
    assert "cop" in data.columns and data["cop"].min() > 1.5
    truth = scenario.sim.params
    got = identify_rc(data, eta=truth.eta).params
    for name in ("r_ra_k_per_w", "c_r_j_per_k", "c_m_j_per_k"):
        assert getattr(got, name) == pytest.approx(getattr(truth, name), rel=0.1), name
    without = identify_rc(data.drop(columns="cop"), eta=truth.eta).params
    assert abs(without.c_r_j_per_k / truth.c_r_j_per_k - 1) > 0.5  # electrical power only


@pytest.fixture(scope="module")
def winter_model():
    scenario = get_scenario("winter_household")
    data = generate(scenario, days=14, seed=2, policy="random-level")
    config = TrainConfig(n_seeds=3, epochs=20, depth=8, u_max_w=scenario.sim.u_max_w)
    return scenario, train_model(data, arch="hybrid", config=config, progress=False)


def test_a_trained_model_carries_its_identified_rc_and_ranges(winter_model) -> None:
    scenario, model = winter_model
    guard = model_guard(model)
    assert guard.rc is not None
    assert guard.rc.c_m_j_per_k == pytest.approx(scenario.sim.params.c_m_j_per_k, rel=0.2)
    lo, hi = guard.training_ranges["T_a"]
    assert lo < hi
    assert model.meta["identified_rc"]["fit"]["rmse_c"] < 0.2


def test_a_model_that_mispredicts_is_replaced_by_the_rc_mpc_and_counted(winter_model) -> None:
    """Sabotage the trained hybrid (its heater gain at a third): the planner over it would
    overheat less but freeze; the monitor sees the delivered-power and room errors, hands the
    decisions to the QP MPC on the RC identified from the same data, and the run ends within a
    few per cent of that MPC alone."""
    scenario, model = winter_model
    broken = train_model(
        generate(scenario, days=14, seed=2, policy="random-level"),
        arch="hybrid",
        config=TrainConfig(n_seeds=3, epochs=20, depth=8, u_max_w=scenario.sim.u_max_w),
        progress=False,
    )
    block = broken.module.physics
    assert block is not None
    with torch.no_grad():
        block.log_b.add_(math.log(1 / 3))
    n = scenario.steps_per_day
    kpis = {}
    runs: dict[str, dict[str, Any]] = {
        "cem": {"model": broken},
        "cem, no fallback": {
            "model": broken,
            "planner_options": {"guard": model_guard(broken)._replace(rc=None)},
        },
        "qp-mpc": {"rc_params": model_guard(model).rc},
    }
    for label, kwargs in runs.items():
        name = label.split(",")[0]
        controller = build_controller(name, scenario, n_steps=n, **kwargs)
        kpis[label] = run_closed_loop(scenario, controller, days=1, seed=5).kpis
    assert kpis["cem"]["model_fallback_switches"] >= 1
    assert kpis["cem"]["model_fallback_steps"] > 0
    assert kpis["cem, no fallback"]["model_fallback_steps"] == 0
    assert kpis["cem"]["objective"] <= 1.05 * kpis["qp-mpc"]["objective"]
    assert kpis["cem"]["objective"] < kpis["cem, no fallback"]["objective"]


def test_the_fallback_plans_inside_the_band_only_while_colder_than_its_data_where_asked() -> None:
    """With ``fallback_margin_when_colder`` the fallback's margin is the RC's filtered replay
    error while the forecast is colder than the data, 0 otherwise; the model's own margin is
    unchanged (one step ahead)."""
    m = TrustMonitor(TrustSettings(filter_gain=1.0, fallback_margin_when_colder=True), u_range_w=1.0)
    assert m.fallback_margin_k(colder=True) == 0.0  # not replayed yet
    m.observe(0.02, float("nan"), replay_k=0.4, replay_rc_k=-0.3)
    assert m.fallback_margin_k(colder=True) == pytest.approx(0.3)
    assert m.fallback_margin_k(colder=False) == 0.0
    assert m.margin_k(0.01) == pytest.approx(0.02)
    plain = TrustMonitor(TrustSettings(filter_gain=1.0), u_range_w=1.0)
    plain.observe(0.02, float("nan"), replay_k=0.4, replay_rc_k=-0.3)
    assert plain.fallback_margin_k(colder=True) == 0.0


def test_a_guarded_planner_calls_a_forecast_colder_than_its_training_data_colder(winter_model) -> None:
    """The planner compares the forecast's outdoor temperature over its horizon with the
    lowest of its training data; unknown ranges are never colder."""
    from controllers.base import Forecast

    scenario, model = winter_model
    controller = build_controller("cem", scenario, model=model, n_steps=scenario.steps_per_day)
    assert isinstance(controller, CEM)
    lo = controller.training_ranges["T_a"][0]
    h = controller.spec.horizon_steps

    def forecast(t_a: np.ndarray) -> Forecast:
        zeros = np.zeros(len(t_a))
        return Forecast(
            time_of_day_h=zeros, T_a=t_a, G=zeros, I_g=zeros, price=zeros + 0.2, T_min=zeros + 20, T_max=zeros + 24
        )
    warm = np.full(h + 10, lo + 1.0)
    assert not controller._colder(forecast(warm))
    cold_late = warm.copy()
    cold_late[h - 1] = lo - 0.5
    assert controller._colder(forecast(cold_late))
    beyond = warm.copy()
    beyond[h] = lo - 5.0  # past the horizon: not planned over
    assert not controller._colder(forecast(beyond))
    controller.training_ranges = {}
    assert not controller._colder(forecast(cold_late))


def test_a_guarded_planner_sets_its_fallbacks_margin_only_where_asked(winter_model) -> None:
    """cem's shadow RC MPC plans with the monitor's fallback margin: positive after a day with
    ``margin_from_replay`` (the RC errs a little on the winter household), 0 without."""
    scenario, model = winter_model
    margins = {}
    for from_replay in (True, False):
        guard = model_guard(model)._replace(settings=TrustSettings(margin_from_replay=from_replay))
        controller = build_controller(
            "cem", scenario, model=model, n_steps=scenario.steps_per_day, planner_options={"guard": guard}
        )
        assert isinstance(controller, CEM) and controller.shadow is not None
        run_closed_loop(scenario, controller, days=1, seed=5)
        margins[from_replay] = controller.shadow.comfort_margin_k
        assert margins[from_replay] == pytest.approx(controller.monitor.fallback_margin_k(), abs=0.05)
    assert margins[True] > 0.0 and margins[False] == 0.0


def test_a_good_model_keeps_control(winter_model) -> None:
    scenario, model = winter_model
    controller = build_controller("cem", scenario, model=model, n_steps=scenario.steps_per_day)
    kpis = run_closed_loop(scenario, controller, days=1, seed=5).kpis
    assert kpis["model_fallback_steps"] == 0 and kpis["model_fallback_switches"] == 0


def test_models_are_checked_against_the_scenario(winter_model) -> None:
    scenario, model = winter_model
    assert check_model_fits(model, scenario) == []
    with pytest.raises(InputError, match="powers up to"):
        check_model_fits(model, get_scenario("paper_household"))  # 10 kW data, a 5 kW heater
    record = dataclasses.replace(
        model.record, training_data={**model.record.training_data, "columns": ["cop"]}
    )
    heat_pump_model = copy.copy(model)
    heat_pump_model.record = record
    with pytest.raises(InputError, match="heat-pump data"):
        check_model_fits(heat_pump_model, scenario)


def test_train_warns_about_data_that_cannot_teach_the_model() -> None:
    data = generate(get_scenario("winter_household"), days=5, seed=1, policy="random-level")
    notes = data_warnings(data)
    assert any("5.0 days" in n for n in notes)
    # A day's last step short of 14 days says 13.9, not 14.0 (< 14).
    almost = generate(get_scenario("winter_household"), days=14, seed=1, policy="random-level").iloc[:-1]
    assert any("cover 13.9 days (< 14)" in n for n in data_warnings(almost))
    narrow = data.assign(T_a=5.0 + 0.1 * np.sin(np.arange(len(data))))
    assert any("T_a spans only" in n for n in data_warnings(narrow))
    low = data.assign(u_phys=np.where(np.arange(len(data)) == 3, 9000.0, 1000.0))
    assert any("largest power" in n for n in data_warnings(low))
