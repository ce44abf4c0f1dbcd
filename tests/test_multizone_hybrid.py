"""The hybrid of a building of several zones (``train`` on data of several zones): its residual
heat enters as a heater of that power would (checked against the RC with one more heater), its
predictions rise with every heater's power whatever the network learned, it finds the plant's
R, C and walls, keeps a residual only where it predicts held-out data better, and the commands
train, plan over and export it; what does not fit is refused in one line."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.data import write_timeseries
from pinn_mpc.errors import InputError
from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
from pinn_mpc.models.multizone_hybrid import MULTIZONE_FILE, fit_multizone_hybrid, load_multizone
from pinn_mpc.models.multizone_rc import MultiZoneRCModel
from pinn_mpc.models.zone_residual import CLOCK, DAY_TYPE, HIDDEN, ResidualHeat
from pinn_mpc_cli.cli import main
from scenarios import get_scenario
from scenarios.running.datagen import generate
from tests.multizone_data import (
    DT_S,
    cem_plans_the_house_for_a_day,
    multizone_frame,
    two_zone_house,
)

_RC = ("r_ra_k_per_w", "r_rm_k_per_w", "c_r_j_per_k", "c_m_j_per_k")


def _named(actuators: tuple[ActuatorSpec, ...]) -> tuple[ActuatorSpec, ...]:
    return tuple(dataclasses.replace(a, name=f"a{i}") for i, a in enumerate(actuators))


def _dated(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.assign(time=pd.Timestamp("2023-01-02") + pd.to_timedelta(frame["time"], unit="s"))


def _constant_residual(heat_w: tuple[float, ...], scale_w: float = 2000.0) -> ResidualHeat:
    """A residual of the clock and calendar whose output is ``heat_w`` per zone at any time."""
    z_n = len(heat_w)
    return ResidualHeat(
        names=(CLOCK, DAY_TYPE), mean=np.zeros(0), std=np.zeros(0), w1=np.zeros((3, HIDDEN)),
        b1=np.zeros(HIDDEN), w2=np.zeros((HIDDEN, z_n)), b2=np.arctanh(np.array(heat_w) / scale_w),
        scale_w=np.full(z_n, scale_w),
    )


def _history(frame: pd.DataFrame, rows: int, powers: list[str]) -> dict[str, np.ndarray]:
    """The first ``rows`` rows as an observation's history (no T_m: the filter estimates it)."""
    part = frame.iloc[:rows]
    history = {c: part[c].to_numpy(dtype=float) for c in part.columns if c != "time" and not c.startswith("T_m")}
    for c in powers:
        history[c] = history[c][:-1]
    history[CLOCK] = np.arange(rows) * DT_S / 3600.0 % 24.0
    history[DAY_TYPE] = np.zeros(rows)
    return history


def test_residual_heat_enters_the_zone_as_a_heater_of_that_power_would() -> None:
    """The hybrid with a constant residual of 400 W in the south zone and 150 W in the north
    zone predicts, filter and rollout alike, what the RC predicts with one more ideal heater in
    each zone running at that power: the exact ZOH of the same heat."""
    params, actuators = two_zone_house()
    actuators = _named(actuators)
    extra = (ActuatorSpec(upper_w=5000.0, zone=0, name="q0"), ActuatorSpec(upper_w=5000.0, zone=1, name="q1"))
    frame = multizone_frame(params, actuators, days=2, seed=3)
    frame["u_phys[q0]"], frame["u_phys[q1]"] = 400.0, 150.0
    hybrid = MultiZoneRCModel(params, actuators, DT_S, residual=_constant_residual((400.0, 150.0)),
                              backup_low_c=5.0, backup_high_c=40.0)
    reference = MultiZoneRCModel(params, (*actuators, *extra), DT_S, backup_low_c=5.0, backup_high_c=40.0)
    powers = ["u_phys[a0]", "u_phys[a1]"]
    history = _history(frame, 60, powers)
    plans = torch.rand(5, 12, 2, dtype=torch.float64) * 5000.0
    exog = {n: np.resize(history[n], 12) for n in ("T_a", "G", "I_g", "G_south")} | {
        CLOCK: np.arange(12) * 0.5, DAY_TYPE: np.zeros(12),
    }
    got = hybrid.rollout(history, plans, exog)
    ref_history = _history(frame, 60, [*powers, "u_phys[q0]", "u_phys[q1]"])
    with_heat = torch.cat([plans, torch.tensor([400.0, 150.0], dtype=torch.float64).expand(5, 12, 2)], dim=2)
    want = reference.rollout(ref_history, with_heat, exog)
    torch.testing.assert_close(got.t_r_c, want.t_r_c, rtol=0, atol=1e-9)
    torch.testing.assert_close(got.u_phys_w, want.u_phys_w - 550.0, rtol=0, atol=1e-9)


