"""Plants: what the closed loop steps, one protocol and one result of a step (:mod:`.base`).

The RC simulator (:mod:`.rc`, the 2R2C or 3R3C of :mod:`pinn_mpc.simulator`) and EnergyPlus
(:mod:`.energyplus`) implement it; :mod:`.settings` holds a scenario's plant (its kind and
that kind's settings), :mod:`.kinds` makes the plant of a kind and answers what a kind knows
in advance (a calendar, scheduled gains). A plant knows no scenario, controller or
experiment: this layer imports only :mod:`pinn_mpc` and itself.
"""

__all__: list[str] = []
