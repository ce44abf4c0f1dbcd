"""A controller comparison: train, identify and run every controller on one scenario.

1. Training data: ``train_days`` from the training part of the scenario's weather (see
   :mod:`scenarios.inputs.exogenous`) under a random policy (seed ``seed``): ``random-level``
   (a uniform power level per interval, the default) or the paper's on/off ``random``. On/off
   data shows a network only 0 and full power, while the controllers modulate it, so a model
   trained on uniform levels predicts the closed-loop operating points better.
2. Models: the recommended hybrid (see :class:`pinn_mpc.models.HybridNet`) and the paper's
   physnet, physreg and mlp seed ensembles; grey-box RC identification (T_m hidden); the RC
   parameters exported from the hybrid and the physnet ensembles.
3. Closed loop on the same ``days`` test days from the test part of the weather (seed
   ``seed + 1``; no calendar day in common with the training data, warm-up and forecast lead
   included), same perfect forecasts, same one-day thermostat warm-up, for: thermostat,
   random shooting and CEM over the hybrid (and CEM without its LP polish, to show what the
   polish adds), CEM over physnet, physreg and mlp (physreg and mlp unless
   ``cem_all_models=False``), CEM over the linear ARX baseline (:mod:`pinn_mpc.models.arx`) and its physics-informed variant, casadi-mpc and qp-mpc on the identified RC, qp-mpc on the
   hybrid- and physnet-exported RCs, qp-mpc on both ARX models (:mod:`controllers.arx_mpc`), oracle and clairvoyant (where the plant has a true RC
   and state; on EnergyPlus there is no oracle and every controller is measured against the
   thermostat, :attr:`scenarios.inputs.registry.Scenario.reference`).
   With a heat pump (``scenario.sim.actuator``) the data's power is electrical and its ``cop``
   column the heat per electrical watt: the hybrid and the grey-box identification work on the
   delivered heat (COP(T_a) x electrical power); the paper's networks train on the electrical
   power with ``eta`` times the data's power-weighted mean COP (their prior and export then
   describe the building with that actuator gain), and their exported RCs get the building's
   own ``eta`` back, since the RC MPCs multiply by the COP of each forecast step themselves.
4. Prediction: every model's T_r error 1, 6, 24 and 48 steps ahead on held-out data of the
   test part (:mod:`scenarios.experiments.prediction`): the learned models, a linear ARX baseline fitted on
   the same training data (:mod:`pinn_mpc.models.arx`), and the identified, exported and true RC as
   the RC MPCs use them.
5. Outputs (written by the command, :func:`pinn_mpc_cli.experiment_commands.compare`; :func:`run_comparison`
   returns them as a :class:`ComparisonResult`): a JSON table (one row per controller with every KPI), a markdown report with the
   dates of the training data and of the test days, the KPI table, each objective relative to
   the reference's (oracle or thermostat), the RC parameters against the true ones and a
   figure of the trajectories, one panel per controller family against the reference (PNG
   next to the report,
   :func:`scenarios.reports.plots.comparison_figure`).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import pandas as pd
from tqdm import tqdm

from controllers.planners import CEMPlanner, RandomShootingPlanner
from pinn_mpc.choices import ARX, AUTO, COMPARED_ARCHS, DEFAULT_ARCH, PHYSICS_ARX
from pinn_mpc.errors import warn
from pinn_mpc.physics import RCParams, params_from_summary, rc_summary
from pinn_mpc.records import RcSummary
from scenarios.choices import RANDOM_POLICIES
from scenarios.experiments.prediction import prediction_errors
from scenarios.inputs.exogenous import day_span
from scenarios.inputs.registry import Scenario, check_seed
from scenarios.records import CompareRow, PredictionRow
from scenarios.reports.report import objective_ratios
from scenarios.running.closed_loop import one_torch_thread, run_closed_loop
from scenarios.running.factory import build_controller, weather_range_note

if TYPE_CHECKING:
    from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
    from pinn_mpc.model_choice import ModelChoice
    from pinn_mpc.models.arx import ARXModel
    from pinn_mpc.models.learned import LearnedModel
    from pinn_mpc.models.multizone_paper import PaperZoneTraining
    from pinn_mpc.models.rollout import FittedModel
    from pinn_mpc.training import TrainConfig

__all__ = [
    "ARCHS",
    "REFERENCE",
    "CompareSettings",
    "ComparisonResult",
    "identify_scenario_rc",
    "identify_scenario_zones",
    "rc_for_mpc",
    "run_comparison",
    "run_plan",
    "train_scenario_zones",
    "zone_solar_inputs",
]

#: The recommended model first; physnet for the paper's best; physreg and mlp for the CEM rows.
ARCHS = COMPARED_ARCHS
_RS = RandomShootingPlanner(lower=0.0, upper=1.0)  # the planners' defaults
_CEM = CEMPlanner(lower=0.0, upper=1.0)
REFERENCE = "oracle"
#: Test days of a comparison, and of one run with ``--quick``, when none are asked for.
TEST_DAYS = 5
QUICK_TEST_DAYS = 2


@dataclass(frozen=True, kw_only=True)
class CompareSettings:
    """Everything a comparison depends on (all of it is written into the report)."""

    train_days: int
    test_days: int
    seed: int
    n_seeds: int = 10
    epochs: int | None = None  # None: see training_epochs
    # 8 h of history: the thermal mass's slow mode needs more than the paper's 4 h to be
    # estimated in winter (24 h-ahead bias on the oracle trajectory 0.002 K at 16, 0.05 K at 8).
    depth: int = 16
    recipe: str = "converged"
    policy: str = "random-level"
    # The controllers' defaults: the decisions the benchmark times are the ones compared.
    shooting_samples: int = _RS.n_samples
    cem_samples: int = _CEM.n_samples
    cem_iters: int = _CEM.n_iters
    cem_all_models: bool = True
    quick: bool = False

    def __post_init__(self) -> None:
        check_seed(self.seed)
        if self.policy not in RANDOM_POLICIES:
            raise ValueError(
                f"compare: unknown policy {self.policy!r}; choose one of {', '.join(RANDOM_POLICIES)}"
            )
        for name in ("train_days", "test_days", "n_seeds", "depth", "shooting_samples",
                     "cem_samples", "cem_iters"):
            if getattr(self, name) < 1:
                raise ValueError(f"compare: {name} must be >= 1, got {getattr(self, name)}")

    @classmethod
    def for_run(
        cls, *, train_days: int, days: int | None, seed: int, quick: bool, policy: str = "random-level"
    ) -> CompareSettings:
        """The defaults, or with ``quick`` small ensembles and short training; ``days`` test
        days (None: :data:`TEST_DAYS`, with ``quick`` :data:`QUICK_TEST_DAYS`). The planners
        run with their defaults either way."""
        if not quick:
            return cls(train_days=train_days, test_days=TEST_DAYS if days is None else days, seed=seed, policy=policy)
        return cls(
            policy=policy,
            train_days=train_days,
            test_days=QUICK_TEST_DAYS if days is None else days,
            seed=seed,
            n_seeds=3,
            epochs=60,
            quick=True,
        )

    @property
    def test_seed(self) -> int:
        return self.seed + 1

    @property
    def training_epochs(self) -> int:
        """``epochs``, or as many optimizer steps as the ``converged`` recipe was calibrated
        with (60 epochs of 120 days): 7200 / ``train_days`` epochs, within 60..240 (120 epochs
        at 60 days)."""
        if self.epochs is not None:
            return self.epochs
        return min(240, max(60, round(7200 / self.train_days)))

    def train_config(self, *, eta: float, u_max_w: float | None) -> TrainConfig:
        """How the comparison trains every ensemble: ``n_seeds`` members from seed ``seed``,
        ``depth``, ``recipe`` and :attr:`training_epochs`; ``eta`` the actuator's heat per
        watt, ``u_max_w`` its limit [W] (None where the data may exceed the controllers'
        limit, as a BOPTEST emulator's does)."""
        from pinn_mpc.training import TrainConfig

        return TrainConfig(
            depth=self.depth,
            n_seeds=self.n_seeds,
            first_seed=self.seed,
            epochs=self.training_epochs,
            recipe=self.recipe,
            eta=eta,
            u_max_w=u_max_w,
        )


@dataclass(frozen=True, kw_only=True)
class ComparisonResult:
    """``rows``: one KPI dict per controller (keys of :mod:`scenarios.running.kpis` plus ``controller``
    label, ``name``, ``model``, ``objective_to_oracle``, or ``objective_to_thermostat`` on a
    plant without an oracle, see :attr:`scenarios.inputs.registry.Scenario.reference`); ``rc``: RC summaries by source;
    ``trajectories`` by label; ``wall_time_s`` by stage; ``errors`` the controller exceptions
    of each run that had any (the fallback acted, see :mod:`scenarios.running.closed_loop`);
    ``prediction`` each model's prediction error (:mod:`scenarios.experiments.prediction`);
    ``days``: [first, last] dates of the ``training`` data, the ``test`` days counted and the
    ``test weather`` (warm-up and forecast lead included)."""

    rows: list[CompareRow]
    days: dict[str, list[str]]
    rc: dict[str, RcSummary]
    trajectories: dict[str, pd.DataFrame]
    wall_time_s: dict[str, float]
    errors: dict[str, tuple[str, ...]]
    prediction: list[PredictionRow] = dataclasses.field(default_factory=list)
    notes: tuple[str, ...] = ()  # what a user should know: weather outside the training range
    #: A building of several zones (:mod:`scenarios.experiments.compare_zones`): each source's
    #: zones' R and C and walls' conductances, by source (``rc`` then empty).
    zone_rc: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)
    #: Which model ``train``'s default chose and why, where the comparison ran it (zones).
    default_model: str | None = None


