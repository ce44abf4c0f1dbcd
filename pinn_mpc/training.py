"""Training a seed ensemble: all members at once, as one vectorised model.

Loss (paper Eq. gen-loss) = L_reg + lambda * L_phys, both on scaled quantities: L_reg is the
mean squared error of the scaled (T_r,i+1 - T_r,i, u_phys,i); L_phys the mean squared physics
residual divided by the temperature scale. Every member has its own ``torch.Generator``
(seed ``first_seed + m``) for its initial weights and its mini-batch order, so a run is
deterministic given the seeds. Physics-informed members train on mini-batches made of chunks
of consecutive samples, because the residuals link neighbours (T_m,i -> T_m,i+1).

Each architecture gives its loss terms (:meth:`pinn_mpc.models.base.Architecture.loss_fn`):
the paper's networks L_reg + lambda L_phys (:mod:`pinn_mpc.models.paper`), the hybrid its own
(:mod:`pinn_mpc.models.hybrid`); this loop only draws the mini-batches and steps the optimiser.

Recipes: ``"paper"`` is the published one (Adam, lr 1e-3, batch 2048, 75 epochs: ~225 steps,
far from converged); ``"converged"`` uses batch 512, 60 epochs and a learning rate decayed
from 1e-2 to 1e-4 on a cosine; ``"long"`` the same schedule over 150 epochs. Depth and recipe
default to the architecture's (:mod:`pinn_mpc.models.registry`).
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
import torch
from tqdm import tqdm

from pinn_mpc import __version__, physics
from pinn_mpc.actuator import CopCurve
from pinn_mpc.choices import RECIPES, RESIDUALS
from pinn_mpc.data import validate_timeseries
from pinn_mpc.errors import InputError, InternalError
from pinn_mpc.features import (
    MAX_DEPTH,
    MIN_TRAIN_SAMPLES,
    FeatureConfig,
    fit_feature_config,
    make_windows,
    with_scheduled_gains,
)
from pinn_mpc.identify import check_power_sign, gain_schedule_applies
from pinn_mpc.models.base import HOLD_TOLERANCE_W, Batch, TrainingSet
from pinn_mpc.models.learned import MAX_MEMBERS, EnsembleModule, LearnedModel, ModelRecord
from pinn_mpc.models.registry import (
    ALL_ARCHS,
    AUTO,
    BASELINES,
    ArchSpec,
    get_architecture,
    get_spec,
)

if TYPE_CHECKING:
    from pinn_mpc.identify import IdentifyResult

__all__ = ["TrainConfig", "data_summary", "data_warnings", "train_model"]

#: Consecutive samples per mini-batch chunk (the physics residuals link neighbours).
CHUNK = 8
#: Threads while training: the matmuls are small, and the machine is shared.
TRAIN_THREADS = 1


@dataclass(frozen=True, kw_only=True)
class TrainConfig:
    """How to train an ensemble. ``None`` means "the recipe's value" (epochs, lam, batch, lr).

    ``prior`` gives the initial 2R2C coefficients (default :data:`physics.PAPER_HOUSEHOLD`),
    ``eta`` the heat per watt of actuator power (1 a heater, -COP a cooling machine; its sign
    fixes the sign of ``b``, and the model's record of heating or cooling). ``u_max_w`` is the
    actuator's limit when known: the data's power must not exceed it. ``residual`` is
    ``"exact"`` (both 2R2C rows, ZOH) or ``"finite_difference"`` (the paper's Eq. est_Tm).
    ``physics_lr_factor`` scales the learning rate of the log-space coefficients against the
    network's: at 10 the coefficients reach the same values from a prior 30-40 % off as from
    the true one (tested on paper_household); at 1 they barely leave the prior. ``None``: the
    architecture's (10 for the paper's networks, 0.1 for the hybrid, whose block starts at the
    identified values). ``depth`` and ``recipe``: ``None`` means the architecture's
    (:data:`pinn_mpc.models.registry.ARCHITECTURES`).

    Hybrid only: without ``prior`` the physics block starts at the grey-box identification of
    the training data (:func:`pinn_mpc.identify.identify_rc`); ``anchor_weight`` penalises the
    squared distance of its log-coefficients from that start, ``residual_weight`` the squared
    scaled output of the residual net (so the physics, not the network, explains T_r).
    """

    depth: int | None = None
    n_seeds: int = 20
    first_seed: int = 0
    epochs: int | None = None
    lam: float | None = None
    recipe: str | None = None
    prior: physics.RCParams | None = None
    eta: float = 1.0
    residual: str = "exact"
    batch_size: int | None = None
    lr: float | None = None
    physics_lr_factor: float | None = None
    residual_weight: float = 1.0
    anchor_weight: float = 10.0
    u_max_w: float | None = None

    def __post_init__(self) -> None:
        if self.depth is not None and not 1 <= self.depth <= MAX_DEPTH:
            raise ValueError(f"TrainConfig.depth must be 1 .. {MAX_DEPTH}, got {self.depth}")
        if not 1 <= self.n_seeds <= MAX_MEMBERS:
            raise ValueError(
                f"TrainConfig.n_seeds must be 1 .. {MAX_MEMBERS} members, got {self.n_seeds}"
            )
        if self.recipe is not None and self.recipe not in RECIPES:
            raise ValueError(f"unknown recipe {self.recipe!r}; choose one of {', '.join(RECIPES)}")
        if self.residual not in RESIDUALS:
            raise ValueError(
                f"unknown residual {self.residual!r}; choose one of {', '.join(RESIDUALS)}"
            )
        if self.epochs is not None and self.epochs < 1:
            raise ValueError(f"TrainConfig.epochs must be >= 1, got {self.epochs}")
        if self.lam is not None and not (math.isfinite(self.lam) and self.lam >= 0):
            raise ValueError(f"TrainConfig.lam must be a finite number >= 0, got {self.lam}")
        physics.check_plausible("eta", self.eta, name="TrainConfig.eta")
        if self.u_max_w is not None and not (math.isfinite(self.u_max_w) and self.u_max_w > 0):
            raise ValueError(f"TrainConfig.u_max_w must be positive, got {self.u_max_w!r}")
        if self.batch_size is not None and self.batch_size < 1:
            raise ValueError(f"TrainConfig.batch_size must be >= 1, got {self.batch_size}")
        if self.lr is not None and not (math.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"TrainConfig.lr must be positive, got {self.lr}")
        if self.physics_lr_factor is not None and not (
            math.isfinite(self.physics_lr_factor) and self.physics_lr_factor > 0
        ):
            raise ValueError(
                f"TrainConfig.physics_lr_factor must be positive, got {self.physics_lr_factor}"
            )
        for name in ("residual_weight", "anchor_weight"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"TrainConfig.{name} must be a finite number >= 0, got {value}")

    def for_arch(self, spec: ArchSpec) -> TrainConfig:
        """This config with the architecture's depth and recipe where it leaves them open."""
        return replace(
            self,
            depth=spec.depth if self.depth is None else self.depth,
            recipe=spec.recipe if self.recipe is None else self.recipe,
        )

    def resolved(self) -> dict[str, Any]:
        """Epochs, batch size, learning rates and lambda with the recipe's defaults filled in
        (the recipe must be set: see :meth:`for_arch`)."""
        if self.recipe is None:
            raise InternalError("TrainConfig.resolved needs a recipe; call for_arch first")
        r = RECIPES[self.recipe]
        lr = self.lr if self.lr is not None else r["lr"]
        return {
            "epochs": int(self.epochs if self.epochs is not None else r["epochs"]),
            "batch_size": int(self.batch_size if self.batch_size is not None else r["batch_size"]),
            "lr": float(lr),
            "lr_final": float(lr * r["lr_final"] / r["lr"]),
            "lam": float(self.lam if self.lam is not None else r["lam"]),
        }

    def prior_params(self) -> physics.RCParams:
        """``prior`` (default the paper's household) with ``eta`` from this config."""
        return replace(self.prior or physics.PAPER_HOUSEHOLD, eta=self.eta)


@contextlib.contextmanager
def _threads(n: int) -> Iterator[None]:
    """Small batched matmuls: more than the physical cores only adds contention."""
    before = torch.get_num_threads()
    torch.set_num_threads(max(1, min(n, os.cpu_count() or 1)))
    try:
        yield
    finally:
        torch.set_num_threads(before)


def data_summary(df: pd.DataFrame) -> dict[str, Any]:
    """What a model was trained on: size, period, step and ranges of the main columns."""
    out: dict[str, Any] = {
        "n_rows": len(df),
        "start": str(df["time"].iloc[0]),
        "end": str(df["time"].iloc[-1]),
        "dt_s": float(df.attrs.get("dt_s", 0.0)),
        "columns": [str(c) for c in df.columns],
    }
    for col in ("T_r", "u_phys", "T_a", "T_m", "G", "I_g"):
        if col in df.columns:
            v = df[col].to_numpy(dtype=float)
            out[f"{col}_range"] = [float(v.min()), float(v.max())]
    return out


def _identify(df: pd.DataFrame, eta: float, *, unmeasured_gains: bool) -> IdentifyResult | None:
    """The grey-box identification of the training data (with ``unmeasured_gains`` as
    :func:`~pinn_mpc.identify.identify_rc` takes it), or None where it fails."""
    from pinn_mpc.identify import identify_rc

    try:
        return identify_rc(df, eta=eta, unmeasured_gains=unmeasured_gains)
    except InputError:
        return None


#: Below these the data barely constrain a model outside them (see :func:`data_warnings`).
MIN_T_A_SPAN_K = 10.0
MIN_NEAR_FULL_SHARE = 0.02
MIN_TRAIN_DAYS = 14.0


def data_warnings(df: pd.DataFrame) -> list[str]:
    """What a validated training frame cannot teach a model, one sentence each: few days, a
    narrow outdoor-temperature range, few intervals near the largest power."""
    out = []
    days = len(df) * float(df.attrs.get("dt_s", 1800.0)) / 86400.0
    if days < MIN_TRAIN_DAYS:
        out.append(
            f"training data cover {math.floor(days * 10 + 1e-9) / 10:.1f} days (< {MIN_TRAIN_DAYS:g}): the model sees few "
            "weather situations; more days of data usually help"
        )
    t_a = df["T_a"].to_numpy(dtype=float)
    span = float(t_a.max() - t_a.min())
    if span < MIN_T_A_SPAN_K:
        out.append(
            f"T_a spans only {t_a.min():.1f} .. {t_a.max():.1f} C ({span:.1f} K): the model "
            "extrapolates in other weather; train on data from more of the season"
        )
    u_phys = df["u_phys"].to_numpy(dtype=float)
    top = float(u_phys.max())
    share = float(np.mean(u_phys >= 0.9 * top)) if top > 0 else 0.0
    if share < MIN_NEAR_FULL_SHARE:
        out.append(
            f"only {100 * share:.1f} % of intervals deliver >= 90 % of the largest power "
            f"({top:.0f} W): the response near full power is barely identified; add data "
            "at high power (colder days, a lower room temperature: a backup thermostat that "
            "cuts the heater in warm rooms keeps data from full power)"
        )
    return out


def _training_set(df: pd.DataFrame, features: FeatureConfig, chunk: int) -> TrainingSet:
    """The samples of a validated frame as tensors (see :class:`TrainingSet`)."""
    win = make_windows(df, features, min_samples=MIN_TRAIN_SAMPLES)
    p_s, d_s = features.power, features.delta_t_r
    y = np.stack(
        [
            (win.t_r_next - win.t_r[win.rows] - d_s.mean) / d_s.std,
            (win.u_phys_now - p_s.mean) / p_s.std,
        ],
        axis=1,
    )
    rows = win.rows  # consecutive: sample s+1 is row rows[s] + 1
    inputs = np.concatenate([win.u_phys[:, None], win.exog_raw], axis=1)[rows]
    # Where the backup thermostat changed the demand within an interval, the delivered power
    # was not held constant, so the zero-order-hold residual does not apply: leave those out.
    held = np.abs(df["u"].to_numpy(dtype=float) - win.u_phys) <= HOLD_TOLERANCE_W
    return TrainingSet(
        x=torch.from_numpy(win.x),
        y=torch.from_numpy(y.astype(np.float32)),
        t_r=torch.from_numpy(win.t_r[rows[0] : rows[-1] + 2].astype(np.float32)),  # (S+1,)
        inputs=torch.from_numpy(inputs.astype(np.float32)),  # (S, 4) u_phys, T_a, G, I_g
        held=torch.from_numpy(held[rows].astype(np.float32)),  # (S,)
        df=df,
        features=features,
        chunk=chunk,
    )


def train_model(
    df: pd.DataFrame,
    *,
    arch: str,
    config: TrainConfig,
    progress: bool = True,
    init_weights: Mapping[str, torch.Tensor] | None = None,
) -> LearnedModel:
    """Train a seed ensemble of ``arch`` on a frame in the data format.

    Parameters
    ----------
    df
        Training data in the data format (:func:`pinn_mpc.read_timeseries`).
    arch
        An architecture name (``"hybrid"``, ``"mlp"``, ``"physreg"``, ``"physnet"``).
    config
        How to train; depth and recipe left open are the architecture's.
    init_weights
        Names and shapes of the module's state dict (e.g. part of another model's of the same
        architecture and size) that replace those weights before training: fine-tuning a
        pre-trained model.
    progress
        Show a progress bar on stderr.

    Returns
    -------
    LearnedModel
        ``config.n_seeds`` members trained together, with the RC identified from the same data.
    """
    if arch == AUTO or arch in BASELINES:
        raise ValueError(
            f"train_model trains the networks ({', '.join(ALL_ARCHS)}); {arch!r} is fitted by "
            f"pinn_mpc.fit(df, arch={arch!r}, config=config), which fits every model by name"
        )
    architecture = get_architecture(arch)
    config = config.for_arch(get_spec(arch))
    assert config.depth is not None and config.recipe is not None
    df = validate_timeseries(df, source="training data", u_max_w=config.u_max_w)
    check_power_sign(df, config.eta, what=arch)  # the physics prior and planners take its sign
    hp = config.resolved()
    # The RC kept for the planner's fallback has the unmeasured gains' schedule where the data
    # call for one; an architecture whose 2R2C reads internal gains (the hybrid, pcnn) takes the
    # same schedule as its I_g: its features and the RC that seeds its physics are fitted on
    # the data with those gains.
    scheduled = _identify(df, config.eta, unmeasured_gains=True) if gain_schedule_applies(df) else None
    schedule = (
        scheduled.params.unmeasured_gains_w
        if scheduled is not None and architecture.gain_schedule and "I_g" not in df.columns
        else ()
    )
    seen = with_scheduled_gains(df, schedule) if schedule else df
    features = replace(
        fit_feature_config(seen, depth=config.depth, calendar=architecture.calendar, optional=architecture.optional_exog),
        gain_schedule_w=schedule,
    )
    # The RC that seeds the physics has no gain schedule of its own.
    identified = _identify(seen, config.eta, unmeasured_gains=False)
    kept_rc = scheduled if scheduled is not None else identified
    cop_curve = CopCurve.fit(df["T_a"].to_numpy(float), df["cop"].to_numpy(float)) if "cop" in df else None
    prior = architecture.training_prior(config, df, identified)
    m = config.n_seeds
    gens = [torch.Generator().manual_seed(config.first_seed + i) for i in range(m)]
    module = EnsembleModule(
        arch, features=features, n_members=m, prior=prior, generators=gens, cop_curve=cop_curve
    )
    if init_weights is not None:
        _load_weights(module, init_weights)
    lam = architecture.physics_weight(hp["lam"])
    data = _training_set(df, features, CHUNK)
    # A rollout loss's chunk is at most the samples there are (a day of data, a day's rollout).
    chunk = min(architecture.chunk_length(lam, CHUNK), data.x.shape[0])
    data = replace(data, chunk=chunk)
    loss_fn = architecture.loss_fn(module, data, config, lam)

    n_samples = data.x.shape[0]
    n_chunks = (n_samples - chunk) // chunk + 1
    per_batch = max(1, min(hp["batch_size"] // chunk, n_chunks))
    n_batches = math.ceil(n_chunks / per_batch)
    total = hp["epochs"] * n_batches
    groups: list[dict[str, Any]] = [{"params": list(module.net.parameters()), "factor": 1.0}]
    if module.physics is not None:
        factor = config.physics_lr_factor
        factor = architecture.physics_lr_factor if factor is None else factor
        groups.append({"params": list(module.physics.parameters()), "factor": factor})
    opt = torch.optim.Adam(groups, lr=hp["lr"], fused=True)
    decay = hp["lr_final"] / hp["lr"]

    def lr_at(step: int) -> float:
        return hp["lr"] * (
            decay + (1 - decay) * 0.5 * (1 + math.cos(math.pi * step / max(total, 1)))
        )

    offsets = torch.arange(chunk)
    history: list[tuple[float, float]] = []
    started = time.perf_counter()
    bar = tqdm(total=total, desc=f"train {arch} x{m}", disable=None if progress else True)
    with _threads(TRAIN_THREADS), bar:
        module.train()
        step = 0
        for _epoch in range(hp["epochs"]):
            # Each member: chunks of `chunk` consecutive samples, random phase and order.
            starts = torch.stack(
                [
                    torch.randint(0, n_samples - chunk * n_chunks + 1, (1,), generator=g)
                    + chunk * torch.randperm(n_chunks, generator=g)
                    for g in gens
                ]
            )  # (M, n_chunks)
            sum_reg = sum_phys = 0.0
            for b in range(n_batches):
                first = starts[:, b * per_batch : (b + 1) * per_batch]  # (M, C)
                idx = first[..., None] + offsets  # (M, C, L)
                terms = loss_fn(Batch(first=first, idx=idx, flat=idx.reshape(m, -1)))
                for group in opt.param_groups:
                    group["lr"] = lr_at(step) * group["factor"]
                opt.zero_grad(set_to_none=True)
                # Members are independent: the summed loss gives each its own gradient.
                (terms.total * m).backward()
                opt.step()
                step += 1
                sum_reg += float(terms.reg.detach())
                sum_phys += float(terms.phys.detach())
                bar.update(1)
            history.append((sum_reg / n_batches, sum_phys / n_batches))
            bar.set_postfix(reg=f"{history[-1][0]:.2e}", phys=f"{history[-1][1]:.2e}")
    elapsed = time.perf_counter() - started
    architecture.after_training(module, data)
    u_phys = df["u_phys"].to_numpy(dtype=float)
    fields: dict[str, Any] = {"cop_curve": None} | architecture.record_fields(config, cop_curve)
    record = ModelRecord(
        package_version=__version__,
        arch=arch,
        n_members=m,
        seeds=[config.first_seed + i for i in range(m)],
        recipe=config.recipe,
        hyperparameters=hp | {"lam": lam},
        residual=config.residual,
        eta=prior.eta,
        prior=prior.to_dict(),
        # The fallback of the planners over this model: the RC MPC on these parameters.
        identified_rc=(
            {
                **physics.rc_summary(kept_rc.params, source="identify (training data)"),
                "fit": kept_rc.fit_statistics(),
            }
            if kept_rc is not None
            else None
        ),
        data_warnings=data_warnings(df),
        u_phys_range_w=[float(u_phys.min()), float(u_phys.max())],
        training_data=data_summary(df),
        final_loss={"reg": history[-1][0], "phys": history[-1][1]},
        train_seconds=elapsed,
        **fields,
    )
    return LearnedModel(features=features, module=module, record=record)


def _load_weights(module: EnsembleModule, weights: Mapping[str, torch.Tensor]) -> None:
    """Copy ``weights`` into ``module`` (each name and shape must be the module's)."""
    own = module.state_dict()
    for name, value in weights.items():
        if name not in own or tuple(own[name].shape) != tuple(value.shape):
            shape = tuple(own[name].shape) if name in own else None
            raise ValueError(
                f"init_weights: {name!r} {tuple(value.shape)} does not fit the model "
                f"(its shape there: {shape}); pre-train with the same architecture, depth and seeds"
            )
    with torch.no_grad():
        for name, value in weights.items():
            own[name].copy_(value)
