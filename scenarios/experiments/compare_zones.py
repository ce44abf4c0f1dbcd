"""``compare`` on a building of several zones or actuators: train, identify and run every
controller that plans such a building, on one scenario.

1. Training data: as :mod:`scenarios.experiments.compare` (``train_days`` of the training part
   of the scenario's weather under the settings' policy, seed ``seed``), with a column per zone
   and per actuator.
2. Models: ``train``'s default (:func:`~scenarios.experiments.compare.train_scenario_zones`
   with ``auto``: the multi-zone hybrid or physics-informed ARX, whichever predicts the data's
   last quarter better) and every other family ``train`` fits on such a building (the hybrid,
   parx, the paper's PhysNet and PhysReg of every zone, their networks trained for
   :func:`paper_training`'s epochs); the multi-zone grey-box RC identified from the same data
   (:func:`~scenarios.experiments.compare.identify_scenario_zones`).
3. Closed loop on the same test days as a one-zone comparison (seed ``seed + 1``, one-day
   thermostat warm-up, perfect forecasts): the dual-setpoint thermostat of every zone,
   random shooting and cem over the default model, cem over every other family (each with
   the guard of several zones, which narrows each zone's band by its model's replay error and
   hands no decision to the RC MPC by default: a row whose model replayed past the guard's
   limits says so in the notes), casadi-mpc and qp-mpc on the
   identified RC, qp-mpc on each paper network's learned RC, and the oracle where the plant
   is the package's multi-zone RC (on EnergyPlus none exists: every objective is divided by
   the thermostat's).
4. Prediction: every model's and every RC's rooms' error 1, 6, 24 and 48 steps ahead from the
   same starts of held-out data of the test part, on the data's delivered powers
   (:func:`zone_prediction_errors`; an RC from a Kalman estimate of its state, :func:`rc_models`):
   the mean over the zones, and each zone's at 24 steps.
5. RC parameters (:func:`zone_rc_summary`): each zone's R and C and each internal wall's
   conductance, of the true building (where the plant has one), the identified RC and each
   paper network's learned RC.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from pinn_mpc.choices import AUTO, DEFAULT_ARCH, PHYSICS_ARX
from pinn_mpc.errors import InputError
from scenarios.experiments.compare import (
    CompareSettings,
    ComparisonResult,
    identify_scenario_zones,
    run_plan,
    train_scenario_zones,
    zone_solar_inputs,
)
from scenarios.experiments.prediction import PREDICTION_HORIZON, PREDICTION_HORIZONS
from scenarios.inputs.exogenous import day_span
from scenarios.inputs.registry import Scenario
from scenarios.records import PredictionRow
from scenarios.reports.report import objective_ratios

if TYPE_CHECKING:
    from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
    from pinn_mpc.model_choice import ModelChoice
    from pinn_mpc.models.multizone_paper import PaperZoneTraining
    from pinn_mpc.models.rollout import FittedModel
    from pinn_mpc.multizone import MultiZoneParams

__all__ = ["paper_training", "rc_models", "run_zone_comparison", "zone_prediction_errors", "zone_rc_summary"]


def paper_training(settings: CompareSettings) -> PaperZoneTraining:
    """How a comparison trains the paper's networks of every zone: the multi-zone fit's
    defaults (:class:`~pinn_mpc.models.multizone_paper.PaperZoneTraining`, as ``train``), its
    epochs the settings' where they give them (``--quick``: 60)."""
    from pinn_mpc.models.multizone_paper import PaperZoneTraining

    return PaperZoneTraining() if settings.epochs is None else PaperZoneTraining(epochs=settings.epochs)


def zone_families() -> tuple[str, ...]:
    """The families ``train`` fits on a building of several zones, the default's candidates
    first."""
    from pinn_mpc.models.multizone_paper import ARCHS as PAPER_ARCHS

    return (DEFAULT_ARCH, PHYSICS_ARX.name, *PAPER_ARCHS)


