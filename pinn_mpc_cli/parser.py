"""The ``pinn-mpc`` argument parser: one function per command adds that command's options.

Each command names its handler ("module:function" of this package), imported only when the
command runs, so ``--help`` stays fast: the choices come from the light name modules
:mod:`pinn_mpc.choices` and :mod:`scenarios.choices`.
"""

from __future__ import annotations

import argparse
import math
from typing import Any, NoReturn, TypeAlias

from pinn_mpc import __version__
from pinn_mpc.choices import AUTO, DEFAULT_ARCH, MODEL_CHOICES, RECIPES, TRAIN_CHOICES
from pinn_mpc.models.registry import ARCHITECTURES, BASELINES, CONSISTENT_ARX, PHYSICS_ARX
from scenarios.choices import CONTROLLER_NAMES, POLICIES, RANDOM_POLICIES, WEATHER_PARTS

__all__ = ["COMMANDS", "MAX_DAYS", "SETTING_DESTS", "Commands", "build_parser", "command_flags"]

#: The longest run any command accepts. Timestamps are labelled from 2021 and pandas' clock
#: ends in 2262, so some limit is needed; ten years is more than any building study simulates.
MAX_DAYS = 3650


def _whole(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None


def _positive_int(text: str) -> int:
    value = _whole(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _nonnegative_int(text: str) -> int:
    value = _whole(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be at least 0, got {value}")
    return value


def _days(text: str) -> int:
    value = _positive_int(text)
    if value > MAX_DAYS:
        raise argparse.ArgumentTypeError(
            f"{value} days is more than the {MAX_DAYS} (ten years) a run may cover"
        )
    return value


def _seed(text: str) -> int:
    value = _whole(text)
    if not 0 <= value < 2**63:  # torch and numpy both take seeds in this range
        raise argparse.ArgumentTypeError(f"must be a whole number in 0..2**63-1, got {text}")
    return value


def _finite_non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def _horizons(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a comma-separated list of steps"
        ) from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"horizons must be whole numbers >= 1, got {text!r}")
    return values


def arch_help() -> str:
    """One line per architecture: what it is and its defaults, then the baselines (for
    ``train --help``)."""
    return "; ".join(
        [
            f"{s.name}: {s.summary} (depth {s.depth}, recipe {s.recipe}, data of "
            f"`simulate --policy {s.policy}`{', the network auto chooses' if s.name == DEFAULT_ARCH else ''})"
            for s in ARCHITECTURES.values()
        ]
        + [
            f"{b.name}: {b.summary.removesuffix(')')}; --depth, --seeds, --epochs, --lambda and "
            "--recipe do not apply)"
            for b in BASELINES.values()
        ]
        + [
            f"{AUTO} (the default): {DEFAULT_ARCH} or {PHYSICS_ARX.name}, whichever predicts the "
            f"data's last quarter better over a planner's 24 h ({PHYSICS_ARX.name} when its error is at most "
            f"three quarters of the hybrid's, and then {CONSISTENT_ARX} where it errs less still), "
            "fitted on all of it"
        ]
    )


def _scenario_names() -> str:
    """Every built-in scenario name, BOPTEST's too (imported only to print help: scenarios
    are data)."""
    from scenarios.inputs.scenario_file import builtin_names

    return ", ".join(builtin_names())


class _HelpFormatter(argparse.HelpFormatter):
    """Shows each option's default (unless it has none) and fills ``{scenarios}`` from the
    registry only when help is printed, so start-up stays fast."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "{scenarios}" in text:
            text = text.replace("{scenarios}", _scenario_names())
        no_default = any(action.default is v for v in (None, False, argparse.SUPPRESS))
        if action.option_strings and not action.required and not no_default:
            text += " (default: %(default)s)"
        return text


class _Parser(argparse.ArgumentParser):
    """Usage errors are one line (what is wrong and where to look), like every other error."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _add_weather_part(p: argparse.ArgumentParser, default: str) -> None:
    p.add_argument(
        "--weather-part",
        choices=WEATHER_PARTS,
        default=default,
        help="days of the scenario's weather to draw from: 'train' (training data), 'test' "
        "(the days closed loops and compare are judged on, disjoint from 'train'), or 'whole' "
        "(the whole seasonal window, both mixed, as before the split)",
    )


#: Where the commands are added (what ``add_subparsers`` returns).
Commands: TypeAlias = "argparse._SubParsersAction[_Parser]"


def _add(sub: Commands, name: str, handler: str, help_: str) -> argparse.ArgumentParser:
    """A command ``name`` run by ``handler`` ("module:function" of :mod:`pinn_mpc_cli`, taking
    the parsed arguments, imported when it runs)."""
    p = sub.add_parser(name, help=help_, description=help_, formatter_class=_HelpFormatter)
    p.set_defaults(handler=f"pinn_mpc_cli.{handler}")
    return p


def _scenario(p: argparse.ArgumentParser, **kwargs: Any) -> None:
    kwargs.setdefault("help", "scenario name, one of: {scenarios}; or a scenario file (.toml, see `scenario`)")
    p.add_argument("--scenario", **kwargs)


def _days_option(p: argparse.ArgumentParser, help_: str, **kwargs: Any) -> None:
    p.add_argument("--days", type=_days, help=f"{help_}, 1..{MAX_DAYS}", **kwargs)


def _columns(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--columns",
        help="column mapping for data with other names, e.g. T_r=T_int,u_phys=P_hea,T_a=T_ext",
    )


def _data(p: argparse.ArgumentParser, help_: str) -> None:
    p.add_argument("--data", required=True, help=f"{help_} (CSV in the data format)")


def _model(p: argparse.ArgumentParser, help_: str, **kwargs: Any) -> None:
    p.add_argument("--model", help=f"{help_} (written by `pinn-mpc train`)", **kwargs)


def _force(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--force",
        action="store_true",
        help="write into an existing directory that holds other files too (only this "
        "command's own files there are replaced; the rest is kept)",
    )


def _replace(p: argparse.ArgumentParser, files: str) -> None:
    """``--force`` of a command that writes the files ``files`` names (one or more options)."""
    p.add_argument(
        "--force",
        action="store_true",
        help=f"replace an existing {files}; without it an existing file is refused before any "
        "work is done",
    )


def _eta_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--eta",
        type=float,
        default=None,
        help="heat per W of actuator power (default: 1 heating; give -COP for cooling)",
    )


def _boptest_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--test-period",
        choices=("peak_heat_day", "typical_heat_day"),
        default=None,
        help="BOPTEST scenarios: BOPTEST's test period (time_period; default peak_heat_day)",
    )
    p.add_argument(
        "--price-scenario",
        choices=("constant", "dynamic", "highly_dynamic"),
        default=None,
        help="BOPTEST scenarios: BOPTEST's electricity price scenario (default dynamic)",
    )


