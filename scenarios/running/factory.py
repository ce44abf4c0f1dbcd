"""Build any controller by its CLI name for a scenario.

``thermostat`` needs nothing; ``random-shooting`` and ``cem`` plan over a trained model
(``--model``); ``casadi-mpc`` and ``qp-mpc`` work on an RC parameter set (``--rc``, from
``pinn-mpc identify`` or ``pinn-mpc export-rc``), and ``qp-mpc`` also on an ARX model
(``--model`` of ``train --arch arx`` or ``parx``, :mod:`controllers.arx_mpc`); ``oracle`` and ``clairvoyant`` use the
scenario's true parameters (and the true T_m), as references: the QP MPC composed with the
true-state estimator (:mod:`controllers.rc_mpc.references`). On a plant of higher order than
the models (``SimConfig.plant`` 3r3c, :mod:`pinn_mpc.plant`) no 2-state QP has the true model:
they then plan on the plant's R/C without its envelope node (the 2R2C it reduces to as C_e ->
0, same steady state) with the true T_r and T_m, so they are strong references there, not
bounds. With a heat pump they plan on its COP curve at the forecast T_a (exact).

On a building of several zones or actuators (:data:`ZONE_CONTROLLERS`): ``oracle`` is the QP
MPC over zones x actuators on the true building and state; ``qp-mpc`` the same on a multi-zone
RC file (``--rc``, :class:`pinn_mpc.identify_multizone.MultiZoneIdentifyResult`'s JSON) with a
Kalman observer, and ``casadi-mpc`` that problem solved by ``casadi.qpsol``
(:mod:`controllers.rc_mpc.multizone_casadi`); ``cem`` and ``random-shooting`` plan over that file's building
(:class:`pinn_mpc.models.multizone_rc.MultiZoneRCModel`, with the scenario's backup limits) and
fall back on its QP MPC, or over the model ``train --scenario`` fits (``--model``: the
multi-zone hybrid or physics-informed ARX, with the scenario's backup limits) and fall back on
the QP MPC on the RC it carries.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias, TypeGuard

from controllers.base import Controller
from pinn_mpc.data import KW_SUSPECT_W
from pinn_mpc.errors import InputError, InternalError, setting, warn
from pinn_mpc.physics import RCParams, params_from_summary, read_rc_json, time_constants_h
from scenarios.choices import (
    CONTROLLER_NAMES,
    MODEL_CONTROLLERS,
    RC_CONTROLLERS,
    TRUTH_CONTROLLERS,
    ZONE_CONTROLLERS,
    ZONE_RC_CONTROLLERS,
)
from scenarios.inputs.registry import Scenario

if TYPE_CHECKING:
    import pandas as pd

    from controllers.base import ControlSpec
    from controllers.sampling import Guard
    from pinn_mpc.models.learned import ModelRecord
    from pinn_mpc.models.multizone_arx import MultiZoneARX
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid
    from pinn_mpc.models.multizone_paper import MultiZonePaperModel
    from pinn_mpc.models.rollout import BatchDynamics
    from pinn_mpc.multizone import MultiZoneParams

__all__ = [
    "CONTROLLER_NAMES",
    "MODEL_CONTROLLERS",
    "RC_CONTROLLERS",
    "FitChecks",
    "TRUTH_CONTROLLERS",
    "build_controller",
    "check_zone_model",
    "check_data_fits",
    "check_model_fits",
    "check_rc_fits",
    "cold_fallback_margin",
    "make_controller",
    "model_guard",
    "planner_guard",
    "read_zone_rc",
    "weather_range_note",
    "zone_backup_limits",
    "zone_planner",
]

#: Ranges of the training data's inputs a planner watches (see controllers.trust).
_WATCHED = ("T_a", "G")


@dataclass(frozen=True, kw_only=True)
class FitChecks:
    """How a model or RC file is checked against a scenario (:func:`check_model_fits`): refused
    when made on powers above ``power_slack`` x the scenario's actuator limit (default: its
    own measurements, a little noise); time constants compared with the scenario's building
    where ``true_building`` (None: where the scenario has true parameters)."""

    power_slack: float = 1.05
    true_building: bool | None = None

    def __post_init__(self) -> None:
        if not self.power_slack >= 1.0:
            raise ValueError(f"FitChecks.power_slack must be >= 1, got {self.power_slack!r}")


def _unknown(name: str) -> InputError:
    return InputError(f"unknown controller {name!r}; choose one of {', '.join(CONTROLLER_NAMES)}")


def _record(model: BatchDynamics | None) -> ModelRecord | None:
    """The training record of a model from ``train`` (None for others, e.g. the RC model)."""
    from pinn_mpc.models.learned import LearnedModel

    return model.record if isinstance(model, LearnedModel) else None


def _trained_on(model: BatchDynamics | None) -> tuple[dict[str, Any] | None, dict[str, Any]]:
    """The RC JSON object identified from a model's training data and that data's summary:
    a network's from its training record, an ARX's from :func:`pinn_mpc.arx.fit_linear`
    (``train --arch arx``, ``parx`` or ``auto``); (None, {}) for other models."""
    from pinn_mpc.models.arx import ARXModel

    record = _record(model)
    if record is not None:
        return record.identified_rc, record.training_data
    if isinstance(model, ARXModel):
        return model.identified_rc, model.training_data
    return None, {}


def _ranges(summary: Mapping[str, Any]) -> dict[str, tuple[float, float]]:
    """The training data's ranges of the watched inputs (none without a summary)."""
    return {
        name: (float(summary[f"{name}_range"][0]), float(summary[f"{name}_range"][1]))
        for name in _WATCHED
        if f"{name}_range" in summary
    }


