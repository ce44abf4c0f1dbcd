"""Run a committed sweep definition and write its results page (docs/results/<spec>.md).

The page is generated, not typed: it states the command that wrote it, the date, the commit,
the machine and the wall time, then the sweep's summary (objective / oracle's per scenario x
controller x training days: mean, 95 % t-interval and worst seed over seeds) and every cell.

    python docs/gen_results.py --spec sweeps/robustness.toml   # ~8 min on two cores
    python docs/gen_results.py --spec sweeps/smoke.toml        # ~2 min

A BOPTEST sweep (``sweeps/boptest.toml``: its cells carry a test period) runs against the
BOPTEST server at ``$BOPTEST_URL``; its page gives BOPTEST's KPIs of every cell and BOPTEST's
published baseline figures beside the summary. It takes hours: run it once with ``--out DIR``
(or ``pinn-mpc sweep --spec sweeps/boptest.toml --out DIR``) and write the page with
``--from-dir DIR``.

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
import re
import shlex
import subprocess
import sys
import tempfile
import time
import tomllib
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from scenarios.reports.online_report import online_section, plot_online_days
from scenarios.reports.sweep_report import place_label, ratio

ROOT = Path(__file__).resolve().parents[1]
#: What the results depend on: an uncommitted change here is stated on the page.
CODE = ("pinn_mpc", "pinn_mpc_cli", "controllers", "scenarios", "sweeps", "pyproject.toml",
        "constraints.txt")


def commit() -> str:
    """The checked-out commit, with ``+ uncommitted changes`` when :data:`CODE` differs from
    it (:func:`scenarios.experiments.sweep.store.code_revision`, as a sweep's cells name theirs)."""
    from scenarios.experiments.sweep.store import code_revision

    return code_revision(CODE) or "unknown"


def cells_code(directory: Path) -> str:
    """The commits at which a sweep's cells ran (each cell's record keeps its own, since a
    rerun reuses the cells of earlier runs), most cells first, with their counts."""
    counts: Counter[str] = Counter()
    for path in (directory / "cells").glob("*.json"):
        record = json.loads(path.read_text(encoding="utf-8"))
        if "code" not in record:
            counts["not recorded (a sweep from before cells kept it)"] += 1
        else:
            counts[f"`{record['code']}`" if record["code"] else "not a git checkout"] += 1
    return ", ".join(f"{what} ({n} cell{'s' if n != 1 else ''})" for what, n in counts.most_common())


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
    x controller x training days, and the mean avoidable and unavoidable discomfort."""
    baseline = summary["rows"][0]["baseline"] if summary["rows"] else ""
    lines = [
        f"| scenario | controller | train days | seeds | reference | objective / reference (mean) "
        f"| 95 % interval | worst seed | minus {baseline} (paired mean) "
        "| avoidable discomfort K h (mean) | unavoidable discomfort K h (mean) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
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
            f"| {place_label(r)} | {r['controller']} | {days} | {r['n']} | {reference} "
            f"| {_ratio(ratio(r, 'mean'))} | {_ci(ratio(r, 'ci95'))} "
            f"| {by_seed[worst_seed]:.3f} (seed {worst_seed}) | {diff_text} "
            f"| {_discomfort(r, 'avoidable')} | {_discomfort(r, 'unavoidable')} |"
        )
    return lines


def _discomfort(row: dict[str, Any], part: str) -> str:
    """A summary row's mean avoidable or unavoidable discomfort; a summary from before the
    split has neither."""
    value = row.get(f"discomfort_{part}_kh_mean")
    return "not computed" if value is None else f"{value:.3f}"


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
                model = f" ({kpis['model']})" if name.endswith("/auto") and kpis.get("model") else ""
                fallbacks.append(f"{name}{model} {kpis['model_fallback_steps']} of {decisions}")
        lines.append(
            f"| {scenario} | {'' if days is None else days} | {seed} | " + " | ".join(row)
            + f" | {'' if ref is None else f'{ref:.2f}'} | {', '.join(fallbacks)} |"
        )
    return lines


def zone_table(directory: Path, order: list[str]) -> list[str]:
    """Buildings of several zones: each zone's discomfort too cold / too warm [K h] and the
    share of the planner's own decisions (not the fallback's), the mean over seeds (the share's
    worst seed beside it), per scenario, controller and training days; empty without such
    cells."""
    groups: dict[tuple[str, str, int | None], list[dict[str, Any]]] = {}
    for record in _cells(directory):
        c, kpis = record["cell"], record["kpis"]
        if len(kpis.get("zones") or {}) > 1:
            groups.setdefault((c["scenario"], c["controller"], c["train_days"]), []).append(kpis)
    if not groups:
        return []
    rank = {name: i for i, name in enumerate(order)}
    lines = [
        "## Discomfort by zone",
        "",
        "Each zone's discomfort too cold / too warm in K h, the mean over seeds, and the share "
        "of decisions the controller made itself (the rest its fallback's: a failed plan or, "
        "over a learned model, its guard), the mean and the worst seed.",
        "",
        "| scenario | controller | train days | seeds | own decisions mean (worst) | each zone: too cold / too warm K h |",
        "|---|---|---|---|---|---|",
    ]
    for (scenario, controller, days), runs in sorted(
        groups.items(), key=lambda item: (item[0][0], rank.get(item[0][1].partition("/")[0], len(rank)), item[0][1], item[0][2] or 0)
    ):
        shares = [k.get("own_decisions_share") for k in runs]
        share = (
            f"{100 * float(np.mean(shares)):.1f} % ({100 * min(shares):.1f} %)"
            if all(s is not None for s in shares) else ""
        )
        zones = ", ".join(
            f"{zone} {np.mean([k['zones'][zone]['discomfort_too_cold_kh'] for k in runs]):.2f} / "
            f"{np.mean([k['zones'][zone]['discomfort_too_warm_kh'] for k in runs]):.2f}"
            for zone in runs[0]["zones"]
        )
        lines.append(f"| {scenario} | {controller} | {'' if days is None else days} | {len(runs)} | {share} | {zones} |")
    return [*lines, ""]


#: BOPTEST's published KPIs of its baseline controller on bestest_hydronic_heat_pump (its
#: baselines/csv/df_kpi_bestest_hydronic_heat_pump.csv, whole 14-day test periods): tdis K h/zone,
#: energy kWh/m2, cost EUR/m2, by (test period, price scenario).
PUBLISHED_BASELINE = {
    ("peak_heat_day", "dynamic"): (8.381, 3.478, 0.8828),
    ("peak_heat_day", "highly_dynamic"): (8.381, 3.478, 0.9088),
    ("typical_heat_day", "dynamic"): (9.442, 1.774, 0.4423),
    ("typical_heat_day", "highly_dynamic"): (9.442, 1.774, 0.4127),
}
#: BOPTEST's KPIs a BOPTEST page shows: (key in its /kpi, heading).
BOPTEST_KPIS = (
    ("tdis_tot", "tdis K h/zone (total)"),
    ("ener_tot", "energy kWh/m2"),
    ("cost_tot", "cost EUR/m2"),
    ("emis_tot", "emissions kg/m2"),
    ("time_rat", "time ratio"),
)


def _cells(directory: Path) -> list[dict[str, Any]]:
    return [json.loads(p.read_text(encoding="utf-8")) for p in sorted((directory / "cells").glob("*.json"))]


def is_boptest_sweep(directory: Path) -> bool:
    """Whether the sweep's cells ran on BOPTEST (they carry a test period)."""
    return any(r["cell"].get("test_period") is not None for r in _cells(directory))


