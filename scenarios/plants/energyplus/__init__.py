"""EnergyPlus as a plant: a building model run step by step through EnergyPlus's Python API.

By concern: :mod:`.settings` (the building, weather and heater a scenario asks for),
:mod:`.files` (the engine, its bundled buildings and weather, names resolved to
files), :mod:`.model` (a building prepared: HVAC removed, zones merged or kept, one ideal
heater each, and a chiller each where each zone is controlled), :mod:`.run` (one simulation in
a thread of its own, handed over through queues every control interval), :mod:`.zoned` (such
a run of zones each controlled by actuators of their own), :mod:`.plant` (the closed loop's
plant), :mod:`.schedules` (the building's holidays and scheduled gains) and :mod:`.sizing`
(the heater it needs, or each zone's heater and chiller).
"""

__all__: list[str] = []
