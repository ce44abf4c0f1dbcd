"""``identify`` on data of a building of several zones: the command reads each zone's and each
actuator's columns, takes the building's layout from ``--scenario`` and writes the multi-zone
RC file, whose every R, C and wall conductance is checked against the plant's."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pinn_mpc.data import write_timeseries
from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
from pinn_mpc_cli.cli import main
from scenarios import get_scenario
from scenarios.running.datagen import generate

_RC = ("r_ra_k_per_w", "r_rm_k_per_w", "c_r_j_per_k", "c_m_j_per_k")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_identify_recovers_the_two_zone_house_from_fourteen_days(tmp_path: Path, seed: int, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = get_scenario("two_zone_house")
    data, out = tmp_path / "house.csv", tmp_path / "rc.json"
    write_timeseries(generate(scenario, days=14, seed=seed, policy="random-level"), data)
    assert main(["identify", "--data", str(data), "--scenario", "two_zone_house", "--out", str(out)]) == 0
    assert "identified 2 zones (south, north), walls south-north" in capsys.readouterr().out
    found = MultiZoneIdentifyResult.from_json(out.read_text(), source=str(out)).params
    true = scenario.plant.settings.building  # type: ignore[attr-defined]
    for got, want in zip(found.zones, true.zones, strict=True):
        for key in _RC:
            assert getattr(got.rc, key) == pytest.approx(getattr(want.rc, key), rel=0.15), (got.zone, key)
    assert found.walls[0, 1] == pytest.approx(true.walls[0, 1], rel=0.15)
    assert json.loads(out.read_text())["source"] == f"identify:{data}"


def test_identify_of_zones_needs_the_buildings_layout_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = tmp_path / "house.csv"
    write_timeseries(generate(get_scenario("two_zone_house"), days=2, seed=0), data)
    assert main(["identify", "--data", str(data), "--out", str(tmp_path / "rc.json")]) == 2
    assert "holds 2 zones (south, north); identifying them needs the building's layout" in capsys.readouterr().err
    assert main(["identify", "--data", str(data), "--scenario", "shoulder_office", "--out", str(tmp_path / "rc.json")]) == 2
    assert "its zones (east, west) are not the data's (south, north)" in capsys.readouterr().err
    assert not (tmp_path / "rc.json").exists()
