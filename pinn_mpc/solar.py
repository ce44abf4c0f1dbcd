"""Irradiance on a building's facades: plane-of-array irradiance on vertical surfaces.

Global horizontal irradiance ``G`` says little of what the windows of a building let in: in
winter the low sun puts several times more beam irradiance on a south facade than on the
ground, and east and west facades get theirs in the morning and the afternoon. So the data
format has four optional columns (:data:`FACADE_COLUMNS`, W/m2): the irradiance on vertical
surfaces facing south, east, west and north, the plane-of-array irradiance pvlib computes
(:func:`facade_irradiance`) from a weather file's beam normal and diffuse horizontal
irradiance and the sun's position (interval means: :data:`MAX_SUBSTEP_S`): the beam on the surface
(``DNI cos(angle of incidence)``, 0 when the sun is behind it), half the diffuse horizontal
(an isotropic sky: a vertical surface sees half of it) and half the ground-reflected global
(``albedo G / 2``).

The facades are the compass directions of the site, not of a particular building's walls: a
model weighs the four by what its building's windows take from each.
"""

from __future__ import annotations

import datetime as dt
import math
from typing import Any

import numpy as np
import pandas as pd

from pinn_mpc.errors import InputError

__all__ = [
    "DEFAULT_ALBEDO",
    "FACADE_AZIMUTHS_DEG",
    "FACADE_COLUMNS",
    "MAX_SUBSTEP_S",
    "facade_irradiance",
    "interval_means",
]

#: Data-format columns of the facades' irradiance [W/m2], in this order.
FACADE_COLUMNS = ("G_south", "G_east", "G_west", "G_north")
#: Azimuth of each facade's outward normal [deg], clockwise from north (pvlib's convention).
FACADE_AZIMUTHS_DEG = {"G_south": 180.0, "G_east": 90.0, "G_west": 270.0, "G_north": 0.0}
#: Ground reflectance: EnergyPlus's default (``Site:GroundReflectance``, snow-free ground).
DEFAULT_ALBEDO = 0.2
#: Longest step [s] at which an interval's mean is sampled (EnergyPlus's 10-min timestep).
MAX_SUBSTEP_S = 600.0


def facade_irradiance(
    seconds: np.ndarray,
    *,
    ghi_w_per_m2: np.ndarray,
    dni_w_per_m2: np.ndarray,
    dhi_w_per_m2: np.ndarray,
    latitude_deg: float,
    longitude_deg: float,
    utc_offset_h: float,
    altitude_m: float = 0.0,
    albedo: float = DEFAULT_ALBEDO,
    year: int = 2021,
) -> dict[str, np.ndarray]:
    """Irradiance on the four facades (module docstring) at the instants ``seconds`` (N,)
    [s after 1 January 00:00 local standard time, UTC + ``utc_offset_h``, of ``year``].

    The three irradiance arrays (H,) [W/m2] are hourly means of a weather file's rows, row i
    the hour ending at (i+1) h, as EPW and TMY3 files have them; as EnergyPlus does between
    its weather file's hours, each is interpolated linearly between the hours' midpoints
    (periodic over the H hours: a typical year wraps around), and the sun's position is that
    at each instant. Returns :data:`FACADE_COLUMNS` -> (N,) [W/m2], each >= 0.
    """
    import pvlib

    ghi, dni, dhi = (np.asarray(a, dtype=float) for a in (ghi_w_per_m2, dni_w_per_m2, dhi_w_per_m2))
    if not (ghi.shape == dni.shape == dhi.shape and ghi.ndim == 1 and len(ghi) >= 1):
        raise ValueError(
            f"facade_irradiance: GHI, DNI and DHI must be hourly series of one length, got "
            f"{ghi.shape}, {dni.shape}, {dhi.shape}"
        )
    if not (np.all(np.isfinite(ghi)) and np.all(np.isfinite(dni)) and np.all(np.isfinite(dhi))):
        raise InputError("facade_irradiance: the weather's irradiance has missing values")
    if not (-90.0 <= latitude_deg <= 90.0 and -180.0 <= longitude_deg <= 180.0):
        raise InputError(
            f"facade_irradiance: site at latitude {latitude_deg}, longitude {longitude_deg} is "
            "not on Earth"
        )
    if not 0.0 <= albedo <= 1.0:
        raise ValueError(f"facade_irradiance: albedo must lie in [0, 1], got {albedo!r}")
    t_s = np.asarray(seconds, dtype=float).reshape(-1)
    if t_s.size == 0:
        return {name: np.zeros(0) for name in FACADE_COLUMNS}
    middles_s = (np.arange(len(ghi)) + 0.5) * 3600.0
    period_s = len(ghi) * 3600.0
    ghi, dni, dhi = (
        np.maximum(np.interp(t_s, middles_s, hourly, period=period_s), 0.0)
        for hourly in (ghi, dni, dhi)
    )
    zone = dt.timezone(dt.timedelta(hours=float(utc_offset_h)))
    times = pd.Timestamp(year=year, month=1, day=1, tz=zone) + pd.to_timedelta(t_s, unit="s")
    sun = pvlib.solarposition.get_solarposition(
        pd.DatetimeIndex(times), latitude_deg, longitude_deg, altitude=altitude_m
    )
    out = {}
    for name in FACADE_COLUMNS:
        poa = pvlib.irradiance.get_total_irradiance(
            surface_tilt=90.0,
            surface_azimuth=FACADE_AZIMUTHS_DEG[name],
            solar_zenith=sun["apparent_zenith"].to_numpy(),
            solar_azimuth=sun["azimuth"].to_numpy(),
            dni=dni,
            ghi=ghi,
            dhi=dhi,
            albedo=albedo,
            model="isotropic",
        )
        out[name] = np.maximum(np.nan_to_num(np.asarray(poa["poa_global"], dtype=float)), 0.0)
    return out


def interval_means(
    start_s: float, n: int, dt_s: float, **site: Any
) -> dict[str, np.ndarray]:
    """The facades' irradiance as means over ``n`` consecutive intervals of ``dt_s`` from
    ``start_s`` (as :func:`facade_irradiance` counts seconds): each the mean of
    :func:`facade_irradiance` at the middles of equal substeps no longer than
    :data:`MAX_SUBSTEP_S`; ``site`` the keyword arguments of :func:`facade_irradiance`."""
    pieces = max(1, math.ceil(dt_s / MAX_SUBSTEP_S))
    offsets = (np.arange(pieces) + 0.5) / pieces * dt_s
    instants = start_s + (np.arange(n)[:, None] * dt_s + offsets[None, :]).ravel()
    values = facade_irradiance(instants, **site)
    return {name: v.reshape(n, pieces).mean(axis=1) for name, v in values.items()}
