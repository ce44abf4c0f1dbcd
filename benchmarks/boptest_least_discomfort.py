"""How little thermal discomfort a heating-only controller can reach on a BOPTEST test period:
a hindsight reference, not a controller of the package.

The controller here knows what no controller of the package knows: BOPTEST's forecasts are
exact, and its model of the emulator is fitted on the test period's own weeks. It minimises
BOPTEST's discomfort alone (energy only breaks ties), so its discomfort is what the emulator
gives when comfort is all that counts and the model errs by about 0.2 C a day ahead.

1. Four identification runs through BOPTEST's API over the six weeks that end with the test
   period (from day 7 at the earliest, after BOPTEST's 7-day warm-up): two of random heat-pump
   modulation, two of a noisy thermostat at random set-points.
2. A linear ARX of the zone temperature (lags of the room, the modulation u and u * T_out, the
   outdoor temperature, irradiance and internal gains), fitted one step ahead, then refined on
   its 24-h rollouts. u enters linearly, so control over it is a linear programme.
3. A receding-horizon LP (72 h, re-solved every 30 min) on that ARX, the comfort band narrowed
   by a back-off, run on the test period; its run is added to the data and the ARX refitted.
4. The same controller with back-offs 0, 0.2 and 0.4 K on the refitted ARX: BOPTEST's KPIs,
   the discomfort per day, and the ARX's own open-loop optimum over the period.
5. No model: the least-discomfort run of the lowest tdis replayed on the emulator up to 20:00
   before the period's last day, then the heat pump off. Heating only raises the temperatures
   that follow, so from that state no policy has less discomfort above the band after it.

Needs a BOPTEST server (``BOPTEST_URL`` or ``--url``): BOPTEST's own service (``docker compose
up web worker provision`` in a clone of https://github.com/ibpsa/project1-boptest), or see
docs/boptest.md to run it without Docker. About 11-20 min on two cores::

    python benchmarks/boptest_least_discomfort.py [--period typical_heat_day] [--price dynamic]
"""

from __future__ import annotations

import argparse
import datetime as dt
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import closing, contextmanager
from dataclasses import dataclass

import cvxpy as cp
import numpy as np
from scipy.optimize import least_squares

from scenarios.plants.boptest_client import BoptestClient, BoptestTest, server_url

TESTCASE = "bestest_hydronic_heat_pump"
DT_S = 1800.0
PER_DAY = int(86400 / DT_S)
PERIOD_DAYS = 14
#: the test periods' first day of the year (BOPTEST's days.json: 14 days centred on 23 and 115)
FIRST_DAY = {"peak_heat_day": 16, "typical_heat_day": 108}
ID_DAYS = 42  # identification runs: six weeks ending with the test period (from day 7 at the earliest)
WARMUP_DAYS = 7
NA, NB = 4, 12  # ARX lags of the room temperature and of each input (2 h and 6 h)
FORECAST = ["TDryBul", "HGloHor", "InternalGainsCon[1]", "InternalGainsRad[1]", "LowerSetp[1]",
            "UpperSetp[1]"]


@dataclass
class Run:
    """One run at 30-min intervals: room temperature at each boundary (n+1), the modulation
    and the exogenous inputs of each interval (n+1, the last unused), and the band."""

    T: np.ndarray
    u: np.ndarray
    To: np.ndarray
    irr: np.ndarray
    gains: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def inputs(self) -> np.ndarray:
        """The ARX's input columns per interval: u, u * T_out, T_out, irradiance/100, gains/100."""
        return np.stack([self.u, self.u * self.To, self.To, self.irr / 100, self.gains / 100], 1)


@contextmanager
def one_test(url: str) -> Iterator[BoptestTest]:
    """A test of TESTCASE on the server at ``url``: stopped, and its session closed, however
    the block is left."""
    with closing(BoptestClient(url, timeout_s=600)) as client, client.select(TESTCASE) as test:
        yield test


