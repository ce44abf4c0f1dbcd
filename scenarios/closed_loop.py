"""The closed loop: a controller against the simulator, do-mpc style.

Every control interval k::

    obs = measure(sim)                 # Observation: measured T_r, the past, hidden T_m
    u = controller.act(obs, forecast)  # timed; an exception or non-finite u -> fallback
    result = sim.step(u, T_a, G, I_g)  # minute substeps with the backup thermostat

Warm-up: learned models need a history of at least ``depth + 1`` steps and observers need
time to settle, so every run starts with ``warmup_steps`` intervals (default one day) driven by
the thermostat. They are not counted in the KPIs nor written to the trajectory; the counted
steps are the ``days`` that follow, and observations keep the whole past, warm-up included, with
``Observation.k`` counting from the start of the warm-up.

Forecasts are perfect by default: at step k the controller gets every known future row, from k
to the end of the run plus ``scenario.horizon_steps`` lead rows. ``forecast_noise_std_c`` adds
seeded Gaussian noise to the future outdoor temperature (rows after the current one); the noise
depends only on ``seed``, so every controller sees the same forecasts.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from tqdm import tqdm

from controllers.base import Controller, ControlSpec, Forecast, Observation, fallback_power
from controllers.thermostat import Thermostat
from pinn_mpc.data import write_timeseries
from pinn_mpc.errors import InputError
from pinn_mpc.io import PathsArg, atomic_write_json, check_distinct, check_writable
from pinn_mpc.simulator import Simulator
from scenarios.factory import MODEL_CONTROLLERS, make_controller
from scenarios.inputs import day_span, time_of_day_h
from scenarios.kpis import compute_kpis
from scenarios.registry import EXOGENOUS_COLUMNS, Scenario, check_seed, get_scenario

#: Columns the trajectory adds to the data format.
EXTRA_COLUMNS = ("overridden", "fallback", "decision_ms")
_FORECAST_NOISE_STREAM = 1
_EXOGENOUS = EXOGENOUS_COLUMNS[1:]  # all but time


@dataclass(frozen=True, kw_only=True)
class ClosedLoopResult:
    """One run: ``trajectory`` has one row per counted interval (data format + EXTRA_COLUMNS,
    ``attrs['dt_s']``); ``kpis`` the KPI dict (see :mod:`scenarios.kpis`) plus ``controller``,
    ``scenario``, ``days``, ``seed``, ``weather_part`` and the [first, last] dates of the
    ``counted_days`` and of the ``weather_days`` (warm-up and forecast lead included);
    ``errors`` one line per controller exception."""

    trajectory: pd.DataFrame
    kpis: dict[str, Any]
    errors: tuple[str, ...]


def _decide(
    controller: Controller, obs: Observation, forecast: Forecast, spec: ControlSpec
) -> tuple[float, float, bool, str | None]:
    """Call ``act`` once, timed: (demand [W], decision time [s], fallback used, error line)."""
    error = None
    start = time.perf_counter()
    try:
        action = np.asarray(controller.act(obs, forecast), dtype=float)
        if action.size != 1 or not math.isfinite(float(action.reshape(-1)[0])):
            error = f"act returned {action!r}, not one finite number"
    except Exception as exc:  # a controller failure must not end the run: fall back, count it
        error = f"{type(exc).__name__}: {exc}"
    elapsed = time.perf_counter() - start
    if error is not None:
        return fallback_power(obs, forecast, spec), elapsed, True, error
    try:
        own_fallback = bool(controller.last_stats.fallback)
    except Exception as exc:
        own_fallback, error = True, f"last_stats: {type(exc).__name__}: {exc}"
    u = float(np.clip(float(action.reshape(-1)[0]), 0.0, spec.u_max_w))
    return u, elapsed, own_fallback, error


def run_closed_loop(
    scenario: Scenario,
    controller: Controller,
    *,
    days: int,
    seed: int,
    forecast_noise_std_c: float = 0.0,
    warmup_steps: int | None = None,
    label: str | None = None,
    weather_part: str = "test",
    progress: bool = False,
) -> ClosedLoopResult:
    """Run ``controller`` on ``scenario`` for ``days`` counted days after the warm-up.

    ``seed`` fixes the weather/price draw of the scenario, the sensor noise and the forecast
    noise, so two runs with the same seed see the same disturbances. ``weather_part`` is the
    part of the scenario's weather the run is drawn from (default the test part; see
    :mod:`scenarios.inputs`). ``warmup_steps`` defaults to one day of intervals. ``label``
    names the controller in the KPIs (default its ``name``).
    ``progress`` shows a bar on stderr for runs over a second, when it is a terminal.
    """
    if days < 1:
        raise InputError(f"closed loop: days must be >= 1, got {days}")
    check_seed(seed)
    if not (math.isfinite(forecast_noise_std_c) and forecast_noise_std_c >= 0):
        raise InputError(f"forecast_noise_std_c must be >= 0, got {forecast_noise_std_c!r}")
    sim_config = scenario.sim
    spec: ControlSpec = scenario.control_spec()
    spd = scenario.steps_per_day
    warmup = spd if warmup_steps is None else warmup_steps
    if warmup < 0:
        raise InputError(f"closed loop: warmup_steps must be >= 0, got {warmup}")
    n_run = days * spd
    total = warmup + n_run
    horizon = scenario.horizon_steps
    exo = scenario.exogenous(
        days=days + math.ceil(warmup / spd), seed=seed, part=weather_part, lead_steps=horizon
    )
    if len(exo) < total + horizon:
        raise InputError(
            f"scenario {scenario.name!r} gave {len(exo)} exogenous rows, need {total + horizon}"
        )
    exo = exo.iloc[: total + horizon].reset_index(drop=True)
    cols = {c: exo[c].to_numpy(dtype=float) for c in _EXOGENOUS}
    tod = time_of_day_h(exo["time"])

    warmup_controller = Thermostat(spec)
    warmup_controller.reset(seed)
    controller.reset(seed)
    sim = Simulator(sim_config, n_buildings=1, seed=seed)
    sim.reset(scenario.initial_t_r_c, scenario.initial_t_m_c)
    forecast_rng = np.random.default_rng([seed, _FORECAST_NOISE_STREAM])

    t_r_meas = np.zeros(total)
    t_m_true = np.zeros(total)
    u_dem = np.zeros(total)
    u_phys = np.zeros(total)
    overridden = np.zeros(total, dtype=bool)
    fallback = np.zeros(total, dtype=bool)
    decision_s = np.zeros(total)
    t_r_sub = np.zeros((total, sim_config.n_substeps))
    errors: list[str] = []
    history_src = {"T_a": cols["T_a"], "G": cols["G"], "I_g": cols["I_g"], "time_of_day_h": tod}
    steps = tqdm(
        range(total),
        desc=label or controller.name,
        unit="step",
        delay=1.0,
        leave=False,
        disable=None if progress else True,  # None: off when stderr is not a terminal
    )
    for k in steps:
        t_r_meas[k] = sim.measure()[0]
        t_m_true[k] = sim.state[0, 1]
        # Copies: a controller may keep or change what it is given without touching the run.
        history = {name: np.array(src[: k + 1]) for name, src in history_src.items()}
        history["T_r"] = np.array(t_r_meas[: k + 1])
        history["u"] = np.array(u_dem[:k])
        history["u_phys"] = np.array(u_phys[:k])
        obs = Observation(
            k=k, t_r_c=float(t_r_meas[k]), history=history, t_m_true_c=float(t_m_true[k])
        )
        t_a_forecast = cols["T_a"][k:].copy()
        if forecast_noise_std_c > 0:
            n_future = len(t_a_forecast) - 1
            t_a_forecast[1:] += forecast_rng.normal(0.0, forecast_noise_std_c, n_future)
        forecast = Forecast(
            time_of_day_h=np.array(tod[k:]),
            t_a_c=t_a_forecast,
            g_w_per_m2=np.array(cols["G"][k:]),
            i_g_w=np.array(cols["I_g"][k:]),
            price_eur_per_kwh=np.array(cols["price"][k:]),
            t_min_c=np.array(cols["T_min"][k:]),
            t_max_c=np.array(cols["T_max"][k:]),
        )
        acting = warmup_controller if k < warmup else controller
        u_dem[k], decision_s[k], fallback[k], error = _decide(acting, obs, forecast, spec)
        if error is not None:
            errors.append(f"step {k}: {error}")
        step = sim.step(u_dem[k], cols["T_a"][k], cols["G"][k], cols["I_g"][k])
        u_phys[k] = step.u_phys_w[0]
        overridden[k] = bool(step.overridden[0])
        t_r_sub[k] = step.t_r_sub_c[0]

    counted = slice(warmup, total)
    trajectory = pd.DataFrame(
        {
            "time": exo["time"].iloc[counted].reset_index(drop=True),
            "T_r": t_r_meas[counted],
            "T_m": t_m_true[counted],
            "u": u_dem[counted],
            "u_phys": u_phys[counted],
            **{c: cols[c][counted] for c in _EXOGENOUS},
            "overridden": overridden[counted].astype(int),
            "fallback": fallback[counted].astype(int),
            "decision_ms": decision_s[counted] * 1000.0,
        }
    )
    trajectory.attrs["dt_s"] = float(sim_config.dt_s)
    kpis = compute_kpis(
        u_phys_w=u_phys[counted],
        price_eur_per_kwh=cols["price"][counted],
        t_r_sub_c=t_r_sub[counted],
        t_min_c=cols["T_min"][counted],
        t_max_c=cols["T_max"][counted],
        decision_s=decision_s[counted],
        overridden=overridden[counted],
        fallback=fallback[counted],
        dt_s=sim_config.dt_s,
        comfort_weight_eur_per_kh=spec.comfort_weight_eur_per_kh,
    )
    kpis.update(
        controller=label or controller.name,
        scenario=scenario.name,
        days=days,
        seed=seed,
        weather_part=weather_part,
        counted_days=day_span(trajectory["time"]),
        weather_days=day_span(exo["time"]),  # warm-up and forecast lead included
    )
    return ClosedLoopResult(trajectory=trajectory, kpis=kpis, errors=tuple(errors))


@contextlib.contextmanager
def one_torch_thread() -> Iterator[None]:
    """Planners roll out small tensors: one intra-op thread is fastest on a shared machine."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def write_trajectory(result: ClosedLoopResult, path: str | Path) -> Path:
    """The trajectory CSV: the data format's columns, then :data:`EXTRA_COLUMNS`."""
    return write_timeseries(result.trajectory, path)


