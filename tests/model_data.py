"""Data for the learned-model tests: the paper's simulated household (section 4.3.1).

``scenarios.running.datagen.generate`` of ``paper_household`` with the random on/off policy: 2R2C
with the backup thermostat, 30-min intervals, T_r = T_m = 17 C at the start. Frames are
cached per (days, seed) and returned as copies. Also a model's network and layers, typed.
"""

from __future__ import annotations

import functools
from typing import TypeVar, cast

import pandas as pd
from torch import nn

from pinn_mpc.data import validate_timeseries
from pinn_mpc.models.layers import EnsembleLinear
from pinn_mpc.models.learned import LearnedModel
from scenarios.inputs.scenario_file import get_scenario
from scenarios.running.datagen import generate


@functools.lru_cache(maxsize=8)
def _household(days: int, seed: int) -> pd.DataFrame:
    df = generate(get_scenario("paper_household"), days=days, seed=seed, policy="random")
    return validate_timeseries(df, source="paper_household")


def household_data(days: int, seed: int) -> pd.DataFrame:
    """A validated frame of ``days`` x 48 rows in the data format (with the true ``T_m``)."""
    df = _household(days, seed)
    out = df.copy()
    out.attrs.update(df.attrs)
    return out


N = TypeVar("N", bound=nn.Module)


def net_of(model: LearnedModel, kind: type[N]) -> N:
    """``model``'s network, which must be a ``kind``."""
    net = model.module.net
    assert isinstance(net, kind)
    return net


def ensemble_layers(layers: nn.ModuleList) -> list[EnsembleLinear]:
    """The layers of an ensemble MLP (:func:`pinn_mpc.models.layers.mlp_layers`)."""
    return [cast(EnsembleLinear, layer) for layer in layers]
