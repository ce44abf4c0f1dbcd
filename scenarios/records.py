"""The experiments' records: KPIs, comparison and prediction rows, sweep cells and summaries,
fleet results.

Typed dictionaries (:class:`typing.TypedDict`): at run time plain dicts, written to JSON as
they are, keys in the order the producer sets them; the types say which keys a record has,
what each holds and in which unit. Keys only some runs have (a planner over a learned model,
a fleet under a cap, a plant without an oracle, a scenario file) are ``NotRequired``. The
modelling layer's records (RC summary, evaluation metrics, trust report) are in
:mod:`pinn_mpc.records`.
"""

# No `from __future__ import annotations`: evaluated, the annotations tell NotRequired keys at
# run time too (`__optional_keys__`, which tests/test_records.py checks the producers against).
from typing import Any, NotRequired, TypedDict

from pinn_mpc.records import RcSummary, TrustReport

__all__ = [
    "AggregateSeries",
    "BuildingKpis",
    "BuildingRecord",
    "CapAccount",
    "CellKey",
    "CellRecord",
    "CellResult",
    "CompareRow",
    "CompareTable",
    "DayKpis",
    "DualAscentRecord",
    "EngineRecord",
    "FleetInfo",
    "FleetJson",
    "FleetTotals",
    "FleetTraining",
    "GridRecord",
    "Kpis",
    "PredictionRow",
    "RcSummary",
    "RunKpis",
    "SweepRow",
    "SweepSettingsRecord",
    "SweepSummary",
    "TrustReport",
]


class Kpis(TypedDict):
    """The KPIs of one building's counted intervals (:func:`scenarios.running.kpis.compute_kpis`; the
    definitions are in :mod:`scenarios.running.kpis`), in the order of :data:`scenarios.running.kpis.KPI_KEYS`."""

    energy_kwh: float
    """Delivered electrical energy [kWh]."""
    cost_eur: float
    """Price x delivered electrical energy [EUR]."""
    discomfort_kh: float
    """Time integral of the comfort-band violation [K h]."""
    discomfort_too_cold_kh: float
    """Its part below the band [K h]."""
    discomfort_too_warm_kh: float
    """Its part above the band [K h]; the two parts sum to ``discomfort_kh``."""
    discomfort_unavoidable_kh: float | None
    """The part no actuation could have avoided [K h]: the too-warm discomfort of the same
    days with the heater off (a cooling machine's: too cold with it off), from the same
    warm-up; None: not computed (BOPTEST)."""
    discomfort_avoidable_kh: float | None
    """``discomfort_kh`` - ``discomfort_unavoidable_kh`` [K h]: what the controller is judged on;
    None: not computed."""
    peak_kw: float
    """Largest interval-mean delivered electrical power [kW]."""
    objective: float
    """``cost_eur`` + comfort weight x ``discomfort_kh`` [EUR]."""
    decision_ms_median: float
    """Median wall-clock time of the controller's decisions [ms]."""
    decision_ms_mean: float
    """Mean decision time [ms]."""
    decision_ms_p95: float
    """95th percentile of the decision time [ms]."""
    time_ratio: float
    """Total decision time / simulated time [-]."""
    backup_overrides: int
    """Intervals in which the backup thermostat changed the demand."""
    fallbacks: int
    """Intervals in which the controller's documented fallback acted."""
    own_decisions_share: float
    """Share of the intervals the controller decided itself, without its fallback [-]."""
    zones: dict[str, dict[str, float]]
    """Each zone's ``discomfort_kh``, ``discomfort_too_cold_kh``, ``discomfort_too_warm_kh`` and
    ``energy_kwh`` (of the actuators on it), by the zone's name."""


class DayKpis(TypedDict):
    """One counted day of a closed loop (:func:`scenarios.running.closed_loop.day_kpis`)."""

    day: int
    """The day's number, 1 for the first counted day."""
    objective: float
    """The day's cost + comfort weight x discomfort [EUR]."""
    discomfort_kh: float
    """The day's discomfort [K h]."""
    own_decisions_share: float
    """Share of the day's intervals the controller decided itself [-]."""