def exogenous(fc: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    """The forecast's first n samples as the run's exogenous columns [C, W/m2, W]."""
    return {
        "To": fc["TDryBul"][:n] - 273.15, "irr": fc["HGloHor"][:n],
        "gains": fc["InternalGainsCon[1]"][:n] + fc["InternalGainsRad[1]"][:n],
        "lo": fc["LowerSetp[1]"][:n] - 273.15, "hi": fc["UpperSetp[1]"][:n] - 273.15,
    }


def identification_run(url: str, seed: int, first_day: float, days: int, policy: str) -> Run:
    """``days`` days from first_day (after a 7-day warm-up) under random modulation (policy
    ``random``) or a noisy proportional thermostat at random set-points 19.5-24.5 C (``band``)."""
    rng = np.random.default_rng(seed)
    n = days * PER_DAY
    levels, setpoints = np.empty(n), np.empty(n)
    k = 0
    while k < n:  # held 1-8 h; off a third of the time
        hold = int(rng.integers(2, 17))
        levels[k:k + hold] = 0.0 if rng.random() < 0.35 else rng.uniform(0.05, 1.0)
        k += hold
    k = 0
    while k < n:  # set-points held 2-12 h
        hold = int(rng.integers(4, 25))
        setpoints[k:k + hold] = rng.uniform(19.5, 24.5)
        k += hold
    with one_test(url) as test:
        test.set_step(DT_S)
        y = test.initialize(first_day * 86400, WARMUP_DAYS * 86400)
        fc = test.forecast(FORECAST, horizon_s=(days + 1) * 86400, interval_s=DT_S)
        T = [y["reaTZon_y"] - 273.15]
        u = np.zeros(n + 1)
        for k in range(n):
            if policy == "band":
                demand = 0.6 * (setpoints[k] - T[-1]) + 0.15 * rng.standard_normal() + 0.2
                u[k] = 0.0 if demand < 0.05 else min(demand, 1.0)
            else:
                u[k] = levels[k]
            m = test.advance({"oveHeaPumY_u": float(u[k]), "oveHeaPumY_activate": 1})
            T.append(m["reaTZon_y"] - 273.15)
    return Run(T=np.array(T), u=u, **exogenous(fc, n + 1))


def regressors(T: np.ndarray, X: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The ARX's regressors predicting T[k+1] for each k (len(k), NA + 5 NB + 1)."""
    lags_t = T[k[:, None] - np.arange(NA)[None, :]]
    lags_x = X[k[:, None] - np.arange(NB)[None, :]].transpose(0, 2, 1).reshape(len(k), -1)
    return np.concatenate([lags_t, lags_x, np.ones((len(k), 1))], 1)


def rollouts(theta: np.ndarray, T: np.ndarray, X: np.ndarray, starts: np.ndarray, h: int) -> np.ndarray:
    """The ARX rolled out h steps from each start k0 (T known up to k0): (len(starts), h)."""
    a_t = theta[:NA]
    b_x = theta[NA:-1].reshape(X.shape[1], NB)
    buf = np.stack([T[starts - m] for m in range(NA)], 1)
    out = np.empty((len(starts), h))
    for i in range(h):
        xs = X[(starts + i)[:, None] - np.arange(NB)[None, :]]  # (S, NB, inputs)
        nxt = buf @ a_t + np.einsum("snc,cn->s", xs, b_x) + theta[-1]
        out[:, i] = nxt
        buf = np.concatenate([nxt[:, None], buf[:, :-1]], 1)
    return out


def fit(runs: list[Run], h: int = 2 * PER_DAY) -> np.ndarray:
    """Least squares one step ahead over all runs, then refined on h-step rollouts from every
    third interval (trust-region least squares)."""
    first = max(NA, NB)
    rows, targets = [], []
    for r in runs:
        k = np.arange(first, len(r.T) - 1)
        rows.append(regressors(r.T, r.inputs(), k))
        targets.append(r.T[k + 1])
    A, b = np.concatenate(rows), np.concatenate(targets)
    theta0 = np.linalg.solve(A.T @ A + 1e-6 * np.eye(A.shape[1]), A.T @ b)
    packs = []
    for r in runs:
        starts = np.arange(first, len(r.T) - h - 1, 3)
        packs.append((r.T, r.inputs(), starts, np.stack([r.T[k + 1:k + 1 + h] for k in starts])))

    def residuals(theta: np.ndarray) -> np.ndarray:
        return np.concatenate([(rollouts(theta, T, X, s, h) - Y).ravel() for T, X, s, Y in packs])

    return np.asarray(least_squares(residuals, theta0, max_nfev=100, x_scale="jac").x)


def day_ahead_mae(theta: np.ndarray, run: Run) -> float:
    """The ARX's mean absolute error 24 h ahead over the run [C]."""
    starts = np.arange(max(NA, NB), len(run.T) - PER_DAY - 1, 4)
    truth = np.stack([run.T[k + 1:k + 1 + PER_DAY] for k in starts])
    return float(np.abs(rollouts(theta, run.T, run.inputs(), starts, PER_DAY) - truth).mean())


def prediction(theta: np.ndarray, T: np.ndarray, X: np.ndarray, now: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """T[now+1..now+h] = c + M u[now..now+h-1] for the ARX, given T up to ``now``, the inputs
    before ``now`` and the exogenous columns ahead: (c (h,), M (h, h))."""
    a_t, b_x = theta[:NA], theta[NA:-1].reshape(X.shape[1], NB)
    rhs, B, L = np.full(h, theta[-1]), np.zeros((h, h)), np.zeros((h, h))
    for i in range(h):
        for m in range(NA):
            j = now + i - m
            if j <= now:
                rhs[i] += a_t[m] * T[j]
            else:
                L[i, j - now - 1] += a_t[m]
        for m in range(NB):
            j = now + i - m
            rhs[i] += b_x[2:, m] @ X[j, 2:]
            gain = b_x[0, m] + b_x[1, m] * X[j, 2]  # per unit of u: u and u * T_out
            if j < now:
                rhs[i] += gain * X[j, 0]
            else:
                B[i, j - now] += gain
    inv = np.linalg.inv(np.eye(h) - L)
    return inv @ rhs, inv @ B


def discomfort_lp(h: int, energy_weight: float = 1e-3) -> tuple[cp.Problem, dict[str, cp.Parameter], cp.Variable]:
    """min sum of the band's violations + energy_weight * sum u over h intervals, 0 <= u <= 1,
    with T = c + M u (parameters ``c``, ``M``, ``lo``, ``hi``)."""
    u = cp.Variable(h)
    par = {"c": cp.Parameter(h), "M": cp.Parameter((h, h)), "lo": cp.Parameter(h), "hi": cp.Parameter(h)}
    t = par["c"] + par["M"] @ u
    cost = cp.sum(cp.pos(t - par["hi"])) + cp.sum(cp.pos(par["lo"] - t)) + energy_weight * cp.sum(u)
    return cp.Problem(cp.Minimize(cost), [u >= 0, u <= 1]), par, u


@dataclass
class Outcome:
    """A least-discomfort run: BOPTEST's KPIs, the run, and the ARX's open-loop optimum [K h]."""

    kpi: dict[str, float | None]
    run: Run
    model_optimum_k_h: float


def least_discomfort_run(url: str, theta: np.ndarray, period: str, price: str, margin_k: float,
                         horizon: int = 3 * PER_DAY) -> Outcome:
    """The receding-horizon LP on the ARX over BOPTEST's test period, the band narrowed by
    margin_k; the history before the period (BOPTEST's warm-up) from ``/results``."""
    n = PERIOD_DAYS * PER_DAY
    history = max(NA, NB) + 1
    problem, par, u_var = discomfort_lp(horizon)
    with one_test(url) as test:
        t0 = float(test.set_scenario(time_period=period, electricity_price=price)["time_period"]["time"])
        test.set_step(DT_S)
        fc = exogenous(test.forecast(FORECAST, horizon_s=(PERIOD_DAYS + horizon / PER_DAY + 1) * 86400,
                                     interval_s=DT_S), n + horizon + 1)
        past = test.results(["reaTZon_y", "reaHeaPumY_y", "weaSta_reaWeaTDryBul_y", "weaSta_reaWeaHGloHor_y"],
                            start_time_s=t0 - history * DT_S, final_time_s=t0)
        edges = t0 - np.arange(history, -1, -1) * DT_S
        T = list(np.interp(edges, past["time"], past["reaTZon_y"]) - 273.15)
        idx = np.clip(np.searchsorted(edges, past["time"], side="right") - 1, 0, history - 1)

        def mean_past(name: str) -> np.ndarray:
            return np.bincount(idx, past[name], history) / np.maximum(np.bincount(idx, None, history), 1)

        u_all = np.concatenate([mean_past("reaHeaPumY_y"), np.zeros(n + horizon + 1)])
        X = np.stack([
            u_all, np.zeros_like(u_all),
            np.concatenate([mean_past("weaSta_reaWeaTDryBul_y") - 273.15, fc["To"]]),
            np.concatenate([mean_past("weaSta_reaWeaHGloHor_y"), fc["irr"]]) / 100,
            np.concatenate([fc["gains"][PER_DAY - history:PER_DAY], fc["gains"]]) / 100,  # daily schedule
        ], 1)
        X[:, 1] = X[:, 0] * X[:, 2]
        c, M = prediction(theta, np.array(T), X, history, n)
        u_open = cp.Variable(n)
        t_open = c + M @ u_open
        violation = cp.sum(cp.pos(t_open - fc["hi"][1:n + 1])) + cp.sum(cp.pos(fc["lo"][1:n + 1] - t_open))
        cp.Problem(cp.Minimize(violation + 1e-3 * cp.sum(u_open)), [u_open >= 0, u_open <= 1]).solve(solver=cp.HIGHS)
        optimum = float(violation.value) * DT_S / 3600
        for k in range(n):
            now = history + k
            par["c"].value, par["M"].value = prediction(theta, np.array(T), X, now, horizon)
            par["lo"].value = fc["lo"][k + 1:k + 1 + horizon] + margin_k
            par["hi"].value = fc["hi"][k + 1:k + 1 + horizon] - margin_k
            problem.solve(solver=cp.HIGHS)
            u = 0.5 if u_var.value is None else float(np.clip(u_var.value[0], 0.0, 1.0))
            X[now, 0], X[now, 1] = u, u * X[now, 2]
            T.append(test.advance({"oveHeaPumY_u": u, "oveHeaPumY_activate": 1})["reaTZon_y"] - 273.15)
        kpi = test.kpi()
    run = Run(T=np.array(T[history:]), u=X[history:history + n + 1, 0], **{k: v[:n + 1] for k, v in fc.items()})
    return Outcome(kpi=kpi, run=run, model_optimum_k_h=optimum)


def off_after(url: str, run: Run, period: str, price: str, cut: int) -> tuple[float, float]:
    """``run``'s modulation replayed on the emulator up to interval ``cut``, then the heat pump
    off: the K h above and below the band after ``cut`` (30-min samples)."""
    n = PERIOD_DAYS * PER_DAY
    T = []
    with one_test(url) as test:
        T.append(test.set_scenario(time_period=period, electricity_price=price)["time_period"]["reaTZon_y"] - 273.15)
        test.set_step(DT_S)
        for k in range(n):
            u = float(run.u[k]) if k < cut else 0.0
            T.append(test.advance({"oveHeaPumY_u": u, "oveHeaPumY_activate": 1})["reaTZon_y"] - 273.15)
    after = np.array(T)[cut + 1:]
    above = np.maximum(after - run.hi[cut + 1:], 0).sum() * DT_S / 3600
    below = np.maximum(run.lo[cut + 1:] - after, 0).sum() * DT_S / 3600
    return float(above), float(below)


def per_day(run: Run) -> list[tuple[float, float]]:
    """Kelvin-hours above and below the band per day, from the 30-min samples."""
    above = np.maximum(run.T - run.hi, 0)[1:] * DT_S / 3600
    below = np.maximum(run.lo - run.T, 0)[1:] * DT_S / 3600
    days = len(above) // PER_DAY
    return [(float(above[d * PER_DAY:(d + 1) * PER_DAY].sum()), float(below[d * PER_DAY:(d + 1) * PER_DAY].sum()))
            for d in range(days)]


def _or_inf(value: float | None) -> float:
    """A KPI BOPTEST may leave empty (None), as infinity."""
    return np.inf if value is None else float(value)


def main() -> None:
    """Parse the arguments, run the four stages and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--url", default=None, help="BOPTEST server (default: $BOPTEST_URL)")
    parser.add_argument("--period", default="typical_heat_day", choices=sorted(FIRST_DAY))
    parser.add_argument("--price", default="dynamic")
    parser.add_argument("--margins", default="0,0.2,0.4", help="back-offs [K] of the final runs")
    args = parser.parse_args()
    url = server_url(args.url)
    first = FIRST_DAY[args.period]
    start = time.perf_counter()
    plan = [(1, "random"), (2, "random"), (3, "band"), (4, "band")]
    with ThreadPoolExecutor(2) as pool:
        id_first = max(WARMUP_DAYS, first + PERIOD_DAYS - ID_DAYS)
        id_days = first + PERIOD_DAYS - id_first
        runs = list(pool.map(lambda p: identification_run(url, p[0], id_first, id_days, p[1]), plan))
    print(f"identification: {len(runs)} runs of {id_days} days from day {id_first} ({time.perf_counter() - start:.0f} s)", flush=True)
    theta = fit(runs)
    first_pass = least_discomfort_run(url, theta, args.period, args.price, 0.2)
    print(f"ARX on the identification runs: 24-h MAE {day_ahead_mae(theta, first_pass.run):.3f} C on its own "
          f"controlled run; tdis there {first_pass.kpi['tdis_tot']:.2f} K h", flush=True)
    theta = fit([*runs, first_pass.run])
    margins = [float(m) for m in args.margins.split(",")]
    with ThreadPoolExecutor(2) as pool:
        outcomes = list(pool.map(lambda m: least_discomfort_run(url, theta, args.period, args.price, m), margins))
    print(f"refitted ARX (+ that run): 24-h MAE on the back-off runs {', '.join(f'{day_ahead_mae(theta, o.run):.3f}' for o in outcomes)} C; "
          f"its open-loop optimum over the period {outcomes[0].model_optimum_k_h:.2f} K h")
    print(f"\n{args.period}, {args.price} price; least-discomfort LP, 72-h horizon, exact forecasts")
    print("| back-off K | BOPTEST tdis K h/zone | above K h | below K h | cost EUR/m2 | energy kWh/m2 |")
    print("|---|---|---|---|---|---|")
    daily = [per_day(o.run) for o in outcomes]
    for m, o, days in zip(margins, outcomes, daily, strict=True):
        print(f"| {m:g} | {o.kpi['tdis_tot']:.2f} | {sum(a for a, _ in days):.2f} | {sum(b for _, b in days):.2f} | "
              f"{o.kpi['cost_tot']:.3f} | {o.kpi['ener_tot']:.3f} |")
    print("\nper day, above / below K h (30-min samples):")
    for d in range(PERIOD_DAYS):
        date = dt.date(2018, 1, 1) + dt.timedelta(days=first + d)
        cells = [days[d] for days in daily]
        print(f"{date} {date:%a}: " + "   ".join(f"{a:.2f} / {b:.2f}" for a, b in cells))
    best_i = min(range(len(outcomes)), key=lambda i: _or_inf(outcomes[i].kpi["tdis_tot"]))
    best = outcomes[best_i]
    cut = (PERIOD_DAYS - 1) * PER_DAY - 4 * PER_DAY // 24
    kept = daily[best_i]
    above, below = off_after(url, best.run, args.period, args.price, cut)
    print(f"\nthe run of tdis {best.kpi['tdis_tot']:.2f} replayed to 20:00 before the last day, then the heat pump off: "
          f"{above:.2f} K h above and {below:.2f} below the band after it (that run: "
          f"{sum(a for a, _ in kept[-1:]):.2f} above, {sum(b for _, b in kept[-1:]):.2f} below on the last day)")
    print(f"\nwall time {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
