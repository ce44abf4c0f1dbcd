"""Imports only point downwards: pinn_mpc -> nothing of ours; controllers -> pinn_mpc;
scenarios -> both; the application pinn_mpc_cli -> all three, with no exception: ``python -m
pinn_mpc`` finds the command through the installed entry point, and no module may import a
``__main__``. Inside scenarios, the subpackages form a stack (SCENARIO_STACK): each imports
only those before it and the shared modules (choices, records), which import none of them;
plants come first, knowing no scenario."""

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
#: The subpackages of scenarios, lowest first: each may import itself and those before it.
SCENARIO_STACK = ("plants", "inputs", "running", "fleets", "reports", "experiments")
#: Modules at the top of scenarios every subpackage may import; they import no subpackage.
SCENARIO_SHARED = ("choices", "records")


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


def imported_modules(source: str) -> set[str]:
    """Dotted names of every module a module imports (anywhere, lazily too)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module)
    return found


def test_detector_sees_lazy_and_from_imports():
    src = (
        "import numpy\n"
        "def f():\n"
        "    from scenarios.running.kpis import KPI_KEYS\n"
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


def _scenarios_part(module: str) -> str | None:
    """The subpackage or shared module of ``scenarios`` a dotted name lies in (None: not ours,
    or the package itself)."""
    parts = module.split(".")
    if parts[0] != "scenarios":
        return None
    return parts[1] if len(parts) > 1 else "scenarios"


def test_scenarios_subpackages_import_only_those_below() -> None:
    bad = []
    for path in sorted((ROOT / "scenarios").rglob("*.py")):
        rel = path.relative_to(ROOT)
        own = rel.parts[1] if len(rel.parts) > 2 else path.stem
        if own in SCENARIO_SHARED:
            allowed: set[str] = set(SCENARIO_SHARED)
        elif own in SCENARIO_STACK:
            allowed = set(SCENARIO_SHARED) | set(SCENARIO_STACK[: SCENARIO_STACK.index(own) + 1])
        else:  # the package's face (__init__): anything of scenarios
            continue
        for module in imported_modules(path.read_text(encoding="utf-8")):
            part = _scenarios_part(module)
            if part is not None and part not in allowed:
                bad.append(f"{rel} imports {module}")
    assert not bad, "; ".join(bad)


def test_every_scenarios_module_has_a_place_in_the_stack():
    """A new module of scenarios goes into a subpackage of the stack (or is a shared one)."""
    top = {p.stem for p in (ROOT / "scenarios").glob("*.py")} - {"__init__"}
    subpackages = {p.name for p in (ROOT / "scenarios").iterdir() if (p / "__init__.py").is_file()}
    assert top == set(SCENARIO_SHARED)
    assert subpackages == set(SCENARIO_STACK)


def test_plants_import_nothing_of_scenarios_but_plants():
    """A plant knows no scenario, controller or experiment: BOPTEST's and the next come here."""
    bad = []
    for path in sorted((ROOT / "scenarios" / "plants").rglob("*.py")):
        found = imported_modules(path.read_text(encoding="utf-8"))
        bad += [
            f"{path.relative_to(ROOT)} imports {m}" for m in found
            if m.split(".")[0] == "controllers" or (
                _scenarios_part(m) is not None and _scenarios_part(m) != "plants"
            )
        ]
    assert not bad, "; ".join(bad)
