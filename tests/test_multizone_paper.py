"""The paper's PhysNet and PhysReg per zone of a building of several zones
(:mod:`pinn_mpc.models.multizone_paper`): the walls' coupling is the heat a wall of the
learned conductance conducts, the conductances stay symmetric and positive, the learned 2R2C's
zero-order hold is the building's, a zone without walls is moved by its own heat only, the file
round-trips exactly and a tampered one is refused, and trained on a week of the two-zone house
the networks predict the next day."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.errors import InputError
from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
from pinn_mpc.models.layers import EnsembleLinear
from pinn_mpc.models.multizone_paper import (
    MULTIZONE_PAPER_FILE,
    MultiZonePaperModel,
    PaperZoneTraining,
    ZonePhysics,
    fit_multizone_paper,
    load_multizone_paper,
    save_multizone_paper,
    zone_residuals,
)
from pinn_mpc.multizone import MultiZoneParams, discretise
from tests.multizone_data import (
    DT_S,
    cem_plans_the_house_for_a_day,
    multizone_frame,
    row_of_zones,
    two_zone_house,
)

_QUICK = PaperZoneTraining(epochs=1, horizon=4, batch=32, depth=2)
#: The mean |error| [K] the networks trained on a week stay under, 12 h ahead on the next day
#: (measured 1.10 physnet, 0.57 physreg, 0.008 the identified RC: a margin of a third).
BOUND_C = 1.5


def _named(actuators: tuple[ActuatorSpec, ...]) -> tuple[ActuatorSpec, ...]:
    return tuple(dataclasses.replace(a, name=f"a{i}") for i, a in enumerate(actuators))


def _dated(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.assign(time=pd.Timestamp("2023-01-02") + pd.to_timedelta(frame["time"], unit="s"))


def _known(params: MultiZoneParams) -> MultiZoneIdentifyResult:
    """The true building as an identification's result (the physics' start)."""
    n = params.n_zones
    return MultiZoneIdentifyResult(
        params=params, rmse_c=(0.0,) * n, t_m0_c=(20.0,) * n, n_rows=0, identified_solar=(True,) * n,
        identified_gain_shares=True, cost_evaluations=0,
    )


def _house_frame(
    days: int, wall_w_per_k: float = 60.0, noise_std_c: float = 0.05
) -> tuple[pd.DataFrame, MultiZoneParams, tuple[ActuatorSpec, ...]]:
    params, actuators = two_zone_house(wall_w_per_k)
    actuators = _named(actuators)
    frame = multizone_frame(params, actuators, days=days, seed=0, noise_std_c=noise_std_c)
    return _dated(frame), params, actuators


def _history(frame: pd.DataFrame, rows: int, powers: list[str]) -> dict[str, np.ndarray]:
    part = frame.iloc[:rows]
    history = {c: part[c].to_numpy(dtype=float) for c in part.columns if c != "time" and not c.startswith("T_m")}
    for c in powers:
        history[c] = history[c][:-1]
    return history


def _forecast(frame: pd.DataFrame, start: int, h: int) -> dict[str, np.ndarray]:
    part = frame.iloc[start : start + h]
    out = {c: part[c].to_numpy(dtype=float) for c in ("T_a", "G", "I_g", "G_south")}
    times = pd.to_datetime(part["time"])
    out["time_of_day_h"] = (times.dt.hour + times.dt.minute / 60.0).to_numpy(dtype=float)
    out["day_of_week"] = times.dt.day_of_week.to_numpy(dtype=float)
    return out


def test_the_walls_move_each_room_by_the_heat_a_wall_conducts() -> None:
    """With the networks' last layer zeroed and its bias set (the increment a known constant
    c, the same for every window), a step of three zones in a row at 18, 21 and 25 C gives each
    room c + dt sum_j U_zj (T_j - T_z) / C_r,z: the walls' conductances and each zone's air
    capacity as the building declares them."""
    from pinn_mpc.models.multizone_paper import ZoneNets, ZoneScaling, _Stepper

    params, _ = row_of_zones(3, seed=2)
    physics = ZonePhysics(params, [(0, 1), (1, 2)])
    nets = ZoneNets("physreg", 3, 2, seed=0).double()
    last = nets.trunk[-1]
    assert isinstance(last, EnsembleLinear)
    with torch.no_grad():
        last.weight.zero_()
        last.bias.zero_()
        last.bias[:, 0, 0] = 0.5  # the scaled increment
    scaling = ZoneScaling(
        t_mean_c=20.0, t_std_k=2.0, delta_std_k=0.2, heat_scale_w=(1000.0,) * 3, solar_scale=100.0, gains_scale_w=100.0
    )
    step = _Stepper(nets, physics, scaling, DT_S)
    rooms_c = np.array([18.0, 21.0, 25.0])
    window = torch.as_tensor((rooms_c - 20.0) / 2.0).expand(1, 3, 3)
    nxt, _ = step(window, torch.zeros(1, 3, 3), torch.zeros(1, 3, 3, 3), torch.zeros(1, 3))
    u = params.walls
    c_r = np.array([z.rc.c_r_j_per_k for z in params.zones])
    flow_w = np.array([u[0, 1] * (21 - 18), u[0, 1] * (18 - 21) + u[1, 2] * (25 - 21), u[1, 2] * (21 - 25)])
    expected = rooms_c + 0.5 * 0.2 + flow_w * DT_S / c_r
    np.testing.assert_allclose(nxt[0].detach().numpy() * 2.0 + 20.0, expected, rtol=0, atol=1e-12)


def test_conductances_are_symmetric_positive_and_only_on_walls() -> None:
    """Whatever the raw parameters (large of either sign), every conductance is >= 0, K = K^T,
    the diagonal 0, and a pair without a wall in the layout 0."""
    params, _ = row_of_zones(4, seed=1)
    physics = ZonePhysics(params, [(0, 1), (1, 2), (2, 3)])
    for raw in (torch.tensor([-50.0, 0.0, 50.0]), torch.tensor([1e3, -1e3, 3.0])):
        with torch.no_grad():
            physics.raw_k.copy_(raw)
        k = physics.conductances().detach().numpy()
        assert np.all(k >= 0) and np.array_equal(k, k.T) and np.all(np.diag(k) == 0)
        assert k[0, 2] == k[0, 3] == k[1, 3] == 0.0
    np.testing.assert_allclose(physics.conductances()[2, 3].item(), 3.0 + np.log1p(np.exp(-3.0)), rtol=1e-12)


def test_the_learned_buildings_zero_order_hold_is_the_buildings() -> None:
    """At the true building's values the physics block's ZOH equals
    :func:`pinn_mpc.multizone.discretise`'s (scipy's exponential of the same building), and on
    simulated data with the true masses and no measurement noise the residuals of
    :func:`zone_residuals` vanish (backups at 12 / 30 C: each interval's power is held)."""
    frame, params, _ = _house_frame(3, noise_std_c=0.0)
    physics = ZonePhysics(params, [(0, 1)])
    ad, bd = physics.discretised(DT_S)
    ref = discretise(params, [ActuatorSpec(upper_w=1.0, zone=z) for z in range(2)], DT_S)
    np.testing.assert_allclose(ad.detach().numpy(), ref.a, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(bd[:, :2].detach().numpy(), ref.b_u, rtol=1e-9, atol=1e-15)
    def column(*names: str) -> torch.Tensor:
        return torch.tensor(frame[list(names)].to_numpy(dtype=float))

    sun = torch.cat([column("G_south"), torch.zeros(len(frame), 1, dtype=torch.float64)], dim=1)
    inputs = physics.heat_inputs(column("u_phys[a0]", "u_phys[a1]"), column("T_a")[:, 0], sun, column("I_g")[:, 0])
    rooms, masses = column("T_r[south]", "T_r[north]"), column("T_m[south]", "T_m[north]")
    r_room, r_mass = zone_residuals(physics, DT_S, rooms_c=rooms, masses_c=masses, inputs=inputs)
    assert float(r_room.detach().abs().max()) < 1e-6 and float(r_mass.detach().abs().max()) < 1e-6


@pytest.fixture(scope="module")
def no_wall_model() -> tuple[MultiZonePaperModel, pd.DataFrame]:
    frame, params, actuators = _house_frame(2, wall_w_per_k=0.0)
    model = fit_multizone_paper(
        frame, arch="physnet", zones=params.zone_specs, actuators=actuators,
        solar_inputs=["G_south", None], dt_s=DT_S, settings=_QUICK, adjacency=[[False, False], [False, False]],
        identified=_known(params),
    )
    return model, frame


@pytest.mark.parametrize("wall", [False, True])
def test_a_zone_without_walls_is_moved_by_its_own_heater_only(
    wall: bool, no_wall_model: tuple[MultiZonePaperModel, pd.DataFrame]
) -> None:
    """Two zones the layout gives no wall (K = 0): plans that differ only in the north heater
    predict the same south room at every step, and the north room differently; with a wall of
    the learned conductance set to 60 W/K the south room then differs too."""
    model, frame = no_wall_model
    if wall:
        physics = ZonePhysics(model.physics.learned(model.identified.params), [(0, 1)])
        with torch.no_grad():
            physics.raw_k.fill_(60.0)
        model = MultiZonePaperModel(
            nets=model.nets, physics=physics, scaling=model.scaling, identified=model.identified,
            actuators=model.actuators, dt_s=model.dt_s, solar_inputs=model.solar_inputs, uses_gains=model.uses_gains,
            training=model.training,
        )
    else:
        assert float(model.physics.conductances().detach().abs().max()) == 0.0
    model = model.for_planning(backup_low_c=5.0, backup_high_c=40.0)
    start, h = 40, 12
    plans = torch.zeros(2, h, 2, dtype=torch.float64)
    plans[:, :, 0] = 2000.0
    plans[1, :, 1] = 5000.0
    out = model.rollout(_history(frame, start + 1, ["u_phys[a0]", "u_phys[a1]"]), plans, _forecast(frame, start, h))
    south, north = out.t_r_c[0, :, :, 0], out.t_r_c[0, :, :, 1]
    assert not torch.equal(north[0], north[1])
    if wall:
        assert float((south[1] - south[0]).abs().max()) > 1e-4
    else:
        assert torch.equal(south[0], south[1])


def test_the_file_round_trips_exactly_and_a_tampered_one_is_refused(
    tmp_path: Path, no_wall_model: tuple[MultiZonePaperModel, pd.DataFrame]
) -> None:
    model, frame = no_wall_model
    file = save_multizone_paper(model, tmp_path / "m")
    back = load_multizone_paper(tmp_path / "m")
    assert back.to_json() == model.to_json()
    starts = np.array([30, 50])
    np.testing.assert_array_equal(back.predict_paths(frame, starts, 6), model.predict_paths(frame, starts, 6))
    data = json.loads(file.read_text())
    data["networks"]["encoder.0.bias"][0][0][0] += 0.1
    file.write_text(json.dumps(data))
    with pytest.raises(InputError, match=rf"{MULTIZONE_PAPER_FILE}: its numbers do not match its sha256"):
        load_multizone_paper(tmp_path / "m")


@pytest.mark.slow
def test_trained_on_a_week_of_the_two_zone_house_it_predicts_the_next_day() -> None:
    """physnet trained on 7 days of ``simulate``'s two-zone house (the scenario's layout, the RC
    it starts from identified from the same days) predicts the 8th day's rooms 12 h ahead from
    every start of its first half within :data:`BOUND_C` on average, from the measured history;
    the identified RC, the plant's own form, from its Kalman state within 0.1 K (the failure
    message gives every error). physreg's held-out error is checked where the command line
    trains it (the next test)."""
    from pinn_mpc.models.multizone_hybrid import MultiZoneHybrid, held_out_error_c
    from scenarios import get_scenario
    from scenarios.experiments.compare import identify_scenario_zones, zone_solar_inputs
    from scenarios.running.datagen import generate

    scenario = get_scenario("two_zone_house")
    spec = scenario.control_spec()
    data = generate(scenario, days=8, seed=0, policy="random-level")
    week = data.iloc[: 7 * 48].reset_index(drop=True)
    identified = identify_scenario_zones(scenario, week)
    starts, h = np.arange(7 * 48, 7 * 48 + 24), 24
    truth = data[["T_r[south]", "T_r[north]"]].to_numpy()[starts[:, None] + np.arange(1, h + 1)]
    rc = MultiZoneHybrid(
        identified, spec.actuators, DT_S, residual=None, solar_inputs=zone_solar_inputs(scenario), selection={},
        training={},
    )
    measured = {"rc": held_out_error_c(rc, data, starts, h)}
    model = fit_multizone_paper(
        week, arch="physnet", zones=spec.zones, actuators=spec.actuators, solar_inputs=zone_solar_inputs(scenario),
        dt_s=DT_S, adjacency=scenario.plant.settings.zone_adjacency, identified=identified,
    )
    measured["physnet"] = float(np.mean(np.abs(model.predict_paths(data, starts, h) - truth)))
    assert measured["rc"] < 0.1 and measured["physnet"] < BOUND_C, measured


@pytest.mark.slow
def test_train_physreg_on_the_house_exports_its_learned_rc_and_cem_plans_over_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``train --arch physreg`` on 7 days of the two-zone house's data writes the paper
    network's file, which predicts the 8th day's rooms 12 h ahead from every start of its first
    half within :data:`BOUND_C` on average; ``export-rc`` writes the learned building (its wall's conductance with its unit), which
    reads back as a multi-zone RC file; ``closed-loop --controller cem --model`` plans over it
    for a day, its planning never failing (every fallback is the guard's hand-over to the RC
    the network carries, credible on the RC house)."""
    from pinn_mpc.data import write_timeseries
    from pinn_mpc_cli.cli import main
    from scenarios import get_scenario
    from scenarios.running.datagen import generate

    data = tmp_path / "house.csv"
    frame = generate(get_scenario("two_zone_house"), days=8, seed=0, policy="random-level")
    write_timeseries(frame.iloc[: 7 * 48].reset_index(drop=True), data)
    model = tmp_path / "model"
    assert main(["train", "--data", str(data), "--scenario", "two_zone_house", "--arch", "physreg", "--out", str(model)]) == 0
    assert "the physreg of 2 zones (south, north; learned walls south-north" in capsys.readouterr().out
    assert (model / MULTIZONE_PAPER_FILE).is_file()
    starts, h = np.arange(7 * 48, 7 * 48 + 24), 24
    truth = frame[["T_r[south]", "T_r[north]"]].to_numpy()[starts[:, None] + np.arange(1, h + 1)]
    error = float(np.mean(np.abs(load_multizone_paper(model).predict_paths(frame, starts, h) - truth)))
    assert error < BOUND_C, error
    rc = tmp_path / "rc.json"
    assert main(["export-rc", "--model", str(model), "--out", str(rc)]) == 0
    assert "south-north U=" in capsys.readouterr().out
    learned = MultiZoneIdentifyResult.from_json(rc.read_text(), source=str(rc))
    assert learned.params.walls[0, 1] == pytest.approx(load_multizone_paper(model).physics.conductances()[0, 1].item())
    status, err, result = cem_plans_the_house_for_a_day(model, tmp_path)
    assert status == 0, err
    assert result["fallbacks"] == result["model_fallback_steps"] and set(result["zones"]) == {"south", "north"}
