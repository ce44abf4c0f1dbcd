"""Imports only point downwards: pinn_mpc -> nothing of ours; controllers -> pinn_mpc;
scenarios -> both. ``pinn_mpc/cli.py`` is the application entry point and may import all."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("pinn_mpc", "controllers", "scenarios")
ALLOWED = {
    "pinn_mpc": {"pinn_mpc"},
    "controllers": {"pinn_mpc", "controllers"},
    "scenarios": {"pinn_mpc", "controllers", "scenarios"},
}
EXEMPT = {Path("pinn_mpc/cli.py")}


def imported_layers(source: str) -> set[str]:
    """Top-level packages among LAYERS that a module imports (anywhere, lazily too)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        found |= {n.split(".")[0] for n in names} & set(LAYERS)
    return found


def test_detector_sees_lazy_and_from_imports():
    src = (
        "import numpy\n"
        "def f():\n"
        "    from scenarios.kpis import KPI_KEYS\n"
        "import controllers.base\n"
    )
    assert imported_layers(src) == {"scenarios", "controllers"}


@pytest.mark.parametrize("layer", LAYERS)
def test_layer_imports_point_downwards(layer):
    files = sorted((ROOT / layer).rglob("*.py"))
    assert files, f"no modules found under {layer}/"
    bad = []
    for path in files:
        rel = path.relative_to(ROOT)
        if rel in EXEMPT:
            continue
        wrong = imported_layers(path.read_text(encoding="utf-8")) - ALLOWED[layer]
        if wrong:
            bad.append(f"{rel} imports {sorted(wrong)}")
    assert not bad, "; ".join(bad)
