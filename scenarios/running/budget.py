"""Work estimated before it starts: memory of big runs against the machine, size of grids.

``simulate --buildings`` holds every row of every building in memory (and a text copy while
the CSV is written); a fleet closed loop holds one controller per building. Both are refused
before any work when the estimate exceeds what the machine has available, with the estimate
and a size that would fit. A sweep grid of more than :data:`LARGE_GRID_CELLS` cells (or a
fleet of more than :data:`LARGE_FLEET_BUILDINGS` buildings) runs only when the user confirms
it with ``--large``.
"""

from __future__ import annotations

import os

from pinn_mpc.errors import InputError, setting
from scenarios.choices import MODEL_CONTROLLERS, RC_CONTROLLERS, TRUTH_CONTROLLERS
from scenarios.inputs.registry import Scenario

__all__ = [
    "BYTES_PER_SIMULATED_ROW",
    "BYTES_PER_FLEET_BUILDING",
    "LARGE_FLEET_BUILDINGS",
    "LARGE_GRID_CELLS",
    "SECONDS_PER_BUILDING_DAY",
    "available_memory_bytes",
    "check_batched_fleet_memory",
    "check_fleet_memory",
    "check_fleet_size",
    "check_grid_size",
    "check_simulate_memory",
]

#: Peak memory per simulated row (one building, one interval), generation and CSV writing
#: together, rounded up from tracemalloc's peak on winter_household.
BYTES_PER_SIMULATED_ROW = 400
#: Memory per building of a fleet closed loop, by controller, rounded up from the resident
#: memory a fleet adds per building (the MPCs hold a solver's problem each).
BYTES_PER_FLEET_BUILDING = {
    **dict.fromkeys(RC_CONTROLLERS, 1_000_000),
    **dict.fromkeys(TRUTH_CONTROLLERS, 1_000_000),
    **dict.fromkeys(MODEL_CONTROLLERS, 500_000),
    "thermostat": 100_000,
}
#: Memory per building and counted interval of a fleet's record (states, powers, KPI inputs).
BYTES_PER_FLEET_STEP = 200
#: Rough wall time per building and simulated day [s] of a fleet by controller, on one core
#: of the development machine (it varies with the machine; it only sizes the warning).
SECONDS_PER_BUILDING_DAY = {
    "thermostat": 0.02,
    "qp-mpc": 0.1,
    "casadi-mpc": 0.15,
    "oracle": 0.16,
    "clairvoyant": 0.16,
    "random-shooting": 2.5,
    "cem": 2.5,
}
#: Share of the available memory a run may plan to use (the rest is the process and the OS).
MEMORY_SHARE = 0.8
#: Sweep grids above this many cells are confirmed with ``--large``.
LARGE_GRID_CELLS = 1000
#: Fleets above this many buildings are confirmed with ``--large``.
LARGE_FLEET_BUILDINGS = 1000


