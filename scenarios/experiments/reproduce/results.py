"""Typed results of a reproduction and the paper's published numbers they are set against.

:class:`ReproductionResults` holds every trained ensemble's errors (:class:`EnsembleRun`) and
derives the three experiments from them; :meth:`ReproductionResults.to_json` is what
``results.json`` holds. Temperatures in C, power in W.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from pinn_mpc.choices import ARCHS
from scenarios.experiments.reproduce.config import ReproduceConfig

__all__ = [
    "PAPER_CLAIMS",
    "PAPER_VALIDATION",
    "EnsembleRun",
    "ErrorStats",
    "OneStepPredictions",
    "ReproductionResults",
    "SeriesBlock",
]

#: Paper Table val_results: one-step MAE [C] of T_r and T_m, 120 simulated days, depth 8.
PAPER_VALIDATION = {
    "mlp": {"T_r": 0.209, "T_m": 1.413},
    "physreg": {"T_r": 0.197, "T_m": 0.385},
    "physnet": {"T_r": 0.226, "T_m": 0.436},
}
#: What the paper says about Figs. res2 and res3 (cold-storage data; the plots are not in the text).
PAPER_CLAIMS = {
    "training_size": [
        "At 24 steps (12 h) PhysNet and PhysReg beat the MLP; for 15-45 days their MAE is at "
        "least 15 % lower than the MLP's.",
        "The gap closes with more data: above 90 days all three are similar.",
        "At 6 steps (3 h) the MLP beats PhysNet and is similar to PhysReg.",
        "All three beat persistence at the same horizon for most training sizes.",
    ],
    "horizon": [
        "With much training data all three have similar mean errors; the physics-informed "
        "ones have narrower error bars.",
        "With 30 days the MLP degrades fast with the horizon, close to 1 C at 24 h (48 steps); "
        "the physics-informed models stay around 0.75 C +- 0.3 C.",
    ],
}


@dataclass(frozen=True, kw_only=True)
class ErrorStats:
    """One metric of one seed ensemble: ``members`` (M,) each member's MAE, ``ensemble`` the
    MAE of the ensemble-mean prediction [C, or W for delivered power]."""

    members: tuple[float, ...]
    ensemble: float

    @classmethod
    def of(cls, members: np.ndarray, ensemble: float) -> ErrorStats:
        return cls(members=tuple(float(v) for v in members), ensemble=float(ensemble))

    @property
    def mean(self) -> float:
        """Mean over members (what the paper's figures show)."""
        return float(np.asarray(self.members).mean())

    @property
    def std(self) -> float:
        """Standard deviation over members (population, ddof 0)."""
        return float(np.asarray(self.members).std())

    def to_json(self) -> dict[str, Any]:
        return {
            "mean": self.mean,
            "std": self.std,
            "ensemble": self.ensemble,
            "members": list(self.members),
        }


def _stats_json(stats: ErrorStats | None) -> dict[str, Any] | None:
    return None if stats is None else stats.to_json()


class OneStepPredictions(NamedTuple):
    """Ensemble-mean one-step predictions on the test frame, for the validation figure: each
    (N,) at sample rows ``row``: ``T_r`` at row + 1 [C], ``u_phys`` at row [W], the hidden
    ``T_m`` at row [C] (None for the mlp)."""

    row: np.ndarray
    t_r_next_c: np.ndarray
    u_phys_w: np.ndarray
    t_m_c: np.ndarray | None


@dataclass(frozen=True, kw_only=True)
class EnsembleRun:
    """One seed ensemble (architecture, training size) evaluated on the test days.

    One-step errors of ``T_r``, delivered power and the hidden ``T_m`` (None for the mlp);
    ``horizons`` the recursive ``T_r`` errors by horizon [steps]; ``persistence`` the MAE of
    ``T_r,i+h = T_r,i`` over the same start rows, by horizon [C].
    """

    one_step_t_r: ErrorStats
    one_step_u_phys: ErrorStats
    one_step_t_m: ErrorStats | None
    horizons: Mapping[int, ErrorStats]
    persistence: Mapping[int, float]
    train_seconds: float
    final_loss: Mapping[str, float]

    def to_json(self) -> dict[str, Any]:
        return {
            "one_step": {
                "T_r_mae": self.one_step_t_r.to_json(),
                "u_phys_mae": self.one_step_u_phys.to_json(),
                "T_m_mae": _stats_json(self.one_step_t_m),
            },
            "horizons": {str(h): s.to_json() for h, s in self.horizons.items()},
            "persistence": {str(h): v for h, v in self.persistence.items()},
            "train_seconds": self.train_seconds,
            "final_loss": dict(self.final_loss),
        }


@dataclass(frozen=True, kw_only=True)
class SeriesBlock:
    """One panel of experiment 2 or 3: recursive ``T_r`` errors per architecture against ``x``,
    training sizes [days] (``x_name="days"``) or horizons [steps] (``"horizons"``)."""

    x_name: str
    x: tuple[int, ...]
    errors: Mapping[str, tuple[ErrorStats, ...]]
    persistence: tuple[float, ...]

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {self.x_name: list(self.x)}
        out |= {arch: [s.to_json() for s in self.errors[arch]] for arch in ARCHS}
        return out | {"persistence": list(self.persistence)}


@dataclass(frozen=True, kw_only=True)
class ReproductionResults:
    """Every ensemble of a reproduction, ``runs[arch][days]``, and the three experiments built
    from them. ``test`` is the test frame and ``predictions`` the validation-size ensembles'
    one-step predictions on it (for the figure; not in :meth:`to_json`). ``dates`` holds the
    first and last calendar day of the training data and of the test days."""

    config: ReproduceConfig
    hyperparameters: Mapping[str, Any]
    runs: Mapping[str, Mapping[int, EnsembleRun]]
    test: pd.DataFrame
    predictions: Mapping[str, OneStepPredictions]
    dates: Mapping[str, list[str]]

    @property
    def sizes(self) -> list[int]:
        return self.config.sizes()

    @property
    def validation(self) -> dict[str, EnsembleRun]:
        """Experiment 1: each architecture's ensemble trained on ``validation_days``."""
        return {arch: self.runs[arch][self.config.validation_days] for arch in ARCHS}

    @property
    def persistence(self) -> Mapping[int, float]:
        """Persistence MAE by horizon [C] (the same for every ensemble: same test rows)."""
        return next(iter(self.runs["mlp"].values())).persistence

    @property
    def naive_t_m_mae(self) -> float:
        """MAE [C] of taking T_m = T_r on the test days: the scale of the T_m errors."""
        t_r, t_m = self.test["T_r"].to_numpy(dtype=float), self.test["T_m"].to_numpy(dtype=float)
        return float(np.mean(np.abs(t_r - t_m)))

    def _block(self, pairs: Sequence[tuple[int, int]], *, by_days: bool) -> SeriesBlock:
        return SeriesBlock(
            x_name="days" if by_days else "horizons",
            x=tuple(d if by_days else h for d, h in pairs),
            errors={
                arch: tuple(self.runs[arch][d].horizons[h] for d, h in pairs) for arch in ARCHS
            },
            persistence=tuple(self.persistence[h] for _, h in pairs),
        )

    @property
    def training_size(self) -> dict[int, SeriesBlock]:
        """Experiment 2: per horizon [steps], errors against the training size."""
        days = self.config.train_days
        return {
            h: self._block([(d, h) for d in days], by_days=True) for h in self.config.size_horizons
        }

    @property
    def horizon(self) -> dict[int, SeriesBlock]:
        """Experiment 3: per training size [days], errors against the horizon."""
        hs = self.config.horizons
        return {
            d: self._block([(d, h) for h in hs], by_days=False) for d in self.config.horizon_days
        }

    @property
    def train_seconds_total(self) -> float:
        return sum(r.train_seconds for arch in ARCHS for r in self.runs[arch].values())

    def to_json(self) -> dict[str, Any]:
        """The ``results.json`` document."""
        return {
            "config": asdict(self.config),
            "hyperparameters": dict(self.hyperparameters),
            "sizes": self.sizes,
            "dates": dict(self.dates),
            "paper": {"validation": PAPER_VALIDATION, "claims": PAPER_CLAIMS},
            "validation": {
                arch: {
                    "T_r": run.one_step_t_r.to_json(),
                    "T_m": _stats_json(run.one_step_t_m),
                    "u_phys_w": run.one_step_u_phys.to_json(),
                }
                for arch, run in self.validation.items()
            },
            "naive_t_m_mae": self.naive_t_m_mae,
            "training_size": {str(h): b.to_json() for h, b in self.training_size.items()},
            "horizon": {str(d): b.to_json() for d, b in self.horizon.items()},
            "persistence": {str(h): v for h, v in self.persistence.items()},
            "runs": {
                arch: {str(d): run.to_json() for d, run in by_days.items()}
                for arch, by_days in self.runs.items()
            },
            "train_seconds_total": self.train_seconds_total,
        }