def test_every_zone_warms_with_each_heaters_power_whatever_the_residual_learned() -> None:
    params, actuators = two_zone_house()
    actuators = _named(actuators)
    rng = np.random.default_rng(0)
    residual = ResidualHeat(
        names=(CLOCK, DAY_TYPE), mean=np.zeros(0), std=np.zeros(0), w1=rng.normal(0, 3, (3, HIDDEN)),
        b1=rng.normal(0, 1, HIDDEN), w2=rng.normal(0, 3, (HIDDEN, 2)), b2=rng.normal(0, 1, 2),
        scale_w=np.array([2500.0, 2500.0]),
    )
    model = MultiZoneRCModel(params, actuators, DT_S, residual=residual, backup_low_c=5.0, backup_high_c=40.0)
    frame = multizone_frame(params, actuators, days=2, seed=1)
    history = _history(frame, 50, ["u_phys[a0]", "u_phys[a1]"])
    exog = {n: np.resize(history[n], 24) for n in ("T_a", "G", "I_g", "G_south")} | {
        CLOCK: np.arange(24) * 0.5 % 24, DAY_TYPE: np.full(24, 5.0),
    }
    base = torch.rand(8, 24, 2, dtype=torch.float64) * 4000.0
    more = base.clone()
    more[:, 5, 1] += 800.0  # the north heater, one interval
    low, high = model.rollout(history, base, exog).t_r_c, model.rollout(history, more, exog).t_r_c
    assert torch.all(high >= low - 1e-12)
    assert torch.all(high[..., 6:, :] > low[..., 6:, :])  # both zones, through the wall
    assert torch.equal(high[..., :5, :], low[..., :5, :])


@pytest.mark.slow
def test_a_residual_is_kept_where_unmeasured_gains_leave_the_rc_short() -> None:
    """The house's internal gains (a daily schedule) left out of the data: the RC alone
    cannot hold their daily swing, the residual of the clock learns it and is kept, and the
    held-out error falls."""
    params, actuators = two_zone_house()
    actuators = _named(actuators)
    frame = _dated(multizone_frame(params, actuators, days=30, seed=1)).assign(I_g=0.0)
    model = fit_multizone_hybrid(frame, zones=params.zone_specs, actuators=actuators,
                                 solar_inputs=["G_south", None], dt_s=DT_S)
    errors = model.selection["held_out_mae_c"]
    assert model.selection["kept"] and model.residual is not None
    assert errors["with_residual"] < 0.9 * errors["rc"], errors


@pytest.fixture(scope="module")
def house_data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("house") / "house.csv"
    write_timeseries(generate(get_scenario("two_zone_house"), days=14, seed=0, policy="random-level"), path)
    return path


@pytest.fixture(scope="module")
def house_model(house_data: Path) -> Path:
    out = house_data.parent / "model"
    assert main(["train", "--data", str(house_data), "--scenario", "two_zone_house", "--out", str(out)]) == 0
    return out


