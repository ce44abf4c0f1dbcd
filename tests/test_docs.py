"""The documentation: the site builds with ``mkdocs build --strict``, its API reference names
every public name, its code blocks run (Python) or parse (the `pinn-mpc` commands against the
CLI's parser, TOML with tomllib), the walkthrough "your building from your data" runs as
written, and the results generator writes what it says."""

from __future__ import annotations

import importlib
import importlib.util
import json
import os
import re
import shlex
import subprocess
import sys
import tomllib
from functools import cache
from pathlib import Path

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
    and every command, as the page gives them."""
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


def _gen_results():
    spec = importlib.util.spec_from_file_location("gen_results", DOCS / "gen_results.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_results_page_states_command_commit_machine_and_cells(tmp_path: Path) -> None:
    """The results generator's page from a sweep directory (two seeds, two controllers)."""
    from scenarios.reports.sweep_report import summarise

    gen = _gen_results()
    cells = []
    for seed, (oracle, cem, qp) in enumerate([(10.0, 10.1, 10.3), (20.0, 20.4, 20.2)]):
        for controller, objective in (("oracle", oracle), ("cem", cem), ("qp-mpc", qp)):
            cells.append({
                "cell": {"scenario": "winter_household", "controller": controller, "seed": seed,
                         "train_days": None if controller == "oracle" else 14},
                "kpis": {"objective": objective, "days": 1, "model_fallback_steps": 3 if controller == "cem" else None},
            })
    sweep = tmp_path / "sweep"
    (sweep / "cells").mkdir(parents=True)
    for i, cell in enumerate(cells):
        (sweep / "cells" / f"{i}.json").write_text(json.dumps(cell))
    summary = {"rows": summarise(cells, baseline="qp-mpc", order=["cem", "qp-mpc"]),
               "cells_run": 6, "cells_reused": 0, "models_trained": 4, "settings": {"quick": False}}
    (sweep / "summary.json").write_text(json.dumps(summary))
    spec = ROOT / "sweeps" / "smoke.toml"
    text = gen.page(spec, sweep, "python docs/gen_results.py --spec sweeps/smoke.toml", 90.0, "abc123")
    assert "**Generated** by `python docs/gen_results.py --spec sweeps/smoke.toml` on " in text
    assert "- commit: `abc123`" in text and "- machine: " in text and "1.5 min" in text
    assert spec.read_text().strip() in text
    assert "| winter_household | cem | 14 | 2 | oracle | 1.015 |" in text  # mean of 1.010 and 1.020
    assert "| winter_household | 14 | 1 | 1.020 | 1.010 | 20.00 | cem 3 of 48 |" in text
    assert "| winter_household | oracle |" not in text


def test_readme_two_commands_are_the_main_job_and_ci() -> None:
    """The README's two commands: install and run the main job; install and run what CI runs."""
    first, second = blocks(README, "")[:2]
    assert first.strip() == (
        "python -m pip install -c constraints.txt -e . && "
        "pinn-mpc compare --scenario winter_household --quick"
    )
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").strip().splitlines()[-1]
    assert second.strip() == ci
