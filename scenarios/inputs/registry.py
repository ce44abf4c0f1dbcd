"""Named scenarios: building, actuator, backup thermostat, weather, price, comfort, gains.

A :class:`Scenario` is an immutable description; :meth:`Scenario.exogenous` turns it into the
exogenous frame of a run (deterministic in the seed and the weather part) and
:meth:`Scenario.control_spec` into the objective every controller shares. Each built-in's
description ends with its weather split (:attr:`Scenario.weather_split`): training and test
runs never share a calendar day (see :mod:`scenarios.inputs.exogenous`).

The comfort weights price discomfort well above the energy it would take to avoid it: in
``winter_household`` keeping the room 1 K warmer for an hour costs about UA x 1 K x 1 h =
0.27 kWh, i.e. under 0.1 EUR at the dynamic price, while 1 K h of discomfort costs 5 EUR.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from dataclasses import dataclass, field
from typing import Any, Literal, cast

import numpy as np
import pandas as pd

from controllers.base import ControlSpec
from pinn_mpc.actuator import Actuator, ActuatorSpec
from pinn_mpc.data import WIND
from pinn_mpc.errors import InputError
from pinn_mpc.multizone import MultiZoneParams
from pinn_mpc.physics import PAPER_HOUSEHOLD, RCParams
from pinn_mpc.simulator import SimConfig
from pinn_mpc.solar import FACADE_COLUMNS
from scenarios.inputs.exogenous import (
    ComfortSchedule,
    GainsSchedule,
    PriceProfile,
    SyntheticWeather,
    TMY3Weather,
    steps_per_day,
    tmy3_path,
    weather_part,
)
from scenarios.inputs.measured import CSVWeather, PriceCSV
from scenarios.inputs.series import ForecastErrors
from scenarios.inputs.zoned import (
    SHOULDER_OFFICE,
    SHOULDER_OFFICE_ACTUATORS,
    TWO_ZONE_HOUSE,
    TWO_ZONE_HOUSE_ACTUATORS,
)
from scenarios.plants.energyplus.settings import (
    DATA_POLICY,
    NOMINAL_BUILDING,
    WEATHER_WINDOW,
    ZONE_CHILLER,
    EnergyPlusSettings,
    WeatherWindow,
    season_window,
)
from scenarios.plants.multizone import MultiZoneSettings
from scenarios.plants.rc import RCSettings
from scenarios.plants.settings import PlantSettings

__all__ = [
    "COLD_ROOM",
    "ENERGYPLUS_DATA_POLICY",
    "EPLUS_NOMINAL",
    "eplus_weather",
    "with_sized_heater",
    "EXOGENOUS_COLUMNS",
    "INITIAL_TEMPERATURE_RANGE_C",
    "Scenario",
    "check_seed",
    "builtin_scenario",
    "is_scenario_file",
    "scenario_names",
]

#: Plausible starting temperatures of a building's room and mass [C] (a cold store at -40 C
#: to a sauna); beyond them a value is a typo or another unit.
INITIAL_TEMPERATURE_RANGE_C = (-50.0, 80.0)
#: The training-data policy of EnergyPlus scenarios (:attr:`Scenario.data_policy`): random
#: setpoints tracked, which keep the room inside the 14/28 C backup thermostat's band.
ENERGYPLUS_DATA_POLICY = DATA_POLICY
#: Columns of :meth:`Scenario.exogenous`, in order.
EXOGENOUS_COLUMNS = ("time", "T_a", "G", "I_g", "price", "T_min", "T_max")
# Independent random streams per input, so changing one input's settings leaves the others.
_WEATHER_STREAM, _PRICE_STREAM, _GAINS_STREAM = 1, 2, 3
# Test runs draw from streams of their own: the same seed never repeats a training draw (on
# stationary synthetic weather only the dates would differ otherwise).
_TEST_PART_STREAM = 1


@dataclass(frozen=True, kw_only=True)
class Scenario:
    """A named experiment setting. ``sim`` holds the building, actuator limit, control interval,
    substep, backup-thermostat limits and sensor noise; ``plant`` the plant's kind and settings
    (``sim.plant`` is set from it: the structure the RC simulator integrates); the rest
    describes the exogenous inputs and (``forecast``) what the controllers' forecasts get
    wrong."""

    name: str
    description: str
    sim: SimConfig
    plant: PlantSettings = field(default_factory=PlantSettings)
    comfort_weight_eur_per_kh: float
    horizon_steps: int = 48
    initial_t_r_c: float
    initial_t_m_c: float
    weather: SyntheticWeather | TMY3Weather | CSVWeather
    price: PriceProfile | PriceCSV
    comfort: ComfortSchedule
    gains: GainsSchedule = field(default_factory=GainsSchedule)
    forecast: ForecastErrors = field(default_factory=ForecastErrors)
    #: The policy of the scenario's training data when none is asked for (``simulate``,
    #: ``compare``; :mod:`scenarios.running.datagen`): uniform random levels on the RC plants,
    #: ``closed-loop`` (random setpoints tracked) on EnergyPlus, where random levels overheat
    #: the room into the backup thermostat, which then cuts the heat inside intervals.
    data_policy: Literal["random", "random-level", "closed-loop"] = "random-level"

    def __post_init__(self) -> None:
        if self.sim.plant != self.plant.rc:  # the simulator's structure follows the plant's kind
            object.__setattr__(self, "sim", dataclasses.replace(self.sim, plant=self.plant.rc))
        steps_per_day(self.sim.dt_s)
        if not (math.isfinite(self.comfort_weight_eur_per_kh) and self.comfort_weight_eur_per_kh >= 0):
            raise InputError(
                f"Scenario {self.name!r}: comfort_weight_eur_per_kh must be >= 0, "
                f"got {self.comfort_weight_eur_per_kh!r}"
            )
        if self.horizon_steps < 1:
            raise InputError(f"Scenario {self.name!r}: horizon_steps must be >= 1, got {self.horizon_steps}")
        lo, hi = INITIAL_TEMPERATURE_RANGE_C
        for key in ("initial_t_r_c", "initial_t_m_c"):
            value = getattr(self, key)
            if not (math.isfinite(value) and lo <= value <= hi):
                raise InputError(
                    f"Scenario.{key} = {value:g} C is outside the plausible {lo:g} .. {hi:g} C of "
                    "a building's starting temperature; give it in Celsius"
                )
        if self.plant.settings.weather_file is not None:
            self._check_own_weather(self.plant.settings.weather_file)

    def _check_own_weather(self, plant_weather: str) -> None:
        """A plant with a weather file of its own (an EnergyPlus building) brings its own
        internal gains too: the scenario's weather must be that file (the controllers'
        forecasts), its gains none."""
        weather = self.weather
        same = isinstance(weather, TMY3Weather) and (
            weather.file_name == plant_weather
            or str(tmy3_path(weather.file_name)) == str(tmy3_path(plant_weather))
        )
        if not same:
            raise InputError(
                f"Scenario {self.name!r}: the EnergyPlus plant runs on weather {plant_weather!r}, "
                "so [weather] must be a TMY3Weather of the same file (leave weather.file_name "
                "out to use the plant's, or [weather] out to get it with a January / February split)"
            )
        if self.gains.active:
            raise InputError(
                f"Scenario {self.name!r}: an EnergyPlus building has its own internal gains; "
                "leave [gains] out"
            )
        if self.plant.settings.measured_gains and not self.forecast.gains_known:
            raise InputError(
                f"Scenario {self.name!r}: simulation.plant.gains = \"measured\" makes the "
                "building's gains known, but forecast.gains_known = false hides them; give one"
            )

    @property
    def steps_per_day(self) -> int:
        return steps_per_day(self.sim.dt_s)

    @property
    def band_setpoint_c(self) -> float:
        """The comfort band's highest lower bound over a day (a cooled building: its lowest
        upper bound), where an EnergyPlus plant's heater is sized and its gains schedule is
        evaluated."""
        day = pd.date_range("2001-01-01", periods=self.steps_per_day, freq=f"{int(self.sim.dt_s)}s")
        t_min, t_max = self.comfort.sample(day)
        return float(np.max(t_min)) if self.sim.params.heating else float(np.min(t_max))

    @property
    def band_limits_c(self) -> tuple[float, float]:
        """The comfort band's highest lower bound and lowest upper bound over a day [C]: where
        a building's heaters and its coolers are sized."""
        day = pd.date_range("2001-01-01", periods=self.steps_per_day, freq=f"{int(self.sim.dt_s)}s")
        t_min, t_max = self.comfort.sample(day)
        return float(np.max(t_min)), float(np.min(t_max))

    @property
    def reference(self) -> Literal["oracle", "thermostat"]:
        """The controller every other is measured against: the oracle on a plant with true
        parameters and state, the thermostat on one without (EnergyPlus), where no oracle
        exists."""
        return "oracle" if self.plant.true_state else "thermostat"

    @property
    def uses_solar(self) -> bool:
        return self.sim.params.solar_aperture_m2 > 0

    @property
    def gains_given(self) -> bool:
        """Whether the controllers are given the building's internal gains (its data carry an
        ``I_g`` column): a simulated building's own gains, or a plant's measured ones; not an
        EnergyPlus building's unmeasured gains."""
        return self.gains.active or self.plant.settings.measured_gains

    @property
    def gains_hidden(self) -> bool:
        """Whether the building has internal gains its controllers are not given (an EnergyPlus
        building's, unmeasured)."""
        return self.plant.settings.own_gains and not self.plant.settings.measured_gains

    @property
    def weather_split(self) -> str:
        """One sentence: the calendar days of the training and the test part."""
        return self.weather.split_text()

    def exogenous(self, *, days: int, seed: int, part: str, lead_steps: int = 0) -> pd.DataFrame:
        """Exogenous inputs of a run: ``days * steps_per_day + lead_steps`` rows.

        Columns ``time`` (datetime64, interval start), ``T_a`` [C], ``G`` [W/m2], ``I_g`` [W],
        ``price`` [EUR/kWh], ``T_min``/``T_max`` [C]; for an EnergyPlus plant also the
        irradiance on its site's facades (:data:`pinn_mpc.solar.FACADE_COLUMNS` [W/m2], from
        the plant's weather file, :meth:`scenarios.inputs.exogenous.TMY3Weather.facades`), its wind speed
        (``wind`` [m/s], :meth:`scenarios.inputs.exogenous.TMY3Weather.wind`) and ``holiday``
        (1 on the building's holidays, :func:`scenarios.plants.energyplus.schedules.holidays`). ``part`` is the weather part the run is
        drawn from (``train``, ``test`` or ``whole``, see :mod:`scenarios.inputs.exogenous`); a run that
        does not fit in its part raises InputError. The ``lead_steps`` extra rows at the end
        give a controller at the last step a full-horizon forecast; with ``whole`` they never
        change the first rows, in a part they are placed inside it too. Same seed and part ->
        identical frame; ``test`` draws every random input from streams of its own.
        ``attrs['dt_s']`` is the control interval.
        """
        if days < 1:
            raise ValueError(f"scenario {self.name!r}: days must be >= 1, got {days}")
        if lead_steps < 0:
            raise ValueError(f"scenario {self.name!r}: lead_steps must be >= 0, got {lead_steps}")
        check_seed(seed)
        chosen = weather_part(part)
        extra = (_TEST_PART_STREAM,) if chosen == "test" else ()

        def rng(stream: int) -> np.random.Generator:
            return np.random.default_rng([seed, stream, *extra])

        dt_s = self.sim.dt_s
        n = days * self.steps_per_day + lead_steps
        try:
            times, t_a, g = self.weather.sample(
                n=n, dt_s=dt_s, run_days=days, part=chosen, rng=rng(_WEATHER_STREAM)
            )
        except InputError as exc:
            raise InputError(f"scenario {self.name!r}: {exc.marked}") from None
        price = self.price.sample(times, dt_s=dt_s, rng=rng(_PRICE_STREAM))
        i_g = self.gains.sample(times, rng=rng(_GAINS_STREAM))
        plant = self.plant
        scheduled = plant.settings.scheduled_gains(  # a plant whose gains are measured: its own schedules'
            times.to_numpy(), setpoint_c=self.band_setpoint_c, dt_s=dt_s, heat_per_w=self.sim.params.eta,
        )
        if scheduled is not None:
            i_g = scheduled
        t_min, t_max = self.comfort.sample(times)
        frame = pd.DataFrame(
            {
                "time": times,
                "T_a": t_a,
                "G": g,
                "I_g": i_g,
                "price": price,
                "T_min": t_min,
                "T_max": t_max,
            }
        )
        if plant.settings.needs_facades and plant.settings.weather_file is None:
            if not isinstance(self.weather, TMY3Weather):
                raise InputError(
                    f"scenario {self.name!r}: the building's windows take facade irradiance "
                    "(a zone's solar_input), which comes from a TMY3 weather file; give [weather] one"
                )
            facades = self.weather.facades(times, dt_s=dt_s)
            for name in FACADE_COLUMNS:
                frame[name] = facades[name]
        if plant.settings.weather_file is not None:  # the plant's EPW (checked): its facades' irradiance and wind too
            epw = cast(TMY3Weather, self.weather)
            facades = epw.facades(times, dt_s=dt_s)
            for name in FACADE_COLUMNS:
                frame[name] = facades[name]
            frame[WIND] = epw.wind(times, dt_s=dt_s)
        holiday = plant.settings.holidays(times.to_numpy())  # the plant kind's calendar, if any
        if holiday is not None:
            frame["holiday"] = holiday
        frame.attrs["dt_s"] = float(dt_s)
        return frame

    def control_spec(self) -> ControlSpec:
        """The objective and the actuators (``sim.actuators``) every controller of this scenario
        shares."""
        settings = self.plant.settings
        return ControlSpec(
            actuators=settings.own_actuators or self.sim.actuators,
            zones=settings.zone_specs,
            dt_s=self.sim.dt_s,
            horizon_steps=self.horizon_steps,
            comfort_weight_eur_per_kh=self.comfort_weight_eur_per_kh,
            sensor_noise_std_c=self.sim.noise_std_c,
        )


