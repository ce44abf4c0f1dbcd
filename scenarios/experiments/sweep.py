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
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import re
import socket
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias, TypedDict, cast

from tqdm import tqdm

from pinn_mpc import __version__
from pinn_mpc.choices import ARX, AUTO, DEFAULT_ARCH, MODEL_CHOICES, PHYSICS_ARX
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.io import atomic_write_json, atomic_write_text, setting_changes
from pinn_mpc.physics import RCParams, params_from_summary, rc_summary
from scenarios.choices import TRUTH_CONTROLLERS
from scenarios.inputs.registry import is_scenario_file
from scenarios.inputs.scenario_file import get_scenario
from scenarios.plants.boptest import BUILTIN_BOPTEST, TEST_PERIOD_DAYS
from scenarios.plants.boptest_client import BOPTEST_URL_ENV
from scenarios.records import (
    CellKey,
    CellRecord,
    CellResult,
    GridRecord,
    SweepSettingsRecord,
    SweepSummary,
)
from scenarios.reports.sweep_report import REFERENCE, plot_sweep, render_sweep_report, summarise
from scenarios.running.boptest_loop import BASELINE as BOPTEST_BASELINE
from scenarios.running.boptest_loop import RC_FIT as BOPTEST_RC
from scenarios.running.boptest_loop import is_boptest_scenario
from scenarios.running.factory import CONTROLLER_NAMES, MODEL_CONTROLLERS, RC_CONTROLLERS
from scenarios.running.ray_engine import check_engine_options, ray_engine

if TYPE_CHECKING:
    import pandas as pd

    from pinn_mpc.models.arx import ARXModel
    from pinn_mpc.models.learned import LearnedModel
    from pinn_mpc.models.rollout import BatchDynamics
    from scenarios.running.boptest_loop import BoptestScenario

#: What a sweep trains for a cell (:func:`fit_model`): a learned ensemble or an identified RC.
SweepModel: TypeAlias = "LearnedModel | ARXModel | RCParams"

#: The architecture the model-based controllers plan over by default: the one ``train`` makes by
#: default (``SweepSettings.arch`` another, e.g. the physics-informed ARX).
ARCH = DEFAULT_ARCH
#: The linear baselines a sweep fits instead of training (:func:`pinn_mpc.models.arx.fit_linear`).
_LINEAR = (ARX.name, PHYSICS_ARX.name)
RC_KIND = "rc"
#: Test days per cell, and with ``--quick``, when none are asked for.
TEST_DAYS = 3
QUICK_TEST_DAYS = 2
FIGURE = "objective_to_oracle.png"
#: Tasks an engine worker runs before it is replaced when the grid has an EnergyPlus scenario.
ENERGYPLUS_CALLS_PER_WORKER = 20
#: The controllers a BOPTEST sweep runs besides BOPTEST's baseline (its reference).
BOPTEST_CONTROLLERS = ("thermostat", "qp-mpc", "cem")

__all__ = ["BOPTEST_CONTROLLERS", "Cell", "ModelKey", "SweepGrid", "SweepOutcome", "SweepSettings", "boptest_training_data", "fit_model", "model_kind", "parse_ints", "parse_names", "run_cell", "run_sweep", "scenario_digest"]
#: Training-data policies of a sweep: each scenario's own, or one for all.
_POLICIES = ("scenario", "random", "random-level", "closed-loop")


@dataclass(frozen=True, kw_only=True)
class SweepSettings:
    """What every cell shares (the grid axes are separate, see :class:`SweepGrid`)."""

    test_days: int = 3
    n_members: int = 10
    epochs: int | None = None  # None: compare's rule, 7200 / train_days within 60..240
    depth: int = 16
    #: The training data's policy; ``scenario``: each scenario's own ``data_policy`` (random-level
    #: on the RC plants, closed-loop on EnergyPlus), as ``simulate`` and ``compare`` default to.
    policy: str = "scenario"
    quick: bool = False
    #: The architecture ``cem`` and ``random-shooting`` plan over (``train --arch``'s choices).
    arch: str = ARCH

    def __post_init__(self) -> None:
        for name in ("test_days", "n_members", "depth"):
            if getattr(self, name) < 1:
                raise InputError(f"sweep: {name} must be >= 1, got {getattr(self, name)}")
        if self.epochs is not None and self.epochs < 1:
            raise InputError(f"sweep: epochs must be >= 1, got {self.epochs}")
        if self.arch not in MODEL_CHOICES:
            raise InputError(f"sweep: arch {self.arch!r} is unknown; choose one of {', '.join(MODEL_CHOICES)}")
        if self.policy not in _POLICIES:
            raise InputError(f"sweep: policy {self.policy!r} is unknown; choose one of {', '.join(_POLICIES)}")

    @classmethod
    def for_run(cls, *, days: int | None, quick: bool, arch: str = ARCH) -> SweepSettings:
        """Defaults, or with ``quick`` 2-member ensembles and 30 epochs; ``days`` test days
        per cell (None: :data:`TEST_DAYS`, with ``quick`` :data:`QUICK_TEST_DAYS`)."""
        if not quick:
            return cls(test_days=TEST_DAYS if days is None else days, arch=arch)
        test_days = QUICK_TEST_DAYS if days is None else days
        return cls(test_days=test_days, n_members=2, epochs=30, quick=True, arch=arch)


