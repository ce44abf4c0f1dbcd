"""KPIs against hand computations."""

import numpy as np
import pytest

from pinn_mpc.errors import InternalError
from scenarios.running.kpis import KPI_KEYS, compute_kpis

DT_S = 1800.0


def kpis(n=8, s=30, *, power_w=2000.0, price=0.25, t_r=20.0, t_min=19.0, t_max=23.0,
         decision_s=None, overridden=None, fallback=None, weight=2.0):
    def full(v, shape=(n,)):
        return np.broadcast_to(np.asarray(v, dtype=float), shape).copy()

    return compute_kpis(
        u_phys_w=full(power_w),
        price_eur_per_kwh=full(price),
        t_r_sub_c=full(t_r, (n, s)),
        t_min_c=full(t_min),
        t_max_c=full(t_max),
        decision_s=full(0.01) if decision_s is None else decision_s,
        overridden=np.zeros(n, bool) if overridden is None else overridden,
        fallback=np.zeros(n, bool) if fallback is None else fallback,
        dt_s=DT_S,
        comfort_weight_eur_per_kh=weight,
    )


def test_keys_are_the_contract():
    assert tuple(kpis()) == KPI_KEYS


def test_constant_power_energy_cost_peak():
    # 2 kW for 8 half-hours = 4 h -> 8 kWh; at 0.25 EUR/kWh -> 2 EUR; inside the band.
    k = kpis(n=8, power_w=2000.0, price=0.25)
    assert k["energy_kwh"] == pytest.approx(8.0, rel=1e-12)
    assert k["cost_eur"] == pytest.approx(2.0, rel=1e-12)
    assert k["peak_kw"] == pytest.approx(2.0, rel=1e-12)
    assert k["discomfort_kh"] == 0.0
    assert k["objective"] == pytest.approx(2.0, rel=1e-12)


def test_cost_follows_price_interval_by_interval():
    power = np.array([0.0, 1000.0, 4000.0, 1000.0])
    price = np.array([1.0, 0.1, 0.2, 0.3])
    k = kpis(n=4, power_w=power, price=price)
    # kWh per interval: 0, 0.5, 2, 0.5 -> cost 0.05 + 0.4 + 0.15
    assert k["energy_kwh"] == pytest.approx(3.0, rel=1e-12)
    assert k["cost_eur"] == pytest.approx(0.6, rel=1e-12)
    assert k["peak_kw"] == pytest.approx(4.0, rel=1e-12)


def test_constant_violation_below_and_above():
    # 0.5 K below the band for 6 half-hours = 3 h -> 1.5 K h; weight 2 EUR/(K h) -> 3 EUR.
    below = kpis(n=6, power_w=0.0, t_r=18.5, t_min=19.0)
    assert below["discomfort_kh"] == pytest.approx(1.5, rel=1e-12)
    assert below["objective"] == pytest.approx(3.0, rel=1e-12)
    above = kpis(n=6, power_w=0.0, t_r=24.0, t_max=23.0)
    assert above["discomfort_kh"] == pytest.approx(3.0, rel=1e-12)


def test_violation_integrates_over_substeps_against_interval_band():
    n, s = 2, 30
    t_r = np.full((n, s), 20.0)
    t_r[0, :10] = 18.0  # 1 K below for 10 of 30 minutes of interval 0 -> 1/6 K h
    t_min = np.array([19.0, 21.0])  # interval 1: 1 K below for its whole 30 min -> 1/2 K h
    k = compute_kpis(
        u_phys_w=np.zeros(n), price_eur_per_kwh=np.zeros(n), t_r_sub_c=t_r, t_min_c=t_min,
        t_max_c=np.full(n, 25.0), decision_s=np.zeros(n), overridden=np.zeros(n, bool),
        fallback=np.zeros(n, bool), dt_s=DT_S, comfort_weight_eur_per_kh=1.0,
    )
    assert k["discomfort_kh"] == pytest.approx(1 / 6 + 1 / 2, rel=1e-12)


def test_decision_times_ratio_and_counts():
    decision = np.array([0.010, 0.020, 0.030, 0.040, 1.0])
    over = np.array([True, False, True, True, False])
    fb = np.array([False, False, False, False, True])
    k = kpis(n=5, decision_s=decision, overridden=over, fallback=fb)
    assert k["decision_ms_median"] == pytest.approx(30.0, rel=1e-12)
    assert k["decision_ms_mean"] == pytest.approx(220.0, rel=1e-12)
    assert k["decision_ms_p95"] == pytest.approx(40.0 + 0.8 * 960.0, rel=1e-12)
    assert k["time_ratio"] == pytest.approx(1.1 / (5 * DT_S), rel=1e-12)
    assert (k["backup_overrides"], k["fallbacks"]) == (3, 1)
    assert k["own_decisions_share"] == pytest.approx(0.8, rel=1e-12)


