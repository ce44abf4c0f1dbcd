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


def test_shape_mismatch_is_an_internal_error():
    with pytest.raises(InternalError, match=r"price_eur_per_kwh must be \(3,\)"):
        compute_kpis(
            u_phys_w=np.zeros(3), price_eur_per_kwh=np.zeros(2), t_r_sub_c=np.zeros((3, 4)),
            t_min_c=np.zeros(3), t_max_c=np.zeros(3), decision_s=np.zeros(3),
            overridden=np.zeros(3, bool), fallback=np.zeros(3, bool), dt_s=DT_S,
            comfort_weight_eur_per_kh=1.0,
        )
