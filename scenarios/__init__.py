"""Experiments: scenarios, training data, the closed loop, KPIs, comparisons, reproduction.

Public names (imported on first use, see :mod:`pinn_mpc.lazy`): scenarios
(:class:`Scenario`, :func:`get_scenario`, :func:`scenario_names`), training data
(:func:`generate`), controllers by name (:func:`build_controller`, :func:`make_controller`,
:func:`read_rc`, :data:`CONTROLLER_NAMES`), the closed loop (:func:`run_closed_loop` ->
:class:`ClosedLoopResult`; its engine :class:`ClosedLoop` and :class:`ExogenousSeries`; the
Gymnasium face :class:`BuildingEnv`), fleets (:func:`run_fleet_closed_loop` -> :class:`FleetResult`,
:func:`format_fleet`), KPIs (:func:`compute_kpis`, :data:`KPI_KEYS`,
:func:`format_kpis`, :func:`kpi_table_text`), figures (:func:`plot_trajectory`,
:func:`plot_comparison`), the controller comparison (:class:`CompareSettings`,
:func:`run_comparison` -> :class:`ComparisonResult`) and the paper reproduction
(:class:`ReproduceConfig`, :func:`run_reproduction`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pinn_mpc.lazy import lazy_exports

if TYPE_CHECKING:
    from pinn_mpc.artifacts import read_rc as read_rc
    from scenarios.choices import CONTROLLER_NAMES as CONTROLLER_NAMES
    from scenarios.experiments.compare import CompareSettings as CompareSettings
    from scenarios.experiments.compare import ComparisonResult as ComparisonResult
    from scenarios.experiments.compare import run_comparison as run_comparison
    from scenarios.experiments.reproduce import ReproduceConfig as ReproduceConfig
    from scenarios.experiments.reproduce import run_reproduction as run_reproduction
    from scenarios.fleets.fleet import FleetResult as FleetResult
    from scenarios.fleets.fleet import run_fleet_closed_loop as run_fleet_closed_loop
    from scenarios.inputs.registry import Scenario as Scenario
    from scenarios.inputs.registry import scenario_names as scenario_names
    from scenarios.inputs.scenario_file import get_scenario as get_scenario
    from scenarios.inputs.series import ExogenousSeries as ExogenousSeries
    from scenarios.records import BuildingKpis as BuildingKpis
    from scenarios.records import CellRecord as CellRecord
    from scenarios.records import CompareRow as CompareRow
    from scenarios.records import FleetJson as FleetJson
    from scenarios.records import Kpis as Kpis
    from scenarios.records import PredictionRow as PredictionRow
    from scenarios.records import RunKpis as RunKpis
    from scenarios.records import SweepRow as SweepRow
    from scenarios.records import SweepSummary as SweepSummary
    from scenarios.reports.plots import plot_comparison as plot_comparison
    from scenarios.reports.plots import plot_trajectory as plot_trajectory
    from scenarios.reports.report import format_fleet as format_fleet
    from scenarios.reports.report import format_kpis as format_kpis
    from scenarios.reports.report import kpi_table_text as kpi_table_text
    from scenarios.running.closed_loop import ClosedLoopResult as ClosedLoopResult
    from scenarios.running.closed_loop import run_closed_loop as run_closed_loop
    from scenarios.running.datagen import generate as generate
    from scenarios.running.engine import ClosedLoop as ClosedLoop
    from scenarios.running.factory import build_controller as build_controller
    from scenarios.running.factory import make_controller as make_controller
    from scenarios.running.gym_env import BuildingEnv as BuildingEnv
    from scenarios.running.kpis import KPI_KEYS as KPI_KEYS
    from scenarios.running.kpis import compute_kpis as compute_kpis

_EXPORTS = {
    "scenarios.choices": ("CONTROLLER_NAMES",),
    "scenarios.running.closed_loop": ("ClosedLoopResult", "run_closed_loop"),
    "scenarios.experiments.compare": ("CompareSettings", "ComparisonResult", "run_comparison"),
    "scenarios.running.datagen": ("generate",),
    "scenarios.running.engine": ("ClosedLoop",),
    "scenarios.inputs.series": ("ExogenousSeries",),
    "scenarios.running.factory": ("build_controller", "make_controller"),
    "pinn_mpc.artifacts": ("read_rc",),
    "scenarios.fleets.fleet": ("FleetResult", "run_fleet_closed_loop"),
    "scenarios.running.gym_env": ("BuildingEnv",),
    "scenarios.running.kpis": ("KPI_KEYS", "compute_kpis"),
    "scenarios.records": (
        "BuildingKpis",
        "CellRecord",
        "CompareRow",
        "FleetJson",
        "Kpis",
        "PredictionRow",
        "RunKpis",
        "SweepRow",
        "SweepSummary",
    ),
    "scenarios.reports.plots": ("plot_comparison", "plot_trajectory"),
    "scenarios.inputs.registry": ("Scenario", "scenario_names"),
    "scenarios.inputs.scenario_file": ("get_scenario",),
    "scenarios.reports.report": ("format_fleet", "format_kpis", "kpi_table_text"),
    "scenarios.experiments.reproduce": ("ReproduceConfig", "run_reproduction"),
}
__all__ = [name for names in _EXPORTS.values() for name in names]
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