def _kpi(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, int | float) and not isinstance(value, bool) else "-"


def boptest_cell_table(directory: Path, order: list[str]) -> list[str]:
    """Every BOPTEST cell: BOPTEST's KPIs, the share of its own decisions, the wall time per
    simulated day and the decision times; per test period and price, controllers in ``order``."""
    rank = {name: i for i, name in enumerate(order)}
    records = sorted(
        _cells(directory),
        key=lambda r: (
            r["cell"]["scenario"], r["cell"]["test_period"], r["cell"]["price_scenario"],
            rank.get(r["cell"]["controller"], len(rank)), r["cell"]["controller"],
            r["cell"]["train_days"] or 0, r["cell"]["seed"],
        ),
    )
    heads = [h for _, h in BOPTEST_KPIS]
    lines = [
        "| test period | price | controller | train days | seed | model | " + " | ".join(heads)
        + " | own decisions | wall s / day | decision ms (median / p95) |",
        "|---" * (len(heads) + 9) + "|",
    ]
    for r in records:
        c, k = r["cell"], r["kpis"]
        b = k.get("boptest") or {}
        wall = k.get("wall_s_per_day", r["wall_time_s"] / max(k["days"], 1))
        lines.append(
            f"| {c['test_period']} | {c['price_scenario']} | {c['controller']} "
            f"| {'' if c['train_days'] is None else c['train_days']} | {c['seed']} | {k.get('model', '')} | "
            + " | ".join(_kpi(b.get(key)) for key, _ in BOPTEST_KPIS)
            + f" | {100 * k['own_decisions_share']:.0f} % | {wall:.1f} "
            f"| {k['decision_ms_median']:.1f} / {k['decision_ms_p95']:.1f} |"
        )
    return lines