def run_comparison(scenario: Scenario, settings: CompareSettings) -> ComparisonResult:
    """Steps 1-3 of the module docstring; progress bars when attached to a terminal."""
    from pinn_mpc.models.arx import fit_linear
    from scenarios.running.datagen import generate

    wall: dict[str, float] = {}
    # Refuse test days that do not fit in the test weather before minutes of training: drawn
    # as run_closed_loop draws them (one warm-up day, a horizon of forecast lead rows).
    scenario.exogenous(
        days=settings.test_days + 1,
        seed=settings.test_seed,
        part="test",
        lead_steps=scenario.horizon_steps,
    )
    start = time.perf_counter()
    data = generate(
        scenario,
        days=settings.train_days,
        seed=settings.seed,
        policy=settings.policy,
        weather_part="train",
    )
    wall["training data"] = time.perf_counter() - start
    actuator = scenario.sim.actuator
    models = _train_ensembles(scenario, settings, data, wall=wall)
    start = time.perf_counter()
    identified = identify_scenario_rc(scenario, data)
    wall["identify RC"] = time.perf_counter() - start
    has_truth = scenario.reference == "oracle"  # an EnergyPlus plant has no true RC or state
    rc, rc_params = _rc_sets(scenario, identified, models, has_truth=has_truth)
    best = models[DEFAULT_ARCH]
    start = time.perf_counter()
    held_out = generate(
        scenario,
        days=settings.test_days + 1,
        seed=settings.test_seed,
        policy=settings.policy,
        weather_part="test",
    )
    # Each carries the RC identified from the same data: the fallback of cem over it.
    arx = fit_linear(ARX.name, data, eta=scenario.sim.params.eta)
    parx = fit_linear(PHYSICS_ARX.name, data, eta=scenario.sim.params.eta)
    prediction = prediction_errors(
        held_out,
        learned=models,
        linear={ARX.label: arx, PHYSICS_ARX.label: parx},
        rc={**rc_params, **({"true RC": scenario.sim.params} if has_truth else {})},
        actuator=actuator,
    )
    wall["prediction"] = time.perf_counter() - start

    n_steps = settings.test_days * scenario.steps_per_day
    plan = _controller_plan(settings, models, best, arx, parx, rc_params, has_truth=has_truth)
    rows, trajectories, errors = run_plan(scenario, settings, plan, n_steps=n_steps, wall=wall)
    for row, ratio in zip(rows, objective_ratios(rows, reference=scenario.reference), strict=True):
        if scenario.reference == "oracle":
            row["objective_to_oracle"] = ratio
        else:
            row["objective_to_thermostat"] = ratio
    notes = _notes(rows, weather_range_note(best, trajectories[rows[0]["controller"]]))
    days = {
        "training": day_span(data["time"]),
        "test": rows[0]["counted_days"],
        "test weather": rows[0]["weather_days"],
    }
    return ComparisonResult(
        rows=rows,
        days=days,
        rc=rc,
        trajectories=trajectories,
        wall_time_s=wall,
        errors=errors,
        prediction=prediction,
        notes=tuple(notes),
    )