def model_guard(model: BatchDynamics) -> Guard:
    """The fallback of a planner over ``model`` (:class:`controllers.sampling.Guard`): the RC
    identified from its training data, which ``train`` stores with every model it writes (a
    network's ``model.json``, an ARX's ``arx.json``), and the training data's input ranges.
    Models without them (older, or not from ``train``) get no RC fallback."""
    from controllers.sampling import Guard

    identified, summary = _trained_on(model)
    rc = params_from_summary(identified) if isinstance(identified, dict) else None
    return Guard(rc=rc, training_ranges=_ranges(summary))


def planner_guard(model: BatchDynamics, scenario: Scenario) -> Guard:
    """The guard of a planner over ``model`` on ``scenario`` (:func:`build_controller`'s):
    :func:`model_guard`, its fallback planning with a margin where
    :func:`cold_fallback_margin` says so."""
    guard = model_guard(model)
    if cold_fallback_margin(scenario):
        return guard._replace(settings=replace(guard.settings, fallback_margin_when_colder=True))
    return guard


def cold_fallback_margin(scenario: Scenario) -> bool:
    """Whether a guarded planner's fallback RC MPC on ``scenario`` plans inside the comfort band
    by its RC's filtered replay error while the forecast is colder than the data it was fitted
    on (:attr:`controllers.trust.TrustSettings.fallback_margin_when_colder`): where the
    identified RC errs hours ahead by its structure (the plant's kind says so,
    :attr:`scenarios.plants.kinds.KindSettings.rc_errs_hours_ahead`: EnergyPlus) and the room
    is measured without noise (the replayed error is then the RC's own, not the sensor's). An
    RC fitted on milder days, riding the band's edge on a colder one, leaves the room below
    it."""
    return scenario.plant.settings.rc_errs_hours_ahead and scenario.sim.noise_std_c == 0


def check_model_fits(
    model: BatchDynamics, scenario: Scenario, checks: FitChecks = FitChecks()
) -> list[str]:
    """Refuse a model made for another actuator (a heat pump's data has a ``cop`` column), for
    a larger one (training power above the scenario's limit, :class:`FitChecks`), on power in
    kW (peaking a thousandth of the scenario's limit) or on internal gains the scenario's
    controllers are not given (:attr:`Scenario.gains_hidden`); return warnings for a model whose data
    never came near the scenario's full power or whose identified time constants differ from
    the scenario's building (where it has true parameters) by more than a factor of 3."""
    rc, summary = _trained_on(model)
    record = _record(model)
    if record is not None:
        power_max_w: float | None = float(record.u_phys_range_w[1])
    elif "u_phys_range" in summary:
        power_max_w = float(summary["u_phys_range"][1])
    else:
        return []
    columns = summary.get("columns", [])
    gains = summary.get("I_g_range")
    return _check_fits(
        "the model", "trained on", "train", scenario,
        heat_pump_data="cop" in columns if columns else None,
        power_max_w=power_max_w,
        identified=params_from_summary(rc) if isinstance(rc, dict) else None,
        checks=checks,
        gains=_gains_text(float(gains[1]) if isinstance(gains, list) and len(gains) == 2 else None),
    )


