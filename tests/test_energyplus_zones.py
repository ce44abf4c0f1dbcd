"""EnergyPlus with its zones kept and each controlled on its own (``zones = "controlled"``): a
heater and a chiller per zone as actuators of their own, checked against EnergyPlus's own
output (its SQLite file), the chiller's Carnot EER written out by hand, the zones' physics
(heat warms the zone it is in most) and the built-in ``eplus_small_office_zones`` by season."""

import dataclasses
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("pyenergyplus.api")

from pinn_mpc.actuator import Actuator, ActuatorSpec  # noqa: E402
from pinn_mpc.errors import InputError, InternalError  # noqa: E402
from scenarios.inputs.scenario_file import get_scenario  # noqa: E402
from scenarios.inputs.series import ExogenousSeries  # noqa: E402
from scenarios.plants.energyplus.model import prepare_model  # noqa: E402
from scenarios.plants.energyplus.settings import ZONE_CHILLER, EnergyPlusSettings  # noqa: E402
from scenarios.plants.energyplus.sizing import size_zones  # noqa: E402
from scenarios.plants.energyplus.zoned import ZonedRun  # noqa: E402
from scenarios.running.engine import ClosedLoop  # noqa: E402
from tests.test_energyplus import _sqlite_series  # noqa: E402

SCENARIO = "eplus_small_office_zones"
ZONES = ("Core_ZN", "Perimeter_ZN_1", "Perimeter_ZN_2", "Perimeter_ZN_3", "Perimeter_ZN_4")
WEATHER = "usa_il_chicago"
#: The office's Core_ZN floor area over the five zones' (DOE's model: 149.66 of 511.16 m2).
CORE_SHARE = 149.66 / 511.16
FILE = """
name = "zones_file"
comfort_weight_eur_per_kh = 5.0
initial_t_r_c = 21.0
initial_t_m_c = 21.0
[simulation]
{simulation}backup_low_c = 14.0
backup_high_c = 28.0
[simulation.plant]
kind = "energyplus"
building = "small_office"
weather = "usa_il_chicago"
zones = "controlled"
{plant}
{weather}
[price]
type = "PriceProfile"
kind = "dynamic"
[comfort]
day_min_c = 21.0
day_max_c = 24.0
night_min_c = 16.0
night_max_c = 27.0
"""


def _prepared():
    return prepare_model("small_office", zones="controlled")


def _actuators(heater_w: float = 5000.0, chiller_w: float = 1000.0) -> tuple[ActuatorSpec, ...]:
    """A heater and a chiller of ZONE_CHILLER's EER on each of the office's five zones."""
    return tuple(
        spec
        for z, name in enumerate(ZONES)
        for spec in (
            ActuatorSpec(upper_w=heater_w, zone=z, name=f"heat_{name}"),
            ActuatorSpec(upper_w=chiller_w, zone=z, heats=False, efficiency=ZONE_CHILLER, name=f"cool_{name}"),
        )
    )


def _with_outputs(prepared):
    """``prepared`` writing every zone's air temperature, every heater's and chiller's heating
    rate and the outdoor dry-bulb per timestep to EnergyPlus's own SQLite output."""
    model = dict(prepared.model)
    model["Output:SQLite"] = {"Output:SQLite 1": {"option_type": "Simple"}}
    model["Output:Variable"] = {
        name: {"key_value": "*", "variable_name": variable, "reporting_frequency": "Timestep"}
        for name, variable in (
            ("T", "Zone Mean Air Temperature"), ("Q", "Other Equipment Total Heating Rate"),
            ("A", "Site Outdoor Air Drybulb Temperature"),
        )
    }
    return dataclasses.replace(prepared, model=model)


