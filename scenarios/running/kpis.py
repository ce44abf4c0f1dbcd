"""Closed-loop key performance indicators, following BOPTEST's definitions.

- ``energy_kwh``: actuator energy, the delivered ELECTRICAL power ``u_phys`` integrated over
  the run (a heat pump's heat is COP times it, :mod:`pinn_mpc.actuator`).
- ``cost_eur``: price x delivered electrical energy, interval by interval.
- ``discomfort_kh``: integral over time of the comfort-band violation [K h]. The room
  temperature is the simulator's at the end of every substep (1 min by default), held over that
  substep and compared with the band of its control interval.
- ``discomfort_too_cold_kh``, ``discomfort_too_warm_kh``: its parts below and above the band;
  they sum to ``discomfort_kh`` (exactly where one of them is 0, else to floating-point
  rounding).
- ``discomfort_unavoidable_kh``: the part no actuation could have avoided: the too-warm
  discomfort of the same days with the heater asked for nothing (a cooling machine: the
  too-cold discomfort with it off), measured on the same plant from the same warm-up under the
  same weather, gains and seed (:func:`scenarios.running.closed_loop.free_records`). A heater
  only adds heat and the backup thermostat adds heat only below its floor, so the room is no
  cooler under any heating than without it, and no heating controller's too-warm discomfort
  can be smaller; the sensor noise and the forecast errors change what a controller does,
  not this bound. Taken at most the run's own too-warm part (the backup thermostat's floor,
  applied minute by minute, can leave a run a few hundredths of a kelvin below the free run
  for a minute). None where it was not computed (a BOPTEST run).
- ``discomfort_avoidable_kh``: ``discomfort_kh - discomfort_unavoidable_kh``, never below 0:
  what a controller is to be judged on (None where the unavoidable part was not computed).
- ``peak_kw``: the largest interval-mean delivered electrical power.
- ``objective``: ``cost_eur + comfort_weight x discomfort_kh``, the objective every controller
  optimises (:mod:`controllers.objective`, whose primitives compute both terms here), measured on
  the true trajectory at the substep resolution.
- ``decision_ms_median/mean/p95``: wall-clock time of the controller's decisions.
- ``time_ratio``: total decision time / simulated time (BOPTEST's computational time ratio).
- ``backup_overrides``: intervals in which the backup thermostat changed the demand.
- ``fallbacks``: intervals in which the controller's documented fallback acted (for a planner
  over a model with an RC fallback, every decision that MPC made for it, :mod:`controllers.trust`).
- ``own_decisions_share``: the share of the intervals the controller decided itself, without
  its fallback (1 - fallbacks / intervals).
- ``zones``: each zone's figures by its name: its ``discomfort_kh`` with its
  ``discomfort_too_cold_kh`` and ``discomfort_too_warm_kh``, and ``energy_kwh``, the electrical
  energy of the actuators on it; the building's figures above are their sums.

In a building of several zones with heaters and coolers the free run bounds nothing (a cooler
can take the heat a free run leaves), so ``discomfort_unavoidable_kh`` is None there; with
heaters only (coolers only) it is each zone's too-warm (too-cold) discomfort of the free run,
summed, as for one zone (the zones' coupling is through walls, so every zone is no cooler
under any heating than free-running).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from controllers.objective import band_violation_k, energy_cost_eur
from pinn_mpc.errors import InternalError
from pinn_mpc.zones import ONE_ZONE, ZoneSpec
from scenarios.records import Kpis

__all__ = ["KPI_KEYS", "compute_kpis"]

#: The KPI JSON keys, in order.
KPI_KEYS = (
    "energy_kwh",
    "cost_eur",
    "discomfort_kh",
    "discomfort_too_cold_kh",
    "discomfort_too_warm_kh",
    "discomfort_unavoidable_kh",
    "discomfort_avoidable_kh",
    "peak_kw",
    "objective",
    "decision_ms_median",
    "decision_ms_mean",
    "decision_ms_p95",
    "time_ratio",
    "backup_overrides",
    "fallbacks",
    "own_decisions_share",
    "zones",
)


def compute_kpis(
    *,
    u_phys_w: np.ndarray,
    price_eur_per_kwh: np.ndarray,
    t_r_sub_c: np.ndarray,
    t_min_c: np.ndarray,
    t_max_c: np.ndarray,
    decision_s: np.ndarray,
    overridden: np.ndarray,
    fallback: np.ndarray,
    dt_s: float,
    comfort_weight_eur_per_kh: float,
    free_t_r_sub_c: np.ndarray | None = None,
    heating: bool | None = True,
    zones: Sequence[ZoneSpec] | None = None,
    u_phys_act_w: np.ndarray | None = None,
    actuator_zones: Sequence[int] = (0,),
) -> Kpis:
    """KPIs of N control intervals of one building of Z zones: a zone's discomfort counts
    for the building (its K h summed over the zones), the energy is every actuator's.

    Parameters
    ----------
    u_phys_w, price_eur_per_kwh, decision_s, overridden, fallback
        Arrays (N,): delivered power [W], price [EUR/kWh], decision time [s], and whether
        the backup thermostat overrode the demand or the controller's fallback acted (bool).
    t_min_c, t_max_c
        The comfort band [C]: (N,) for every zone, or (N, Z) each zone's.
    t_r_sub_c
        (N, S, Z): the true room temperature of each zone at the end of each of the S
        substeps of every interval [C]; (N, S) for a one-zone building.
    dt_s
        The control interval [s].
    comfort_weight_eur_per_kh
        The price of a kelvin-hour outside the band, in the objective.
    free_t_r_sub_c
        (N, S, Z) or (N, S) as ``t_r_sub_c``: the true room temperature of the same intervals
        with the actuator asked for nothing [C] (:func:`scenarios.running.closed_loop.free_records`), whose too-warm
        (``heating``) or too-cold (a cooling machine) discomfort is the unavoidable part; None:
        not computed (``discomfort_unavoidable_kh`` and ``discomfort_avoidable_kh`` None).
    heating
        Whether the actuators heat (True) or cool; None: some do each (no free-run bound).
    zones
        The building's zones (names of the ``zones`` block), Z of them; None: the one zone's
        name for one, ``zone_1`` .. ``zone_Z`` for several.
    u_phys_act_w, actuator_zones
        (N, A) each actuator's delivered power [W] and (A,) the zone each acts on, for each
        zone's energy; None: ``u_phys_w`` is the one actuator's, on zone 0.

    Returns
    -------
    Kpis
        The keys :data:`KPI_KEYS` (floats, counts as ints).
    """
    u = np.asarray(u_phys_w, dtype=float)
    n = len(u)
    sub = np.asarray(t_r_sub_c, dtype=float)
    if n == 0:
        raise InternalError("compute_kpis: no control intervals; run at least one step")
    if sub.ndim == 2:  # one zone
        sub = sub[:, :, None]
    if sub.ndim != 3 or sub.shape[0] != n:
        raise InternalError(f"compute_kpis: t_r_sub_c must be (N={n}, S, Z), got shape {np.shape(t_r_sub_c)}")
    t_min, t_max = (_zone_band(name, b, sub.shape) for name, b in (("t_min_c", t_min_c), ("t_max_c", t_max_c)))
    for name, arr in (
        ("price_eur_per_kwh", price_eur_per_kwh),
        ("decision_s", decision_s),
        ("overridden", overridden),
        ("fallback", fallback),
    ):
        if np.shape(arr) != (n,):
            raise InternalError(f"compute_kpis: {name} must be ({n},), got shape {np.shape(arr)}")
    dt_h = dt_s / 3600.0
    energy_kwh_k = u / 1000.0 * dt_h
    zones_range = range(sub.shape[2])
    # Zone by zone, each zone's sum as one zone's (a one-zone building's figures as they were).
    discomfort_kh = sum(
        float(np.sum(band_violation_k(sub[:, :, z], t_min[:, :, z], t_max[:, :, z])) * dt_h / sub.shape[1])
        for z in zones_range
    )
    cold_z, warm_z = _band_sides_kh(sub, t_min, t_max, dt_h)
    too_cold_kh, too_warm_kh = sum(cold_z), sum(warm_z)
    unavoidable_kh = avoidable_kh = None
    if free_t_r_sub_c is not None:
        free = np.asarray(free_t_r_sub_c, dtype=float)
        free = free[:, :, None] if free.ndim == 2 else free
        if free.shape != sub.shape:
            raise InternalError(
                f"compute_kpis: free_t_r_sub_c must be {np.shape(t_r_sub_c)} as t_r_sub_c, got "
                f"{np.shape(free_t_r_sub_c)}"
            )
        free_sides = _band_sides_kh(free, t_min, t_max, dt_h)
        if heating is not None:
            # The run's own side is at least the free run's wherever the plant is monotone in
            # the actuation; the backup thermostat's floor, applied minute by minute, can leave
            # it short by a few hundredths of a kelvin for a minute, which the min absorbs
            # (zone by zone: each zone's bound is its own free run's).
            own, free_side = (warm_z, free_sides[1]) if heating else (cold_z, free_sides[0])
            unavoidable_kh = sum(min(f, o) for f, o in zip(free_side, own, strict=True))
            avoidable_kh = discomfort_kh - unavoidable_kh
    cost_eur = float(np.sum(energy_cost_eur(u, np.asarray(price_eur_per_kwh, dtype=float), dt_h)))
    act = u[:, None] if u_phys_act_w is None else np.asarray(u_phys_act_w, dtype=float)
    if zones is None:
        zones = ONE_ZONE if sub.shape[2] == 1 else tuple(ZoneSpec(f"zone_{z + 1}") for z in zones_range)
    if len(zones) != sub.shape[2] or act.shape != (n, len(actuator_zones)):
        raise InternalError(
            f"compute_kpis: {len(zones)} zone names for {sub.shape[2]} zones, or u_phys_act_w "
            f"{act.shape} not (N, A) for the {len(actuator_zones)} actuator zones"
        )
    zone_energy_kwh = [
        float(np.sum(act[:, [i for i, a in enumerate(actuator_zones) if a == z]]) / 1000.0 * dt_h) for z in zones_range
    ]
    decision_ms = np.asarray(decision_s, dtype=float) * 1000.0
    return {
        "energy_kwh": float(np.sum(energy_kwh_k)),
        "cost_eur": cost_eur,
        "discomfort_kh": discomfort_kh,
        "discomfort_too_cold_kh": too_cold_kh,
        "discomfort_too_warm_kh": too_warm_kh,
        "discomfort_unavoidable_kh": unavoidable_kh,
        "discomfort_avoidable_kh": avoidable_kh,
        "peak_kw": float(np.max(u) / 1000.0),
        "objective": cost_eur + comfort_weight_eur_per_kh * discomfort_kh,
        "decision_ms_median": float(np.median(decision_ms)),
        "decision_ms_mean": float(np.mean(decision_ms)),
        "decision_ms_p95": float(np.percentile(decision_ms, 95)),
        "time_ratio": float(np.sum(decision_s) / (n * dt_s)),
        "backup_overrides": int(np.count_nonzero(overridden)),
        "fallbacks": int(np.count_nonzero(fallback)),
        "own_decisions_share": 1.0 - float(np.count_nonzero(fallback)) / n,
        "zones": {
            spec.name: {
                "discomfort_kh": cold_z[z] + warm_z[z],
                "discomfort_too_cold_kh": cold_z[z],
                "discomfort_too_warm_kh": warm_z[z],
                "energy_kwh": zone_energy_kwh[z],
            }
            for z, spec in enumerate(zones)
        },
    }


def _zone_band(name: str, band: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """A comfort band, (N,) for every zone or (N, Z) each zone's, as (N, 1, Z) against
    substep temperatures of ``shape`` (N, S, Z)."""
    n, _, z = shape
    b = np.asarray(band, dtype=float)
    if b.shape == (n,):
        return np.repeat(b[:, None, None], z, axis=2)
    if b.shape == (n, z):
        return b[:, None, :]
    raise InternalError(f"compute_kpis: {name} must be ({n},) or ({n}, {z}), got shape {b.shape}")


def _band_sides_kh(
    sub: np.ndarray, t_min: np.ndarray, t_max: np.ndarray, dt_h: float
) -> tuple[list[float], list[float]]:
    """Each zone's (too cold, too warm) [K h] of substep temperatures ``sub`` (N, S, Z)
    against the band (N, 1, Z), integrated as ``discomfort_kh`` is, so that one side alone
    equals it exactly."""
    n_sub = sub.shape[1]
    cold, warm = [], []
    for z in range(sub.shape[2]):
        cold.append(float(np.sum(np.maximum(t_min[:, :, z] - sub[:, :, z], 0.0)) * dt_h / n_sub))
        warm.append(float(np.sum(np.maximum(sub[:, :, z] - t_max[:, :, z], 0.0)) * dt_h / n_sub))
    return cold, warm
