"""PhysNet: encoder x_f -> 2x24 tanh -> T_m,i; dynamics (T_m,i, x_obs,i, u_i, w_i) -> 1x128
tanh -> x_obs,i+1 (paper Eq. physnet-forward), trained with the physics loss. Here x_f also
holds the exogenous history (see :mod:`pinn_mpc.features`): without T_a,i-1 the encoder cannot
pin T_m."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from pinn_mpc.features import FeatureConfig
from pinn_mpc.models.base import NetParts
from pinn_mpc.models.layers import mlp_layers, run_layers, sigmoid_form, transposed
from pinn_mpc.models.paper import (
    PaperArchitecture,
    PaperNet,
    StaticInputs,
    StepFn,
    run_transposed,
    tp_weight,
)

__all__ = ["ENCODER", "DYNAMICS", "PhysNet", "PhysNetNet"]

#: Hidden layers of the encoder and of the dynamics network.
ENCODER = (24, 24)
DYNAMICS = (128,)


class PhysNetNet(PaperNet):
    """Encoder and dynamics networks of M members: ``forward(x (M, B, F))`` returns
    ``(obs (M, B, 2), z (M, B))``."""

    def __init__(
        self, *, features: FeatureConfig, n_members: int, generators: Sequence[torch.Generator]
    ):
        super().__init__()
        self.n_members = n_members
        x_f, now = features.x_f_index(), features.now_index()
        self.x_f_index = torch.tensor(x_f)
        self.now_index = torch.tensor(now)
        self.encoder = mlp_layers((len(x_f), *ENCODER, 1), n_members, generators)
        self.dynamics = mlp_layers((1 + len(now), *DYNAMICS, 2), n_members, generators)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        z = run_layers(self.encoder, x.index_select(-1, self.x_f_index))
        dyn_in = torch.cat([z, x.index_select(-1, self.now_index)], dim=-1)
        return run_layers(self.dynamics, dyn_in), z[..., 0]

    def rollout_steps(self, inputs: StaticInputs, depth: int) -> StepFn:
        k, k1 = depth, depth + 1
        n_series, n_e, u_rows = inputs.n_series, inputs.n_e, inputs.u_rows
        enc = sigmoid_form(self.encoder, tanh_last=False)
        dyn = sigmoid_form(self.dynamics, tanh_last=False)
        (w_e0, b_e0), (w_d0, b_d0) = enc[0], dyn[0]
        enc_e = [s * k1 + j for s in range(n_series) for j in range(k)]
        pre_enc = inputs.pre(w_e0, b_e0, list(range(2 * k, 2 * k + len(enc_e))), enc_e)
        w_enc = tp_weight(w_e0, list(range(k)), list(range(k, 2 * k)))
        # Dynamics rows: z, T_r now, u_phys now, exogenous now (n_series), u, time of day.
        now_e = [s * k1 + k for s in range(n_series)]
        dyn_static_rows = [*range(3, 3 + n_series), 4 + n_series, 5 + n_series]
        pre_dyn = inputs.pre(w_d0, b_d0, dyn_static_rows, [*now_e, n_e, n_e + 1])
        w_dyn = w_d0[:, [0, 1, 2, 3 + n_series]].transpose(1, 2).contiguous()  # (M, out, 4)
        enc_rest, dyn_rest = transposed(enc[1:]), transposed(dyn[1:])

        def step_net(tp: torch.Tensor, h: int) -> tuple[torch.Tensor, torch.Tensor | None]:
            m, n = tp.shape[0], tp.shape[-1]
            x = torch.baddbmm(pre_enc[h], w_enc, tp[:, h : h + k].reshape(m, 2 * k, n))
            z = run_transposed(enc_rest, torch.sigmoid(x)) if enc_rest else x  # (M, 1, N)
            small = torch.cat([z, tp[:, h + k], u_rows[h].expand(m, 1, n)], dim=1)
            hidden = torch.sigmoid(torch.baddbmm(pre_dyn[h], w_dyn, small))
            return run_transposed(dyn_rest, hidden), z[:, 0]

        return step_net


class PhysNet(PaperArchitecture):
    """The encoder-dynamics network and the physics block."""

    def build_net(self, parts: NetParts) -> nn.Module:
        return PhysNetNet(
            features=parts.features, n_members=parts.n_members, generators=parts.generators
        )
