"""Package attributes imported on first use (PEP 562), so that ``import pinn_mpc`` (and the
CLI's start-up) does not load torch, pandas or matplotlib until a name that needs them is used.

A package lists its public names as ``{module: names}``; :func:`lazy_exports` gives it the
module-level ``__getattr__`` and ``__dir__`` that import a name's module when the name is first
asked for. The package also imports the names under ``TYPE_CHECKING``, so type checkers and
editors see them; ``tests/test_public_api.py`` checks that both lists and ``__all__`` agree.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str, exports: Mapping[str, Sequence[str]]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package`` serving ``exports`` ({module: names})."""
    where = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str) -> Any:
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(where[name]), name)
        setattr(sys.modules[package], name, value)  # later look-ups skip this function
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(where))

    return __getattr__, __dir__