def check_seed(seed: int) -> None:
    """Seeds feed ``np.random.default_rng``, which needs a non-negative integer."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be a non-negative whole number, got {seed!r}")


#: Cold room of about 50 m2: well insulated (UA 80 W/K), racks and air in C_r, about 14 t of
#: stored goods in C_m, a cooling machine with COP 2.5 (eta = -2.5 per electrical watt).
COLD_ROOM = RCParams(
    r_ra_k_per_w=1.0 / 80.0,
    r_rm_k_per_w=1.0 / 500.0,
    c_r_j_per_k=3.0e6,
    c_m_j_per_k=5.0e7,
    eta=-2.5,
    gain_to_air_fraction=0.8,
)

#: What the controllers' side of a scenario assumes of an EnergyPlus building (its kind's
#: :data:`scenarios.plants.energyplus.settings.NOMINAL_BUILDING`).
EPLUS_NOMINAL = NOMINAL_BUILDING


_SIZING_REPORTED: set[str] = set()
_LOG = logging.getLogger(__name__)


def with_sized_heater(scenario: Scenario, *, given_u_max_w: float | None = None) -> Scenario:
    """The scenario of an EnergyPlus plant with ``heater_w = "auto"``, its ``u_max_w`` the
    heater :func:`scenarios.plants.energyplus.sizing.size_heater` finds for it: holding the comfort band's
    highest lower bound (a chiller, ``eta < 0``: its lowest upper bound) through the weather
    file's coldest (hottest) three days. A plant that sizes its own actuators (an EnergyPlus
    building whose zones are each controlled: each zone's heater and chiller,
    :func:`scenarios.plants.energyplus.sizing.size_zones`) gets them in its settings, the
    heaters at the band's highest lower bound and the coolers at its lowest upper bound, and
    ``u_max_w`` their heaters' total. A note (``logging``, level INFO) says what was sized
    (once per process). A ``given_u_max_w`` must be that value (a file ``scenario export`` wrote)."""
    sim, settings = scenario.sim, scenario.plant.settings
    if settings.sizes_own_actuators:  # each of the plant's own actuators, into its settings
        heating_c, cooling_c = scenario.band_limits_c
        settings, sizings = settings.size_own_actuators(heating_c=heating_c, cooling_c=cooling_c, dt_s=sim.dt_s)
        own = settings.own_actuators or ()
        heaters_w = sum(a.upper_w for a in own if a.heats) or sum(a.upper_w for a in own)
        scenario = dataclasses.replace(scenario, plant=dataclasses.replace(scenario.plant, settings=settings))
    else:
        sizings = (settings.size_actuator(scenario.band_setpoint_c, heat_per_w=sim.params.eta, dt_s=sim.dt_s),)
        heaters_w = sizings[0].power_w
    if given_u_max_w is not None and abs(given_u_max_w - heaters_w) > 1e-6 * heaters_w:
        raise InputError(
            f"simulation.u_max_w = {given_u_max_w:g} W, but plant.heater_w = \"auto\" sizes "
            f"{heaters_w:g} W; give the heater's power once (a number in heater_w, or "
            "leave u_max_w out)"
        )
    for sizing in sizings:
        line = f"scenario {scenario.name!r}: {sizing.line()}"
        if line not in _SIZING_REPORTED:
            _SIZING_REPORTED.add(line)
            _LOG.info(line)
    return dataclasses.replace(scenario, sim=dataclasses.replace(sim, u_max_w=heaters_w))


def eplus_weather(file_name: str) -> TMY3Weather:
    """The weather of an EnergyPlus scenario: the plant's EPW, January and February, trained
    on January (a longer training run reaches back into December), tested on February
    (:data:`scenarios.plants.energyplus.settings.WEATHER_WINDOW`)."""
    return TMY3Weather(file_name=file_name, **WEATHER_WINDOW)


def _with_split(scenario: Scenario) -> Scenario:
    """The scenario with its weather split appended to the description."""
    return dataclasses.replace(
        scenario, description=f"{scenario.description} {scenario.weather_split}"
    )


_SCENARIOS: dict[str, Scenario] = {
    s.name: _with_split(s)
    for s in (
        Scenario(
            name="paper_household",
            description=(
                "The paper's simulated household: default 2R2C, electric heater 0-5000 W, backup "
                "17/20.5 C, synthetic spring weather, no solar or internal gains, T_r=T_m=17 C at "
                "start, day/night price, comfort 18-20.5 C."
            ),
            sim=SimConfig(params=PAPER_HOUSEHOLD, u_max_w=5000.0, backup_low_c=17.0, backup_high_c=20.5),
            comfort_weight_eur_per_kh=5.0,
            initial_t_r_c=17.0,
            initial_t_m_c=17.0,
            # Peaks stay near 24 C: with the room held at 20.5 C by the backup, a warmer
            # afternoon would push T_r past the backup's upper limit (it cannot cool).
            weather=SyntheticWeather(
                mean_c=14.5, daily_amplitude_c=4.0, slow_amplitude_c=3.5, noise_std_c=0.6
            ),
            price=PriceProfile(kind="day_night", level_eur_per_kwh=0.30, night_eur_per_kwh=0.15),
            comfort=ComfortSchedule(day_min_c=18.0, day_max_c=20.5, night_min_c=18.0, night_max_c=20.5),
        ),
        Scenario(
            name="winter_household",
            description=(
                "The paper's household with 3 m2 of solar aperture (30 % to the air), occupancy "
                "gains, a 10 kW heater (enough for the coldest TMY3 hours), real TMY3 winter "
                "weather (Greensboro NC, Nov-Mar), a dynamic price, comfort 20-22 C 07-22 h and "
                "17-22 C at night, backup 16/24 C."
            ),
            sim=SimConfig(
                params=dataclasses.replace(
                    PAPER_HOUSEHOLD,
                    solar_aperture_m2=3.0,
                    solar_to_air_fraction=0.3,
                    gain_to_air_fraction=0.5,
                ),
                u_max_w=10000.0,
                backup_low_c=16.0,
                backup_high_c=24.0,
            ),
            comfort_weight_eur_per_kh=5.0,
            initial_t_r_c=20.0,
            initial_t_m_c=20.0,
            # Trained on the first three months of the heating season, tested on the last two (a
            # model fitted on the season so far, then used): February keeps cold test days
            # (mean 5.0 C against 0.3 C in January and 11.4 C in March), and 59 test days hold
            # a 57-day closed-loop run. 120 training days reach back into October.
            weather=TMY3Weather(
                file_name="723170TYA.CSV",
                window_start="11-01",
                window_days=151,
                test_start="02-01",
                test_days=59,
            ),
            price=PriceProfile(kind="dynamic", level_eur_per_kwh=0.22, peak_eur_per_kwh=0.15),
            comfort=ComfortSchedule(day_min_c=20.0, day_max_c=22.0, night_min_c=17.0, night_max_c=22.0),
            gains=GainsSchedule(base_w=100.0, scheduled_w=400.0, periods_h=((6.0, 8.5), (17.0, 23.0))),
        ),
        Scenario(
            name="cold_storage",
            description=(
                "A cold room (UA 80 W/K) cooled by a 2.5 kW (electrical) machine with COP 2.5, "
                "band 2-6 C, backup 0/8 C, TMY3 summer weather (Greensboro NC, Jun-Aug), door "
                "openings 07-19 h, day/night price, no windows."
            ),
            sim=SimConfig(params=COLD_ROOM, u_max_w=2500.0, backup_low_c=0.0, backup_high_c=8.0),
            comfort_weight_eur_per_kh=10.0,
            initial_t_r_c=4.0,
            initial_t_m_c=4.0,
            # Tested on the last five weeks of summer (August is nearly as hot as July: 24.8 C
            # against 25.4 C mean), enough for a 33-day closed-loop run; training on June and
            # July, reaching back into May (60 days) or March (120 days) for longer runs.
            weather=TMY3Weather(
                file_name="723170TYA.CSV",
                window_start="06-01",
                window_days=92,
                test_start="07-28",
                test_days=35,
            ),
            price=PriceProfile(kind="day_night", level_eur_per_kwh=0.25, night_eur_per_kwh=0.12),
            comfort=ComfortSchedule(day_min_c=2.0, day_max_c=6.0, night_min_c=2.0, night_max_c=6.0),
            gains=GainsSchedule(
                base_w=150.0, periods_h=((7.0, 19.0),), event_w=2500.0, event_probability=0.3
            ),
        ),
    )
}



def _winter_variant(
    name: str, description: str, *, plant: PlantSettings | None = None, **sim_changes: Any
) -> Scenario:
    """winter_household with other simulation settings or another plant (its weather, price,
    comfort, gains)."""
    base = _SCENARIOS["winter_household"]
    return _with_split(
        dataclasses.replace(
            base,
            name=name,
            description=description,
            sim=dataclasses.replace(base.sim, **sim_changes),
            plant=base.plant if plant is None else plant,
        )
    )


_SCENARIOS.update(
    (s.name, s)
    for s in (
        _winter_variant(
            "heat_pump_household",
            "winter_household heated by an air-source heat pump of 4 kW electrical (COP = 45 % "
            "of Carnot to a 35 C supply, clipped to 1..6: about 4.0 at 0 C, 3.1 at -10 C), "
            "minimum modulation 30 % (a lower demand runs at 30 % or is off, whichever is "
            "nearer); power, energy and cost are electrical.",
            u_max_w=4000.0,
            actuator=Actuator(
                kind="heat_pump",
                supply_temp_c=35.0,
                carnot_efficiency=0.45,
                cop_min=1.0,
                cop_max=6.0,
                min_modulation=0.3,
            ),
        ),
        _winter_variant(
            "mismatch_household",
            "winter_household on a 3R3C plant the models cannot represent: R_ra split in halves "
            "at an envelope node of 1e7 J/K (outer wall layers; a third time constant of 2.6 h, "
            "same steady state). Models, RC MPCs and the oracle are 2R2C; the oracle plans on the "
            "plant's R/C without the envelope (the 2R2C it reduces to as C_e -> 0) with the true "
            "T_r and T_m, so it is no longer a lower bound, nor is the clairvoyant.",
            plant=PlantSettings(
                kind="3r3c",
                settings=RCSettings(envelope_capacity_j_per_k=1.0e7, envelope_resistance_fraction=0.5),
            ),
        ),
    )
)


def _energyplus_scenario(
    *,
    name: str,
    description: str,
    building: str,
    weather: str,
    heater_w: float,
    initial_t_r_c: float,
    comfort: ComfortSchedule,
    settings: EnergyPlusSettings | None = None,
    window: WeatherWindow = WEATHER_WINDOW,
    data_policy: Literal["random", "random-level", "closed-loop"] = ENERGYPLUS_DATA_POLICY,
) -> Scenario:
    """A built-in EnergyPlus scenario: the bundled ``building`` in the bundled ``weather``,
    heated by an ideal ``heater_w`` electric heater (``settings``: the plant's, its actuators
    of its own), backup 14/28 C, winter_household's dynamic price, January to train and
    February to test (:func:`eplus_weather`; ``window``: another part of the year), its
    training data ``data_policy``'s."""
    return _with_split(
        Scenario(
            name=name,
            description=description,
            sim=SimConfig(
                params=EPLUS_NOMINAL,
                u_max_w=heater_w,
                backup_low_c=14.0,
                backup_high_c=28.0,
            ),
            plant=PlantSettings(
                kind="energyplus",
                settings=settings or EnergyPlusSettings(building=building, weather=weather, heater_w=heater_w),
            ),
            comfort_weight_eur_per_kh=5.0,
            initial_t_r_c=initial_t_r_c,
            initial_t_m_c=initial_t_r_c,
            data_policy=data_policy,
            weather=TMY3Weather(file_name=weather, **window),
            price=PriceProfile(kind="dynamic", level_eur_per_kwh=0.22, peak_eur_per_kwh=0.15),
            comfort=comfort,
        )
    )