def _train_ensembles(
    scenario: Scenario, settings: CompareSettings, data: pd.DataFrame, *, wall: dict[str, float]
) -> dict[str, LearnedModel]:
    """The compared architectures' ensembles trained on ``data`` (each one's wall time added
    to ``wall``)."""
    from pinn_mpc.training import train_model

    config = settings.train_config(eta=scenario.sim.params.eta, u_max_w=scenario.sim.u_max_w)
    models = {}
    # physreg and mlp only serve the CEM rows; without them only hybrid and physnet train.
    for arch in ARCHS if settings.cem_all_models else ARCHS[:2]:
        start = time.perf_counter()
        models[arch] = train_model(data, arch=arch, config=config, progress=True)
        wall[f"train {arch}"] = time.perf_counter() - start
    return models


def _rc_sets(
    scenario: Scenario, identified: RCParams, models: dict[str, LearnedModel], *, has_truth: bool
) -> tuple[dict[str, RcSummary], dict[str, RCParams]]:
    """The comparison's R/C values (true where the plant has them, identified, each
    physics-informed ensemble's export) and the parameter sets its RC MPCs plan on."""
    from pinn_mpc.export import export_rc

    rc: dict[str, RcSummary] = {
        **(
            {"true": rc_summary(scenario.sim.params, source=f"scenario {scenario.name}")}
            if has_truth
            else {}
        ),
        "identified": rc_summary(identified, source="identify (training data)"),
        **{
            f"{arch} export": export_rc(models[arch], source=f"{arch} ensemble (compare)")
            for arch in ARCHS[:2]
        },
    }
    rc_params: dict[str, RCParams] = {
        "identified RC": identified,
        **{
            f"{arch} RC": rc_for_mpc(params_from_summary(rc[f"{arch} export"]), scenario)
            for arch in ARCHS[:2]
        },
    }
    return rc, rc_params


