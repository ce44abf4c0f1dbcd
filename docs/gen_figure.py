"""Write the overview figure of the README and the docs (docs/img/overview.png).

Two February test days of ``winter_household``: CEM over a hybrid trained on 30 days of
random-level data (the package's default model and planner), the thermostat and the oracle;
room temperature against the comfort band, delivered power, price. About a minute on two cores:

    python docs/gen_figure.py
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from pinn_mpc import TrainConfig, train_model
from scenarios import build_controller, generate, get_scenario, run_closed_loop
from scenarios.reports.plots import (
    draw_band,
    draw_power,
    draw_price,
    draw_room,
    format_time_axis,
    new_figure,
    save_figure,
)

ROOT = Path(__file__).resolve().parents[1]
STYLES: dict[str, dict[str, Any]] = {
    "thermostat": {"color": "tab:blue"},
    "cem": {"color": "tab:red", "lw": 1.6},
    "oracle": {"color": "black", "ls": "--"},
}
LABELS = {"thermostat": "thermostat", "cem": "CEM over the learned hybrid", "oracle": "oracle"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "overview.png")
    args = parser.parse_args()
    scenario = get_scenario("winter_household")
    data = generate(scenario, days=30, seed=0, policy="random-level")
    config = TrainConfig(n_seeds=10, eta=scenario.sim.params.eta, u_max_w=scenario.sim.u_max_w)
    model = train_model(data, arch="hybrid", config=config, progress=False)
    days = 2
    n_steps = days * scenario.steps_per_day
    runs = {}
    for name in STYLES:
        controller = build_controller(
            name, scenario, model=model if name == "cem" else None, n_steps=n_steps
        )
        runs[name] = run_closed_loop(scenario, controller, days=days, seed=1)

    fig, axes = new_figure(3, 1, figsize=(8, 4.6), height_ratios=(2, 1.1, 0.6), sharex=True)
    ax_t, ax_u, ax_p = axes[:, 0]
    first = runs["oracle"].trajectory
    draw_band(ax_t, first)
    for name, result in runs.items():
        k = result.kpis
        label = f"{LABELS[name]}: {k['objective']:.1f} EUR, {k['discomfort_kh']:.1f} K h"
        draw_room(ax_t, result.trajectory, label, **STYLES[name])
        draw_power(ax_u, result.trajectory, LABELS[name], **STYLES[name])
    ax_t.set_ylabel("room [C]")
    ax_u.set_ylabel("heat [kW]")
    for ax in (ax_t, ax_u):
        ax.grid(alpha=0.3)
    ax_t.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), fontsize=7.5, frameon=False, ncols=2)
    draw_price(ax_p, first)
    format_time_axis(ax_p, first)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    print(f"wrote {save_figure(fig, args.out)}")


if __name__ == "__main__":
    main()
