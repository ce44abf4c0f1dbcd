"""Running the paper's three experiments: simulate, train every ensemble once, evaluate.

Each (architecture, training size) ensemble is trained once and evaluated at every horizon the
experiments need (see :class:`~scenarios.experiments.reproduce.config.ReproduceConfig`); the result is a
:class:`~scenarios.experiments.reproduce.results.ReproductionResults`. Nothing is written here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
from tqdm import tqdm

from pinn_mpc.choices import ARCHS
from pinn_mpc.evaluation import evaluate_model, recursive_t_r
from pinn_mpc.models import LearnedModel
from pinn_mpc.training import TrainConfig, train_model
from scenarios.experiments.reproduce.config import ReproduceConfig
from scenarios.experiments.reproduce.results import (
    EnsembleRun,
    ErrorStats,
    OneStepPredictions,
    ReproductionResults,
)
from scenarios.inputs.exogenous import day_span
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate

__all__ = ["evaluate_members", "run_experiments"]


def _member_mae(pred: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(M, N) predictions, (N,) truth -> (M,) MAE of each member."""
    return np.asarray(np.mean(np.abs(pred - truth[None]), axis=1), dtype=float)


def evaluate_members(
    model: LearnedModel, test: pd.DataFrame, horizons: Sequence[int]
) -> tuple[EnsembleRun, OneStepPredictions]:
    """Per-member and ensemble errors of one trained ensemble on the test frame, and its
    ensemble-mean one-step predictions (for plotting)."""
    ens = evaluate_model(model, test, horizons)
    one = model.predict_one_step(test)
    rows = np.asarray(one["row"])
    t_r = test["T_r"].to_numpy(dtype=float)
    t_m_pred = one["T_m"]
    one_step: Mapping[str, Any] = ens["one_step"]

    def stats(pred: np.ndarray, truth: np.ndarray, key: str) -> ErrorStats:
        return ErrorStats.of(_member_mae(pred, truth), one_step[key])

    recursive = {}
    for h in sorted({int(v) for v in horizons}):
        pred, starts = recursive_t_r(model, test, h)
        ensemble = ens["horizons"][str(h)]["T_r_mae"]
        recursive[h] = ErrorStats.of(_member_mae(pred, t_r[starts + h]), ensemble)
    run = EnsembleRun(
        one_step_t_r=stats(one["T_r_next"], t_r[rows + 1], "T_r_mae"),
        one_step_u_phys=stats(
            one["u_phys"], test["u_phys"].to_numpy(dtype=float)[rows], "u_phys_mae"
        ),
        one_step_t_m=None
        if t_m_pred is None
        else stats(t_m_pred, test["T_m"].to_numpy(dtype=float)[rows], "T_m_mae"),
        horizons=recursive,
        persistence={int(h): v["T_r_mae"] for h, v in ens["persistence"]["horizons"].items()},
        train_seconds=float(model.record.train_seconds),
        final_loss=model.record.final_loss,
    )
    predictions = OneStepPredictions(
        row=rows,
        t_r_next_c=one["T_r_next"].mean(axis=0),
        u_phys_w=one["u_phys"].mean(axis=0),
        t_m_c=None if t_m_pred is None else t_m_pred.mean(axis=0),
    )
    return run, predictions


def run_experiments(config: ReproduceConfig, *, progress: bool = True) -> ReproductionResults:
    """Simulate the training pool and the test days, train and evaluate every ensemble."""
    scenario = get_scenario(config.scenario)
    sizes = config.sizes()
    horizons = config.eval_horizons()
    per_day = scenario.steps_per_day
    jobs = [(arch, days) for days in sizes for arch in ARCHS]
    bar = tqdm(total=len(jobs) + 1, desc="reproduce", disable=None if progress else True)
    with bar:
        bar.set_postfix_str("simulating data")
        draws = {"train": (max(sizes), config.train_seed), "test": (config.test_days, config.test_seed)}
        pool, test = (
            generate(scenario, days=days, seed=seed, policy="random", weather_part=part)
            for part, (days, seed) in draws.items()
        )
        bar.update(1)
        runs: dict[str, dict[int, EnsembleRun]] = {a: {} for a in ARCHS}
        preds: dict[str, OneStepPredictions] = {}
        hp: dict[str, Any] = {}
        tc = TrainConfig(
            depth=config.depth,
            n_seeds=config.seeds,
            epochs=config.epochs,
            recipe=config.recipe,
            eta=scenario.sim.params.eta,
        )
        for arch, days in jobs:
            bar.set_postfix_str(f"{arch}, {days} days")
            train = pool.iloc[: days * per_day].reset_index(drop=True)
            train.attrs = dict(pool.attrs)
            model = train_model(train, arch=arch, config=tc, progress=False)
            runs[arch][days], one_step = evaluate_members(model, test, horizons)
            if days == config.validation_days:
                preds[arch] = one_step
            if arch != "mlp":  # the mlp trains with lambda 0: report the physics-informed recipe
                hp = model.record.hyperparameters
            bar.update(1)
    return ReproductionResults(
        config=config,
        hyperparameters=hp,
        runs=runs,
        test=test,
        predictions=preds,
        dates={"training": day_span(pool["time"]), "test": day_span(test["time"])},
    )
