"""Gymnasium face of the closed loop (:class:`scenarios.running.engine.ClosedLoop`): one building, one
control interval per step.

Observation (float32, shape (9,) or more): what a controller may see at the start of interval
k: ``(T_r measured [C], T_a [C], G [W/m2], I_g [W], price [EUR/kWh], T_min [C], T_max [C],
sin(2 pi h/24), cos(2 pi h/24))`` with h the hour of day (:data:`OBSERVATION_NAMES`), then
the site's inputs the frame has (:data:`pinn_mpc.data.SITE_COLUMNS`: an EnergyPlus building's
facade irradiance [W/m2] and wind speed [m/s]); ``env.observation_names`` names them all.
Action (float32, shape (1,)): the demanded power [W] within the building's actuator's bounds
(``env.actuator``, the action space's; clipped). Reward: minus the objective of the interval, i.e.
``-(price x delivered energy [kWh] + comfort_weight x band violation of T_r at the end of the
interval [K] x interval [h])``: :class:`controllers.objective.HorizonObjective` of one interval
against that interval's band, the objective the controllers use. ``info`` carries the
hidden ``T_m`` [C], the true ``T_r`` [C], ``u_phys`` [W], ``overridden`` (the backup acted),
``energy_kwh``, ``cost_eur``, ``discomfort_kh`` and the interval's ``T_a`` [C], ``G`` [W/m2]
and ``I_g`` [W] as the plant had them: on an EnergyPlus building its own weather and the
internal gains that happened, which the observation's ``I_g`` (the frame's: the building's
gains schedule where the scenario says ``gains = "measured"``) does not show.

The exogenous inputs come as a frame (as :meth:`scenarios.inputs.registry.Scenario.exogenous` makes
it); an episode covers ``episode_steps`` consecutive rows. When the frame is longer than an
episode, ``reset`` draws the first row from the environment's own generator, which
``reset(seed=...)`` reseeds; the generator also seeds the sensor noise. The plant is the RC
simulator of ``config.plant`` unless ``plant_settings`` (a scenario's ``plant``, given with its
``sim``) names another kind. On an EnergyPlus building each reset starts a fresh EnergyPlus
run, at a midnight row;
``info`` then has no hidden ``T_m`` (NaN). Call :meth:`close` to end the run's thread; an env
that is dropped or outlives the interpreter without it is closed then, so no EnergyPlus run's
directory is left behind.
"""

from __future__ import annotations

import math
import numbers
import weakref
from typing import Any

import gymnasium as gym
import numpy as np
import pandas as pd

from controllers.base import ControlSpec
from controllers.objective import HorizonObjective, band_violation_k, energy_cost_eur
from pinn_mpc.data import SITE_COLUMNS, TEMPERATURE_RANGE_C, WIND, WIND_RANGE_M_S
from pinn_mpc.simulator import SimConfig
from scenarios.inputs.series import EXOGENOUS_FIELDS, ExogenousSeries
from scenarios.plants.settings import PlantSettings
from scenarios.running.engine import ClosedLoop

__all__ = ["OBSERVATION_NAMES", "BuildingEnv"]

EXOGENOUS = EXOGENOUS_FIELDS
OBSERVATION_NAMES = ("T_r", "T_a", "G", "I_g", "price", "T_min", "T_max", "sin_time", "cos_time")