class RunKpis(Kpis):
    """A closed loop's KPI JSON (:attr:`scenarios.running.closed_loop.ClosedLoopResult.kpis`,
    ``closed-loop --json``): the :class:`Kpis`, the run's labels, and a planner over a learned
    model's :class:`~pinn_mpc.records.TrustReport`."""

    controller: str
    """The controller's label (its name, or the label the run was given)."""
    scenario: str
    """The scenario's name."""
    days: int
    """Counted days (after the warm-up)."""
    seed: int
    """Seed of the weather, prices, noise and forecast errors."""
    weather_part: str
    """``test``, ``train`` or ``whole``: the part of the weather the run was drawn from."""
    counted_days: list[str]
    """[first, last] ISO date of the counted intervals."""
    weather_days: list[str]
    """[first, last] ISO date of the weather, warm-up and forecast lead included."""
    # the TrustReport of a planner over a learned model (random-shooting, cem)
    model_fallback: NotRequired[bool]
    model_fallback_switches: NotRequired[int]
    model_fallback_steps: NotRequired[int]
    model_fallback_reasons: NotRequired[dict[str, int]]
    out_of_training_range_steps: NotRequired[int]
    model_error_k: NotRequired[float]
    model_replay_error_k: NotRequired[float | None]
    rc_replay_error_k: NotRequired[float | None]
    comfort_margin_k: NotRequired[float]
    """An RC MPC planning inside the band by its replay error (ReplayMarginReport): the
    margin at the end [K]."""
    scenario_file: NotRequired[str]
    """``closed-loop --scenario FILE``: the scenario file's absolute path."""
    per_day: NotRequired[list[DayKpis]]
    """Each counted day's figures (a sweep's cells on the package's own plants)."""
    # a run on a BOPTEST scenario (scenarios.running.boptest_loop)
    boptest: NotRequired[dict[str, float | None]]
    """BOPTEST's own KPIs of the run (``GET /kpi``: ``tdis_tot``, ``ener_tot``, ...)."""
    boptest_testcase: NotRequired[str]
    boptest_version: NotRequired[str | None]
    """BOPTEST's version as the server reported it (``GET /version``)."""
    test_period: NotRequired[str]
    """BOPTEST's ``time_period``."""
    price_scenario: NotRequired[str]
    """BOPTEST's ``electricity_price``."""


class CompareRow(RunKpis):
    """A row of a comparison (:attr:`scenarios.experiments.compare.ComparisonResult.rows`): a run's KPIs,
    what ran, and its objective relative to the scenario's reference."""

    name: str
    """The controller's name (``cem``, ``qp-mpc``, ...)."""
    model: str
    """What it ran on: a model (``hybrid``, ``ARX``, ``identified RC``, ...), ``true`` or
    ``-``."""
    objective_to_oracle: NotRequired[float | None]
    """``objective`` / the oracle's [-] (None if it has none, or not positive); on a plant with
    an oracle."""
    objective_to_thermostat: NotRequired[float | None]
    """``objective`` / the thermostat's [-]; on a plant without an oracle (EnergyPlus)."""


class PredictionRow(TypedDict):
    """A model's prediction error of the room temperature
    (:func:`scenarios.experiments.prediction.prediction_errors`)."""

    model: str
    """The model's name (``hybrid``, ``ARX``, ``identified RC``, ...)."""
    kind: str
    """``learned``, ``linear`` or ``RC``."""
    T_r_mae_c: float
    """MAE of T_r at the main horizon [K] (NaN when the data is too short for it)."""
    T_r_bias_c: float
    """Mean of prediction - truth at the main horizon [K]."""
    n_starts: int
    """Starts the main horizon's errors are taken over."""
    T_r_mae_by_horizon_c: dict[str, float]
    """MAE [K] by intervals ahead (as a string), for each horizon the data holds."""
    T_r_mae_by_zone_c: NotRequired[dict[str, float]]
    """A model of several zones: each zone's MAE [K] at the main horizon, by zone name."""


