"""What ``--scenario`` names for the commands that take one: the files it reads (inputs no
output may overwrite), its label in summaries, and the records that name a scenario file."""

from __future__ import annotations

import os
from typing import TypeVar

from pinn_mpc.errors import InputError
from pinn_mpc.io import PathsArg
from scenarios.inputs.registry import Scenario, is_scenario_file
from scenarios.records import FleetInfo, RunKpis

__all__ = ["scenario_inputs", "scenario_label", "with_scenario_file"]


def scenario_inputs(name: str) -> dict[str, PathsArg]:
    """The files ``--scenario`` reads (the file and the files it names), as inputs to protect."""
    from scenarios.inputs.scenario_file import scenario_inputs as files

    return {
        f"--scenario {name}'s {key}" if key else "--scenario": path
        for key, path in files(name).items()
    }


def scenario_label(name: str, scenario: Scenario) -> str:
    """The scenario as results name it: its name, and for a file the file too (a file may
    carry any name, a built-in's included)."""
    return f"{scenario.name} (file {name})" if is_scenario_file(name) else scenario.name


#: A record that names its scenario file (``scenario_file``) when ``--scenario`` is one.
_Labelled = TypeVar("_Labelled", RunKpis, FleetInfo)


def with_scenario_file(kpis: _Labelled, name: str) -> _Labelled:
    """The KPIs with ``scenario_file`` (absolute) when ``--scenario`` is a file: its ``name``
    alone may be anything, a built-in's included."""
    if not is_scenario_file(name):
        return kpis
    return {**kpis, "scenario_file": os.path.abspath(name)}


def refuse_boptest_options(
    given: dict[str, object], scenario: str, *, does: str = "applies to BOPTEST scenarios (e.g. boptest_hydronic_heat_pump)"
) -> None:
    """One line for the first BOPTEST-only option in ``given`` ({argparse dest: value}) that is
    set on ``scenario``, which is not a BOPTEST scenario: ``--OPTION`` ``does``; ``scenario`` is
    not one."""
    for option, value in given.items():
        if value is not None:
            raise InputError(f"--{option.replace('_', '-')} {does}; {scenario} is not one")
