"""What a sweep fits for its cells: the learned model a planner plans over (an ensemble or an
ARX) or the RC an RC MPC works on, one Ray task per :class:`~scenarios.experiments.sweep.grid.ModelKey`."""

from __future__ import annotations

from typing import TYPE_CHECKING, TypeAlias

from pinn_mpc.errors import InputError, InternalError, setting
from pinn_mpc.physics import RCParams
from scenarios.experiments.sweep.grid import RC_KIND, ModelKey, SweepSettings
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.boptest_loop import RC_FIT as BOPTEST_RC
from scenarios.running.boptest_loop import is_boptest_scenario

if TYPE_CHECKING:
    import pandas as pd

    from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
    from pinn_mpc.models.rollout import FittedModel

__all__ = ["SweepModel", "fit_model"]

#: What a sweep fits for a cell (:func:`fit_model`): a model of any family
#: (:func:`pinn_mpc.fitted.fit`), an identified RC, or a building of several zones' identified
#: multi-zone RC.
SweepModel: TypeAlias = "FittedModel | RCParams | MultiZoneIdentifyResult"


def _model_family(model: SweepModel) -> str:
    """What a fitted model is: its family (a network's architecture, ``arx``, ``parx``), or
    the RC."""
    from pinn_mpc.identify_multizone import MultiZoneIdentifyResult

    return RC_KIND if isinstance(model, RCParams | MultiZoneIdentifyResult) else model.family


def fit_model(key: ModelKey, settings: SweepSettings, data: pd.DataFrame | None = None) -> SweepModel:
    """Fit the model ``key.kind`` names (:data:`ARCH` by default; any ``train --arch``,
    :func:`pinn_mpc.fitted.fit`; ``auto``: ``train``'s default choice) or identify the RC of
    ``key`` on the scenario's simulated data (``train_days`` days under the settings' policy, by default the scenario's, seed ``key.seed``).
    A BOPTEST scenario's ``data`` is the emulator's (:func:`boptest_training_data`), its
    ensembles trained as ``compare`` trains them (:func:`boptest_fit`)."""
    from pinn_mpc.models.multizone_paper import ARCHS as PAPER_ARCHS
    from pinn_mpc.models.registry import AUTO, DEFAULT_ARCH, PHYSICS_ARX
    from scenarios.experiments.compare import (
        CompareSettings,
        identify_scenario_rc,
        identify_scenario_zones,
        train_scenario_zones,
    )
    from scenarios.running.datagen import generate

    if is_boptest_scenario(key.scenario):
        from scenarios.running.boptest_loop import boptest_fit

        if data is None:
            raise InternalError(f"fit_model: {key.name} is a BOPTEST model and needs the emulator's data")
        config = CompareSettings(
            train_days=key.train_days, test_days=1, seed=key.seed, n_seeds=settings.n_members,
            depth=settings.depth, epochs=settings.epochs,
        ).train_config(eta=1.0, u_max_w=None)
        return boptest_fit(BOPTEST_RC if key.kind == RC_KIND else key.kind, data, config)[0]
    scenario = get_scenario(key.scenario)
    policy = scenario.data_policy if settings.policy == "scenario" else settings.policy
    data = generate(scenario, days=key.train_days, seed=key.seed, policy=policy)
    if len(scenario.control_spec().zones) > 1:
        if key.kind == RC_KIND:
            return identify_scenario_zones(scenario, data)
        if key.kind not in (AUTO, DEFAULT_ARCH, PHYSICS_ARX.name, *PAPER_ARCHS):
            raise InputError(
                f"sweep: scenario {key.scenario!r} has several zones, on which train fits the "
                f"{DEFAULT_ARCH}, the {PHYSICS_ARX.name} or the paper's {' or '.join(PAPER_ARCHS)} of every zone; "
                f"{setting('arch')} {key.kind} takes one zone"
            )
        return train_scenario_zones(scenario, data, seed=key.seed, arch=key.kind).model
    if key.kind == RC_KIND:  # as compare identifies (on delivered heat under a heat pump)
        return identify_scenario_rc(scenario, data)
    from pinn_mpc.fitted import fit
    from pinn_mpc.training import TrainConfig

    epochs = CompareSettings(
        train_days=key.train_days, test_days=1, seed=key.seed, epochs=settings.epochs
    ).training_epochs
    config = TrainConfig(
        depth=settings.depth,
        n_seeds=settings.n_members,
        first_seed=key.seed,
        epochs=epochs,
        eta=scenario.sim.params.eta,
        u_max_w=scenario.sim.u_max_w,
    )
    return fit(data, arch=key.kind, config=config).model


