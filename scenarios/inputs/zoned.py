"""The built-in buildings of several zones: their zones, internal walls and actuators.

- :data:`TWO_ZONE_HOUSE`: the paper's household split in two halves (each half its R/C
  values: conductances and capacities halved), a south zone whose windows (6 m2 of glazing,
  g = 0.5: an aperture of 3 m2) take the irradiance on the south facade and a north zone
  without windows that count, coupled through an internal wall and door of 40 W/K (about
  15 m2 of a 1.5 W/(m2 K) partition plus the door's air exchange), each heated by its own
  5 kW electric heater (:data:`TWO_ZONE_HOUSE_ACTUATORS`).
- :data:`SHOULDER_OFFICE`: a small office of two 150 m2 perimeter zones, one facing east and
  one west (each with 8 m2 of glazing, g = 0.5), coupled through an open-plan partition of
  150 W/K; occupancy gains split evenly. Each zone has an electric heater of 3 kW and a
  chiller of 1 kW electrical (12 C supply at 30 % of Carnot: an EER of 4.8 at 30 C outdoor
  air, 6 below 24 C: 5-6 kW of cooling) (:data:`SHOULDER_OFFICE_ACTUATORS`): in spring the mornings need heat and the
  afternoons, with the sun and the people in, need cooling.
"""

from __future__ import annotations

from pinn_mpc.actuator import Actuator, ActuatorSpec
from pinn_mpc.multizone import MultiZoneParams, ZoneRC
from pinn_mpc.physics import PAPER_HOUSEHOLD, RCParams
from pinn_mpc.zones import ZoneSpec

__all__ = [
    "SHOULDER_OFFICE",
    "SHOULDER_OFFICE_ACTUATORS",
    "TWO_ZONE_HOUSE",
    "TWO_ZONE_HOUSE_ACTUATORS",
]

_HALF_HOUSEHOLD = RCParams(
    r_ra_k_per_w=2.0 * PAPER_HOUSEHOLD.r_ra_k_per_w,
    r_rm_k_per_w=2.0 * PAPER_HOUSEHOLD.r_rm_k_per_w,
    c_r_j_per_k=0.5 * PAPER_HOUSEHOLD.c_r_j_per_k,
    c_m_j_per_k=0.5 * PAPER_HOUSEHOLD.c_m_j_per_k,
    gain_to_air_fraction=0.5,
)

TWO_ZONE_HOUSE = MultiZoneParams(
    zones=(
        ZoneRC(
            zone=ZoneSpec("south"),
            rc=RCParams(**{**_HALF_HOUSEHOLD.to_dict(), "solar_aperture_m2": 3.0, "solar_to_air_fraction": 0.3}),
            gain_share=0.5,
            solar_input="G_south",
        ),
        ZoneRC(zone=ZoneSpec("north"), rc=_HALF_HOUSEHOLD, gain_share=0.5),
    ),
    wall_conductance_w_per_k=((0.0, 40.0), (40.0, 0.0)),
)
TWO_ZONE_HOUSE_ACTUATORS = (
    ActuatorSpec(upper_w=5000.0, zone=0, name="heat_south"),
    ActuatorSpec(upper_w=5000.0, zone=1, name="heat_north"),
)

_OFFICE_ZONE = RCParams(
    r_ra_k_per_w=1.0 / 120.0,
    r_rm_k_per_w=1.0 / 900.0,
    c_r_j_per_k=3.0e6,
    c_m_j_per_k=4.0e7,
    solar_aperture_m2=4.0,
    solar_to_air_fraction=0.4,
    gain_to_air_fraction=0.6,
)
SHOULDER_OFFICE = MultiZoneParams(
    zones=(
        ZoneRC(zone=ZoneSpec("east"), rc=_OFFICE_ZONE, gain_share=0.5, solar_input="G_east"),
        ZoneRC(zone=ZoneSpec("west"), rc=_OFFICE_ZONE, gain_share=0.5, solar_input="G_west"),
    ),
    wall_conductance_w_per_k=((0.0, 150.0), (150.0, 0.0)),
)
_CHILLER = Actuator(kind="chiller", supply_temp_c=12.0, carnot_efficiency=0.3, cop_min=1.0, cop_max=6.0)
SHOULDER_OFFICE_ACTUATORS = (
    ActuatorSpec(upper_w=3000.0, zone=0, name="heat_east"),
    ActuatorSpec(upper_w=1000.0, zone=0, heats=False, efficiency=_CHILLER, name="cool_east"),
    ActuatorSpec(upper_w=3000.0, zone=1, name="heat_west"),
    ActuatorSpec(upper_w=1000.0, zone=1, heats=False, efficiency=_CHILLER, name="cool_west"),
)
