"""Record the command line's outputs on a fixed set of runs, and compare two recordings.

A refactoring that must not change behaviour is checked by recording before it and after it
and comparing the two. The runs go through the CLI as subprocesses
(``python -m pinn_mpc_cli ...``), so they survive any move of modules inside the packages; the
subprocesses inherit ``PYTHONPATH``, so the checkout under test is the one on it.

Record (the directory must be new or empty; ``--resume`` continues a run of DIR that was
interrupted or had failures, keeping the commands that succeeded)::

    PYTHONPATH=$PWD nice -n 10 python benchmarks/record_outputs.py --out DIR

Compare two recordings (one line per file; exit status 1 if anything differs)::

    python benchmarks/record_outputs.py --compare DIR_A DIR_B

The runs, all with fixed seeds and the smallest sizes the CLI allows:

- on every built-in scenario: training data (``simulate``), an identified RC (``identify``), a
  small hybrid ensemble, an ARX and a physics-informed ARX (``train``), and a one-day closed
  loop of every kind of controller: thermostat, cem and random-shooting over the hybrid,
  qp-mpc and casadi-mpc on the identified RC, qp-mpc over each ARX, and oracle and clairvoyant
  where the plant has a true RC (not on EnergyPlus); KPI JSON and trajectory CSV of each;
- fleets: qp-mpc on four buildings one after another, the batched qp-mpc under a power cap in
  an evening window, and the batched cem over per-building models (``train --per-building``)
  under the same cap;
- a one-scenario sweep (qp-mpc and cem, one seed, ``--quick``, one worker);
- ``compare --quick`` (its ``table.json``);
- ``train --arch`` of every architecture (mlp, physreg, physnet, hybrid, arx, parx, auto) on the
  same data, ``evaluate`` of each on held-out test data (metrics JSON) and ``export-rc`` of the
  physics-informed networks.

Every command runs in the recording directory with relative paths, so no output holds the
directory's name. ``manifest.json`` lists each command, its exit status, its wall time and its
CPU time; the standard output and error of each are kept under ``logs/`` (read, not compared:
they hold timings). The recording exits 1 if any command failed.

The comparison covers every ``.json`` and ``.csv`` file of either recording (``logs/`` aside).
JSON values are compared exactly, CSV cells as text, except the fields listed in
``IGNORED_KEYS`` and ``IGNORED_PATHS``: what measures compute time, the versions of the package
and of Ray, and what describes the machine. ``--rtol`` compares numbers within a relative
tolerance instead (for a run on another machine; on the same machine the recordings are
identical).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import resource
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

SEED = 0
TEST_SEED = 1
TRAIN_DAYS = 7
SCENARIOS = (
    "paper_household",
    "winter_household",
    "cold_storage",
    "heat_pump_household",
    "mismatch_household",
    "eplus_small_office",
    "eplus_midrise_apartment",
)
ENERGYPLUS = ("eplus_small_office", "eplus_midrise_apartment")
# The actuator gain a model needs for the scenario (``train/identify --eta``; 1, a heater, if absent).
ETA = {"cold_storage": "-2.5"}
ARCHITECTURES = ("mlp", "physreg", "physnet", "hybrid", "arx", "parx", "auto")
# Small networks, so the recording stays short: what matters is that the same seed gives the same numbers.
SMALL = ("--seeds", "2", "--epochs", "5")
CAP = ("--cap-kw", "12", "--cap-window", "17:00-19:00")

# Fields ignored by the comparison, matched against a JSON key or a CSV column name. Two
# recordings of the same code, run at the same time on a busy machine, differed in these fields
# only (every other value of all files identical, the models' weight digests included):
# - decision times and the fleet's step times (`decision_ms_*`, `controllers_ms_*`, `plant_ms_*`,
#   `total_ms_*`, the trajectory's `decision_ms`), the time ratio, wall and training seconds
#   (`wall_time_s`, `wall_seconds`, `train_seconds`, the manifest's `seconds`): compute time;
# - `package_version`: the version, which a release may change (did not differ);
# - `host`: the machine's name in a sweep's cells (did not differ).
IGNORED_KEYS = (
    re.compile(r"(^|_)ms(_|$)"),
    re.compile(r"^time_ratio$"),
    re.compile(r"(^|_)seconds?$"),
    re.compile(r"(^|_)(wall|elapsed|duration)(_|$)"),
    re.compile(r"^package_version$"),
    re.compile(r"^host(name)?$"),
)
# Fields ignored by their place (dotted path from the top of the JSON):
# - the sweep's Ray engine: its version, and the resources Ray reports (its `memory` is what
#   the machine has free when Ray starts, so it differs from run to run on the same code);
# - `cpu_count` in compare's settings: the machine, not the code (did not differ);
# - a sweep cell's `code`: the commit that ran it, which two recordings compared differ in by
#   design.
IGNORED_PATHS = (
    re.compile(r"^engine\.(version|resources)(\.|$)"),
    re.compile(r"(^|\.)settings\.cpu_count$"),
    re.compile(r"^code$"),
)


@dataclass(frozen=True)
class Step:
    """One CLI command of a recording: its name (and log file stem) and its arguments."""

    name: str
    args: tuple[str, ...]


def _eta(scenario: str) -> tuple[str, ...]:
    return ("--eta", ETA[scenario]) if scenario in ETA else ()


def scenario_steps(scenario: str) -> Iterator[Step]:
    """Training data, models and one closed loop of every kind of controller on ``scenario``."""
    data = f"data/{scenario}.csv"
    models = f"models/{scenario}"
    yield Step(f"{scenario}-simulate", (
        "simulate", "--scenario", scenario, "--days", str(TRAIN_DAYS), "--seed", str(SEED),
        "--out", data,
    ))
    yield Step(f"{scenario}-identify", (
        "identify", "--data", data, *_eta(scenario), "--out", f"{models}/rc.json",
    ))
    yield Step(f"{scenario}-train-hybrid", (
        "train", "--data", data, "--arch", "hybrid", *SMALL, "--seed", str(SEED),
        *_eta(scenario), "--out", f"{models}/hybrid",
    ))
    for arch in ("arx", "parx"):
        yield Step(f"{scenario}-train-{arch}", (
            "train", "--data", data, "--arch", arch, *_eta(scenario), "--out", f"{models}/{arch}",
        ))
    loops: list[tuple[str, str, tuple[str, ...]]] = [
        ("thermostat", "thermostat", ()),
        ("cem", "cem", ("--model", f"{models}/hybrid")),
        ("random-shooting", "random-shooting", ("--model", f"{models}/hybrid")),
        ("qp-mpc-rc", "qp-mpc", ("--rc", f"{models}/rc.json")),
        ("casadi-mpc-rc", "casadi-mpc", ("--rc", f"{models}/rc.json")),
        ("qp-mpc-arx", "qp-mpc", ("--model", f"{models}/arx")),
        ("qp-mpc-parx", "qp-mpc", ("--model", f"{models}/parx")),
    ]
    if scenario not in ENERGYPLUS:
        loops += [("oracle", "oracle", ()), ("clairvoyant", "clairvoyant", ())]
    for name, controller, extra in loops:
        out = f"loops/{scenario}/{name}"
        yield Step(f"{scenario}-loop-{name}", (
            "closed-loop", "--scenario", scenario, "--controller", controller, *extra,
            "--days", "1", "--seed", str(TEST_SEED), "--json", f"{out}.json", "--csv", f"{out}.csv",
        ))


def fleet_steps() -> Iterator[Step]:
    """Fleets of winter_household: one after another, batched under a cap, cem over own models."""
    loop = ("closed-loop", "--scenario", "winter_household", "--days", "1", "--seed", str(TEST_SEED))
    yield Step("fleet-qp-mpc", (
        *loop, "--controller", "qp-mpc", "--buildings", "4", "--json", "fleet/qp-mpc.json",
    ))
    yield Step("fleet-qp-mpc-cap", (
        *loop, "--controller", "qp-mpc", "--buildings", "4", "--batched", *CAP,
        "--json", "fleet/qp-mpc-cap.json",
    ))
    yield Step("fleet-simulate", (
        "simulate", "--scenario", "winter_household", "--buildings", "3", "--spread", "0.2",
        "--days", str(TRAIN_DAYS), "--seed", str(SEED), "--out", "fleet/data.csv",
    ))
    yield Step("fleet-train", (
        "train", "--data", "fleet/data.csv", "--per-building", "--arch", "hybrid", *SMALL,
        "--seed", str(SEED), "--workers", "1", "--out", "fleet/models",
    ))
    yield Step("fleet-cem-cap", (
        *loop, "--controller", "cem", "--model", "fleet/models", "--buildings", "3", *CAP,
        "--json", "fleet/cem-cap.json",
    ))


def experiment_steps() -> Iterator[Step]:
    """A small sweep and the quick comparison."""
    yield Step("sweep", (
        "sweep", "--scenarios", "winter_household", "--controllers", "qp-mpc,cem",
        "--seeds", str(SEED), "--train-days", str(TRAIN_DAYS), "--days", "1", "--quick",
        "--workers", "1", "--out", "sweep",
    ))
    yield Step("compare-quick", (
        "compare", "--scenario", "winter_household", "--quick", "--seed", str(SEED),
        "--json", "compare/table.json", "--report", "compare/report.md",
    ))


def architecture_steps() -> Iterator[Step]:
    """Every architecture trained on the same data and evaluated on held-out test data."""
    data = "data/winter_household.csv"  # written by the scenario steps
    test = "data/winter_household-test.csv"
    yield Step("architectures-test-data", (
        "simulate", "--scenario", "winter_household", "--days", "3", "--seed", str(TEST_SEED + 1),
        "--weather-part", "test", "--out", test,
    ))
    for arch in ARCHITECTURES:
        model = f"architectures/{arch}"
        network = () if arch in ("arx", "parx") else (*SMALL, "--seed", str(SEED))
        yield Step(f"architectures-train-{arch}", (
            "train", "--data", data, "--arch", arch, *network, "--out", model,
        ))
        yield Step(f"architectures-evaluate-{arch}", (
            "evaluate", "--model", model, "--data", test, "--horizons", "1,6,12,24",
            "--json", f"architectures/{arch}-metrics.json",
        ))
        if arch in ("physreg", "physnet", "hybrid"):
            yield Step(f"architectures-export-rc-{arch}", (
                "export-rc", "--model", model, "--out", f"architectures/{arch}-rc.json",
            ))


def all_steps() -> list[Step]:
    """Every command of a recording, in the order they run (later ones read earlier outputs)."""
    steps: list[Step] = []
    for scenario in SCENARIOS:
        steps += scenario_steps(scenario)
    steps += fleet_steps()
    steps += experiment_steps()
    steps += architecture_steps()
    return steps


def _outputs(step: Step) -> list[Path]:
    """The files and directories a step writes (their parents are created before it runs)."""
    flags = {"--out", "--json", "--csv", "--report", "--plot"}
    return [Path(v) for f, v in zip(step.args, step.args[1:], strict=False) if f in flags]


def _remove_earlier_files(output: Path) -> None:
    """Remove what an earlier run of a step left at its output file ``output`` (a resumed
    recording reruns the step; the commands refuse to replace an existing file), and the files
    the command writes beside it (``data.fleet.json``, ``k.fleet.png``); a directory is left to
    the command, which replaces its own files there."""
    if output.is_file():
        output.unlink()
    for beside in output.parent.glob(f"{output.stem}.fleet.*"):
        beside.unlink()


def record(out: Path, resume: bool = False) -> int:
    """Run every step in ``out`` and write ``manifest.json``; 1 if a command failed.

    With ``resume``, the steps that ``out/manifest.json`` lists as succeeded with the same
    arguments are kept, and only the others run (after an interruption or a failure)."""
    done: dict[str, dict[str, Any]] = {}
    if resume and (out / "manifest.json").is_file():
        done = {
            entry["name"]: entry
            for entry in json.loads((out / "manifest.json").read_text())["steps"]
            if entry["returncode"] == 0
        }
    elif out.exists() and any(out.iterdir()):
        print(f"record_outputs: {out} is not empty; give a new directory (or --resume)",
              file=sys.stderr)
        return 2
    (out / "logs").mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    # One thread for BLAS and OpenMP, fixed hashing, no display: the same numbers every run.
    env.update(
        OMP_NUM_THREADS="1", MKL_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
        PYTHONHASHSEED="0", MPLBACKEND="Agg",
    )
    # The commands run in ``out``: a relative PYTHONPATH would silently pick another checkout.
    paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    env["PYTHONPATH"] = os.pathsep.join(str(Path(p).resolve()) for p in paths)
    where = subprocess.run(
        [sys.executable, "-c", "import pinn_mpc_cli; print(pinn_mpc_cli.__file__)"],
        cwd=out, env=env, capture_output=True, text=True, check=False,
    ).stdout.strip()
    print(f"recording the CLI of {where or '(not importable)'}", flush=True)
    manifest: list[dict[str, Any]] = []
    failed: list[str] = []
    steps = all_steps()
    for i, step in enumerate(steps, 1):
        kept = done.get(step.name)
        if kept is not None and kept["args"] == list(step.args):
            manifest.append(kept)
            print(f"[{i}/{len(steps)}] {step.name}: kept from the earlier run", flush=True)
            continue
        for path in _outputs(step):
            (out / path).parent.mkdir(parents=True, exist_ok=True)
            _remove_earlier_files(out / path)
        argv = [sys.executable, "-m", "pinn_mpc_cli", *step.args]
        t0, cpu0 = time.perf_counter(), _children_cpu_s()
        with (out / "logs" / f"{step.name}.stdout").open("w") as so, \
                (out / "logs" / f"{step.name}.stderr").open("w") as se:
            rc = subprocess.run(argv, cwd=out, env=env, stdout=so, stderr=se, check=False).returncode
        seconds = time.perf_counter() - t0
        manifest.append({"name": step.name, "args": list(step.args), "returncode": rc,
                         "seconds": round(seconds, 2),
                         "cpu_seconds": round(_children_cpu_s() - cpu0, 2)})
        status = "ok" if rc == 0 else f"FAILED (exit {rc}, see logs/{step.name}.stderr)"
        print(f"[{i}/{len(steps)}] {step.name}: {status} in {seconds:.1f} s", flush=True)
        if rc != 0:
            failed.append(step.name)
        _write_manifest(out, manifest)
    total = _write_manifest(out, manifest)
    cpu = sum(entry.get("cpu_seconds", 0.0) for entry in manifest)
    print(f"recorded {len(steps)} commands into {out}: {total / 60:.1f} min of commands' wall "
          f"time, {cpu / 60:.1f} min of their CPU time; "
          f"{len(failed)} failed{': ' + ', '.join(failed) if failed else ''}")
    return 1 if failed else 0


def _children_cpu_s() -> float:
    """CPU seconds (user and system) of the finished child processes (Ray's workers not counted)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _write_manifest(out: Path, manifest: list[dict[str, Any]]) -> float:
    """Write the steps so far (after each, so that ``--resume`` can continue); their seconds."""
    total = round(sum(entry["seconds"] for entry in manifest), 1)
    tmp = out / "manifest.json.tmp"
    tmp.write_text(json.dumps({"steps": manifest, "total_seconds": total}, indent=1) + "\n")
    tmp.replace(out / "manifest.json")
    return total


def _ignored(path: str, key: str) -> bool:
    return any(p.search(key) for p in IGNORED_KEYS) or any(p.search(path) for p in IGNORED_PATHS)


def _same_number(a: float, b: float, rtol: float) -> bool:
    if math.isnan(a) and math.isnan(b):
        return True
    return a == b or (rtol > 0 and math.isclose(a, b, rel_tol=rtol))


def diff_json(a: Any, b: Any, rtol: float, path: str = "") -> Iterator[tuple[str, Any, Any]]:
    """Yield ``(path, value_a, value_b)`` for every difference, ignored fields skipped."""
    if isinstance(a, dict) and isinstance(b, dict):
        for key in sorted(set(a) | set(b), key=str):
            sub = f"{path}.{key}" if path else str(key)
            if _ignored(sub, str(key)):
                continue
            yield from diff_json(a.get(key, "<absent>"), b.get(key, "<absent>"), rtol, sub)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            yield f"{path} (length)", len(a), len(b)
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            yield from diff_json(x, y, rtol, f"{path}[{i}]")
    elif (isinstance(a, (int, float)) and isinstance(b, (int, float))
          and not isinstance(a, bool) and not isinstance(b, bool)):
        if not _same_number(float(a), float(b), rtol):
            yield path, a, b
    elif a != b or type(a) is not type(b):
        yield path, a, b


def _cell(a: str, b: str, rtol: float) -> bool:
    if a == b:
        return True
    try:
        return _same_number(float(a), float(b), rtol)
    except ValueError:
        return False


def diff_csv(a: Path, b: Path, rtol: float) -> Iterator[tuple[str, Any, Any]]:
    """Yield ``(row:column, value_a, value_b)`` for every differing cell, ignored columns skipped."""
    with a.open(newline="") as fa, b.open(newline="") as fb:
        ra, rb = list(csv.reader(fa)), list(csv.reader(fb))
    if not ra or not rb:
        if ra != rb:
            yield "(empty)", len(ra), len(rb)
        return
    if ra[0] != rb[0]:
        yield "header", ra[0], rb[0]
        return
    if len(ra) != len(rb):
        yield "rows", len(ra) - 1, len(rb) - 1
    keep = [i for i, name in enumerate(ra[0]) if not _ignored(name, name)]
    for r, (x, y) in enumerate(zip(ra[1:], rb[1:], strict=False), 1):
        for i in keep:
            if i >= len(x) or i >= len(y):
                if len(x) != len(y):
                    yield f"row {r} (length)", len(x), len(y)
                break
            if not _cell(x[i], y[i], rtol):
                yield f"row {r}:{ra[0][i]}", x[i], y[i]


def _files(root: Path) -> set[str]:
    return {
        p.relative_to(root).as_posix()
        for p in root.rglob("*")
        if p.is_file() and p.suffix in (".json", ".csv") and p.relative_to(root).parts[0] != "logs"
    }


def compare(dir_a: Path, dir_b: Path, rtol: float, shown: int = 3) -> int:
    """Print one line per file (identical / differs with the first differences); 1 if any differ."""
    for d in (dir_a, dir_b):
        if not d.is_dir():
            print(f"record_outputs: {d} is not a directory", file=sys.stderr)
            return 2
    fa, fb = _files(dir_a), _files(dir_b)
    n_diff = 0
    for name in sorted(fa | fb):
        if name not in fa or name not in fb:
            print(f"{name}: only in {dir_a if name in fa else dir_b}")
            n_diff += 1
            continue
        a, b = dir_a / name, dir_b / name
        if name.endswith(".json"):
            try:
                diffs = list(diff_json(json.loads(a.read_text()), json.loads(b.read_text()), rtol))
            except json.JSONDecodeError as exc:
                diffs = [("(not JSON)", str(exc), "")]
        else:
            diffs = list(diff_csv(a, b, rtol))
        if not diffs:
            print(f"{name}: identical")
            continue
        n_diff += 1
        first = "; ".join(f"{p}: {va!r} != {vb!r}" for p, va, vb in diffs[:shown])
        more = f" (+{len(diffs) - shown} more)" if len(diffs) > shown else ""
        print(f"{name}: differs ({len(diffs)}): {first}{more}")
    print(f"{len(fa | fb)} files, {n_diff} differ")
    return 1 if n_diff else 0


def main(argv: list[str] | None = None) -> int:
    """Parse the command line and record or compare."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--out", type=Path, help="record into this (new or empty) directory")
    mode.add_argument("--compare", nargs=2, type=Path, metavar=("DIR_A", "DIR_B"),
                      help="compare two recordings")
    parser.add_argument("--resume", action="store_true",
                        help="with --out: keep the steps an earlier run of DIR finished, run the rest")
    parser.add_argument("--rtol", type=float, default=0.0,
                        help="relative tolerance of numbers in --compare (default 0: exact)")
    a = parser.parse_args(argv)
    if a.compare:
        return compare(a.compare[0], a.compare[1], a.rtol)
    return record(a.out, resume=a.resume)


if __name__ == "__main__":
    sys.exit(main())
