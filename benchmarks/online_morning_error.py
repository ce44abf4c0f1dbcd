"""How an online run's models and a pretrained model err on the morning heat-up (issue 45), and
how much the data each learned from excite the heater: the figures behind "online cem rides the
band's edge closer than cem pretrained" in the docs.

Run from the checkout: ``PYTHONPATH=. python benchmarks/online_morning_error.py --online-dir DIR
--model MODEL [--data D.csv] [--hour 6] [--ahead 2] [--from-day 8]``, where ``DIR`` is the
folder of an online run (``pinn-mpc closed-loop --online DIR``, or this script's ``--run``) and
``MODEL`` a model trained once (``pinn-mpc train``, or a sweep's ``models/<cell>/``). With
``--run SCENARIO`` the online run is made first into ``DIR`` as a sweep's ``cem-online`` cell
makes it (``--data-days`` days of the scenario's data, seed ``--cell-seed``, the days right
before the run; the run ``--days`` days, seed ``--cell-seed`` + 1; ensembles of ``--members``
members, default 10, depth 16).

For each day of service from ``--from-day`` on: the model running that morning (the version the
night before took over) and ``MODEL`` each predict the room temperature ``--ahead`` steps after
``--hour`` o'clock, from that step, on the measured power and weather (``evaluate``'s recursive
prediction, on the columns the refits were given: where the data at hand had no internal gains,
those the run recorded are left out, as the refits left them out). Prints each
day's errors (prediction minus measured) and their mean and mean absolute value. Then the
excitation of the run's days of service (its warm-up day excluded) and of ``--data``: the
heater power's standard deviation [kW] and the share of its variance the half-hour of the day
explains (R2 of a least-squares fit on 48 half-hour indicators). Exits 0.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pinn_mpc import fitted
from pinn_mpc.data import COLUMNS, validate_timeseries
from pinn_mpc.evaluation import t_r_ahead


def hour_share(frame: pd.DataFrame) -> float:
    """Share of the variance of ``frame['u']`` a least-squares fit on the half-hour of the day
    explains (R2; NaN for a constant power)."""
    u = frame["u"].to_numpy(dtype=float)
    slot = (frame["time"].dt.hour * 2 + frame["time"].dt.minute // 30).to_numpy()
    onehot = np.eye(48)[slot]
    beta, *_ = np.linalg.lstsq(onehot, u, rcond=None)
    var = float(np.var(u))
    return float("nan") if var == 0 else 1.0 - float(np.var(u - onehot @ beta)) / var


def refit_columns(online_dir: Path) -> list[str] | None:
    """The data columns a learned model of the run's versions was fitted on (its
    ``model.json``'s ``training_data``; None where no version holds one)."""
    for path in sorted((online_dir / "versions").glob("v*/model/model.json")):
        columns = json.loads(path.read_text()).get("training_data", {}).get("columns")
        if columns:
            return list(columns)
    return None


