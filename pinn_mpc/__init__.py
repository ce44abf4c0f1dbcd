"""pinn-mpc: physics-informed neural network models of buildings, and control with them.

The modelling layer. Public names (imported on first use, see :mod:`pinn_mpc.lazy`):
data (:func:`read_timeseries`, :func:`write_timeseries`, :func:`validate_timeseries`), the 2R2C
physics (:class:`RCParams`, :data:`PAPER_HOUSEHOLD`, :func:`discretise`, :func:`rc_summary`,
:func:`params_from_summary`) and simulator (:class:`SimConfig`, :class:`Simulator`), learned
models (:class:`TrainConfig`, :func:`train_model`, :class:`LearnedModel`, :func:`evaluate_model`,
:data:`ARCHS`, :data:`RECIPES`), every model ``train`` makes (:class:`FittedModel`, one of any
family: :func:`fit` (every ``train --arch``, ``auto`` included), :func:`save`, :func:`load`
(any model directory)), and R/C values
(:func:`identify_rc`, :class:`IdentifyResult`, :func:`export_rc`). Bad input raises
:class:`InputError`; an internal inconsistency (a bug) raises :class:`InternalError`; input
that is accepted but deserves attention warns with :class:`PinnMpcWarning`. Controllers are in :mod:`controllers`, experiments in :mod:`scenarios`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pinn_mpc.lazy import lazy_exports

__version__ = "0.1.0"

if TYPE_CHECKING:
    from pinn_mpc.choices import ARCHS as ARCHS
    from pinn_mpc.choices import RECIPES as RECIPES
    from pinn_mpc.data import read_timeseries as read_timeseries
    from pinn_mpc.data import validate_timeseries as validate_timeseries
    from pinn_mpc.data import write_timeseries as write_timeseries
    from pinn_mpc.errors import InputError as InputError
    from pinn_mpc.errors import InternalError as InternalError
    from pinn_mpc.errors import PinnMpcWarning as PinnMpcWarning
    from pinn_mpc.evaluation import evaluate_model as evaluate_model
    from pinn_mpc.export import export_rc as export_rc
    from pinn_mpc.fitted import fit as fit
    from pinn_mpc.fitted import load as load
    from pinn_mpc.fitted import save as save
    from pinn_mpc.identify import IdentifyResult as IdentifyResult
    from pinn_mpc.identify import identify_rc as identify_rc
    from pinn_mpc.models import LearnedModel as LearnedModel
    from pinn_mpc.models.rollout import FittedModel as FittedModel
    from pinn_mpc.physics import PAPER_HOUSEHOLD as PAPER_HOUSEHOLD
    from pinn_mpc.physics import RCParams as RCParams
    from pinn_mpc.physics import discretise as discretise
    from pinn_mpc.physics import params_from_summary as params_from_summary
    from pinn_mpc.physics import rc_summary as rc_summary
    from pinn_mpc.records import EvaluationMetrics as EvaluationMetrics
    from pinn_mpc.records import RcSummary as RcSummary
    from pinn_mpc.records import TrustReport as TrustReport
    from pinn_mpc.simulator import SimConfig as SimConfig
    from pinn_mpc.simulator import Simulator as Simulator
    from pinn_mpc.training import TrainConfig as TrainConfig
    from pinn_mpc.training import train_model as train_model

_EXPORTS = {
    "pinn_mpc.choices": ("ARCHS", "RECIPES"),
    "pinn_mpc.data": ("read_timeseries", "validate_timeseries", "write_timeseries"),
    "pinn_mpc.errors": ("InputError", "InternalError", "PinnMpcWarning"),
    "pinn_mpc.evaluation": ("evaluate_model",),
    "pinn_mpc.export": ("export_rc",),
    "pinn_mpc.identify": ("IdentifyResult", "identify_rc"),
    "pinn_mpc.fitted": ("fit", "load", "save"),
    "pinn_mpc.models": ("LearnedModel",),
    "pinn_mpc.models.rollout": ("FittedModel",),
    "pinn_mpc.records": ("EvaluationMetrics", "RcSummary", "TrustReport"),
    "pinn_mpc.physics": (
        "PAPER_HOUSEHOLD", "RCParams", "discretise", "params_from_summary", "rc_summary",
    ),
    "pinn_mpc.simulator": ("SimConfig", "Simulator"),
    "pinn_mpc.training": ("TrainConfig", "train_model"),
}
__all__ = ["__version__", *(name for names in _EXPORTS.values() for name in names)]
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
