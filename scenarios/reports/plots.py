"""Figures of closed-loop trajectories (matplotlib, Agg backend, written atomically).

One set of drawing helpers (comfort band, room temperature, power, price, time axis) serves the
figure of one run (:func:`trajectory_figure`) and the small multiples of a comparison
(:func:`comparison_figure`); :func:`new_figure` and :func:`save_figure` are shared with the
reproduction's figures (:mod:`scenarios.experiments.reproduce.render`). Temperatures in C, power in kW on
the axes (W in the trajectories), time as in the trajectory's ``time`` column.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from itertools import cycle
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.dates as mdates  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from pinn_mpc.io import atomic_write  # noqa: E402
from pinn_mpc.zones import zones_in  # noqa: E402
from scenarios.running.factory import (  # noqa: E402
    MODEL_CONTROLLERS,
    RC_CONTROLLERS,
    TRUTH_CONTROLLERS,
)

__all__ = [
    "FAMILIES",
    "REFERENCE",
    "comparison_figure",
    "controller_name",
    "draw_band",
    "draw_power",
    "draw_price",
    "draw_room",
    "fleet_figure",
    "format_time_axis",
    "group_by_family",
    "new_figure",
    "plot_comparison",
    "plot_trajectory",
    "save_figure",
    "trajectory_figure",
    "zone_comparison_figure",
]

#: Panels of the comparison figure: (title, controller names), in drawing order.
FAMILIES: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("thermostat", ("thermostat",)),
    ("sampling planners over learned models", MODEL_CONTROLLERS),
    ("MPC on RC parameters (identified or exported) or an ARX", RC_CONTROLLERS),
    ("references: true parameters and state", TRUTH_CONTROLLERS),
)
#: The run every panel of a comparison is drawn against.
REFERENCE = "oracle"
_REFERENCE_STYLE: dict[str, Any] = {"color": "k", "ls": "--", "lw": 1.1, "alpha": 0.8}
# Colours for the controllers of one panel; black is the reference's, green the band's.
_COLORS = ("tab:blue", "tab:orange", "tab:red", "tab:purple", "tab:brown", "tab:pink",
           "tab:olive", "tab:cyan", "tab:gray")


def new_figure(
    rows: int,
    cols: int,
    *,
    figsize: tuple[float, float],
    height_ratios: Sequence[float] | None = None,
    sharex: bool = False,
) -> tuple[Figure, np.ndarray]:
    """A figure with a (rows, cols) array of axes and constrained layout."""
    fig, axes = plt.subplots(
        rows,
        cols,
        figsize=figsize,
        sharex=sharex,
        squeeze=False,
        layout="constrained",
        height_ratios=height_ratios,
    )
    return fig, axes


def save_figure(fig: Figure, path: str | os.PathLike[str]) -> Path:
    """Write ``fig`` as PNG atomically (temp file, then rename) and close it."""
    try:
        return atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    finally:
        plt.close(fig)


def draw_band(ax: Axes, traj: pd.DataFrame, zone: str | None = None) -> None:
    """The comfort band ``T_min``..``T_max`` of each interval, shaded (``zone``: that zone's,
    ``T_min[<zone>]``, where the building's zones have their own)."""
    low, high = (_zone_column(traj, series, zone) for series in ("T_min", "T_max"))
    ax.fill_between(
        traj["time"], traj[low], traj[high], step="post", color="tab:green", alpha=0.15,
        lw=0, label="comfort band",
    )


def _zone_column(traj: pd.DataFrame, series: str, zone: str | None) -> str:
    """The trajectory's column of a zone series: ``series[<zone>]`` where it has one, else
    ``series`` (the one zone's, or the band every zone shares)."""
    column = f"{series}[{zone}]"
    return column if zone is not None and column in traj else series


def draw_room(ax: Axes, traj: pd.DataFrame, label: str, zone: str | None = None, **style: Any) -> None:
    """Measured room temperature ``T_r`` [C] (``zone``: that zone's)."""
    ax.plot(traj["time"], traj[_zone_column(traj, "T_r", zone)], label=label, **{"lw": 1.2, **style})


def draw_power(ax: Axes, traj: pd.DataFrame, label: str, column: str = "u_phys", **style: Any) -> None:
    """Power of each interval [kW] as steps; ``column`` ``u_phys`` (delivered) or ``u``."""
    ax.step(traj["time"], traj[column] / 1000.0, where="post", label=label, **{"lw": 1.0, **style})


def draw_price(ax: Axes, traj: pd.DataFrame) -> None:
    ax.step(traj["time"], traj["price"], where="post", color="tab:purple", lw=1.0)
    ax.set_ylabel("price\n[EUR/kWh]")
    ax.grid(alpha=0.3)


def format_time_axis(ax: Axes, traj: pd.DataFrame) -> None:
    """Concise date labels (no rotation) when ``time`` holds dates, and no margin."""
    if pd.api.types.is_datetime64_any_dtype(traj["time"]):
        locator = mdates.AutoDateLocator()
        ax.xaxis.set_major_locator(locator)
        ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
    ax.set_xlim(traj["time"].iloc[0], traj["time"].iloc[-1])
    ax.set_xlabel("time")


def _legend(ax: Axes) -> None:
    ax.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=8, frameon=False)