def add_simulate(sub: Commands) -> None:
    """``simulate``: data from a scenario."""
    p = _add(sub, "simulate", "loop_commands:simulate", "simulate a scenario and write time-series data (CSV)")
    _scenario(p, required=True)
    _days_option(p, "days to simulate", required=True)
    p.add_argument("--seed", type=_seed, default=0, help="seed of the weather, price and policy")
    p.add_argument(
        "--policy",
        choices=POLICIES,
        default=None,
        help="heating demand: a uniform random power level per interval (best for models that "
        "will drive a controller), the paper's random on/off, a thermostat, or random "
        "setpoints tracked by a proportional controller with a dither (closed-loop) (default: "
        "the scenario's data_policy: random-level, closed-loop on EnergyPlus)",
    )
    p.add_argument("--buildings", type=_positive_int, default=1, help="buildings simulated")
    p.add_argument(
        "--spread",
        type=_finite_non_negative_float,
        default=None,
        help="draw the buildings around the scenario's with this log-normal spread of R, C and "
        "solar aperture (as closed-loop --buildings; their parameters go to OUT's .fleet.json); "
        "default: every building the scenario's",
    )
    _add_weather_part(p, "train")
    p.add_argument(
        "--first-day",
        type=_finite_non_negative_float,
        default=None,
        help="BOPTEST scenarios: the first day of the year of the data (0 = 1 January), off "
        "every test period and its warm-up (default 30)",
    )
    p.add_argument(
        "--test-period",
        choices=("peak_heat_day", "typical_heat_day"),
        default=None,
        help="BOPTEST scenarios: the data's days nearest this test period, off it (right before "
        "its warm-up, else right after it), as compare takes them",
    )
    p.add_argument("--out", required=True, help="CSV file to write")
    _replace(p, "--out file (and the parameters file beside it)")