@dataclass(frozen=True, kw_only=True, order=True)
class Cell:
    scenario: str
    controller: str  # a controller's name, or ``cem/<arch>``: cem over that model
    seed: int
    train_days: int | None  # None for controllers that need no model
    #: BOPTEST's test period and price scenario (None on the package's own plants).
    test_period: str | None = None
    price_scenario: str | None = None

    @property
    def name(self) -> str:
        days = "" if self.train_days is None else f"--train{self.train_days}"
        test = "" if self.test_period is None else f"--{self.test_period}--{self.price_scenario}"
        controller = self.controller.replace("/", "-")
        return f"{_label(self.scenario)}{test}--{controller}--seed{self.seed}{days}"

    @property
    def model(self) -> ModelKey | None:
        kind = model_kind(self.controller)
        if kind is None or self.train_days is None:
            return None
        return ModelKey(
            scenario=self.scenario, kind=kind, seed=self.seed, train_days=self.train_days,
            test_period=self.test_period,
        )


@dataclass(frozen=True, kw_only=True, order=True)
class ModelKey:
    scenario: str
    kind: str  # ARCH or RC_KIND
    seed: int
    train_days: int
    #: BOPTEST: the test period whose nearest days the training data are recorded on.
    test_period: str | None = None

    @property
    def name(self) -> str:
        near = "" if self.test_period is None else f"--near-{self.test_period}"
        return f"{_label(self.scenario)}--{self.kind}--seed{self.seed}--train{self.train_days}{near}"


def _label(scenario: str) -> str:
    """A scenario in file names: a built-in's name, or a scenario file's stem followed by the
    first 12 hex digits of :func:`scenario_digest`, so that two files of the same stem never
    share a cell and an edited file makes new cells (built-ins change only with the package
    version, which ``sweep.json`` pins)."""
    if not is_scenario_file(scenario) or scenario in BUILTIN_BOPTEST:
        return scenario
    return f"{Path(scenario).stem}-{scenario_digest(scenario)[:12]}"


def scenario_digest(scenario: str) -> str:
    """The sha256 of a scenario's content: the complete TOML of the resolved scenario (every
    default filled in) and the bytes of each weather, price or RC file it reads; of a BOPTEST
    scenario file, its bytes (the test case is the server's)."""
    if is_boptest_scenario(scenario):
        return hashlib.sha256(Path(scenario).read_bytes()).hexdigest()
    stat = os.stat(scenario)
    return _digest(scenario, stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=64)
