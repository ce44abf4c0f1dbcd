"""A plant kind is a plug-in: a kind registered here, in this file alone (the RC simulator
under a second name, with a setting of its own), is read from a scenario file, exported,
simulated and run in closed loop by every layer above the plants without a change there."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np
import pytest

import scenarios.plants.kinds as kinds
from pinn_mpc.physics import RCParams
from pinn_mpc.plant import Plant
from scenarios.inputs.scenario_file import get_scenario, load_scenario_file, scenario_to_toml
from scenarios.plants.kinds import KindSettings, PlantKind, PlantRequest, register
from scenarios.plants.rc import RCPlant
from scenarios.running.closed_loop import run_closed_loop
from scenarios.running.datagen import generate
from scenarios.running.factory import build_controller


@dataclass(frozen=True, kw_only=True)
class MirrorSettings(KindSettings):
    """The stand-in kind's own setting: a label it keeps (nothing else reads it)."""

    label: str = "mirror"


def _make(settings: KindSettings, request: PlantRequest) -> RCPlant:
    assert isinstance(settings, MirrorSettings)
    return RCPlant(
        request.config, t_a_c=request.t_a_c, g_w_per_m2=request.g_w_per_m2, i_g_w=request.i_g_w,
        seed=request.seed, fleet=cast(Sequence[RCParams] | None, request.fleet), n_buildings=request.n_buildings,
    )


MIRROR = PlantKind(
    name="mirror_2r2c", summary="the RC simulator under a second name (a test's stand-in kind)",
    settings_type=MirrorSettings, make=_make, structure=lambda settings: Plant(), true_state=True,
    fleets=True,
)


@pytest.fixture
def mirror_kind(monkeypatch: pytest.MonkeyPatch) -> PlantKind:
    """The stand-in kind, registered for one test (the registry as it was afterwards)."""
    kinds.kind_names()  # the built-ins first
    monkeypatch.setattr(kinds, "_KINDS", dict(kinds._KINDS))
    return register(MIRROR)


def test_a_kind_registered_in_one_file_runs_through_every_layer(mirror_kind, tmp_path) -> None:
    base = get_scenario("winter_household")
    text = scenario_to_toml(base).replace('kind = "2r2c"', 'kind = "mirror_2r2c"\nlabel = "twin"')
    text = text.replace('name = "winter_household"', 'name = "mirror"')
    path = tmp_path / "mirror.toml"
    path.write_text(text)
    mirror = load_scenario_file(path)
    assert mirror.plant.kind == "mirror_2r2c" and mirror.plant.settings == MirrorSettings(label="twin")
    assert mirror.reference == "oracle"
    assert 'label = "twin"' in scenario_to_toml(mirror)  # exported with its own field
    assert load_scenario_file(path) == mirror
    # The same RC simulator: the same data and the same closed loops as the built-in kind's.
    twin = dataclasses.replace(base, name="mirror")
    for policy in ("random-level", "thermostat", "closed-loop"):
        a = generate(mirror, days=1, seed=4, policy=policy, n_buildings=2)
        b = generate(twin, days=1, seed=4, policy=policy, n_buildings=2)
        assert a.equals(b), policy
    for name in ("oracle", "thermostat"):
        runs = [
            run_closed_loop(s, build_controller(name, s, n_steps=48), days=1, seed=1)
            for s in (mirror, twin)
        ]
        assert runs[0].kpis["objective"] == runs[1].kpis["objective"]
        np.testing.assert_array_equal(runs[0].trajectory["T_r"], runs[1].trajectory["T_r"])


def test_an_unknown_kind_names_the_registered_ones(tmp_path) -> None:
    text = scenario_to_toml(get_scenario("winter_household")).replace('kind = "2r2c"', 'kind = "mars"')
    path = tmp_path / "mars.toml"
    path.write_text(text)
    with pytest.raises(Exception, match="plant kind 'mars' is unknown; choose one of 2r2c, 3r3c, energyplus"):
        load_scenario_file(path)
