"""The ``scenario`` command: list the built-in scenarios, show one, or export it as a TOML file."""

from __future__ import annotations

import argparse

__all__ = ["scenario"]


def scenario(a: argparse.Namespace) -> str:
    """``pinn-mpc scenario list | show NAME | export NAME --out FILE.toml``."""
    from scenarios.inputs.scenario_file import scenario_command

    return scenario_command(
        a.action,
        name=getattr(a, "name", None),
        out=getattr(a, "out", None),
        force=getattr(a, "force", False),
    )
