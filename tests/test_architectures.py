"""Architectures as plug-ins: the registry, per-architecture defaults, the typed model record,
and a new architecture added without touching training, artifacts or the planners."""

from __future__ import annotations

import argparse
import ast
import dataclasses
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

from pinn_mpc.artifacts import load_model, save_model
from pinn_mpc.evaluation import recursive_t_r
from pinn_mpc.models import registry
from pinn_mpc.models.base import Architecture, NetParts
from pinn_mpc.models.learned import ModelRecord
from pinn_mpc.models.mlp import MLP, TrunkNet
from pinn_mpc.training import TrainConfig, train_model
from pinn_mpc_cli.cli import build_parser
from tests.model_data import household_data

ROOT = Path(__file__).resolve().parents[1]


def test_every_registered_architecture_loads_under_its_name() -> None:
    for name, spec in registry.ARCHITECTURES.items():
        architecture = registry.get_architecture(name)
        assert isinstance(architecture, Architecture)
        assert architecture.name == name and architecture.spec is spec
    assert registry.DEFAULT_ARCH in registry.ALL_ARCHS
    assert set(registry.ARCHS) < set(registry.ALL_ARCHS)


#: The packages whose modules the name check reads.
PACKAGES = ("pinn_mpc", "controllers", "scenarios", "pinn_mpc_cli")


def test_architecture_names_appear_only_in_the_registry() -> None:
    """No module of the packages but the registry spells an architecture's or a baseline's
    name (the paper's reproduction keys the paper's published figures by its networks' names)."""
    names = set(registry.MODEL_CHOICES)
    found = []
    paths = [p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")]
    for path in sorted(paths):
        if path.name == "registry.py" or "reproduce" in path.parts:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Constant) and node.value in names:
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.value!r}")
    assert not found, found


def test_the_paper_networks_default_to_the_paper_depth_and_train_help_says_so() -> None:
    assert registry.get_spec("physnet").depth == registry.get_spec("physreg").depth == 8
    assert registry.get_spec("hybrid").depth == 16
    train = next(
        a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)
    ).choices["train"]
    text = " ".join(train.format_help().split())
    for spec in registry.ARCHITECTURES.values():
        assert f"{spec.name}: " in text and f"depth {spec.depth}, recipe {spec.recipe}" in text
        assert f"--policy {spec.policy}" in text


def test_config_takes_the_architecture_defaults_unless_given() -> None:
    spec = registry.get_spec("physnet")
    assert TrainConfig().for_arch(spec).depth == spec.depth
    assert TrainConfig().for_arch(spec).recipe == spec.recipe
    assert TrainConfig(depth=3, recipe="paper").for_arch(spec).depth == 3
    assert TrainConfig(depth=3, recipe="paper").for_arch(spec).recipe == "paper"


def test_model_record_round_trips_and_omits_what_an_architecture_lacks() -> None:
    record = ModelRecord(
        arch="physnet", n_members=2, prior={"eta": 1.0}, u_phys_range_w=[0.0, 10.0],
        extra={"format_version": 2},
    )
    out = record.to_dict()
    assert "residual_weight" not in out and out["format_version"] == 2
    assert ModelRecord.from_dict(out) == record
    hybrid = dataclasses.replace(record, residual_weight=1.0, anchor_weight=10.0)
    assert hybrid.to_dict()["anchor_weight"] == 10.0


class ScaledMLP(MLP):
    """A new architecture for the test: the MLP's trunk, its outputs halved."""

    def build_net(self, parts: NetParts) -> nn.Module:
        return HalfTrunk(
            features=parts.features, n_members=parts.n_members, generators=parts.generators,
            t_m_head=False,
        )


class HalfTrunk(TrunkNet):
    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        obs, z = super().forward(x)
        return 0.5 * obs, z

    def rollout_steps(self, inputs, depth):
        step = super().rollout_steps(inputs, depth)
        return lambda tp, h: (0.5 * step(tp, h)[0], None)


@pytest.fixture
def plugged_in(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    spec = registry.ArchSpec(
        name="half", implementation=f"{__name__}:ScaledMLP", label="Half", paper=False,
        depth=3, recipe="converged", policy="random-level", summary="a test architecture",
    )
    monkeypatch.setitem(registry.ARCHITECTURES, "half", spec)
    monkeypatch.setattr(registry, "ALL_ARCHS", (*registry.ALL_ARCHS, "half"))
    monkeypatch.setattr("pinn_mpc.artifacts.ALL_ARCHS", registry.ALL_ARCHS)
    registry.get_architecture.cache_clear()
    yield "half"
    registry.get_architecture.cache_clear()


def test_a_new_architecture_trains_rolls_out_saves_and_loads(plugged_in: str, tmp_path: Path) -> None:
    df = household_data(3, 0)
    model = train_model(df, arch=plugged_in, config=TrainConfig(n_seeds=2, epochs=2), progress=False)
    assert model.depth == 3 and model.record.recipe == "converged"
    series = model.features.exog_series
    history = {n: df[n].to_numpy()[:10] for n in ("T_r", "u_phys", *series)}
    exog = {n: df[n].to_numpy()[10:16] for n in series} | {"time_of_day_h": np.arange(6) * 0.5}
    roll = model.rollout(history, torch.full((4, 6), 1000.0), exog)
    assert roll.t_r_c.shape == (2, 4, 6, 1) and roll.t_m_c is None
    # The fused rollout's first step is the one-step model (the halved outputs included).
    pred, starts = recursive_t_r(model, df, 1)
    one = model.predict_one_step(df)
    common, mine, theirs = np.intersect1d(starts, one["row"], return_indices=True)
    assert len(common) > 100
    assert np.allclose(pred[:, mine], one["T_r_next"][:, theirs], atol=1e-4)
    plain = train_model(df, arch="mlp", config=TrainConfig(n_seeds=2, epochs=2, depth=3), progress=False)
    assert not np.allclose(plain.predict_one_step(df)["T_r_next"], one["T_r_next"], atol=1e-3)
    loaded = load_model(save_model(model, tmp_path / "m"))
    again = loaded.rollout(history, torch.full((4, 6), 1000.0), exog)
    assert loaded.arch == plugged_in and torch.equal(again.t_r_c, roll.t_r_c)