def zones_figure(traj: pd.DataFrame, *, title: str = "") -> Figure:
    """One run of a building of several zones: a panel per zone (its T_r against its band, and
    its hidden T_m where the plant has one), each actuator's delivered power (``u_phys[<name>]``)
    and the price."""
    zones = [z.name for z in zones_in(traj.columns)]
    actuators = [c for c in traj.columns if c.startswith("u_phys[")]
    fig, axes = new_figure(
        len(zones) + 2, 1, figsize=(11, 2.2 * len(zones) + 3.5),
        height_ratios=(1.5,) * len(zones) + (1.2, 0.7), sharex=True,
    )
    column = axes[:, 0]
    for ax, zone in zip(column, zones, strict=False):
        draw_band(ax, traj, zone)
        draw_room(ax, traj, "T_r (measured)", zone, color="tab:red")
        if f"T_m[{zone}]" in traj:
            ax.plot(traj["time"], traj[f"T_m[{zone}]"], color="tab:brown", ls="--", label="T_m (true, hidden)")
        ax.set_title(zone, loc="left", fontsize=10, fontweight="bold")
        ax.set_ylabel("[C]")
    ax_u = column[len(zones)]
    for name in actuators:
        draw_power(ax_u, traj, name.removeprefix("u_phys[").removesuffix("]"), column=name)
    ax_u.set_ylabel("delivered\n[kW]")
    for ax in column[:-1]:
        _legend(ax)
    return _finish_zone_panels(fig, column, len(zones), traj, title)


def _finish_zone_panels(fig: Figure, column: np.ndarray, n_zones: int, traj: pd.DataFrame, title: str) -> Figure:
    """A figure of a panel per zone, a power panel and a price panel (``column``, its axes),
    finished: grids, one scale for the zones' panels, the price of ``traj``, the time axis
    and ``title``."""
    for ax in column[:-1]:
        ax.grid(alpha=0.3)
    _share_y(list(column[:n_zones]))
    draw_price(column[-1], traj)
    format_time_axis(column[-1], traj)
    if title:
        fig.suptitle(title)
    return fig


def trajectory_figure(traj: pd.DataFrame, *, title: str = "") -> Figure:
    """One run: T_r with the band and the hidden T_m (where the plant has one); power demanded
    and delivered; price (a building of several zones: :func:`zones_figure`)."""
    if len(zones_in(traj.columns)) > 1:
        return zones_figure(traj, title=title)
    fig, axes = new_figure(3, 1, figsize=(11, 7), height_ratios=(2, 1.2, 0.7), sharex=True)
    ax_t, ax_u, ax_p = axes[:, 0]
    draw_band(ax_t, traj)
    draw_room(ax_t, traj, "T_r (measured)", color="tab:red")
    if "T_m" in traj and traj["T_m"].notna().any():  # EnergyPlus and BOPTEST have none
        ax_t.plot(traj["time"], traj["T_m"], color="tab:brown", ls="--", label="T_m (true, hidden)")
    ax_t.set_ylabel("temperature [C]")
    draw_power(ax_u, traj, "demanded u", column="u", lw=3, alpha=0.4, color="tab:blue")
    draw_power(ax_u, traj, "delivered u_phys", color="tab:blue")
    ax_u.set_ylabel("power [kW]")
    for ax in (ax_t, ax_u):
        ax.grid(alpha=0.3)
        _legend(ax)
    draw_price(ax_p, traj)
    format_time_axis(ax_p, traj)
    if title:
        fig.suptitle(title)
    return fig


