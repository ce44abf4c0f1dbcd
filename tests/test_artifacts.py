"""Model directories: round trip, and every kind of damage -> ModelFileError."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pinn_mpc.artifacts import CHECKSUM, META, WEIGHTS, load_model, save_model
from pinn_mpc.errors import ModelFileError, PinnMpcWarning
from pinn_mpc.models import HybridNet, LearnedModel
from pinn_mpc.training import TrainConfig, train_model
from tests.model_data import household_data, net_of


@pytest.fixture(scope="module")
def model() -> LearnedModel:
    return train_model(
        household_data(3, 0),
        arch="physnet",
        config=TrainConfig(n_seeds=2, epochs=1, depth=4),
        progress=False,
    )


@pytest.fixture()
def saved(model: LearnedModel, tmp_path: Path) -> Path:
    return Path(save_model(model, tmp_path / "m"))


def test_round_trip_gives_identical_predictions(model: LearnedModel, saved: Path) -> None:
    loaded = load_model(saved)
    df = household_data(2, 7)
    a, b = model.predict_one_step(df), loaded.predict_one_step(df)
    for key in ("T_r_next", "u_phys", "T_m"):
        np.testing.assert_array_equal(a[key], b[key])
    assert (loaded.arch, loaded.depth, loaded.n_members, loaded.exog_names) == (
        "physnet",
        4,
        2,
        ("time_of_day_h", "T_a"),
    )
    assert loaded.physics_coefficients() == model.physics_coefficients()
    meta = json.loads((saved / META).read_text())
    assert meta["package_version"] and meta["training_data"]["n_rows"] == 144
    assert set(meta["learned_coefficients_per_s"]["ensemble"]) >= {"a11", "a12", "a21", "b", "c13"}
    assert sorted(p.name for p in saved.iterdir()) == [META, WEIGHTS]


def test_hybrid_round_trip_keeps_physics_backup_and_rollouts(tmp_path: Path) -> None:
    hybrid = train_model(
        household_data(3, 0), arch="hybrid", config=TrainConfig(n_seeds=2, epochs=2, depth=4),
        progress=False,
    )
    loaded = load_model(save_model(hybrid, tmp_path / "h"))
    assert loaded.arch == "hybrid"
    assert loaded.physics_coefficients() == hybrid.physics_coefficients()
    df = household_data(2, 7)
    a, b = hybrid.predict_one_step(df), loaded.predict_one_step(df)
    for key in ("T_r_next", "u_phys", "T_m"):
        np.testing.assert_array_equal(a[key], b[key])
    net = net_of(loaded, HybridNet)
    assert bool((net.full_power_w == net_of(hybrid, HybridNet).full_power_w).all())
    assert bool((net.full_power_w > 0).all())


def test_saving_over_an_existing_model_replaces_it(model: LearnedModel, saved: Path) -> None:
    save_model(model, saved)
    assert sorted(p.name for p in saved.iterdir()) == [META, WEIGHTS]
    assert [p.name for p in saved.parent.iterdir()] == ["m"]


def test_missing_directory(tmp_path: Path) -> None:
    with pytest.raises(ModelFileError, match="does not exist; train one"):
        load_model(tmp_path / "nope")


@pytest.mark.parametrize("keep", [0, 8, 200, -1])
def test_truncated_weights(saved: Path, keep: int) -> None:
    data = (saved / WEIGHTS).read_bytes()
    (saved / WEIGHTS).write_bytes(data[:keep] if keep >= 0 else data[: len(data) - 4])
    with pytest.raises(ModelFileError, match="truncated or corrupt"):
        load_model(saved)


def test_missing_weights_and_bad_json(saved: Path) -> None:
    (saved / META).write_text("{not json")
    with pytest.raises(ModelFileError, match="is not valid JSON"):
        load_model(saved)
    (saved / META).unlink()
    with pytest.raises(ModelFileError, match=f"has no {META}"):
        load_model(saved)


def test_weights_missing(saved: Path) -> None:
    (saved / WEIGHTS).unlink()
    with pytest.raises(ModelFileError, match=f"has no {WEIGHTS}"):
        load_model(saved)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("n_members", 3, "has shape"),
        ("arch", "physreg", "does not match"),
        ("arch", "rnn", "unknown arch"),
        ("format_version", 99, "format_version 99"),
        ("features", {"depth": 4}, "invalid field"),
    ],
)
def test_inconsistent_metadata(saved: Path, field: str, value: object, match: str) -> None:
    meta = json.loads((saved / META).read_text())
    meta[field] = value
    (saved / META).write_text(json.dumps(meta))
    with pytest.raises(ModelFileError, match=match):
        load_model(saved)


def test_depth_mismatch_is_a_shape_error(saved: Path) -> None:
    meta = json.loads((saved / META).read_text())
    meta["features"]["depth"] = 6
    (saved / META).write_text(json.dumps(meta))
    with pytest.raises(ModelFileError, match="has shape"):
        load_model(saved)


def _edit_meta(saved: Path, path: str, value: object) -> None:
    """Set the model.json field at a dotted path (``features.depth``), or delete it (value None)."""
    meta = json.loads((saved / META).read_text())
    *parents, last = path.split(".")
    node = meta
    for key in parents:
        node = node[key]
    if value is None:
        del node[last]
    else:
        node[last] = value
    (saved / META).write_text(json.dumps(meta))


def test_flipped_bit_in_the_weights_is_detected(saved: Path) -> None:
    raw = bytearray((saved / WEIGHTS).read_bytes())
    header_len = int.from_bytes(raw[:8], "little")
    raw[8 + header_len + 10] ^= 0x40  # inside the tensor data: the header stays valid
    (saved / WEIGHTS).write_bytes(bytes(raw))
    with pytest.raises(ModelFileError, match=f"{WEIGHTS} does not match {META} .*re-train"):
        load_model(saved)


def test_older_directory_without_checksum_or_eta_loads_as_a_heater(saved: Path) -> None:
    assert len(json.loads((saved / META).read_text())[CHECKSUM]) == 64
    _edit_meta(saved, CHECKSUM, None)
    _edit_meta(saved, "eta", None)
    with pytest.warns(PinnMpcWarning) as caught:
        loaded = load_model(saved)
    assert loaded.eta == 1.0
    assert len(caught) == 1 and f"has no {CHECKSUM}" in str(caught[0].message)


@pytest.mark.parametrize(
    ("path", "value", "match"),
    [
        # Sizes are checked against caps and the weights' header before allocating anything.
        ("n_members", 1e9, r"n_members is 1000000000, must be 1 \.\. 1000"),
        ("n_members", 1000, r"has shape \(2, .*implies \(1000, "),
        ("n_members", 2.5, "n_members must be a whole number"),
        ("features.depth", 1e8, r"depth must be 1 \.\. 1008 intervals, got 100000000"),
        ("features.dt_s", 0, r"dt_s must be a control interval of 60 \.\. 21600 s, got 0"),
        ("features.dt_s", -1800, "dt_s must be a control interval"),
        ("eta", 0, "eta is 0"),
        ("eta", float("nan"), "eta is nan, not a finite number"),
        ("eta", -2.5, "disagree on heating vs cooling"),
        ("u_phys_range_w", [0.0, 1e12], "u_phys_range_w .* must lie within"),
    ],
)
def test_implausible_model_json_is_refused(saved: Path, path: str, value: object, match: str) -> None:
    _edit_meta(saved, path, value)
    with pytest.raises(ModelFileError, match=match):
        load_model(saved)
