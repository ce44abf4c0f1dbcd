"""Figures of closed-loop trajectories (matplotlib, Agg backend, written atomically)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from pinn_mpc.io import atomic_write  # noqa: E402


def _save(fig: Figure, path: str | os.PathLike[str]) -> Path:
    try:
        return atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    finally:
        plt.close(fig)


def _draw_band(ax: Axes, traj: pd.DataFrame) -> None:
    ax.fill_between(
        traj["time"], traj["T_min"], traj["T_max"], step="post", color="tab:green", alpha=0.15,
        label="comfort band",
    )


def plot_trajectory(
    traj: pd.DataFrame, path: str | os.PathLike[str], *, title: str = ""
) -> Path:
    """Three panels of one run: T_r with the band and T_m; power demanded and delivered; price."""
    fig, axes = plt.subplots(3, 1, figsize=(10, 7.5), sharex=True)
    ax_t, ax_u, ax_p = axes
    _draw_band(ax_t, traj)
    ax_t.plot(traj["time"], traj["T_r"], color="tab:red", label="T_r (measured)")
    ax_t.plot(traj["time"], traj["T_m"], color="tab:brown", ls="--", label="T_m (true, hidden)")
    ax_t.set_ylabel("temperature [C]")
    ax_t.legend(loc="upper right", fontsize=8)
    ax_u.step(traj["time"], traj["u"] / 1000.0, where="post", lw=3, alpha=0.4, label="demanded u")
    ax_u.step(traj["time"], traj["u_phys"] / 1000.0, where="post", lw=1, label="delivered u_phys")
    ax_u.set_ylabel("power [kW]")
    ax_u.legend(loc="upper right", fontsize=8)
    ax_p.step(traj["time"], traj["price"], where="post", color="tab:purple")
    ax_p.set_ylabel("price [EUR/kWh]")
    ax_p.set_xlabel("time")
    if title:
        fig.suptitle(title)
    fig.autofmt_xdate()
    fig.tight_layout()
    return _save(fig, path)


def plot_comparison(
    trajectories: Mapping[str, pd.DataFrame], path: str | os.PathLike[str], *, title: str = ""
) -> Path:
    """All runs of a comparison on the same test days: T_r against the band, and u_phys."""
    fig, (ax_t, ax_u) = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    first = next(iter(trajectories.values()))
    _draw_band(ax_t, first)
    for label, traj in trajectories.items():
        ax_t.plot(traj["time"], traj["T_r"], lw=1.0, label=label)
        ax_u.step(traj["time"], traj["u_phys"] / 1000.0, where="post", lw=1.0, label=label)
    ax_t.set_ylabel("T_r [C]")
    ax_u.set_ylabel("delivered power [kW]")
    ax_u.set_xlabel("time")
    ax_t.legend(loc="upper right", fontsize=7, ncol=2)
    if title:
        fig.suptitle(title)
    fig.autofmt_xdate()
    fig.tight_layout()
    return _save(fig, path)