_SCENARIOS["eplus_small_office"] = _energyplus_scenario(
    name="eplus_small_office",
    description=(
        "DOE's small office (EnergyPlus reference building, 511 m2) in Chicago (TMY3), its "
        "HVAC removed, its five conditioned zones merged into one, heated by an ideal 25 kW "
        "electric heater; run by EnergyPlus (no R/C parameters, no oracle). Office comfort "
        "20-23 C 07-19 h, 16-25 C otherwise, winter_household's dynamic "
        "price, backup 14/28 C; the office's internal gains are unmeasured."
    ),
    building="small_office",
    weather="usa_il_chicago",
    heater_w=25000.0,
    initial_t_r_c=20.0,
    comfort=ComfortSchedule(
        day_min_c=20.0, day_max_c=23.0, night_min_c=16.0, night_max_c=25.0,
        day_start_h=7.0, day_end_h=19.0,
    ),
)
_SCENARIOS["eplus_midrise_apartment"] = _energyplus_scenario(
    name="eplus_midrise_apartment",
    description=(
        "DOE's mid-rise apartment building (EnergyPlus reference building, four floors, "
        "3,135 m2; merged, its middle floor, which stands for two, counts once: 2,351 m2) in "
        "Denver (TMY3), its HVAC removed, its conditioned zones merged into one, "
        "heated by an ideal 71 kW electric heater (what heater_w = \"auto\" sizes for it); "
        "run by EnergyPlus (no R/C parameters, no "
        "oracle). Residential comfort 20-24 C 06-23 h, 18-24 C at night, winter_household's "
        "dynamic price, backup 14/28 C; the residents' internal gains are unmeasured. A "
        "second building and city, not the one the package's EnergyPlus defaults were "
        "tuned on."
    ),
    building="midrise_apartment",
    weather="usa_co_denver",
    heater_w=71000.0,
    initial_t_r_c=21.0,
    comfort=ComfortSchedule(
        day_min_c=20.0, day_max_c=24.0, night_min_c=18.0, night_max_c=24.0,
        day_start_h=6.0, day_end_h=23.0,
    ),
)