def _gains_text(largest_w: float | None) -> str | None:
    """The internal gains data had, for :func:`_check_fits` (None: none, or 0 W at most)."""
    return None if largest_w is None or largest_w <= 0 else f"internal gains (I_g up to {largest_w / 1000:.3g} kW)"


def check_data_fits(data: pd.DataFrame, scenario: Scenario, source: str = "the data at hand") -> None:
    """Refuse, as :func:`check_model_fits` refuses a model, a data set a controller will learn
    from (``source`` names it) that is another actuator's (a heat pump's ``cop`` column on a
    scenario without one), went above the scenario's power, was in kW or holds internal gains
    its controllers are not given (:attr:`Scenario.gains_hidden`). Its warnings are not
    given: the controller's own rows extend the data. A data set without a one-zone ``u_phys``
    column is not checked."""
    if "u_phys" not in data.columns or len(data) == 0:
        return
    _check_fits(
        source, "recorded with", "give the data", scenario,
        heat_pump_data="cop" in data.columns,
        power_max_w=float(data["u_phys"].max()),
        identified=None,
        checks=FitChecks(),
        remedy="give data of this scenario's building",
        gains=_gains_text(float(data["I_g"].max()) if "I_g" in data.columns else None),
    )


def check_rc_fits(
    path: str | os.PathLike[str], scenario: Scenario, checks: FitChecks = FitChecks()
) -> list[str]:
    """:func:`check_model_fits` for an RC JSON (``identify``, ``export-rc``): refused when its
    data were another actuator's, went above the scenario's power, were in kW or held measured
    gains the scenario's controllers are not given; warnings when they stayed
    under half of it or its time constants differ from the scenario's building by more than a
    factor of 3. An RC JSON without the data's power range (written by hand, or before it was
    recorded) is checked for its time constants only."""
    params, data = read_rc_json(path)
    return _rc_fit_notes(Path(path).name, params, data, scenario, checks)


def _rc_fit_notes(
    name: str, params: RCParams, data: Mapping[str, Any], scenario: Scenario, checks: FitChecks
) -> list[str]:
    """:func:`check_rc_fits` of the RC JSON ``name``, already read as ``params`` and ``data``."""
    power = data.get("power_range_w")
    hp = data.get("heat_pump_data")
    fit = data.get("fit")
    measured_gains = isinstance(fit, dict) and fit.get("identified_gains") is True and fit.get("unmeasured_gains") is False
    return _check_fits(
        f"the RC of {name}", "identified on", "identify", scenario,
        heat_pump_data=hp if isinstance(hp, bool) else None,
        power_max_w=float(power[1]) if isinstance(power, list) and len(power) == 2 else None,
        identified=params,
        checks=checks,
        gains="measured internal gains (an I_g column)" if measured_gains else None,
    )


