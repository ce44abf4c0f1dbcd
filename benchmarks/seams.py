"""Count what the seams between the package's layers look like, for a before/after of a redesign.

Prints, for the checkout it runs in (or ``--root DIR``):

- **control bounds written out**: lines outside the actuator type that write a control input's
  bounds themselves: a literal 0 beside ``u_max`` in a clip, clamp, box or bound argument;
- **plant-kind branches outside the plant layer**: lines outside the plant layer (``scenarios/plants/``, the RC structures of ``pinn_mpc/plant.py``) that ask
  which kind a plant is (``is_energyplus``, ``runs_in_simulator``, ``is_boptest*``,
  ``kind ==``, ``isinstance(..., BoptestScenario)`` and the like);
- **fleet-only planning and rollout lines**: the lines of the modules that plan or roll out a
  fleet apart from the single building (``controllers/fleet_sampling.py``,
  ``controllers/fleet.py``, ``pinn_mpc/models/fleet.py``);
- **the largest module** and the **functions over 80 lines** (their names);
- **``Any`` at the seams**: public functions of the three packages whose return annotation
  holds ``Any``;
- **``raise InputError`` in the library**: the raise sites of what the user can fix in
  ``pinn_mpc``, ``controllers`` and ``scenarios`` (a Python caller's misuse raises
  ``ValueError`` / ``TypeError``, a broken invariant ``InternalError``);
- **library lines naming a flag**: code lines of the three packages that name a flag of the
  command line (the ``--`` options of ``pinn_mpc_cli/parser.py``); a library message names the
  setting (``pinn_mpc.errors.setting``) and the command line adds the flag.

Plain text search and ``ast``; nothing of the package is imported or run::

    python benchmarks/seams.py [--root DIR] [--list]
"""

from __future__ import annotations

import argparse
import ast
import re
from collections.abc import Iterable
from pathlib import Path

PACKAGES = ("pinn_mpc", "controllers", "scenarios", "pinn_mpc_cli")
#: A literal lower bound of 0 next to the upper bound u_max in one expression.
BOUND = re.compile(
    r"(clip|clamp)\(.*\b0(\.0)?\b.*u_max"
    r"|\blow(er)?\s*=\s*0(\.0)?\b.*\bhigh|\blow(er)?\s*=\s*0(\.0)?\b.*\bupper"
    r"|u_max\w*\s+if\s.*\belse\s+0(\.0)?\b|\b0(\.0)?\s+if\s.*\belse\s.*u_max"
    r"|where\(.*u_max\w*,.*\b0(\.0)?\b"
)
#: A question of which kind a plant is.
KIND = re.compile(
    r"\b(is_energyplus|runs_in_simulator|is_boptest\w*)\b|\bplant(_settings)?\.kind\b|"
    r"isinstance\([^)]*(BoptestScenario|EnergyPlusPlant|RCPlant|BoptestPlant)"
)
#: The plant layer: the plug-ins, and the RC simulator's own structures (2R2C, 3R3C).
PLANT_LAYER = ("scenarios/plants/", "pinn_mpc/plant.py")
FLEET_ONLY = ("controllers/fleet_sampling.py", "controllers/fleet.py", "pinn_mpc/models/fleet.py")
LONG_FUNCTION = 80
#: The library: the packages below the command line.
LIBRARY = ("pinn_mpc", "controllers", "scenarios")
#: A raise of what the user can fix.
RAISE_INPUT = re.compile(r"\braise (InputError|ModelFileError)\b")
#: A ``--name`` token (the flag itself, not a longer word it begins).
FLAG = re.compile(r"(?<![\w-])--([a-z][a-z0-9-]*)(?![a-z0-9{-])")


def sources(root: Path) -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (root / pkg).rglob("*.py"))


def code_lines(path: Path) -> list[tuple[int, str]]:
    """The file's lines that are code: not blank, not comments, not inside docstrings."""
    text = path.read_text(encoding="utf-8")
    doc_lines: set[int] = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            doc_lines.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))
    return [
        (i, line) for i, line in enumerate(text.splitlines(), 1)
        if line.strip() and not line.strip().startswith("#") and i not in doc_lines
    ]


def cli_flags(root: Path) -> set[str]:
    """The command line's flags: the ``"--name"`` literals of its parser."""
    text = (root / "pinn_mpc_cli" / "parser.py").read_text(encoding="utf-8")
    return set(re.findall(r"\"--([a-z][a-z0-9-]*)\"", text))


def library_lines(root: Path) -> list[tuple[str, int, str]]:
    """(module, line number, line) of every code line of the library."""
    return [
        (path.relative_to(root).as_posix(), i, line)
        for pkg in LIBRARY for path in sorted((root / pkg).rglob("*.py"))
        for i, line in code_lines(path)
    ]


def flag_lines(root: Path) -> list[str]:
    """The library's code lines that name a flag of the command line (``module: line``)."""
    flags = cli_flags(root)
    return [
        f"{rel}: {line.strip()}" for rel, _, line in library_lines(root)
        if any(name in flags for name in FLAG.findall(line))
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", default=str(Path(__file__).resolve().parents[1]))
    parser.add_argument("--list", action="store_true", help="list every line counted")
    a = parser.parse_args()
    root = Path(a.root)
    bounds, kinds, long_functions, any_returns = [], [], [], []
    sizes = {}
    for path in sources(root):
        rel = path.relative_to(root).as_posix()
        lines = code_lines(path)
        sizes[rel] = len(path.read_text(encoding="utf-8").splitlines())
        for i, line in lines:
            if BOUND.search(line):
                bounds.append(f"{rel}:{i}: {line.strip()}")
            if KIND.search(line) and not rel.startswith(PLANT_LAYER):
                kinds.append(f"{rel}:{i}: {line.strip()}")
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > LONG_FUNCTION:
                    long_functions.append(f"{rel}:{node.name} ({length} lines)")
                if (not node.name.startswith("_") and node.returns is not None
                        and "Any" in ast.unparse(node.returns)):
                    any_returns.append(f"{rel}:{node.name} -> {ast.unparse(node.returns)}")
    fleet_only = sum(len(code_lines(root / f)) for f in FLEET_ONLY if (root / f).is_file())
    largest = max(sizes, key=lambda k: sizes[k])
    rows = [
        ("control bounds written out", len(bounds), bounds),
        ("plant-kind branches outside scenarios/plants/", len(kinds), kinds),
        ("fleet-only planning and rollout code lines", fleet_only, [f for f in FLEET_ONLY if (root / f).is_file()]),
        (f"largest module: {largest}", sizes[largest], []),
        (f"functions over {LONG_FUNCTION} lines", len(long_functions), long_functions),
        ("public functions returning Any", len(any_returns), any_returns),
        ("raise InputError in the library", *_listed(
            f"{rel}:{i}" for rel, i, line in library_lines(root) if RAISE_INPUT.search(line)
        )),
        ("library lines naming a flag", *_listed(flag_lines(root))),
    ]
    for name, count, items in rows:
        print(f"{name}: {count}")
        if a.list:
            for item in items:
                print(f"    {item}")


def _listed(items: Iterable[str]) -> tuple[int, list[str]]:
    listed = list(items)
    return len(listed), listed


if __name__ == "__main__":
    main()