#: The small office's zones' heaters and chillers (electrical) [W], in its zones' order
#: (Core_ZN, Perimeter_ZN_1 .. 4): what heater_w and chiller_w = "auto" size for them at
#: 21 C (6-8 January) and 24 C (16-18 July) in Chicago.
_OFFICE_ZONE_HEATERS_W = (4600.0, 5600.0, 3800.0, 5800.0, 3700.0)
_OFFICE_ZONE_CHILLERS_W = (900.0, 1100.0, 800.0, 1000.0, 1000.0)
#: The comfort band of the offices of zones, in every zone.
_OFFICE_ZONE_COMFORT = ComfortSchedule(
    day_min_c=21.0, day_max_c=24.0, night_min_c=16.0, night_max_c=27.0, day_start_h=7.0, day_end_h=19.0,
)
#: The seasons of the small office of zones: a built-in each (the first without a suffix).
_OFFICE_ZONE_SEASONS = ("january", "april", "july")


def _office_zones(season: str) -> Scenario:
    """eplus_small_office with its five zones kept, heated and cooled each on its own, tested
    on ``season`` (a month: :func:`season_window`)."""
    def name(month: str) -> str:
        return "eplus_small_office_zones" + ("" if month == _OFFICE_ZONE_SEASONS[0] else f"_{month}")

    others = [s for s in _OFFICE_ZONE_SEASONS if s != season]
    return _energyplus_scenario(
        name=name(season),
        description=(
            "DOE's small office (EnergyPlus reference building, 511 m2) in Chicago (TMY3), its "
            "HVAC removed, its five conditioned zones kept (Core_ZN, Perimeter_ZN_1-4), each "
            "with an ideal electric heater and an ideal chiller of its own (heat_<zone>, "
            "cool_<zone>: ten actuators; heaters 3.7-5.8 kW, 23.5 kW in all, chillers 0.8-1.1 "
            "kW electrical, 4.8 kW, EER 4.8 at 30 C: what \"auto\" sizes for 21 and 24 C); run "
            "by EnergyPlus (no R/C parameters, no oracle). Office comfort 21-24 C 07-19 h, "
            "16-27 C otherwise, in every zone; winter_household's dynamic price, backup 14/28 C "
            "per actuator on its zone; the office's internal gains are unmeasured. "
            f"Season: {season.capitalize()} (in {' and '.join(m.capitalize() for m in others)}: "
            f"{' and '.join(map(name, others))}; a scenario file takes [weather] "
            "season = \"<month>\")."
        ),
        building="small_office",
        weather="usa_il_chicago",
        heater_w=sum(_OFFICE_ZONE_HEATERS_W),
        initial_t_r_c=21.0,
        comfort=_OFFICE_ZONE_COMFORT,
        settings=EnergyPlusSettings(
            building="small_office", weather="usa_il_chicago", zones="controlled",
            heater_w=_OFFICE_ZONE_HEATERS_W, chiller_w=_OFFICE_ZONE_CHILLERS_W, chiller=ZONE_CHILLER,
        ),
        window=season_window(season),
        # Each zone's setpoints tracked (random levels drive the rooms into the backup's
        # 14/28 C in three intervals of four).
    )