def _check_fits(
    what: str,
    made: str,
    command: str,
    scenario: Scenario,
    *,
    heat_pump_data: bool | None,
    power_max_w: float | None,
    identified: RCParams | None,
    checks: FitChecks,
    remedy: str | None = None,
    gains: str | None = None,
) -> list[str]:
    """The checks of :func:`check_model_fits` for ``what`` (``made`` on data; ``command`` makes
    another, ``remedy`` says so where given; ``gains`` names the internal gains the data had,
    None: none): refusals raised, warnings returned. Data with gains are refused where the
    building has gains its controllers are not given (:attr:`Scenario.gains_hidden`): the
    model would be given 0 W for them."""
    if gains is not None and scenario.gains_hidden:
        raise InputError(
            f"{what} was {made} {gains}, but the controllers of scenario {scenario.name!r} are "
            "not given its internal gains (they are unmeasured): it would plan as if there were "
            f"none; drop the data's I_g column and {command} again"
        )
    remedy = remedy or f"{command} on data of this scenario"
    heat_pump = not scenario.sim.actuator.is_ideal
    if heat_pump_data and not heat_pump:
        raise InputError(
            f"{what} was {made} heat-pump data (a cop column), but the controllers of scenario "
            f"{scenario.name!r} plan without a COP (its actuator an ideal heater or chiller, or "
            f"an emulator's measured power); {remedy}"
        )
    notes = []
    if heat_pump and heat_pump_data is False:
        notes.append(
            f"scenario {scenario.name!r} has a heat pump, but {what}'s data had no cop "
            "column: it sees electrical power only (add the COP per row as a cop column)"
        )
    u_max = scenario.sim.u_max_w
    if power_max_w is not None and 0 < power_max_w < KW_SUSPECT_W and (
        0.5 * u_max <= 1000 * power_max_w <= 1.05 * u_max
    ):
        raise InputError(
            f"{what} was {made} powers up to {power_max_w:.3g} W, but the actuator of scenario "
            f"{scenario.name!r} gives up to {u_max:.0f} W, a thousand times more: the data's "
            f"power was in kW; convert its power columns to W (x 1000) and {command} again"
        )
    if power_max_w is not None and power_max_w > checks.power_slack * u_max:
        raise InputError(
            f"{what} was {made} powers up to {power_max_w:.0f} W, but scenario {scenario.name!r}'s "
            f"actuator gives at most {u_max:.0f} W: it was made for another building; {remedy}"
        )
    if power_max_w is not None and 0 < power_max_w < 0.5 * u_max:
        notes.append(
            f"{what}'s data reach {power_max_w:.0f} W, under half the scenario's {u_max:.0f} W: "
            "it extrapolates at high power (was it made for this building?)"
        )
    # A plant without true parameters (EnergyPlus) has only nominal ones: nothing to compare.
    true_building = scenario.reference == "oracle" if checks.true_building is None else checks.true_building
    if identified is not None and true_building:
        mine = time_constants_h(identified)
        theirs = time_constants_h(scenario.sim.params)
        ratio = max(max(a / b, b / a) for a, b in zip(mine, theirs, strict=True))
        if ratio > 3:
            notes.append(
                f"{what}'s data show time constants of {mine[0]:.2g} h and {mine[1]:.2g} h, "
                f"the scenario's building {theirs[0]:.2g} h and {theirs[1]:.2g} h: "
                "is it the same building?"
            )
    return notes


def weather_range_note(model: BatchDynamics | None, trajectory: pd.DataFrame) -> str | None:
    """How far a run's weather left the model's training data (None when it stayed inside)."""
    parts = []
    units = {"T_a": "K", "G": "W/m2"}
    for name, (lo, hi) in _ranges(_trained_on(model)[1]).items():
        if name not in trajectory.columns:
            continue
        v = trajectory[name].to_numpy(dtype=float)
        above, below = float(v.max()) - hi, lo - float(v.min())
        if above > 0:
            parts.append(f"{name} up to {v.max():.1f}, {above:.1f} {units[name]} above the training data's {hi:.1f}")
        if below > 0:
            parts.append(f"{name} down to {v.min():.1f}, {below:.1f} {units[name]} below the training data's {lo:.1f}")
    if not parts:
        return None
    return "the test weather leaves the model's training range: " + "; ".join(parts)