def run_cell(scenario_name: str, out: Path, *, days: int, data_days: int, seed: int, members: int) -> None:
    """The online run of a sweep's ``cem-online`` cell of seed ``seed`` into ``out``."""
    from pinn_mpc.training import TrainConfig
    from scenarios import get_scenario
    from scenarios.running.closed_loop import one_torch_thread, prepare_run
    from scenarios.running.online import OnlineSettings, data_before_run, run_online

    scenario = get_scenario(scenario_name)
    run = prepare_run(scenario, days=days, seed=seed + 1, warmup_steps=None, weather_part="test")
    data = data_before_run(scenario, days=data_days, seed=seed, policy=scenario.data_policy,
                           first_time=pd.Timestamp(run.exo["time"].iloc[0]))
    settings = OnlineSettings(controller="cem", config=TrainConfig(n_seeds=members, depth=16))
    with one_torch_thread():
        run_online(scenario, data, days=days, seed=seed + 1, out_dir=out, settings=settings)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--online-dir", required=True, type=Path, help="an online run's folder")
    parser.add_argument("--model", required=True, help="a model trained once (a model directory)")
    parser.add_argument("--data", default=None, help="the data MODEL was trained on (CSV), for its excitation")
    parser.add_argument("--hour", type=int, default=6, help="the hour the predictions start at (default 6)")
    parser.add_argument("--ahead", type=int, default=2, help="steps ahead (default 2)")
    parser.add_argument("--from-day", type=int, default=8, help="first day of service judged (default 8)")
    parser.add_argument("--run", default=None, metavar="SCENARIO", help="make the online run first")
    parser.add_argument("--days", type=int, default=28, help="with --run: days of service (default 28)")
    parser.add_argument("--data-days", type=int, default=3, help="with --run: days of data (default 3)")
    parser.add_argument("--cell-seed", type=int, default=0, help="with --run: the cell's seed (default 0)")
    parser.add_argument("--members", type=int, default=10, help="with --run: ensemble members (default 10)")
    args = parser.parse_args(argv)
    if args.run is not None:
        run_cell(args.run, args.online_dir, days=args.days, data_days=args.data_days, seed=args.cell_seed,
                 members=args.members)
    observed = pd.read_csv(args.online_dir / "observed.csv", parse_dates=["time"])
    seen = refit_columns(args.online_dir) or list(observed.columns)
    frame = observed[[c for c in COLUMNS if c in observed.columns and c in seen]].copy()
    frame.attrs["dt_s"] = float((observed["time"].iloc[1] - observed["time"].iloc[0]).total_seconds())
    frame = validate_timeseries(frame, source=str(args.online_dir / "observed.csv"))
    log = {int(e["night"]): e for e in map(json.loads, (args.online_dir / "log.jsonl").read_text().splitlines())}
    pretrained = fitted.load(args.model)
    versions: dict[str, Any] = {}
    first = frame["time"].iloc[0].normalize() + pd.Timedelta(days=1)  # the first day of service
    errors: dict[str, list[float]] = {"running": [], "pretrained": []}
    print(f"{'day':>4} {'running':>8} {'error K':>8} {'pretrained error K':>19}")
    for day in range(args.from_day, max(log, default=0) + 2):
        running = log.get(day - 1, {}).get("running")
        at = first + pd.Timedelta(days=day - 1, hours=args.hour)
        rows = np.flatnonzero(frame["time"].to_numpy() == at.to_datetime64())
        if running is None or len(rows) == 0 or rows[0] + args.ahead >= len(frame):
            continue
        if running not in versions:
            versions[running] = fitted.load(args.online_dir / "versions" / running / "model")
        lo = max(0, int(rows[0]) - 48)  # a day of history before the start, the rest cut off
        window = frame.iloc[lo:int(rows[0]) + args.ahead + 1].reset_index(drop=True)
        window.attrs["dt_s"] = frame.attrs["dt_s"]
        truth = float(window["T_r"].iloc[-1])  # the window's last row: the start's target
        e_run = float(t_r_ahead(versions[running], window, args.ahead, len(window) - 1 - args.ahead)[0][0]) - truth
        e_pre = float(t_r_ahead(pretrained, window, args.ahead, len(window) - 1 - args.ahead)[0][0]) - truth
        errors["running"].append(e_run)
        errors["pretrained"].append(e_pre)
        print(f"{day:>4} {running:>8} {e_run:>+8.3f} {e_pre:>+19.3f}")
    for name, values in errors.items():
        e = np.array(values)
        print(f"{name}: {len(e)} mornings, mean error {e.mean():+.3f} K, mean |error| {np.abs(e).mean():.3f} K")
    own = observed[observed["time"] >= first]
    print(f"online run's days of service: power std {own['u'].std() / 1e3:.1f} kW, "
          f"half-hour of day explains {hour_share(own):.2f} of its variance")
    if args.data is not None:
        data = pd.read_csv(args.data, parse_dates=["time"])
        print(f"{args.data}: power std {data['u'].std() / 1e3:.1f} kW, "
              f"half-hour of day explains {hour_share(data):.2f} of its variance")
    return 0


if __name__ == "__main__":
    sys.exit(main())
