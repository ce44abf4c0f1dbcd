"""Figures of closed-loop runs: the comparison's small multiples and the one-run figure, checked
on the matplotlib Figure (which axes, what they show), on real closed-loop trajectories."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection

from pinn_mpc.models.rc import RCBatchModel
from scenarios.inputs.scenario_file import get_scenario
from scenarios.reports.plots import (
    FAMILIES,
    comparison_figure,
    group_by_family,
    plot_comparison,
    trajectory_figure,
)
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.factory import CONTROLLER_NAMES, build_controller


def _runs(scenario_name: str) -> dict[str, pd.DataFrame]:
    """One day of thermostat, random shooting over the exact 2R2C, qp-mpc on the true
    parameters, oracle and clairvoyant: one controller of every family."""
    scenario = get_scenario(scenario_name)
    sim = scenario.sim
    exact = RCBatchModel(
        sim.params, dt_s=sim.dt_s, actuator=sim.actuators[0],
        backup_low_c=sim.backup_low_c, backup_high_c=sim.backup_high_c,
    )
    plan: dict[str, tuple[str, dict[str, Any]]] = {
        "thermostat": ("thermostat", {}),
        "random-shooting / exact RC": (
            "random-shooting", {"model": exact, "planner_options": {"n_samples": 16}}
        ),
        "qp-mpc / true RC": ("qp-mpc", {"rc_params": sim.params}),
        "oracle": ("oracle", {}),
        "clairvoyant": ("clairvoyant", {}),
    }
    out = {}
    for label, (name, kwargs) in plan.items():
        controller = build_controller(name, scenario, n_steps=scenario.steps_per_day, **kwargs)
        result = run_closed_loop(scenario, controller, days=1, seed=3, label=label)
        out[label] = result.trajectory
    return out


@pytest.fixture(scope="module", params=["winter_household", "cold_storage"])
def runs(request: pytest.FixtureRequest) -> dict[str, pd.DataFrame]:
    return _runs(request.param)


def _band_extent(ax: Axes) -> tuple[float, float] | None:
    """(lowest, highest) y of the shaded band on ``ax``, None if there is none."""
    bands = [c for c in ax.collections if isinstance(c, PolyCollection)]
    if not bands:
        return None
    y = np.concatenate([np.asarray(p.vertices)[:, 1] for c in bands for p in c.get_paths()])
    return float(y.min()), float(y.max())


def _family_axes(fig) -> dict[str, Axes]:
    return {ax.get_title(loc="left"): ax for ax in fig.axes if ax.get_title(loc="left")}


def test_one_temperature_panel_per_family_with_the_band(runs: dict[str, pd.DataFrame]) -> None:
    fig = comparison_figure(runs, title="test")
    panels = _family_axes(fig)
    assert list(panels) == [title for title, _ in FAMILIES]
    traj = runs["oracle"]
    for ax in panels.values():
        assert _band_extent(ax) == pytest.approx(
            (traj["T_min"].min(), traj["T_max"].max()), abs=1e-9
        )
    # Below each temperature panel its power panel, then the price: 2 per family + 1.
    assert len(fig.axes) == 2 * len(FAMILIES) + 1


def test_every_panel_is_drawn_against_the_oracle(runs: dict[str, pd.DataFrame]) -> None:
    fig = comparison_figure(runs)
    groups = group_by_family(list(runs))
    for family, ax in _family_axes(fig).items():
        labels = [line.get_label() for line in ax.get_lines()]
        others = [label for label in groups[family] if label != "oracle"]
        assert labels == ["oracle (reference)", *others]
        for line in ax.get_lines():  # every T_r as it was simulated
            source = runs["oracle" if line.get_label() == "oracle (reference)" else str(line.get_label())]
            np.testing.assert_array_equal(np.asarray(line.get_ydata(), dtype=float), source["T_r"])


def test_panels_share_their_scales_and_show_all_data(runs: dict[str, pd.DataFrame]) -> None:
    fig = comparison_figure(runs)
    temp = list(_family_axes(fig).values())
    lo, hi = temp[0].get_ylim()
    for ax in temp:
        assert ax.get_ylim() == (lo, hi)
        assert temp[0].get_shared_x_axes().joined(temp[0], ax)
    t_r = np.concatenate([t["T_r"].to_numpy() for t in runs.values()])
    assert lo <= t_r.min() and t_r.max() <= hi


def test_unknown_controller_gets_its_own_panel_and_every_known_one_a_family() -> None:
    groups = group_by_family(["oracle", "my-controller / v2", "cem / mlp", "thermostat"])
    assert groups == {
        "thermostat": ["thermostat"],
        "sampling planners over learned models": ["cem / mlp"],
        "references: true parameters and state": ["oracle"],
        "my-controller": ["my-controller / v2"],
    }
    assert sorted(n for _, names in FAMILIES for n in names) == sorted(CONTROLLER_NAMES)


def test_one_run_figure_uses_the_same_band_and_power(runs: dict[str, pd.DataFrame]) -> None:
    traj = runs["qp-mpc / true RC"]
    fig = trajectory_figure(traj, title="qp-mpc")
    ax_t, ax_u, ax_p = fig.axes
    assert _band_extent(ax_t) == pytest.approx((traj["T_min"].min(), traj["T_max"].max()))
    delivered = next(line for line in ax_u.get_lines() if line.get_label() == "delivered u_phys")
    np.testing.assert_allclose(np.asarray(delivered.get_ydata()), traj["u_phys"] / 1000.0)
    assert ax_p.get_ylabel().startswith("price")


@pytest.mark.parametrize("t_m", ["missing", "nan"])
def test_a_run_without_a_hidden_mass_is_drawn_without_it(runs: dict[str, pd.DataFrame], t_m: str) -> None:
    """EnergyPlus and BOPTEST runs have no T_m (an online run's trajectory no column at all,
    which stopped `closed-loop --online --plot` with a KeyError): the figure draws T_r without it."""
    traj = runs["qp-mpc / true RC"].drop(columns=["T_m"])
    if t_m == "nan":
        traj["T_m"] = np.nan
    ax_t = trajectory_figure(traj).axes[0]
    labels = [line.get_label() for line in ax_t.get_lines()]
    assert "T_r (measured)" in labels and "T_m (true, hidden)" not in labels


def test_plot_comparison_writes_a_png(runs: dict[str, pd.DataFrame], tmp_path: Path) -> None:
    path = plot_comparison(runs, tmp_path / "cmp.png", title="x")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["cmp.png"]