def available_memory_bytes() -> int | None:
    """Memory the machine has available now [B] (Linux ``MemAvailable``, else free pages);
    None when the system does not say."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _gb(n_bytes: float) -> str:
    return f"{n_bytes / 1e9:.1f} GB" if n_bytes < 10e9 else f"{n_bytes / 1e9:.0f} GB"


def _check(what: str, need: float, way_out: str, available: int | None) -> None:
    if available is None:
        return
    budget = MEMORY_SHARE * available
    if need > budget:
        raise InputError(
            f"{what} needs about {_gb(need)} of memory, more than the {_gb(budget)} this "
            f"machine can give it ({_gb(available)} available); {way_out}"
        )


def check_simulate_memory(
    scenario: Scenario, *, days: int, buildings: int, available: int | None = None
) -> None:
    """Refuse ``simulate`` when ``days`` x ``buildings`` rows would not fit in memory
    (``available``: bytes, default :func:`available_memory_bytes`)."""
    available = available_memory_bytes() if available is None else available
    rows_per_building = days * scenario.steps_per_day
    need = BYTES_PER_SIMULATED_ROW * rows_per_building * buildings
    if available is None:
        return
    fit = int(MEMORY_SHARE * available / (BYTES_PER_SIMULATED_ROW * rows_per_building))
    way_out = (
        f"use at most {fit} buildings for {days} days, or fewer days, or several runs with "
        "other seeds"
        if fit >= 1
        else "use fewer days"
    )
    _check(
        f"simulate {setting('buildings')} {buildings} {setting('days')} {days} "
        f"({rows_per_building * buildings:,} "
        f"rows of {BYTES_PER_SIMULATED_ROW} B)",
        need,
        way_out,
        available,
    )


def check_fleet_memory(
    scenario: Scenario,
    controller: str,
    *,
    days: int,
    buildings: int,
    available: int | None = None,
) -> None:
    """Refuse a fleet closed loop whose controllers and records would not fit in memory."""
    available = available_memory_bytes() if available is None else available
    if available is None:
        return
    per_building = BYTES_PER_FLEET_BUILDING.get(controller, 1_000_000)
    per_building += BYTES_PER_FLEET_STEP * (days + 1) * scenario.steps_per_day
    fit = int(MEMORY_SHARE * available / per_building)
    _check(
        f"closed-loop {setting('controller')} {controller} {setting('buildings')} {buildings} (about "
        f"{per_building / 1e6:.1f} MB per building)",
        per_building * buildings,
        f"use at most {fit} buildings, or split the fleet into several runs",
        available,
    )


#: Bytes of one rollout column of a batched fleet model per horizon step: the states, the
#: residual net's hidden layer and the plan-free terms, float32, with the CEM's samples and
#: costs and torch's temporaries (rounded up from the peak of StackedHybrids.roll).
BYTES_PER_ROLLOUT_COLUMN_STEP = 4 * (3 + 2 * 34 + 8)


def check_batched_fleet_memory(
    *, buildings: int, members: int, samples: int, horizon_steps: int, available: int | None = None
) -> None:
    """Refuse a batched rollout of ``buildings`` x ``members`` x ``samples`` columns over
    ``horizon_steps`` that would not fit in memory (the batched cem of a fleet)."""
    available = available_memory_bytes() if available is None else available
    if available is None:
        return
    per_building = BYTES_PER_ROLLOUT_COLUMN_STEP * members * samples * (horizon_steps + 1)
    fit = int(MEMORY_SHARE * available / per_building)
    _check(
        f"a batched rollout of {buildings} buildings x {members} member(s) x {samples} samples "
        f"x {horizon_steps} steps (about {per_building / 1e6:.1f} MB per building)",
        per_building * buildings,
        f"use at most {fit} buildings, or fewer samples",
        available,
    )


def check_fleet_size(controller: str, *, buildings: int, days: int, large: bool) -> None:
    """Refuse a fleet of more than :data:`LARGE_FLEET_BUILDINGS` buildings unless ``large``;
    the message gives a rough estimate of the run time (:data:`SECONDS_PER_BUILDING_DAY`)."""
    if buildings > LARGE_FLEET_BUILDINGS and not large:
        seconds = SECONDS_PER_BUILDING_DAY.get(controller, 1.0) * buildings * (days + 1)
        raise InputError(
            f"{setting('buildings')} {buildings} builds and runs {buildings:,} {controller} controllers, "
            f"more than {LARGE_FLEET_BUILDINGS}: roughly {_duration(seconds)} of work for "
            f"{days} day(s) and the warm-up day; add {setting('large')} to confirm, or use fewer "
            "buildings"
        )


def _duration(seconds: float) -> str:
    if seconds < 3600:
        return f"{max(1, round(seconds / 60))} min"
    return f"{seconds / 3600:.0f} h" if seconds < 48 * 3600 else f"{seconds / 86400:.0f} days"


def check_grid_size(cells: int, *, large: bool, what: str) -> None:
    """Refuse a grid of more than :data:`LARGE_GRID_CELLS` cells unless ``large``; ``what``
    names its axes in the message."""
    if cells > LARGE_GRID_CELLS and not large:
        raise InputError(
            f"sweep: the grid has {cells:,} cells ({what}), more than {LARGE_GRID_CELLS}; add "
            f"{setting('large')} to confirm, or give fewer seeds, scenarios or controllers"
        )
