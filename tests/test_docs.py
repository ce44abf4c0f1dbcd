"""The documentation: the site builds with ``mkdocs build --strict``, its API reference names
every public name, its code blocks run (Python) or parse (the `pinn-mpc` commands against the
CLI's parser, TOML with tomllib), the walkthrough "your building from your data" and the
commands of getting-started, realistic-conditions, sweeps-and-fleets and BOPTEST (the README's
included) run as written, sizes shrunk, and the results generator writes what it says."""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import json
import os
import re
import shlex
import subprocess
import sys
import tomllib
from collections import Counter
from functools import cache
from pathlib import Path
from typing import cast

import pytest

from pinn_mpc_cli.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PACKAGES = ("pinn_mpc", "controllers", "scenarios")
README = ROOT / "README.md"
PAGES = sorted(DOCS.rglob("*.md"))
#: The README's Python block runs in test_public_api (which checks its output too).
README_EXAMPLE_HEADING = "## Python API"
FENCE = re.compile(r"^```([a-z]*)\n(.*?)^```$", re.S | re.M)


SNIPPET = re.compile(r'^--8<-- "([^":]+)"$', re.M)


def blocks(path: Path, lang: str) -> list[str]:
    """The fenced code blocks of ``path`` in language ``lang`` ("" for unlabelled ones), with
    included files (``--8<-- "path"``) in place, as the site shows them."""
    return [
        SNIPPET.sub(lambda m: (ROOT / m.group(1)).read_text(encoding="utf-8"), body)
        for tag, body in FENCE.findall(path.read_text(encoding="utf-8"))
        if tag == lang
    ]


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}


def test_readme_is_short() -> None:
    assert len(README.read_text(encoding="utf-8").splitlines()) <= 200


@cache
def _site(directory: str) -> Path:
    site = Path(directory) / "site"
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
        env={**_env(), "NO_MKDOCS_2_WARNING": "1"},
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-5000:]
    return site


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _site(str(tmp_path_factory.mktemp("docs")))


def test_mkdocs_build_strict(site: Path) -> None:
    for page in ("index", "getting-started/index", "your-building/index", "results/smoke/index"):
        assert (site / f"{page}.html").exists(), page


@pytest.mark.parametrize("package", PACKAGES)
def test_api_reference_names_every_public_name(site: Path, package: str) -> None:
    html = (site / "api" / package / "index.html").read_text(encoding="utf-8")
    pkg = importlib.import_module(package)
    for module, names in pkg._EXPORTS.items():
        for name in names:
            assert f'id="{module}.{name}"' in html, f"{package}.{name} not in the API reference"
    missing = [n for n in pkg.__all__ if n not in html]
    assert not missing, f"not in the built API reference of {package}: {missing}"


def test_api_pages_are_current() -> None:
    result = subprocess.run(
        [sys.executable, str(DOCS / "gen_api.py"), "--check"], capture_output=True, text=True,
        env=_env(),
    )
    assert result.returncode == 0, result.stderr


def _python_blocks() -> dict[str, tuple[str, str]]:
    """Every distinct Python block of the README and the docs: {id: (where, code)}."""
    readme_example = FENCE.search(
        README.read_text(encoding="utf-8").split(README_EXAMPLE_HEADING, 1)[1]
    )
    assert readme_example, "the README's Python example is missing"
    skip = {readme_example.group(2)}
    found: dict[str, tuple[str, str]] = {}
    for path in (README, *PAGES):
        for i, code in enumerate(blocks(path, "python")):
            if code in skip or any(code == c for _, c in found.values()):
                continue
            found[f"{path.relative_to(ROOT)}#{i}"] = (str(path), code)
    return found


@pytest.mark.parametrize("block", sorted(_python_blocks()))
def test_python_blocks_run(block: str, tmp_path: Path) -> None:
    _, code = _python_blocks()[block]
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
        env=_env(), timeout=600,
    )
    assert result.returncode == 0, result.stderr[-3000:]


def _commands(code: str) -> list[list[str]]:
    """The simple commands of a shell block (comments dropped, split at && ; |)."""
    commands = []
    for line in code.splitlines():
        words = shlex.split(line, comments=True)
        command: list[str] = []
        for word in [*words, "&&"]:
            if word in ("&&", ";", "||", "|"):
                if command:
                    commands.append(command)
                command = []
            else:
                command.append(word)
    return commands


def _shell_blocks() -> list[tuple[str, str]]:
    return [
        (f"{path.relative_to(ROOT)}", code)
        for path in (README, *PAGES)
        for lang in ("bash", "")
        for code in blocks(path, lang)
    ]


def test_shell_blocks_use_real_commands_and_files() -> None:
    """Every `pinn-mpc ...` command shown parses with the CLI's parser; every script exists."""
    parser = build_parser()
    checked = 0
    for where, code in _shell_blocks():
        for command in _commands(code):
            if command[0] == "pinn-mpc":
                try:
                    parser.parse_args(command[1:])
                except SystemExit as exc:
                    pytest.fail(f"{where}: `{shlex.join(command)}` does not parse ({exc})")
                checked += 1
            elif command[0] == "python" and command[1].endswith(".py"):
                assert (ROOT / command[1]).is_file(), f"{where}: no script {command[1]}"
    assert checked >= 20


