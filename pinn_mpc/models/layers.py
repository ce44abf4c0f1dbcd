"""Ensemble layers: every layer holds the weights of all M members, shape (M, in, out), and
applies them with one ``torch.baddbmm`` on inputs (M, B, F); and the same layers rewritten for
fast recursive rollouts (feature-major, tanh folded into a sigmoid)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import cast

import torch
from torch import nn

__all__ = ["EnsembleLinear", "fold", "mlp_layers", "run_layers", "sigmoid_form", "transposed"]


class EnsembleLinear(nn.Module):
    """M independent affine maps: (M, B, n_in) -> (M, B, n_out)."""

    def __init__(
        self, n_members: int, n_in: int, n_out: int, generators: Sequence[torch.Generator]
    ):
        super().__init__()
        self.weight = nn.Parameter(torch.empty(n_members, n_in, n_out))
        self.bias = nn.Parameter(torch.empty(n_members, 1, n_out))
        bound = 1.0 / math.sqrt(n_in)  # PyTorch's nn.Linear default, drawn per member
        with torch.no_grad():
            for m, g in enumerate(generators):
                self.weight[m].uniform_(-bound, bound, generator=g)
                self.bias[m].uniform_(-bound, bound, generator=g)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.baddbmm(self.bias, x, self.weight)


def mlp_layers(sizes: Sequence[int], m: int, gens: Sequence[torch.Generator]) -> nn.ModuleList:
    return nn.ModuleList(
        EnsembleLinear(m, a, b, gens) for a, b in zip(sizes[:-1], sizes[1:], strict=True)
    )


def run_layers(layers: nn.ModuleList, x: torch.Tensor) -> torch.Tensor:
    """tanh on every layer but the last (identity output, as in the paper)."""
    for layer in layers[:-1]:
        x = torch.tanh(layer(x))
    out: torch.Tensor = layers[-1](x)
    return out



def fold(
    weight: torch.Tensor, bias: torch.Tensor, *, sigmoid_in: bool, tanh_out: bool
) -> tuple[torch.Tensor, torch.Tensor]:
    """An ensemble layer (M, in, out), (M, 1, out) rewritten for ``tanh = 2 sigmoid(2 .) - 1``:
    its input is ``sigmoid(2a)`` instead of ``tanh(a)`` when ``sigmoid_in``, and its output
    feeds a sigmoid instead of a tanh when ``tanh_out``. Same function, exactly in real numbers."""
    w, b = weight.detach(), bias.detach()
    if sigmoid_in:  # W tanh(a) + b = 2W sigmoid(2a) + (b - W 1)
        w, b = 2.0 * w, b - w.sum(dim=1, keepdim=True)
    if tanh_out:
        w, b = 2.0 * w, 2.0 * b
    return w, b


def sigmoid_form(
    layers: nn.ModuleList, *, tanh_last: bool
) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """:func:`fold` over a chain of layers with tanh between them (and after the last if
    ``tanh_last``); (weight (M, in, out), bias (M, 1, out)) per layer."""
    n = len(layers)
    return [
        fold(
            cast(EnsembleLinear, layer).weight,
            cast(EnsembleLinear, layer).bias,
            sigmoid_in=i > 0,
            tanh_out=tanh_last or i < n - 1,
        )
        for i, layer in enumerate(layers)
    ]


def transposed(
    layers: list[tuple[torch.Tensor, torch.Tensor]],
) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """Feature-major layers: weight (M, out, in), bias (M, out, 1)."""
    return [(w.transpose(1, 2).contiguous(), b.transpose(1, 2).contiguous()) for w, b in layers]

