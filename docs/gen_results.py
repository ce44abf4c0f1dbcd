"""Run a committed sweep definition and write its results page (docs/results/<spec>.md).

The page is generated, not typed: it states the command that wrote it, the date, the commit,
the machine and the wall time, then the sweep's summary (objective / oracle's per scenario x
controller x training days: mean, 95 % t-interval and worst seed over seeds) and every cell.

    python docs/gen_results.py --spec sweeps/robustness.toml   # ~8 min on two cores
    python docs/gen_results.py --spec sweeps/smoke.toml        # ~2 min

``--out DIR`` keeps the sweep's directory (its cells are reused by a rerun with the same DIR,
as with ``pinn-mpc sweep``); by default the sweep runs in a temporary directory, so a page
always reflects the code it was generated on. ``--from-dir DIR`` writes the page from a sweep
that has already run (the page then says so, and gives no wall time).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path
from typing import Any

from scenarios.reports.sweep_report import ratio

ROOT = Path(__file__).resolve().parents[1]
#: What the results depend on: an uncommitted change here is stated on the page.
CODE = ("pinn_mpc", "pinn_mpc_cli", "controllers", "scenarios", "sweeps", "pyproject.toml",
        "constraints.txt")


def _git(*args: str) -> str:
    try:
        return subprocess.run(
            ["git", *args], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def commit() -> str:
    """The checked-out commit, with ``+ uncommitted changes`` when the tree differs from it."""
    head = _git("rev-parse", "--short=12", "HEAD")
    dirty = _git("status", "--porcelain", "--untracked-files=no", "--", *CODE)
    return head + (" + uncommitted changes to the code" if dirty and dirty != "unknown" else "")


def machine() -> str:
    """CPU model, logical CPUs, load, OS and Python of this machine."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    load = ""
    if hasattr(os, "getloadavg"):
        load = f", load {os.getloadavg()[0]:.1f} at the end"
    return (
        f"{cpu}, {os.cpu_count()} logical CPUs{load}; {platform.system()} {platform.release()}, "
        f"Python {platform.python_version()}"
    )


def _ratio(x: float | None) -> str:
    return "" if x is None else f"{x:.3f}"


def _ci(ci: list[float | None]) -> str:
    low, high = ci
    return "" if low is None or high is None else f"[{low:.3f}, {high:.3f}]"