def test_toml_blocks_parse() -> None:
    for path in (README, *PAGES):
        for code in blocks(path, "toml"):
            tomllib.loads(code)


def test_walkthrough_commands_are_its_steps() -> None:
    """The walkthrough shows identify, train, evaluate, a scenario file, closed loops and
    compare, in that order."""
    page = DOCS / "your-building.md"
    order = [c[1] for code in blocks(page, "bash") for c in _commands(code) if c[0] == "pinn-mpc"]
    firsts = [order.index(step) for step in ("identify", "train", "evaluate", "scenario",
                                             "closed-loop", "compare")]
    assert firsts == sorted(firsts)
    assert len(blocks(page, "toml")) == 1


@pytest.mark.slow
def test_walkthrough_runs_as_written(tmp_path: Path) -> None:
    """"Your building from your data", from an empty directory: the Python block, the TOML file
    and every command, as the page gives them but for compare's sizes (:data:`SIZES`: it trains
    every family on 14 days and runs 1 test day); compare runs on the scenario file whose
    building is the identified RC."""
    page = DOCS / "your-building.md"
    env = {**_env(), "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    workdir = tmp_path
    for tag, code in FENCE.findall(page.read_text(encoding="utf-8")):
        if tag == "python":
            (workdir / "prep.py").write_text(code, encoding="utf-8")
            command = [sys.executable, "prep.py"]
            result = subprocess.run(command, cwd=workdir, env=env, capture_output=True, text=True)
            assert result.returncode == 0, result.stderr[-3000:]
        elif tag == "toml":
            name = re.search(r'^name = "(.*)"', code, re.M)
            assert name
            (workdir / f"{name.group(1)}.toml").write_text(code, encoding="utf-8")
        elif tag == "bash":
            for command in _commands(code):
                if command[0] == "mkdir":
                    (workdir / command[1]).mkdir()
                elif command[0] == "cd":
                    workdir = workdir / command[1]
                else:
                    assert command[0] == "pinn-mpc", command
                    if command[1] == "compare":
                        command = _shrunk(WALKTHROUGH, command)
                    result = subprocess.run(
                        [sys.executable, "-m", "pinn_mpc", *command[1:]], cwd=workdir, env=env,
                        capture_output=True, text=True, timeout=900,
                    )
                    assert result.returncode == 0, f"{shlex.join(command)}: {result.stderr[-3000:]}"
    kpis = {c: json.loads((workdir / f"{c}.json").read_text()) for c in ("thermostat", "cem", "oracle")}
    # What the page says: cem near the oracle, the thermostat well above.
    assert kpis["cem"]["objective"] < 1.02 * kpis["oracle"]["objective"]
    assert kpis["thermostat"]["objective"] > 1.3 * kpis["oracle"]["objective"]
    assert (workdir / "compare" / "report.md").exists()
    table = json.loads((workdir / "compare" / "table.json").read_text())
    assert table["scenario"] == "my_building"
    assert {"oracle", "qp-mpc / identified RC"} <= {row["controller"] for row in table["rows"]}


#: The pages whose commands run as written (test_pages_run_as_written); "your building" has its
#: own test (test_walkthrough_runs_as_written).
RUN_AS_WRITTEN = ("README.md", "docs/getting-started.md", "docs/realistic-conditions.md",
                  "docs/sweeps-and-fleets.md", "docs/boptest.md", "docs/zones.md")
REALISTIC = "docs/realistic-conditions.md"
WALKTHROUGH = "docs/your-building.md"
#: The sizes a run as written shrinks: {(page, command, option): value}, "*" for any page or
#: command, the most specific entry first. No other word of a command changes.
SIZES: dict[tuple[str, str, str], str] = {
    ("*", "*", "--days"): "1",  # test days of closed-loop and compare
    ("*", "simulate", "--days"): "2",  # data to train on (one day is fewer rows than a model's depth)
    (REALISTIC, "simulate", "--days"): "7",  # the office: identify refuses 3 to 5 days of it, the ARX 2
    ("*", "compare", "--train-days"): "2",
    (REALISTIC, "compare", "--train-days"): "7",
    ("docs/boptest.md", "compare", "--train-days"): "4",  # its ARX families need 4 days' lags
    (WALKTHROUGH, "compare", "--train-days"): "14",  # the walkthrough's compare (its other commands as written)
    ("*", "*", "--buildings"): "3",
    ("*", "sweep", "--seeds"): "0",
}
#: Size options added to a command that does not give them (a sweep's sizes come from --spec):
#: {(page, command): options}, "*" for any page, the most specific entry first.
_SWEEP_SIZES = [("--quick",), ("--days", "1"), ("--seeds", "0"), ("--train-days", "2")]
ADDED_SIZES: dict[tuple[str, str], list[tuple[str, ...]]] = {
    # a BOPTEST sweep: one test period and one price (its grid's other axes)
    ("docs/boptest.md", "sweep"): [
        *_SWEEP_SIZES, ("--test-periods", "peak_heat_day"), ("--price-scenarios", "dynamic"),
    ],
    # the EnergyPlus sweep: cem over the default model only (the grid's other archs are
    # cem over named models, which test_sweep's arch-cell test runs), on the office alone
    ("docs/realistic-conditions.md", "sweep"): [
        *_SWEEP_SIZES, ("--archs", "auto"), ("--scenarios", "eplus_small_office"),
    ],
    # the robustness sweep on two of its five scenarios: a resistive heater and the heat pump
    # (the table script reads whichever cells the directory holds)
    ("docs/sweeps-and-fleets.md", "sweep"): [
        *_SWEEP_SIZES, ("--scenarios", "winter_household,heat_pump_household"),
    ],
    ("*", "sweep"): _SWEEP_SIZES,
    # compare trains every family: compare's small ensembles and short training
    ("*", "compare"): [("--quick",)],
}
#: Commands not run, by how their line starts, each with the reason.
NOT_RUN = {
    "pip ": "installs the package (the tests run the checkout)",
    "python -m pip ": "installs the package (the tests run the checkout)",
    "python -m venv ": "creates the virtual environment of an installation",
    ". .venv/bin/activate": "activates the virtual environment of an installation",
    "mkdocs serve": "serves the site until stopped (test_mkdocs_build_strict builds it)",
    "mkdocs build --strict": "test_mkdocs_build_strict runs it",
    "python -m pytest": "the test suite itself",
    "'BOPTEST_HOME=": "starts a local BOPTEST server (the tests take the boptest_server fixture's)",
    "export BOPTEST_URL=": "names a user's BOPTEST server (each command here gets the "
    "boptest_server fixture's in BOPTEST_URL)",
    "BOPTEST_URL=": "the test suite itself, given a BOPTEST server",
    "python examples/": "tests/test_examples.py runs the examples",
    "python docs/gen_results.py": "writes the committed results page (the results-page tests "
    "write pages of a small and of a BOPTEST sweep)",
    "python benchmarks/boptest_least_discomfort.py": "a measurement of 11 minutes whose figures "
    "the page quotes (tests/test_least_discomfort.py checks its model and programme)",
    "nice -n 10 pinn-mpc sweep --spec sweeps/online_households.toml": "a measurement of "
    "about an hour on one worker whose figures docs/results/online_households.md gives "
    "(tests/test_sweep_online.py runs online cells on winter_household)",
    "nice -n 10 pinn-mpc sweep --spec sweeps/online_eplus.toml": "a measurement of about 25 "
    "minutes on one worker on EnergyPlus whose figures docs/results/online_eplus.md gives "
    "(tests/test_online_eplus.py runs the online runner on EnergyPlus and resumes it)",
    "PYTHONPATH=. python benchmarks/bench_online_decisions.py": "a measurement of a few minutes "
    "whose figures the CHANGELOG gives (tests/test_online.py runs the online runner and its refits)",
    "PYTHONPATH=. python benchmarks/online_morning_error.py": "a measurement of a few minutes on "
    "EnergyPlus beside a sweep's model, whose figures the page quotes "
    "(tests/test_online_morning_error.py runs the script on heat_pump_household)",
    "PYTHONPATH=. python benchmarks/merged_vs_zones.py": "a measurement of most of an hour on "
    "EnergyPlus whose figures the page quotes (tests/test_merged.py runs the script on two_zone_house)",
}
#: Commands a page shares with another page that runs them: {(page, command): the other page}.
RUN_ON_ANOTHER_PAGE = {
    ("README.md", "pinn-mpc compare --scenario winter_household --quick"): "docs/getting-started.md",
}
#: The options that name a command's outputs.
OUTPUTS = ("--out", "--json", "--report", "--csv", "--plot")
#: Pages whose commands run as several tests, so that the suite's workers share them: {page:
#: {part: its selectors}}. A selector is a section (a "## " heading of the page, "" the text
#: before the first) or, written "$ " and the start of a command line, the commands that start so
#: wherever they are; a command a "$ " selector names belongs to that selector's part only. A part
#: runs its commands in the page's order from an empty directory of its own: no part reads what
#: another writes, and the parts together hold every command of the page that runs, each once.
PARTS: dict[str, dict[str, tuple[str, ...]]] = {
    "docs/boptest.md": {
        # one part: _boptest_page_outputs compares the MPC on the identified RC with the thermostat
        "closed-loops": ("Closed loops", "Training data from the emulator"),
        "compare": ("A comparison",),
        "sweep": ("Sweeps",),
    },
    REALISTIC: {
        # the user's path: a scenario file, then the office's data, models, evaluation and loops
        "user-path": ("", "EnergyPlus buildings"),
        "compare": ("$ pinn-mpc compare ",),
        "sweep": ("$ pinn-mpc sweep ",),
    },
    "docs/sweeps-and-fleets.md": {
        "sweep": ("$ pinn-mpc sweep --scenarios ",),
        "robustness": ("$ pinn-mpc sweep --spec sweeps/robustness.toml", "$ python benchmarks/robustness_table.py"),
        "fleets": ("Fleets: many buildings",),
    },
    "docs/zones.md": {
        "shoulder-office": ("",),
        "two-zone-house": ("Data and identification", "Fleets of buildings of several zones"),
        "compare": ("$ pinn-mpc compare ",),
    },
}
#: Commands a page repeats word for word, each run once: at the repeat, the files the first run
#: wrote and the files it names are as that run left them, so the repeat (the same command on the
#: same files) would write what is there already. {page: command lines}.
REPEATED: dict[str, tuple[str, ...]] = {
    REALISTIC: (  # its last example trains the office's default model again, for cem's seed 1
        "pinn-mpc train --data train.csv --out model",
    ),
}


def _not_run(page: str, command: list[str]) -> str | None:
    """Why ``command`` of ``page`` is not run by test_pages_run_as_written (None: it is)."""
    line = shlex.join(command)
    if (page, line) in RUN_ON_ANOTHER_PAGE:
        return f"run on {RUN_ON_ANOTHER_PAGE[page, line]}"
    return next((why for start, why in NOT_RUN.items() if line.startswith(start)), None)


def _shrunk(page: str, command: list[str]) -> list[str]:
    """``command`` (``pinn-mpc NAME ...``) of ``page`` with the sizes of :data:`SIZES` and
    :data:`ADDED_SIZES`."""
    name, out = command[1], list(command)
    for i in range(2, len(out) - 1):
        for key in ((page, name, out[i]), ("*", name, out[i]), ("*", "*", out[i])):
            if key in SIZES:
                out[i + 1] = SIZES[key]
                break
    added = ADDED_SIZES.get((page, name), ADDED_SIZES.get(("*", name), []))
    return out + [w for option in added if option[0] not in out for w in option]


def _sections(text: str) -> dict[str, str]:
    """A page's text by its "## " headings ("" for what comes before the first)."""
    pieces = re.split(r"^## (.*)\n", text, flags=re.M)
    return {"": pieces[0], **dict(zip(pieces[1::2], pieces[2::2], strict=True))}


def _page_commands(page: str, part: str | None = None) -> list[list[str]]:
    """The commands of ``page``'s shell blocks (``bash`` and unlabelled), in the page's order;
    of its ``part`` (:data:`PARTS`) only, if one is given."""
    text = (ROOT / page).read_text(encoding="utf-8")
    sections = _sections(text) if part is not None else {"": text}
    out = []
    for heading, body in sections.items():
        for command in (c for tag, code in FENCE.findall(body) if tag in ("bash", "") for c in _commands(code)):
            if part is None or _part_of(page, heading, shlex.join(command)) == part:
                out.append(command)
    return out


def _part_of(page: str, heading: str, line: str) -> str | None:
    """The part (:data:`PARTS`) of ``page`` that runs the command ``line`` of section
    ``heading``: the part of a "$ " selector it starts with, else of its section."""
    parts = PARTS[page]
    by_start = [p for p, selectors in parts.items() for s in selectors if s.startswith("$ ") and line.startswith(s[2:])]
    if by_start:
        return by_start[0]
    return next((p for p, selectors in parts.items() if heading in selectors), None)


def _runs_as_written() -> list[tuple[str, str | None]]:
    """(page, part) of each test_pages_run_as_written: a page of :data:`PARTS` in its parts, any
    other whole (part None). The README's only command runs on getting-started."""
    return [
        (page, part)
        for page in RUN_AS_WRITTEN[1:]
        for part in (PARTS[page] if page in PARTS else [None])
    ]


def test_every_command_of_the_pages_run_as_written_is_run_or_says_why() -> None:
    """Each command of those pages is a `pinn-mpc` command or a script of benchmarks/ (run), or
    listed with the reason it is not run; the parts of a page hold each command that runs once
    (in the page's order), each selector naming a section or a command of the page; a repeated
    command is repeated in one part; the size tables shrink what they name."""
    for page in RUN_AS_WRITTEN:
        for command in _page_commands(page):
            if _not_run(page, command) is None:
                assert command[0] == "pinn-mpc" or (
                    command[0] == "python" and command[1].startswith("benchmarks/")
                ), f"{page}: `{shlex.join(command)}` is neither run nor listed in NOT_RUN"
    for page, parts in PARTS.items():
        sections = _sections((ROOT / page).read_text(encoding="utf-8"))
        run = [shlex.join(c) for c in _page_commands(page) if _not_run(page, c) is None]
        for selector in (s for part in parts.values() for s in part):
            assert (selector in sections) if not selector.startswith("$ ") else any(
                line.startswith(selector[2:]) for line in run), f"{page}: no {selector!r}"
        in_parts = {
            part: [shlex.join(c) for c in _page_commands(page, part) if _not_run(page, c) is None]
            for part in parts
        }
        assert Counter(line for lines in in_parts.values() for line in lines) == Counter(run), (
            f"{page}: its parts do not hold each command that runs once")
        for lines in in_parts.values():
            assert lines == [line for line in run if line in lines], f"{page}: not in the page's order"
    for page, repeated in REPEATED.items():
        for line in repeated:
            holding = [part for part in PARTS.get(page, {None: ()})
                       if [shlex.join(c) for c in _page_commands(page, part)].count(line) >= 2]
            assert len(holding) == 1, f"{page}: `{line}` is not repeated within one part"
    assert _shrunk(REALISTIC, ["pinn-mpc", "simulate", "--days", "30", "--out", "t.csv"])[3] == "7"
    assert _shrunk("README.md", ["pinn-mpc", "sweep", "--seeds", "0-7", "--out", "s"]) == [
        "pinn-mpc", "sweep", "--seeds", "0", "--out", "s", "--quick", "--days", "1", "--train-days", "2"]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("page", "part"),
    [pytest.param(page, part, id=page if part is None else f"{page}#{part}")
     for page, part in _runs_as_written()],
)
def test_pages_run_as_written(
    page: str, part: str | None, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    """Every command of the page's shell blocks (of its part, for a page of ``PARTS``: e.g.
    BOPTEST's closed loops with its training data, its comparison, its sweep, each a test of
    its own), in order, from an empty directory (with the
    checkout's ``sweeps/`` and ``benchmarks/``, which the pages name, linked in), exactly as
    written but for the sizes, each shrunk to the smallest the command and the page's later
    commands accept, through these tables alone (and nothing else):

    - ``SIZES`` {(page, command, option): value}: ``--days`` 1 (closed-loop, compare);
      ``simulate --days`` 2, on realistic-conditions 7 (EnergyPlus's office: identify refuses
      3 to 5 days of it, the ARX 2); ``compare --train-days`` 2, on realistic-conditions 7, on
      BOPTEST 4 (its compare fits the ARX families, whose lags 2 days do not fill);
      ``--buildings`` 3; ``sweep --seeds`` 0;
    - ``ADDED_SIZES``: ``sweep`` gets ``--quick --days 1 --seeds 0 --train-days 2`` where the
      line does not give them (over its ``--spec``'s sizes), on the BOPTEST page also one test
      period and one price (``--test-periods peak_heat_day --price-scenarios dynamic``), on
      realistic-conditions (the EnergyPlus sweep) the default model only (``--archs auto``), and
      the BOPTEST ``compare`` gets ``--quick`` (small ensembles, short training of every family);
    - ``NOT_RUN`` and ``RUN_ON_ANOTHER_PAGE``: the commands not run, each with its reason;
    - ``REPEATED``: a command the page repeats word for word is not run again when the files
      its first run wrote and the files it names are as that run left them (else it runs
      again).

    Each command must exit 0 and leave the outputs it names (``--out``, ``--json``,
    ``--report``, ``--csv``, ``--plot``). The BOPTEST page runs against the session's server,
    and its outputs are checked further (:func:`_boptest_page_outputs`)."""
    env = {**_env(), "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    if page == "docs/boptest.md":
        env["BOPTEST_URL"] = request.getfixturevalue("boptest_server").url
    for linked in ("sweeps", "benchmarks"):
        (tmp_path / linked).symlink_to(ROOT / linked)
    ran = 0
    printed: dict[str, str] = {}  # each command's standard output
    left: dict[str, dict[str, str]] = {}  # a repeated command: the files as its first run left them
    for command in _page_commands(page, part):
        if _not_run(page, command) is not None:
            continue
        line = shlex.join(command)
        if line in left and _files(tmp_path, left[line]) == left[line]:
            continue
        run = _shrunk(page, command) if command[0] == "pinn-mpc" else command
        argv = [sys.executable, "-m", "pinn_mpc", *run[1:]] if run[0] == "pinn-mpc" else [sys.executable, *run[1:]]
        before = _files(tmp_path) if line in REPEATED.get(page, ()) else {}
        result = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
        assert result.returncode == 0, f"{page}: `{shlex.join(run)}`: {result.stderr[-3000:]}"
        printed[line] = result.stdout
        for option, value in zip(run, run[1:], strict=False):
            if option in OUTPUTS:
                assert (tmp_path / value).exists(), f"{page}: `{shlex.join(run)}` wrote no {value}"
        if line in REPEATED.get(page, ()):  # what it wrote and the files it names
            after = _files(tmp_path)
            left[line] = {name: digest for name, digest in after.items() if before.get(name) != digest
                          or any(name == word or name.startswith(f"{word}/") for word in run)}
        ran += 1
    assert ran > 0
    if page == "docs/boptest.md":
        _boptest_page_outputs(tmp_path, part)
    if page == REALISTIC:
        _energyplus_page_outputs(tmp_path, part, printed)
    if page == "docs/zones.md" and part == "compare":
        _zones_compare_outputs(tmp_path / "house_compare")


def _zones_compare_outputs(out: Path) -> None:
    """What the zones page says of ``compare`` on the two-zone house (two training days and
    one test day, as the page's sizes shrink): every controller it names, each row with each
    zone's discomfort; the RC identified from the data within 15 % of the plant's (each R, C
    and the wall: the house's scenario file gives them), the paper networks' learned RCs
    beside it; each model's error per zone; the ARX, which two days cannot fit, left out with
    the reason in the notes."""
    table = json.loads((out / "table.json").read_text())
    rows = {r["controller"]: r for r in table["rows"]}
    default = next(c for c in rows if c.startswith("cem / default ("))
    family = default.removeprefix("cem / default (").removesuffix(")")
    assert family == "hybrid"  # the ARX cannot be fitted on two days
    expected = {"thermostat", f"random-shooting / default ({family})", default, "cem / physnet", "cem / physreg",
                "casadi-mpc / identified RC", "qp-mpc / identified RC", "qp-mpc / physnet RC",
                "qp-mpc / physreg RC", "oracle"}
    assert set(rows) == expected, sorted(rows)
    for row in rows.values():
        assert set(row["zones"]) == {"south", "north"}
        assert row["objective_to_oracle"] == pytest.approx(row["objective"] / rows["oracle"]["objective"])
    assert rows[default]["objective"] < rows["thermostat"]["objective"]
    assert table["rc"] == {} and set(table["zone_rc"]) == {"true", "identified", "physnet learned", "physreg learned"}
    true, identified = table["zone_rc"]["true"], table["zone_rc"]["identified"]
    assert true["walls"] == {"south-north": pytest.approx(40.0)}
    assert identified["walls"]["south-north"] == pytest.approx(40.0, rel=0.15)
    for zone, values in true["zones"].items():
        for key, value in values.items():
            assert identified["zones"][zone][key] == pytest.approx(value, rel=0.15), (zone, key)
    models = {r["model"]: r for r in table["prediction"]}
    assert set(models) == {"hybrid", "physnet", "physreg", "identified RC", "physnet RC", "physreg RC", "true RC"}
    assert all(set(r["T_r_mae_by_zone_c"]) == {"south", "north"} for r in models.values())
    assert models["true RC"]["kind"] == "RC" and models["true RC"]["T_r_mae_c"] < 0.1  # the plant itself
    assert models["hybrid"]["T_r_mae_c"] < 0.1  # the identified RC and its residual
    report = (out / "report.md").read_text()
    assert "## Zones" in report and "wall south-north U [W/K]" in report
    assert "parx is not compared: multi-zone ARX: 96 rows are too few" in report
    assert (out / "report.png").is_file()


def _energyplus_page_outputs(workdir: Path, part: str | None, printed: dict[str, str]) -> None:
    """What realistic-conditions says of ``compare`` and ``sweep`` on EnergyPlus: no oracle
    (nor clairvoyant) exists there, every controller is measured against the thermostat
    (``/ thermostat`` in the tables, ``objective_to_thermostat`` in the JSON), and the prediction
    table gives the ARX baseline's error 1, 6, 24 and 48 steps ahead beside the learned models."""
    if part == "compare":
        table = json.loads((workdir / "t.json").read_text())
        rows = {r["controller"]: r for r in table["rows"]}
        assert "oracle" not in rows and "clairvoyant" not in rows
        assert rows["thermostat"]["objective_to_thermostat"] == pytest.approx(1.0)
        assert all("objective_to_oracle" not in r for r in rows.values())
        assert "true" not in table["rc"]
        prediction = {r["model"]: r for r in table["prediction"]}
        assert {"ARX", "hybrid"} <= set(prediction) and "true RC" not in prediction
        assert set(prediction["ARX"]["T_r_mae_by_horizon_c"]) == {"1", "6", "24", "48"}
        assert "/ thermostat" in (workdir / "r.md").read_text()
    elif part == "sweep":
        summary = json.loads((workdir / "eplus" / "summary.json").read_text())
        assert {r["controller"] for r in summary["rows"]} == {"cem/auto", "qp-mpc", "thermostat"}
        assert all(r["reference"] == "thermostat" for r in summary["rows"])
        assert all(r["objective_to_thermostat_mean"] == pytest.approx(1.0)
                   for r in summary["rows"] if r["controller"] == "thermostat")
        [sweep] = [out for line, out in printed.items() if line.startswith("pinn-mpc sweep ")]
        assert "objective/thermostat" in sweep


def _files(directory: Path, only: dict[str, str] | None = None) -> dict[str, str]:
    """{path relative to ``directory``: sha256} of its files (of those of ``only`` that still
    exist, if given), not following its symbolic links."""
    found = {}
    for path in sorted(directory.rglob("*")):
        name = path.relative_to(directory).as_posix()
        if path.is_file() and not path.is_symlink() and (only is None or name in only):
            found[name] = hashlib.sha256(path.read_bytes()).hexdigest()
    return found


def _boptest_page_outputs(workdir: Path, part: str | None) -> None:
    """The outputs of the BOPTEST page's ``part`` (:data:`PARTS`). Closed loops and training
    data: the data are the emulator's, off the test periods, and the closed loops' KPI JSON
    carries BOPTEST's KPI dict, which agrees with the package's KPIs of the run. The comparison:
    a row with BOPTEST's KPIs for each controller the page names, on data off the test period.
    The sweep: its four cells, each with BOPTEST's KPIs."""
    if part == "compare":
        assert (workdir / "boptest" / "report.md").is_file()
        table = json.loads((workdir / "boptest" / "table.json").read_text())
        assert table["data_days"] == ["2018-01-31", "2018-02-03"]
        families = ("hybrid", "physnet", "physreg", "mlp", "arx", "parx")
        controllers = [row["controller"] for row in table["rows"]]
        assert controllers[:3] == ["boptest-baseline", "thermostat", "qp-mpc"], controllers
        default = re.fullmatch(r"cem / default \((\w+)\)", controllers[3])
        assert default and default.group(1) in families, controllers
        assert controllers[4:] == [f"cem / {f}" for f in families if f != default.group(1)]
        for row in table["rows"]:
            assert row["test_period"] == "peak_heat_day" and {"tdis_tot", "ener_tot"} <= set(row["boptest"])
        return
    if part == "sweep":
        summary = json.loads((workdir / "boptest_sweep" / "summary.json").read_text())
        assert summary["cells_run"] == 4, summary["cells_run"]
        cells = [json.loads(p.read_text()) for p in (workdir / "boptest_sweep" / "cells").glob("*.json")]
        assert sorted(c["cell"]["controller"] for c in cells) == sorted(
            ["boptest-baseline", "thermostat", "qp-mpc", "cem/auto"])
        assert all({"tdis_tot", "ener_tot"} <= set(c["kpis"]["boptest"]) for c in cells)
        return
    from pinn_mpc.data import read_timeseries
    from scenarios.plants.boptest import read_boptest_file

    frame = read_timeseries(workdir / "boptest14.csv")
    assert len(frame) == 96 and str(frame["time"].iloc[0]).startswith("2018-01-31")
    assert frame["u_phys"].max() > 1500.0 and frame["T_r"].between(15.0, 28.0).all()
    scenario = ROOT / "scenarios" / "plants" / "boptest_hydronic_heat_pump.toml"
    area = read_boptest_file(str(scenario)).points.floor_area_m2
    results: dict[str, dict] = {}
    for name in ("baseline", "thermostat", "qp", "cem"):
        kpis = json.loads((workdir / f"{name}.json").read_text())
        b = kpis["boptest"]
        assert {"tdis_tot", "idis_tot", "ener_tot", "cost_tot", "emis_tot", "pele_tot", "time_rat"} <= set(b)
        assert kpis["test_period"] == "peak_heat_day" and kpis["price_scenario"] == "dynamic"
        assert kpis["counted_days"] == ["2018-01-17", "2018-01-17"]
        assert kpis["energy_kwh"] / area == pytest.approx(b["ener_tot"], rel=1e-3)
        assert kpis["cost_eur"] / area == pytest.approx(b["cost_tot"], rel=2e-3)
        assert kpis["discomfort_kh"] == pytest.approx(b["tdis_tot"], rel=0.05, abs=0.05)
        results[name] = kpis
    # the MPC on the identified RC keeps the band better than the thermostat's switching
    assert results["qp"]["boptest"]["tdis_tot"] < results["thermostat"]["boptest"]["tdis_tot"]
    # it plans inside the band by its RC's replay error, as cem's fallback does
    qp = results["qp"]
    assert qp["rc_replay_error_k"] is not None and 0.0 < qp["comfort_margin_k"] <= 0.5, qp


def _gen_results():
    spec = importlib.util.spec_from_file_location("gen_results", DOCS / "gen_results.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_results_page_states_command_commit_machine_and_cells(tmp_path: Path) -> None:
    """The results generator's page from a sweep directory (two seeds, two controllers)."""
    from scenarios.records import CellRecord
    from scenarios.reports.sweep_report import summarise

    gen = _gen_results()
    cells = []
    for seed, (oracle, cem, qp) in enumerate([(10.0, 10.1, 10.3), (20.0, 20.4, 20.2)]):
        for controller, objective in (("oracle", oracle), ("cem", cem), ("qp-mpc", qp)):
            cells.append({
                "cell": {"scenario": "winter_household", "controller": controller, "seed": seed,
                         "train_days": None if controller == "oracle" else 14},
                "kpis": {"objective": objective, "days": 1, "model_fallback_steps": 3 if controller == "cem" else None,
                         # qp-mpc's cells from before the split have no parts
                         **({} if controller == "qp-mpc" else {"discomfort_avoidable_kh": 0.5 + seed,
                                                               "discomfort_unavoidable_kh": 2.0})},
            })
    sweep = tmp_path / "sweep"
    (sweep / "cells").mkdir(parents=True)
    for i, cell in enumerate(cells):  # cells of two runs at two commits, one from before it was kept
        code = {} if i == 0 else {"code": "def456" if i < 3 else "abc123 + uncommitted changes"}
        (sweep / "cells" / f"{i}.json").write_text(json.dumps({**cell, **code}))
    summary = {"rows": summarise(cast(list[CellRecord], cells), baseline="qp-mpc", order=["cem", "qp-mpc"]),
               "cells_run": 6, "cells_reused": 0, "models_trained": 4, "settings": {"quick": False}}
    (sweep / "summary.json").write_text(json.dumps(summary))
    spec = ROOT / "sweeps" / "smoke.toml"
    text = gen.page(spec, sweep, "python docs/gen_results.py --spec sweeps/smoke.toml", 90.0, "abc123")
    assert "**Generated** by `python docs/gen_results.py --spec sweeps/smoke.toml` on " in text
    assert "- commit: `abc123` (where this page was written)" in text
    assert ("- the cells ran at: `abc123 + uncommitted changes` (3 cells), `def456` (2 cells), "
            "not recorded (a sweep from before cells kept it) (1 cell)") in text
    assert "- machine: " in text and "1.5 min" in text
    assert spec.read_text().strip() in text
    assert "| winter_household | cem | 14 | 2 | oracle | 1.015 |" in text  # mean of 1.010 and 1.020
    assert "| avoidable discomfort K h (mean) | unavoidable discomfort K h (mean) |" in text
    assert "| 1.000 | 2.000 |" in text and "| not computed | not computed |" in text
    assert "| winter_household | 14 | 1 | 1.020 | 1.010 | 20.00 | cem 3 of 48 |" in text
    assert "| winter_household | oracle |" not in text


def test_a_zoned_results_page_gives_each_zones_discomfort_and_own_decisions(tmp_path: Path) -> None:
    """Cells of a building of several zones get a table of each zone's too cold / too warm
    discomfort (the mean over seeds) and the own decisions' share (mean and worst seed)."""
    gen = _gen_results()
    sweep = tmp_path / "sweep"
    (sweep / "cells").mkdir(parents=True)
    for seed, (cold, warm, share) in enumerate([(0.2, 1.0, 1.0), (0.4, 3.0, 0.9)]):
        zones = {"south": {"discomfort_too_cold_kh": cold, "discomfort_too_warm_kh": warm},
                 "north": {"discomfort_too_cold_kh": 0.0, "discomfort_too_warm_kh": 0.5}}
        cell = {"cell": {"scenario": "two_zone_house", "controller": "cem", "seed": seed, "train_days": 14},
                "kpis": {"objective": 1.0, "days": 1, "own_decisions_share": share, "zones": zones}}
        (sweep / "cells" / f"{seed}.json").write_text(json.dumps(cell))
    lines = gen.zone_table(sweep, ["cem"])
    assert "| two_zone_house | cem | 14 | 2 | 95.0 % (90.0 %) | south 0.30 / 2.00, north 0.00 / 0.50 |" in lines
    assert gen.zone_table(tmp_path / "nothing", ["cem"]) == []


def test_a_results_page_names_a_sweeps_scenario_files_as_the_repository_holds_them() -> None:
    """A sweep run from another checkout records its scenario files' absolute paths; the page
    names each as the repository holds it (relative to the repository's root), wherever the
    sweep ran, and leaves other paths as they are."""
    gen = _gen_results()
    spec = ROOT / "sweeps" / "eplus_consistent.toml"
    text = (
        "| /work/clone-7/sweeps/buildings/eplus_warehouse.toml | cem | 14 |\n"
        f"| {ROOT}/sweeps/buildings/eplus_standalone_retail.toml | cem |\n"
        "| /data/other/eplus_warehouse.toml | eplus_small_office |"
    )
    assert gen._relative(text, spec).splitlines() == [
        "| sweeps/buildings/eplus_warehouse.toml | cem | 14 |",
        "| sweeps/buildings/eplus_standalone_retail.toml | cem |",
        "| /data/other/eplus_warehouse.toml | eplus_small_office |",
    ]


def test_a_boptest_results_page_says_what_it_was_measured_on(tmp_path: Path) -> None:
    """A BOPTEST sweep's page names BOPTEST's version and the test case its cells record, and
    the commands that measure it again (the cells here are written by the test: only the
    generator is checked, no figure of BOPTEST's)."""
    gen = _gen_results()
    sweep = tmp_path / "sweep"
    (sweep / "cells").mkdir(parents=True)
    for i, controller in enumerate(("boptest-baseline", "qp-mpc")):
        cell = {"cell": {"scenario": "boptest_hydronic_heat_pump", "controller": controller,
                         "seed": 0, "train_days": None if i == 0 else 14,
                         "test_period": "peak_heat_day", "price_scenario": "dynamic"},
                "kpis": {"objective": 1.0 + i, "days": 14, "boptest": {"tdis_tot": 1.0},
                         "boptest_testcase": "bestest_hydronic_heat_pump",
                         "boptest_version": "1.0.0-dev", "own_decisions_share": 1.0,
                         "decision_ms_median": 1.0, "decision_ms_p95": 2.0},
                "wall_time_s": 10.0}
        (sweep / "cells" / f"{i}.json").write_text(json.dumps(cell))
    (sweep / "summary.json").write_text(json.dumps({"rows": [], "cells_run": 2, "cells_reused": 0, "models_trained": 1}))
    text = gen.page(ROOT / "sweeps" / "boptest.toml", sweep, "python docs/gen_results.py", None, "abc123")
    assert "- BOPTEST: version 1.0.0-dev (the server's `GET /version`), test case `bestest_hydronic_heat_pump`" in text
    assert ("`pinn-mpc sweep --spec sweeps/boptest.toml --out sweep --workers 2`, then "
            "`python docs/gen_results.py --spec sweeps/boptest.toml --from-dir sweep`") in text


def test_readme_two_commands_are_the_main_job_and_ci() -> None:
    """The README's two commands: install and run the main job; install and run what CI runs."""
    first, second = blocks(README, "")[:2]
    assert first.strip() == (
        "python -m pip install -c constraints.txt -e . && "
        "pinn-mpc compare --scenario winter_household --quick"
    )
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").strip().splitlines()[-1]
    assert second.strip() == ci
