"""``compare`` on a building of several zones (:mod:`scenarios.experiments.compare_zones`): its
RC table, its prediction errors and its refusals; the command end to end runs as the zones page
writes it (tests/test_docs.py, ``docs/zones.md#compare``)."""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.experiments.compare_zones import zone_prediction_errors, zone_rc_summary
from scenarios.inputs.scenario_file import get_scenario
from scenarios.reports.report import zone_kpi_table_markdown, zone_rc_table_markdown


def test_the_rc_summary_of_the_two_zone_house_is_its_scenario_s_building() -> None:
    """Each zone's R and C and the wall as the scenario's description gives them (40 W/K)."""
    building = get_scenario("two_zone_house").plant.settings.building  # type: ignore[attr-defined]
    summary = zone_rc_summary(building, source="truth")
    assert summary["walls"] == {"south-north": pytest.approx(40.0)}
    assert set(summary["zones"]) == {"south", "north"}
    for zone in building.zones:
        assert summary["zones"][zone.zone.name]["r_ra_k_per_w"] == zone.rc.r_ra_k_per_w
        assert summary["zones"][zone.zone.name]["c_m_j_per_k"] == zone.rc.c_m_j_per_k


def test_the_rc_table_gives_a_wall_a_source_does_not_have_as_zero() -> None:
    """A learned RC whose wall vanished (not in its ``walls``) shows 0 W/K; values scaled to
    mK/W and MJ/K."""
    values = {"r_ra_k_per_w": 7.5e-3, "r_rm_k_per_w": 1.5e-3, "c_r_j_per_k": 2e6, "c_m_j_per_k": 3e7}
    table = "\n".join(zone_rc_table_markdown({
        "true": {"zones": {"a": values}, "walls": {"a-b": 40.0}},
        "learned": {"zones": {"a": values}, "walls": {}},
    }))
    assert "| wall a-b U [W/K] | 40 | 0 |" in table
    assert "| a R_ra [mK/W] | 7.5 | 7.5 |" in table and "| a C_m [MJ/K] | 30 | 30 |" in table


def test_the_zone_kpi_table_gives_each_zone_too_cold_too_warm_and_energy() -> None:
    row = {"controller": "cem", "zones": {
        "south": {"discomfort_kh": 1.5, "discomfort_too_cold_kh": 1.0, "discomfort_too_warm_kh": 0.5, "energy_kwh": 12.0},
    }}
    assert "| `cem` | 1.00 / 0.50, 12.0 kWh |" in "\n".join(zone_kpi_table_markdown([row]))


class _Persistence:
    """A model of two zones that predicts each room stays as it was at the start."""

    first_path_start = 2
    zones = get_scenario("two_zone_house").control_spec().zones

    def predict_paths(self, frame, starts, horizon):  # noqa: ANN001, ANN201
        rooms = frame[["T_r[south]", "T_r[north]"]].to_numpy(dtype=float)
        return np.repeat(rooms[starts][:, None, :], horizon, axis=1)


def test_prediction_errors_per_zone_against_a_ramp() -> None:
    """Rooms that warm 0.1 and 0.2 K per interval: persistence errs h x 0.1 and h x 0.2 K h
    steps ahead (bias negative); each zone's figure its own; a frame too short for any horizon
    gives no rows."""
    import pandas as pd

    k = np.arange(120, dtype=float)
    frame = pd.DataFrame({"T_r[south]": 20 + 0.1 * k, "T_r[north]": 18 + 0.2 * k})
    [row] = zone_prediction_errors(frame, {"persistence": _Persistence()})  # type: ignore[dict-item]
    assert row["T_r_mae_by_horizon_c"] == {str(h): pytest.approx(0.15 * h) for h in (1, 6, 24, 48)}
    assert row["T_r_mae_c"] == pytest.approx(0.15 * 24) and row["T_r_bias_c"] == pytest.approx(-0.15 * 24)
    assert row["T_r_mae_by_zone_c"] == {"south": pytest.approx(2.4), "north": pytest.approx(4.8)}
    assert row["n_starts"] == 120 - 1 - 48 - 2
    assert zone_prediction_errors(frame.iloc[:3], {"persistence": _Persistence()}) == []  # type: ignore[dict-item]


def test_a_planner_whose_model_replays_past_the_guard_s_limits_is_said_to_have_decided() -> None:
    """The zones' guard hands nothing over by default: a row whose model replayed worse than
    the floor (1 K) and twice the RC's gets a note; one within either limit, or a row whose
    fallback acted, none."""
    from scenarios.experiments.compare_zones import _distrusted_note

    row = {"controller": "cem / physreg", "model_fallback": False, "rc_replay_error_k": 0.02}
    assert "2.08 K off" in _distrusted_note({**row, "model_replay_error_k": 2.08})
    assert "hand_over=False" in _distrusted_note({**row, "model_replay_error_k": 2.08})
    assert _distrusted_note({**row, "model_replay_error_k": 0.9}) == ""  # under the floor
    assert _distrusted_note({**row, "model_replay_error_k": 1.5, "rc_replay_error_k": 0.8}) == ""
    # by default: the RC was not credible (on EnergyPlus), or the guard handed over
    beside = {**row, "model_fallback": True, "model_replay_error_k": 2.5, "rc_replay_error_k": 1.2}
    assert "only beside an RC that replays the past within 0.2 K" in _distrusted_note(beside)
    assert _distrusted_note({**beside, "model_fallback_steps": 12}) == ""
    assert _distrusted_note({"controller": "thermostat", "model_fallback": None}) == ""