def add_train(sub: Commands) -> None:
    """``train``: a model from data."""
    p = _add(
        sub,
        "train",
        "model_commands:train",
        "train a model on data: by default the hybrid, the physics-informed ARX or the "
        "consistent network on its structure (pcnn-parx), whichever predicts it better; or a "
        "seed ensemble of hybrid, mlp, physreg, physnet, pcnn or pcnn-parx, or an ARX",
    )
    _data(p, "training data")
    p.add_argument(
        "--arch",
        choices=TRAIN_CHOICES,
        default=AUTO,
        help=f"the architecture, each with its own defaults: {arch_help()}",
    )
    p.add_argument(
        "--depth",
        type=_positive_int,
        default=None,
        help="history steps the model sees (default: the architecture's)",
    )
    p.add_argument("--seeds", type=_positive_int, default=20, help="ensemble members")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the first member")
    p.add_argument("--epochs", type=_positive_int, default=None, help="epochs (default: recipe's)")
    p.add_argument(
        "--lambda",
        dest="lam",
        metavar="LAMBDA",
        type=_finite_non_negative_float,
        default=None,
        help="physics-loss weight (default: recipe's)",
    )
    p.add_argument(
        "--recipe",
        choices=tuple(RECIPES),
        default=None,
        help="'paper': 75 epochs of batch 2048 as published; 'converged': 60 epochs of batch 512 "
        "on a decaying learning rate; 'long': the same over 150 epochs (default: the "
        "architecture's)",
    )
    _columns(p)
    p.add_argument(
        "--out", required=True, help="model directory to write (model.json, weights.safetensors)"
    )
    _eta_option(p)
    _scenario(
        p, dest="layout", metavar="SCENARIO",
        help="for data of several zones: the building's layout (its zones, their actuators and "
        "windows) from this scenario; train then fits the hybrid of every zone",
    )
    _force(p)
    p.add_argument(
        "--per-building",
        action="store_true",
        help="--data is a fleet data set (a building column, simulate --buildings N): train one "
        "model per building on Ray into --out/buildings/, keeping those already there",
    )
    p.add_argument(
        "--address", default=None, help="with --per-building: Ray cluster (HOST:PORT, ray://HOST:PORT, auto)"
    )
    p.add_argument(
        "--workers", type=_positive_int, default=None, help="with --per-building: local CPUs (default all)"
    )


def add_evaluate(sub: Commands) -> None:
    """``evaluate``: a model's prediction errors."""
    p = _add(sub, "evaluate", "model_commands:evaluate", "one-step and recursive multi-step errors of a model on data")
    _model(p, "model directory", required=True)
    _data(p, "test data")
    p.add_argument(
        "--horizons",
        type=_horizons,
        default="1,6,12,24,36,48",
        help="recursive prediction horizons [steps], comma-separated",
    )
    _columns(p)
    p.add_argument("--json", required=True, help="metrics JSON file to write")
    _replace(p, "--json file")


def add_export_rc(sub: Commands) -> None:
    """``export-rc``: a model's learned RC."""
    p = _add(sub, "export-rc", "model_commands:export_rc_json", "export the learned 2R2C parameters of a model")
    _model(
        p,
        "model directory: a physics-informed network's learned R and C (physreg, physnet, "
        "hybrid, pcnn), or the RC any other model identified from its training data",
        required=True,
    )
    p.add_argument("--out", required=True, help="RC JSON file to write (for --rc)")
    _replace(p, "--out file")


def add_identify(sub: Commands) -> None:
    """``identify``: an RC from data."""
    p = _add(
        sub, "identify", "model_commands:identify",
        "grey-box identification of 2R2C parameters from data (T_m hidden)",
    )
    _data(p, "measured data")
    _columns(p)
    _eta_option(p)
    _scenario(
        p, dest="layout", metavar="SCENARIO",
        help="for data of several zones: the building's layout (its zones, their actuators and "
        "windows) from this scenario, a built-in name (`pinn-mpc scenario list`) or a scenario file",
    )
    p.add_argument("--out", required=True, help="RC JSON file to write (for --rc)")
    _replace(p, "--out file")


