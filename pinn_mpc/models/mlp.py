"""The paper's plain MLP: features -> 2x64 tanh -> (T_r,i+1, u_phys,i); regression loss only.

:class:`TrunkNet` is also PhysReg's network (:mod:`pinn_mpc.models.physreg`), which adds a
linear T_m head to the same trunk.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from pinn_mpc.features import FeatureConfig
from pinn_mpc.models.base import NetParts
from pinn_mpc.models.layers import EnsembleLinear, fold, mlp_layers, sigmoid_form, transposed
from pinn_mpc.models.paper import PaperArchitecture, PaperNet, StaticInputs, StepFn, tp_weight

__all__ = ["HIDDEN", "MLP", "TrunkNet"]

#: Hidden layers of the trunk.
HIDDEN = (64, 64)


class TrunkNet(PaperNet):
    """A tanh trunk with a linear head for (T_r increment, u_phys) and, when ``t_m_head``, one
    for T_m: ``forward(x (M, B, F))`` returns ``(obs (M, B, 2), z (M, B) or None)``."""

    def __init__(
        self,
        *,
        features: FeatureConfig,
        n_members: int,
        generators: Sequence[torch.Generator],
        t_m_head: bool,
    ):
        super().__init__()
        self.n_members = n_members
        self.trunk = mlp_layers((features.n_features, *HIDDEN), n_members, generators)
        self.head = EnsembleLinear(n_members, HIDDEN[-1], 2, generators)
        self.z_head = EnsembleLinear(n_members, HIDDEN[-1], 1, generators) if t_m_head else None

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        s = x
        for layer in self.trunk:
            s = torch.tanh(layer(s))
        obs = self.head(s)
        if self.z_head is not None:
            return obs, self.z_head(s)[..., 0]
        return obs, None

    def rollout_steps(self, inputs: StaticInputs, depth: int) -> StepFn:
        k1 = depth + 1
        n_e, u_rows = inputs.n_e, inputs.u_rows
        trunk = sigmoid_form(self.trunk, tanh_last=True)
        w_t0, b_t0 = trunk[0]
        n_x = 2 * k1 + n_e
        pre_trunk = inputs.pre(w_t0, b_t0, [*range(2 * k1, n_x), n_x + 1, n_x + 2], [*range(n_e), n_e, n_e + 1])
        w_trunk = tp_weight(w_t0, list(range(k1)), list(range(k1, 2 * k1)))
        w_u = w_t0[:, n_x][:, :, None]  # (M, out, 1)
        trunk_rest = transposed(trunk[1:])
        head = transposed([fold(self.head.weight, self.head.bias, sigmoid_in=True, tanh_out=False)])[0]
        z_head = (
            transposed([fold(self.z_head.weight, self.z_head.bias, sigmoid_in=True, tanh_out=False)])[0]
            if self.z_head is not None
            else None
        )

        def step_reg(tp: torch.Tensor, h: int) -> tuple[torch.Tensor, torch.Tensor | None]:
            m, n = tp.shape[0], tp.shape[-1]
            base = torch.addcmul(pre_trunk[h], w_u, u_rows[h])
            s = torch.sigmoid(torch.baddbmm(base, w_trunk, tp[:, h : h + k1].reshape(m, 2 * k1, n)))
            for w, b in trunk_rest:
                s = torch.sigmoid(torch.baddbmm(b, w, s))
            obs = torch.baddbmm(head[1], head[0], s)
            return obs, (torch.baddbmm(z_head[1], z_head[0], s)[:, 0] if z_head else None)

        return step_reg


class MLP(PaperArchitecture):
    """The plain network: no physics block, no T_m, lambda 0 (with a physics block, the
    trunk gets a T_m head: :class:`pinn_mpc.models.physreg.PhysReg`)."""

    has_physics = False

    def build_net(self, parts: NetParts) -> nn.Module:
        return TrunkNet(
            features=parts.features,
            n_members=parts.n_members,
            generators=parts.generators,
            t_m_head=self.has_physics,
        )