class CompareTable(TypedDict):
    """The JSON table of ``compare``."""

    scenario: str
    training_dates: list[str]
    """[first, last] ISO date of the training data."""
    test_dates: list[str]
    """[first, last] ISO date of the counted test days."""
    settings: dict[str, object]
    """What the comparison depended on (its report's settings table)."""
    rows: list[CompareRow]
    rc: dict[str, RcSummary]
    """The RC parameters by source (``true``, ``identified``, ``<arch> export``); empty on a
    building of several zones, whose are ``zone_rc``."""
    prediction: list[PredictionRow]
    zone_rc: NotRequired[dict[str, dict[str, object]]]
    """A building of several zones: each source's zones' R and C and walls' conductances
    (:func:`scenarios.experiments.compare_zones.zone_rc_summary`)."""


# ---- sweeps ----


class CellKey(TypedDict):
    """What a sweep cell is (the fields of :class:`scenarios.experiments.sweep.Cell`)."""

    scenario: str
    """A built-in scenario's name or a scenario file."""
    controller: str
    seed: int
    """Seed of the training data; the test days are drawn with ``seed + 1``."""
    train_days: int | None
    """Days of training data; None for a controller without a model."""
    test_period: NotRequired[str]
    """BOPTEST's test period (BOPTEST scenarios only)."""
    price_scenario: NotRequired[str]
    """BOPTEST's price scenario (BOPTEST scenarios only)."""


class SweepSettingsRecord(TypedDict):
    """What every cell of a sweep shares (``sweep.json``, each cell's and the summary's
    ``settings``): the fields of :class:`scenarios.experiments.sweep.SweepSettings`, the architecture and
    the package version."""

    test_days: int
    n_members: int
    """Members of each learned ensemble."""
    epochs: int | None
    """Training epochs; None: compare's rule."""
    depth: int
    """History steps the learned models see."""
    policy: str
    """The training data's policy: ``scenario`` (each scenario's own ``data_policy``) or one
    for all."""
    quick: bool
    arch: str
    """The architecture the model-based controllers plan over (``sweep --arch``)."""
    package_version: str


class CellResult(TypedDict):
    """What a cell's task returns (:func:`scenarios.experiments.sweep.run_cell`)."""

    kpis: RunKpis
    errors: list[str]
    """One line per controller exception (the fallback acted)."""
    host: str
    """The machine the cell ran on."""
    wall_time_s: float
    """Wall-clock time of the cell [s]."""
    online_log: NotRequired[list[dict[str, Any]]]
    """A controller run online: its nights, the lines of its ``log.jsonl``."""


class CellRecord(CellResult):
    """A cell's file ``cells/<name>.json``: ``cell``, ``scenario_sha256`` and ``settings``,
    then the keys of the :class:`CellResult`."""

    cell: CellKey
    scenario_sha256: str | None
    """sha256 of a scenario file's content (:func:`scenarios.experiments.sweep.scenario_digest`); None
    for a built-in scenario."""
    settings: SweepSettingsRecord
    code: NotRequired[str | None]
    """The commit of the package's checkout that ran the cell
    (:func:`scenarios.experiments.sweep.store.code_revision`); None outside a git checkout;
    absent from the records of sweeps before it was kept."""


