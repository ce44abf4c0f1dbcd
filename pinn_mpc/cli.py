"""Command line: ``pinn-mpc COMMAND ...`` (also ``python -m pinn_mpc``).

This module only parses arguments and calls one library function per command; each returns
a short summary that is printed. It is the application entry point, the one place above all
three layers, so it imports ``scenarios`` (lazily, inside the handlers, to keep start-up fast).
Bad input (:class:`~pinn_mpc.errors.InputError`) becomes one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from pinn_mpc import __version__
from pinn_mpc.archs import ALL_ARCHS, DEFAULT_ARCH
from pinn_mpc.errors import InputError


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value >= 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
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


def _simulate(a: argparse.Namespace) -> str:
    from scenarios.datagen import simulate_to_csv

    return simulate_to_csv(
        scenario=a.scenario,
        days=a.days,
        seed=a.seed,
        policy=a.policy,
        buildings=a.buildings,
        out=a.out,
    )


def _train(a: argparse.Namespace) -> str:
    from pinn_mpc.training import train_to_dir

    return train_to_dir(
        data=a.data,
        arch=a.arch,
        out=a.out,
        depth=a.depth,
        seeds=a.seeds,
        epochs=a.epochs,
        lam=a.lam,
        columns=a.columns,
        recipe=a.recipe,
        seed=a.seed,
    )


def _evaluate(a: argparse.Namespace) -> str:
    from pinn_mpc.evaluation import evaluate_to_json

    return evaluate_to_json(
        model=a.model, data=a.data, horizons=a.horizons, columns=a.columns, json_path=a.json
    )


def _export_rc(a: argparse.Namespace) -> str:
    from pinn_mpc.export import export_rc_to_json

    return export_rc_to_json(model=a.model, out=a.out)


def _identify(a: argparse.Namespace) -> str:
    from pinn_mpc.identify import identify_to_json

    return identify_to_json(data=a.data, columns=a.columns, out=a.out, eta=a.eta)


def _closed_loop(a: argparse.Namespace) -> str:
    from scenarios.closed_loop import closed_loop_command

    return closed_loop_command(
        scenario=a.scenario,
        controller=a.controller,
        model=a.model,
        rc=a.rc,
        days=a.days,
        seed=a.seed,
        json_path=a.json,
        csv_path=a.csv,
        plot_path=a.plot,
    )


def _compare(a: argparse.Namespace) -> str:
    from scenarios.compare import compare_command

    return compare_command(
        scenario=a.scenario,
        train_days=a.train_days,
        days=a.days,
        seed=a.seed,
        json_path=a.json,
        report_path=a.report,
        quick=a.quick,
        policy=a.policy,
    )


def _reproduce(a: argparse.Namespace) -> str:
    from scenarios.reproduce import reproduce_command

    return reproduce_command(out=a.out, quick=a.quick, seeds=a.seeds)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pinn-mpc",
        description="Physics-informed neural network building models and receding-horizon control.",
    )
    parser.add_argument("--version", action="version", version=f"pinn-mpc {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(
        name: str, handler: Callable[[argparse.Namespace], str], help_: str
    ) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=help_, description=help_)
        p.set_defaults(handler=handler)
        return p

    p = add("simulate", _simulate, "simulate a scenario and write time-series data (CSV)")
    p.add_argument("--scenario", required=True, help="scenario name, e.g. paper_household")
    p.add_argument("--days", type=_positive_int, required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--policy",
        choices=["random", "random-level", "thermostat"],
        default="random-level",
        help="'random-level': a uniform power level per interval (for control); "
        "'random': the paper's on/off",
    )
    p.add_argument("--buildings", type=_positive_int, default=1)
    p.add_argument("--out", required=True, help="CSV file to write")

    p = add("train", _train, "train a seed ensemble of hybrid, mlp, physreg or physnet on data")
    p.add_argument("--data", required=True)
    p.add_argument(
        "--arch",
        choices=list(ALL_ARCHS),
        default=DEFAULT_ARCH,
        help="hybrid (default, recommended for control): the identified 2R2C with learned "
        "corrections; mlp, physreg, physnet: the paper's",
    )
    p.add_argument("--depth", type=_positive_int, default=16, help="history length (paper: 8)")
    p.add_argument("--seeds", type=_positive_int, default=20, help="ensemble members")
    p.add_argument("--seed", type=int, default=0, help="first seed")
    p.add_argument("--epochs", type=_positive_int, default=None, help="default: recipe's")
    p.add_argument(
        "--lambda",
        dest="lam",
        type=_non_negative_float,
        default=None,
        help="physics-loss weight (default: recipe's)",
    )
    p.add_argument(
        "--recipe",
        choices=["converged", "paper"],
        default="converged",
        help="'paper': 75 epochs of batch 2048 as published; 'converged': trains to convergence",
    )
    p.add_argument(
        "--columns", default=None, help="column mapping, e.g. T_r=T_int,u_phys=P_hea,T_a=T_ext"
    )
    p.add_argument("--out", required=True, help="model directory to write")

    p = add("evaluate", _evaluate, "one-step and recursive multi-step errors of a model on data")
    p.add_argument("--model", required=True)
    p.add_argument("--data", required=True)
    p.add_argument("--horizons", type=_horizons, default=[1, 6, 12, 24, 36, 48])
    p.add_argument("--columns", default=None)
    p.add_argument("--json", required=True, help="metrics JSON to write")

    p = add("export-rc", _export_rc, "export the learned 2R2C parameters of a model")
    p.add_argument("--model", required=True)
    p.add_argument("--out", required=True)

    p = add(
        "identify", _identify, "grey-box identification of 2R2C parameters from data (T_m hidden)"
    )
    p.add_argument("--data", required=True)
    p.add_argument("--columns", default=None)
    p.add_argument(
        "--eta",
        type=float,
        default=None,
        help="heat per W of actuator power (default: 1 heating; give -COP for cooling)",
    )
    p.add_argument("--out", required=True)

    p = add("closed-loop", _closed_loop, "run one controller against the simulator")
    p.add_argument("--scenario", required=True)
    p.add_argument(
        "--controller",
        required=True,
        help="thermostat, random-shooting, cem, casadi-mpc, qp-mpc, oracle, clairvoyant",
    )
    p.add_argument("--model", default=None, help="model directory (random-shooting, cem)")
    p.add_argument("--rc", default=None, help="RC JSON (casadi-mpc, qp-mpc)")
    p.add_argument("--days", type=_positive_int, required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", required=True)
    p.add_argument("--csv", default=None)
    p.add_argument("--plot", default=None)

    p = add("compare", _compare, "train, identify and run every controller on one scenario")
    p.add_argument("--scenario", default="paper_household")
    p.add_argument("--train-days", type=_positive_int, default=60)
    p.add_argument("--days", type=_positive_int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", default="compare/table.json")
    p.add_argument("--report", default="compare/report.md")
    p.add_argument("--quick", action="store_true", help="small ensembles and short runs (minutes)")
    p.add_argument(
        "--policy",
        choices=["random-level", "random"],
        default="random-level",
        help="training-data policy: uniform random power levels (default) or the paper's on/off",
    )

    p = add("reproduce", _reproduce, "reproduce the paper's three experiments on simulated data")
    p.add_argument("--out", required=True)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--seeds", type=_positive_int, default=None)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    # The numerical work here is many small matrices (MPC, observers, identification): a
    # multi-threaded BLAS only adds synchronisation on top of them. Torch keeps its own threads.
    from threadpoolctl import threadpool_limits

    try:
        with threadpool_limits(limits=1, user_api="blas"):
            summary = args.handler(args)
    except InputError as exc:
        print(f"pinn-mpc {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
        print(f"pinn-mpc {args.command}: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"pinn-mpc {args.command}: interrupted", file=sys.stderr)
        return 130
    if summary:
        print(summary)
    return 0