_SCENARIOS.update((s.name, s) for s in map(_office_zones, _OFFICE_ZONE_SEASONS))

#: The medium office's zones' heaters and chillers (electrical) [W], in its zones' order
#: (Core_bottom, Core_mid, Core_top, then each storey's Perimeter_<storey>_ZN_1 .. 4): what
#: heater_w and chiller_w = "auto" size for them at 21 C (6-8 January) and 24 C (16-18 July)
#: in Chicago.
_MEDIUM_OFFICE_ZONE_HEATERS_W = (
    1100.0, 900.0, 25900.0,
    10000.0, 7000.0, 10400.0, 6900.0,
    10000.0, 7100.0, 10600.0, 7000.0,
    15900.0, 10800.0, 16400.0, 10700.0,
)
_MEDIUM_OFFICE_ZONE_CHILLERS_W = (
    7300.0, 5900.0, 7600.0,
    2800.0, 2100.0, 2000.0, 2700.0,
    3200.0, 2400.0, 2400.0, 3000.0,
    3500.0, 2400.0, 2800.0, 3300.0,
)
_SCENARIOS["eplus_medium_office_zones"] = _energyplus_scenario(
    name="eplus_medium_office_zones",
    description=(
        "DOE's medium office (EnergyPlus reference building, three storeys, 4,982 m2) in "
        "Chicago (TMY3), its HVAC removed, its 15 conditioned zones kept (each storey's core "
        "and four perimeter zones; its three plenums unconditioned, not zones of the "
        "building), each with an ideal electric heater and an ideal chiller of its own "
        "(heat_<zone>, cool_<zone>: 30 actuators; heaters 0.9-25.9 kW, 150.7 kW in all, "
        "chillers 2.0-7.6 kW electrical, 53.4 kW, EER 4.8 at 30 C: what \"auto\" sizes for 21 "
        "and 24 C); run by EnergyPlus (no R/C parameters, no oracle). Office comfort 21-24 C "
        "07-19 h, 16-27 C otherwise, in every zone; winter_household's dynamic price, backup "
        "14/28 C per actuator on its zone; the office's internal gains are unmeasured. "
        "Season: January (a scenario file takes [weather] season = \"<month>\")."
    ),
    building="medium_office",
    weather="usa_il_chicago",
    heater_w=sum(_MEDIUM_OFFICE_ZONE_HEATERS_W),
    initial_t_r_c=21.0,
    comfort=_OFFICE_ZONE_COMFORT,
    settings=EnergyPlusSettings(
        building="medium_office", weather="usa_il_chicago", zones="controlled",
        heater_w=_MEDIUM_OFFICE_ZONE_HEATERS_W, chiller_w=_MEDIUM_OFFICE_ZONE_CHILLERS_W,
        chiller=ZONE_CHILLER,
    ),
    window=season_window("january"),
)