def run_zone_comparison(scenario: Scenario, settings: CompareSettings) -> ComparisonResult:
    """Steps 1-5 of the module docstring: the rows (``default (<family>)`` names the model
    ``train`` chose), trajectories, prediction errors, RC values and wall times."""
    from scenarios.running.datagen import generate

    wall: dict[str, float] = {}
    scenario.exogenous(  # test days that do not fit are refused before any training
        days=settings.test_days + 1, seed=settings.test_seed, part="test", lead_steps=scenario.horizon_steps,
    )
    start = time.perf_counter()
    data = generate(scenario, days=settings.train_days, seed=settings.seed, policy=settings.policy,
                    weather_part="train")
    wall["training data"] = time.perf_counter() - start
    with _each_warning_once():  # every fit identifies the building again, with its notes
        identified, models, choice, notes = _fit_zone_models(scenario, settings, data, wall)
    learned_rc = {
        family: model.learned_rc() for family, model in models.items() if hasattr(model, "learned_rc")
    }
    start = time.perf_counter()
    held_out = generate(scenario, days=settings.test_days + 1, seed=settings.test_seed,
                        policy=settings.policy, weather_part="test")
    truth = _true_building(scenario)
    rc_sets = {
        "identified RC": identified,
        **{f"{family} RC": rc for family, rc in learned_rc.items()},
        **({"true RC": dataclasses.replace(identified, params=truth)} if truth is not None else {}),
    }
    prediction = zone_prediction_errors(held_out, {**models, **rc_models(scenario, rc_sets)})
    wall["prediction"] = time.perf_counter() - start

    default = f"default ({choice.chosen})"
    shooting = {"n_samples": settings.shooting_samples}
    cem = {"n_samples": settings.cem_samples, "n_iters": settings.cem_iters}
    has_truth = scenario.reference == "oracle"
    plan: list[tuple[str, str, dict[str, Any]]] = [
        ("thermostat", "-", {}),
        ("random-shooting", default, {"model": choice.model, "planner_options": shooting}),
        ("cem", default, {"model": choice.model, "planner_options": cem}),
        *(("cem", family, {"model": model, "planner_options": cem})
          for family, model in models.items() if family != choice.chosen),
        ("casadi-mpc", "identified RC", {"zone_params": identified.params}),
        ("qp-mpc", "identified RC", {"zone_params": identified.params}),
        *(("qp-mpc", f"{family} RC", {"zone_params": rc.params}) for family, rc in learned_rc.items()),
        *((("oracle", "true", {}),) if has_truth else ()),
    ]
    n_steps = settings.test_days * scenario.steps_per_day
    rows, trajectories, errors = run_plan(scenario, settings, plan, n_steps=n_steps, wall=wall)
    for row, ratio in zip(rows, objective_ratios(rows, reference=scenario.reference), strict=True):
        row["objective_to_oracle" if has_truth else "objective_to_thermostat"] = ratio
    notes += [
        f"`{row['controller']}`: its fallback (the RC MPC) decided {row['model_fallback_steps']} of "
        f"{n_steps} intervals"
        for row in rows if row.get("model_fallback_steps")
    ]
    notes += [note for note in map(_distrusted_note, rows) if note]
    zone_rc = {
        **({"true": zone_rc_summary(truth, source=f"scenario {scenario.name}")} if truth is not None else {}),
        "identified": zone_rc_summary(identified.params, source="identify (training data)"),
        **{f"{family} learned": zone_rc_summary(rc.params, source=f"the {family} of every zone (compare)")
           for family, rc in learned_rc.items()},
    }
    days = {
        "training": day_span(data["time"]),
        "test": rows[0]["counted_days"],
        "test weather": rows[0]["weather_days"],
    }
    return ComparisonResult(
        rows=rows, days=days, rc={}, trajectories=trajectories, wall_time_s=wall, errors=errors,
        prediction=prediction, notes=tuple(notes), zone_rc=zone_rc,
        default_model=f"{choice.chosen}: {choice.why}",
    )


def _fit_zone_models(
    scenario: Scenario, settings: CompareSettings, data: pd.DataFrame, wall: dict[str, float]
) -> tuple[MultiZoneIdentifyResult, dict[str, FittedModel], ModelChoice, list[str]]:
    """The identified RC, every family's model of ``data`` (the default's first), the
    default's choice and the notes of the families the data cannot fit; each fit's wall
    time added to ``wall``."""
    start = time.perf_counter()
    identified = identify_scenario_zones(scenario, data)
    wall["identify RC"] = time.perf_counter() - start
    paper = paper_training(settings)
    start = time.perf_counter()
    choice = train_scenario_zones(scenario, data, seed=settings.seed, arch=AUTO, paper=paper)
    wall[f"train {AUTO} ({choice.chosen})"] = time.perf_counter() - start
    models: dict[str, FittedModel] = {choice.chosen: choice.model}
    notes: list[str] = []
    for family in zone_families():
        if family not in models:
            start = time.perf_counter()
            try:
                models[family] = train_scenario_zones(
                    scenario, data, seed=settings.seed, arch=family, paper=paper, identified=identified
                ).model
            except InputError as e:  # too few rows for its coefficients: left out, said why
                notes.append(f"{family} is not compared: {e}")
            wall[f"train {family}"] = time.perf_counter() - start
    return identified, models, choice, notes