def _run(day: int, plan: np.ndarray, *, warmup_c: float = 21.0, backup=None, actuators=None):
    """Each interval's means of a ZonedRun from ``day`` holding the rows of ``plan`` (K, A)."""
    with ZonedRun(_prepared(), weather=WEATHER, actuators=actuators or _actuators(),
                  warmup_setpoint_c=warmup_c, backup_c=backup) as run:
        first = run.start(day, 1 + len(plan) // 48)
        return first, [run.step(u) for u in plan]


def _carnot_eer(t_a_c: np.ndarray) -> np.ndarray:
    """ZONE_CHILLER's EER written out: 30 % of the Carnot EER of a 12 C supply, in 1 .. 6."""
    supply_k = 12.0 + 273.15
    return np.clip(0.3 * supply_k / (t_a_c + 273.15 - supply_k), 1.0, 6.0)


def test_each_actuator_delivers_what_energyplus_reports():
    """Random powers on every heater and chiller over the hottest July day: EnergyPlus's own
    report of each object's heating rate is the heater's power, and minus the chiller's power
    times its EER at EnergyPlus's own outdoor dry-bulb of that timestep (the Carnot EER written
    out here); the power reported back is the power asked, each zone's substep temperatures
    are EnergyPlus's, and the EER did vary over the day."""
    prepared = _prepared()
    actuators = _actuators()
    asked = np.random.default_rng(0).uniform(0.0, 1.0, (48, 10)) * np.array([a.upper_w for a in actuators])
    with ZonedRun(_with_outputs(prepared), weather=WEATHER, actuators=actuators, warmup_setpoint_c=24.0) as run:
        run.start(198, 1)  # 17 July, among Chicago's hottest
        means = [run.step(u) for u in asked]
        series = _sqlite_series(run)
    t_a = series[("ENVIRONMENT", "Site Outdoor Air Drybulb Temperature")]
    eer = _carnot_eer(t_a)
    assert eer.max() - eer.min() > 0.5 and eer.min() < 5.0
    for i, a in enumerate(actuators):
        name = (prepared.heaters if a.heats else prepared.chillers)[a.zone].upper()
        heat = series[(name, "Other Equipment Total Heating Rate")]
        per_step = np.repeat(asked[:, i], 3)  # 3 zone timesteps per 30 min
        assert heat == pytest.approx(per_step if a.heats else -eer * per_step, rel=1e-9, abs=1e-6)
    delivered = np.array([m.u_phys_act_w for m in means])
    assert delivered == pytest.approx(asked, rel=1e-9, abs=1e-6)
    assert np.array([m.u_phys_w for m in means]) == pytest.approx(asked.sum(axis=1), rel=1e-9)
    temps = np.array([series[(z.upper(), "Zone Mean Air Temperature")] for z in prepared.zones]).T
    assert np.concatenate([m.t_r_zones_sub_c for m in means]) == pytest.approx(temps, abs=1e-9)
    assert np.array([m.t_r_zones_c for m in means]) == pytest.approx(temps[2::3], abs=1e-9)


@pytest.mark.parametrize("zone", [0, 2])
def test_heating_a_zone_warms_that_zone_most(zone):
    """Six hours of one zone's heater at full power on a January night: that zone warms by
    kelvins, every other zone by much less (heat reaches them only through walls and doors)."""
    off = np.zeros((12, 10))
    on = off.copy()
    on[:, 2 * zone] = 5000.0
    first_off, free = _run(20, off)
    first_on, heated = _run(20, on)
    assert first_on == pytest.approx(first_off, abs=1e-12)  # the same warm-up
    rise = heated[-1].t_r_zones_c - free[-1].t_r_zones_c
    others = np.delete(rise, zone)
    assert rise[zone] > 3.0 and rise[zone] > 3.0 * others.max() and others.min() > -1e-6


def test_cooling_a_zone_in_july_lowers_it():
    """A July afternoon: Perimeter_ZN_1's chiller at full power keeps it kelvins cooler than
    unconditioned, most of all the zones; Perimeter_ZN_3, across the core (no wall shared),
    least; the power delivered is the power asked."""
    plan = np.zeros((36, 10))
    plan[24:, 3] = 1000.0  # noon to 6 pm
    _, free = _run(198, np.zeros((36, 10)), warmup_c=26.0)
    _, cooled = _run(198, plan, warmup_c=26.0)
    drop = np.array([f.t_r_zones_c - c.t_r_zones_c for f, c in zip(free[24:], cooled[24:], strict=True)])
    assert drop[:, 1].min() > 2.0 and drop[-1].argmax() == 1 and drop[-1].argmin() == 3
    assert np.array([m.u_phys_act_w[3] for m in cooled[24:]]) == pytest.approx(1000.0, rel=1e-9)


def test_backup_acts_per_actuator_on_its_own_zone():
    """Warmed up at 30 C on a hot day with a 10/28 C backup: every zone's chiller is forced to
    full power in the first interval (asked nothing), the heaters stay off; with the zones at
    24 C nothing is forced."""
    _, hot = _run(198, np.zeros((1, 10)), warmup_c=30.0, backup=(10.0, 28.0))
    assert hot[0].overridden
    assert hot[0].u_phys_act_w[1::2] == pytest.approx(1000.0 / 3, rel=1e-9)  # the first of 3 timesteps
    assert hot[0].u_phys_act_w[0::2] == pytest.approx(0.0, abs=1e-9)
    _, mild = _run(198, np.zeros((1, 10)), warmup_c=24.0, backup=(10.0, 28.0))
    assert not mild[0].overridden and mild[0].u_phys_act_w == pytest.approx(0.0, abs=1e-9)


def test_the_control_spec_has_five_zones_and_ten_actuators():
    """Each zone a zone of the building, a heater then a chiller per zone, their powers the
    settings' (a number split by floor area, the core's share DOE's 149.66 of 511.16 m2)."""
    spec = get_scenario(SCENARIO).control_spec()
    assert [z.name for z in spec.zones] == list(ZONES) and spec.n_actuators == 10
    assert [a.name for a in spec.actuators] == [f"{k}_{z}" for z in ZONES for k in ("heat", "cool")]
    assert [a.zone for a in spec.actuators] == [z for z in range(5) for _ in range(2)]
    assert [a.heats for a in spec.actuators] == [True, False] * 5
    assert all(a.efficiency == ZONE_CHILLER for a in spec.actuators[1::2])
    settings = get_scenario(SCENARIO).plant.settings
    assert tuple(a.upper_w for a in spec.actuators[0::2]) == settings.heater_w
    assert tuple(a.upper_w for a in spec.actuators[1::2]) == settings.chiller_w
    split = EnergyPlusSettings(building="small_office", weather=WEATHER, zones="controlled",
                               heater_w=20000.0, chiller_w=5000.0).own_actuators
    assert split is not None and sum(a.upper_w for a in split if a.heats) == pytest.approx(20000.0)
    assert split[0].upper_w == pytest.approx(20000.0 * CORE_SHARE, rel=1e-3)
    assert split[1].upper_w == pytest.approx(5000.0 * CORE_SHARE, rel=1e-3)


MEDIUM = "eplus_medium_office_zones"
#: The medium office's conditioned zones: each storey's core and four perimeter zones (its
#: three plenums are not conditioned).
MEDIUM_ZONES = (
    "Core_bottom", "Core_mid", "Core_top",
    *(f"Perimeter_{storey}_ZN_{k}" for storey in ("bot", "mid", "top") for k in range(1, 5)),
)


def test_the_medium_office_has_fifteen_zones_and_thirty_actuators():
    """DOE's medium office with its conditioned zones kept (its plenums left out): a heater then
    a chiller on each, the powers the built-in's, tested in January, trained in December."""
    scenario = get_scenario(MEDIUM)
    spec = scenario.control_spec()
    assert [z.name for z in spec.zones] == list(MEDIUM_ZONES) and spec.n_actuators == 30
    assert [a.name for a in spec.actuators] == [f"{k}_{z}" for z in MEDIUM_ZONES for k in ("heat", "cool")]
    assert [a.zone for a in spec.actuators] == [z for z in range(15) for _ in range(2)]
    assert [a.heats for a in spec.actuators] == [True, False] * 15
    settings = scenario.plant.settings
    assert tuple(a.upper_w for a in spec.actuators[0::2]) == settings.heater_w
    assert tuple(a.upper_w for a in spec.actuators[1::2]) == settings.chiller_w
    assert scenario.sim.u_max_w == sum(settings.heater_w)
    assert (scenario.weather.test_start, scenario.weather.window_start) == ("01-01", "12-01")


@pytest.mark.parametrize(("name", "zones", "storeys"), [(SCENARIO, ZONES, 1), (MEDIUM, MEDIUM_ZONES, 3)])
def test_zones_touch_where_they_share_a_surface(name, zones, storeys):
    """DOE's offices: on each storey the core touches its four perimeter zones and each
    perimeter zone its two neighbours (eight walls a storey); storeys touch only through the
    plenums left out, so no zone of one touches a zone of another."""
    touching = get_scenario(name).plant.settings.zone_adjacency
    assert touching.shape == (len(zones),) * 2 and (touching == touching.T).all() and not touching.diagonal().any()
    assert touching.sum() == 2 * 8 * storeys
    storey = ["" if storeys == 1 else ("bot" if "bot" in z else "mid" if "mid" in z else "top") for z in zones]
    for i, a in enumerate(zones):
        core, numbered = a.startswith("Core"), int(a[-1]) if not a.startswith("Core") else 0
        for j, b in enumerate(zones):
            if i == j or storey[i] != storey[j]:
                assert not touching[i, j], (a, b)
            elif core or b.startswith("Core"):
                assert touching[i, j], (a, b)
            else:  # two perimeter zones: neighbours around the ring 1-2-3-4
                assert touching[i, j] == ((numbered - int(b[-1])) % 4 in (1, 3)), (a, b)
    assert get_scenario("eplus_small_office").plant.settings.zone_adjacency is None  # merged: one zone


@pytest.mark.parametrize(("name", "zones"), [(SCENARIO, ZONES), (MEDIUM, MEDIUM_ZONES)])
def test_each_zone_takes_the_irradiance_of_the_facade_its_windows_face(name, zones):
    """DOE's offices name each perimeter zone's windows by their wall (``..._ZN_1_wall_south_
    Window_1``: zones 1-4 face south, east, north and west); the cores have no windows and take
    the global horizontal G. The merged office has one zone, whose facades are not known."""
    from scenarios.plants.energyplus.model import prepare_model

    settings = get_scenario(name).plant.settings
    facing = {"1": "G_south", "2": "G_east", "3": "G_north", "4": "G_west"}
    assert settings.zone_solar_inputs == tuple("G" if z.startswith("Core") else facing[z[-1]] for z in zones)
    windows = prepare_model(settings.building, zones="controlled").model["FenestrationSurface:Detailed"]
    for window in windows:  # each window's name says its wall, which its zone's input faces
        zone = next(i for i, z in enumerate(zones) if window.lower().startswith(f"{z.lower()}_wall_"))
        assert settings.zone_solar_inputs[zone] == "G_" + window.lower().split("_wall_")[1].split("_")[0], window
    assert get_scenario("eplus_small_office").plant.settings.zone_solar_inputs is None


def test_a_window_faces_its_azimuth_turned_by_the_north_axis():
    """A window's outward normal (x east, y north, z up) gives its facade; the building's north
    axis turns it clockwise; a skylight takes G."""
    from scenarios.plants.energyplus.model import window_facade

    assert [window_facade(v, 0.0) for v in [(0, -2, 0), (3, 0, 0), (0, 1, 0), (-1, 0, 0)]] == [
        "G_south", "G_east", "G_north", "G_west",
    ]
    assert window_facade((0, -2, 0), 90.0) == "G_west" and window_facade((0, -2, 0), -90.0) == "G_east"
    assert window_facade((0, -1, 0), 30.0) == "G_south" and window_facade((0, -1, 0), 50.0) == "G_west"
    assert window_facade((0.2, 0.1, 1.0), 0.0) == "G" and window_facade((0, -1, 0.9), 0.0) == "G_south"


@pytest.mark.parametrize(("name", "month", "before"), [
    (SCENARIO, 1, 12), (f"{SCENARIO}_april", 4, 3), (f"{SCENARIO}_july", 7, 6),
])
def test_the_season_sets_the_dates_and_energyplus_runs_on_them(name, month, before):
    """Each built-in tests on its month and trains on the month before; a closed loop's
    EnergyPlus runs on those dates: its outdoor temperature is the weather file's of the
    series' rows (interval means within 0.5 K; a month apart they differ by many kelvins)."""
    scenario = get_scenario(name)
    test = scenario.exogenous(days=3, seed=0, part="test", lead_steps=48)
    train = scenario.exogenous(days=3, seed=0, part="train")
    assert set(pd.DatetimeIndex(test["time"]).month) == {month}
    assert set(pd.DatetimeIndex(train["time"]).month) == {before}
    series = ExogenousSeries.from_frame(test)
    spec = scenario.control_spec()
    with ClosedLoop(scenario.sim, series, spec=spec, initial_t_r_c=21.0, initial_t_m_c=21.0,
                    plant_settings=scenario.plant, seed=0) as loop:
        for _ in range(48):
            loop.step(np.zeros(spec.n_actuators))
        rec = loop.record()
    assert np.abs(rec.t_a_c - series.T_a[:48]).mean() < 0.5
    assert rec.t_r_c.shape == (48, 5) and rec.t_r_sub_c.shape == (48, 3, 5)


def test_a_scenario_file_takes_a_season_and_a_chillers_constant_eer(tmp_path):
    """``[weather] season`` is that month's window (April tested, March trained on);
    ``[simulation.plant.chiller]`` with cop_min = cop_max is a constant EER; u_max_w is the
    heaters' total."""
    path = tmp_path / "zones.toml"
    chiller = '[simulation.plant.chiller]\nkind = "chiller"\nsupply_temp_c = 12.0\ncop_min = 3.0\ncop_max = 3.0'
    path.write_text(FILE.format(
        simulation="", plant="heater_w = 20000.0\nchiller_w = 5000.0",
        weather=f'{chiller}\n[weather]\nseason = "April"',
    ))
    scenario = get_scenario(str(path))
    weather = scenario.weather
    assert (weather.window_start, weather.window_days, weather.test_start, weather.test_days) == ("03-01", 61, "04-01", 30)
    assert scenario.sim.u_max_w == 20000.0
    cooler = scenario.control_spec().actuators[1]
    assert not cooler.heats and cooler.gain(np.array([15.0, 30.0, 40.0])) == pytest.approx(3.0)


def test_auto_sizes_each_zone_to_hold_its_setpoint():
    """heater_w = "auto": each zone's heater at full power holds its zone at or above the 21 C
    it was sized for through the coldest days (6-8 January), a third of it does not."""
    plant = EnergyPlusSettings(building="small_office", weather=WEATHER, zones="controlled", heater_w="auto")
    sizing = size_zones(plant, 21.0)
    assert sizing.zones == ZONES and sizing.start_day == 6 and not sizing.cooling
    assert all(p >= 1.2 * peak and p % 100 == 0 for p, peak in zip(sizing.powers_w, sizing.peaks_w, strict=True))
    for fraction, holds in ((1.0, True), (1 / 3, False)):
        heaters = tuple(
            ActuatorSpec(upper_w=fraction * p, zone=z, name=f"heat_{z}") for z, p in enumerate(sizing.powers_w)
        )
        plan = np.array([[a.upper_w for a in heaters]] * 144)
        with ZonedRun(_prepared(), weather=WEATHER, actuators=heaters, warmup_setpoint_c=21.0) as run:
            run.start(6, 3)
            lowest = np.min([run.step(u).t_r_zones_sub_c.min(axis=0) for u in plan], axis=0)
        assert (lowest >= 21.0).all() == holds, lowest


def test_closed_loop_prints_each_zone_and_cools_in_july(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "pinn_mpc", "closed-loop", "--scenario", f"{SCENARIO}_july",
         "--controller", "thermostat", "--days", "1", "--seed", "0", "--csv", "t.csv"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
    )
    assert result.returncode == 0, result.stderr
    lines = [line for line in result.stdout.splitlines() if line.startswith("  zone ")]
    assert [line.split()[1].rstrip(":") for line in lines] == list(ZONES)
    assert all("too cold" in line and "too warm" in line for line in lines)
    trajectory = pd.read_csv(tmp_path / "t.csv")
    assert trajectory[[f"u_phys[cool_{z}]" for z in ZONES]].to_numpy().sum() > 0


@pytest.mark.parametrize(("settings", "named"), [
    ({"zones": "merged", "chiller_w": 5000.0}, "chiller_w is the zones' own chillers of zones = \"controlled\""),
    ({"heater_w": (1000.0, 2000.0)}, "a list, one per zone, needs zones = \"controlled\""),
    ({"zones": "controlled", "heater_w": 0.0}, "has no actuator: give heater_w or chiller_w"),
    ({"zones": "controlled", "heater_w": -5.0}, "heater_w = -5.0 must be \"auto\""),
    ({"zones": "controlled", "heater_w": 1000.0, "chiller": Actuator(kind="heat_pump")}, "must be a chiller's efficiency"),
])
def test_settings_misuse_is_one_line_naming_the_field(settings, named):
    with pytest.raises(InputError) as error:
        EnergyPlusSettings(building="small_office", weather=WEATHER, **settings)
    assert named in str(error.value) and "\n" not in str(error.value)


def test_actuators_asked_of_unsized_or_miscounted_settings_are_refused():
    auto = EnergyPlusSettings(building="small_office", weather=WEATHER, zones="controlled", heater_w="auto")
    with pytest.raises(InputError, match=r'heater_w = "auto" is sized when a scenario is read'):
        _ = auto.own_actuators
    three = dataclasses.replace(auto, heater_w=(1000.0, 1000.0, 1000.0))
    with pytest.raises(InputError, match=r"gives 3 power\(s\), but the building has 5 zones \(Core_ZN, "):
        _ = three.own_actuators


@pytest.mark.parametrize(("simulation", "plant", "weather", "named"), [
    ("", "heater_w = 20000.0", '[weather]\nseason = "summer"', "weather.season = 'summer' is not a month; choose one of january,"),
    ("", "heater_w = 20000.0", '[weather]\nseason = "july"\ntest_start = "07-10"', "leave out weather.test_start"),
    ("u_max_w = 30000.0\n", "heater_w = [4000.0, 4000.0, 4000.0, 4000.0, 4000.0]", "",
     "simulation.u_max_w = 30000 W, but simulation.plant.heater_w gives the zones' heaters 20000 W"),
])
def test_file_misuse_is_one_line(tmp_path, simulation, plant, weather, named):
    (tmp_path / "bad.toml").write_text(FILE.format(simulation=simulation, plant=plant, weather=weather))
    with pytest.raises(InputError) as error:
        get_scenario(str(tmp_path / "bad.toml"))
    assert named in str(error.value) and "\n" not in str(error.value)


def test_run_misuse_names_the_fix():
    with pytest.raises(ValueError, match="prepare it with zones = 'controlled'"):
        ZonedRun(prepare_model("small_office", zones="separate"), weather=WEATHER, actuators=_actuators())
    twice = (*_actuators()[:2], ActuatorSpec(upper_w=1.0, zone=0, name="heat_again"))
    with pytest.raises(ValueError, match=r"two heaters on zone 0 \(Core_ZN\)"):
        ZonedRun(_prepared(), weather=WEATHER, actuators=twice)
    with ZonedRun(_prepared(), weather=WEATHER, actuators=_actuators()) as run:
        run.start(20, 1)
        with pytest.raises(InternalError, match=r"one finite power per actuator \(10\)"):
            run.step(np.zeros(3))


@pytest.mark.slow
def test_identify_smoke_on_three_days_of_the_medium_office(tmp_path, capsys):
    """simulate then identify --scenario on the medium office: a multi-zone RC file of its 15
    zones in order, walls only between zones that share a surface, every zone's fit finite."""
    from pinn_mpc.data import write_timeseries
    from pinn_mpc.identify_multizone import MultiZoneIdentifyResult
    from pinn_mpc_cli.cli import main
    from scenarios.running.datagen import generate

    scenario = get_scenario(MEDIUM)
    data, out = tmp_path / "medium.csv", tmp_path / "medium_rc.json"
    write_timeseries(generate(scenario, days=3, seed=0, policy=scenario.data_policy), data)
    assert main(["identify", "--data", str(data), "--scenario", MEDIUM, "--out", str(out)]) == 0
    assert "identified 15 zones (Core_bottom, Core_mid" in capsys.readouterr().out
    result = MultiZoneIdentifyResult.from_json(out.read_text(encoding="utf-8"), source=str(out))
    assert [z.name for z in result.params.zone_specs] == list(MEDIUM_ZONES)
    touching = scenario.plant.settings.zone_adjacency
    walls = np.asarray(result.params.walls)
    assert np.all(walls[~touching] == 0) and np.all(walls >= 0)
    assert np.all(np.isfinite(result.rmse_c)) and result.n_rows == 144
