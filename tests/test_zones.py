"""The zone axis at the seams: the data format's zone columns, a plant of several zones through
the closed loop, its observation and record, the trajectory and the KPIs."""

import dataclasses

import numpy as np
import pandas as pd
import pytest

from controllers.base import ControlSpec, Observation
from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.data import read_timeseries, validate_timeseries, write_timeseries, zone_values
from pinn_mpc.errors import InputError
from pinn_mpc.physics import PAPER_HOUSEHOLD
from pinn_mpc.simulator import SimConfig, Simulator
from pinn_mpc.zones import (
    ONE_ZONE,
    ZoneSpec,
    parse_zone_column,
    zone_column,
    zone_columns,
    zones_in,
)
from scenarios import get_scenario
from scenarios.inputs.series import ExogenousSeries
from scenarios.plants.base import PlantStep
from scenarios.running.closed_loop import counted_kpis, prepare_run, run_trajectory
from scenarios.running.engine import ClosedLoop
from scenarios.running.kpis import compute_kpis

ZONES = (ZoneSpec("south"), ZoneSpec("north"))


def _two_zone_frame(n: int = 10) -> pd.DataFrame:
    return pd.DataFrame({
        "time": pd.date_range("2021-01-04", periods=n, freq="30min"),
        "T_r[south]": np.linspace(20.0, 21.0, n),
        "T_r[north]": np.linspace(19.0, 18.0, n),
        "u": 1000.0, "u_phys": 1000.0, "T_a": 2.0,
        "T_min": 20.0,
        "T_max[south]": 24.0, "T_max[north]": 23.0,
    })


def test_zone_columns_are_the_one_zone_names_for_one_zone_and_bracketed_for_several():
    assert zone_columns("T_r", ONE_ZONE) == ("T_r",)
    assert zone_columns("T_min", ZONES) == ("T_min[south]", "T_min[north]")
    assert parse_zone_column("T_m[Perimeter_ZN_1]") == ("T_m", "Perimeter_ZN_1")
    assert parse_zone_column("T_r") is None and parse_zone_column("u[south]") is None
    assert zones_in(["time", "T_r[b]", "T_min[b]", "T_r[a]"]) == (ZoneSpec("b"), ZoneSpec("a"))
    assert zones_in(["time", "T_r"]) == ONE_ZONE
    with pytest.raises(ValueError, match="letters, digits"):
        ZoneSpec("south zone")
    with pytest.raises(ValueError, match="zone 2 of a building with 2"):
        zone_column("T_r", ZONES, 2)


def test_a_two_zone_file_round_trips_and_the_one_zone_reader_refuses_it(tmp_path):
    path = tmp_path / "zones.csv"
    write_timeseries(_two_zone_frame(), path)
    frame = read_timeseries(path, zones=True)
    assert list(frame.columns) == [
        "time", "T_r[south]", "T_r[north]", "u", "u_phys", "T_a", "T_min", "T_max[south]", "T_max[north]",
    ]
    np.testing.assert_allclose(zone_values(frame, "T_r")[-1], [21.0, 18.0])
    np.testing.assert_array_equal(zone_values(frame, "T_min")[0], [20.0, 20.0])  # one band for both
    np.testing.assert_array_equal(zone_values(frame, "T_max")[0], [24.0, 23.0])
    with pytest.raises(InputError, match=r"holds 2 zones \(south, north\); this takes one zone \(train and identify take several"):
        read_timeseries(path)


def test_a_file_naming_one_zone_reads_as_the_one_zone_file():
    frame = _two_zone_frame().drop(columns=["T_r[north]", "T_max[north]"])
    one = validate_timeseries(frame)
    assert list(one.columns) == ["time", "T_r", "u", "u_phys", "T_a", "T_min", "T_max"]
    assert zone_values(one, "T_r").shape == (10, 1)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda f: f.assign(T_r=20.0), "has both 'T_r' and T_r"),
        (lambda f: f.drop(columns="T_max[north]"), "T_max is given for some zones but not for north"),
        (lambda f: f.assign(**{"T_m[east]": 20.0}), "zone.s. east without a room temperature"),
        (lambda f: f.assign(**{"T_r[north]": 66.0}), "'T_r\\[north\\]' has a median of 66.0.*Fahrenheit"),
    ],
)
def test_zone_columns_are_checked_as_their_series(change, message):
    with pytest.raises(InputError, match=message):
        validate_timeseries(change(_two_zone_frame()), zones=True)