class SweepRow(TypedDict):
    """A row of ``summary.json`` (:func:`scenarios.reports.sweep_report.summarise`): one scenario x
    controller (x training days). The ratio keys are named after the scenario's reference:
    ``objective_to_oracle_*``, ``objective_to_thermostat_*`` on a plant without an oracle, or
    ``objective_to_boptest-baseline_*`` on BOPTEST."""

    scenario: str
    test_period: NotRequired[str]
    """BOPTEST's test period (BOPTEST sweeps only)."""
    price_scenario: NotRequired[str]
    """BOPTEST's price scenario (BOPTEST sweeps only)."""
    controller: str
    train_days: int | None
    n: int
    """Seeds with a reference objective."""
    reference: str
    """The controller the objectives are divided by (``oracle`` or ``thermostat``)."""
    objective_to_oracle_mean: NotRequired[float]
    """Mean over seeds of objective / the oracle's [-]."""
    objective_to_oracle_ci95: NotRequired[list[float | None]]
    """Its 95 % Student t interval ([None, None] for one seed)."""
    objective_to_oracle_by_seed: NotRequired[dict[str, float]]
    """The ratio by seed (as a string)."""
    objective_to_thermostat_mean: NotRequired[float]
    objective_to_thermostat_ci95: NotRequired[list[float | None]]
    objective_to_thermostat_by_seed: NotRequired[dict[str, float]]
    discomfort_avoidable_kh_mean: float | None
    """Mean over the same seeds of ``discomfort_avoidable_kh`` [K h]; None where a cell's is
    not computed (BOPTEST; a cell reused from before the split)."""
    discomfort_unavoidable_kh_mean: float | None
    """Mean over the same seeds of ``discomfort_unavoidable_kh`` [K h]; None likewise."""
    baseline: str
    """The controller of the paired differences."""
    paired_difference_n: int
    """Seeds that both this controller and the baseline have."""
    paired_difference_mean: float | None
    """Mean over those seeds of this ratio minus the baseline's [-]; None without any."""
    paired_difference_ci95: list[float | None]
    """Its 95 % interval."""


class EngineRecord(TypedDict):
    """The engine a sweep ran on (:func:`scenarios.running.ray_engine.ray_engine`)."""

    name: str
    version: str
    resources: dict[str, float]
    """The cluster's ``CPU``, ``GPU``, ``memory`` [bytes] and alive ``nodes``."""


class GridRecord(TypedDict):
    """A sweep's grid axes."""

    scenarios: list[str]
    controllers: list[str]
    seeds: list[int]
    train_days: list[int]
    archs: NotRequired[list[str]]
    """The models cem planned over (controller labels ``cem/<arch>``), when given."""
    test_periods: NotRequired[list[str]]
    """BOPTEST's test periods (BOPTEST sweeps only)."""
    price_scenarios: NotRequired[list[str]]
    """BOPTEST's price scenarios (BOPTEST sweeps only)."""


class SweepSummary(TypedDict):
    """``summary.json`` of a sweep (:attr:`scenarios.experiments.sweep.SweepOutcome.summary`)."""

    rows: list[SweepRow]
    baseline: str
    engine: EngineRecord
    cells_run: int
    cells_reused: int
    """Cells read from an earlier run's files."""
    models_trained: int
    models_reused: int
    grid: GridRecord
    settings: SweepSettingsRecord
    wall_time_s: float
    """Wall-clock time of the sweep [s]."""


# ---- fleets ----


class BuildingKpis(Kpis):
    """One building's KPIs in a fleet run (:attr:`scenarios.fleets.fleet.FleetResult.kpis`)."""

    building: int
    """The building's index in the fleet."""
    model_fallback_steps: NotRequired[int]
    """A batched run: decisions its RC MPC made for a distrusted model."""


class FleetTotals(TypedDict):
    """A fleet's totals (:func:`scenarios.fleets.fleet.fleet_totals`), in the order of
    :data:`scenarios.fleets.fleet.FLEET_TOTAL_KEYS`."""

    energy_kwh: float
    """Summed over the buildings [kWh]."""
    cost_eur: float
    """Summed [EUR]."""
    discomfort_kh: float
    """Summed [K h]."""
    discomfort_too_cold_kh: float
    """Summed [K h]."""
    discomfort_too_warm_kh: float
    """Summed [K h]."""
    discomfort_unavoidable_kh: float | None
    """Summed [K h]; None if a building's is not computed."""
    discomfort_avoidable_kh: float | None
    """Summed [K h]; None if a building's is not computed."""
    objective: float
    """Summed [EUR]."""
    peak_kw: float
    """Peak of the AGGREGATE interval-mean power [kW], not the sum of the buildings' peaks."""
    backup_overrides: int
    fallbacks: int
    buildings_with_fallbacks: int
    """Buildings whose fallback acted at least once."""


class DualAscentRecord(TypedDict):
    """The coordination's settings (:class:`controllers.coordination.DualAscent`)."""

    iterations: int
    step_eur_per_kwh: float
    max_price_eur_per_kwh: float
    secant: NotRequired[bool]
    interpolate: NotRequired[bool]