def _controller_plan(
    settings: CompareSettings,
    models: dict[str, LearnedModel],
    best: LearnedModel,
    arx: ARXModel,
    parx: ARXModel,
    rc_params: dict[str, RCParams],
    *,
    has_truth: bool,
) -> list[tuple[str, str, dict[str, Any]]]:
    """Every closed loop of a comparison: (controller name, what it runs on, keyword arguments
    of build_controller), in the table's order."""
    shooting = {"n_samples": settings.shooting_samples}
    cem = {"n_samples": settings.cem_samples, "n_iters": settings.cem_iters}
    return [
        ("thermostat", "-", {}),
        ("random-shooting", DEFAULT_ARCH, {"model": best, "planner_options": shooting}),
        (
            "cem",
            f"{DEFAULT_ARCH}, no LP polish",
            {"model": best, "planner_options": {**cem, "polish_iters": 0}},
        ),
        *(
            ("cem", arch, {"model": model, "planner_options": cem})
            for arch, model in models.items()
        ),
        ("cem", ARX.label, {"model": arx, "planner_options": cem}),
        ("cem", PHYSICS_ARX.label, {"model": parx, "planner_options": cem}),
        ("casadi-mpc", "identified RC", {"rc_params": rc_params["identified RC"]}),
        ("qp-mpc", "identified RC", {"rc_params": rc_params["identified RC"]}),
        *(("qp-mpc", f"{arch} RC", {"rc_params": rc_params[f"{arch} RC"]}) for arch in ARCHS[:2]),
        ("qp-mpc", ARX.label, {"model": arx}),
        ("qp-mpc", PHYSICS_ARX.label, {"model": parx}),
        *((("oracle", "true", {}), ("clairvoyant", "true", {})) if has_truth else ()),
    ]


