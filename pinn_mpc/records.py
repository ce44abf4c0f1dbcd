"""Records of the modelling layer that the layers above pass on and write as JSON.

Typed dictionaries (:class:`typing.TypedDict`): at run time plain dicts, so ``json.dumps``
writes them as before; the types say which keys a record has, what each holds and in which
unit. Keys only some records have are ``NotRequired``. The experiment records (KPIs, rows,
sweep cells, fleet results) are in :mod:`scenarios.records`.
"""

# No `from __future__ import annotations`: evaluated, the annotations tell NotRequired keys at
# run time too (`__optional_keys__`, which tests/test_records.py checks the producers against).
from typing import Any, NotRequired, TypedDict

__all__ = [
    "EvaluationMetrics",
    "HorizonErrors",
    "OneStepErrors",
    "PersistenceErrors",
    "RcSummary",
    "ReplayMarginReport",
    "TimeConstants",
    "TrustReport",
]


class TimeConstants(TypedDict):
    """The two time constants of a 2R2C [h]."""

    fast: float
    slow: float


class RcSummary(TypedDict):
    """The RC JSON (:func:`pinn_mpc.physics.rc_summary`; ``identify``, ``export-rc``)."""

    R_ra_K_per_W: float
    """Resistance room air - ambient [K/W]."""
    R_rm_K_per_W: float
    """Resistance room air - thermal mass [K/W]."""
    C_r_J_per_K: float
    """Capacitance of the room air [J/K]."""
    C_m_J_per_K: float
    """Capacitance of the thermal mass [J/K]."""
    eta: float
    """Heat per watt of actuator power [-] (negative for cooling)."""
    solar_aperture_m2: float
    """Solar gain per irradiance [m2]."""
    solar_to_air_fraction: float
    """Share of the solar gain that reaches the room air [-]."""
    gain_to_air_fraction: float
    """Share of the internal gains that reaches the room air [-]."""
    unmeasured_gains_W: NotRequired[list[float]]
    """Unmeasured internal gains [W] of each two-hour block of a workday, then of a weekend day
    or holiday (:attr:`pinn_mpc.physics.RCParams.unmeasured_gains_w`), where identified."""
    coefficients_per_s: dict[str, float]
    """The continuous-time coefficients (``a11`` ... ``c22``) [1/s, K/(W s), ...]."""
    time_constants_h: TimeConstants
    source: str
    """Where the values come from (``identify:<data>``, an ensemble, a scenario)."""
    member_coefficients_per_s: NotRequired[list[dict[str, float]]]
    """``export-rc`` only: the coefficients of every ensemble member."""
    fit: NotRequired[dict[str, Any]]
    """``identify`` only: the fit's statistics
    (:meth:`pinn_mpc.identify.IdentifyResult.fit_statistics`)."""
    power_range_w: NotRequired[list[float]]
    """``identify`` and ``export-rc``: the lowest and highest actuator power [W] of the data the
    values come from (electrical for a heat pump), checked against a scenario's actuator."""
    heat_pump_data: NotRequired[bool]
    """``identify`` and ``export-rc``: whether those data were a heat pump's (a ``cop`` column)."""


class OneStepErrors(TypedDict):
    """One-step errors of the ensemble mean over every row with enough history."""

    T_r_mae: float
    """Room temperature one interval ahead, MAE [K]."""
    zones: NotRequired[dict[str, float]]
    """A model of several zones: each zone's room MAE [K], by zone name."""
    u_phys_mae: NotRequired[float]
    """Delivered power, MAE [W] (not for an ARX model)."""
    T_m_mae: NotRequired[float | None]
    """Thermal mass temperature, MAE [K]; None without ``T_m`` in the data or the model
    (not for an ARX model)."""


class HorizonErrors(TypedDict):
    """The room temperature's error h intervals ahead, recursively rolled out."""

    T_r_mae: float
    """MAE of the ensemble mean [K]."""
    T_r_mae_std: NotRequired[float]
    """Standard deviation of the members' MAEs [K] (not for an ARX model)."""
    zones: NotRequired[dict[str, float]]
    """A model of several zones: each zone's room MAE [K], by zone name (``T_r_mae`` is
    their mean)."""


class PersistenceErrors(TypedDict):
    """The persistence baseline (T_r at i+h predicted as T_r at i) over the same starts."""

    horizons: dict[str, HorizonErrors]
    """By horizon (intervals ahead, as a string): ``T_r_mae`` [K]."""


class EvaluationMetrics(TypedDict):
    """The ``evaluate`` JSON (:func:`pinn_mpc.evaluation.evaluate_model`)."""

    one_step: OneStepErrors
    horizons: dict[str, HorizonErrors]
    """By horizon (intervals ahead, as a string)."""
    persistence: NotRequired[PersistenceErrors]
    """Not for an ARX model."""


class TrustReport(TypedDict):
    """How often a planner over a learned model distrusted it since its reset (the
    ``trust_report`` of :class:`controllers.sampling.RandomShooting` and
    :class:`controllers.sampling.CEM`, from :class:`controllers.trust.TrustMonitor`); a closed
    loop adds it to the run's KPIs."""

    model_fallback: bool
    """Whether an RC MPC fallback was there to take over."""
    model_fallback_switches: int
    """Switches from the model to the fallback."""
    model_fallback_steps: int
    """Decisions the fallback made."""
    model_fallback_reasons: dict[str, int]
    """Switches by reason."""
    out_of_training_range_steps: int
    """Decisions whose forecast left the model's training ranges."""
    model_error_k: float
    """Filtered absolute one-step error (innovation) of the model's T_r at the end [K],
    rounded to 0.1 mK."""
    model_replay_error_k: float | None
    """Filtered absolute error of the model replaying the recent past [K], rounded; None
    before there was one."""
    rc_replay_error_k: float | None
    """The same of the fallback RC [K]; None before there was one (or without a fallback)."""


class ReplayMarginReport(TypedDict):
    """How far inside the band an RC MPC planning with its replay error plans at the end of a
    run (:attr:`controllers.rc_mpc.problem.RCMPC.replay_report`, ``qp-mpc`` on BOPTEST); a
    closed loop adds it to the run's KPIs."""

    rc_replay_error_k: float | None
    """Filtered absolute error of its RC replaying the recent past [K], rounded; None before
    there was one."""
    comfort_margin_k: float
    """The margin it plans with [K]: that error, at most 0.5 K."""