def build_controller(
    name: str,
    scenario: Scenario,
    *,
    model: BatchDynamics | None = None,
    rc_params: RCParams | None = None,
    zone_params: MultiZoneParams | None = None,
    n_steps: int,
    planner_options: Mapping[str, Any] | None = None,
    checks: FitChecks = FitChecks(),
) -> Controller:
    """A controller by its command-line name, from objects already in memory.

    Parameters
    ----------
    name
        One of :data:`scenarios.CONTROLLER_NAMES`.
    scenario
        The scenario the controller will run on (its control spec, and the true parameters
        for ``oracle`` and ``clairvoyant``).
    model
        For ``cem`` and ``random-shooting``: a model with the rollout interface, such as a
        :class:`pinn_mpc.LearnedModel`. For ``qp-mpc``: an ARX model
        (:class:`pinn_mpc.models.arx.ARXModel`, :class:`controllers.arx_mpc.ARXQPMPC`) in place
        of ``rc_params``.
    rc_params
        For ``qp-mpc`` and ``casadi-mpc``: the RC parameters they plan on.
    zone_params
        On a building of several zones or actuators, for ``qp-mpc``, ``cem`` and
        ``random-shooting``: the multi-zone RC building they plan on (:func:`read_zone_rc`).
    n_steps
        The number of counted intervals of the run (used by ``clairvoyant``).
    planner_options
        Keyword arguments of ``random-shooting`` / ``cem`` (e.g. samples).
    checks
        How a learned or ARX ``model`` is checked against the scenario
        (:func:`check_model_fits`: refusals raised, warnings through ``warnings``).

    Returns
    -------
    Controller
        Ready for :func:`scenarios.run_closed_loop`.

    Raises
    ------
    InputError
        An unknown name, a missing model or RC, or one that does not fit the scenario.
    """
    spec = scenario.control_spec()
    options = dict(planner_options or {})
    if not spec.single and name in CONTROLLER_NAMES:
        return _zone_controller(
            name, scenario, spec, model=model, rc_params=rc_params, zone_params=zone_params, options=options
        )
    if zone_params is not None:
        raise InputError(
            f"a multi-zone RC building plans a scenario of several zones or actuators; scenario "
            f"{scenario.name!r} has one zone with one actuator: give a one-zone RC file"
        )
    if name == "thermostat":
        from controllers.thermostat import Thermostat

        return Thermostat(spec)
    if name in MODEL_CONTROLLERS:
        if model is None:
            raise ValueError(
                f"controller {name!r} plans over a trained model: give model (one of "
                "pinn_mpc.fit, or the directory of `pinn-mpc train` to make_controller's model_dir)"
            )
        from controllers.sampling import CEM, RandomShooting

        options.setdefault("guard", planner_guard(model, scenario))
        planner = RandomShooting if name == "random-shooting" else CEM
        controller = planner(model, spec, **options)  # checks heating vs cooling and interval
        for note in check_model_fits(model, scenario, checks):
            warn(note)
        return controller
    if name == "qp-mpc" and model is not None:
        arx_mpc = _arx_mpc(model, scenario, rc_params)  # checks heating vs cooling and interval
        for note in check_model_fits(model, scenario, checks):
            warn(note)
        return arx_mpc
    if name in RC_CONTROLLERS:
        if rc_params is None:
            also = f" or {setting('model_dir')} ARX_DIR (an ARX of `pinn-mpc train`)" if name == "qp-mpc" else ""
            raise InputError(
                f"controller {name!r} needs RC parameters: add {setting('rc_path')} rc.json{also} "
                "(`pinn-mpc identify` writes one from data)"
            )
        if name == "casadi-mpc":
            from controllers.rc_mpc.casadi import CasadiMPC

            return CasadiMPC(rc_params, spec)
        from controllers.rc_mpc.osqp import QPMPC

        return QPMPC(rc_params, spec)
    if name == "oracle":
        from controllers.rc_mpc.references import oracle_mpc

        return oracle_mpc(scenario.sim.params, spec)
    if name == "clairvoyant":
        from controllers.rc_mpc.references import clairvoyant_mpc

        return clairvoyant_mpc(scenario.sim.params, spec, n_steps)
    raise _unknown(name)


def _zones_text(spec: ControlSpec) -> str:
    return (
        f"{len(spec.zones)} zones ({', '.join(z.name for z in spec.zones)}) and {spec.n_actuators} "
        "actuators"
    )