def _digest(scenario: str, mtime_ns: int, size: int) -> str:
    """:func:`scenario_digest`, computed once per version of the file (its time and size)."""
    from scenarios.inputs.scenario_file import scenario_inputs, scenario_to_toml

    digest = hashlib.sha256(scenario_to_toml(get_scenario(scenario)).encode("utf-8"))
    for key, path in sorted(scenario_inputs(scenario).items()):
        if key:  # the TOML file itself is in the resolved text
            digest.update(f"\n{key}\n".encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


def _model_key(cell: Cell, settings: SweepSettings) -> ModelKey | None:
    """The model ``cell`` needs under ``settings``: its learned model (the architecture its
    label names, ``cem/<arch>``, else the settings'), its identified RC, or None."""
    key = cell.model
    if key is not None and key.kind == ARCH and "/" not in cell.controller:
        return dataclasses.replace(key, kind=settings.arch)
    return key


def model_kind(controller: str) -> str | None:
    """What a controller needs trained: the learned architecture (``cem/<arch>``: that one; a
    bare planner: :data:`ARCH`), an identified RC, or nothing."""
    name, _, arch = controller.partition("/")
    if name in MODEL_CONTROLLERS:
        return arch or ARCH
    if name in RC_CONTROLLERS:
        return RC_KIND
    return None


def _model_family(model: SweepModel) -> str:
    """What a fitted model is: a network's architecture, ``arx`` or ``parx``, or the RC."""
    from pinn_mpc.models.arx import ARXModel

    if isinstance(model, RCParams):
        return RC_KIND
    if isinstance(model, ARXModel):
        return PHYSICS_ARX.name if model.interaction else ARX.name
    return model.arch


@dataclass(frozen=True, kw_only=True)
class SweepGrid:
    """The axes of a sweep. ``archs``: the models each planner over a learned model
    (``cem``, ``random-shooting``) runs over, one controller label ``cem/<arch>`` each (``auto``:
    ``train``'s default choice); empty: the settings' one, label ``cem``. ``test_periods`` and
    ``price_scenarios``: BOPTEST's (BOPTEST scenarios only; by default peak_heat_day and
    dynamic)."""

    scenarios: tuple[str, ...]
    controllers: tuple[str, ...]
    seeds: tuple[int, ...]
    train_days: tuple[int, ...]
    archs: tuple[str, ...] = ()
    test_periods: tuple[str, ...] = ()
    price_scenarios: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for name in ("scenarios", "controllers", "seeds", "train_days"):
            if not getattr(self, name):
                raise InputError(f"sweep: no {name.replace('_', ' ')} given")
        unknown_archs = [a for a in self.archs if a not in (AUTO, *MODEL_CHOICES)]
        for controller in self.controllers:
            name, slash, arch = controller.partition("/")
            if slash and name in MODEL_CONTROLLERS:
                unknown_archs += [arch] if arch not in (AUTO, *MODEL_CHOICES) else []
            elif slash:
                raise InputError(
                    f"sweep: controller {controller!r}: only {', '.join(MODEL_CONTROLLERS)} plan "
                    "over a model (cem/<arch>)"
                )
        if unknown_archs:
            raise InputError(
                f"sweep: unknown architecture(s) {', '.join(unknown_archs)}; choose from "
                f"{AUTO}, {', '.join(MODEL_CHOICES)}"
            )
        if self.is_boptest:
            self._check_boptest()
        else:
            self._check_own()
        if min(self.train_days) < 2:
            raise InputError(f"sweep: training days must be >= 2, got {min(self.train_days)}")

    @functools.cached_property
    def is_boptest(self) -> bool:
        """Whether the grid's scenarios are BOPTEST's (a grid holds BOPTEST scenarios or the
        package's own, not both)."""
        boptest = [s for s in self.scenarios if is_boptest_scenario(s)]
        if boptest and len(boptest) != len(self.scenarios):
            own = [s for s in self.scenarios if s not in boptest]
            raise InputError(
                f"sweep: {', '.join(boptest)} run(s) on BOPTEST and {', '.join(own)} on the "
                "package's own plants; sweep them separately (their controllers and references differ)"
            )
        return bool(boptest)

    def _check_boptest(self) -> None:
        from scenarios.plants.boptest import PRICE_SCENARIOS
        from scenarios.running.boptest_loop import boptest_scenario

        allowed = (BOPTEST_BASELINE, *BOPTEST_CONTROLLERS)
        wrong = [c for c in self.controllers if c.partition("/")[0] not in allowed]
        if wrong:
            raise InputError(
                f"sweep: controller(s) {', '.join(wrong)} do not run on BOPTEST; choose from "
                f"{', '.join(allowed)} (cem also as cem/<arch>)"
            )
        for scenario in self.scenarios:
            periods = boptest_scenario(scenario).settings.points.test_periods
            bad = [p for p in self.boptest_periods if p not in periods]
            if bad:
                raise InputError(
                    f"sweep: test period(s) {', '.join(bad)} are not {scenario}'s; choose from "
                    f"{', '.join(periods)}"
                )
        bad = [p for p in self.boptest_prices if p not in PRICE_SCENARIOS]
        if bad:
            raise InputError(
                f"sweep: price scenario(s) {', '.join(bad)} are not BOPTEST's; choose from "
                f"{', '.join(PRICE_SCENARIOS)}"
            )

    def _check_own(self) -> None:
        for key, given in (("test_periods", self.test_periods), ("price_scenarios", self.price_scenarios)):
            if given:
                raise InputError(
                    f"sweep: {key} applies to BOPTEST scenarios (e.g. boptest_hydronic_heat_pump); "
                    f"{', '.join(self.scenarios)} {'is' if len(self.scenarios) == 1 else 'are'} not"
                )
        for scenario in self.scenarios:
            # an unknown name raises InputError listing the valid ones
            truth = [c for c in self.controllers if c in TRUTH_CONTROLLERS]
            if get_scenario(scenario).reference != REFERENCE and truth:
                raise InputError(
                    f"sweep: scenario {scenario!r} has no true parameters or state (EnergyPlus), "
                    f"so {', '.join(truth)} cannot run on it; leave them out (its cells are "
                    "measured against the thermostat)"
                )
        unknown = [c for c in self.controllers if c.partition("/")[0] not in CONTROLLER_NAMES]
        if unknown:
            raise InputError(
                f"sweep: unknown controller(s) {', '.join(unknown)}; "
                f"choose from {', '.join(CONTROLLER_NAMES)}"
            )

    @property
    def boptest_periods(self) -> tuple[str, ...]:
        """BOPTEST's test periods of a BOPTEST grid (peak_heat_day unless given)."""
        return self.test_periods or ("peak_heat_day",)

    @property
    def boptest_prices(self) -> tuple[str, ...]:
        """BOPTEST's price scenarios of a BOPTEST grid (dynamic unless given)."""
        return self.price_scenarios or ("dynamic",)

    @property
    def periods(self) -> tuple[str | None, ...]:
        """The test periods of the cells: BOPTEST's, (None,) on the package's own plants."""
        return self.boptest_periods if self.is_boptest else (None,)

    @property
    def prices(self) -> tuple[str | None, ...]:
        """The price scenarios of the cells: BOPTEST's, (None,) on the package's own plants."""
        return self.boptest_prices if self.is_boptest else (None,)

    @property
    def labels(self) -> tuple[str, ...]:
        """The controllers of the cells: each planner over a learned model once per arch
        (``cem/<arch>``) when ``archs`` are given, every other controller as given."""
        out: list[str] = []
        for c in self.controllers:
            many = self.archs and "/" not in c and c in MODEL_CONTROLLERS
            out += [f"{c}/{a}" for a in self.archs] if many else [c]
        return tuple(dict.fromkeys(out))

    @functools.cached_property
    def references(self) -> dict[str, str]:
        """Each scenario's reference controller (the oracle, the thermostat on a plant
        without an oracle, EnergyPlus, BOPTEST's baseline on BOPTEST): the denominator of its
        cells (read once: a scenario file is parsed on every look-up)."""
        if self.is_boptest:
            return dict.fromkeys(self.scenarios, BOPTEST_BASELINE)
        return {s: get_scenario(s).reference for s in self.scenarios}

    @property
    def has_energyplus(self) -> bool:
        return not self.is_boptest and any(ref != REFERENCE for ref in self.references.values())

    def cells(self) -> list[Cell]:
        """Every cell of the grid, plus the reference of each scenario and seed (the
        denominator), on BOPTEST for each test period and price scenario."""
        out = []
        for scenario in self.scenarios:
            for controller in dict.fromkeys([*self.labels, self.references[scenario]]):
                days: Sequence[int | None] = (
                    self.train_days if model_kind(controller) else (None,)
                )
                out += [
                    Cell(scenario=scenario, controller=controller, seed=s, train_days=d,
                         test_period=period, price_scenario=price)
                    for period in self.periods
                    for price in self.prices
                    for s in self.seeds
                    for d in days
                ]
        return out


def parse_names(text: str, what: str) -> tuple[str, ...]:
    """``"a,b"`` -> ("a", "b"), duplicates dropped; empty -> InputError."""
    names = tuple(dict.fromkeys(n.strip() for n in text.split(",") if n.strip()))
    if not names:
        raise InputError(f"sweep: no {what} given in {text!r}; give a comma-separated list")
    return names


#: Keys of a sweep definition file (``pinn-mpc sweep --spec FILE.toml``).
SPEC_KEYS = ("description", "scenarios", "controllers", "seeds", "train_days", "days", "baseline", "arch",
             "archs", "test_periods", "price_scenarios")


def read_sweep_spec(path: str | os.PathLike[str]) -> dict[str, Any]:
    """A sweep definition (TOML): lists or comma-separated strings for ``scenarios``,
    ``controllers``, ``seeds`` and ``train_days`` (ranges as ``"0-7"``), ``archs`` (cem over
    each), and BOPTEST's ``test_periods`` and ``price_scenarios``; an integer ``days``, a
    controller name ``baseline``, an architecture ``arch``; scenario files named relative to the
    definition file.
    Returns the values as the command line gives them."""
    import tomllib

    source = Path(path)
    if not source.is_file():
        raise InputError(f"{source}: no such sweep definition; see sweeps/ for examples")
    try:
        data = tomllib.loads(source.read_text(encoding="utf-8-sig"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{source}: not a valid TOML file ({exc})") from exc
    unknown = sorted(set(data) - set(SPEC_KEYS))
    if unknown:
        raise InputError(f"{source}: unknown key(s) {', '.join(unknown)}; known: {', '.join(SPEC_KEYS)}")
    out: dict[str, Any] = {}
    for key in ("scenarios", "controllers", "seeds", "train_days", "archs", "test_periods", "price_scenarios"):
        if key not in data:
            continue
        value = data[key]
        items = value if isinstance(value, list) else [value]
        if not all(isinstance(v, str | int) and not isinstance(v, bool) for v in items):
            raise InputError(f"{source}: {key} must be a list of names or numbers, or a string")
        if key == "scenarios":  # a scenario file is relative to the definition
            items = [
                str(source.parent / v) if isinstance(v, str) and v.endswith(".toml") else v
                for v in items
            ]
        out[key] = ",".join(str(v) for v in items)
    if "days" in data:
        if isinstance(data["days"], bool) or not isinstance(data["days"], int) or data["days"] < 1:
            raise InputError(f"{source}: days must be a whole number >= 1, got {data['days']!r}")
        out["days"] = data["days"]
    if "baseline" in data:
        if not isinstance(data["baseline"], str):
            raise InputError(f"{source}: baseline must be a controller name, got {data['baseline']!r}")
        out["baseline"] = data["baseline"]
    if "arch" in data:
        if data["arch"] not in MODEL_CHOICES:
            raise InputError(f"{source}: arch must be one of {', '.join(MODEL_CHOICES)}, got {data['arch']!r}")
        out["arch"] = data["arch"]
    return out


def parse_ints(text: str, what: str) -> tuple[int, ...]:
    """``"0-7"``, ``"0,3,5"`` or ``"0-3,8"`` -> sorted whole numbers >= 0; an empty range
    (``"5-2"``) or nothing at all is an InputError."""
    values: set[int] = set()
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        match = re.fullmatch(r"(\d+)(?:-(\d+))?", part)
        if match is None:
            raise InputError(
                f"sweep: {what} {part!r} is not a whole number >= 0 or a range like 0-7"
            )
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) is not None else first
        if last < first:
            raise InputError(f"sweep: {what} range {part!r} is empty; write it low-high, e.g. 0-7")
        values.update(range(first, last + 1))
    if not values:
        raise InputError(f"sweep: no {what} given in {text!r}; write e.g. 0-7 or 0,3,5")
    return tuple(sorted(values))


# ---- the adapter: the one place that calls the package's closed loop and model fitting ----


def fit_model(key: ModelKey, settings: SweepSettings, data: pd.DataFrame | None = None) -> SweepModel:
    """Train the learned ensemble (:data:`ARCH`, or the model ``key.kind`` names; ``auto``:
    ``train``'s default choice) or identify the RC of ``key`` on the scenario's simulated data
    (``train_days`` days under the settings' policy, by default the scenario's, seed ``key.seed``).
    A BOPTEST scenario's ``data`` is the emulator's (:func:`boptest_training_data`), its
    ensembles trained as ``compare`` trains them (:func:`boptest_fit`)."""
    from scenarios.experiments.compare import CompareSettings, identify_scenario_rc
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
    if key.kind == RC_KIND:  # as compare identifies (on delivered heat under a heat pump)
        return identify_scenario_rc(scenario, data)
    if key.kind in _LINEAR:
        from pinn_mpc.models.arx import fit_linear

        return fit_linear(key.kind, data, eta=scenario.sim.params.eta)
    from pinn_mpc.model_choice import fit_model as fit_named
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
    return fit_named(data, arch=key.kind, config=config).model


def boptest_training_data(key: ModelKey, boptest_url: str | None = None) -> pd.DataFrame:
    """The emulator's training data of a BOPTEST model ``key``: ``key.train_days`` days on the
    days nearest its test period, as ``compare`` and ``simulate --test-period`` take them
    (:func:`scenarios.running.boptest_loop.boptest_data`), seed ``key.seed``; ``boptest_url``
    the server when the scenario file names none."""
    from scenarios.running.boptest_loop import DATA_FIRST_DAY, boptest_data

    chosen = _boptest_chosen(key.scenario, boptest_url)
    first_day = (
        DATA_FIRST_DAY if key.test_period is None
        else chosen.settings.points.data_first_day(key.test_period, float(key.train_days))
    )
    return boptest_data(chosen, days=key.train_days, seed=key.seed, first_day=first_day)


def _boptest_chosen(scenario: str, boptest_url: str | None) -> BoptestScenario:
    from scenarios.running.boptest_loop import boptest_scenario

    chosen = boptest_scenario(scenario)
    if chosen.settings.url is None and boptest_url is not None:
        chosen = boptest_scenario(scenario, url=boptest_url)
    return chosen


def run_cell(
    cell: Cell,
    settings: SweepSettings,
    model: BatchDynamics | RCParams | None,
    boptest_url: str | None = None,
) -> CellResult:
    """One closed loop on the test days (seed + 1): ``{"kpis", "errors", "host", "wall_time_s"}``.

    ``model`` is what :func:`fit_model` returned for ``cell.model`` (None when it has none):
    the learned model a planner plans over, or the RC an RC MPC works on. On BOPTEST the
    cell is one test on the server (``boptest_url`` when the scenario file names none): the
    first ``test_days`` of its test period, its KPIs with BOPTEST's under ``boptest``.
    """
    from scenarios.running.closed_loop import one_torch_thread, run_closed_loop
    from scenarios.running.factory import build_controller

    start = time.perf_counter()
    if cell.test_period is not None:
        return _run_boptest_cell(cell, settings, model, boptest_url, start)
    scenario = get_scenario(cell.scenario)
    kind = model_kind(cell.controller)
    learned = model if kind not in (None, RC_KIND) and not isinstance(model, RCParams) else None
    controller = build_controller(
        cell.controller.partition("/")[0],  # cem/<arch>: cem, over the model of that arch
        scenario,
        model=learned,
        rc_params=model if kind == RC_KIND and isinstance(model, RCParams) else None,
        n_steps=settings.test_days * scenario.steps_per_day,
    )
    with one_torch_thread():
        result = run_closed_loop(
            scenario, controller, days=settings.test_days, seed=cell.seed + 1,
            label=cell.controller,
        )
    kpis = result.kpis
    if learned is not None:
        kpis["model"] = _model_family(cast("SweepModel", learned))  # type: ignore[typeddict-unknown-key]
    return {
        "kpis": kpis,
        "errors": list(result.errors),
        "host": socket.gethostname(),
        "wall_time_s": time.perf_counter() - start,
    }


def _run_boptest_cell(
    cell: Cell,
    settings: SweepSettings,
    model: BatchDynamics | RCParams | None,
    boptest_url: str | None,
    start: float,
) -> CellResult:
    from scenarios.plants.boptest import BoptestRun
    from scenarios.running.boptest_loop import boptest_planner, run_boptest_closed_loop
    from scenarios.running.closed_loop import one_torch_thread

    chosen = _boptest_chosen(cell.scenario, boptest_url)
    run = BoptestRun(
        time_period=cell.test_period, days=float(settings.test_days),
        price_scenario=cell.price_scenario or "dynamic",
    )
    fitted = cast("SweepModel | None", model)
    controller = boptest_planner(
        cell.controller.partition("/")[0], chosen, fitted, dt_s=run.dt_s, n_steps=run.n_intervals
    )
    with one_torch_thread():
        result = run_boptest_closed_loop(chosen, cell.controller, controller, run=run, seed=cell.seed)
    wall = time.perf_counter() - start
    kpis = result.kpis
    kpis["wall_s_per_day"] = wall / settings.test_days  # type: ignore[typeddict-unknown-key]
    if fitted is not None:
        kpis["model"] = _model_family(fitted)  # type: ignore[typeddict-unknown-key]
    return {
        "kpis": kpis,
        "errors": list(result.errors),
        "host": socket.gethostname(),
        "wall_time_s": wall,
    }


# ---- storage in DIR ----


def _settings_record(settings: SweepSettings) -> SweepSettingsRecord:
    record = {**dataclasses.asdict(settings), "package_version": __version__}
    return cast(SweepSettingsRecord, record)  # SweepSettings' fields, then two


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(
            f"{path}: not valid JSON ({exc}); it was not written by pinn-mpc sweep "
            "(whose writes are atomic): move it away and rerun"
        ) from exc


def _check_settings(out: Path, settings: SweepSettings) -> None:
    """Refuse a rerun in ``out`` with other settings than its ``sweep.json``."""
    path = out / "sweep.json"
    record = _settings_record(settings)
    if not path.exists():
        return
    stored = _read_json(path)
    before = stored.get("settings") if isinstance(stored, dict) else None
    before = before if isinstance(before, dict) else {}
    if before != record:
        diff = setting_changes(before, record)
        raise InputError(
            f"sweep: {out} holds a sweep with other settings ({diff}); "
            "use another --out, or the same settings to extend it"
        )


class _CellRecordKey(TypedDict):
    cell: CellKey
    scenario_sha256: str | None


def _cell_record_key(cell: Cell) -> _CellRecordKey:
    """What identifies a cell in its record: its fields (BOPTEST's test period and price only
    on BOPTEST) and its scenario's content digest."""
    digest = (
        scenario_digest(cell.scenario)
        if is_scenario_file(cell.scenario) and cell.scenario not in BUILTIN_BOPTEST
        else None
    )
    fields = dataclasses.asdict(cell)
    if cell.test_period is None:
        del fields["test_period"], fields["price_scenario"]
    return {"cell": cast(CellKey, fields), "scenario_sha256": digest}


def _read_cell(path: Path, cell: Cell) -> CellRecord | None:
    if not path.exists():
        return None
    record = _read_json(path)
    key = _cell_record_key(cell)
    if not isinstance(record, dict) or any(record.get(k) != v for k, v in key.items()):
        raise InputError(f"{path}: not the record of cell {cell.name}; move it away and rerun")
    return cast(CellRecord, record)  # written by this module


def _model_path(out: Path, key: ModelKey) -> Path:
    suffix = ".json" if key.kind == RC_KIND else ""
    return out / "models" / f"{key.name}{suffix}"


def _load_model(out: Path, key: ModelKey) -> SweepModel | None:
    path = _model_path(out, key)
    if not path.exists():
        return None
    if key.kind == RC_KIND:
        return params_from_summary(_read_json(path))
    from pinn_mpc.models.arx import is_arx_directory, load_arx

    if is_arx_directory(path):
        return load_arx(path)
    from pinn_mpc.artifacts import load_model

    return load_model(path)


def _store_model(out: Path, key: ModelKey, model: SweepModel) -> None:
    path = _model_path(out, key)
    if isinstance(model, RCParams):
        atomic_write_json(path, rc_summary(model, source=f"identify ({key.name})"))
        return
    from pinn_mpc.models.arx import ARXModel, save_arx

    if isinstance(model, ARXModel):
        save_arx(model, path)
        return
    from pinn_mpc.artifacts import save_model

    save_model(model, path)


def _one_blas_thread(function: Callable[..., Any], *args: Any) -> Any:
    """A Ray task body: each task holds one CPU, so its linear algebra gets one thread."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return function(*args)


def _task_failure(what: str, exc: Exception) -> InputError:
    cause = getattr(exc, "cause", None) or exc
    first = (str(cause).strip().splitlines() or [""])[0]
    return InputError(f"sweep: {what} failed: {type(cause).__name__}: {first}")


@dataclass(frozen=True, kw_only=True)
class SweepOutcome:
    summary: SweepSummary
    summary_path: Path
    report_path: Path
    figure_path: Path


def _check_out(root: Path, *, force: bool) -> None:
    """Refuse an ``--out`` that is a file, or a directory of something else than a sweep
    (unless ``force``)."""
    if root.exists() and not root.is_dir():
        raise InputError(f"sweep: --out {root} is a file; give a directory")
    if root.is_dir() and not force and not (root / "sweep.json").is_file():
        foreign = sorted(p.name + ("/" if p.is_dir() else "") for p in root.iterdir())
        if foreign:
            shown = ", ".join(foreign[:5]) + (", ..." if len(foreign) > 5 else "")
            raise InputError(
                f"sweep: --out {root} already holds {shown} and is not a sweep directory (no "
                "sweep.json); give a new or empty directory, or add --force to write the sweep's "
                "files there (nothing else in it is touched)"
            )


def _start_line(cells: int, reused: int, models: int, recordings: int) -> str:
    """What the sweep starts: its cells, its models and (BOPTEST) their training data."""
    data = f", on {recordings} recording(s) of BOPTEST training data first" if recordings else ""
    return f"sweep: {cells} cell(s) to run ({reused} reused), {models} model(s) to train{data}"


def _progress_line(
    done: int, total: int, reused: int, trained: int, elapsed_s: float, *, waiting: Mapping[str, int]
) -> str:
    """The sweep's progress: cells done of ``total``, models trained, time left, and the
    tasks still running or queued (``waiting``: their kind -> how many)."""
    from scenarios.running.closed_loop import duration_text

    run_now = done - reused
    left = (
        f"about {duration_text(elapsed_s / run_now * (total - done))} left"
        if run_now
        else "no cell finished yet"
    )
    busy = ", ".join(f"{n} {kind}(s)" for kind, n in waiting.items() if n)
    return (
        f"sweep: {done} of {total} cells ({reused} reused), {trained} model(s) "
        f"trained, {duration_text(elapsed_s)} elapsed, {left}"
        + (f"; running or queued: {busy}" if busy else "")
    )


def _run_on_ray(
    root: Path,
    grid: SweepGrid,
    settings: SweepSettings,
    *,
    keys: Sequence[ModelKey],
    missing: Sequence[Cell],
    records: dict[Cell, CellRecord | None],
    total: int,
    reused: int,
) -> int:
    """Train the models ``keys`` (those stored under ``root`` are reused) and run the
    ``missing`` cells (of ``total``, ``reused`` of them read back) as Ray tasks, writing each model and cell the moment it arrives and
    entering each cell's record in ``records``; the number of models trained."""
    import ray

    from scenarios.running.closed_loop import PROGRESS_EVERY_S

    trained = 0
    # EnergyPlus leaks ~0.55 MB per run inside the engine: its workers are recycled.
    max_calls = ENERGYPLUS_CALLS_PER_WORKER if grid.has_energyplus else 0  # 0: never
    task = ray.remote(num_cpus=1, max_calls=max_calls)(_one_blas_thread)
    pending: dict[Any, tuple[str, Any]] = {}
    model_refs: dict[ModelKey, Any] = {}
    # BOPTEST: the emulator's data, recorded once per scenario x seed x training days x period
    data_refs: dict[ModelKey, Any] = {}
    url = os.environ.get(BOPTEST_URL_ENV)
    for key in keys:
        stored = _load_model(root, key)
        if stored is not None:
            model_refs[key] = ray.put(stored)
            continue
        data = None
        if grid.is_boptest:
            source = dataclasses.replace(key, kind="data")
            if source not in data_refs:
                data_refs[source] = task.remote(boptest_training_data, source, url)
            data = data_refs[source]
        model_refs[key] = task.remote(fit_model, key, settings, data)
        pending[model_refs[key]] = ("model", key)
    for cell in missing:
        needed = _model_key(cell, settings)
        ref = task.remote(run_cell, cell, settings, model_refs.get(needed) if needed else None, url)
        pending[ref] = ("cell", cell)

    to_train = sum(kind == "model" for kind, _ in pending.values())

    def say(line: str) -> None:  # through tqdm: a terminal's bar stays intact
        tqdm.write(line, file=sys.stderr)
        sys.stderr.flush()

    say(_start_line(len(missing), reused, to_train, len(data_refs)))
    began = last = time.monotonic()
    done = reused  # counted here: off a terminal the bar is disabled and does not count
    with tqdm(total=total, initial=reused, desc="sweep", unit="cell", disable=None) as bar:
        while pending:
            now = time.monotonic()
            if now - last >= PROGRESS_EVERY_S:  # a line a minute, a cell finished or not
                last = now
                waiting = {kind: sum(k == kind for k, _ in pending.values()) for kind in ("model", "cell")}
                say(_progress_line(done, total, reused, trained, now - began, waiting=waiting))
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=PROGRESS_EVERY_S)
            if not ready:  # nothing finished within a minute: report progress, wait again
                continue
            kind, what = pending.pop(ready[0])
            try:
                value = ray.get(ready[0])
            except ray.exceptions.RayError as exc:
                raise _task_failure(f"{kind} {what.name}", exc) from None
            if kind == "model":
                _store_model(root, what, value)
                trained += 1
                say(f"sweep: model {what.name} trained ({trained} of {to_train})")
                continue
            record: CellRecord = {
                **_cell_record_key(what),
                "settings": _settings_record(settings),
                **cast(CellResult, value),
            }
            atomic_write_json(root / "cells" / f"{what.name}.json", record)
            records[what] = record
            done += 1
            bar.update()
    return trained


def _grid_record(grid: SweepGrid) -> GridRecord:
    record: GridRecord = {
        "scenarios": list(grid.scenarios),
        "controllers": list(grid.controllers),
        "seeds": list(grid.seeds),
        "train_days": list(grid.train_days),
    }
    if grid.archs:
        record["archs"] = list(grid.archs)
    if grid.is_boptest:
        record["test_periods"] = list(grid.boptest_periods)
        record["price_scenarios"] = list(grid.boptest_prices)
    return record


def run_sweep(
    grid: SweepGrid,
    settings: SweepSettings,
    out: str | os.PathLike[str],
    *,
    baseline: str,
    address: str | None = None,
    workers: int | None = None,
    force: bool = False,
) -> SweepOutcome:
    """Run the missing cells of ``grid`` on Ray, then write the summary, report and figure.

    ``out`` must be new, empty or an earlier sweep's directory (it holds ``sweep.json``); any
    other directory needs ``force`` (then the sweep's files are added and nothing else in it is
    touched, but a ``summary.json`` or ``report.md`` of the user's would be replaced)."""

    if baseline not in (*grid.labels, *grid.references.values()):
        raise InputError(
            f"sweep: baseline {baseline!r} is not among the controllers ({', '.join(grid.labels)})"
        )
    if grid.is_boptest and settings.test_days > TEST_PERIOD_DAYS:
        raise InputError(
            f"sweep: days {settings.test_days}: a BOPTEST test period has {TEST_PERIOD_DAYS:g} days"
        )
    check_engine_options(address, workers)
    if grid.is_boptest:  # no server: one line now, not a failed cell after Ray has started
        for scenario in grid.scenarios:
            _boptest_chosen(scenario, None).check_server()
    start = time.perf_counter()
    root = Path(out)
    _check_out(root, force=force)
    _check_settings(root, settings)
    cells = grid.cells()
    records = {c: _read_cell(root / "cells" / f"{c.name}.json", c) for c in cells}
    missing = [c for c in cells if records[c] is None]
    reused = len(cells) - len(missing)
    keys = sorted({k for c in missing if (k := _model_key(c, settings)) is not None})
    with ray_engine(address, workers) as engine:
        # Only now that the engine runs: a refused address leaves no directory behind.
        (root / "models").mkdir(parents=True, exist_ok=True)
        (root / "cells").mkdir(exist_ok=True)
        atomic_write_json(root / "sweep.json", {"settings": _settings_record(settings)})
        trained = _run_on_ray(
            root, grid, settings, keys=keys, missing=missing, records=records,
            total=len(cells), reused=reused,
        )
    done = [r for r in records.values() if r is not None]
    rows = summarise(
        done,
        baseline=baseline,
        order=[*grid.labels, *dict.fromkeys(grid.references.values())],
        references=grid.references,
    )
    summary: SweepSummary = {
        "rows": rows,
        "baseline": baseline,
        "engine": engine,
        "cells_run": len(missing),
        "cells_reused": reused,
        "models_trained": trained,
        "models_reused": len(keys) - trained,
        "grid": _grid_record(grid),
        "settings": _settings_record(settings),
        "wall_time_s": time.perf_counter() - start,
    }
    summary_path = atomic_write_json(root / "summary.json", summary)
    figure_path = plot_sweep(rows, root / FIGURE)
    report_path = atomic_write_text(
        root / "report.md", render_sweep_report(summary, figure_name=FIGURE)
    )
    return SweepOutcome(
        summary=summary, summary_path=summary_path, report_path=report_path, figure_path=figure_path
    )
