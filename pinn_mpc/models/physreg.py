"""PhysReg MLP: the MLP's trunk (2x64 tanh) with linear heads for x_obs,i+1 and z_i = T_m,i
(paper Eq. physreg-forward), trained with the physics loss."""

from __future__ import annotations

from pinn_mpc.models.mlp import MLP

__all__ = ["PhysReg"]


class PhysReg(MLP):
    """The MLP's trunk with a T_m head, and the physics block."""

    has_physics = True