def _zone_controller(
    name: str,
    scenario: Scenario,
    spec: ControlSpec,
    *,
    model: BatchDynamics | None,
    rc_params: RCParams | None,
    zone_params: MultiZoneParams | None,
    options: dict[str, Any],
) -> Controller:
    """:func:`build_controller` on a building of several zones or actuators (module docstring)."""
    from scenarios.plants.multizone import MultiZoneSettings

    where = f"scenario {scenario.name!r} has {_zones_text(spec)}"
    if name not in ZONE_CONTROLLERS:
        raise InputError(f"controller {name!r} plans one zone with one actuator; {where}: choose {' or '.join(ZONE_CONTROLLERS)}")
    settings = scenario.plant.settings
    if name == "oracle":
        from controllers.rc_mpc.references import oracle_multizone

        if not isinstance(settings, MultiZoneSettings):
            raise InputError(f"the oracle needs the true building of a multi-zone plant; {where} on another plant")
        return oracle_multizone(settings.building, spec)
    if name == "thermostat":
        from controllers.thermostat import Thermostat

        return Thermostat(spec)
    zone_model = model is not None and _is_zone_model(model)
    if rc_params is not None or (model is not None and not zone_model):
        what = f"a trained model ({setting('model_dir')})" if model is not None else "a one-zone RC"
        raise InputError(
            f"controller {name!r} plans {what} of one zone; {where}: give it a multi-zone RC file "
            f"({setting('rc_path')}, `pinn-mpc identify` on the scenario's data with its layout) or "
            f"the model `pinn-mpc train` fits on that data, given the scenario's layout, instead"
        )
    if model is not None and name in RC_CONTROLLERS:
        raise InputError(
            f"{name} plans on a multi-zone RC file ({setting('rc_path')}); write the model's with "
            "`pinn-mpc export-rc`, or plan over the model with cem or random-shooting"
        )
    if model is None and zone_params is None:
        raise InputError(
            f"controller {name!r} on a building of several zones plans on a multi-zone RC file or model; "
            f"{where}: add {setting('rc_path')} rc.json (`pinn-mpc identify` on the scenario's data writes "
            f"one) or {setting('model_dir')} DIR (`pinn-mpc train` on that data with the scenario's layout)"
        )
    if model is not None and _is_zone_model(model):
        check_zone_model(model, spec, scenario.name)
    return zone_planner(
        name, spec, model=model, zone_params=zone_params, backup_limits_c=zone_backup_limits(scenario),
        options=options,
    )


def _is_zone_model(model: BatchDynamics) -> TypeGuard[MultiZoneHybrid | MultiZoneARX | MultiZonePaperModel]:
    """Whether ``model`` is a trained model of several zones (their classes, and torch, are
    imported here: an RC or no model needs neither)."""
    from pinn_mpc.models.multizone_arx import MultiZoneARX
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid
    from pinn_mpc.models.multizone_paper import MultiZonePaperModel

    return isinstance(model, MultiZoneHybrid | MultiZoneARX | MultiZonePaperModel)


#: The backup thermostat's (low, high) limits [C]: one for every zone or one per zone.
BackupLimits: TypeAlias = tuple[float | tuple[float, ...], float | tuple[float, ...]]


def zone_backup_limits(scenario: Scenario) -> BackupLimits:
    """The limits of the backup thermostat of the scenario's building of several zones: its
    multi-zone plant's own where it gives them, else the scenario's (``SimConfig``)."""
    from scenarios.plants.multizone import MultiZoneSettings

    low, high = scenario.sim.backup_low_c, scenario.sim.backup_high_c
    settings = scenario.plant.settings
    return settings.backup_limits(low, high) if isinstance(settings, MultiZoneSettings) else (low, high)


