"""Write the API reference pages (docs/api/*.md) from the packages' public names.

Each package names its public API in ``_EXPORTS`` (module -> names), from which its ``__all__``
is built; this script writes one page per package with one mkdocstrings block per name, grouped
by the module that defines it. Run it after adding a public name:

    python docs/gen_api.py          # write docs/api/*.md
    python docs/gen_api.py --check  # exit 1 if a page is out of date (the tests run this)
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {
    "pinn_mpc": "Modelling: data, the 2R2C physics and simulator, learned models, identification.",
    "controllers": "Decisions: the controller interface, the objective, estimators, controllers.",
    "scenarios": "Experiments: scenarios, data generation, the closed loop, KPIs, comparisons.",
}


def page(package: str) -> str:
    """The markdown of ``docs/api/<package>.md``."""
    pkg = importlib.import_module(package)
    exports: dict[str, tuple[str, ...]] = pkg._EXPORTS
    lines = [
        f"# `{package}`",
        "",
        "<!-- Written by docs/gen_api.py from the package's public names; do not edit. -->",
        "",
        PACKAGES[package],
        f"Every name below is in `{package}.__all__` and imports as `from {package} import NAME`.",
        "",
    ]
    if "__version__" in pkg.__all__:
        lines += [f"`{package}.__version__`: the package's version (`{pkg.__version__}`).", ""]
    for module in sorted(exports):
        lines += [f"## `{module}`", ""]
        for name in sorted(exports[module], key=str.lower):
            lines += [f"::: {module}.{name}", ""]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="fail if a page is out of date")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    stale = []
    for package in PACKAGES:
        path = ROOT / "docs" / "api" / f"{package}.md"
        text = page(package)
        if path.exists() and path.read_text(encoding="utf-8") == text:
            continue
        if args.check:
            stale.append(str(path.relative_to(ROOT)))
        else:
            path.write_text(text, encoding="utf-8")
            print(f"wrote {path.relative_to(ROOT)}")
    if stale:
        print(f"out of date: {', '.join(stale)}; run python docs/gen_api.py", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