def summary_table(summary: dict[str, Any]) -> list[str]:
    """Objective / the reference's (oracle, or thermostat where no oracle exists) per scenario
    x controller x training days."""
    baseline = summary["rows"][0]["baseline"] if summary["rows"] else ""
    lines = [
        f"| scenario | controller | train days | seeds | reference | objective / reference (mean) "
        f"| 95 % interval | worst seed | minus {baseline} (paired mean) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in summary["rows"]:
        reference = r.get("reference", "oracle")
        if r["controller"] == reference:  # 1 by definition
            continue
        by_seed = ratio(r, "by_seed")
        worst_seed = max(by_seed, key=by_seed.get)
        days = "" if r.get("train_days") is None else str(r["train_days"])
        diff = r.get("paired_difference_mean")
        diff_text = "" if diff is None or r["controller"] == baseline else f"{diff:+.3f}"
        lines.append(
            f"| {r['scenario']} | {r['controller']} | {days} | {r['n']} | {reference} "
            f"| {_ratio(ratio(r, 'mean'))} | {_ci(ratio(r, 'ci95'))} "
            f"| {by_seed[worst_seed]:.3f} (seed {worst_seed}) | {diff_text} |"
        )
    return lines


def _steps_per_day(scenario: str) -> int:
    from scenarios import get_scenario

    return get_scenario(scenario).steps_per_day


def cell_table(directory: Path, order: list[str], references: dict[str, str]) -> list[str]:
    """Every cell: objective / the reference's per controller (``references`` by scenario,
    the oracle by default), and the fallback's decisions."""
    cells: dict[tuple[str, str, int, int | None], dict[str, Any]] = {}
    for path in sorted((directory / "cells").glob("*.json")):
        record = json.loads(path.read_text(encoding="utf-8"))
        c = record["cell"]
        cells[(c["scenario"], c["controller"], c["seed"], c["train_days"])] = record["kpis"]
    def is_reference(scenario: str, controller: str) -> bool:
        return controller == references.get(scenario, "oracle")

    oracle = {(s, seed): k["objective"] for (s, c, seed, _), k in cells.items() if is_reference(s, c)}
    found = {c for (s, c, _, _) in cells if not is_reference(s, c)}
    controllers = [c for c in order if c in found] + sorted(found - set(order))
    runs = sorted({(s, d, seed) for (s, c, seed, d) in cells if not is_reference(s, c)}, key=str)
    lines = [
        "| scenario | train days | seed | "
        + " | ".join(controllers)
        + " | reference objective EUR | fallback decisions |",
        "|---|---|---|" + "---|" * len(controllers) + "---|---|",
    ]
    for scenario, days, seed in runs:
        ref = oracle.get((scenario, seed))
        row, fallbacks = [], []
        for name in controllers:
            kpis = cells.get((scenario, name, seed, days))
            row.append("" if kpis is None or not ref else f"{kpis['objective'] / ref:.3f}")
            if kpis is not None and kpis.get("model_fallback_steps") is not None:
                decisions = kpis["days"] * _steps_per_day(scenario)
                fallbacks.append(f"{name} {kpis['model_fallback_steps']} of {decisions}")
        lines.append(
            f"| {scenario} | {'' if days is None else days} | {seed} | " + " | ".join(row)
            + f" | {'' if ref is None else f'{ref:.2f}'} | {', '.join(fallbacks)} |"
        )
    return lines


def page(spec: Path, directory: Path, command: str, wall_s: float | None, at: str) -> str:
    """The markdown of the results page."""
    summary = json.loads((directory / "summary.json").read_text(encoding="utf-8"))
    spec_text = spec.read_text(encoding="utf-8").rstrip()
    now = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    wall = (
        f"{wall_s / 60:.1f} min ({summary['cells_run']} cells run, {summary['cells_reused']} "
        f"reused; {summary['models_trained']} models trained)"
        if wall_s is not None
        else "not timed (written from an existing sweep directory)"
    )
    settings = summary.get("settings", {})
    engine = summary.get("engine") or summary.get("ray") or {}
    lines = [
        f"# {spec.stem.replace('_', ' ').capitalize()} sweep",
        "",
        f"<!-- Written by docs/gen_results.py from {spec.relative_to(ROOT)}; do not edit: "
        "rerun the command below. -->",
        "",
        f"**Generated** by `{command}` on {now}.",
        "",
        f"- commit: `{at}`",
        f"- machine: {machine()}",
        f"- wall time: {wall}",
        f"- settings: `{json.dumps(settings, sort_keys=True)}`" if settings else "- settings: defaults",
    ]
    if engine:
        lines.append(f"- engine: `{json.dumps(engine, sort_keys=True)}`")
    lines += [
        "",
        f"The specification, `{spec.relative_to(ROOT)}`:",
        "",
        "```toml",
        spec_text,
        "```",
        "",
        "## Objective / the reference's over seeds",
        "",
        "Each cell's objective (cost + comfort weight x discomfort) divided by the reference's on "
        "the same test days (the oracle's; the thermostat's on an EnergyPlus building, which has "
        "no oracle); mean and 95 % Student t interval over seeds, the worst seed, and the "
        "mean paired difference to the baseline (negative: better than it).",
        "",
        *summary_table(summary),
        "",
        "## Every cell",
        "",
        "Objective / the reference's of each controller on each run; the fallback column counts the "
        "decisions a planner over a learned model handed to the RC MPC, of the test days' decisions.",
        "",
        *cell_table(
            directory,
            list(tomllib.loads(spec_text).get("controllers", [])),
            {r["scenario"]: r.get("reference", "oracle") for r in summary["rows"]},
        ),
        "",
    ]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spec", type=Path, required=True, help="a sweep definition (sweeps/*.toml)")
    parser.add_argument("--out", type=Path, help="keep the sweep's directory here (reused by a rerun)")
    parser.add_argument("--from-dir", type=Path, help="write the page from a sweep that has run")
    parser.add_argument("--page", type=Path, help="the page to write (default docs/results/<spec>.md)")
    args = parser.parse_args()
    spec = args.spec.resolve()
    if not spec.is_file():
        parser.error(f"no sweep definition at {args.spec}")
    target = args.page or ROOT / "docs" / "results" / f"{spec.stem}.md"
    command = "python docs/gen_results.py --spec " + shlex.quote(str(spec.relative_to(ROOT)))
    if args.from_dir is not None:
        text = page(spec, args.from_dir, command, None, commit())
    else:
        with tempfile.TemporaryDirectory(prefix="gen_results_") as tmp:
            directory = args.out or Path(tmp) / spec.stem
            at, start = commit(), time.perf_counter()
            subprocess.run(
                [sys.executable, "-m", "pinn_mpc", "sweep", "--spec", str(spec), "--out", str(directory)],
                cwd=ROOT, check=True,
            )
            text = page(spec, directory, command, time.perf_counter() - start, at)
    target.write_text(text, encoding="utf-8")
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