def published_baseline_table() -> list[str]:
    """BOPTEST's published baseline KPIs of bestest_hydronic_heat_pump (14-day test periods)."""
    lines = [
        "| test period | price | tdis K h/zone (total) | energy kWh/m2 | cost EUR/m2 |",
        "|---|---|---|---|---|",
    ]
    for (period, price), (tdis, energy, cost) in PUBLISHED_BASELINE.items():
        lines.append(f"| {period} | {price} | {tdis} | {energy} | {cost} |")
    return lines


def boptest_provenance(spec: Path, directory: Path) -> list[str]:
    """What a BOPTEST page was measured on (BOPTEST's version as its server reported it, the
    test cases) and the commands that measure it again, given a BOPTEST server."""
    kpis = [r["kpis"] for r in _cells(directory)]
    versions = sorted({str(k["boptest_version"]) for k in kpis if k.get("boptest_version")})
    cases = sorted({str(k["boptest_testcase"]) for k in kpis if k.get("boptest_testcase")})
    name = directory.name
    return [
        f"- BOPTEST: version {', '.join(versions) or 'not recorded by the cells'} (the server's "
        f"`GET /version`), test case {', '.join(f'`{c}`' for c in cases) or 'not recorded'}",
        f"- measured again (needs a BOPTEST server, docs/boptest.md): `pinn-mpc sweep --spec "
        f"{spec.relative_to(ROOT)} --out {name} --workers 2`, then `python docs/gen_results.py "
        f"--spec {spec.relative_to(ROOT)} --from-dir {name}`",
    ]


def _boptest_sections(spec_text: str, directory: Path) -> list[str]:
    order = ["boptest-baseline", *tomllib.loads(spec_text).get("controllers", [])]
    return [
        "## BOPTEST's KPIs of every cell",
        "",
        "Each cell is one test on the BOPTEST server: the first `days` of the test period after "
        "BOPTEST's warm-up, at 30-min control steps. BOPTEST's own KPIs (`/kpi`: thermal "
        "discomfort per zone, energy, cost and emissions per m2 of floor, the time ratio of "
        "decision time to simulated time); the share of decisions the controller made itself "
        "(not its RC MPC fallback); the cell's wall time per simulated day through the web API "
        "(select, warm-up and decisions included); each decision's time. `model` is what cem "
        "planned over (for `cem/auto`, the family `train` chose) or `rc` for qp-mpc.",
        "",
        *boptest_cell_table(directory, order),
        "",
        "## BOPTEST's published baseline",
        "",
        "For reference: BOPTEST's published KPIs of the test case's own controller on the whole "
        "14-day test periods (its `baselines/csv/df_kpi_bestest_hydronic_heat_pump.csv`); the "
        "`boptest-baseline` cells above reproduce them when `days` is 14.",
        "",
        *published_baseline_table(),
        "",
    ]


def page(
    spec: Path, directory: Path, command: str, wall_s: float | None, at: str, days_figure: str | None = None
) -> str:
    """The markdown of the results page (of a BOPTEST sweep: BOPTEST's KPIs of every cell and
    its published baseline instead of the objective ratio of every cell); with controllers run
    online, their per-week table and the figure ``days_figure`` (:func:`days_figure`)."""
    summary = json.loads((directory / "summary.json").read_text(encoding="utf-8"))
    spec_text = spec.read_text(encoding="utf-8").rstrip()
    now = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    counts = (
        f"{summary['cells_run']} cells run, {summary['cells_reused']} reused; "
        f"{summary['models_trained']} models trained"
    )
    if wall_s is not None:
        wall = f"{wall_s / 60:.1f} min ({counts})"
    elif summary.get("wall_time_s") is not None:  # the sweep's own last run, from its summary
        wall = f"{summary['wall_time_s'] / 60:.1f} min, the sweep's last run ({counts})"
    else:
        wall = "not timed (written from an existing sweep directory)"
    settings = dict(summary.get("settings", {}))
    if summary.get("grid", {}).get("archs"):  # the grid's archs, not the settings' arch, ran
        settings.pop("arch", None)
    engine = summary.get("engine") or summary.get("ray") or {}
    lines = [
        f"# {spec.stem.replace('_', ' ').capitalize()} sweep",
        "",
        f"<!-- Written by docs/gen_results.py from {spec.relative_to(ROOT)}; do not edit: "
        "rerun the command below. -->",
        "",
        f"**Generated** by `{command}` on {now}.",
        "",
        f"- commit: `{at}` (where this page was written)",
        f"- the cells ran at: {cells_code(directory)}",
        f"- machine: {machine()}",
        f"- wall time: {wall}",
        f"- settings: `{json.dumps(settings, sort_keys=True)}`" if settings else "- settings: defaults",
    ]
    if engine:
        lines.append(f"- engine: `{json.dumps(engine, sort_keys=True)}`")
    if is_boptest_sweep(directory):
        lines += boptest_provenance(spec, directory)
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
        "no oracle; on BOPTEST its baseline's, per test period and price); mean and 95 % Student t interval over seeds, the worst seed, and the "
        "mean paired difference to the baseline (negative: better than it). Discomfort, the "
        "mean over the same seeds, in two parts: unavoidable, what the test days gave with the "
        "heater off from the same warm-up (no heating controller could avoid it), and "
        "avoidable, the rest, which the controller is judged on; not computed on BOPTEST.",
        "",
        *summary_table(summary),
        "",
    ]
    if is_boptest_sweep(directory):
        lines += _boptest_sections(spec_text, directory)
        return _relative("\n".join(lines), spec)
    lines += [
        "## Every cell",
        "",
        "Objective / the reference's of each controller on each run; the fallback column counts the "
        "decisions a planner over a learned model handed to the RC MPC, of the test days' decisions "
        "(for `cem/auto`, with the model `train`'s default chose in brackets).",
        "",
        *cell_table(
            directory,
            list(tomllib.loads(spec_text).get("controllers", [])),
            {r["scenario"]: r.get("reference", "oracle") for r in summary["rows"]},
        ),
        "",
        *zone_table(directory, list(tomllib.loads(spec_text).get("controllers", []))),
        *online_section(_cells(directory), baseline=_baseline(summary), figure_name=days_figure),
    ]
    return _relative("\n".join(lines), spec)