def add_closed_loop(sub: Commands) -> None:
    """``closed-loop``: one controller, one building or a fleet."""
    p = _add(sub, "closed-loop", "loop_commands:closed_loop", "run one controller against the simulator")
    _scenario(p, required=True)
    p.add_argument(
        "--controller", required=True,
        help="controller, one of: " + ", ".join(CONTROLLER_NAMES) + "; on a BOPTEST scenario "
        "also boptest-baseline (the test case's own controller)",
    )
    _boptest_options(p)
    _model(
        p, "model directory for random-shooting and cem; for qp-mpc an ARX model directory "
        "(train --arch arx or parx)", default=None,
    )
    p.add_argument(
        "--rc", default=None, help="RC JSON for casadi-mpc and qp-mpc (from identify, export-rc); on "
        "a scenario of several zones the multi-zone RC JSON (from identify) for qp-mpc, cem and "
        "random-shooting"
    )
    _days_option(
        p, "counted days after a one-day thermostat warm-up (required; on a BOPTEST scenario the "
        "days of its test period, after BOPTEST's warm-up, default the whole period: 14)",
        default=None,
    )
    p.add_argument("--seed", type=_seed, default=0, help="seed of the weather, price and noise")
    p.add_argument(
        "--json", default=None,
        help="KPI JSON file to write (default: the KPIs are only printed)",
    )
    p.add_argument("--csv", default=None, help="trajectory CSV file to write")
    p.add_argument("--plot", default=None, help="trajectory figure (PNG) to write")
    _replace(p, "--json, --csv or --plot file (and a fleet's figure beside --json)")
    _add_weather_part(p, "test")
    p.add_argument(
        "--buildings",
        type=_positive_int,
        default=1,
        help="a fleet of this many buildings drawn around the scenario's, each with its own "
        "controller on its own RC (the KPI JSON then holds every building, the fleet totals "
        "and the time per control step; no --rc, --csv, --plot; --model only a directory of "
        "per-building models, for cem)",
    )
    p.add_argument(
        "--spread",
        type=_finite_non_negative_float,
        default=None,
        help="log-normal spread of the fleet's R, C and solar aperture (0.2 is about +-20 %%, "
        "0 copies the scenario's building; default 0.2, only with --buildings > 1)",
    )
    p.add_argument(
        "--large",
        action="store_true",
        help="confirm a fleet of more than 1000 buildings (hours of work)",
    )
    p.add_argument(
        "--batched",
        action="store_true",
        help="plan the whole fleet in one batch each step (qp-mpc: every building's RC MPC; cem: "
        "over the buildings' own models, --model DIR of train --per-building); implied by "
        "--cap-kw and --model",
    )
    p.add_argument(
        "--cap-kw",
        type=_positive_float,
        default=None,
        help="keep the fleet's aggregate electrical power at or under this many kW (a price "
        "signal by dual ascent over the batched planners; the JSON counts every capped "
        "interval over it); writes the fleet figure next to --json. On a scenario of several "
        "zones any of its controllers, each building's total over its actuators coordinated "
        "(a thermostat or sampler, deaf to the price, is scaled down to the cap)",
    )
    p.add_argument(
        "--cap-window",
        default=None,
        help="HH:MM-HH:MM: the cap holds in this window of every day (default all day)",
    )
    p.add_argument(
        "--rc-candidates",
        choices=("auto", "on", "off"),
        nargs="?",
        const="on",
        default="auto",
        help="with --model (the batched cem): score each building's RC MPC plan (on the RC "
        "identified from its model's data) among the samples of each step's first plan, "
        "every building's re-solved every third step in turn; plans closer to qp-mpc's, at "
        "one more QP per three buildings and step; auto (the default): on under "
        "--cap-kw (where the cem's own samples lose the comfort), off without it",
    )
    p.add_argument(
        "--online", default=None, metavar="DIR",
        help="online operation (--controller cem or random-shooting; qp-mpc on the RC alone): "
        "start from what --data holds, record what is observed and refit the model and the RC every --retrain-every "
        "days at 00:00 in a worker process, taking over at 03:00; DIR keeps the recorded data, "
        "each model version, the log and the state",
    )
    p.add_argument(
        "--data", default=None,
        help="with --online: the data set at hand (data format; whole days, its rows taken as "
        "those right before the run); without it the thermostat starts",
    )
    p.add_argument(
        "--retrain-every", type=_positive_int, default=1,
        help="with --online: days of service between refits (default 1)",
    )
    p.add_argument(
        "--resume", action="store_true",
        help="with --online: continue the run DIR holds from its last takeover",
    )
    p.add_argument(
        "--online-seeds", type=_positive_int, default=None,
        help="with --online: ensemble members of each refit (default train's)",
    )
    p.add_argument(
        "--online-epochs", type=_positive_int, default=None,
        help="with --online: epochs of each refit (default the recipe's)",
    )


