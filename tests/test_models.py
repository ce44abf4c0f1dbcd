"""Networks, physics block and residuals, rollout: against analytic truth and each other."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from pinn_mpc import physics
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InternalError
from pinn_mpc.features import time_of_day_h
from pinn_mpc.models import (
    EnsembleLinear,
    HybridNet,
    LearnedModel,
    Physics,
    discretise_torch,
    residual_exact,
    residual_finite_difference,
)
from pinn_mpc.training import TrainConfig, train_model
from tests.model_data import ensemble_layers, household_data, net_of


@pytest.fixture(scope="module", params=["mlp", "physreg", "physnet"])
def small_model(request: pytest.FixtureRequest) -> LearnedModel:
    config = TrainConfig(n_seeds=3, epochs=2, depth=4)
    return train_model(household_data(4, 0), arch=request.param, config=config, progress=False)


def _tensor_coefficients(p: physics.RCParams) -> physics.Coefficients:
    c = physics.to_coefficients(p)
    return physics.Coefficients(
        **{k: torch.tensor([v], dtype=torch.float64) for k, v in c.to_dict().items()}
    )


def test_ensemble_linear_members_are_independent_affine_maps() -> None:
    gens = [torch.Generator().manual_seed(s) for s in (0, 1, 2)]
    layer = EnsembleLinear(3, 5, 4, gens)
    x = torch.randn(3, 7, 5)
    y = layer(x)
    for m in range(3):
        torch.testing.assert_close(y[m], x[m] @ layer.weight[m] + layer.bias[m])
    again = EnsembleLinear(1, 5, 4, [torch.Generator().manual_seed(1)])
    torch.testing.assert_close(again.weight[0], layer.weight[1])


def test_physics_block_starts_at_the_prior_and_keeps_the_structure() -> None:
    prior = physics.PAPER_HOUSEHOLD
    block = Physics(prior, n_members=4, exog_names=("time_of_day_h", "T_a"))
    coef = block.coefficients()
    truth = physics.to_coefficients(prior)
    for name in ("a11", "a12", "a21", "a22", "b", "c13"):
        np.testing.assert_allclose(
            getattr(coef, name).detach().numpy(), getattr(truth, name), rtol=1e-6
        )
    with torch.no_grad():
        block.log_a12.add_(0.3)
    coef = block.coefficients()
    torch.testing.assert_close(coef.a11, coef.a12 + coef.c13)
    torch.testing.assert_close(coef.a22, coef.a21)
    cooling = Physics(
        dataclasses.replace(prior, eta=-3.0), n_members=2, exog_names=("time_of_day_h", "T_a")
    )
    assert torch.all(cooling.coefficients().b < 0)


def test_torch_discretisation_equals_the_scipy_one() -> None:
    params = dataclasses.replace(
        physics.PAPER_HOUSEHOLD,
        solar_aperture_m2=3.0,
        solar_to_air_fraction=0.4,
        gain_to_air_fraction=0.7,
    )
    ad, bd = discretise_torch(_tensor_coefficients(params), 1800.0)
    ad_ref, bd_ref = physics.discretise(params, 1800.0)
    np.testing.assert_allclose(ad[0].numpy(), ad_ref, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(bd[0].numpy(), bd_ref, rtol=1e-10, atol=1e-14)


def test_exact_residual_vanishes_on_true_states_where_power_was_held() -> None:
    df = household_data(3, 2)
    held = np.abs(df["u"].to_numpy() - df["u_phys"].to_numpy()) <= 1.0
    t_r = torch.tensor(df["T_r"].to_numpy())[None, None]
    t_m = torch.tensor(df["T_m"].to_numpy())[None, None]
    zeros = np.zeros(len(df))
    d = torch.tensor(np.stack([df["u_phys"], df["T_a"], zeros, zeros], axis=1))[None, None]
    coef = _tensor_coefficients(physics.PAPER_HOUSEHOLD)
    r_room, r_mass = residual_exact(coef, 1800.0, t_r=t_r, d=d[:, :, :-1], t_m_hat=t_m[..., :-1])
    assert held[:-1].sum() > 20
    assert np.max(np.abs(r_room[0, 0].numpy()[held[:-1]])) < 1e-6
    assert np.max(np.abs(r_mass[0, 0].numpy()[held[:-2]])) < 1e-6
    # A wrong C_m breaks the T_m row even though the T_r row does not involve it.
    wrong = _tensor_coefficients(dataclasses.replace(physics.PAPER_HOUSEHOLD, c_m_j_per_k=3.0e7))
    _, r_mass_wrong = residual_exact(wrong, 1800.0, t_r=t_r, d=d[:, :, :-1], t_m_hat=t_m[..., :-1])
    assert np.mean(np.abs(r_mass_wrong[0, 0].numpy()[held[:-2]])) > 1e-3


def test_finite_difference_residual_is_the_papers_formula() -> None:
    c = physics.to_coefficients(physics.PAPER_HOUSEHOLD)
    coef = _tensor_coefficients(physics.PAPER_HOUSEHOLD)
    t_r = torch.tensor([[[19.0, 19.5, 19.8]]], dtype=torch.float64)
    t_r_hat = torch.tensor([[[19.4, 19.9]]], dtype=torch.float64)
    u_hat = torch.tensor([[[0.0, 5000.0]]], dtype=torch.float64)
    exog = torch.tensor([[[[10.0, 0, 0], [11.0, 0, 0]]]], dtype=torch.float64)
    t_m_hat = torch.tensor([[[18.0, 18.5]]], dtype=torch.float64)
    res = residual_finite_difference(
        coef, 1800.0, t_r=t_r, t_r_hat=t_r_hat, u_phys_hat=u_hat, exog=exog, t_m_hat=t_m_hat
    )
    t_dot = (19.8 - 19.5) / 1800.0
    expected = 18.5 - (t_dot + c.a11 * 19.4 - c.b * 5000.0 - c.c13 * 11.0) / c.a12
    assert res.shape == (1, 1, 1)
    assert float(res[0, 0, 0]) == pytest.approx(expected, rel=1e-12)


def _history(df, i: int, k: int) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], int]:
    hist = {
        "T_r": df["T_r"].to_numpy()[: i + 1],
        "u_phys": df["u_phys"].to_numpy()[:i],
        "T_a": df["T_a"].to_numpy()[: i + 1],
        "time_of_day_h": time_of_day_h(df["time"])[: i + 1],
    }
    h = len(df) - i - 1
    exog = {
        "T_a": df["T_a"].to_numpy()[i : i + h],
        "time_of_day_h": time_of_day_h(df["time"])[i : i + h],
    }
    return hist, exog, h


def test_rollout_feeds_predictions_back_like_a_step_by_step_loop(small_model: LearnedModel) -> None:
    model = small_model
    df = household_data(4, 5).iloc[:32].reset_index(drop=True)
    df.attrs["dt_s"] = 1800.0
    i = 20
    hist, exog, h = _history(df, i, model.depth)
    u = torch.tensor(df["u"].to_numpy()[i : i + h], dtype=torch.float32)[None].repeat(2, 1)
    roll = model.rollout(hist, u, exog)
    m = model.n_members
    assert roll.t_r_c.shape == (m, 2, h, 1) and roll.u_phys_w.shape == (m, 2, h)
    assert (roll.t_m_c is None) == (model.arch == "mlp")
    # Step by step: write each member's prediction into the frame and predict one step.
    for member in range(m):
        frame = df.copy()
        for j in range(h):
            one = model.predict_one_step(frame.iloc[: i + j + 2])
            row = list(one["row"]).index(i + j)
            assert one["T_r_next"][member, row] == pytest.approx(
                float(roll.t_r_c[member, 0, j, 0]), abs=2e-4
            )
            assert one["u_phys"][member, row] == pytest.approx(
                float(roll.u_phys_w[member, 0, j]), abs=0.5
            )
            frame.loc[i + j + 1, "T_r"] = one["T_r_next"][member, row]
            frame.loc[i + j, "u_phys"] = one["u_phys"][member, row]
    # The same plan twice gives the same rollout.
    torch.testing.assert_close(roll.t_r_c[:, 0], roll.t_r_c[:, 1])


def test_every_planner_model_declares_the_rollout_protocol(small_model: LearnedModel) -> None:
    """The learned ensemble, the 2R2C and the ARX subclass BatchDynamics (the type checker holds
    them to it) and say whether their horizon is affine in the plan; the one that is offers
    its prediction matrices, and they give its rollout."""
    from pinn_mpc.models.arx import fit_arx
    from pinn_mpc.models.rc import RCBatchModel
    from pinn_mpc.models.rollout import BatchDynamics

    df = household_data(4, 5)
    arx = fit_arx(df)
    rc = RCBatchModel(physics.PAPER_HOUSEHOLD, dt_s=1800.0, actuator=ActuatorSpec(upper_w=5000.0))
    for model, affine in ((small_model, False), (rc, False), (arx, True)):
        assert BatchDynamics in type(model).__mro__  # declared, not only shaped like it
        assert model.affine_in_plan is affine
        assert model.dt_s == 1800.0 and model.n_members >= 1
    i, h = 20, 12
    hist = {c: df[c].to_numpy()[: i + 1] for c in arx.columns if c != "u_phys"}
    hist["u_phys"] = df["u_phys"].to_numpy()[:i]
    exog = {c: df[c].to_numpy()[i : i + h] for c in arx.columns[2:]}
    exog |= {"time_of_day_h": time_of_day_h(df["time"])[i : i + h], "day_of_week": np.zeros(h)}
    u = torch.rand(3, h, generator=torch.Generator().manual_seed(0), dtype=torch.float64) * 5000.0
    free, gain = arx.prediction_matrices(hist, exog, h)
    torch.testing.assert_close(arx.rollout(hist, u, exog).t_r_c[0, ..., 0], torch.as_tensor(free) + u @ torch.as_tensor(gain).T)


def test_rollout_rejects_short_history(small_model: LearnedModel) -> None:
    df = household_data(4, 5)
    hist, exog, _ = _history(df.iloc[:30], 3, small_model.depth)
    with pytest.raises(InternalError, match="depth\\+1=5"):
        small_model.rollout(hist, torch.zeros(1, 4), exog)


def test_one_step_predictions_have_member_axis(small_model: LearnedModel) -> None:
    df = household_data(4, 5)
    out = small_model.predict_one_step(df)
    n = len(df) - small_model.depth - 2
    assert out["T_r_next"].shape == out["u_phys"].shape == (3, n)
    assert np.all(np.isfinite(out["T_r_next"]))
    lo, hi = small_model.meta["u_phys_range_w"]
    assert out["u_phys"].min() >= lo - 1e-3 and out["u_phys"].max() <= hi + 1e-3
    coef = small_model.physics_coefficients()
    assert (coef is None) == (small_model.arch == "mlp")


def _winter_data(days: int, seed: int, *, heating: bool = True):
    """The true 2R2C and ``days`` of random-level data of winter_household (of cold_storage,
    a cooling machine's, with ``heating`` False)."""
    from pinn_mpc.data import validate_timeseries
    from scenarios.inputs.scenario_file import get_scenario
    from scenarios.running.datagen import generate

    scenario = get_scenario("winter_household" if heating else "cold_storage")
    frame = generate(scenario, days=days, seed=seed, policy="random-level")
    return scenario.sim.params, validate_timeseries(frame)


def _history_and_forecast(df, i: int, h: int):
    tod = time_of_day_h(df["time"])
    history = {c: df[c].to_numpy()[: i + 1] for c in ("T_r", "T_a", "G", "I_g")}
    history["u_phys"] = df["u_phys"].to_numpy()[:i]
    history["time_of_day_h"] = tod[: i + 1]
    exog = {c: df[c].to_numpy()[i : i + h] for c in ("T_a", "G", "I_g")}
    exog["time_of_day_h"] = tod[i : i + h]
    return history, exog


def test_hybrid_without_corrections_is_the_exact_2r2c() -> None:
    """True parameters, no residual, backup far away: the window observer recovers T_m and the
    rollout is the ZOH 2R2C (RCBatchModel started at the true T_m) up to that T_m error; so is
    the model's rollout as a fleet of one building."""
    from pinn_mpc.models.fleet import FleetModels
    from pinn_mpc.models.rc import RCBatchModel

    truth, df = _winter_data(8, 0)
    model = train_model(
        df,
        arch="hybrid",
        config=TrainConfig(n_seeds=2, epochs=1, depth=16, prior=truth),
        progress=False,
    )
    net, block = net_of(model, HybridNet), model.module.physics
    assert block is not None
    with torch.no_grad():
        ensemble_layers(net.residual_net)[-1].weight.zero_()
        ensemble_layers(net.residual_net)[-1].bias.zero_()
        net.init_backup(-100.0, 100.0, 5000.0)
        for p, p0 in zip(block.parameters(), Physics(
            truth, n_members=2, exog_names=model.exog_names
        ).parameters(), strict=True):
            p.copy_(p0)
    held = np.abs(df["u"].to_numpy() - df["u_phys"].to_numpy()) < 1.0
    i = next(j for j in range(40, len(df) - 30) if held[j - 17 : j + 24].all())
    history, exog = _history_and_forecast(df, i, 24)
    u = 500.0 + torch.rand(4, 24, generator=torch.Generator().manual_seed(0)) * 3500.0
    roll = model.rollout(history, u, exog)
    rc = RCBatchModel(truth, dt_s=1800.0, actuator=ActuatorSpec(upper_w=5000.0, heats=truth.heating), backup_low_c=-99, backup_high_c=99)
    ref = rc.rollout({**history, "T_m": df["T_m"].to_numpy()[: i + 1]}, u, exog)
    assert roll.t_m_c is not None
    t_m_error = float((roll.t_m_c[:, :, 0, 0] - df["T_m"].to_numpy()[i]).abs().max())
    assert t_m_error < 0.01
    torch.testing.assert_close(roll.u_phys_w, ref.u_phys_w.expand(2, -1, -1), atol=0.5, rtol=0)
    assert float((roll.t_r_c - ref.t_r_c).abs().max()) <= t_m_error + 1e-3
    # The one-building fleet is the same 2R2C through the same recursion.
    fleet = FleetModels([model]).rollout([history], u[None], exog)
    for got, want in zip(fleet, roll, strict=True):
        assert got is not None
        torch.testing.assert_close(got[0], want, atol=1e-4, rtol=1e-6)


@pytest.mark.parametrize("heating", [True, False])
def test_hybrid_backup_thermostat_saturates_at_the_power_that_ends_at_its_threshold(
    heating: bool,
) -> None:
    """Analytic cases: T_end(p) = t_free + b p; the backup delivers the demand clipped to the
    powers that end the interval at its "off" and "full" thresholds, and [0, full power]."""
    prior, df = _winter_data(4, 0, heating=heating)
    model = train_model(
        df, arch="hybrid", config=TrainConfig(n_seeds=1, epochs=1, depth=4, prior=prior, eta=prior.eta), progress=False
    )
    net = model.module.net
    assert isinstance(net, HybridNet)
    net.init_backup(16.0, 24.0, 5000.0)
    u = torch.tensor([[0.0, 1000.0, 4000.0]])
    b_w = torch.tensor(1e-3 if heating else -1e-3)  # K per W

    def delivered(t_free_c: float) -> torch.Tensor:
        with torch.no_grad():
            return net.delivered_w(u, torch.full_like(u, t_free_c), b_w)

    # Heating: off at 24 C, full below 16 C. Cooling: full above 24 C, off below 16 C.
    # The "off" power ends at the off threshold, the "full" power at the full threshold.
    off_c, full_c = (24.0, 16.0) if heating else (16.0, 24.0)
    torch.testing.assert_close(delivered(20.0), u.clamp(max=(off_c - 20.0) / float(b_w)))
    far = 18.0 if heating else 22.0
    torch.testing.assert_close(delivered(far), u)  # limits out of reach: the demand itself
    hot_side = off_c + (4.0 if heating else -4.0)
    torch.testing.assert_close(delivered(hot_side), torch.zeros_like(u))
    cold_side = full_c - (5.0 if heating else -5.0)
    torch.testing.assert_close(delivered(cold_side), torch.full_like(u, 5000.0))
    near = full_c - (2.0 if heating else -2.0)  # needs 2000 W to reach it
    need = abs(2.0 / float(b_w))
    torch.testing.assert_close(delivered(near), u.clamp(min=need))


def test_hybrid_delivered_power_never_falls_as_demand_rises() -> None:
    """Over a grid of room states (the history shifted by -8 .. +8 K, across both backup
    thresholds) and demands, for every member: the delivered power of the first step rises
    (weakly) with the demand, and so does T_r at every step of a 12-step plan (to 2 mK: the
    residual net sees the state)."""
    _, df = _winter_data(10, 1)
    model = train_model(df, arch="hybrid", config=TrainConfig(n_seeds=3, epochs=3, depth=8), progress=False)
    history, exog = _history_and_forecast(df, 200, 12)
    plans = torch.linspace(0.0, 5000.0, 21)[:, None].expand(21, 12)
    for shift in np.linspace(-8.0, 8.0, 9):
        shifted = {**history, "T_r": np.asarray(history["T_r"]) + shift}
        out = model.rollout(shifted, plans, exog)  # (M, 21, H)
        assert bool((out.u_phys_w[:, 1:, 0] >= out.u_phys_w[:, :-1, 0] - 1e-3).all()), shift
        assert bool((out.t_r_c[:, 1:] >= out.t_r_c[:, :-1] - 2e-3).all()), shift


def test_hybrid_heats_with_the_sign_of_eta() -> None:
    """More demand never cools a heated room (d u_phys / d u >= 0, the residual does not see
    u), in the next interval and over 12."""
    _, df = _winter_data(10, 1)
    config = TrainConfig(n_seeds=3, epochs=3, depth=8)
    model = train_model(df, arch="hybrid", config=config, progress=False)
    history, exog = _history_and_forecast(df, 200, 12)
    plans = torch.linspace(0.0, 5000.0, 11)[:, None].expand(11, 12)
    first = model.rollout(history, plans[:, :1], exog).t_r_c[..., 0, 0]  # (M, 11)
    assert bool((first[:, 1:] > first[:, :-1]).all())
    t_r = model.rollout(history, plans, exog).t_r_c[..., 0]  # (M, 11, H)
    assert bool((t_r[:, 1:] >= t_r[:, :-1]).all())


def _reference_hybrid_rollout(
    net: HybridNet,
    windows: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
    u_s: torch.Tensor,
    tod: torch.Tensor,
    p_bounds: tuple[float, float],
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The hybrid's rollout written plainly (the implementation before it was made fast): per
    horizon step the "now" features are rebuilt and the net's one-step ``_step`` (the one its
    ``forward`` uses) predicts; T_m follows the 2R2C. Raw (T_r, u_phys, T_m), each (M, N, H)."""
    t_win, p_win, e_seq = windows
    f = net.features
    m, k = net.n_members, f.depth
    n, h_len = u_s.shape
    ad, bd = net._matrices()
    t, pw = f.temperature, f.power
    t_r = (t_win * t.std + t.mean).expand(m, -1, -1)
    p_past = (p_win * pw.std + pw.mean).expand(m, -1, -1)
    scales = [f.exog[name] for name in f.exog_series]
    e_raw = torch.stack([e_seq[:, j] * sc.std + sc.mean for j, sc in enumerate(scales)])
    exog = net._exog_raw(e_raw).expand(m, -1, -1, -1)
    d_win = net._inputs(p_past[..., 1:], exog[..., :k, :])
    t_m = net.observe_linear(ad, bd, torch.cat([t_r, d_win.flatten(-2)], dim=-1)).expand(m, n)
    t_now = t_r[..., k].expand(m, n)
    p_now = p_win[:, k].expand(m, n)
    e_seq, tod = e_seq.expand(n, -1, -1), tod.expand(n, -1, -1)
    out = torch.empty(3, m, n, h_len)
    with torch.no_grad():
        for h in range(h_len):
            z = (t_m - t.mean) / t.std
            static = torch.cat([e_seq[:, :, k + h], u_s[:, h, None], tod[:, h]], dim=-1)
            t_s = ((t_now - t.mean) / t.std)[..., None]
            now = torch.cat([t_s, p_now[..., None], static.expand(m, n, -1)], dim=-1)
            exog_now = exog[..., k + h, :].expand(m, n, -1)
            obs, _ = net._step(ad, bd, t_now, t_m, z, now, exog_now=exog_now, p_bounds=p_bounds)
            d = net._inputs(obs[..., 1] * pw.std + pw.mean, exog_now)
            out[2, ..., h] = t_m
            t_m = ad[:, None, 1, 0] * t_now + ad[:, None, 1, 1] * t_m + (d * bd[:, None, 1]).sum(-1)
            t_now = t_now + (obs[..., 0] * f.delta_t_r.std + f.delta_t_r.mean)
            p_now = obs[..., 1]
            out[0, ..., h] = t_now
            out[1, ..., h] = p_now * pw.std + pw.mean
    return out[0], out[1], out[2]


def _scaled_windows(model: LearnedModel, df, starts: np.ndarray, h: int):
    """Scaled (t_win, p_win, e_seq, u_s, tod) of :meth:`LearnedModel.rollout_scaled` for the
    measured data from each start row, N0 = N = len(starts)."""
    f, k = model.features, model.depth
    back, ahead = np.arange(-k, 1), np.arange(h)
    t_r = (df["T_r"].to_numpy() - f.temperature.mean) / f.temperature.std
    p = (df["u_phys"].to_numpy() - f.power.mean) / f.power.std
    u = (df["u"].to_numpy() - f.power.mean) / f.power.std
    exog = f.scale_exog({n: df[n].to_numpy() for n in f.exog_series})
    tod = f.encode_time(time_of_day_h(df["time"]))
    e_seq = exog[:, starts[:, None] + np.arange(-k, h)].transpose(1, 0, 2)
    as_t = lambda a: torch.from_numpy(np.ascontiguousarray(a, dtype=np.float32))  # noqa: E731
    return (
        as_t(t_r[starts[:, None] + back]),
        as_t(p[starts[:, None] + back - 1]),
        as_t(e_seq),
        as_t(u[starts[:, None] + ahead]),
        as_t(tod[starts[:, None] + ahead]),
    )


@pytest.mark.parametrize("heating", [True, False])
def test_hybrid_rollout_equals_stepping_the_one_step_model(heating: bool) -> None:
    """The fast rollout against the plain one (the net's one-step ``_step`` per horizon step):
    the same predictions up to float32 round-off, for one start and N plans (N0 = 1) and N
    starts (N0 = N), with a residual and a backup thermostat that both act; and again after
    the weights change in place (the rollout's cached constants must follow)."""
    prior, df = _winter_data(3, 2, heating=heating)
    config = TrainConfig(n_seeds=3, epochs=1, depth=6, prior=prior, eta=prior.eta)
    model = train_model(df, arch="hybrid", config=config, progress=False)
    net = model.module.net
    assert isinstance(net, HybridNet) and net.heating == heating
    gen = torch.Generator().manual_seed(0)
    t_mid = float(np.median(df["T_r"]))
    with torch.no_grad():
        for layer in ensemble_layers(net.residual_net):  # a residual of a few 0.1 K
            layer.weight.normal_(0.0, 0.3, generator=gen)
            layer.bias.normal_(0.0, 0.3, generator=gen)
        net.init_backup(t_mid - 0.5, t_mid + 0.5, 5000.0)
    h, bounds = 24, (model.scaling.p_lo, model.scaling.p_hi)
    starts = np.arange(40, len(df) - h, 7)
    t_win, p_win, e_seq, u_s, tod = _scaled_windows(model, df, starts, h)
    plans = (u_s[:1] + torch.randn(5, h, generator=gen)).clamp(-3.0, 3.0)
    cases = {
        "N0=N": ((t_win, p_win, e_seq), u_s, tod),
        "N0=1": ((t_win[:1], p_win[:1], e_seq[:1]), plans, tod[:1]),
        "N0=1, N=1": ((t_win[:1], p_win[:1], e_seq[:1]), plans[:1], tod[:1]),
    }

    def check() -> list[torch.Tensor]:
        outs = []
        for name, (windows, u, tods) in cases.items():
            ref = _reference_hybrid_rollout(net, windows, u, tods, bounds)
            roll = model.rollout_scaled(*windows, u, tods)
            assert roll.t_m_c is not None
            for a, b, tol in zip(ref, (roll.t_r_c[..., 0], roll.u_phys_w, roll.t_m_c[..., 0]), (1e-4, 0.5, 1e-4), strict=True):
                assert b.shape == (3, u.shape[0], h), name
                assert float((a - b).abs().max()) < tol, name
            outs.append(roll.t_r_c)
        return outs

    first = check()
    # The thermostat overrode the demand somewhere, and the residual moved T_r.
    ref_p = _reference_hybrid_rollout(net, *cases["N0=N"], bounds)[1]
    demand = (u_s * model.features.power.std + model.features.power.mean).clamp(*model.meta["u_phys_range_w"])
    assert float((ref_p - demand).abs().max()) > 1000.0
    block = model.module.physics
    assert block is not None
    with torch.no_grad():
        block.log_a12.add_(0.2)
        net.backup_low_c.sub_(0.3)
        ensemble_layers(net.residual_net)[0].weight.mul_(1.5)
    second = check()
    assert all(float((a - b).abs().max()) > 0.05 for a, b in zip(first, second, strict=True))
    with torch.no_grad():  # without the residual
        ensemble_layers(net.residual_net)[-1].weight.zero_()
        ensemble_layers(net.residual_net)[-1].bias.zero_()
    third = check()
    assert all(float((a - b).abs().max()) > 0.05 for a, b in zip(second, third, strict=True))


def test_hybrid_residual_is_bounded_by_what_it_added_on_its_training_data() -> None:
    """Far outside the training weather (T_a +40 K, sun x3) the residual net adds at most its
    bound to each step's T_r, and the bound is 1.5 x its largest training increment."""
    _, df = _winter_data(10, 1)
    model = train_model(df, arch="hybrid", config=TrainConfig(n_seeds=2, epochs=3, depth=8), progress=False)
    net = model.module.net
    assert isinstance(net, HybridNet)
    bound = net.residual_bound_k
    assert bool((bound > 1e-3).all()) and bool((bound < 1.0).all())
    history, exog = _history_and_forecast(df, 200, 12)
    hot = {**exog, "T_a": np.asarray(exog["T_a"]) + 40.0}
    if "G" in hot:
        hot["G"] = np.asarray(hot["G"]) * 3.0
    plans = torch.full((3, 12), 1000.0)
    with_res = model.rollout(history, plans, hot).t_r_c[..., 0]
    with torch.no_grad():
        for p in net.residual_net[-1].parameters():
            p.zero_()
    model._constants = None
    bare = model.rollout(history, plans, hot).t_r_c[..., 0]
    # The residual's effect accumulates through the 2R2C, at most the bound per step.
    steps = torch.arange(1, 13, dtype=torch.float32)
    assert bool(((with_res - bare).abs() <= bound[:, None, :] * steps + 1e-4).all())