@pytest.mark.parametrize(
    ("wrong", "message"),
    [
        ({"price_eur_per_kwh": np.zeros(2)}, r"price_eur_per_kwh must be \(3,\)"),
        ({"free_t_r_sub_c": np.zeros((3, 5))}, r"free_t_r_sub_c must be \(3, 4\)"),
    ],
)
def test_shape_mismatch_is_an_internal_error(wrong, message):
    right = {"price_eur_per_kwh": np.zeros(3)}
    with pytest.raises(InternalError, match=message):
        compute_kpis(
            u_phys_w=np.zeros(3), t_r_sub_c=np.zeros((3, 4)),
            t_min_c=np.zeros(3), t_max_c=np.zeros(3), decision_s=np.zeros(3),
            overridden=np.zeros(3, bool), fallback=np.zeros(3, bool), dt_s=DT_S,
            comfort_weight_eur_per_kh=1.0, **(right | wrong),
        )


def split(t_r, free, *, heating=True, t_min=19.0, t_max=23.0):
    """KPIs of two intervals of 4 substeps with the run's and the free run's temperatures."""
    n, s = 2, 4
    return compute_kpis(
        u_phys_w=np.zeros(n), price_eur_per_kwh=np.zeros(n),
        t_r_sub_c=np.asarray(t_r, float).reshape(n, s), t_min_c=np.full(n, t_min),
        t_max_c=np.full(n, t_max), decision_s=np.zeros(n), overridden=np.zeros(n, bool),
        fallback=np.zeros(n, bool), dt_s=DT_S, comfort_weight_eur_per_kh=1.0,
        free_t_r_sub_c=None if free is None else np.asarray(free, float).reshape(n, s),
        heating=heating,
    )


def test_discomfort_splits_into_too_cold_and_too_warm():
    # substeps of a quarter interval (7.5 min = 1/8 h): two 1 K below, three 0.5 K above
    t_r = [18.0, 18.0, 20.0, 20.0, 23.5, 23.5, 23.5, 21.0]
    k = split(t_r, None)
    assert k["discomfort_too_cold_kh"] == pytest.approx(2 * 1.0 / 8, rel=1e-12)
    assert k["discomfort_too_warm_kh"] == pytest.approx(3 * 0.5 / 8, rel=1e-12)
    assert k["discomfort_too_cold_kh"] + k["discomfort_too_warm_kh"] == pytest.approx(
        k["discomfort_kh"], rel=1e-15
    )
    # not computed: None, never 0
    assert k["discomfort_unavoidable_kh"] is None and k["discomfort_avoidable_kh"] is None


@pytest.mark.parametrize("t_r", [[18.3] * 8, [24.1] * 8, list(np.linspace(23.1, 29.7, 8))])
def test_one_sided_discomfort_is_the_total_exactly(t_r):
    k = split(t_r, None)
    assert k["discomfort_too_cold_kh"] + k["discomfort_too_warm_kh"] == k["discomfort_kh"] > 0


def test_unavoidable_is_the_free_runs_too_warm_part_when_heating():
    # the run: 1 K too warm in one substep and 2 K too cold in another; the free run: 0.5 K too
    # warm in two substeps (its too-cold part, which heating could avoid, does not count)
    t_r = [24.0, 20.0, 17.0, 20.0, 20.0, 20.0, 20.0, 20.0]
    free = [23.5, 23.5, 15.0, 15.0, 20.0, 20.0, 20.0, 20.0]
    k = split(t_r, free)
    assert k["discomfort_unavoidable_kh"] == pytest.approx(2 * 0.5 / 8, rel=1e-12)
    assert k["discomfort_avoidable_kh"] == pytest.approx((1.0 + 2.0) / 8 - 1.0 / 8, rel=1e-12)
    assert k["discomfort_avoidable_kh"] + k["discomfort_unavoidable_kh"] == pytest.approx(
        k["discomfort_kh"], rel=1e-15
    )


def test_unavoidable_is_the_free_runs_too_cold_part_when_cooling():
    # a cold room (band 2-6 C): with the cooler off it is 1 K too warm (avoidable by cooling)
    # and 0.5 K too cold in one substep (no cooling warms it)
    t_r = [1.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0]
    free = [1.5, 7.0, 7.0, 7.0, 7.0, 7.0, 7.0, 7.0]
    k = split(t_r, free, heating=False, t_min=2.0, t_max=6.0)
    assert k["discomfort_unavoidable_kh"] == pytest.approx(0.5 / 8, rel=1e-12)
    assert k["discomfort_avoidable_kh"] == pytest.approx(1.0 / 8 - 0.5 / 8, rel=1e-12)


def test_unavoidable_is_at_most_the_runs_own_side_so_avoidable_is_never_negative():
    # a run 0.05 K below the free run while both are too warm (what the backup floor's
    # minute steps can do): the unavoidable part is the run's own too-warm part, the rest 0
    free = [24.0] * 8
    k = split([23.95] * 8, free)
    assert k["discomfort_unavoidable_kh"] == k["discomfort_too_warm_kh"]
    assert k["discomfort_avoidable_kh"] == 0.0