def _baseline(summary: dict[str, Any]) -> str:
    """The sweep's baseline (a summary of an older sweep names it in its rows only)."""
    rows = summary.get("rows") or [{}]
    return str(summary.get("baseline") or rows[0].get("baseline", ""))


def days_figure(directory: Path, target: Path) -> str | None:
    """Write the figure of the objective per day of service of the controllers run online
    beside the page ``target`` (``<page>_days.png``); its file name, None when none ran."""
    figure = target.with_name(f"{target.stem}_days.png")
    summary = json.loads((directory / "summary.json").read_text(encoding="utf-8"))
    written = plot_online_days(_cells(directory), figure, baseline=_baseline(summary))
    return None if written is None else written.name


def _relative(text: str, spec: Path) -> str:
    """``text`` with the paths of the scenario files ``spec`` names relative to the repository,
    as the committed files lie: this checkout's and another's (a sweep run from a clone records
    its own absolute paths)."""
    text = text.replace(f"{ROOT}{os.sep}", "")
    for entry in tomllib.loads(spec.read_text(encoding="utf-8")).get("scenarios", []):
        path = (spec.parent / entry).resolve()
        if path.is_file() and path.is_relative_to(ROOT):
            name = str(path.relative_to(ROOT))
            text = re.sub(rf"(?<![\w.{os.sep}]){re.escape(os.sep)}[^\s|`'\"]*?{re.escape(os.sep + name)}", name, text)
    return text


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spec", type=Path, required=True, help="a sweep definition (sweeps/*.toml)")
    parser.add_argument("--out", type=Path, help="keep the sweep's directory here (reused by a rerun)")
    parser.add_argument("--from-dir", type=Path, help="write the page from a sweep that has run")
    parser.add_argument("--page", type=Path, help="the page to write (default docs/results/<spec>.md)")
    parser.add_argument("--workers", type=int, help="the sweep's local workers (default all CPUs)")
    args = parser.parse_args()
    spec = args.spec.resolve()
    if not spec.is_file():
        parser.error(f"no sweep definition at {args.spec}")
    target = args.page or ROOT / "docs" / "results" / f"{spec.stem}.md"
    command = "python docs/gen_results.py --spec " + shlex.quote(str(spec.relative_to(ROOT)))
    if args.from_dir is not None:  # the page says so: its sweep ran before, maybe elsewhere
        command += f" --from-dir {shlex.quote(args.from_dir.name)}"
        text = page(spec, args.from_dir, command, None, commit(), days_figure(args.from_dir, target))
    else:
        with tempfile.TemporaryDirectory(prefix="gen_results_") as tmp:
            directory = args.out or Path(tmp) / spec.stem
            at, start = commit(), time.perf_counter()
            subprocess.run(
                [sys.executable, "-m", "pinn_mpc", "sweep", "--spec", str(spec), "--out", str(directory),
                 *(["--workers", str(args.workers)] if args.workers else [])],
                cwd=ROOT, check=True,
            )
            text = page(
                spec, directory, command, time.perf_counter() - start, at, days_figure(directory, target)
            )
    target.write_text(text, encoding="utf-8")
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
