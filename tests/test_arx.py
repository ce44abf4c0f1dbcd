"""The linear ARX baseline: exact on a linear plant it can represent, and careful with input."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.models.arx import ARXModel, fit_arx
from pinn_mpc.physics import RCParams, discretise


def _rc_data(days: int, seed: int, *, measured_gains: bool = False) -> pd.DataFrame:
    """A 2R2C driven by random power and weather, plus a workday-only internal gain of 1 kW
    from 08:00 to 18:00 that the data does not show: the ARX must learn it as its schedule."""
    rng = np.random.default_rng(seed)
    dt_s, n = 1800.0, days * 48
    params = RCParams(
        r_ra_k_per_w=1 / 150, r_rm_k_per_w=1 / 600, c_r_j_per_k=4e6, c_m_j_per_k=4e7,
        solar_aperture_m2=3.0, gain_to_air_fraction=1.0,
    )
    ad, bd = discretise(params, dt_s)
    time = pd.date_range("2022-01-03", periods=n, freq="30min")
    workday_hours = (time.day_of_week < 5) & (time.hour >= 8) & (time.hour < 18)
    gains = np.where(workday_hours, 1000.0, 0.0)
    u = rng.uniform(0, 5000, n)
    t_a = 5 + 5 * np.sin(np.arange(n) / 48 * 2 * np.pi) + rng.normal(0, 1, n)
    g = np.clip(300 * np.sin((np.arange(n) % 48 - 12) / 24 * np.pi), 0, None)
    x = np.array([20.0, 20.0])
    t_r = np.empty(n)
    for k in range(n):
        t_r[k] = x[0]
        x = ad @ x + bd @ np.array([u[k], t_a[k], g[k], gains[k]])
    df = pd.DataFrame({"time": time, "T_r": t_r, "u": u, "u_phys": u, "T_a": t_a, "G": g})
    if measured_gains:
        df["I_g"] = gains
    df.attrs["dt_s"] = dt_s
    return df


@pytest.mark.parametrize(("measured_gains", "tolerance_c"), [(True, 1e-3), (False, 0.25)])
def test_arx_predicts_a_linear_plant(measured_gains, tolerance_c):
    """With the gains measured the 2R2C is exactly an ARX of order 2: the fit reproduces it.
    Unmeasured, the workday schedule stands in for them; it is block-constant, so the gains'
    lagged effect (through T_m) after a block edge is not, and errors stay within 0.25 K of a
    room swinging by several K."""
    model = fit_arx(_rc_data(21, seed=0, measured_gains=measured_gains), lags=4)
    test = _rc_data(7, seed=1, measured_gains=measured_gains)
    starts = np.arange(model.lags - 1, len(test) - 48)
    path = model.predict_path(test, 48, starts)
    for horizon in (1, 24, 48):
        pred = model.predict_t_r(test, horizon, starts)
        assert np.mean(np.abs(pred - test["T_r"].to_numpy()[starts + horizon])) < tolerance_c
        assert np.array_equal(path[:, horizon - 1], pred)
    assert set(model.to_dict()) >= {"kind", "columns", "lags", "coef", "dt_s"}


def test_a_planned_prediction_takes_the_demand_from_its_start_and_the_delivered_before():
    """``planned``: the power from each start on is the demanded ``u`` (as a network's
    rollout and a planner take it), the history's the delivered ``u_phys``. On data where the
    two differ (a backup heater that delivers what was not demanded), the planned prediction
    is the ordinary one on data whose delivered power from the start on is the demand."""
    model = fit_arx(_rc_data(21, seed=0, measured_gains=True), lags=4)
    test = _rc_data(7, seed=1, measured_gains=True)
    rng = np.random.default_rng(2)
    test["u_phys"] = test["u"] + rng.choice([0.0, 3000.0], len(test), p=[0.8, 0.2])
    start, horizon = 100, 24
    planned = model.predict_path(test, horizon, np.array([start]), planned=True)
    as_demanded = test.copy()
    as_demanded.loc[start:, "u_phys"] = as_demanded.loc[start:, "u"]
    np.testing.assert_allclose(planned, model.predict_path(as_demanded, horizon, np.array([start])), rtol=0, atol=1e-12)
    assert not np.allclose(planned, model.predict_path(test, horizon, np.array([start])))
    assert model.horizon_mae(test, horizon, planned=True) == pytest.approx(float(np.mean(np.abs(
        model.predict_t_r(test, horizon, np.arange(3, len(test) - horizon), planned=True)
        - test["T_r"].to_numpy()[np.arange(3, len(test) - horizon) + horizon]
    ))))


def test_arx_refuses_short_data_and_out_of_range_starts() -> None:
    with pytest.raises(InputError, match="too few"):
        fit_arx(_rc_data(1, seed=0))
    model: ARXModel = fit_arx(_rc_data(14, seed=0))
    test = _rc_data(2, seed=1)
    with pytest.raises(InternalError, match="starts must lie"):
        model.predict_t_r(test, 24, np.array([len(test) - 10]))
    with pytest.raises(InternalError, match="at least 1 step"):
        model.predict_t_r(test, 0, np.array([10]))
    with pytest.raises(InputError, match="lacks column"):
        model.predict_t_r(test.drop(columns="G"), 1, np.array([10]))


def test_arx_rollout_is_its_recursion_for_the_planners():
    """The planners' rollout of the ARX model from a history and a plan equals its own
    recursion on the same data (the plan being the data's delivered power)."""
    import torch

    from pinn_mpc.features import time_of_day_h

    model = fit_arx(_rc_data(21, seed=0), lags=4)
    test = _rc_data(3, seed=1)
    k, h = 30, 24
    time = pd.to_datetime(test["time"])
    history = {
        "T_r": test["T_r"].to_numpy()[: k + 1],
        "u_phys": test["u_phys"].to_numpy()[:k],
        "T_a": test["T_a"].to_numpy()[: k + 1],
        "G": test["G"].to_numpy()[: k + 1],
    }
    exog = {
        "time_of_day_h": time_of_day_h(test["time"])[k : k + h],
        "day_of_week": time.dt.day_of_week.to_numpy(dtype=float)[k : k + h],
        "T_a": test["T_a"].to_numpy()[k : k + h],
        "G": test["G"].to_numpy()[k : k + h],
    }
    plan = torch.tensor(test["u_phys"].to_numpy()[k : k + h])[None]
    roll = model.rollout(history, plan.repeat(3, 1), exog)
    assert roll.t_r_c.shape == (1, 3, h, 1) and model.exog_names == ("time_of_day_h", "day_of_week", "T_a", "G")
    for step in (1, 6, h):
        expected = model.predict_t_r(test, step, np.array([k]))[0]
        assert float(roll.t_r_c[0, 2, step - 1, 0]) == pytest.approx(expected, abs=1e-9)
    assert model.eta == 1.0
    with pytest.raises(InputError, match="dates"):
        model.rollout(history, plan, {**exog, "day_of_week": np.full(h, np.nan)})


def test_train_arch_arx_writes_numbers_that_evaluate_and_closed_loop_load(tmp_path, capsys):
    """The user's path with the ARX: ``train --arch arx`` writes arx.json, ``evaluate`` reads
    it, ``closed-loop --controller cem --model`` plans over it; tuning flags of the networks
    are refused, and a tampered file is refused with one line."""
    import json

    from pinn_mpc.data import write_timeseries
    from pinn_mpc_cli.cli import main

    data = tmp_path / "d.csv"
    write_timeseries(_rc_data(21, seed=0), data)
    model = tmp_path / "arx"
    assert main(["train", "--data", str(data), "--arch", "arx", "--out", str(model)]) == 0
    assert sorted(p.name for p in model.iterdir()) == ["arx.json"]
    assert main(["train", "--data", str(data), "--arch", "arx", "--out", str(tmp_path / "b"),
                 "--epochs", "5"]) == 2
    assert "do(es) not apply" in capsys.readouterr().err
    test = tmp_path / "t.csv"
    write_timeseries(_rc_data(4, seed=1), test)
    metrics = tmp_path / "m.json"
    assert main(["evaluate", "--model", str(model), "--data", str(test), "--json", str(metrics),
                 "--horizons", "1,24"]) == 0
    assert json.loads(metrics.read_text())["horizons"]["24"]["T_r_mae"] < 0.25
    kpis = tmp_path / "k.json"
    assert main(["closed-loop", "--scenario", "winter_household", "--controller", "cem",
                 "--model", str(model), "--days", "1", "--json", str(kpis)]) == 0
    assert json.loads(kpis.read_text())["objective"] > 0
    stored = json.loads((model / "arx.json").read_text())
    (model / "arx.json").write_text(json.dumps({**stored, "coef": stored["coef"][:-1]}))
    capsys.readouterr()
    assert main(["evaluate", "--model", str(model), "--data", str(test), "--json", str(tmp_path / "m2.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a valid ARX model" in err


def _occupied_data(
    days: int, seed: int, *, heater_gain: float = 0.002, start_h: int = 8,
    holidays: tuple[str, ...] = (), start: str = "2022-01-03",
) -> pd.DataFrame:
    """A first-order room whose heat loss and gains follow a workday / Saturday / Sunday
    schedule (occupancy-driven ventilation, from ``start_h`` to 18 h on workdays), with
    Sunday's on ``holidays`` (marked in a ``holiday`` column when there are any): exactly a
    physics-informed ARX of one lag."""
    rng = np.random.default_rng(seed)
    n = days * 48
    time = pd.date_range(start, periods=n, freq="30min")  # 2022-01-03 a Monday
    hour = time.hour.to_numpy()
    holiday = np.isin(time.normalize(), pd.DatetimeIndex(holidays))
    dow = np.where(holiday, 6, time.day_of_week.to_numpy())
    occupied = (hour >= start_h) & (hour < 18) & ((dow < 5) | ((dow == 5) & (hour < 12)))
    loss = np.where(occupied, 0.12, 0.05)  # share of T_r - T_a lost per interval
    gains = np.where(occupied, 0.6, 0.1) + np.where(dow == 5, 0.2, 0.0)  # K per interval
    u = rng.uniform(0, 1000, n)
    t_a = 2 + 4 * np.sin(np.arange(n) / 48 * 2 * np.pi) + rng.normal(0, 1, n)
    t_r = np.empty(n)
    t_r[0] = 20.0
    for k in range(n - 1):
        t_r[k + 1] = t_r[k] - loss[k] * (t_r[k] - t_a[k]) + heater_gain * u[k] + gains[k]
    df = pd.DataFrame({"time": time, "T_r": t_r, "u": u, "u_phys": u, "T_a": t_a})
    if holidays:
        df["holiday"] = holiday.astype(float)
    df.attrs["dt_s"] = 1800.0
    return df


def test_physics_informed_arx_recovers_an_occupancy_scaled_heat_loss_exactly():
    """On a room whose loss coefficient follows the occupancy (and a Saturday schedule of its
    own) the physics-informed ARX recovers the plant: its power coefficient and the loss of
    every block, and predicts 48 steps ahead exactly; the plain ARX cannot."""
    from pinn_mpc.models.arx import AIC_RESOLUTION_C, BLOCK_H, fit_physics_informed_arx

    train, test = _occupied_data(28, seed=0), _occupied_data(14, seed=1)
    model = fit_physics_informed_arx(train, lags=1)
    assert model.day_types == 3 and model.interaction
    assert model.block_h == BLOCK_H  # the schedule changes on even hours: the coarser blocks
    # The least squares of that structure recovers the plant; the fit taken may pool its
    # Saturdays and Sundays where the one-step errors stay below the criterion's resolution.
    exact = fit_arx(train, lags=1, day_types=3, interaction=True, block_h=BLOCK_H)
    n_lag = len(model.columns)  # one lag of T_r, u_phys, T_a
    for fit, tolerance in ((exact, 1e-6), (model, 1e-4)):
        assert fit.coef[1] * 1e-3 == pytest.approx(0.002, rel=tolerance)  # scaled: K per kW
        q = fit.coef[n_lag + fit.n_schedule :]
        blocks = int(24 / BLOCK_H)
        # workday 08-18 h is blocks 4-8, the T_r coefficient itself absorbs the unoccupied loss
        assert q[4] - q[0] == pytest.approx(-0.07, abs=100 * tolerance)
        assert q[blocks + 4] - q[blocks + 0] == pytest.approx(-0.07, abs=100 * tolerance)  # Saturday morning
        assert q[2 * blocks + 4] - q[2 * blocks + 0] == pytest.approx(0.0, abs=100 * tolerance)  # Sunday
    starts = np.arange(0, len(test) - 48)
    truth = test["T_r"].to_numpy()
    for fit, tolerance_c in ((exact, 1e-4), (model, AIC_RESOLUTION_C)):
        for horizon in (1, 24, 48):
            err = fit.predict_t_r(test, horizon, starts) - truth[starts + horizon]
            assert np.max(np.abs(err)) < tolerance_c  # the ridge of 1e-9 only; the pooling's
    plain = fit_arx(train, lags=1)
    assert np.mean(np.abs(plain.predict_t_r(test, 24, starts) - truth[starts + 24])) > 0.1


@pytest.mark.parametrize("seed", [1, 2])
def test_physics_informed_arx_keeps_the_saturday_schedule_of_two_noisy_weeks(seed):
    """Two weeks with a 0.05 K sensor noise hold two Saturdays: a cross-validation part that
    holds one out fits the Saturday blocks on the other and mispredicts, which took the
    schedule without Saturdays on these seeds (24-step MAE 0.24-0.27 K on the next two
    weeks); the schedule's information criterion on all the data keeps Saturdays, and the
    next two weeks are predicted at the noise's scale."""
    from pinn_mpc.models.arx import fit_physics_informed_arx, schedule_aic

    train = _occupied_data(14, seed=seed)
    train["T_r"] += np.random.default_rng(seed + 100).normal(0.0, 0.05, len(train))
    test = _occupied_data(14, seed=seed + 10, start="2022-01-17")
    model = fit_physics_informed_arx(train, lags=2)
    assert model.day_types == 3
    starts = np.arange(1, len(test) - 48)
    err = model.predict_t_r(test, 24, starts) - test["T_r"].to_numpy()[starts + 24]
    assert np.mean(np.abs(err)) < 0.1
    # The criterion by hand: n log(MSE) + 2 k over the one-step errors of the fit.
    steps = np.arange(1, len(train) - 1)
    one_step = model.predict_t_r(train, 1, steps) - train["T_r"].to_numpy()[steps + 1]
    n = steps.size
    expected = n * np.log(np.mean(one_step**2)) + 2 * model.coef.size
    assert schedule_aic(model, train) == pytest.approx(expected, rel=1e-12)


def test_offset_response_is_the_product_of_the_rooms_own_decay():
    """On the first-order room the lagged T_r weight plus a block's loss weight is 1 - loss, so
    a history 1 K warmer is left at the product of (1 - loss) over the horizon; the largest
    over the week's starts is a weekend's, at the unoccupied loss 0.05."""
    from pinn_mpc.models.arx import fit_physics_informed_arx

    model = fit_physics_informed_arx(_occupied_data(28, seed=0), lags=1)
    assert model.offset_response(24) == pytest.approx(0.95**24, rel=1e-4)
    assert model.offset_response(1) == pytest.approx(0.95, rel=1e-4)


def test_physics_informed_arx_on_a_week_takes_a_schedule_the_rows_can_fit():
    """A week (336 rows) cannot fit hourly blocks of three day types with 8 lags (more than
    half as many coefficients as rows), but 2-hour blocks: the fit takes those; a day of data
    fits none and is refused in one line."""
    from pinn_mpc.models.arx import fit_physics_informed_arx

    model = fit_physics_informed_arx(_occupied_data(7, seed=0))
    assert model.block_h == 2.0
    with pytest.raises(InputError, match="too few to fit"):
        fit_physics_informed_arx(_occupied_data(1, seed=0))


def test_a_pooled_fit_is_the_least_squares_without_its_ridge_and_one_weekend_with_a_large_one():
    """Pooling re-expresses Saturday's and Sunday's coefficients as a weekend's plus a deviation:
    with a vanishing ridge on the deviations the fit predicts as the least squares of the 3 day
    types does (its coefficients may differ along the directions the data leave undetermined:
    the room's own weight against the sum of the loss weights);
    with a large one Saturdays and Sundays get one schedule and one indoor-outdoor weight per
    block (the weekend's), while the workdays' stay near the least squares'."""
    from pinn_mpc.models.arx import fit_arx

    train = _occupied_data(14, seed=1)
    train["T_r"] += np.random.default_rng(1).normal(0.0, 0.05, len(train))
    plain = fit_arx(train, lags=2, day_types=3, interaction=True)
    tiny = fit_arx(train, lags=2, day_types=3, interaction=True, pool=1e-12)
    test = _occupied_data(14, seed=11, start="2022-01-17")
    starts = np.arange(1, len(test) - 49)
    assert np.allclose(tiny.predict_t_r(test, 48, starts), plain.predict_t_r(test, 48, starts), atol=1e-6)
    large = fit_arx(train, lags=2, day_types=3, interaction=True, pool=1e6)
    n_lag, blocks = 2 * len(large.columns), large.n_schedule // 3
    for first in (n_lag, n_lag + large.n_schedule):  # the schedule, then the loss weights
        workday, saturday, sunday = (large.coef[first + t * blocks : first + (t + 1) * blocks] for t in range(3))
        assert np.allclose(saturday, sunday, atol=1e-5 * np.max(np.abs(saturday)))
        assert not np.allclose(workday, saturday, atol=1e-3 * np.max(np.abs(saturday)))
    with pytest.raises(ValueError, match="pool must be a non-negative number"):
        fit_arx(train, lags=2, day_types=3, interaction=True, pool=-1.0)


def test_physics_informed_arx_pools_saturdays_and_sundays_where_two_noisy_weeks_hold_two_of_each():
    """Two weeks of the occupied room with a 0.05 K sensor noise: the least squares of 3 day
    types fits each weekend day's blocks on two days' rows, noise included, and errs 0.116 K
    on the next two weeks 24 steps ahead; the physics-informed ARX pools them as far as its
    criterion on the effective number of coefficients says, and errs 0.058 K."""
    from pinn_mpc.models.arx import fit_arx, fit_physics_informed_arx

    train = _occupied_data(14, seed=1, start_h=7)
    train["T_r"] += np.random.default_rng(1).normal(0.0, 0.05, len(train))
    test = _occupied_data(14, seed=11, start_h=7, start="2022-02-14")
    model = fit_physics_informed_arx(train)
    assert model.day_types == 3
    plain = fit_arx(train, lags=model.lags, day_types=3, interaction=True, block_h=model.block_h)
    starts = np.arange(model.lags, len(test) - 25)
    truth = test["T_r"].to_numpy()[starts + 24]

    def error(fit):
        return float(np.mean(np.abs(fit.predict_t_r(test, 24, starts) - truth)))

    assert not np.allclose(model.coef, plain.coef)
    assert error(model) < 0.07 and error(plain) > 0.1, (error(model), error(plain))


@pytest.mark.parametrize(("seed", "days"), [(0, 11), (6, 10)])
def test_physics_informed_arx_refuses_a_schedule_whose_room_runs_away(seed, days):
    """With one Saturday in noisy data the schedule of the lowest information criterion fits
    that day with a room that amplifies its own deviations (a history 1 K warmer is 1.5 K
    warmer 12 h later); the fit takes the best schedule whose room settles, which predicts the
    next two weeks better."""
    from pinn_mpc.models.arx import fit_arx, fit_physics_informed_arx, schedule_aic

    train = _occupied_data(days, seed=seed)
    train["T_r"] += np.random.default_rng(seed).normal(0.0, 0.1, len(train))
    test = _occupied_data(14, seed=seed + 10, start="2022-01-17")
    fits = [
        fit_arx(train, lags=3, day_types=d, interaction=True, block_h=b) for b in (2.0, 1.0) for d in (3, 2)
    ]
    lowest = min(fits, key=lambda fit: schedule_aic(fit, train))
    assert lowest.offset_response(24) > 1.0
    model = fit_physics_informed_arx(train, lags=3)
    assert model.offset_response(24) <= 1.0
    starts = np.arange(2, len(test) - 24)
    truth = test["T_r"].to_numpy()[starts + 24]

    def error(fit):
        return np.mean(np.abs(fit.predict_t_r(test, 24, starts) - truth))

    assert error(model) < error(lowest)


def test_physics_informed_arx_counts_holidays_as_sundays_and_takes_hourly_blocks_when_needed(tmp_path):
    """Occupancy from 07 h, and a Monday holiday run on the Sunday schedule in both the
    training and the test days: the fit takes hourly blocks and the ``holiday`` column, and
    predicts exactly, the holiday too; the saved model keeps its blocks. Without the column
    the holiday looks like a workday and the prediction of that day is off."""
    from pinn_mpc.models.arx import AIC_RESOLUTION_C, fit_physics_informed_arx, load_arx, save_arx

    train = _occupied_data(28, seed=0, start_h=7, holidays=("2022-01-17",))
    test = _occupied_data(14, seed=1, start_h=7, holidays=("2022-02-21",), start="2022-02-14")
    model = fit_physics_informed_arx(train, lags=1)
    assert model.block_h == 1.0
    starts = np.arange(0, len(test) - 48)
    truth = test["T_r"].to_numpy()
    err = model.predict_t_r(test, 24, starts) - truth[starts + 24]
    assert np.max(np.abs(err)) < AIC_RESOLUTION_C  # exact but for the pooling (test above)
    assert load_arx(save_arx(model, tmp_path / "m").parent).block_h == 1.0
    blind = fit_physics_informed_arx(train.drop(columns="holiday"), lags=1)
    off = blind.predict_t_r(test.drop(columns="holiday"), 24, starts) - truth[starts + 24]
    assert np.max(np.abs(off)) > 0.5


def test_polish_linearises_the_physics_informed_arx_exactly_by_probing_every_step():
    """The physics-informed ARX's horizon is affine in the plan but time-varying (its heat
    loss follows the schedule), so the LP polish's sensitivities equal the model's own gain
    matrix only when every step is probed, which the sampling planners do for it."""
    import torch

    from controllers.lp_polish import jacobians, probes
    from controllers.sampling import CEM
    from pinn_mpc.features import time_of_day_h
    from pinn_mpc.models.arx import fit_physics_informed_arx
    from scenarios.inputs.scenario_file import get_scenario

    data = _occupied_data(28, seed=0)
    model = fit_physics_informed_arx(data, lags=1)
    k, h = 40, 48
    time = pd.to_datetime(data["time"])
    history = {c: data[c].to_numpy()[: k + 1] for c in ("T_r", "T_a")}
    history["u_phys"] = data["u_phys"].to_numpy()[:k]
    exog = {
        "time_of_day_h": time_of_day_h(data["time"])[k : k + h],
        "day_of_week": time.dt.day_of_week.to_numpy(dtype=float)[k : k + h],
        "T_a": data["T_a"].to_numpy()[k : k + h],
    }
    _, gain = model.prediction_matrices(history, exog, h)
    u0 = torch.full((h,), 500.0, dtype=torch.float64)
    errors = {}
    for stride in (1, 4):
        batch, step = probes(u0, 10.0, 1000.0, stride)
        roll = model.rollout(history, batch, exog)
        jr = jacobians(roll.t_r_c[..., 0], roll.u_phys_w, step)[2][0]
        errors[stride] = np.max(np.abs(jr - gain))
    assert errors[1] < 1e-9 < 1e-5 < errors[4]
    spec = get_scenario("winter_household").control_spec()
    assert CEM(model, spec).polish.probe_stride == 1


def test_physics_informed_arx_round_trips_plans_as_it_predicts_and_refuses_cooling_heat(tmp_path):
    import torch

    from pinn_mpc.features import time_of_day_h
    from pinn_mpc.models.arx import fit_physics_informed_arx, load_arx, save_arx

    model = fit_physics_informed_arx(_occupied_data(21, seed=0), lags=2)
    save_arx(model, tmp_path)
    loaded = load_arx(tmp_path)
    assert loaded.day_types == 3 and loaded.interaction and np.array_equal(loaded.coef, model.coef)
    test = _occupied_data(4, seed=1)
    k, h = 100, 24  # a Thursday afternoon: the horizon crosses the evening's schedule change
    time = pd.to_datetime(test["time"])
    history = {"T_r": test["T_r"].to_numpy()[: k + 1], "u_phys": test["u_phys"].to_numpy()[:k],
               "T_a": test["T_a"].to_numpy()[: k + 1]}
    exog = {"time_of_day_h": time_of_day_h(test["time"])[k : k + h],
            "day_of_week": time.dt.day_of_week.to_numpy(dtype=float)[k : k + h],
            "T_a": test["T_a"].to_numpy()[k : k + h]}
    plan = torch.tensor(test["u_phys"].to_numpy()[k : k + h])[None]
    roll = loaded.rollout(history, plan, exog)
    for step in (1, 6, h):
        expected = loaded.predict_t_r(test, step, np.array([k]))[0]
        assert float(roll.t_r_c[0, 0, step - 1, 0]) == pytest.approx(expected, abs=1e-9)
    with pytest.raises(InputError, match="more power cools"):
        fit_physics_informed_arx(_occupied_data(21, seed=0, heater_gain=-0.002), lags=1)
    cooling = fit_physics_informed_arx(_occupied_data(21, seed=0, heater_gain=-0.002), lags=1, eta=-3.0)
    assert cooling.eta == -1.0
    with pytest.raises(InputError, match="more power warms"):
        fit_physics_informed_arx(_occupied_data(21, seed=0), lags=1, eta=-3.0)


def _windy_data(days: int, seed: int, wind_loss: float = 0.01) -> pd.DataFrame:
    """:func:`_occupied_data`'s room, whose heat loss also grows with the wind speed (as
    wind-driven infiltration): ``wind_loss`` more of ``T_r - T_a`` per interval per m/s."""
    df = _occupied_data(days, seed)
    rng = np.random.default_rng(seed + 100)
    wind = np.clip(3.0 + np.cumsum(rng.normal(0, 0.4, len(df))) * 0.3, 0.0, 12.0)
    time = pd.DatetimeIndex(df["time"])
    hour, dow = time.hour.to_numpy(), time.day_of_week.to_numpy()
    occupied = (hour >= 8) & (hour < 18) & ((dow < 5) | ((dow == 5) & (hour < 12)))
    loss = np.where(occupied, 0.12, 0.05) + wind_loss * wind
    gains = np.where(occupied, 0.6, 0.1) + np.where(dow == 5, 0.2, 0.0)
    t_r, t_a, u = df["T_r"].to_numpy().copy(), df["T_a"].to_numpy(), df["u_phys"].to_numpy()
    for k in range(len(df) - 1):
        t_r[k + 1] = t_r[k] - loss[k] * (t_r[k] - t_a[k]) + 0.002 * u[k] + gains[k]
    out = df.assign(T_r=t_r, wind=wind)
    out.attrs["dt_s"] = 1800.0
    return out


def test_physics_informed_arx_recovers_wind_driven_infiltration(tmp_path):
    """A room whose loss follows the wind as well as the occupancy: the physics-informed ARX
    weighs wind x (T_r - T_a) where the data has the wind, recovers its weight (scaled by 0.1
    per m/s) and predicts 48 steps ahead exactly; its horizon stays affine in the plan (the
    wind's weight from the forecast) and the file keeps the term."""
    from pinn_mpc.models.arx import fit_physics_informed_arx, load_arx, save_arx

    train, test = _windy_data(28, seed=0), _windy_data(14, seed=1)
    model = fit_physics_informed_arx(train, lags=1)
    assert model.wind and "wind" in model.exog_names
    assert model.coef[-1] * 0.1 == pytest.approx(-0.01, rel=1e-5)
    starts = np.arange(10, len(test) - 48)
    assert np.allclose(model.predict_t_r(test, 48, starts), test["T_r"].to_numpy()[starts + 48], atol=1e-6)
    without = fit_physics_informed_arx(train.drop(columns="wind"), lags=1)
    assert not without.wind
    assert np.abs(without.predict_t_r(test.drop(columns="wind"), 48, starts) - test["T_r"].to_numpy()[starts + 48]).mean() > 0.05
    k, h = 200, 24
    t = pd.DatetimeIndex(test["time"])
    history = {c: test[c].to_numpy()[: k + 1] for c in ("T_r", "T_a")}
    history["u_phys"] = test["u_phys"].to_numpy()[:k]
    exog = {
        "time_of_day_h": (t.hour + t.minute / 60).to_numpy()[k : k + h],
        "day_of_week": t.day_of_week.to_numpy()[k : k + h].astype(float),
        "T_a": test["T_a"].to_numpy()[k : k + h],
        "wind": test["wind"].to_numpy()[k : k + h],
    }
    free, gain = model.prediction_matrices(history, exog, h)
    plan = test["u_phys"].to_numpy()[k : k + h]
    recursion = [model.predict_t_r(test, j, np.array([k]))[0] for j in range(1, h + 1)]
    assert np.allclose(free + gain @ plan, recursion, atol=1e-6)
    with pytest.raises(InputError, match="wind"):
        model.prediction_matrices(history, {n: v for n, v in exog.items() if n != "wind"}, h)
    loaded = load_arx(save_arx(model, tmp_path / "m").parent)
    assert loaded.wind and np.array_equal(loaded.coef, model.coef)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        # a coefficient of the power edited to 1e6: it once evaluated at 2e7 C one step ahead
        (lambda coef, lags, n_col: coef.__setitem__(1, 1e6), r"a coefficient of 1e\+06"),
        # the latest room temperature's weight 1.5: a room that runs away, never settles
        (lambda coef, lags, n_col: coef.__setitem__(0, 1.5), "never settles"),
    ],
)
def test_a_tampered_arx_is_refused_on_load_in_one_line(tmp_path, capsys, edit, message):
    import json

    from pinn_mpc.data import write_timeseries
    from pinn_mpc.models.arx import load_arx, save_arx
    from pinn_mpc_cli.cli import main

    model = fit_arx(_rc_data(14, seed=0))
    assert 0.0 < model.settling_radius() < 1.0
    assert model.offset_response(7 * 48) < 1.0
    save_arx(model, tmp_path / "arx")
    stored = json.loads((tmp_path / "arx" / "arx.json").read_text())
    edit(stored["coef"], model.lags, len(model.columns))
    (tmp_path / "arx" / "arx.json").write_text(json.dumps(stored))
    with pytest.raises(InputError, match=message) as caught:
        load_arx(tmp_path / "arx")
    assert str(caught.value).endswith("it was edited or damaged; train it again (arch arx)")
    test = tmp_path / "t.csv"
    write_timeseries(_rc_data(3, seed=1), test)
    assert main(["evaluate", "--model", str(tmp_path / "arx"), "--data", str(test),
                 "--json", str(tmp_path / "m.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a plausible ARX model" in err
    assert err.endswith("train it again (train --arch arx)")  # evaluate names train's flag
    assert not (tmp_path / "m.json").exists()


def test_an_arx_refuses_data_at_another_interval(tmp_path, capsys):
    """As a hybrid is: an ARX trained at 30 minutes steps 30 minutes, not 15."""
    from pinn_mpc.data import write_timeseries
    from pinn_mpc.models.arx import save_arx
    from pinn_mpc_cli.cli import main

    save_arx(fit_arx(_rc_data(14, seed=0)), tmp_path / "arx")
    quarter = _rc_data(3, seed=1)
    quarter["time"] = pd.date_range("2022-01-03", periods=len(quarter), freq="15min")
    quarter.attrs["dt_s"] = 900.0
    test = tmp_path / "q.csv"
    write_timeseries(quarter, test)
    assert main(["evaluate", "--model", str(tmp_path / "arx"), "--data", str(test),
                 "--json", str(tmp_path / "m.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert "trained at 1800 s (30 min) intervals but the data has 900 s (15 min)" in err, err
    assert len(err.splitlines()) == 1 and not (tmp_path / "m.json").exists()


def test_a_fit_whose_room_never_settles_is_refused_when_fitted_not_when_loaded(tmp_path):
    """On heat_pump_household's 14 days of seed 2 no schedule of the physics-informed ARX
    settles (a history 1 K warmer is 1.11 K warmer a week later). ``train`` wrote that model
    and every later load refused it as "edited or damaged"; the fit now says so of the data,
    and ``train --arch auto`` on the same data writes a model that loads."""
    from pinn_mpc.fitted import load, save
    from pinn_mpc.model_choice import choose_model
    from pinn_mpc.models.arx import (
        RUNAWAY_OFFSET_K,
        fit_linear,
        fit_physics_informed_arx,
        week_offset_k,
    )
    from pinn_mpc.training import TrainConfig
    from scenarios.inputs.scenario_file import get_scenario
    from scenarios.running.datagen import generate

    scenario = get_scenario("heat_pump_household")
    eta = scenario.sim.params.eta
    df = generate(scenario, days=14, seed=2, policy=scenario.data_policy)
    assert week_offset_k(fit_physics_informed_arx(df, eta=eta)) > RUNAWAY_OFFSET_K
    with pytest.raises(InputError, match="no fit on these data lets the room settle"):
        fit_linear("parx", df, eta=eta)
    choice = choose_model(df, TrainConfig(n_seeds=1, epochs=2, eta=eta))
    save(choice.model, tmp_path / "model")
    load(tmp_path / "model")  # loads: what auto writes is never refused as damaged


def test_physics_informed_arx_on_too_few_rows_for_its_lags_fits_fewer():
    """Three days hold too few rows for any schedule with 8 lags (an online run's first nights):
    the fit halves them to 4, the model a direct fit with 4 lags gives, and on the room of one
    lag it predicts its days 24 steps ahead exactly; a week fits 8 lags as it did before the
    fallback, and two days, too few for 2 lags, are still refused."""
    from pinn_mpc.models.arx import (
        DEFAULT_LAGS,
        TooFewRowsError,
        _physics_informed_fit,
        fit_physics_informed_arx,
    )

    short = _occupied_data(3, seed=0)
    with pytest.raises(TooFewRowsError):
        _physics_informed_fit(short, lags=DEFAULT_LAGS, eta=1.0)
    model = fit_physics_informed_arx(short)
    assert model.lags == 4
    np.testing.assert_array_equal(model.coef, fit_physics_informed_arx(short, lags=4).coef)
    starts = np.arange(model.lags, len(short) - 24)
    truth = short["T_r"].to_numpy()
    assert np.max(np.abs(model.predict_t_r(short, 24, starts) - truth[starts + 24])) < 1e-3
    week = _occupied_data(7, seed=0)
    model = fit_physics_informed_arx(week)
    assert model.lags == DEFAULT_LAGS
    np.testing.assert_array_equal(model.coef, _physics_informed_fit(week, lags=DEFAULT_LAGS, eta=1.0).coef)
    with pytest.raises(TooFewRowsError, match="too few"):
        fit_physics_informed_arx(_occupied_data(2, seed=0))
