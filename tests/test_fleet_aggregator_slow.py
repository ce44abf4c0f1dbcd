"""The aggregator's acceptance run at test scale (slow): 200 winter_household buildings (spread
0.2), each with its own learned hybrid from 14 days of its own data, one test day with a 2-hour
cap at 60 % of the uncoordinated fleet's peak in that window.

Run twice: the batched cem as it plans by default, and with ``rc_candidates`` (each building's
RC MPC plan, on the RC identified from its model's data, scored among the samples of every
plan). Each run prints its figures (``pytest -s``).

The models are trained with fast settings (2 members, 8 epochs; train's defaults, 5 members
and the architecture's epochs, take about 2-3 s of CPU a building, mostly the RC
identification, which these settings keep) on Ray with two workers, as `train --per-building`
does.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from pinn_mpc import TrainConfig
from pinn_mpc.simulator import draw_fleet
from scenarios.fleets.aggregator import cap_in_force, learned_fleet_planner, run_coordinated_fleet
from scenarios.fleets.training import building_frames, load_fleet_models, train_per_building
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.closed_loop import one_torch_thread
from scenarios.running.datagen import generate

pytestmark = pytest.mark.slow

N_BUILDINGS = 200
COLD_SEED = 13  # winter_household's test day 2023-02-12: heating all day
WINDOW = "17:00-19:00"


@pytest.fixture(scope="module")
def fleet_models(tmp_path_factory):
    scenario = get_scenario("winter_household")
    fleet = draw_fleet(scenario.sim.params, N_BUILDINGS, spread=0.2, rng=np.random.default_rng(19))
    data = generate(scenario, days=14, seed=0, policy="random-level", n_buildings=N_BUILDINGS, fleet=fleet)
    root = tmp_path_factory.mktemp("fleet_models")
    config = TrainConfig(n_seeds=2, epochs=8, eta=scenario.sim.params.eta, u_max_w=scenario.sim.u_max_w)
    train_per_building(building_frames(data), root, arch="hybrid", config=config, params=fleet, workers=2)
    models, params = load_fleet_models(root)
    assert params is not None and len(models) == N_BUILDINGS
    return scenario, models, params


@pytest.fixture(scope="module", params=[False, True], ids=["cem", "cem-rc-candidates"])
def fleet_runs(request, fleet_models):
    scenario, models, params = fleet_models
    with one_torch_thread():
        free = run_coordinated_fleet(
            scenario, learned_fleet_planner(models, rc_candidates=request.param), n_buildings=N_BUILDINGS,
            days=1, seed=COLD_SEED, fleet=params,
        )
        in_window = ~np.isnan(cap_in_force(free.times, {"kw": 1.0, "window": WINDOW}))
        cap_kw = 0.6 * free.aggregate_u_phys_w[in_window].max() / 1000.0
        capped = run_coordinated_fleet(
            scenario, learned_fleet_planner(models, rc_candidates=request.param), n_buildings=N_BUILDINGS,
            days=1, seed=COLD_SEED, fleet=params, cap_kw=cap_kw, cap_window=WINDOW,
        )
    print(
        f"\n{N_BUILDINGS} learned buildings ({'cem, rc candidates' if request.param else 'cem'}), cap {cap_kw:.1f} kW "
        f"{WINDOW}: discomfort per building {_discomfort_per_building(free):.3f} -> "
        f"{_discomfort_per_building(capped):.3f} K h; intervals over {capped.cap['intervals_over']} of "
        f"{capped.cap['intervals']}; window {np.round(capped.aggregate_u_phys_w[in_window] / 1000, 1)} kW; "
        f"energy {free.totals['energy_kwh']:.0f} -> {capped.totals['energy_kwh']:.0f} kWh; step "
        f"{free.step_time['controllers_ms_median']:.0f} / {capped.step_time['controllers_ms_median']:.0f} ms "
        f"median (load {os.getloadavg()[0]:.1f})"
    )
    return free, capped, cap_kw, in_window, request.param


def _discomfort_per_building(result) -> float:
    return float(np.mean([k["discomfort_kh"] for k in result.kpis]))


def test_200_learned_buildings_hold_a_cap_at_60_percent_of_their_window_peak(fleet_runs):
    free, capped, cap_kw, in_window, _ = fleet_runs
    assert free.info["batched"] and free.totals["fallbacks"] == 0
    assert capped.cap is not None and capped.cap["intervals"] == 4
    assert capped.cap["intervals_over"] == 0, capped.cap
    assert np.all(capped.aggregate_u_phys_w[in_window] <= cap_kw * 1000.0 + 1.0)
    # The cap binds: uncoordinated, the fleet would have been well over it.
    assert free.aggregate_u_phys_w[in_window].max() > 1.5 * cap_kw * 1000.0


def test_the_cap_costs_at_most_0_2_kelvin_hours_per_building(fleet_runs):
    free, capped, _, _, rc_candidates = fleet_runs
    extra = _discomfort_per_building(capped) - _discomfort_per_building(free)
    if not rc_candidates:
        # A strict expected failure: the cem's own samples miss the bound (CHANGELOG).
        assert extra > 0.2, f"+{extra:.3f} K h per building: reached, drop this expected failure"
        pytest.xfail(f"+{extra:.3f} K h per building with the cem's own samples (over 0.2)")
    assert extra <= 0.2
