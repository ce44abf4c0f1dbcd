"""Print the robustness sweep's per-cell table and its worst cells.

Run the sweep, then this on its directory:

    pinn-mpc sweep --spec sweeps/robustness.toml --out robustness
    python benchmarks/robustness_table.py robustness

Per cell (scenario x training days x seed): objective / oracle's of cem and random shooting over
the default model and of qp-mpc on the RC identified from the same data, cem / qp-mpc, and the
decisions the RC fallback made (of the test days' decisions) under cem and random shooting.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path


def load_cells(directory: Path) -> dict[tuple[str, str, int, int | None], dict]:
    """The sweep's cells: (scenario, controller, seed, training days) -> KPIs; a planner over
    the default model (``cem/auto``, the sweep's ``archs = ["auto"]``) is named as the
    planner alone (``cem``)."""
    cells = {}
    for path in sorted((directory / "cells").glob("*.json")):
        record = json.loads(path.read_text(encoding="utf-8"))
        c = record["cell"]
        controller = c["controller"].removesuffix("/auto")
        cells[(c["scenario"], controller, c["seed"], c["train_days"])] = record["kpis"]
    if not any(controller == "cem" for _, controller, _, _ in cells):
        raise SystemExit(f"{directory}: no cells of cem over the default model (cem or cem/auto)")
    return cells


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path, help="the sweep's --out directory")
    args = parser.parse_args()
    cells = load_cells(args.directory)
    oracle = {(s, seed): k["objective"] for (s, c, seed, _), k in cells.items() if c == "oracle"}
    print("| scenario | train days | seed | cem | random-shooting | qp-mpc | cem / qp-mpc | fallback decisions (cem, rs) |")
    print("|---|---|---|---|---|---|---|---|")
    ratios: dict[str, list[tuple[float, str]]] = {"cem": [], "rs": [], "qp": [], "cem/qp": []}
    for (scenario, controller, seed, days), cem in sorted(cells.items()):
        if controller != "cem" or (scenario, seed) not in oracle:
            continue
        ref = oracle[(scenario, seed)]
        rs = cells[(scenario, "random-shooting", seed, days)]
        qp = cells[(scenario, "qp-mpc", seed, days)]
        row = {
            "cem": cem["objective"] / ref,
            "rs": rs["objective"] / ref,
            "qp": qp["objective"] / ref,
            "cem/qp": cem["objective"] / qp["objective"],
        }
        label = f"{scenario} {days} d seed {seed}"
        for key, value in row.items():
            ratios[key].append((value, label))
        decisions = cem["days"] * round(86400 / 1800)
        print(
            f"| {scenario} | {days} | {seed} | {row['cem']:.3f} | {row['rs']:.3f} | {row['qp']:.3f} "
            f"| {row['cem/qp']:.3f} | {cem['model_fallback_steps']}, {rs['model_fallback_steps']} of {decisions} |"
        )
    for key, values in ratios.items():
        if values:
            worst = max(values)
            print(
                f"{key}: median {statistics.median(v for v, _ in values):.3f}, "
                f"worst {worst[0]:.3f} ({worst[1]})"
            )


if __name__ == "__main__":
    main()
