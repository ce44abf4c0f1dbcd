"""The merged one-zone control of a building of several zones (controllers.merged) against
numbers worked by hand: the split by floor area sums to the planned power and keeps every
actuator within its bounds (a saturated zone's excess going to the others by their shares),
the mean temperature the controller sees is the floor-area-weighted mean, the merged power is
the zones' net heat (a chiller's at its Carnot EER), and a few closed-loop days on the RC
two_zone_house report each zone's KPIs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from controllers.base import ControlSpec, Forecast, Observation
from controllers.merged import MergedView, MergedZones, split_by_share
from controllers.rc_mpc.osqp import QPMPC
from controllers.thermostat import Thermostat
from pinn_mpc.actuator import Actuator, ActuatorSpec
from pinn_mpc.physics import RCParams
from pinn_mpc.zones import ZoneSpec
from scenarios import get_scenario
from scenarios.plants.multizone import MultiZoneSettings
from scenarios.running.closed_loop import run_closed_loop

CHILLER = Actuator(kind="chiller", supply_temp_c=12.0, carnot_efficiency=0.3, cop_min=1.0, cop_max=6.0)
ZONES = (ZoneSpec("a"), ZoneSpec("b"), ZoneSpec("c"))
SHARES = (0.5, 0.3, 0.2)


def _spec() -> ControlSpec:
    """Three zones, a heater in each (zone a's 2 kW, small for its half of the floor) and a
    chiller in zones a and c."""
    return ControlSpec(
        actuators=(
            ActuatorSpec(upper_w=2000.0, zone=0, name="heat_a"),
            ActuatorSpec(upper_w=500.0, zone=0, heats=False, efficiency=CHILLER, name="cool_a"),
            ActuatorSpec(upper_w=5000.0, lower_w=100.0, zone=1, name="heat_b"),
            ActuatorSpec(upper_w=5000.0, zone=2, name="heat_c"),
            ActuatorSpec(upper_w=300.0, zone=2, heats=False, efficiency=CHILLER, name="cool_c"),
        ),
        zones=ZONES,
    )


# -- the split ------------------------------------------------------------------------------------


def test_split_by_share_worked_by_hand():
    w, lo, hi = np.array(SHARES), np.zeros(3), np.array([2000.0, 5000.0, 5000.0])
    # no bound binds: 1000 W in proportion 0.5 : 0.3 : 0.2
    np.testing.assert_allclose(split_by_share(1000.0, w, lo, hi), [500.0, 300.0, 200.0], atol=1e-9)
    # 6000 W: zone a would take 3000 but holds 2000; the other 4000 go 0.3 : 0.2
    np.testing.assert_allclose(split_by_share(6000.0, w, lo, hi), [2000.0, 2400.0, 1600.0], atol=1e-9)
    np.testing.assert_allclose(split_by_share(0.0, w, lo, hi), lo)
    np.testing.assert_allclose(split_by_share(12000.0, w, lo, hi), hi)
    # a lower bound: 100 W held by b until its share passes it (level 333.3 W)
    lo_b = np.array([0.0, 100.0, 0.0])
    np.testing.assert_allclose(split_by_share(200.0, w, lo_b, hi), [100 / 0.7 * 0.5, 100.0, 100 / 0.7 * 0.2], atol=1e-9)


def test_split_sums_to_the_plan_within_every_bound_and_in_proportion_where_free():
    rng = np.random.default_rng(0)
    for _ in range(300):
        n = int(rng.integers(1, 7))
        w = rng.uniform(0.05, 1.0, n)
        lo = rng.choice([0.0, 50.0], n) * rng.uniform(0, 1, n)
        hi = lo + rng.uniform(10.0, 6000.0, n)
        total = float(rng.uniform(lo.sum(), hi.sum()))
        split = split_by_share(total, w, lo, hi)
        assert split.sum() == pytest.approx(total, abs=1e-6)
        assert np.all(split >= lo - 1e-9) and np.all(split <= hi + 1e-9)
        free = (split > lo + 1e-6) & (split < hi - 1e-6)
        if free.sum() > 1:  # one level for every actuator no bound holds
            np.testing.assert_allclose(split[free] / w[free], (split[free] / w[free])[0], rtol=1e-9)


def test_split_refuses_a_plan_beyond_the_bounds_and_bad_weights():
    w, lo, hi = np.array([0.5, 0.5]), np.zeros(2), np.array([1000.0, 1000.0])
    with pytest.raises(ValueError, match=r"total_w = 2500.0 W lies outside .* \[0, 2000\] W; clip"):
        split_by_share(2500.0, w, lo, hi)
    with pytest.raises(ValueError, match=r"weights must be finite and > 0, got \[0.5, 0.0\]"):
        split_by_share(100.0, np.array([0.5, 0.0]), lo, hi)


def test_view_split_of_the_building():
    view = MergedView(spec=_spec(), shares=SHARES)
    heater = view.one_zone_spec.actuator
    assert (heater.lower_w, heater.upper_w, heater.heats, heater.name) == (100.0, 12000.0, True, "")
    u = view.split(6000.0)  # heaters as in the worked split; the chillers off
    np.testing.assert_allclose(u, [2000.0, 0.0, 2400.0, 1600.0, 0.0], atol=1e-9)
    both = MergedView(spec=_spec(), shares=SHARES, cooling=True)
    assert [(a.name, a.upper_w) for a in both.one_zone_spec.actuators] == [("heat", 12000.0), ("cool", 800.0)]
    # 700 W of cooling: a 0.5, c 0.2 -> level 1000 W: a 500 (its bound), c 200
    np.testing.assert_allclose(both.split(np.array([1000.0, 700.0])), [500.0, 500.0, 300.0, 200.0, 200.0], atol=1e-9)
    with pytest.raises(ValueError, match=r"one power per merged actuator \(2\)"):
        both.split(1000.0)


def test_view_refuses_shares_that_are_not_the_floors():
    with pytest.raises(ValueError, match=r"MergedView.shares = \[0.5, 0.5\]: give one floor-area share > 0 per zone \(3: a, b, c\)"):
        MergedView(spec=_spec(), shares=(0.5, 0.5))
    with pytest.raises(ValueError, match=r"MergedView.shares sum to 1.1"):
        MergedView(spec=_spec(), shares=(0.5, 0.3, 0.3))
    heaters_only = dataclasses.replace(_spec(), actuators=tuple(a for a in _spec().actuators if a.heats))
    with pytest.raises(ValueError, match=r"MergedView.cooling = True, but the building has no chiller"):
        MergedView(spec=heaters_only, shares=SHARES, cooling=True)


# -- what the merged controller sees --------------------------------------------------------------


def _history() -> dict[str, np.ndarray]:
    """Two past intervals of the building at 30 C outdoor air (a chiller's EER 4.7525)."""
    history = {
        "T_r[a]": np.array([20.0, 21.0, 20.0]), "T_r[b]": np.array([22.0, 22.0, 22.0]),
        "T_r[c]": np.array([18.0, 19.0, 18.0]), "T_a": np.full(3, 30.0), "G": np.zeros(3),
        "time_of_day_h": np.array([0.0, 0.5, 1.0]),
        "u[heat_a]": np.array([1000.0, 2000.0]), "u[cool_a]": np.array([0.0, 500.0]),
        "u[heat_b]": np.array([100.0, 1000.0]), "u[heat_c]": np.array([0.0, 0.0]),
        "u[cool_c]": np.array([0.0, 0.0]),
    }
    history.update({f"u_phys[{k[2:-1]}]": v for k, v in list(history.items()) if k.startswith("u[")})
    history["u"] = history["u_phys"] = np.array([1100.0, 3500.0])
    return history


def test_the_controller_sees_the_floor_area_weighted_mean_and_the_net_heat():
    view = MergedView(spec=_spec(), shares=SHARES)
    obs = Observation.from_history(2, _history(), zones=ZONES)
    merged = view.observation(obs)
    # 0.5 x 20 + 0.3 x 22 + 0.2 x 18 = 20.2 now; 0.5 x 21 + 0.3 x 22 + 0.2 x 19 = 20.9 before
    assert merged.t_r_c == pytest.approx(20.2, abs=1e-12)
    np.testing.assert_allclose(merged.history["T_r"], [20.2, 20.9, 20.2], atol=1e-12)
    assert merged.zones != ZONES and len(merged.zones) == 1
    # net heat: 2000 + 1000 W of the heaters minus 500 W of chiller at EER 0.3 x 285.15 / 18
    eer = 0.3 * 285.15 / 18.0
    np.testing.assert_allclose(merged.history["u_phys"], [1100.0, 3000.0 - 500.0 * eer], atol=1e-9)
    assert merged.last is not None and merged.last.u_phys == pytest.approx(3000.0 - 500.0 * eer)
    assert not any("[" in name for name in merged.history)  # no zone's or actuator's column left
    both = MergedView(spec=_spec(), shares=SHARES, cooling=True).observation(obs)
    np.testing.assert_allclose(both.history["u_phys[heat]"], [1100.0, 3000.0])
    np.testing.assert_allclose(both.history["u_phys[cool]"], [0.0, 500.0])


def test_each_zone_band_is_merged_into_the_mean_band():
    view = MergedView(spec=_spec(), shares=SHARES)
    h = 4
    fc = Forecast(
        time_of_day_h=np.arange(h) * 0.5, T_a=np.zeros(h), G=np.zeros(h), I_g=np.zeros(h), price=np.ones(h),
        T_min=np.tile([20.0, 21.0, 16.0], (h, 1)), T_max=np.tile([24.0, 24.0, 26.0], (h, 1)),
    )
    merged = view.forecast(fc)
    np.testing.assert_allclose(merged.T_min, np.full(h, 0.5 * 20 + 0.3 * 21 + 0.2 * 16))
    np.testing.assert_allclose(merged.T_max, np.full(h, 0.5 * 24 + 0.3 * 24 + 0.2 * 26))
    same = fc._replace(T_min=np.full(h, 20.0), T_max=np.full(h, 24.0))
    assert view.forecast(same) == same


def test_the_merged_frame_is_what_the_controller_sees():
    history = _history()
    n = 2
    frame = pd.DataFrame({"time": pd.date_range("2024-01-01", periods=n, freq="30min"),
                          **{k: v[:n] for k, v in history.items()}})
    frame.attrs["dt_s"] = 1800.0
    view = MergedView(spec=_spec(), shares=SHARES)
    merged = view.frame(frame)
    seen = view.history(history)
    np.testing.assert_allclose(merged["T_r"], seen["T_r"][:n])
    np.testing.assert_allclose(merged["u_phys"], seen["u_phys"])
    assert list(merged.columns) == ["time", "T_r", "u", "u_phys", "T_a", "G", "time_of_day_h"]
    assert merged.attrs["dt_s"] == 1800.0


# -- in closed loop -------------------------------------------------------------------------------


def _merged_house_rc() -> RCParams:
    """two_zone_house as one zone: each zone's resistances in parallel, capacities and
    apertures summed (exact while both zones are at one temperature)."""
    settings = get_scenario("two_zone_house").plant.settings
    assert isinstance(settings, MultiZoneSettings)
    zones = [z.rc for z in settings.building.zones]
    first = zones[0]
    return dataclasses.replace(
        first,
        r_ra_k_per_w=1.0 / sum(1.0 / z.r_ra_k_per_w for z in zones),
        r_rm_k_per_w=1.0 / sum(1.0 / z.r_rm_k_per_w for z in zones),
        c_r_j_per_k=sum(z.c_r_j_per_k for z in zones), c_m_j_per_k=sum(z.c_m_j_per_k for z in zones),
        solar_aperture_m2=sum(z.solar_aperture_m2 for z in zones),
    )


def test_a_merged_qp_mpc_on_two_zone_house_reports_each_zone():
    scenario = get_scenario("two_zone_house")
    spec = scenario.control_spec()
    view = MergedView(spec=spec, shares=scenario.plant.settings.zone_shares)
    assert view.shares == (0.5, 0.5)
    controller = MergedZones(QPMPC(_merged_house_rc(), view.one_zone_spec), view)
    result = run_closed_loop(scenario, controller, days=1, seed=0)
    kpis = result.kpis
    assert not result.errors and kpis["fallbacks"] == 0
    assert set(kpis["zones"]) == {z.name for z in spec.zones}
    zone_energy = [kpis["zones"][z.name]["energy_kwh"] for z in spec.zones]
    assert sum(zone_energy) == pytest.approx(kpis["energy_kwh"], rel=1e-9)
    assert zone_energy[0] == pytest.approx(zone_energy[1], rel=1e-9)  # equal shares, equal heaters
    assert kpis["energy_kwh"] > 0.1  # the day's cool hours needed heat
    assert controller.name == "merged-qp-mpc"


def test_merged_zones_refuses_a_controller_of_the_true_state():
    view = MergedView(spec=_spec(), shares=SHARES)

    class Knowing(Thermostat):
        knows_true_state = True

    with pytest.raises(ValueError, match=r"MergedZones.inner = 'thermostat' plans on the plant's true state"):
        MergedZones(Knowing(view.one_zone_spec), view)


def test_the_comparison_script_runs_the_merged_and_the_zoned_controllers(tmp_path, capsys):
    from benchmarks.merged_vs_zones import main

    args = ["--scenario", "two_zone_house", "--seeds", "0", "--train-days", "4", "--days", "1", "--out", str(tmp_path)]
    with pytest.raises(SystemExit, match="two_zone_house has no chiller; the merged-hc controllers plan one"):
        main([*args, "--controllers", "merged-hc-qp-mpc"])
    assert main([*args, "--controllers", "thermostat,merged-qp-mpc"]) == 0
    out = capsys.readouterr().out
    assert "merged-qp-mpc  mean" in out and "thermostat     worst (seed 0)" in out
    cells = sorted(p.name for p in tmp_path.iterdir())
    assert cells == [f"two_zone_house_s0_t4_{n}.json" for n in ("merged-qp-mpc", "thermostat")]
