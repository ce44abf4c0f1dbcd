"""The ``scenario`` command: list the built-in scenarios, show one, or export it as a TOML file."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from pathlib import Path

from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.io import PathsArg, atomic_write_text, check_distinct, check_new_files, check_writable

__all__ = ["scenario"]


def scenario(a: argparse.Namespace) -> str:
    """``pinn-mpc scenario list | show NAME | export NAME --out FILE.toml [--force]``: an
    existing ``--out`` is replaced only with ``--force``, and never when the scenario reads it."""
    from scenarios.inputs import scenario_file
    from scenarios.inputs.registry import is_scenario_file
    from scenarios.plants.boptest import boptest_file

    if a.action == "list":
        return scenario_file.scenario_list()
    boptest = boptest_file(a.name)
    if boptest is not None:  # a BOPTEST scenario is its file: the test case is the server's
        return _boptest_scenario(a, boptest)
    if a.action == "show":
        text = scenario_file.scenario_to_toml(scenario_file.get_scenario(a.name)).rstrip("\n")
        if not is_scenario_file(a.name):
            return text
        defaults = scenario_file.defaulted_keys(a.name)
        note = (
            f"# Not in {a.name}, so at their defaults (as shown above): {', '.join(defaults)}"
            if defaults
            else f"# {a.name} gives every key."
        )
        return f"{text}\n\n{note}"
    _check_action(a.action)
    _check_export(
        a,
        lambda: {
            f"NAME {a.name}'s {k}" if k else "NAME": p for k, p in scenario_file.scenario_inputs(a.name).items()
        },
        f" (that is how --scenario tells a file from a built-in name); write --out {a.out}.toml",
    )
    atomic_write_text(a.out, scenario_file.scenario_to_toml(scenario_file.get_scenario(a.name)))
    return f"wrote {a.out}"


def _check_action(action: str) -> None:
    if action != "export":
        raise InternalError(f"unknown scenario action {action!r}; use list, show or export")


def _check_export(a: argparse.Namespace, inputs: Callable[[], Mapping[str, PathsArg]], fix: str) -> None:
    """Refuse an ``--out`` that is no ``.toml`` name (``fix`` says what to write), cannot be
    written, is one of ``inputs()`` (asked only once ``--out`` is a writable name) or exists
    without ``--force``."""
    if not a.out.lower().endswith(".toml"):
        raise InputError(f"--out {a.out}: scenario files end in .toml{fix}")
    check_writable(a.out)
    check_distinct(inputs=inputs(), outputs={"--out": a.out})
    check_new_files({"out": a.out}, force=a.force)


def _boptest_scenario(a: argparse.Namespace, source: Path) -> str:
    """``scenario show`` (the file, checked) or ``export`` (a copy) of a BOPTEST scenario."""
    from scenarios.plants.boptest import read_boptest_file

    read_boptest_file(str(source))  # a bad file is one clear error, as for any scenario
    text = source.read_text(encoding="utf-8")
    if a.action == "show":
        return text.rstrip("\n")
    _check_action(a.action)
    _check_export(a, lambda: {"NAME": source}, f"; write --out {a.out}.toml")
    atomic_write_text(a.out, text)
    return f"wrote {a.out} ({a.name}: a BOPTEST scenario, its [boptest] table)"