def run_plan(
    scenario: Scenario,
    settings: CompareSettings,
    plan: list[tuple[str, str, dict[str, Any]]],
    *,
    n_steps: int,
    wall: dict[str, float],
) -> tuple[list[CompareRow], dict[str, pd.DataFrame], dict[str, tuple[str, ...]]]:
    """Every closed loop of ``plan`` on the test days: the table's rows, each run's trajectory
    and the controller errors by label; each run's wall time is added to ``wall``."""
    rows: list[CompareRow] = []
    trajectories: dict[str, pd.DataFrame] = {}
    errors: dict[str, tuple[str, ...]] = {}
    with one_torch_thread(), tqdm(plan, desc="closed loop", unit="controller", disable=None) as bar:
        for name, model_name, kwargs in bar:
            label = name if model_name in ("-", "true") else f"{name} / {model_name}"
            bar.set_postfix_str(label)
            start = time.perf_counter()
            controller = build_controller(name, scenario, n_steps=n_steps, **kwargs)
            result = run_closed_loop(
                scenario,
                controller,
                days=settings.test_days,
                seed=settings.test_seed,
                label=label,
                weather_part="test",
            )
            wall[f"run {label}"] = time.perf_counter() - start
            rows.append({**result.kpis, "name": name, "model": model_name})
            trajectories[label] = result.trajectory
            if result.errors:
                errors[label] = result.errors
    return rows, trajectories, errors


def _notes(rows: list[CompareRow], weather_note: str | None) -> list[str]:
    """The comparison's notes: the weather outside the training range, and every RC MPC
    fallback of a planner over a learned model."""
    notes = []
    if weather_note is not None:
        notes.append(weather_note)
    for row in rows:
        if row.get("model_fallback_steps"):
            notes.append(
                f"{row['controller']}: the RC MPC fallback made {row['model_fallback_steps']} "
                f"decisions ({row['model_fallback_switches']} switch(es): "
                f"{row['model_fallback_reasons']})"
            )
    return notes


def identify_scenario_rc(scenario: Scenario, data: pd.DataFrame) -> RCParams:
    """The grey-box identification of ``data`` (on the delivered heat when it has a ``cop``
    column, as a heat pump's data has); a building of several zones:
    :func:`identify_scenario_zones`."""
    from pinn_mpc.identify import identify_rc

    result = identify_rc(data, eta=scenario.sim.params.eta)
    for note in result.notes:
        warn(note)
    return result.params


def zone_solar_inputs(scenario: Scenario) -> list[str | None]:
    """Which irradiance each zone's windows take in a building of several zones: what the
    plant knows of them (an RC plant of several zones its declared building's, None for a
    zone without windows; EnergyPlus the facade each zone's windows face, from the model's
    geometry) or, where it knows nothing, the global horizontal ``G`` for every zone, each
    zone's aperture identified."""
    known = scenario.plant.settings.zone_solar_inputs
    if known is None:
        return ["G"] * len(scenario.control_spec().zones)
    return list(known)


def identify_scenario_zones(scenario: Scenario, data: pd.DataFrame) -> MultiZoneIdentifyResult:
    """The multi-zone identification of ``data`` of a building of several zones, its layout
    the scenario's (:func:`pinn_mpc.identify_multizone.identify_multizone`): which actuator
    acts on which zone, and which irradiance each zone's windows take
    (:func:`zone_solar_inputs`); the walls fitted those between zones the plant says touch
    (:attr:`KindSettings.zone_adjacency <scenarios.plants.kinds.KindSettings.zone_adjacency>`:
    EnergyPlus's share a surface), else every pair's."""
    from pinn_mpc.actuator import actuator_columns
    from pinn_mpc.identify_multizone import identify_multizone

    spec = scenario.control_spec()
    result = identify_multizone(
        data, zones=spec.zones, actuators=spec.actuators,
        power_columns=actuator_columns("u_phys", spec.actuators), solar_inputs=zone_solar_inputs(scenario),
        dt_s=scenario.sim.dt_s, adjacency=scenario.plant.settings.zone_adjacency,
    )
    for note in result.notes:
        warn(note)
    return result