def test_kpis_of_two_zones_are_the_sums_of_each_zone_alone():
    """Zone 0 is 1 K below its band and zone 1 2 K above its own over 4 intervals of 0.5 h:
    1 x 2 h + 2 x 2 h = 6 K h, the cold part 2 and the warm part 4."""
    n, s = 4, 3
    sub = np.stack([np.full((n, s), 19.0), np.full((n, s), 25.0)], axis=2)
    common = dict(
        u_phys_w=np.full(n, 1000.0), price_eur_per_kwh=np.full(n, 0.2), decision_s=np.zeros(n),
        overridden=np.zeros(n, bool), fallback=np.zeros(n, bool), dt_s=1800.0,
        comfort_weight_eur_per_kh=1.0,
    )
    kpis = compute_kpis(
        t_r_sub_c=sub, t_min_c=np.full((n, 2), 20.0), t_max_c=np.array([[24.0, 23.0]] * n),
        free_t_r_sub_c=np.stack([np.full((n, s), 25.0), np.full((n, s), 23.5)], axis=2), **common,
    )
    assert kpis["discomfort_kh"] == pytest.approx(6.0)
    assert kpis["discomfort_too_cold_kh"] == pytest.approx(2.0)
    assert kpis["discomfort_too_warm_kh"] == pytest.approx(4.0)
    # Each zone's bound is its own free run's too-warm part, at most its own: zone 0 free
    # 1 K above (2 K h) but never too warm itself (0), zone 1 free 0.5 K above (1 K h) under
    # its own 4 K h; a bound over the building's sums (min(3, 4)) would say 3.
    assert kpis["discomfort_unavoidable_kh"] == pytest.approx(1.0)
    assert kpis["energy_kwh"] == pytest.approx(2.0)
    alone = [
        compute_kpis(t_r_sub_c=sub[:, :, z], t_min_c=np.full(n, 20.0), t_max_c=np.full(n, (24.0, 23.0)[z]), **common)
        for z in range(2)
    ]
    assert kpis["discomfort_kh"] == sum(k["discomfort_kh"] for k in alone)


class TwoZonePlant:
    """Two uncoupled RC zones of one building: the batched simulator's two buildings read as
    the zones ``south`` (solar gains) and ``north`` (none). The one actuator heats zone 0."""

    n_buildings = 1
    has_true_state = False
    zones = ZONES

    def __init__(self, config: SimConfig, exo) -> None:
        south = PAPER_HOUSEHOLD
        north = dataclasses.replace(PAPER_HOUSEHOLD, solar_aperture_m2=0.0)
        self.sim = Simulator(config, fleet=[south, north])
        self.n_substeps, self.exo = config.n_substeps, exo

    def reset(self, t_r_c, t_m_c, *, start, seed):
        self.sim.reset(t_r_c, t_m_c, seed=seed)

    def measure(self):
        return self.sim.measure()[None, :]

    def step(self, u_w, row):
        u = float(np.asarray(u_w, dtype=float).reshape(-1)[0])
        exo = self.exo
        r = self.sim.step(np.array([u, 0.0]), exo.T_a[row], exo.G[row], exo.I_g[row])
        one = np.ones(1)
        return PlantStep(
            t_r_c=r.t_r_c[None], t_m_c=r.t_m_c[None], u_phys_w=r.u_phys_w[:1], overridden=r.overridden[:1],
            t_r_sub_c=r.t_r_sub_c.T[None], t_a_c=exo.T_a[row] * one, g_w_per_m2=exo.G[row] * one,
            i_g_w=exo.I_g[row] * one,
        )

    def close(self):
        pass


def _alone(config: SimConfig, params, exo, demands) -> np.ndarray:
    """A zone's room temperature at each interval's start, simulated by itself."""
    sim = Simulator(config, fleet=[params])
    sim.reset(20.0, 19.0)
    t_r = []
    for k, u in enumerate(demands):
        t_r.append(sim.measure()[0])
        sim.step(np.array([u]), exo.T_a[k], exo.G[k], exo.I_g[k])
    return np.array(t_r)


