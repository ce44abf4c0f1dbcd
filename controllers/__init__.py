"""Decisions: what a controller sees, the one horizon objective, estimators, controllers.

Public names (imported on first use, see :mod:`pinn_mpc.lazy`): the interface
(:class:`Controller`, :class:`ControlSpec`, :class:`Observation`, :class:`Forecast`), the
objective (:class:`HorizonObjective`), estimators (:class:`KalmanEstimator`,
:class:`OffsetFilter`, :class:`TrueState`), and the controllers: :class:`Thermostat`,
:class:`RandomShooting` and :class:`CEM` over a learned model (with their planners
:class:`RandomShootingPlanner`, :class:`CEMPlanner`), :class:`QPMPC` and :class:`CasadiMPC` on
RC parameters, :class:`ARXQPMPC` on an ARX model, and the references :func:`oracle_mpc` and
:func:`clairvoyant_mpc`. To build one
by its CLI name for a scenario, use :func:`scenarios.build_controller`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pinn_mpc.lazy import lazy_exports

if TYPE_CHECKING:
    from controllers.arx_mpc import ARXQPMPC as ARXQPMPC
    from controllers.base import Controller as Controller
    from controllers.base import ControlSpec as ControlSpec
    from controllers.base import Forecast as Forecast
    from controllers.base import Observation as Observation
    from controllers.estimators import KalmanEstimator as KalmanEstimator
    from controllers.estimators import OffsetFilter as OffsetFilter
    from controllers.estimators import TrueState as TrueState
    from controllers.objective import HorizonObjective as HorizonObjective
    from controllers.planners import CEMPlanner as CEMPlanner
    from controllers.planners import RandomShootingPlanner as RandomShootingPlanner
    from controllers.rc_mpc.casadi import CasadiMPC as CasadiMPC
    from controllers.rc_mpc.osqp import QPMPC as QPMPC
    from controllers.rc_mpc.references import clairvoyant_mpc as clairvoyant_mpc
    from controllers.rc_mpc.references import oracle_mpc as oracle_mpc
    from controllers.sampling import CEM as CEM
    from controllers.sampling import RandomShooting as RandomShooting
    from controllers.thermostat import Thermostat as Thermostat

_EXPORTS = {
    "controllers.arx_mpc": ("ARXQPMPC",),
    "controllers.base": ("ControlSpec", "Controller", "Forecast", "Observation"),
    "controllers.estimators": ("KalmanEstimator", "OffsetFilter", "TrueState"),
    "controllers.objective": ("HorizonObjective",),
    "controllers.planners": ("CEMPlanner", "RandomShootingPlanner"),
    "controllers.rc_mpc.casadi": ("CasadiMPC",),
    "controllers.rc_mpc.osqp": ("QPMPC",),
    "controllers.rc_mpc.references": ("clairvoyant_mpc", "oracle_mpc"),
    "controllers.sampling": ("CEM", "RandomShooting"),
    "controllers.thermostat": ("Thermostat",),
}
__all__ = [name for names in _EXPORTS.values() for name in names]
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