def add_compare(sub: Commands) -> None:
    """``compare``: every controller on one scenario."""
    p = _add(sub, "compare", "experiment_commands:compare", "train, identify and run every controller on one scenario")
    _scenario(p, default="paper_household")
    p.add_argument(
        "--train-days",
        type=_days,
        default=60,
        help=f"days of training data, 1..{MAX_DAYS}",
    )
    _days_option(p, "test days of each closed-loop run (default 5; with --quick 2; on BOPTEST its whole 14-day test period)", default=None)
    p.add_argument("--seed", type=_seed, default=0, help="seed of the training data and models")
    p.add_argument("--json", default="compare/table.json", help="KPI table JSON file to write")
    p.add_argument(
        "--report",
        default="compare/report.md",
        help="markdown report to write; its figure goes next to it with the suffix .png",
    )
    p.add_argument(
        "--quick", action="store_true", help="small ensembles, short training, 2 test days unless --days is given (minutes)"
    )
    _boptest_options(p)
    p.add_argument(
        "--policy",
        choices=RANDOM_POLICIES,
        default=None,
        help="training-data policy: uniform random power levels, the paper's on/off or random "
        "setpoints tracked (default: the scenario's data_policy: random-level, closed-loop on "
        "EnergyPlus)",
    )


def add_reproduce(sub: Commands) -> None:
    """``reproduce``: the paper's experiments."""
    p = _add(sub, "reproduce", "experiment_commands:reproduce", "reproduce the paper's three experiments on simulated data")
    p.add_argument(
        "--out", required=True, help="directory to write (report.md, results.json, tables, figures)"
    )
    p.add_argument("--quick", action="store_true", help="fewer seeds, sizes and epochs (minutes)")
    p.add_argument(
        "--seeds", type=_positive_int, default=None, help="ensemble members (default: 20, quick 3)"
    )
    _force(p)


def add_sweep(sub: Commands) -> None:
    """``sweep``: a grid of closed loops on Ray."""
    p = _add(sub, "sweep", "experiment_commands:sweep", "run a grid of closed loops (scenarios x controllers x seeds) on Ray")
    p.add_argument(
        "--spec", default=None,
        help="a sweep definition (TOML: scenarios, controllers, seeds, train_days, days, "
        "baseline, arch, archs, test_periods, price_scenarios, start_days), e.g. sweeps/robustness.toml; "
        "options given here override it",
    )
    p.add_argument("--scenarios", default=None, help="comma-separated scenario names")
    p.add_argument(
        "--controllers", default=None,
        help="comma-separated, e.g. oracle,qp-mpc,cem; cem-online, qp-mpc-online: run online, "
        "refitting every night from --start-days days of data",
    )
    p.add_argument("--seeds", default=None, help="e.g. 0-7 or 0,3,5")
    p.add_argument("--train-days", default=None, help="training days, e.g. 30 or 14,30,60 (default 30)")
    p.add_argument("--days", type=_positive_int, default=None, help="test days per cell (default 3; with --quick 2)")
    p.add_argument(
        "--start-days", type=_nonnegative_int, default=None,
        help="days of data the controllers run online start from (default 3; 0: the thermostat first)",
    )
    p.add_argument("--out", required=True, help="directory of cells, models, summary, report")
    p.add_argument("--quick", action="store_true", help="2-member ensembles, 30 epochs, 2 test days unless --days is given")
    p.add_argument("--address", default=None, help="Ray cluster (HOST:PORT, ray://HOST:PORT, auto)")
    p.add_argument("--workers", type=_positive_int, default=None, help="local CPUs (default all)")
    p.add_argument("--baseline", default=None, help="controller of the paired differences")
    p.add_argument(
        "--arch", default=None, choices=MODEL_CHOICES,
        help=f"the model cem and random-shooting plan over (default {DEFAULT_ARCH}, the network train --arch auto chooses)",
    )
    p.add_argument(
        "--archs", default=None,
        help="cem (and random-shooting) over each of these models, controllers cem/<arch>, "
        "e.g. auto,hybrid,parx (auto: train's default choice)",
    )
    p.add_argument(
        "--test-periods", default=None,
        help="BOPTEST scenarios: BOPTEST's test periods, e.g. peak_heat_day,typical_heat_day "
        "(default peak_heat_day)",
    )
    p.add_argument(
        "--price-scenarios", default=None,
        help="BOPTEST scenarios: BOPTEST's price scenarios, e.g. dynamic,highly_dynamic (default dynamic)",
    )
    p.add_argument(
        "--large", action="store_true", help="confirm a grid of more than 1000 cells"
    )
    _force(p)