def plot_trajectory(
    traj: pd.DataFrame, path: str | os.PathLike[str], *, title: str = ""
) -> Path:
    """Write :func:`trajectory_figure` as PNG."""
    return save_figure(trajectory_figure(traj, title=title), path)


def controller_name(label: str) -> str:
    """The controller of a comparison label (``"cem / physnet"`` -> ``"cem"``)."""
    return label.split(" / ")[0]


def group_by_family(labels: Sequence[str]) -> dict[str, list[str]]:
    """Labels by :data:`FAMILIES` panel, in that order; a controller of no family gets its own."""
    family_of = {name: title for title, names in FAMILIES for name in names}
    groups: dict[str, list[str]] = {title: [] for title, _ in FAMILIES}
    for label in labels:
        name = controller_name(label)
        groups.setdefault(family_of.get(name, name), []).append(label)
    return {title: members for title, members in groups.items() if members}


def comparison_figure(
    trajectories: Mapping[str, pd.DataFrame], *, title: str = "", reference: str = REFERENCE
) -> Figure:
    """Small multiples of a comparison on the same test days: per controller family, T_r
    against the comfort band and, below it, the delivered power, each controller against the
    ``reference`` (dashed black; the oracle by default) when it ran; the price at the bottom.
    Shared time axis; all T_r panels share one scale, all power panels another."""
    groups = group_by_family(list(trajectories))
    ref_name, reference_run = reference, trajectories.get(reference)
    first = next(iter(trajectories.values()))
    n = len(groups)
    fig, axes = new_figure(
        2 * n + 1, 1, figsize=(11, 2.9 * n + 1.2), height_ratios=(2, 1) * n + (0.7,), sharex=True
    )
    axes = axes[:, 0]
    temp_axes, power_axes = list(axes[0:-1:2]), list(axes[1:-1:2])
    for ax_t, ax_u, (family, labels) in zip(temp_axes, power_axes, groups.items(), strict=True):
        draw_band(ax_t, first)
        if reference_run is not None:
            draw_room(ax_t, reference_run, f"{ref_name} (reference)", **_REFERENCE_STYLE)
            draw_power(ax_u, reference_run, f"{ref_name} (reference)", **_REFERENCE_STYLE)
        members = [label for label in labels if not (label == ref_name and reference_run is not None)]
        for label, style in zip(members, _member_styles(len(members)), strict=True):
            draw_room(ax_t, trajectories[label], label, **style)
            draw_power(ax_u, trajectories[label], label, **style)
        ax_t.set_title(family, loc="left", fontsize=10, fontweight="bold")
        ax_t.set_ylabel("T_r [C]")
        ax_u.set_ylabel("delivered\n[kW]")
        for ax in (ax_t, ax_u):
            ax.grid(alpha=0.3)
        _legend(ax_t)
    _share_y(temp_axes)
    _share_y(power_axes)
    draw_price(axes[-1], first)
    format_time_axis(axes[-1], first)
    if title:
        fig.suptitle(title)
    return fig


def _member_styles(n: int) -> list[dict[str, Any]]:
    """A colour each, and lines thinner in drawing order: a run that coincides with an earlier
    one (e.g. two solvers of the same problem) still shows as a thin line on a thick one."""
    widths = np.linspace(2.0, 1.0, n) if n > 1 else [1.3] * n
    return [{"color": c, "lw": float(w)} for c, w in zip(cycle(_COLORS), widths)]


def _share_y(axes: Sequence[Axes]) -> None:
    """One y scale for ``axes``, fitted to the data of all of them."""
    for ax in axes[1:]:
        ax.sharey(axes[0])
    axes[0].autoscale_view(scalex=False)  # sharing keeps the first axes' limits otherwise


