"""The public API: what the packages export, that importing them stays light, and that the
documented layout (docs/layout.md), the README's command line and its Python API example match
the code."""

from __future__ import annotations

import argparse
import ast
import importlib
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from pinn_mpc_cli.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("pinn_mpc", "controllers", "scenarios")
#: The application above the packages (the command line).
APPLICATION = "pinn_mpc_cli"
README = (ROOT / "README.md").read_text(encoding="utf-8")
LAYOUT = (ROOT / "docs" / "layout.md").read_text(encoding="utf-8")


def _type_checking_imports(package: str) -> dict[str, str]:
    """{name: module} imported under ``if TYPE_CHECKING:`` in the package's ``__init__``."""
    tree = ast.parse((ROOT / package / "__init__.py").read_text(encoding="utf-8"))
    found: dict[str, str] = {}
    for node in tree.body:
        if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING":
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom) and imp.module
                found |= {alias.name: imp.module for alias in imp.names}
    return found


@pytest.mark.parametrize("package", PACKAGES)
def test_package_exports_resolve_to_their_modules(package: str) -> None:
    pkg = importlib.import_module(package)
    typed = _type_checking_imports(package)
    exported = set(pkg.__all__) - {"__version__"}
    assert exported == set(typed), "__all__ and the TYPE_CHECKING imports differ"
    assert len(pkg.__all__) == len(set(pkg.__all__))
    for name, module in typed.items():
        assert getattr(pkg, name) is getattr(importlib.import_module(module), name)
    assert exported <= set(dir(pkg))
    with pytest.raises(AttributeError, match=f"module '{package}' has no attribute 'nope'"):
        pkg.nope  # noqa: B018


def _modules() -> list[Path]:
    return sorted(p for pkg in (*PACKAGES, APPLICATION) for p in (ROOT / pkg).rglob("*.py"))


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_module_says_what_is_public(path: Path) -> None:
    if path.name == "__main__.py":
        return
    name = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
    module = importlib.import_module(name)
    assert hasattr(module, "__all__"), f"{name} has no __all__"
    missing = [n for n in module.__all__ if not hasattr(module, n)]
    assert not missing, f"{name}.__all__ names {missing}, which it does not define"


def test_importing_the_packages_and_the_cli_stays_light() -> None:
    """``pinn-mpc --help`` and ``import pinn_mpc`` must not wait for torch, pandas or numpy."""
    code = (
        "import sys, pinn_mpc, controllers, scenarios, pinn_mpc_cli.cli\n"
        "parser = pinn_mpc_cli.cli.build_parser(); parser.format_help()\n"
        "for name in ('train', 'evaluate', 'export-rc', 'identify', 'reproduce'):\n"
        "    parser._subparsers._group_actions[0].choices[name].format_help()\n"
        "print(sorted({'torch', 'pandas', 'numpy', 'matplotlib'} & set(sys.modules)))\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    assert result.stdout.strip() == "[]"


def test_commands_that_plan_on_no_learned_model_load_no_torch(tmp_path: Path) -> None:
    """simulate, identify, and the closed loops of the thermostat, the oracle and qp-mpc on an
    identified rc.json run without importing torch."""
    code = (
        "import sys\n"
        "from pinn_mpc_cli.cli import main\n"
        "for args in (\n"
        "    'simulate --scenario winter_household --days 2 --seed 0 --out d.csv',\n"
        "    'identify --data d.csv --out rc.json',\n"
        "    'closed-loop --scenario winter_household --controller thermostat --days 1',\n"
        "    'closed-loop --scenario winter_household --controller oracle --days 1',\n"
        "    'closed-loop --scenario winter_household --controller qp-mpc --rc rc.json --days 1',\n"
        "):\n"
        "    assert main(args.split()) == 0, args\n"
        "print('torch' in sys.modules)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip().splitlines()[-1] == "False"


def _block(after: str, lang: str = "", text: str = README) -> str:
    section = text[text.index(after) :]
    match = re.search(rf"```{lang or '[a-z]*'}\n(.*?)```", section, re.S)
    assert match, f"no code block after {after!r}"
    return match.group(1)


def test_layout_page_names_every_module() -> None:
    layout = _block("## What is in it", text=LAYOUT)
    named = set(re.findall(r"\b([a-z_]+\.py)\b", layout))
    named |= {f"{d}.py" for d in re.findall(r"\b([a-z_]+)\.py\b", layout)}
    for path in _modules():
        if path.name in ("__init__.py", "__main__.py"):
            continue
        rel = path.relative_to(ROOT)
        sub = rel.parts[1] if len(rel.parts) > 2 else None  # modules of a subpackage
        assert path.name in named or (sub and f"{sub}/" in layout), f"{rel} not in the layout"
    every = {p.name for p in _modules()}
    assert named <= every, f"the layout names modules that do not exist: {named - every}"
    assert "examples/" in layout and (ROOT / "examples").is_dir()


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    action = next(
        a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)
    )
    return dict(action.choices)


def test_readme_command_line_matches_the_parser() -> None:
    lines = [ln for ln in _block("## Command line").splitlines() if ln.startswith("pinn-mpc ")]
    commands = _subparsers()
    assert [ln.split()[1] for ln in lines] == list(commands)
    for line in lines:
        parser = commands[line.split()[1]]
        # A command with actions (`scenario list|show|export`) has its options on the actions.
        parsers = [parser] + [
            sub for action in parser._actions if isinstance(action, argparse._SubParsersAction)
            for sub in action.choices.values()
        ]
        options = {
            opt: action for p in parsers for action in p._actions for opt in action.option_strings
            if opt.startswith("--") and opt != "--help"
        }
        written = dict(re.findall(r"(--[a-z-]+)(?: ([A-Za-z0-9_.,|-]+))?", line))
        assert set(written) == set(options), f"{line.split()[1]}: {set(written) ^ set(options)}"
        for opt, value in written.items():
            choices = options[opt].choices
            if choices is not None:
                assert set(value.split("|")) == set(choices), f"{opt}: {value} vs {choices}"


def test_readme_names_the_scenarios_and_controllers() -> None:
    from scenarios.choices import CONTROLLER_NAMES
    from scenarios.inputs.scenario_file import builtin_names

    line = re.search(r"Scenarios: (.*?)\. Controllers: (.*?)\.\n", README.replace("\n`", " `"))
    assert line, "the sentence naming scenarios and controllers is missing"
    # every built-in --scenario takes, BOPTEST's too (the one list, as --help and errors show)
    assert sorted(re.findall(r"`([a-z_-]+)`", line.group(1))) == sorted(builtin_names())
    assert re.findall(r"`([a-z_-]+)`", line.group(2)) == list(CONTROLLER_NAMES)


@pytest.mark.slow
def test_readme_python_example_runs(tmp_path: Path) -> None:
    code = _block("## Python API", "python")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, env=env,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    lines = result.stdout.splitlines()
    assert [ln.split(" on ")[0] for ln in lines] == ["cem", "oracle"]
    assert all("winter_household, 1 d: energy" in ln for ln in lines)
    assert not list(tmp_path.iterdir()), "the example wrote files"
