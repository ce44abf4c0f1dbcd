"""What a sweep's controllers run online answer per week of service: each week's objective,
discomfort, own decisions and the running model's day-ahead error, the mean over seeds and the
worst seed, against the sweep's baseline (a controller trained once, before the test), and a
figure of the objective per day of service.

A week is :data:`WEEK_DAYS` days of service from the first test day (the last one shorter when
the test days are not whole weeks). A cell's days are its KPIs' ``online`` days (a controller
run online) or ``per_day`` (any other cell on the package's own plants); a cell without them (a
sweep from before they were kept, BOPTEST) is left out.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scenarios.choices import online_controller
from scenarios.inputs.registry import is_scenario_file
from scenarios.reports.plots import save_figure
from scenarios.reports.report import markdown_table

__all__ = ["WEEK_DAYS", "WeekRow", "cell_days", "online_section", "plot_online_days", "refit_table", "week_rows", "week_table"]

#: Days of service in a week of the per-week table.
WEEK_DAYS = 7


@dataclass(frozen=True, kw_only=True)
class WeekRow:
    """One controller's week of service on one scenario, over its seeds. ``objective_*`` are
    the week's summed objective [EUR]; ``to_baseline_*`` the week's objective / the baseline's
    on the same seed and week (``to_baseline_mean``: the mean objective over the seeds both
    ran / the baseline's mean; None without baseline cells); ``discomfort_kh_mean`` the week's
    summed discomfort [K h]; ``own_share_mean`` the share of the week's decisions the
    controller made itself [-]; ``day_ahead_error_c_mean`` the running model's day-ahead error
    [K] over the week's judged days (None: no model ran, or no day was judged)."""

    scenario: str
    controller: str
    data_days: int | None  # the cells' training days; a controller run online: its days of data
    week: int
    first_day: int
    last_day: int
    seeds: tuple[int, ...]
    objective_mean: float
    objective_worst: float
    objective_worst_seed: int
    to_baseline_mean: float | None
    to_baseline_worst: float | None
    to_baseline_worst_seed: int | None
    discomfort_kh_mean: float
    own_share_mean: float
    day_ahead_error_c_mean: float | None


def cell_days(kpis: Mapping[str, Any]) -> list[dict[str, Any]]:
    """A cell's figures per day of service: its ``online`` days, else its ``per_day``, else none."""
    online = kpis.get("online")
    if isinstance(online, Mapping) and online.get("days"):
        return list(online["days"])
    return list(kpis.get("per_day") or [])


def _weeks(days: Sequence[Mapping[str, Any]]) -> dict[int, list[Mapping[str, Any]]]:
    out: dict[int, list[Mapping[str, Any]]] = {}
    for day in days:
        out.setdefault((int(day["day"]) - 1) // WEEK_DAYS + 1, []).append(day)
    return out


def _is_shown(controller: str, baseline: str) -> bool:
    return online_controller(controller) is not None or controller == baseline


def week_rows(records: Sequence[Mapping[str, Any]], *, baseline: str) -> list[WeekRow]:
    """The per-week rows of every controller run online and of ``baseline`` (the sweep's
    baseline, e.g. cem over a model trained once), per scenario and days of data, from the
    cell records ``records`` (``cells/*.json``); empty when no controller ran online. With
    several training lengths of the baseline, the longest is the one compared with."""
    if not any(online_controller(r["cell"]["controller"]) for r in records):
        return []
    groups: dict[tuple[str, str, int | None], dict[int, Sequence[Mapping[str, Any]]]] = {}
    for r in records:
        c = r["cell"]
        days = cell_days(r["kpis"])
        if days and _is_shown(c["controller"], baseline):
            groups.setdefault((c["scenario"], c["controller"], c["train_days"]), {})[c["seed"]] = days
    base_days = {
        scenario: max((d for (s, c, d) in groups if s == scenario and c == baseline), default=None, key=lambda d: d or 0)
        for scenario in {s for (s, _, _) in groups}
    }
    rows = []
    for (scenario, controller, data_days), by_seed in groups.items():
        reference = groups.get((scenario, baseline, base_days[scenario]), {})
        weekly = {seed: _weeks(days) for seed, days in by_seed.items()}
        base_weekly = {seed: _weeks(days) for seed, days in reference.items()}
        for week in sorted({w for weeks in weekly.values() for w in weeks}):
            seeds = tuple(sorted(s for s in weekly if week in weekly[s]))
            objective = {s: sum(d["objective"] for d in weekly[s][week]) for s in seeds}
            worst = max(seeds, key=lambda s: objective[s])
            paired = tuple(s for s in seeds if week in base_weekly.get(s, {}))
            base = {s: sum(d["objective"] for d in base_weekly[s][week]) for s in paired}
            ratios = {s: objective[s] / base[s] for s in paired}
            worst_ratio = max(ratios, key=lambda s: ratios[s]) if ratios else None
            errors = [
                d["model_day_ahead_error_c"] for s in seeds for d in weekly[s][week]
                if d.get("model_day_ahead_error_c") is not None
            ]
            days_of_week = [int(d["day"]) for s in seeds for d in weekly[s][week]]
            rows.append(WeekRow(
                scenario=scenario, controller=controller, data_days=data_days, week=week,
                first_day=min(days_of_week), last_day=max(days_of_week), seeds=seeds,
                objective_mean=float(np.mean([objective[s] for s in seeds])),
                objective_worst=objective[worst], objective_worst_seed=worst,
                to_baseline_mean=(
                    float(np.mean([objective[s] for s in paired]) / np.mean([base[s] for s in paired]))
                    if paired else None
                ),
                to_baseline_worst=None if worst_ratio is None else ratios[worst_ratio],
                to_baseline_worst_seed=worst_ratio,
                discomfort_kh_mean=float(np.mean(
                    [sum(d["discomfort_kh"] for d in weekly[s][week]) for s in seeds]
                )),
                own_share_mean=float(np.mean(
                    [np.mean([d["own_decisions_share"] for d in weekly[s][week]]) for s in seeds]
                )),
                day_ahead_error_c_mean=float(np.mean(errors)) if errors else None,
            ))
    return sorted(rows, key=lambda r: (r.scenario, r.controller != baseline, r.controller, r.week))


def week_table(rows: Sequence[WeekRow], *, baseline: str) -> list[str]:
    """The per-week rows as a markdown table."""
    def number(value: float | None, form: str) -> str:
        return "" if value is None else format(value, form)

    body = [
        [
            r.scenario, r.controller, "" if r.data_days is None else str(r.data_days),
            f"{r.week} ({r.first_day}-{r.last_day})", str(len(r.seeds)),
            f"{r.objective_mean:.2f}", f"{r.objective_worst:.2f} (seed {r.objective_worst_seed})",
            "" if r.controller == baseline else number(r.to_baseline_mean, ".3f"),
            "" if r.controller == baseline or r.to_baseline_worst is None
            else f"{r.to_baseline_worst:.3f} (seed {r.to_baseline_worst_seed})",
            f"{r.discomfort_kh_mean:.2f}", f"{100 * r.own_share_mean:.1f} %",
            number(r.day_ahead_error_c_mean, ".3f"),
        ]
        for r in rows
    ]
    return markdown_table(
        ["scenario", "controller", "days of data", "week (days)", "seeds", "objective EUR (mean)",
         "worst seed EUR", f"/ {baseline} (mean)", f"/ {baseline} worst seed", "discomfort K h (mean)",
         "own decisions (mean)", "day-ahead error K (mean)"],
        body,
    )


def plot_online_days(records: Sequence[Mapping[str, Any]], path: str | os.PathLike[str], *, baseline: str) -> Path | None:
    """One panel per scenario: the objective per day of service [EUR], the mean over seeds, of
    every controller run online and of ``baseline``; None (nothing written) when no controller
    ran online."""
    rows = week_rows(records, baseline=baseline)
    if not rows:
        return None
    import matplotlib.pyplot as plt

    scenarios = sorted({r.scenario for r in rows})
    fig, axes = plt.subplots(1, len(scenarios), figsize=(5.5 * len(scenarios), 3.8), squeeze=False)
    for ax, scenario in zip(axes[0], scenarios, strict=True):
        series: dict[tuple[str, int | None], dict[int, list[float]]] = {}
        for r in records:
            c = r["cell"]
            if c["scenario"] != scenario or not _is_shown(c["controller"], baseline):
                continue
            for day in cell_days(r["kpis"]):
                series.setdefault((c["controller"], c["train_days"]), {}).setdefault(int(day["day"]), []).append(day["objective"])
        for (controller, data_days), by_day in sorted(series.items(), key=lambda item: (item[0][0] != baseline, item[0][0])):
            days = sorted(by_day)
            label = f"{controller} ({data_days} days of data)" if data_days is not None else controller
            ax.plot(days, [np.mean(by_day[d]) for d in days], marker=".", lw=1.2, label=label,
                    color="black" if controller == baseline else None)
        for week_end in range(WEEK_DAYS, max(r.last_day for r in rows), WEEK_DAYS):
            ax.axvline(week_end + 0.5, color="grey", lw=0.6, ls=":")
        ax.set_title(Path(scenario).name if is_scenario_file(scenario) else scenario)  # no machine's path
        ax.set_xlabel("day of service")
        ax.set_ylabel("objective per day [EUR], mean over seeds")
        ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)


def refit_table(records: Sequence[Mapping[str, Any]]) -> list[str]:
    """Per scenario and controller run online: each night's refit wall time [s] over its nights
    and seeds (median, largest and the rows it refitted on), the refits late for their
    takeover, and the machine's 1-minute load as the refits ended (median, largest); from the
    records' ``online_log``, empty without one."""
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for r in records:
        if online_controller(r["cell"]["controller"]) and r.get("online_log"):
            key = (r["cell"]["scenario"], r["cell"]["controller"])
            groups.setdefault(key, []).extend(e for e in r["online_log"] if e.get("verdict") != "initial")
    body = []
    for (scenario, controller), nights in sorted(groups.items()):
        if not nights:
            continue
        walls = [float(e["wall_s"]) for e in nights]
        longest = max(nights, key=lambda e: float(e["wall_s"]))
        loads = [float(e["load_1min"]) for e in nights if e.get("load_1min") is not None]
        body.append([
            scenario, controller, str(len(nights)), f"{np.median(walls):.1f}",
            f"{max(walls):.1f} ({longest['rows']} rows)", str(sum(bool(e.get("late")) for e in nights)),
            f"{np.median(loads):.1f} / {max(loads):.1f}" if loads else "not recorded",
        ])
    if not body:
        return []
    return markdown_table(
        ["scenario", "controller", "nights", "refit wall s (median)", "refit wall s (largest)",
         "late refits", "load 1 min (median / largest)"],
        body,
    )


def online_section(records: Sequence[Mapping[str, Any]], *, baseline: str, figure_name: str | None) -> list[str]:
    """The markdown section of the controllers run online (per-week table and, when given,
    the figure ``figure_name``); empty when none ran."""
    rows = week_rows(records, baseline=baseline)
    if not rows:
        return []
    lines = [
        "## Online: per week of service",
        "",
        "Controllers run online start from their days of data and refit their model and RC every "
        f"night; `{baseline}` is trained once before the test. Per week of service: the week's "
        "objective (summed over its days) and discomfort, the mean over seeds and the worst seed; "
        f"the week's objective / `{baseline}`'s on the same seeds (mean: of the means; worst: the "
        "largest seed's ratio); the share of decisions the controller made itself (a controller "
        "run online: decisions of the model it refitted, or of the RC for `qp-mpc-online`; not its "
        "fallback nor what it started from); the running model's day-ahead error, each day judged "
        "the night after (12 h ahead).",
        "",
        *week_table(rows, baseline=baseline),
        "",
        *([f"![objective per day of service, mean over seeds]({figure_name})", ""] if figure_name else []),
    ]
    refits = refit_table(records)
    return lines + ([
        "Each night's refit in its worker process (one torch thread), over every night of every "
        "seed: its wall time, the refits not done by their takeover at 03:00 (waited for there: "
        "the decisions do not change, the run takes longer), and the machine's load as they ended.",
        "",
        *refits,
        "",
    ] if refits else [])