def zone_planner(
    name: str,
    spec: ControlSpec,
    *,
    model: BatchDynamics | None = None,
    zone_params: MultiZoneParams | None = None,
    backup_limits_c: BackupLimits,
    options: Mapping[str, Any] | None = None,
) -> Controller:
    """``qp-mpc`` on the multi-zone RC ``zone_params``, or ``cem`` / ``random-shooting`` over
    the model of every zone ``model`` (else over ``zone_params``' RC) of the building ``spec``
    (any zones and actuators, one zone with a heater and a chiller too), its backup
    thermostat's limits ``backup_limits_c`` [C]: the planners :func:`build_controller` makes on
    a building of several zones, once the model or RC is checked against it."""
    options = dict(options or {})
    if name == "qp-mpc" and zone_params is not None:
        from controllers.rc_mpc.multizone import MultiZoneMPC

        return MultiZoneMPC(zone_params, spec, estimator="kalman")
    if name == "casadi-mpc" and zone_params is not None:
        from controllers.rc_mpc.multizone_casadi import MultiZoneCasadiMPC

        return MultiZoneCasadiMPC(zone_params, spec, estimator="kalman")
    from controllers.estimators import observer_noise
    from controllers.sampling import CEM, RandomShooting
    from pinn_mpc.models.multizone_arx import MultiZoneARX
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid
    from pinn_mpc.models.multizone_paper import MultiZonePaperModel
    from pinn_mpc.models.multizone_rc import MultiZoneRCModel

    process, measurement = observer_noise(spec)
    planner_settings: dict[str, Any] = {
        "backup_low_c": backup_limits_c[0], "backup_high_c": backup_limits_c[1], "process_std_c": process,
        "measurement_std_c": measurement,
    }
    planner_model: BatchDynamics
    if isinstance(model, MultiZoneHybrid | MultiZoneARX | MultiZonePaperModel):
        planner_model = model.for_planning(**planner_settings)
    elif zone_params is not None:
        planner_model = MultiZoneRCModel(zone_params, spec.actuators, spec.dt_s, **planner_settings)
    else:
        raise InternalError(f"controller {name!r} reached planning with neither a model nor an RC")
    planner = RandomShooting if name == "random-shooting" else CEM
    return planner(planner_model, spec, **options)  # the zones' margin and guard by default


def check_zone_model(model: MultiZoneHybrid | MultiZoneARX | MultiZonePaperModel, spec: ControlSpec, scenario_name: str) -> None:
    """Refuse in one line a model of several zones trained on another building than the
    scenario ``scenario_name``'s (``spec``): other zones, or other actuators (names, zones,
    heating or cooling), or another control interval."""
    label = f"{setting('model_dir')} (a model of the zones {', '.join(z.name for z in model.zones)})"
    if model.zones != spec.zones:
        raise InputError(
            f"{label}: scenario {scenario_name!r} has the zones {', '.join(z.name for z in spec.zones)}; "
            "train on the scenario's data (`pinn-mpc train` with the scenario's layout)"
        )
    mine = [(a.name, a.zone, a.heats) for a in model.actuators]
    theirs = [(a.name, a.zone, a.heats) for a in spec.actuators]
    if mine != theirs:
        raise InputError(
            f"{label}: trained with the actuators {', '.join(a.name for a in model.actuators)}, scenario "
            f"{scenario_name!r} has {', '.join(a.name for a in spec.actuators)} (names, zones and heating or "
            "cooling must match); train on the scenario's data"
        )
    if model.dt_s != spec.dt_s:
        raise InputError(
            f"{label}: trained at {model.dt_s:g} s intervals, scenario {scenario_name!r} controls every "
            f"{spec.dt_s:g} s; train on data at the scenario's interval"
        )


def read_zone_rc(path: str | os.PathLike[str], spec: ControlSpec, scenario_name: str) -> MultiZoneParams:
    """The building of a multi-zone RC file (:meth:`MultiZoneIdentifyResult.from_json
    <pinn_mpc.identify_multizone.MultiZoneIdentifyResult.from_json>`), refused in one line when
    it cannot be read, is not a multi-zone RC file, or has other zones than ``spec``'s (the
    scenario ``scenario_name``'s) in their order."""
    import json

    from pinn_mpc.identify_multizone import JSON_FORMAT, MultiZoneIdentifyResult

    label = f"the RC file {Path(path).name}"
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{label}: cannot read it ({exc}); give the multi-zone RC file of `pinn-mpc identify`") from None
    try:
        data = json.loads(text)
    except ValueError:
        data = text  # from_json names what is wrong with it
    if isinstance(data, dict) and data.get("format") != JSON_FORMAT:
        raise InputError(
            f"{label} is not a multi-zone RC file (format {data.get('format')!r}, not {JSON_FORMAT!r}), "
            f"but scenario {scenario_name!r} has {_zones_text(spec)}: give the multi-zone RC file "
            "`pinn-mpc identify` writes from the scenario's data"
        )
    params = MultiZoneIdentifyResult.from_json(data, source=label).params
    if params.zone_specs != spec.zones:
        raise InputError(
            f"{label} is a building of the zones {', '.join(z.name for z in params.zone_specs)}, but scenario "
            f"{scenario_name!r} has {', '.join(z.name for z in spec.zones)}: identify on the scenario's data"
        )
    return params