class FleetInfo(TypedDict):
    """What a fleet run was (:attr:`scenarios.fleets.fleet.FleetResult.info`, the fleet JSON's
    ``fleet``)."""

    scenario: str
    controller: str
    n_buildings: int
    days: int
    """Counted days."""
    seed: int
    spread: float
    """Log-normal spread of the fleet's R, C and solar aperture [-]."""
    weather_part: str
    batched: NotRequired[bool]
    """A batched run (:func:`scenarios.fleets.aggregator.run_coordinated_fleet`): True."""
    plans_per_step: NotRequired[float]
    """A batched run: fleet plans per counted step (above 1 when the cap's price iterated)."""
    rc_candidates: NotRequired[bool]
    """A batched cem over learned models: whether each building's RC MPC plan was scored among
    its samples (``closed-loop --rc-candidates``)."""
    dual_ascent: NotRequired[DualAscentRecord]
    """A batched run: the coordination's settings."""
    scenario_file: NotRequired[str]
    """``closed-loop --scenario FILE``: the scenario file's absolute path."""


class CapAccount(TypedDict):
    """A capped fleet run's account (:func:`scenarios.fleets.aggregator.cap_account`), measured on
    the plant's delivered power."""

    kw: float | None
    """The cap [kW]; None when no interval was capped."""
    window: str | None
    """``HH:MM-HH:MM`` of every day, or None for all day."""
    intervals: int
    """Counted intervals under the cap."""
    intervals_over: int
    """Capped intervals whose aggregate power exceeded the cap by more than 1 W."""
    kwh_over: float
    """Energy above the cap in them [kWh]."""
    max_over_kw: float
    """Largest excess over the cap [kW]."""
    curtailed_steps: NotRequired[int]
    """A run's steps whose plan the cap curtailed (set by the run, not the account)."""


class AggregateSeries(TypedDict):
    """The fleet's aggregate delivered electrical power per counted interval."""

    time: list[str]
    """Interval starts (ISO 8601)."""
    power_kw: list[float]
    """[kW], rounded to 0.1 W."""


class BuildingRecord(BuildingKpis):
    """A building of the fleet JSON: its KPIs and its parameters."""

    params: dict[str, float]
    """Its :class:`pinn_mpc.physics.RCParams` fields."""


class FleetJson(TypedDict):
    """The fleet JSON of ``closed-loop --buildings N`` (:func:`scenarios.fleets.fleet.fleet_json`)."""

    fleet: FleetInfo
    totals: FleetTotals
    district: dict[str, float]
    """District KPIs of the aggregate power (:func:`scenarios.fleets.fleet.district_kpis`)."""
    aggregate: AggregateSeries
    cap: CapAccount | None
    """None without a cap."""
    fell_back: list[int]
    """Buildings whose fallback or whose model's RC MPC acted at least once."""
    step_time: dict[str, float]
    """Wall time per counted control step [ms]: ``{controllers, plant, total}_ms_{median,
    p95}``."""
    buildings: list[BuildingRecord]


class FleetTraining(TypedDict):
    """``fleet.json`` of ``train --per-building`` (:func:`scenarios.fleets.training.train_per_building`):
    what was trained, on which data, with which settings."""

    arch: str
    """``train --arch`` (``auto``: each building's own choice, in ``chosen``)."""
    config: dict[str, float | str | None]
    """The :class:`pinn_mpc.training.TrainConfig` fields but the prior."""
    buildings: list[int]
    data_sha256: dict[str, str]
    """Each building's data digest (:func:`scenarios.fleets.training.frame_digest`)."""
    trained: list[int]
    """Buildings this run trained."""
    kept: list[int]
    """Buildings whose model was already there and loads."""
    train_seconds: dict[str, float]
    """Each trained building's fitting time [s]."""
    wall_seconds: float
    params: list[dict[str, float]] | None
    """The buildings' :class:`pinn_mpc.physics.RCParams` fields, when the data came with them."""
    chosen: NotRequired[dict[str, str]]
    """The family each building's model is (written once the run ends)."""
