"""The grid of a sweep: its settings, its cells and the models they need, and its
axes (:class:`SweepGrid`, checked as a whole)."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pinn_mpc.choices import AUTO, DEFAULT_ARCH, MODEL_CHOICES
from pinn_mpc.errors import InputError
from scenarios.choices import (
    ONLINE_CONTROLLERS,
    ONLINE_SUFFIX,
    TRUTH_CONTROLLERS,
    online_controller,
)
from scenarios.inputs.registry import is_scenario_file
from scenarios.inputs.scenario_file import get_scenario
from scenarios.plants.boptest import BUILTIN_BOPTEST
from scenarios.reports.sweep_report import REFERENCE
from scenarios.running.boptest_loop import BASELINE as BOPTEST_BASELINE
from scenarios.running.boptest_loop import is_boptest_scenario
from scenarios.running.factory import CONTROLLER_NAMES, MODEL_CONTROLLERS, RC_CONTROLLERS

__all__ = ["ARCH", "BOPTEST_CONTROLLERS", "QUICK_TEST_DAYS", "RC_KIND", "START_DAYS", "TEST_DAYS", "Cell", "ModelKey", "SweepGrid", "SweepSettings", "model_kind", "scenario_digest"]

#: The architecture the model-based controllers plan over by default: the one ``train`` makes by
#: default (``SweepSettings.arch`` another, e.g. the physics-informed ARX).
ARCH = DEFAULT_ARCH
RC_KIND = "rc"
#: Days of data an online cell starts from, when none are asked for.
START_DAYS = 3
#: Test days per cell, and with ``--quick``, when none are asked for.
TEST_DAYS = 3
QUICK_TEST_DAYS = 2
#: The controllers a BOPTEST sweep runs besides BOPTEST's baseline (its reference).
BOPTEST_CONTROLLERS = ("thermostat", "qp-mpc", "cem")
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
                raise ValueError(f"sweep: {name} must be >= 1, got {getattr(self, name)}")
        if self.epochs is not None and self.epochs < 1:
            raise ValueError(f"sweep: epochs must be >= 1, got {self.epochs}")
        if self.arch not in MODEL_CHOICES:
            raise ValueError(f"sweep: arch {self.arch!r} is unknown; choose one of {', '.join(MODEL_CHOICES)}")
        if self.policy not in _POLICIES:
            raise ValueError(f"sweep: policy {self.policy!r} is unknown; choose one of {', '.join(_POLICIES)}")

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
    # None for controllers that need no model; an online cell's: the days of data it starts from
    train_days: int | None
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
    bare planner: :data:`ARCH`, on a building of several zones the hybrid of every zone), an
    identified RC (one zone's or several zones'), or nothing."""
    name, _, arch = controller.partition("/")
    if name in MODEL_CONTROLLERS:
        return arch or ARCH
    if name in RC_CONTROLLERS:
        return RC_KIND
    return None


@dataclass(frozen=True, kw_only=True)
class SweepGrid:
    """The axes of a sweep. ``archs``: the models each planner over a learned model
    (``cem``, ``random-shooting``) runs over, one controller label ``cem/<arch>`` each (``auto``:
    ``train``'s default choice); empty: the settings' one, label ``cem``. ``test_periods`` and
    ``price_scenarios``: BOPTEST's (BOPTEST scenarios only; by default peak_heat_day and
    dynamic). ``start_days``: the days of data a controller run online (``cem-online``,
    ``qp-mpc-online``) starts from, its cells' training days."""

    scenarios: tuple[str, ...]
    controllers: tuple[str, ...]
    seeds: tuple[int, ...]
    train_days: tuple[int, ...]
    archs: tuple[str, ...] = ()
    test_periods: tuple[str, ...] = ()
    price_scenarios: tuple[str, ...] = ()
    start_days: int = START_DAYS

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
        if self.start_days < 0:
            raise InputError(f"sweep: start days must be >= 0 (0: no data, the thermostat first), got {self.start_days}")
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
        unknown = [
            c for c in self.controllers
            if c.partition("/")[0] not in CONTROLLER_NAMES and online_controller(c) is None
        ]
        if unknown:
            run_online = ", ".join(f"{c}{ONLINE_SUFFIX}" for c in ONLINE_CONTROLLERS)
            raise InputError(
                f"sweep: unknown controller(s) {', '.join(unknown)}; "
                f"choose from {', '.join(CONTROLLER_NAMES)}, or run online {run_online}"
            )
        online = [c for c in self.controllers if online_controller(c) is not None]
        for scenario in self.scenarios if online else ():
            # The package's RC plants and EnergyPlus of one zone: a resume steps the plant
            # again from the same seed on the recorded demands (EnergyPlus from its start).
            if len(get_scenario(scenario).control_spec().zones) > 1:
                raise InputError(
                    f"sweep: {', '.join(online)} run(s) on buildings of one zone (the RC plants "
                    f"or EnergyPlus merged); {scenario!r} has several zones: sweep it without them"
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
                    self.train_days if model_kind(controller)
                    else (self.start_days,) if online_controller(controller) else (None,)
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