@contextmanager
def _each_warning_once() -> Iterator[None]:
    """Warnings raised inside, each text once (in the order first raised)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    seen: set[str] = set()
    for w in caught:
        text = str(w.message)
        if text not in seen:
            seen.add(text)
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def rc_models(scenario: Scenario, rc_sets: Mapping[str, MultiZoneIdentifyResult]) -> dict[str, FittedModel]:
    """Each multi-zone RC of ``rc_sets`` as a model whose predictions are the RC's alone
    (:class:`~pinn_mpc.models.multizone_hybrid.MultiZoneHybrid` without a residual: from a
    Kalman estimate of its state at each start, as the RC MPCs estimate it)."""
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid

    spec = scenario.control_spec()
    return {
        name: MultiZoneHybrid(rc, spec.actuators, scenario.sim.dt_s, residual=None,
                              solar_inputs=zone_solar_inputs(scenario), selection={}, training={})
        for name, rc in rc_sets.items()
    }


def _distrusted_note(row: Mapping[str, Any]) -> str:
    """What a row of a planner whose model replayed the past worse than its RC by the zones'
    trust limits (``ZONE_TRUST``'s floor and ratio), yet made every decision, should say: the
    guard of several zones hands decisions over by default only beside a credible RC, or not
    at all when asked so (:class:`controllers.zone_sampling.ZoneGuard`). Empty for any other
    row."""
    from controllers.zone_sampling import ZONE_CREDIBLE_RC_K, ZONE_TRUST

    model, rc = row.get("model_replay_error_k"), row.get("rc_replay_error_k")
    if row.get("model_fallback") is None or model is None or rc is None or row.get("model_fallback_steps"):
        return ""
    if model <= max(ZONE_TRUST.error_floor_k, ZONE_TRUST.error_ratio * rc):
        return ""
    why = (
        "the guard was asked to hand no decision to the RC MPC (`ZoneGuard(hand_over=False)`)"
        if row["model_fallback"] is False
        else "on a building of several zones the guard hands decisions to the RC MPC only beside an "
        f"RC that replays the past within {ZONE_CREDIBLE_RC_K:g} K (`ZoneGuard(hand_over=True)` "
        "hands them over whatever the RC's error)"
    )
    return (
        f"`{row['controller']}`: its model replayed the past hours {model:.2f} K off (the identified "
        f"RC {rc:.2f} K), past the guard's limits, yet made every decision: {why}"
    )


def _true_building(scenario: Scenario) -> MultiZoneParams | None:
    """The plant's building where it is the package's multi-zone RC (None on EnergyPlus)."""
    from scenarios.plants.multizone import MultiZoneSettings

    settings = scenario.plant.settings
    return settings.building if isinstance(settings, MultiZoneSettings) else None


def zone_rc_summary(params: MultiZoneParams, *, source: str) -> dict[str, Any]:
    """``source``, each zone's ``r_ra_k_per_w``, ``r_rm_k_per_w`` [K/W], ``c_r_j_per_k``,
    ``c_m_j_per_k`` [J/K] (``zones``, by name) and each internal wall's conductance [W/K]
    (``walls``, ``"zone-zone"``)."""
    return {
        "source": source,
        "zones": {
            z.zone.name: {key: float(getattr(z.rc, key))
                          for key in ("r_ra_k_per_w", "r_rm_k_per_w", "c_r_j_per_k", "c_m_j_per_k")}
            for z in params.zones
        },
        "walls": {f"{a}-{b}": u for (a, b), u in params.wall_pairs().items()},
    }


def zone_prediction_errors(
    frame: pd.DataFrame,
    models: Mapping[str, FittedModel],
    *,
    horizons: tuple[int, ...] = PREDICTION_HORIZONS,
    horizon: int = PREDICTION_HORIZON,
) -> list[PredictionRow]:
    """One row per model of several zones: its rooms' error ``horizons`` steps ahead from the
    same starts of ``frame`` (every model's first possible start on, each start with the
    longest horizon the frame holds after it), each rolled on the data's delivered powers
    and weather (``predict_paths``): MAE and bias (prediction minus truth) over the zones at
    ``horizon``, MAE by horizon, and each zone's MAE at ``horizon``
    (``T_r_mae_by_zone_c``)."""
    from pinn_mpc.zones import zone_columns

    if not models:
        return []
    first = max(int(getattr(model, "first_path_start", 0)) for model in models.values())
    longest = min(max(horizons), len(frame) - 2 - first)
    steps = [h for h in sorted({*horizons, horizon}) if h <= longest]
    if not steps:
        return []
    starts = np.arange(first, len(frame) - 1 - steps[-1])
    rows: list[PredictionRow] = []
    for name, model in models.items():
        zones = model.zones
        rooms = frame[list(zone_columns("T_r", zones))].to_numpy(dtype=float)
        paths = model.predict_paths(frame, starts, steps[-1])  # type: ignore[attr-defined]
        error = {h: paths[:, h - 1, :] - rooms[starts + h] for h in steps}
        main = error.get(horizon)
        rows.append({
            "model": name,
            "kind": "RC" if name.endswith(" RC") else "linear" if name == PHYSICS_ARX.name else "learned",
            "T_r_mae_c": float("nan") if main is None else float(np.mean(np.abs(main))),
            "T_r_bias_c": float("nan") if main is None else float(np.mean(main)),
            "n_starts": int(len(starts)),
            "T_r_mae_by_horizon_c": {str(h): float(np.mean(np.abs(e))) for h, e in error.items()},
            "T_r_mae_by_zone_c": {} if main is None else {
                z.name: float(np.mean(np.abs(main[:, i]))) for i, z in enumerate(zones)
            },
        })
    return rows
