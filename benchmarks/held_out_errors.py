"""Each stored model's T_r error h intervals ahead on held-out days: the models a sweep trained
(its ``models/`` folder) predicting days of the test part of the weather that no model saw, by
family, building and training days (mean over seeds and the worst seed), with each family's
error over parx's (issue 44's accuracy criterion). A consistent family's model (``pcnn``,
``pcnn-parx``) is judged twice: as trained, and with its unforced network zeroed (the family
name followed by ``-net0``: ``pcnn-parx-net0`` is the positive ARX alone, ``pcnn-net0`` the
2R2C with its schedule and no learned heat), which says what the network adds on days it did
not see.

    PYTHONPATH=. python benchmarks/held_out_errors.py --sweep eplus_consistent \\
        --spec sweeps/eplus_consistent.toml --days 7 --horizon 24

Every family predicts from the same power: from each start on the demanded ``u`` (what a
planner gives a model, and what ``evaluate`` rolls a network out on), before it the delivered
``u_phys``. ``evaluate`` rolls an ARX out on the delivered power from the start on too; where a
backup heater delivers heat nobody demanded (the EnergyPlus warehouse's held-out February days:
6-9 of 336 half-hours), that handed parx heat the networks were not given, and its error
there was 0.05-0.07 C lower than on the demand (the office's 0.01-0.03).

The held-out days are simulated as the training days were (the scenario's data policy) on the
weather's test part with seed s + 1 for the models trained with seed s, so the data differ from
the training data in their days, their weather and their policy's draws. The error is what
``pinn-mpc evaluate`` reports at the horizon (``horizons[h].T_r_mae``): every start of the
held-out days, each model's recursive prediction from the measured history.
"""

from __future__ import annotations

import argparse
import re
import statistics
from collections import defaultdict
from pathlib import Path

import pandas as pd

from pinn_mpc.evaluation import evaluate_model
from pinn_mpc.fitted import load
from pinn_mpc.models.arx import ARXModel
from pinn_mpc.models.consistent import UnforcedNet
from pinn_mpc.models.learned import LearnedModel
from scenarios.experiments.sweep.spec import read_sweep_spec
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate

__all__: list[str] = []

#: What a consistent family's model is called with its unforced network zeroed.
NET0 = "-net0"
#: A stored model's folder: <scenario>[-<hash>]--<arch>--seed<s>--train<d>.
MODEL_DIR = re.compile(r"^(?P<scenario>.+?)(?:-[0-9a-f]{12})?--(?P<arch>[a-z0-9-]+)--seed(?P<seed>\d+)--train(?P<days>\d+)$")


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments (``argv``, default the command line's), evaluate every stored model,
    print each one's error and the table."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sweep", required=True, help="a sweep's output folder (its models/)")
    p.add_argument("--spec", required=True, help="the sweep's definition (its scenarios)")
    p.add_argument("--days", type=int, default=7, help="held-out days per seed (default 7)")
    p.add_argument("--horizon", type=int, default=24, help="intervals ahead (default 24)")
    a = p.parse_args(argv)
    scenarios = {}
    for ref in read_sweep_spec(a.spec)["scenarios"].split(","):  # files relative to the spec
        sc = get_scenario(ref)
        scenarios[sc.name] = sc
    held: dict[tuple[str, int], pd.DataFrame] = {}
    errors: dict[tuple[str, str, int], dict[int, float]] = defaultdict(dict)
    for folder in sorted((Path(a.sweep) / "models").iterdir()):
        m = MODEL_DIR.match(folder.name)
        if m is None or m["arch"] == "rc" or m["scenario"] not in scenarios:
            continue
        name, seed = m["scenario"], int(m["seed"])
        sc = scenarios[name]
        if (name, seed) not in held:
            held[name, seed] = generate(sc, days=a.days, seed=seed + 1, policy=sc.data_policy, weather_part="test")
        model = load(folder)
        df, h = held[name, seed], a.horizon
        if isinstance(model, ARXModel):
            mae = model.horizon_mae(df, h, planned=True)
        elif isinstance(model, LearnedModel):
            mae = evaluate_model(model, df, [h])["horizons"][str(h)]["T_r_mae"]
            if mae is not None and zero_unforced(model):
                net0 = evaluate_model(model, df, [h])["horizons"][str(h)]["T_r_mae"]
                if net0 is not None:
                    errors[name, m["arch"] + NET0, int(m["days"])][seed] = net0
                    print(f"{folder.name}, its unforced network zeroed: {net0:.3f} C", flush=True)
        else:
            continue
        if mae is None:  # held-out days shorter than the horizon
            continue
        errors[name, m["arch"], int(m["days"])][seed] = mae
        print(f"{folder.name}: {mae:.3f} C", flush=True)
    print()
    print(f"| building | family | training days | seeds | T_r error {a.horizon} ahead, mean (worst) [C] | / parx's (mean) |")
    print("|---|---|---|---|---|---|")
    for (name, arch, days), by_seed in sorted(errors.items()):
        mean = statistics.fmean(by_seed.values())
        parx = errors.get((name, "parx", days), {})
        ratio = f"{mean / statistics.fmean(parx.values()):.3f}" if parx else ""
        print(f"| {name} | {arch} | {days} | {len(by_seed)} | {mean:.3f} ({max(by_seed.values()):.3f}) | {ratio} |")
    return 0


def zero_unforced(model: LearnedModel) -> bool:
    """Zero the output layer of ``model``'s unforced network (a consistent family's: its
    learned heat input is then nil in every member), in place; False where it has none."""
    unforced = getattr(model.module.net, "unforced", None)
    if not isinstance(unforced, UnforcedNet):
        return False
    unforced.zero_output()
    return True


if __name__ == "__main__":
    raise SystemExit(main())
