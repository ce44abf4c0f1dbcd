"""The named choices of the experiment layer: data policies, weather parts, controllers.

They live in this light module (no numpy, pandas or torch) so that the CLI can offer them as
choices and print its help without loading what implements them; :mod:`scenarios.running.datagen`,
:mod:`scenarios.inputs.exogenous` and :mod:`scenarios.running.factory` take them from here. Scenario names are
data (:func:`scenarios.inputs.registry.scenario_names`).
"""

from __future__ import annotations

from typing import Literal, get_args

__all__ = [
    "CONTROLLER_NAMES",
    "MODEL_CONTROLLERS",
    "ONLINE_CONTROLLERS",
    "ONLINE_SUFFIX",
    "POLICIES",
    "RANDOM_POLICIES",
    "RC_CONTROLLERS",
    "TRUTH_CONTROLLERS",
    "WEATHER_PARTS",
    "ZONE_CONTROLLERS",
    "ZONE_RC_CONTROLLERS",
    "WeatherPart",
    "online_controller",
]

#: Demand policies of generated data (:mod:`scenarios.running.datagen`).
POLICIES = ("random", "random-level", "thermostat", "closed-loop")
#: The policies of training data for learned models and identification: random (on/off or
#: levels) and closed-loop (random setpoints tracked, the EnergyPlus scenarios' default).
RANDOM_POLICIES = ("random", "random-level", "closed-loop")

#: Parts of a scenario's weather (:mod:`scenarios.inputs.exogenous`).
WeatherPart = Literal["train", "test", "whole"]
WEATHER_PARTS: tuple[str, ...] = get_args(WeatherPart)

#: Controllers by what they run on (:mod:`scenarios.running.factory`): a trained model, RC
#: parameters, or the scenario's true parameters (references).
MODEL_CONTROLLERS = ("random-shooting", "cem")
RC_CONTROLLERS = ("casadi-mpc", "qp-mpc")
TRUTH_CONTROLLERS = ("oracle", "clairvoyant")
CONTROLLER_NAMES = ("thermostat", *MODEL_CONTROLLERS, *RC_CONTROLLERS, *TRUTH_CONTROLLERS)
#: The controllers of a building of several zones or actuators (the others plan one zone's
#: one actuator): the dual-setpoint thermostat per zone, the MPC over zones x actuators on the
#: true building (oracle) or on a multi-zone RC file (qp-mpc with OSQP, casadi-mpc with
#: casadi.qpsol, each with a Kalman observer), and the sampling planners over that file's
#: building (cem, random-shooting).
ZONE_CONTROLLERS = ("thermostat", "oracle", "qp-mpc", "casadi-mpc", "cem", "random-shooting")
#: The controllers that run online (:mod:`scenarios.running.online`): a planner over the model
#: it refits every night, or the RC MPC on the RC it refits every night.
ONLINE_CONTROLLERS = (*MODEL_CONTROLLERS, "qp-mpc")
#: A sweep's label of a controller run online: ``<controller>-online`` (e.g. ``cem-online``).
ONLINE_SUFFIX = "-online"
#: The controllers of a building of several zones that plan on a multi-zone RC file (``--rc``).
ZONE_RC_CONTROLLERS = ("qp-mpc", "casadi-mpc", *MODEL_CONTROLLERS)


def online_controller(label: str) -> str | None:
    """The controller a label ``<controller>-online`` runs online (one of
    :data:`ONLINE_CONTROLLERS`), None for any other label."""
    name = label.removesuffix(ONLINE_SUFFIX)
    return name if name != label and name in ONLINE_CONTROLLERS else None
