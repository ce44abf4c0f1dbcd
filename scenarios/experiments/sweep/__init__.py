"""``pinn-mpc sweep``: grids of closed loops on Ray, each model trained once, each cell kept.

A cell is one closed loop: (scenario, controller, seed[, training days]). The seed fixes the
training data (``seed``) and the test days (``seed + 1``), as in ``compare``. Controllers that
plan over a learned model (``random-shooting``, ``cem``) use an ensemble of the architecture
``train`` makes by default (the hybrid) trained on the scenario's simulated data, as ``compare``
trains it; ``qp-mpc`` / ``casadi-mpc`` the RC identified from the same data (on delivered heat
under a heat pump, as ``compare``).
Each model is trained once per scenario x seed x kind x training days, as a Ray task whose
result every cell needing it receives (Ray passes it through its object store, also between
nodes); the oracle of each scenario and seed always runs, as the denominator.

Everything is written by the driver (this process), so results land in ``DIR`` on the machine
that runs ``pinn-mpc sweep``, whatever nodes did the work:

- ``DIR/sweep.json``: the settings (test days, ensemble sizes, architecture, ...). A rerun with other
  settings is refused; the grid itself (scenarios, controllers, seeds, training days) may grow.
- ``DIR/cells/<scenario>--<controller>--seed<S>[--train<D>].json``: one file per finished
  cell, written atomically the moment it arrives. A rerun reads them and runs only the missing
  cells, so an interrupted sweep loses at most the cells in flight. A scenario file is named
  by its stem and a digest of its content (:func:`scenario_digest`): files of the same stem
  never share a cell, and a rerun after the file (or a CSV it reads) changed runs new cells.
- ``DIR/models/``: the trained models (model directories) and identified RC JSONs, reused
  by reruns that need more cells of the same scenario and seed.
- ``DIR/summary.json``, ``DIR/report.md``, ``DIR/objective_to_oracle.png``: see
  :mod:`scenarios.reports.sweep_report`.

The modules, one per concern: :mod:`.spec` (the definition file, lists and ranges),
:mod:`.grid` (settings, cells, model keys, the grid), :mod:`.models` (fitting a cell's model),
:mod:`.boptest` (a BOPTEST sweep's test case and training data), :mod:`.cells` (running a
cell), :mod:`.store` (what ``DIR`` holds) and :mod:`.engine` (Ray, progress, :func:`run_sweep`).
"""

from scenarios.experiments.sweep.boptest import boptest_training_data
from scenarios.experiments.sweep.cells import run_cell
from scenarios.experiments.sweep.engine import SweepOutcome, run_sweep
from scenarios.experiments.sweep.grid import (
    ARCH,
    BOPTEST_CONTROLLERS,
    RC_KIND,
    Cell,
    ModelKey,
    SweepGrid,
    SweepSettings,
    model_kind,
    scenario_digest,
)
from scenarios.experiments.sweep.models import fit_model
from scenarios.experiments.sweep.spec import parse_ints, parse_names, read_sweep_spec

__all__ = [
    "ARCH",
    "BOPTEST_CONTROLLERS",
    "RC_KIND",
    "Cell",
    "ModelKey",
    "SweepGrid",
    "SweepOutcome",
    "SweepSettings",
    "boptest_training_data",
    "fit_model",
    "model_kind",
    "parse_ints",
    "parse_names",
    "read_sweep_spec",
    "run_cell",
    "run_sweep",
    "scenario_digest",
]