def _zoned_scenario(
    *, name: str, description: str, building: MultiZoneParams, actuators: tuple[ActuatorSpec, ...], **fields: Any
) -> Scenario:
    """A built-in scenario of a building of several zones (:mod:`scenarios.inputs.zoned`) on
    the multi-zone RC plant: its nominal one-zone view is the building with its zones merged
    (:meth:`MultiZoneParams.lumped`), heated by all its heaters at once."""
    heaters_w = sum(a.upper_w for a in actuators if a.heats)
    return _with_split(
        Scenario(
            name=name,
            description=description,
            sim=SimConfig(params=building.lumped(), u_max_w=heaters_w, **fields.pop("sim")),
            plant=PlantSettings(kind="multizone", settings=MultiZoneSettings(building=building, actuators=actuators)),
            **fields,
        )
    )


_SCENARIOS["two_zone_house"] = _zoned_scenario(
    name="two_zone_house",
    description=(
        "winter_household's house in two zones coupled through an internal wall of 40 W/K: "
        "a south zone whose 6 m2 of glazing (aperture 3 m2, 30 % to the air) take the south "
        "facade's irradiance and a north zone without, each a half of the house with its own "
        "5 kW electric heater; each zone judged against the comfort band (20-22 C 07-22 h, "
        "17-22 C at night), winter_household's weather, price and gains (split evenly), "
        "backup 16/24 C per zone."
    ),
    building=TWO_ZONE_HOUSE,
    actuators=TWO_ZONE_HOUSE_ACTUATORS,
    sim={"backup_low_c": 16.0, "backup_high_c": 24.0},
    comfort_weight_eur_per_kh=5.0,
    initial_t_r_c=20.0,
    initial_t_m_c=20.0,
    weather=_SCENARIOS["winter_household"].weather,
    price=_SCENARIOS["winter_household"].price,
    comfort=_SCENARIOS["winter_household"].comfort,
    gains=_SCENARIOS["winter_household"].gains,
)
_SCENARIOS["shoulder_office"] = _zoned_scenario(
    name="shoulder_office",
    description=(
        "A small office of two 150 m2 perimeter zones, east and west (8 m2 of glazing each, "
        "taking its facade's irradiance), coupled through an open-plan partition of 150 W/K, "
        "each with a 3 kW electric heater and a 1 kW chiller (EER 4.8 at 30 C, 6 below 24 C): "
        "spring (TMY3 Greensboro NC, March-May), whose days can need heat in the morning and "
        "cooling in the afternoon. Office comfort 21-24 C 07-19 h, 16-28 C otherwise; occupancy 3 kW "
        "07-19 h on 400 W, split evenly; day/night price; backup 14/30 C per zone."
    ),
    building=SHOULDER_OFFICE,
    actuators=SHOULDER_OFFICE_ACTUATORS,
    sim={"backup_low_c": 14.0, "backup_high_c": 30.0},
    comfort_weight_eur_per_kh=5.0,
    initial_t_r_c=21.0,
    initial_t_m_c=21.0,
    # Tested on April to early May, trained on March (heating weeks) and the rest of May
    # (cooling weeks): the test weeks range from heating-only to cooling-only, with days
    # that need both between.
    weather=TMY3Weather(
        file_name="723170TYA.CSV", window_start="03-01", window_days=92, test_start="04-01", test_days=35
    ),
    price=PriceProfile(kind="day_night", level_eur_per_kwh=0.25, night_eur_per_kwh=0.12),
    comfort=ComfortSchedule(
        day_min_c=21.0, day_max_c=24.0, night_min_c=16.0, night_max_c=28.0, day_start_h=7.0, day_end_h=19.0
    ),
    gains=GainsSchedule(base_w=400.0, scheduled_w=3000.0, periods_h=((7.0, 19.0),)),
)


def scenario_names() -> list[str]:
    """Names of the registered scenarios, sorted."""
    return sorted(_SCENARIOS)


def is_scenario_file(name_or_path: str) -> bool:
    """True when ``--scenario`` names a file (a ``.toml`` name or a path), not a built-in."""
    return name_or_path.lower().endswith(".toml") or "/" in name_or_path or os.sep in name_or_path


def builtin_scenario(name: str) -> Scenario:
    """The built-in scenario ``name`` (one of :func:`scenario_names`; a name or a file:
    :func:`scenarios.inputs.scenario_file.get_scenario`)."""
    if name not in _SCENARIOS:
        raise ValueError(f"unknown built-in scenario {name!r}; choose one of: {', '.join(scenario_names())}")
    return _SCENARIOS[name]
