"""One contract for every controller of the CLI, run on the closed-loop engine: actions within
the actuator's bounds (a heater's and a cooling machine's), the same decisions from the same
seed, and ``reset`` forgets the past; and every controller keeps an actuator's lower bound
when it is above zero."""

import numpy as np
import pytest

from controllers.arx_mpc import ARXQPMPC
from controllers.base import Controller, ControlSpec
from controllers.rc_mpc.casadi import CasadiMPC
from controllers.rc_mpc.osqp import QPMPC
from controllers.rc_mpc.references import clairvoyant_mpc, oracle_mpc
from controllers.sampling import CEM, RandomShooting
from controllers.thermostat import Thermostat
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.models.arx import fit_arx
from pinn_mpc.models.rc import RCBatchModel
from scenarios.inputs.registry import Scenario
from scenarios.inputs.scenario_file import get_scenario
from scenarios.inputs.series import ExogenousSeries
from scenarios.running.datagen import generate
from scenarios.running.engine import ClosedLoop
from scenarios.running.factory import (
    CONTROLLER_NAMES,
    MODEL_CONTROLLERS,
    RC_CONTROLLERS,
    build_controller,
)

N_STEPS = 6
SCENARIOS = {name: get_scenario(name) for name in ("paper_household", "cold_storage")}


def _make(name: str, scenario: Scenario) -> Controller:
    spec = scenario.control_spec()
    kwargs: dict = {}
    if name in MODEL_CONTROLLERS:
        model = RCBatchModel(scenario.sim.params, dt_s=spec.dt_s, actuator=spec.actuator)
        kwargs = {"model": model, "planner_options": {"n_samples": 32}}
    if name in RC_CONTROLLERS:
        kwargs = {"rc_params": scenario.sim.params}
    return build_controller(name, scenario, n_steps=N_STEPS, **kwargs)


def _run(
    controller: Controller, seed: int, scenario: Scenario, spec: ControlSpec | None = None,
    n_steps: int = N_STEPS,
) -> tuple[np.ndarray, list[np.ndarray | None]]:
    frame = scenario.exogenous(days=1, seed=0, part="test", lead_steps=scenario.horizon_steps)
    loop = ClosedLoop(
        scenario.sim,
        ExogenousSeries.from_frame(frame),
        spec=scenario.control_spec() if spec is None else spec,
        initial_t_r_c=scenario.initial_t_r_c,
        initial_t_m_c=scenario.initial_t_m_c,
    )
    controller.reset(seed)
    plans = []
    for _ in range(n_steps):
        decision = loop.advance(controller)
        assert decision.error is None
        plans.append(controller.last_plan)
    return loop.record().u_w, plans


def _within(values: np.ndarray, actuator: ActuatorSpec) -> bool:
    return bool(np.all((values >= actuator.lower_w) & (values <= actuator.upper_w)))


@pytest.mark.parametrize("scenario_name", list(SCENARIOS))
@pytest.mark.parametrize("name", CONTROLLER_NAMES)
def test_bounds_determinism_and_reset(name, scenario_name):
    scenario = SCENARIOS[scenario_name]
    controller = _make(name, scenario)
    assert isinstance(controller, Controller) and controller.name == name
    actuator = scenario.control_spec().actuator
    assert actuator.heats == (scenario_name == "paper_household")
    actions, plans = _run(controller, 3, scenario)
    assert _within(actions, actuator)
    for plan in plans:
        if plan is not None:
            assert _within(plan, actuator)
    assert any(plan is not None for plan in plans)
    assert controller.last_stats.time_s >= 0
    again, _ = _run(controller, 3, scenario)  # reset forgets the warm start, estimator, counters
    np.testing.assert_array_equal(again, actions)
    fresh, _ = _run(_make(name, scenario), 3, scenario)  # a fresh controller with the same seed
    np.testing.assert_array_equal(fresh, actions)


#: A heater that runs between 1.5 and 5 kW: a floor above zero that only a controller asking
#: its actuator for the bounds keeps.
FLOOR = ActuatorSpec(lower_w=1500.0, upper_w=5000.0)


def _floored(kind: str, spec: ControlSpec) -> Controller:
    scenario = SCENARIOS["paper_household"]
    params = scenario.sim.params
    if kind == "thermostat":
        return Thermostat(spec)
    if kind == "qp-mpc":
        return QPMPC(params, spec)
    if kind == "casadi-mpc":
        return CasadiMPC(params, spec)
    if kind == "oracle":
        return oracle_mpc(params, spec)
    if kind == "clairvoyant":
        return clairvoyant_mpc(params, spec, N_STEPS)
    if kind == "qp-mpc over an ARX":
        data = generate(scenario, days=7, seed=0, policy="random-level")
        return ARXQPMPC(fit_arx(data), spec)
    model = RCBatchModel(params, dt_s=spec.dt_s, actuator=spec.actuator)
    if kind == "cem":
        return CEM(model, spec, n_samples=32)
    if kind == "random-shooting":  # in setpoint space
        return RandomShooting(model, spec, n_samples=32)
    return RandomShooting(model, spec, n_samples=32, space="power")


@pytest.mark.parametrize(
    "kind",
    ["thermostat", "qp-mpc", "casadi-mpc", "oracle", "clairvoyant", "qp-mpc over an ARX", "cem",
     "random-shooting", "random-shooting in power space"],
)
def test_every_controller_keeps_a_lower_bound_above_zero(kind):
    """Each controller plans within [1.5, 5] kW and the controllers that would stay off (the
    room is warm at first) sit at the floor: a bound written out as 0 anywhere shows here."""
    scenario = SCENARIOS["paper_household"]
    spec = ControlSpec(
        actuators=(FLOOR,), dt_s=scenario.sim.dt_s, horizon_steps=scenario.horizon_steps,
        comfort_weight_eur_per_kh=scenario.comfort_weight_eur_per_kh,
    )
    controller = _floored(kind, spec)
    _, plans = _run(controller, 3, scenario, spec, n_steps=12)  # the ARX's 8 lags first
    planned = np.concatenate([plan for plan in plans if plan is not None])
    assert len(planned) > 0 and _within(planned, FLOOR)
    assert planned.min() == pytest.approx(FLOOR.lower_w)