def test_train_fits_the_house_and_export_rc_gives_its_r_c_and_wall(house_model: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """On the RC house the identified building is the plant (R, C and the wall within 15 %),
    and the residual, which predicts nothing the RC does not, is dropped."""
    model = load_multizone(house_model)
    assert model.family == "hybrid" and model.residual is None and not model.selection["kept"]
    out = tmp_path / "rc.json"
    assert main(["export-rc", "--model", str(house_model), "--out", str(out)]) == 0
    assert "south-north U=" in capsys.readouterr().out
    found = MultiZoneIdentifyResult.from_json(out.read_text(), source=str(out)).params
    true = get_scenario("two_zone_house").plant.settings.building  # type: ignore[attr-defined]
    for got, want in zip(found.zones, true.zones, strict=True):
        for key in _RC:
            assert getattr(got.rc, key) == pytest.approx(getattr(want.rc, key), rel=0.15), (got.zone, key)
    assert found.walls[0, 1] == pytest.approx(true.walls[0, 1], rel=0.15)


def test_cem_plans_the_house_over_the_trained_model(house_model: Path, tmp_path: Path) -> None:
    status, err, kpis = cem_plans_the_house_for_a_day(house_model, tmp_path)
    assert status == 0, err
    assert kpis["fallbacks"] == 0 and set(kpis["zones"]) == {"south", "north"}


def test_a_saved_model_loads_to_the_same_predictions_and_refuses_a_tampered_file(house_model: Path, tmp_path: Path) -> None:
    model = load_multizone(house_model)
    data = json.loads((house_model / MULTIZONE_FILE).read_text())
    data["residual"] = _constant_residual((100.0, -50.0)).to_json()
    (tmp_path / "ok").mkdir()
    (tmp_path / "ok" / MULTIZONE_FILE).write_text(json.dumps(data))
    again = load_multizone(tmp_path / "ok")
    assert again.residual is not None
    np.testing.assert_allclose(again.residual.heat_w({CLOCK: np.array([3.0]), DAY_TYPE: np.array([0.0])}),
                               [[100.0, -50.0]], atol=1e-9)
    assert again.identified.to_json() == model.identified.to_json()
    for key, value, message in (
        ("format", "pickle", "not a multi-zone model"),
        ("dt_s", -1, "dt_s must be a positive number"),
        ("actuators", [{"upper_w": "x", "efficiency": {}}], "actuator 1"),
        ("residual", {"inputs": ["time_of_day_h"], "w1": "nan"}, "the residual network needs the keys"),
    ):
        bad = tmp_path / key
        bad.mkdir()
        (bad / MULTIZONE_FILE).write_text(json.dumps(data | {key: value}))
        with pytest.raises(InputError, match=message) as caught:
            load_multizone(bad)
        assert "\n" not in str(caught.value)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["train", "--arch", "mlp", "--scenario", "two_zone_house"],
         "train --arch mlp: on a building of several zones train fits the hybrid"),
        (["train", "--seeds", "3", "--scenario", "two_zone_house"], "train: --seeds set a network ensemble's training"),
        (["train", "--scenario", "winter_household"], "--scenario winter_household: its zones (room) are not the data's"),
        (["closed-loop", "--scenario", "shoulder_office", "--controller", "cem"],
         "a model of the zones south, north): scenario 'shoulder_office' has the zones east, west"),
        (["closed-loop", "--scenario", "two_zone_house", "--controller", "qp-mpc"],
         "qp-mpc plans on a multi-zone RC file (--rc); write the model's with `pinn-mpc export-rc`"),
        (["closed-loop", "--scenario", "winter_household", "--controller", "cem"],
         "is a model of a building of several zones (south, north); scenario 'winter_household' has one zone"),
    ],
    ids=["arch", "seeds", "layout", "other-building", "qp-mpc", "one-zone"],
)
def test_what_does_not_fit_a_zoned_model_is_refused_in_one_line(
    house_data: Path, house_model: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    if argv[0] == "train":
        argv = [*argv, "--data", str(house_data), "--out", str(tmp_path / "m")]
    else:
        argv = [*argv, "--model", str(house_model), "--days", "1"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "m").exists()


def test_residual_bound_and_shapes_are_checked() -> None:
    with pytest.raises(ValueError, match="ResidualHeat.w1 has shape"):
        ResidualHeat(names=(CLOCK,), mean=np.zeros(0), std=np.zeros(0), w1=np.zeros((3, 4)), b1=np.zeros(4),
                     w2=np.zeros((4, 2)), b2=np.zeros(2), scale_w=np.ones(2))
    heat = _constant_residual((1999.0, -1999.0)).heat_w({CLOCK: np.zeros(2), DAY_TYPE: np.zeros(2)})
    assert np.all(np.abs(heat) <= 2000.0) and math.isclose(heat[0, 0], 1999.0, rel_tol=1e-9)


def test_each_zones_offset_converges_on_a_constant_bias_as_its_filter_law_says() -> None:
    """The rooms measured 0.4 K above and 0.2 K below what the model predicts for the interval
    that just ended: each zone's offset after n updates of gain g is the bias times
    1 - (1 - g)^n (the filter's law, solved)."""
    from controllers.base import Observation
    from controllers.zone_sampling import _ZoneOffset

    params, actuators = two_zone_house()
    actuators = _named(actuators)
    model = MultiZoneRCModel(params, actuators, DT_S, backup_low_c=5.0, backup_high_c=40.0)
    frame = multizone_frame(params, actuators, days=2, seed=2)
    powers, rooms = ["u_phys[a0]", "u_phys[a1]"], ["T_r[south]", "T_r[north]"]
    offset = _ZoneOffset(model, 0.5)
    bias = np.array([0.4, -0.2])
    for n in range(1, 7):
        history = {k: v.copy() for k, v in _history(frame, 40 + n, powers).items()}
        past = {k: v[:-1] for k, v in history.items()}
        exog = {k: history[k][-2:-1] for k in model.exog_names}
        delivered = torch.tensor([[[history[c][-1] for c in powers]]], dtype=torch.float64)
        predicted = model.rollout(past, delivered, exog).t_r_c[0, 0, 0].numpy()
        for z, column in enumerate(rooms):
            history[column][-1] = predicted[z] + bias[z]
        offset.update(Observation(k=40 + n, t_r_c=float("nan"), history=history, t_m_true_c=float("nan"), zones=params.zone_specs))
        np.testing.assert_allclose(offset.offset_k, bias * (1.0 - 0.5**n), atol=1e-9)
    silent = _ZoneOffset(model, 0.0)
    silent.update(Observation(k=46, t_r_c=float("nan"), history=history, t_m_true_c=float("nan"), zones=params.zone_specs))
    assert np.array_equal(silent.offset_k, [0.0, 0.0])


def test_evaluate_gives_each_zones_errors_and_persistence_as_computed_by_hand(
    house_model: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``evaluate`` on held-out days of the house: each zone's persistence error is the mean
    |T_r[i+h] - T_r[i]| over every start (computed here from the CSV), the model beats it
    (its identified building is the plant within 15 %), and data of another building are
    refused in one line."""
    test = tmp_path / "test.csv"
    write_timeseries(generate(get_scenario("two_zone_house"), days=2, seed=5, policy="random-level"), test)
    out = tmp_path / "metrics.json"
    argv = ["evaluate", "--model", str(house_model), "--data", str(test), "--horizons", "1,12", "--json", str(out)]
    assert main(argv) == 0, capsys.readouterr().err
    assert "by zone south" in capsys.readouterr().out
    metrics = json.loads(out.read_text())
    frame = pd.read_csv(test)
    for h in (1, 12):
        for zone in ("south", "north"):
            rooms = frame[f"T_r[{zone}]"].to_numpy()
            by_hand = float(np.mean(np.abs(rooms[h:] - rooms[:-h])))
            assert metrics["persistence"]["horizons"][str(h)]["zones"][zone] == pytest.approx(by_hand, rel=1e-9)
            assert metrics["horizons"][str(h)]["zones"][zone] < min(0.1, by_hand)
    assert metrics["one_step"]["zones"] == metrics["horizons"]["1"]["zones"]
    other = tmp_path / "other.csv"
    frame.rename(columns=lambda c: c.replace("[north]", "[attic]")).to_csv(other, index=False)
    assert main([*argv[:4], str(other), *argv[5:-1], str(tmp_path / "other.json")]) == 2
    assert "zones south, attic" in capsys.readouterr().err