def train_scenario_zones(
    scenario: Scenario,
    data: pd.DataFrame,
    *,
    seed: int = 0,
    arch: str = AUTO,
    paper: PaperZoneTraining | None = None,
    identified: MultiZoneIdentifyResult | None = None,
) -> ModelChoice:
    """``train``'s model of ``data`` of a building of several zones, its layout the scenario's:
    with ``arch`` ``auto`` (the default) the multi-zone hybrid or physics-informed ARX,
    whichever predicts the data's last quarter better
    (:func:`pinn_mpc.model_choice.choose_zone_model`); ``hybrid``, ``parx``, ``physnet`` or
    ``physreg`` that one (:func:`pinn_mpc.models.multizone_hybrid.fit_multizone_hybrid`, its
    residual from ``seed``; :func:`pinn_mpc.models.multizone_arx.fit_multizone_arx`;
    :func:`pinn_mpc.models.multizone_paper.fit_multizone_paper`, its networks from ``seed``,
    trained as ``paper`` says: None, that function's defaults). ``identified``: the building
    already identified from ``data`` (:func:`identify_scenario_zones`), which parx and the
    paper's networks then start from instead of identifying it again (None: they identify it)."""
    from pinn_mpc.model_choice import ModelChoice, choose_zone_model
    from pinn_mpc.models.multizone_arx import fit_multizone_arx
    from pinn_mpc.models.multizone_hybrid import fit_multizone_hybrid
    from pinn_mpc.models.multizone_paper import ARCHS as PAPER_ARCHS
    from pinn_mpc.models.multizone_paper import fit_multizone_paper

    spec = scenario.control_spec()
    layout: dict[str, Any] = {
        "zones": spec.zones, "actuators": spec.actuators, "solar_inputs": zone_solar_inputs(scenario),
        "dt_s": scenario.sim.dt_s, "adjacency": scenario.plant.settings.zone_adjacency,
    }
    model: FittedModel
    if arch == AUTO:
        choice = choose_zone_model(data, seed=seed, **layout)
    elif arch in (DEFAULT_ARCH, PHYSICS_ARX.name, *PAPER_ARCHS):
        if arch == DEFAULT_ARCH:
            model = fit_multizone_hybrid(data, seed=seed, **layout)
        elif arch == PHYSICS_ARX.name:
            model = fit_multizone_arx(data, identified=identified, **layout)
        else:
            model = fit_multizone_paper(data, arch=arch, seed=seed, settings=paper, identified=identified, **layout)
        choice = ModelChoice(chosen=arch, model=model, held_out_mae_c={}, horizon_steps=0, why="as asked")
    else:
        raise ValueError(
            f"train_scenario_zones: arch {arch!r} is not fitted on a building of several zones; choose "
            f"{AUTO}, {DEFAULT_ARCH}, {PHYSICS_ARX.name} or {' or '.join(PAPER_ARCHS)}"
        )
    carried: MultiZoneIdentifyResult | None = getattr(choice.model, "identified", None)
    for note in () if carried is None else carried.notes:
        warn(note)
    return choice


def rc_for_mpc(params: RCParams, scenario: Scenario) -> RCParams:
    """A network's exported RC as the RC MPCs use it: with a heat pump they multiply by the
    COP of each forecast step themselves, so the building's own ``eta`` replaces the learned
    gain (which holds the training data's mean COP, see :func:`pinn_mpc.training.train_model`)."""
    if scenario.sim.actuator.kind == "ideal":  # a gain of 1: the learned eta is the building's
        return params
    return dataclasses.replace(params, eta=scenario.sim.params.eta)

