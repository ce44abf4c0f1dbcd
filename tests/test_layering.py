"""Imports only point downwards: pinn_mpc -> nothing of ours; controllers -> pinn_mpc;
scenarios -> both; the application pinn_mpc_cli -> all three. No exception: ``python -m
pinn_mpc`` finds the command through the installed entry point, and no module may import a
``__main__``."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("pinn_mpc", "controllers", "scenarios", "pinn_mpc_cli")
ALLOWED = {
    "pinn_mpc": {"pinn_mpc"},
    "controllers": {"pinn_mpc", "controllers"},
    "scenarios": {"pinn_mpc", "controllers", "scenarios"},
    "pinn_mpc_cli": {"pinn_mpc", "controllers", "scenarios", "pinn_mpc_cli"},
}


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
        wrong = imported_layers(path.read_text(encoding="utf-8")) - ALLOWED[layer]
        if wrong:
            bad.append(f"{rel} imports {sorted(wrong)}")
    assert not bad, "; ".join(bad)


def test_nothing_imports_a_main_script():
    """``__main__`` modules run the application on import: no module may import one."""
    bad = []
    for layer in LAYERS:
        for path in sorted((ROOT / layer).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                names = (
                    [a.name for a in node.names] if isinstance(node, ast.Import)
                    else [node.module or ""] if isinstance(node, ast.ImportFrom) else []
                )
                bad += [f"{path.relative_to(ROOT)}: {n}" for n in names if n.endswith("__main__")]
    assert not bad, bad