def test_a_two_zone_plant_runs_through_the_loop_with_a_zone_axis():
    scenario = get_scenario("winter_household")
    one_band = prepare_run(scenario, days=1, seed=0, warmup_steps=0, weather_part="test")
    # Each zone its own comfort band: the north zone's 2 K lower.
    t_min = one_band.exo["T_min"]
    exo = one_band.exo.drop(columns="T_min").assign(**{"T_min[south]": t_min, "T_min[north]": t_min - 2.0})
    run = dataclasses.replace(one_band, exo=exo, series=ExogenousSeries.from_frame(exo))
    assert run.series.T_min.shape == (len(exo), 2) and run.series.T_max.shape == (len(exo),)
    config = dataclasses.replace(scenario.sim, backup_low_c=5.0)
    spec = dataclasses.replace(scenario.control_spec(), zones=ZONES)
    with pytest.raises(ValueError, match=r"zones \['room'\] are not the plant's \['south', 'north'\]"):
        ClosedLoop(config, run.series, spec=scenario.control_spec(), initial_t_r_c=20.0,
                   initial_t_m_c=19.0, plant=TwoZonePlant(config, run.series))
    loop = ClosedLoop(config, run.series, spec=spec, initial_t_r_c=20.0, initial_t_m_c=19.0,
                      plant=TwoZonePlant(config, run.series))
    demands = np.where(np.arange(run.total) % 4 < 2, 3000.0, 0.0)
    for k, u in enumerate(demands):
        obs = loop.observation()
        assert obs.zones == ZONES and "T_r" not in obs.history and np.isnan(obs.t_r_c)
        np.testing.assert_array_equal(obs.t_r_zones_c(), loop.measure())
        assert len(obs.history["T_r[north]"]) == k + 1
        loop.step(u)
    rec = loop.record()
    assert rec.t_r_c.shape == (run.total, 2) and rec.t_r_sub_c.shape == (run.total, config.n_substeps, 2)
    north = dataclasses.replace(PAPER_HOUSEHOLD, solar_aperture_m2=0.0)
    np.testing.assert_allclose(rec.t_r_c[:, 0], _alone(config, PAPER_HOUSEHOLD, run.series, demands), atol=1e-12)
    np.testing.assert_allclose(rec.t_r_c[:, 1], _alone(config, north, run.series, 0 * demands), atol=1e-12)
    assert loop.forecast().T_min.shape == (len(exo) - run.total, 2)
    trajectory = run_trajectory(scenario, run, rec)
    np.testing.assert_array_equal(trajectory["T_r[north]"], rec.t_r_c[run.counted, 1])
    np.testing.assert_array_equal(trajectory["T_min[north]"], t_min[run.counted] - 2.0)
    assert not {"T_r", "T_min"} & set(trajectory) and {"T_m[south]", "T_m[north]", "T_max"} <= set(trajectory)
    # The building's discomfort is each zone's against its own band, summed.
    kpis = counted_kpis(scenario, run, rec)
    counted = rec.t_r_sub_c[run.counted]
    alone = [
        compute_kpis(
            u_phys_w=rec.u_phys_w[run.counted], price_eur_per_kwh=run.series.price[run.counted],
            t_r_sub_c=counted[:, :, z], t_min_c=run.series.T_min[run.counted, z],
            t_max_c=run.series.T_max[run.counted], decision_s=rec.decision_s[run.counted],
            overridden=rec.overridden[run.counted], fallback=rec.fallback[run.counted], dt_s=config.dt_s,
            comfort_weight_eur_per_kh=scenario.comfort_weight_eur_per_kh,
        )
        for z in range(2)
    ]
    assert kpis["discomfort_kh"] == pytest.approx(sum(k["discomfort_kh"] for k in alone), rel=1e-12)
    # Judged by the south zone's band, the colder north zone would count discomfort too.
    assert alone[0]["discomfort_kh"] > 0 and alone[1]["discomfort_kh"] == 0
    shared = counted_kpis(scenario, dataclasses.replace(run, series=one_band.series), rec)
    assert shared["discomfort_kh"] > kpis["discomfort_kh"] + 1.0


def test_an_observation_of_one_zone_reads_as_before():
    obs = Observation.from_history(0, {"T_r": np.array([19.5])}, 18.0)
    assert obs.t_r_c == 19.5 and obs.t_m_true_c == 18.0 and obs.zones == ONE_ZONE
    np.testing.assert_array_equal(obs.t_r_zones_c(), [19.5])


def test_a_control_spec_puts_its_actuators_on_its_zones_and_names_several():
    with pytest.raises(ValueError, match=r"zone index\(es\) \[1\] outside the building's 1 zone"):
        ControlSpec(actuators=(ActuatorSpec(upper_w=1000.0, zone=1),))
    spec = ControlSpec(actuators=(ActuatorSpec(upper_w=1000.0, zone=1),), zones=ZONES)
    assert spec.actuator.zone == 1 and not spec.single
    with pytest.raises(ValueError, match="names each one, uniquely"):
        ControlSpec(actuators=(ActuatorSpec(upper_w=1.0, zone=0), ActuatorSpec(upper_w=1.0, zone=1)), zones=ZONES)
    two = ControlSpec(
        actuators=(ActuatorSpec(upper_w=1.0, zone=0, name="h0"), ActuatorSpec(upper_w=1.0, zone=1, name="h1")),
        zones=ZONES,
    )
    assert two.n_actuators == 2
    with pytest.raises(ValueError, match="has 2 actuators"):
        _ = two.actuator
