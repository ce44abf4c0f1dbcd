"""What a sweep answers: objective / oracle per scenario and controller, with 95 % intervals,
and the mean avoidable and unavoidable discomfort (:mod:`scenarios.running.kpis`).

Each cell's objective is divided by the oracle's on the same scenario and seed (same test
weather, prices and band), which removes most of the variation between seeds; the rows give
the mean of that ratio over seeds with a Student t interval (:func:`mean_ci95`, from
``scipy.stats``), and the paired difference to a baseline controller (per seed, the
controller's ratio minus the baseline's), whose interval is the narrower and fairer test of
"is it better than the baseline".
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
import scipy.stats

from scenarios.records import CellRecord, SweepRow, SweepSummary
from scenarios.reports.plots import save_figure
from scenarios.reports.report import markdown_table

REFERENCE = "oracle"

__all__ = [
    "REFERENCE",
    "mean_ci95",
    "place_label",
    "plot_sweep",
    "ratio",
    "render_sweep_report",
    "row_label",
    "summarise",
]


def mean_ci95(values: Sequence[float]) -> tuple[float, list[float | None]]:
    """Mean and two-sided 95 % Student t interval of the mean (``[None, None]`` for one value;
    ``[mean, mean]`` when all values are equal, where scipy's interval is undefined)."""
    x = np.asarray(values, dtype=float)
    if x.size == 0:
        raise ValueError("mean_ci95 needs at least one value")
    mean = float(x.mean())
    if x.size == 1:
        return mean, [None, None]
    sem = float(scipy.stats.sem(x))
    if sem == 0.0:
        return mean, [mean, mean]
    low, high = scipy.stats.t.interval(0.95, df=x.size - 1, loc=mean, scale=sem)
    return mean, [float(low), float(high)]


def ratio(row: Mapping[str, Any], what: str) -> Any:
    """A summary row's objective-over-reference figure ``what`` (``mean``, ``ci95`` or
    ``by_seed``), whichever its reference (``objective_to_oracle_mean``, ...)."""
    return row[f"objective_to_{row.get('reference', REFERENCE)}_{what}"]


def summarise(
    cells: Sequence[CellRecord],
    *,
    baseline: str,
    order: Sequence[str] = (),
    references: Mapping[str, str] | None = None,
) -> list[SweepRow]:
    """Rows of ``summary.json`` from cell records (``cell``: scenario, controller, seed,
    train_days, on BOPTEST test_period and price_scenario; ``kpis``: with ``objective``), one per
    scenario (x test period x price) x controller (x training size when several), controllers in ``order`` (others after, by name). Objectives are divided by
    the scenario's reference controller's (``references`` by scenario, the oracle by default;
    the thermostat where the plant has no oracle), in keys ``objective_to_<reference>_*``. A
    seed whose reference objective is missing or not positive is left out."""
    rank = {name: i for i, name in enumerate(order)}
    reference_of = dict(references or {})
    oracle: dict[tuple[Place, int], float] = {}
    for c in cells:
        key = c["cell"]
        ref_name = reference_of.get(key["scenario"], REFERENCE)
        if key["controller"] == ref_name and c["kpis"]["objective"] > 0:
            oracle[(_place(key), key["seed"])] = float(c["kpis"]["objective"])
    ratios: dict[tuple[Place, str, int | None], dict[int, float]] = {}
    parts: dict[tuple[Place, str, int | None], dict[int, tuple[float | None, float | None]]] = {}
    for c in cells:
        key = c["cell"]
        ref = oracle.get((_place(key), key["seed"]))
        if ref is None:
            continue
        group = (_place(key), key["controller"], key["train_days"])
        ratios.setdefault(group, {})[key["seed"]] = float(c["kpis"]["objective"]) / ref
        # A cell from before the split (reused) has neither part: not computed.
        parts.setdefault(group, {})[key["seed"]] = (
            c["kpis"].get("discomfort_avoidable_kh"), c["kpis"].get("discomfort_unavoidable_kh")
        )
    rows = []
    for group, by_seed in sorted(
        ratios.items(),
        key=lambda item: (
            tuple(p or "" for p in item[0][0]), rank.get(item[0][1], len(rank)), item[0][1], item[0][2] or 0
        ),
    ):
        place, controller, train_days = group
        scenario, period, price = place
        mean, ci = mean_ci95(list(by_seed.values()))
        ref_name = reference_of.get(scenario, REFERENCE)
        row: dict[str, Any] = {
            "scenario": scenario,
            **({"test_period": period, "price_scenario": price} if period is not None else {}),
            "controller": controller,
            "train_days": train_days,
            "n": len(by_seed),
            "reference": ref_name,
            f"objective_to_{ref_name}_mean": mean,
            f"objective_to_{ref_name}_ci95": ci,
            f"objective_to_{ref_name}_by_seed": {str(s): r for s, r in sorted(by_seed.items())},
            "discomfort_avoidable_kh_mean": _mean_or_none([a for a, _ in parts[group].values()]),
            "discomfort_unavoidable_kh_mean": _mean_or_none([u for _, u in parts[group].values()]),
            "baseline": baseline,
        }
        base = _baseline_ratios(ratios, place, baseline)
        paired = [r - base[s] for s, r in by_seed.items() if s in base]
        if paired:
            diff_mean, diff_ci = mean_ci95(paired)
            row.update(
                paired_difference_n=len(paired),
                paired_difference_mean=diff_mean,
                paired_difference_ci95=diff_ci,
            )
        else:
            row.update(paired_difference_n=0, paired_difference_mean=None, paired_difference_ci95=[None, None])
        rows.append(cast(SweepRow, row))  # its ratio keys named after the reference
    return rows


def _mean_or_none(values: Sequence[float | None]) -> float | None:
    """The mean of ``values``, None if any is None (not computed in some cell)."""
    known = [v for v in values if v is not None]
    return float(np.mean(known)) if known and len(known) == len(values) else None


def _baseline_ratios(
    ratios: Mapping[tuple[Place, str, int | None], dict[int, float]], place: Place, baseline: str
) -> dict[int, float]:
    """The baseline's ratios by seed (its first training size if it has several)."""
    groups = sorted(
        (k for k in ratios if k[0] == place and k[1] == baseline), key=lambda k: k[2] or 0
    )
    return ratios[groups[0]] if groups else {}


#: Where a cell runs: its scenario, and on BOPTEST its test period and price scenario.
Place = tuple[str, "str | None", "str | None"]


def _place(key: Mapping[str, Any]) -> Place:
    return (key["scenario"], key.get("test_period"), key.get("price_scenario"))


def place_label(row: Mapping[str, Any]) -> str:
    """A summary row's scenario, with BOPTEST's test period and price scenario when it has them."""
    if row.get("test_period") is None:
        return str(row["scenario"])
    return f"{row['scenario']} {row['test_period']} {row['price_scenario']}"


def row_label(row: SweepRow) -> str:
    """The controller, with its training size when it was trained."""
    days = row.get("train_days")
    return row["controller"] if days is None else f"{row['controller']} ({days} d)"


def _interval(mean: float | None, ci: Sequence[float | None]) -> str:
    if mean is None:
        return "n/a"
    if ci[0] is None or ci[1] is None:
        return f"{mean:.3f}"
    return f"{mean:.3f} [{ci[0]:.3f}, {ci[1]:.3f}]"


def _discomfort(value: float | None) -> str:
    return "not computed" if value is None else f"{value:.3f}"


def render_sweep_report(summary: SweepSummary, *, figure_name: str) -> str:
    """The markdown report of ``summary.json``."""
    engine = summary["engine"]
    baseline = summary["baseline"]
    lines = [
        "# Sweep: objective relative to the reference",
        "",
        "Each cell is one closed loop (one scenario, controller and seed; learned models trained "
        "on that seed's data). Its objective is divided by the reference's on the same scenario "
        "and seed: the oracle's, or the thermostat's on a plant without an oracle (EnergyPlus). "
        "Mean over seeds with a 95 % Student t interval (scipy.stats); the paired "
        f"difference is, seed by seed, the controller's ratio minus that of `{baseline}`. "
        "Discomfort, the mean over the same seeds: the unavoidable part is what the test days "
        "gave with the heater off (no controller could avoid it), the avoidable part the rest, "
        "which the controller is judged on; not computed on BOPTEST.",
        "",
    ]
    headers = ["scenario", "controller", "n", "reference", "objective / reference [95 % CI]",
               f"minus `{baseline}` [95 % CI]", "avoidable discomfort K h (mean)",
               "unavoidable discomfort K h (mean)"]
    body = [
        [
            f"`{place_label(r)}`",
            f"`{row_label(r)}`",
            str(r["n"]),
            str(r.get("reference", REFERENCE)),
            _interval(ratio(r, "mean"), ratio(r, "ci95")),
            _interval(r["paired_difference_mean"], r["paired_difference_ci95"]),
            _discomfort(r["discomfort_avoidable_kh_mean"]),
            _discomfort(r["discomfort_unavoidable_kh_mean"]),
        ]
        for r in summary["rows"]
    ]
    lines += markdown_table(headers, body)
    lines += [
        "",
        f"![objective / reference per controller and seed]({figure_name})",
        "",
        "## Run",
        "",
        f"- cells: {summary['cells_run']} run now, {summary['cells_reused']} reused from earlier runs",
        f"- models: {summary['models_trained']} trained now, {summary['models_reused']} reused",
        f"- engine: {engine['name']} {engine['version']}, resources {engine['resources']}",
        f"- wall time: {summary['wall_time_s']:.1f} s",
        "",
        "## Settings",
        "",
    ]
    lines += markdown_table(
        ["setting", "value"], [[k, f"`{v}`"] for k, v in summary["settings"].items()]
    )
    return "\n".join(lines) + "\n"


def plot_sweep(rows: Sequence[SweepRow], path: str | os.PathLike[str]) -> Path:
    """One panel per scenario: per controller a box of objective / reference over seeds, with
    the seeds as points on top (few seeds make a box alone misleading)."""
    import matplotlib.pyplot as plt

    scenarios = list(dict.fromkeys(place_label(r) for r in rows))
    fig, axes = plt.subplots(
        1, len(scenarios), figsize=(1.0 + 2.2 * max(3, len(rows) / max(len(scenarios), 1)), 4.2),
        squeeze=False,
    )
    for ax, scenario in zip(axes[0], scenarios, strict=True):
        mine = [r for r in rows if place_label(r) == scenario]
        values = [list(ratio(r, "by_seed").values()) for r in mine]
        positions = np.arange(1, len(mine) + 1)
        ax.boxplot(values, positions=positions, widths=0.5, showfliers=False)
        jitter = np.random.default_rng(0)
        for pos, vals in zip(positions, values, strict=True):
            ax.scatter(pos + jitter.uniform(-0.12, 0.12, len(vals)), vals, s=14, alpha=0.7,
                       color="tab:blue", zorder=3)
        ax.axhline(1.0, color="grey", lw=0.8, ls="--")
        ax.set_xticks(positions, [row_label(r) for r in mine], rotation=30, ha="right")
        ax.set_title(scenario)
        ax.set_ylabel(f"objective / {mine[0].get('reference', REFERENCE)}")
    fig.tight_layout()
    return save_figure(fig, path)