def add_scenario(sub: Commands) -> None:
    """``scenario list | show | export``."""
    p = _add(sub, "scenario", "scenario_commands:scenario", "list, show or export scenarios as TOML files")
    actions = p.add_subparsers(
        dest="action", required=True, metavar="ACTION", help="list, show or export"
    )
    actions.add_parser("list", help="built-in scenarios with one-line descriptions")
    for action, help_ in (
        ("show", "print a scenario (built-in name or .toml file) as its TOML file"),
        ("export", "write a built-in (or file) scenario as a complete, commented TOML file"),
    ):
        q = actions.add_parser(action, help=help_, description=help_, formatter_class=_HelpFormatter)
        q.add_argument("name", metavar="NAME", help="scenario name, one of: {scenarios}; or a .toml file")
        if action == "export":
            q.add_argument("--out", required=True, help="TOML file to write (ending in .toml)")
            _replace(q, "--out file")


#: The commands in the order ``--help`` lists them.
COMMANDS = (
    add_simulate, add_train, add_evaluate, add_export_rc, add_identify, add_closed_loop,
    add_compare, add_reproduce, add_sweep, add_scenario,
)


def build_parser() -> argparse.ArgumentParser:
    """The ``pinn-mpc`` parser: the global options and every command of :data:`COMMANDS`."""
    parser = _Parser(
        prog="pinn-mpc",
        description="Physics-informed neural network building models and receding-horizon control.",
        formatter_class=_HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"pinn-mpc {__version__}")
    parser.add_argument(
        "--debug",
        action="store_true",
        help="on an internal error (a bug in pinn-mpc), print the full traceback too",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in COMMANDS:
        add(sub)
    return parser


#: The library's settings that its messages name otherwise than the flag's dest: {setting: dest}.
SETTING_DESTS = {
    "n_buildings": "buildings",
    "n_seeds": "seeds",
    "model_dir": "model",
    "rc_path": "rc",
    "time_period": "test_period",
}


def command_flags(parser: argparse.ArgumentParser, command: str) -> dict[str, str]:
    """{setting: flag} for the messages of ``command`` (a command of ``parser``): each option's
    dest (and the library's other names of it, :data:`SETTING_DESTS`) mapped to its long flag;
    a setting that is not ``command``'s own but another command's flag is named with that
    command (``train --depth``). The command line names a setting that a library message marks
    (:func:`pinn_mpc.errors.setting`) so."""
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    flags: dict[str, str] = {}
    for name in (command, *(c for c in commands.choices if c != command)):
        own = _flags(commands.choices[name])
        for dest, flag in own.items():
            flags.setdefault(dest, flag if name == command else f"{name} {flag}")
    for setting, dest in SETTING_DESTS.items():
        if dest in flags:
            flags[setting] = flags[dest]
    return flags


def _flags(parser: argparse.ArgumentParser) -> dict[str, str]:
    """{dest: long flag} of ``parser``'s options, its actions' (``scenario export``) too."""
    flags: dict[str, str] = {}
    pending = [parser]
    while pending:
        for action in pending.pop()._actions:
            if isinstance(action, argparse._SubParsersAction):
                pending.extend(action.choices.values())
            elif action.option_strings and action.dest != "help":
                flags.setdefault(action.dest, max(action.option_strings, key=len))
    return flags