def _not_linear() -> InputError:
    return InputError(
        "qp-mpc plans on a linear model: an ARX model directory (of `pinn-mpc train`, "
        f"{setting('arch')} arx or parx) or RC parameters ({setting('rc_path')}); this {setting('model_dir')} is a learned "
        "network: plan over it with cem or random-shooting, or write its RC with "
        "`pinn-mpc export-rc`"
    )


def _both(name: str) -> InputError:
    """Both a model and RC parameters given to controller ``name``, which plans on one."""
    over = "an ARX model" if name == "qp-mpc" else "a model"
    return InputError(f"{name} plans on either RC parameters ({setting('rc_path')}) or {over} ({setting('model_dir')}), not both")


def _arx_mpc(model: BatchDynamics, scenario: Scenario, rc_params: RCParams | None) -> Controller:
    """``qp-mpc`` over a model: only a linear one (the ARX) makes its horizon a QP."""
    from pinn_mpc.models.arx import ARXModel

    if rc_params is not None:
        raise _both("qp-mpc")
    if not isinstance(model, ARXModel):
        raise _not_linear()
    from controllers.arx_mpc import ARXQPMPC

    return ARXQPMPC(model, scenario.control_spec())


def make_controller(
    name: str,
    scenario: Scenario,
    *,
    model_dir: str | os.PathLike[str] | None = None,
    rc_path: str | os.PathLike[str] | None = None,
    n_steps: int,
    checks: FitChecks = FitChecks(),
) -> Controller:
    """The controller ``name`` (see :data:`CONTROLLER_NAMES`), reading ``--model`` / ``--rc``,
    each checked against the scenario (:class:`FitChecks`).

    A model or RC file given to a controller that does not use it is an error, not ignored.
    """
    if name not in CONTROLLER_NAMES:
        raise _unknown(name)
    if model_dir is not None and name not in (*MODEL_CONTROLLERS, "qp-mpc"):
        raise InputError(
            f"{setting('model_dir')} is not used by controller {name!r}; "
            f"only {', '.join(MODEL_CONTROLLERS)} and qp-mpc (an ARX model) take it"
        )
    spec = scenario.control_spec()
    takes_rc = RC_CONTROLLERS if spec.single else ZONE_RC_CONTROLLERS
    if rc_path is not None and name not in takes_rc:
        also = "" if spec.single else " (a multi-zone RC file)"
        raise InputError(
            f"{setting('rc_path')} is not used by controller {name!r}; only {', '.join(takes_rc)} take it{also}"
        )
    if model_dir is not None and rc_path is not None:
        raise _both(name)
    model: BatchDynamics | None = None
    if model_dir is not None:
        from pinn_mpc.fitted import load

        model = load(model_dir)  # qp-mpc checks that it is linear (build_controller)
        if spec.single and model.actuators is not None:
            raise InputError(
                f"{setting('model_dir')} {model_dir} is a model of a building of several zones "
                f"({', '.join(z.name for z in model.zones)}); scenario {scenario.name!r} has one zone: "
                "give it a model trained on its own data"
            )
    rc_params = zone_params = None
    if rc_path is not None and not spec.single:
        zone_params = read_zone_rc(rc_path, spec, scenario.name)
    elif rc_path is not None:  # read once: the parameters and what the file says of its data
        rc_params, data = read_rc_json(rc_path)
        for note in _rc_fit_notes(Path(rc_path).name, rc_params, data, scenario, checks):
            warn(note)
    return build_controller(
        name, scenario, model=model, rc_params=rc_params, zone_params=zone_params, n_steps=n_steps, checks=checks
    )