class BuildingEnv(gym.Env[np.ndarray, np.ndarray]):
    """One simulated building driven by a fixed exogenous frame; see the module docstring."""

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(
        self,
        config: SimConfig,
        exogenous: pd.DataFrame,
        *,
        comfort_weight_eur_per_kh: float,
        episode_steps: int | None = None,
        initial_t_r_c: float = 17.0,
        initial_t_m_c: float = 17.0,
        plant_settings: PlantSettings | None = None,
    ):
        try:
            series = ExogenousSeries.from_frame(exogenous)
        except ValueError as exc:
            raise ValueError(f"BuildingEnv: {exc}") from exc
        if not (math.isfinite(comfort_weight_eur_per_kh) and comfort_weight_eur_per_kh >= 0):
            raise ValueError(
                f"BuildingEnv: comfort_weight_eur_per_kh must be >= 0, got {comfort_weight_eur_per_kh!r}"
            )
        _check_temperature("initial_t_r_c", initial_t_r_c, "BuildingEnv")
        _check_temperature("initial_t_m_c", initial_t_m_c, "BuildingEnv")
        steps = len(exogenous) if episode_steps is None else episode_steps
        if not 1 <= steps <= len(exogenous):
            raise ValueError(
                f"BuildingEnv: episode_steps={episode_steps} must lie in [1, {len(exogenous)}] "
                "(the exogenous frame's rows)"
            )
        self.config = config
        self.comfort_weight_eur_per_kh = float(comfort_weight_eur_per_kh)
        self.episode_steps = steps
        self.initial_state_c = (float(initial_t_r_c), float(initial_t_m_c))
        self._exo = np.column_stack([getattr(series, c) for c in EXOGENOUS])
        # A plant whose runs start at midnight (EnergyPlus): its episodes do too.
        self._starts = (
            np.flatnonzero(np.asarray(series.time_of_day_h) == 0.0)
            if plant_settings is not None and plant_settings.starts_at_midnight
            else np.arange(len(exogenous))
        )
        angle = 2.0 * math.pi * series.time_of_day_h / 24.0
        self._clock = np.column_stack([np.sin(angle), np.cos(angle)])
        site = tuple(name for name in SITE_COLUMNS if getattr(series, name) is not None)
        self.observation_names = (*OBSERVATION_NAMES, *site)
        self._site = np.column_stack(
            [getattr(series, name) for name in site] or [np.empty((len(exogenous), 0))]
        )

        t_lo, t_hi = TEMPERATURE_RANGE_C
        site_low = [0.0] * len(site)
        site_high = [WIND_RANGE_M_S[1] if name == WIND else 2000.0 for name in site]
        low = np.array([t_lo, t_lo, 0.0, 0.0, -10.0, t_lo, t_lo, -1.0, -1.0, *site_low], dtype=np.float32)
        high = np.array([t_hi, t_hi, 2000.0, 1e6, 10.0, t_hi, t_hi, 1.0, 1.0, *site_high], dtype=np.float32)
        self._obs_low, self._obs_high = low, high
        self.observation_space = gym.spaces.Box(low=low, high=high, dtype=np.float32)
        if plant_settings is not None and len(plant_settings.settings.zone_specs) > 1:
            names = ", ".join(z.name for z in plant_settings.settings.zone_specs)
            raise ValueError(
                f"BuildingEnv: its spaces are one zone's and one actuator's; this building has the "
                f"zones {names}: run it with closed-loop's zone controllers (thermostat, oracle)"
            )
        (self.actuator,) = config.actuators
        self.action_space = gym.spaces.Box(
            low=self.actuator.lower_w, high=self.actuator.upper_w, shape=(1,), dtype=np.float32
        )
        spec = ControlSpec(
            actuators=config.actuators,
            dt_s=config.dt_s,
            comfort_weight_eur_per_kh=self.comfort_weight_eur_per_kh,
        )
        try:
            self._loop = ClosedLoop(
                config,
                series,
                spec=spec,
                initial_t_r_c=self.initial_state_c[0],
                initial_t_m_c=self.initial_state_c[1],
                plant_settings=plant_settings,
            )
        except ValueError as exc:
            raise ValueError(f"BuildingEnv: {exc}") from exc
        # Ends a plant's work (an EnergyPlus run's thread and directory) when the env is
        # garbage-collected or the interpreter exits without close().
        self._finalizer = weakref.finalize(self, self._loop.close)

    def _observation(self) -> np.ndarray:
        # After the last interval the next row may not exist: reuse the last row's inputs.
        row = min(self._loop.start + self._loop.k, len(self._exo) - 1)
        raw = np.concatenate(
            [self._loop.measure(), self._exo[row], self._clock[row], self._site[row]]
        )
        return np.clip(raw, self._obs_low, self._obs_high).astype(np.float32)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode; ``options`` may set ``t_r_c``, ``t_m_c`` and ``start`` (row)."""
        super().reset(seed=seed)
        opts = dict(options or {})
        unknown = set(opts) - {"t_r_c", "t_m_c", "start"}
        if unknown:
            raise ValueError(f"BuildingEnv.reset: unknown option(s) {sorted(unknown)}")
        last_start = len(self._exo) - self.episode_steps
        starts = self._starts[self._starts <= last_start]
        if "start" in opts:
            start = opts["start"]
            if isinstance(start, bool) or not isinstance(start, numbers.Integral):
                raise ValueError(
                    f"BuildingEnv.reset: option start={start!r} must be a whole row number "
                    f"in [0, {last_start}]"
                )
        elif starts.size:
            start = int(starts[self.np_random.integers(starts.size)])
        else:
            raise ValueError(
                f"BuildingEnv.reset: no midnight in the first {last_start + 1} rows for an "
                "EnergyPlus run to start at; give a longer exogenous frame"
            )
        if not 0 <= start <= last_start:
            raise ValueError(f"BuildingEnv.reset: start={start} must lie in [0, {last_start}]")
        t_r, t_m = opts.get("t_r_c", self.initial_state_c[0]), opts.get("t_m_c", self.initial_state_c[1])
        _check_temperature("option t_r_c", t_r, "BuildingEnv.reset")
        _check_temperature("option t_m_c", t_m, "BuildingEnv.reset")
        self._loop.reset(t_r, t_m, start=int(start), seed=int(self.np_random.integers(2**63)))
        return self._observation(), {"T_m": float(t_m), "T_r": float(t_r)}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._loop.k >= self.episode_steps:
            raise ValueError("BuildingEnv.step: the episode is over; call reset() first")
        u = float(self.actuator.clip(self._action_w(action)))
        _, _, _, price, t_min, t_max = (float(v) for v in self._exo[self._loop.start + self._loop.k])
        result = self._loop.step(u)
        t_r_next = float(result.t_r_c[0, 0])  # one building, one zone
        u_phys = float(result.u_phys_w[0])
        dt_h = self.config.dt_s / 3600.0
        objective = HorizonObjective(
            price_eur_per_kwh=np.array([price]),
            t_min_c=np.array([t_min]),
            t_max_c=np.array([t_max]),
            dt_h=dt_h,
            comfort_weight_eur_per_kh=self.comfort_weight_eur_per_kh,
        )
        reward = -float(objective.cost(np.array([u_phys]), np.array([t_r_next])))
        truncated = self._loop.k >= self.episode_steps
        info = {
            "T_m": float(result.t_m_c[0, 0]),
            "T_r": t_r_next,
            "u_phys": u_phys,
            "overridden": bool(result.overridden[0]),
            "energy_kwh": u_phys / 1000.0 * dt_h,
            "cost_eur": float(energy_cost_eur(u_phys, price, dt_h)),
            "discomfort_kh": float(band_violation_k(t_r_next, t_min, t_max)) * dt_h,
        }
        info["T_a"], info["G"], info["I_g"] = self._loop.last_means()
        return self._observation(), reward, False, truncated, info

    def _action_w(self, action: np.ndarray) -> float:
        """The demanded power [W] of ``action``, which must hold exactly one finite number."""
        bounds = f"[{self.actuator.lower_w:g}, {self.actuator.upper_w:g}] W"
        try:
            values = np.asarray(action, dtype=float).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise ValueError(
                f"BuildingEnv.step: action {action!r} is not a number; give an array of shape "
                f"(1,) with the demanded power in {bounds}"
            ) from exc
        if values.size != 1:
            raise ValueError(
                f"BuildingEnv.step: action has {values.size} elements, the action space's shape "
                f"is (1,): one demanded power in {bounds}"
            )
        if not math.isfinite(values[0]):
            raise ValueError(
                f"BuildingEnv.step: action {values[0]!r} is not finite; give a demanded power in "
                f"{bounds}"
            )
        return float(values[0])

    def close(self) -> None:
        """End the plant's work (an EnergyPlus run's thread and files); the RC simulator has none."""
        self._finalizer()
        super().close()


def _check_temperature(name: str, value: object, where: str) -> None:
    """Refuse a start temperature that is not a finite number in the plausible range."""
    lo, hi = TEMPERATURE_RANGE_C
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if not (ok and math.isfinite(float(value)) and lo <= float(value) <= hi):  # type: ignore[arg-type]
        raise ValueError(
            f"{where}: {name}={value!r} must be a finite temperature in [{lo:g}, {hi:g}] C"
        )
