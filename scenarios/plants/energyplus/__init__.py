"""EnergyPlus as a plant: a building model run step by step through EnergyPlus's Python API.

By concern: :mod:`.settings` (the building, weather and heater a scenario asks for),
:mod:`.files` (the engine, its bundled buildings and weather, names resolved to
files), :mod:`.model` (a building prepared: HVAC removed, zones merged or kept, one ideal
heater each), :mod:`.run` (one simulation in a thread of its own, handed over through queues
every control interval), :mod:`.plant` (the closed loop's plant), :mod:`.schedules` (the
building's holidays and scheduled gains) and :mod:`.sizing` (the heater it needs).
"""

__all__: list[str] = []
