"""The paper's three experiments (section 5) on the simulated household.

1. Validation (Table val_results, Fig. res1-val): MLP, PhysReg MLP and PhysNet trained on 120
   days at depth 8; one-step MAE of T_r and of the hidden T_m on 5 test days.
2. MAE versus training size (Fig. res2): the first N days of the same training set, recursive
   6- and 24-step T_r MAE, with persistence.
3. MAE versus horizon (Fig. res3): 1..48 recursive steps at 30 and 90 training days.

Errors are reported like the paper's: the mean and standard deviation over the seeded members
of each member's MAE; the MAE of the ensemble-mean prediction is kept too. The paper ran
experiments 2 and 3 on real cold-storage data, which we do not have; here all three use the
simulated household (``paper_household``, random on/off demand).

Modules: :mod:`~scenarios.experiments.reproduce.config` (what to run), :mod:`~scenarios.experiments.reproduce.experiments`
(running, returns typed results), :mod:`~scenarios.experiments.reproduce.results` (the typed results and the
paper's numbers), :mod:`~scenarios.experiments.reproduce.render` (tables, figures, ``report.md``).
"""

from __future__ import annotations

from pathlib import Path

from pinn_mpc.io import check_output_directory, check_writable
from scenarios.experiments.reproduce.config import ReproduceConfig
from scenarios.experiments.reproduce.experiments import run_experiments
from scenarios.experiments.reproduce.render import OUTPUT, validation_table, write_outputs
from scenarios.experiments.reproduce.results import (
    PAPER_CLAIMS,
    PAPER_VALIDATION,
    ReproductionResults,
)

__all__ = [
    "PAPER_CLAIMS",
    "PAPER_VALIDATION",
    "ReproduceConfig",
    "ReproductionResults",
    "run_experiments",
    "run_reproduction",
    "validation_table",
]


def run_reproduction(
    out: str | Path, config: ReproduceConfig, *, progress: bool = True, force: bool = False
) -> ReproductionResults:
    """Run the three experiments and write ``out/``: ``results.json``, ``report.md``,
    ``table1_validation.md``, ``table2_training_size.md``, ``table3_horizon.md`` and the
    figures ``fig1_validation.png``, ``fig2_training_size.png``, ``fig3_horizon.png``
    (:data:`OUTPUT`). ``out`` is checked first, before hours of training: new, empty or an
    earlier reproduction, or ``force`` (then only those files are replaced; anything else in
    ``out`` is kept)."""
    out = Path(out)
    check_writable(out / "results.json", create_parents=True)
    if out.parent.is_dir():  # else it is created at the end, and so is ``out``
        check_output_directory(out, OUTPUT, force=force)
    results = run_experiments(config, progress=progress)
    write_outputs(out, results, force=force)
    return results