def closed_loop_command(
    *,
    scenario: str,
    controller: str,
    model: str | None,
    rc: str | None,
    days: int,
    seed: int,
    json_path: str,
    csv_path: str | None,
    plot_path: str | None,
    weather_part: str = "test",
) -> str:
    """``pinn-mpc closed-loop``: run, write KPI JSON (and CSV, plot), return a summary that
    names every file written. Outputs are checked before the run: writable, and none of them
    the same file as an input (``--model``'s files, ``--rc``) or as another output."""
    from scenarios.plots import plot_trajectory  # matplotlib only when plotting

    outputs = {"--json": json_path, "--csv": csv_path, "--plot": plot_path}
    check_writable(*outputs.values())
    inputs: dict[str, PathsArg] = {"--rc": rc}
    if model is not None:
        from pinn_mpc.artifacts import MODEL_DIRECTORY  # torch: only when a model is given

        inputs["--model"] = MODEL_DIRECTORY.paths(model)
    check_distinct(inputs=inputs, outputs=outputs)
    scen = get_scenario(scenario)
    ctrl = make_controller(
        controller,
        scen,
        model_dir=model,
        rc_path=rc,
        n_steps=days * scen.steps_per_day,
    )
    # torch only for the planners over learned models; the others start faster without it.
    threads = one_torch_thread() if controller in MODEL_CONTROLLERS else contextlib.nullcontext()
    with threads:
        result = run_closed_loop(
            scen, ctrl, days=days, seed=seed, weather_part=weather_part, progress=True
        )
    if csv_path is not None:
        write_trajectory(result, csv_path)
    if plot_path is not None:
        plot_trajectory(result.trajectory, plot_path, title=f"{controller} on {scenario}")
    atomic_write_json(json_path, result.kpis)
    lines = [format_kpis(result.kpis)]
    if result.errors:
        lines.append(f"{len(result.errors)} controller error(s), first: {result.errors[0]}")
    written = [str(p) for p in (json_path, csv_path, plot_path) if p is not None]
    return "\n".join([*lines, f"wrote {', '.join(written)}"])


def format_kpis(kpis: dict[str, Any]) -> str:
    """One line: the main KPIs of a run."""
    return (
        f"{kpis['controller']} on {kpis['scenario']}, {kpis['days']} d: "
        f"energy {kpis['energy_kwh']:.2f} kWh, cost {kpis['cost_eur']:.2f} EUR, "
        f"discomfort {kpis['discomfort_kh']:.2f} K h, peak {kpis['peak_kw']:.2f} kW, "
        f"objective {kpis['objective']:.2f} EUR, decision {kpis['decision_ms_median']:.1f} ms "
        f"(median), overrides {kpis['backup_overrides']}, fallbacks {kpis['fallbacks']}"
    )
