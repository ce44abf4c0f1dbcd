"""One contract for every controller of the CLI, run on the closed-loop engine: actions within
bounds, the same decisions from the same seed, and ``reset`` forgets the past."""

import numpy as np
import pytest

from controllers.base import Controller
from pinn_mpc.models.rc import RCBatchModel
from scenarios.inputs.scenario_file import get_scenario
from scenarios.inputs.series import ExogenousSeries
from scenarios.running.engine import ClosedLoop
from scenarios.running.factory import (
    CONTROLLER_NAMES,
    MODEL_CONTROLLERS,
    RC_CONTROLLERS,
    build_controller,
)

N_STEPS = 6
SCENARIO = get_scenario("paper_household")


def _make(name: str) -> Controller:
    spec = SCENARIO.control_spec()
    kwargs: dict = {}
    if name in MODEL_CONTROLLERS:
        model = RCBatchModel(SCENARIO.sim.params, dt_s=spec.dt_s, u_max_w=spec.u_max_w)
        kwargs = {"model": model, "planner_options": {"n_samples": 32}}
    if name in RC_CONTROLLERS:
        kwargs = {"rc_params": SCENARIO.sim.params}
    return build_controller(name, SCENARIO, n_steps=N_STEPS, **kwargs)


def _run(controller: Controller, seed: int) -> tuple[np.ndarray, list[np.ndarray | None]]:
    frame = SCENARIO.exogenous(days=1, seed=0, part="test", lead_steps=SCENARIO.horizon_steps)
    loop = ClosedLoop(
        SCENARIO.sim,
        ExogenousSeries.from_frame(frame),
        spec=SCENARIO.control_spec(),
        initial_t_r_c=SCENARIO.initial_t_r_c,
        initial_t_m_c=SCENARIO.initial_t_m_c,
    )
    controller.reset(seed)
    plans = []
    for _ in range(N_STEPS):
        decision = loop.advance(controller)
        assert decision.error is None
        plans.append(controller.last_plan)
    return loop.record().u_w, plans


@pytest.mark.parametrize("name", CONTROLLER_NAMES)
def test_bounds_determinism_and_reset(name):
    controller = _make(name)
    assert isinstance(controller, Controller) and controller.name == name
    u_max = SCENARIO.sim.u_max_w
    actions, plans = _run(controller, seed=3)
    assert np.all((actions >= 0.0) & (actions <= u_max))
    for plan in plans:
        if plan is not None:
            assert np.all((plan >= 0.0) & (plan <= u_max))
    assert any(plan is not None for plan in plans)
    assert controller.last_stats.time_s >= 0
    again, _ = _run(controller, seed=3)  # reset forgets the warm start, estimator, counters
    np.testing.assert_array_equal(again, actions)
    fresh, _ = _run(_make(name), seed=3)  # a fresh controller with the same seed
    np.testing.assert_array_equal(fresh, actions)