def zone_comparison_figure(
    trajectories: Mapping[str, pd.DataFrame], *, title: str = "", reference: str = REFERENCE
) -> Figure:
    """A comparison on a building of several zones: a panel per zone (every controller's T_r
    of that zone against its band, the ``reference`` dashed black where it ran), the
    building's delivered power of every controller and the price. Shared time axis; the zones'
    panels share one scale."""
    first = next(iter(trajectories.values()))
    zones = [z.name for z in zones_in(first.columns)]
    fig, axes = new_figure(
        len(zones) + 2, 1, figsize=(11, 2.4 * len(zones) + 3.8),
        height_ratios=(1.6,) * len(zones) + (1.2, 0.7), sharex=True,
    )
    column = axes[:, 0]
    reference_run = trajectories.get(reference)
    members = [label for label in trajectories if not (label == reference and reference_run is not None)]
    styles = _member_styles(len(members))
    ax_u = column[len(zones)]
    for ax, zone in zip(column, zones, strict=False):
        draw_band(ax, first, zone)
        if reference_run is not None:
            draw_room(ax, reference_run, f"{reference} (reference)", zone, **_REFERENCE_STYLE)
        for label, style in zip(members, styles, strict=True):
            draw_room(ax, trajectories[label], label, zone, **style)
        ax.set_title(zone, loc="left", fontsize=10, fontweight="bold")
        ax.set_ylabel("T_r [C]")
    if reference_run is not None:
        draw_power(ax_u, reference_run, f"{reference} (reference)", **_REFERENCE_STYLE)
    for label, style in zip(members, styles, strict=True):
        draw_power(ax_u, trajectories[label], label, **style)
    ax_u.set_ylabel("delivered,\nbuilding [kW]")
    _legend(column[0])
    return _finish_zone_panels(fig, column, len(zones), first, title)


def plot_comparison(
    trajectories: Mapping[str, pd.DataFrame],
    path: str | os.PathLike[str],
    *,
    title: str = "",
    reference: str = REFERENCE,
) -> Path:
    """Write :func:`comparison_figure` as PNG (on a building of several zones
    :func:`zone_comparison_figure`)."""
    zoned = len(zones_in(next(iter(trajectories.values())).columns)) > 1
    figure = zone_comparison_figure if zoned else comparison_figure
    return save_figure(figure(trajectories, title=title, reference=reference), path)


def fleet_figure(
    times: Sequence[str],
    aggregate_kw: np.ndarray,
    discomfort_kh: np.ndarray,
    *,
    cap_kw: np.ndarray | None = None,
    baseline_kw: np.ndarray | None = None,
    title: str = "",
) -> Figure:
    """What an aggregator looks at: the fleet's aggregate power (K,) [kW] over the run against
    its cap (K,) [kW] (NaN where uncapped; None: no cap) and an uncoordinated baseline (K,)
    [kW] when given, and the distribution of per-building discomfort (B,) [K h]."""
    fig, axes = new_figure(1, 2, figsize=(12.0, 4.0))
    ax, hist = axes[0, 0], axes[0, 1]
    t = pd.DatetimeIndex(pd.to_datetime(list(times)))
    if baseline_kw is not None:
        ax.step(t, baseline_kw, where="post", color="tab:gray", lw=1.0, label="uncoordinated")
    ax.step(t, aggregate_kw, where="post", color="tab:blue", lw=1.4, label="fleet")
    if cap_kw is not None:
        ax.step(t, cap_kw, where="post", color="tab:red", ls="--", lw=1.4, label="cap")
    ax.set_ylabel("aggregate electrical power [kW]")
    ax.xaxis.set_major_formatter(mdates.DateFormatter("%H:%M"))
    ax.set_xlabel(f"{t[0]:%Y-%m-%d} .. {t[-1]:%Y-%m-%d}" if len(t) else "")
    ax.grid(alpha=0.3)
    _legend(ax)
    values = np.asarray(discomfort_kh, dtype=float)
    hist.hist(values, bins=min(30, max(5, len(values) // 5)), color="tab:blue", alpha=0.8)
    hist.set_xlabel("total discomfort per building [K h]")
    hist.set_ylabel("buildings")
    hist.set_title(f"mean {values.mean():.2f} K h, worst {values.max():.2f} K h", fontsize=9)
    hist.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=10)
    return fig
