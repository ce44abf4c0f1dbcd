"""Training a seed ensemble: all members at once, as one vectorised model.

Loss (paper Eq. gen-loss) = L_reg + lambda * L_phys, both on scaled quantities: L_reg is the
mean squared error of the scaled (T_r,i+1 - T_r,i, u_phys,i); L_phys the mean squared physics
residual divided by the temperature scale. Every member has its own ``torch.Generator``
(seed ``first_seed + m``) for its initial weights and its mini-batch order, so a run is
deterministic given the seeds. Physics-informed members train on mini-batches made of chunks
of consecutive samples, because the residuals link neighbours (T_m,i -> T_m,i+1).

The hybrid (:class:`pinn_mpc.models.HybridNet`) has no separate physics loss: its physics is
its predictor. Its loss is L_reg + ``residual_weight`` x mean squared residual-net output +
``anchor_weight`` x mean squared distance of the physics block's log-coefficients from their
start (the identification of the training data). Measured on cold_storage (60 days): anchor 1
let C_m drift +8 % and R_rm -7 % (T_m MAE 0.26 C); anchor 10 keeps them within 2 % (0.012 C).

Recipes: ``"paper"`` is the published one (Adam, lr 1e-3, batch 2048, 75 epochs: ~225 steps,
far from converged); the default ``"converged"`` uses batch 512, 60 epochs and a learning
rate decayed from 1e-2 to 1e-4 on a cosine (~700 steps), which reaches the plateau of the
validation error on 120 days of the paper's household at a fraction of a minute per ensemble.
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any, cast

import numpy as np
import pandas as pd
import torch
from tqdm import tqdm

from pinn_mpc import __version__, physics
from pinn_mpc.actuator import CopCurve
from pinn_mpc.choices import ALL_ARCHS, RECIPES, RESIDUALS
from pinn_mpc.data import validate_timeseries
from pinn_mpc.errors import InputError
from pinn_mpc.features import MAX_DEPTH, MIN_TRAIN_SAMPLES, fit_feature_config, make_windows
from pinn_mpc.models import (
    MAX_MEMBERS,
    RESIDUAL_BOUND_FACTOR,
    EnsembleModule,
    HybridInputs,
    HybridNet,
    LearnedModel,
    residual_exact,
    residual_finite_difference,
)

__all__ = ["TrainConfig", "data_summary", "data_warnings", "train_model"]

#: Consecutive samples per mini-batch chunk (the physics residuals link neighbours).
CHUNK = 8
#: |u - u_phys| [W] below which an interval counts as held at constant power.
HOLD_TOLERANCE_W = 1.0
#: Share of the largest power by which delivered must differ from demanded to count as an
#: override of the backup thermostat when its thresholds are guessed.
BACKUP_SHARE = 0.1
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
    the true one (tested on paper_household); at 1 they barely leave the prior. ``None``: 10
    for physreg/physnet, 0.1 for hybrid, whose block starts at the identified values.

    Hybrid only: without ``prior`` the physics block starts at the grey-box identification of
    the training data (:func:`pinn_mpc.identify.identify_rc`); ``anchor_weight`` penalises the
    squared distance of its log-coefficients from that start, ``residual_weight`` the squared
    scaled output of the residual net (so the physics, not the network, explains T_r).
    """

    depth: int = 8
    n_seeds: int = 20
    first_seed: int = 0
    epochs: int | None = None
    lam: float | None = None
    recipe: str = "converged"
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
        if not 1 <= self.depth <= MAX_DEPTH:
            raise InputError(f"TrainConfig.depth must be 1 .. {MAX_DEPTH}, got {self.depth}")
        if not 1 <= self.n_seeds <= MAX_MEMBERS:
            raise InputError(
                f"TrainConfig.n_seeds must be 1 .. {MAX_MEMBERS} members, got {self.n_seeds}"
            )
        if self.recipe not in RECIPES:
            raise InputError(f"unknown recipe {self.recipe!r}; choose one of {', '.join(RECIPES)}")
        if self.residual not in RESIDUALS:
            raise InputError(
                f"unknown residual {self.residual!r}; choose one of {', '.join(RESIDUALS)}"
            )
        if self.epochs is not None and self.epochs < 1:
            raise InputError(f"TrainConfig.epochs must be >= 1, got {self.epochs}")
        if self.lam is not None and not (math.isfinite(self.lam) and self.lam >= 0):
            raise InputError(f"TrainConfig.lam must be a finite number >= 0, got {self.lam}")
        physics.check_plausible("eta", self.eta, name="eta (--eta)")
        if self.u_max_w is not None and not (math.isfinite(self.u_max_w) and self.u_max_w > 0):
            raise InputError(f"TrainConfig.u_max_w must be positive, got {self.u_max_w!r}")
        if self.batch_size is not None and self.batch_size < 1:
            raise InputError(f"TrainConfig.batch_size must be >= 1, got {self.batch_size}")
        if self.lr is not None and not (math.isfinite(self.lr) and self.lr > 0):
            raise InputError(f"TrainConfig.lr must be positive, got {self.lr}")
        if self.physics_lr_factor is not None and not (
            math.isfinite(self.physics_lr_factor) and self.physics_lr_factor > 0
        ):
            raise InputError(
                f"TrainConfig.physics_lr_factor must be positive, got {self.physics_lr_factor}"
            )
        for name in ("residual_weight", "anchor_weight"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise InputError(f"TrainConfig.{name} must be a finite number >= 0, got {value}")

    def resolved(self) -> dict[str, Any]:
        """Epochs, batch size, learning rates and lambda with the recipe's defaults filled in."""
        r = RECIPES[self.recipe]
        lr = self.lr if self.lr is not None else r["lr"]
        return {
            "epochs": int(self.epochs if self.epochs is not None else r["epochs"]),
            "batch_size": int(self.batch_size if self.batch_size is not None else r["batch_size"]),
            "lr": float(lr),
            "lr_final": float(lr * r["lr_final"] / r["lr"]),
            "lam": float(self.lam if self.lam is not None else r["lam"]),
        }

    def prior_params(self, df: pd.DataFrame | None = None, arch: str = "physnet") -> physics.RCParams:
        """The physics block's start: ``prior``, else for a hybrid the identification of
        ``df``, else the paper's household; ``eta`` from this config."""
        if self.prior is None and arch == "hybrid" and df is not None:
            from pinn_mpc.identify import identify_rc

            return identify_rc(df, eta=self.eta).params
        return replace(self.prior or physics.PAPER_HOUSEHOLD, eta=self.eta)

    def physics_lr(self, arch: str) -> float:
        if self.physics_lr_factor is not None:
            return self.physics_lr_factor
        return 0.1 if arch == "hybrid" else 10.0


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


def _identify(df: pd.DataFrame, eta: float) -> Any:
    """The grey-box identification of the training data, or None where it fails."""
    from pinn_mpc.identify import identify_rc

    try:
        return identify_rc(df, eta=eta)
    except InputError:
        return None


def _mean_cop(df: pd.DataFrame) -> float:
    """The power-weighted mean heat per electrical watt (1 without a ``cop`` column)."""
    if "cop" not in df.columns:
        return 1.0
    u_w = df["u_phys"].to_numpy(dtype=float)
    return float(np.sum(u_w * df["cop"].to_numpy(dtype=float)) / max(np.sum(u_w), 1e-9))


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
            f"training data cover {days:.1f} days (< {MIN_TRAIN_DAYS:g}): the model sees few "
            "weather situations; control over it falls back to the RC MPC where it errs"
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


def _backup_guess(df: pd.DataFrame, *, heating: bool) -> tuple[float, float, float]:
    """Start of the hybrid's learned backup thermostat: (low, high) [C] and full power [W].

    Intervals whose delivered power exceeds (falls short of) the demand by more than
    :data:`BACKUP_SHARE` of the largest power were forced on (off);
    the threshold starts at the 90th percentile of the room's lowest temperature over the
    forced intervals on the cold side (the 10th of the highest on the hot side); with no
    such interval, 5 K beyond what the data saw.
    """
    t_r = df["T_r"].to_numpy(dtype=float)
    gap = df["u_phys"].to_numpy(dtype=float)[:-1] - df["u"].to_numpy(dtype=float)[:-1]
    lo, hi = np.minimum(t_r[:-1], t_r[1:]), np.maximum(t_r[:-1], t_r[1:])
    # An override moves a sizeable share of full power; a machine's minimum modulation only
    # rounds the demand (a heat pump cycling below it: a few per cent of its minimum power).
    tolerance = max(HOLD_TOLERANCE_W, BACKUP_SHARE * float(df["u_phys"].max()))
    forced_on, forced_off = gap > tolerance, gap < -tolerance
    cold, hot = (forced_on, forced_off) if heating else (forced_off, forced_on)
    low = float(np.percentile(lo[cold], 90)) if cold.any() else float(t_r.min()) - 5.0
    high = float(np.percentile(hi[hot], 10)) if hot.any() else float(t_r.max()) + 5.0
    if not low < high:
        low, high = float(t_r.min()) - 5.0, float(t_r.max()) + 5.0
    return low, high, float(df["u_phys"].max())


def train_model(
    df: pd.DataFrame, *, arch: str, config: TrainConfig, progress: bool = True
) -> LearnedModel:
    """Train ``config.n_seeds`` members of ``arch`` together on a frame in the data format."""
    if arch not in ALL_ARCHS:
        raise InputError(f"unknown architecture {arch!r}; choose one of {', '.join(ALL_ARCHS)}")
    df = validate_timeseries(df, source="training data", u_max_w=config.u_max_w)
    hp = config.resolved()
    features = fit_feature_config(df, depth=config.depth)
    win = make_windows(df, features, min_samples=MIN_TRAIN_SAMPLES)
    identified = _identify(df, config.eta)
    cop_curve = CopCurve.fit(df["T_a"].to_numpy(float), df["cop"].to_numpy(float)) if "cop" in df else None
    if arch == "hybrid":  # its physics works on the heat, g(T_a) x u_phys
        use_identified = config.prior is None and identified is not None
        prior = identified.params if use_identified else config.prior_params(df, arch)
    else:  # the paper's networks see electrical power: eta times the data's mean COP
        prior = replace(config.prior_params(df, arch), eta=config.eta * _mean_cop(df))
    m = config.n_seeds
    gens = [torch.Generator().manual_seed(config.first_seed + i) for i in range(m)]
    module = EnsembleModule(
        arch, features=features, n_members=m, prior=prior, generators=gens, cop_curve=cop_curve
    )
    lam = hp["lam"] if arch in ("physreg", "physnet") else 0.0
    hybrid = module.net if isinstance(module.net, HybridNet) else None
    chunk = CHUNK if lam > 0 else 1

    t_s, p_s, d_s = features.temperature, features.power, features.delta_t_r
    x_all = torch.from_numpy(win.x)
    y_all = torch.from_numpy(
        np.stack(
            [
                (win.t_r_next - win.t_r[win.rows] - d_s.mean) / d_s.std,
                (win.u_phys_now - p_s.mean) / p_s.std,
            ],
            axis=1,
        ).astype(np.float32)
    )
    rows = win.rows  # consecutive: sample s+1 is row rows[s] + 1
    t_r_rows = torch.from_numpy(win.t_r[rows[0] : rows[-1] + 2].astype(np.float32))  # (S+1,)
    inputs = np.concatenate([win.u_phys[:, None], win.exog_raw], axis=1)[rows]
    d_rows = torch.from_numpy(inputs.astype(np.float32))  # (S, 4) u_phys, T_a, G, I_g
    # Where the backup thermostat changed the demand within an interval, the delivered power
    # was not held constant, so the zero-order-hold residual does not apply: leave those out.
    held = np.abs(df["u"].to_numpy(dtype=float) - win.u_phys) <= HOLD_TOLERANCE_W
    hold_rows = torch.from_numpy(held[rows].astype(np.float32))  # (S,)

    if hybrid is not None:
        hybrid.init_backup(*_backup_guess(df, heating=prior.heating))
        split = hybrid.split(x_all)  # what the hybrid reads, once for all samples

    n_samples = len(rows)
    n_chunks = (n_samples - chunk) // chunk + 1
    per_batch = max(1, min(hp["batch_size"] // chunk, n_chunks))
    n_batches = math.ceil(n_chunks / per_batch)
    total = hp["epochs"] * n_batches
    groups: list[dict[str, Any]] = [{"params": list(module.net.parameters()), "factor": 1.0}]
    if module.physics is not None:
        groups.append(
            {"params": list(module.physics.parameters()), "factor": config.physics_lr(arch)}
        )
        start_physics = [p.detach().clone() for p in module.physics.parameters()]
    opt = torch.optim.Adam(groups, lr=hp["lr"], fused=True)
    decay = hp["lr_final"] / hp["lr"]

    def lr_at(step: int) -> float:
        return hp["lr"] * (
            decay + (1 - decay) * 0.5 * (1 + math.cos(math.pi * step / max(total, 1)))
        )

    dt_s = features.dt_s
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
                c = idx.shape[1]
                flat = idx.reshape(m, -1)
                if hybrid is not None:
                    obs, z, res = hybrid.forward_split(HybridInputs(*(v[flat] for v in split)))
                else:
                    obs, z = module.net(x_all[flat])
                loss_reg = torch.mean((obs - y_all[flat]) ** 2)
                loss = loss_reg
                if hybrid is not None and module.physics is not None:
                    anchor = sum(
                        torch.mean((p - p0) ** 2)
                        for p, p0 in zip(module.physics.parameters(), start_physics, strict=True)
                    )
                    loss = loss + config.residual_weight * torch.mean(res**2)
                    loss = loss + config.anchor_weight * cast(torch.Tensor, anchor)
                loss_phys = torch.zeros(())
                if lam > 0 and z is not None and module.physics is not None:
                    coef = module.physics.coefficients()
                    t_m_hat = (z * t_s.std + t_s.mean).reshape(m, c, chunk)
                    t_r_seq = t_r_rows[first[..., None] + torch.arange(chunk + 1)]
                    if config.residual == "exact":
                        r_room, r_mass = residual_exact(
                            coef, dt_s, t_r=t_r_seq, d=d_rows[idx], t_m_hat=t_m_hat
                        )
                        w_room = hold_rows[idx]
                        w_mass = w_room[..., :-1]
                        # Per member, so that members stay independent of each other.
                        sq_room = (w_room * r_room**2).sum((1, 2))
                        total_sq = sq_room + (w_mass * r_mass**2).sum((1, 2))
                        count = w_room.sum((1, 2)) + w_mass.sum((1, 2))
                        sq = torch.mean(total_sq / count.clamp(min=1.0))
                    else:
                        obs3 = obs.reshape(m, c, chunk, 2)
                        res = residual_finite_difference(
                            coef,
                            dt_s,
                            t_r=t_r_seq,
                            t_r_hat=t_r_seq[..., :-1] + obs3[..., 0] * d_s.std + d_s.mean,
                            u_phys_hat=obs3[..., 1] * p_s.std + p_s.mean,
                            exog=d_rows[idx][..., 1:],
                            t_m_hat=t_m_hat,
                        )
                        sq = torch.mean(res**2)
                    loss_phys = sq / t_s.std**2
                    loss = loss_reg + lam * loss_phys
                for group in opt.param_groups:
                    group["lr"] = lr_at(step) * group["factor"]
                opt.zero_grad(set_to_none=True)
                # Members are independent: the summed loss gives each its own gradient.
                (loss * m).backward()
                opt.step()
                step += 1
                sum_reg += float(loss_reg.detach())
                sum_phys += float(loss_phys.detach())
                bar.update(1)
            history.append((sum_reg / n_batches, sum_phys / n_batches))
            bar.set_postfix(reg=f"{history[-1][0]:.2e}", phys=f"{history[-1][1]:.2e}")
    elapsed = time.perf_counter() - started
    if hybrid is not None:
        module.eval()
        with torch.no_grad():
            every = torch.arange(n_samples).expand(m, -1)
            _, _, res = hybrid.forward_split(HybridInputs(*(v[every] for v in split)))  # (M, S)
            largest = (res.abs() * features.delta_t_r.std).amax(dim=1, keepdim=True)
            hybrid.residual_bound_k.copy_(RESIDUAL_BOUND_FACTOR * largest + 1e-3)
    u_phys = df["u_phys"].to_numpy(dtype=float)
    meta: dict[str, Any] = {
        "package_version": __version__,
        "arch": arch,
        "n_members": m,
        "seeds": [config.first_seed + i for i in range(m)],
        "recipe": config.recipe,
        "hyperparameters": hp | {"lam": lam},
        "residual": config.residual,
        **(
            {"residual_weight": config.residual_weight, "anchor_weight": config.anchor_weight}
            if hybrid is not None
            else {}
        ),
        "eta": prior.eta,
        "prior": prior.to_dict(),
        "cop_curve": cop_curve.to_dict() if cop_curve is not None and hybrid is not None else None,
        # The fallback of the planners over this model: the RC MPC on these parameters.
        "identified_rc": (
            {
                **physics.rc_summary(identified.params, source="identify (training data)"),
                "fit": identified.fit_statistics(),
            }
            if identified is not None
            else None
        ),
        "data_warnings": data_warnings(df),
        "u_phys_range_w": [float(u_phys.min()), float(u_phys.max())],
        "training_data": data_summary(df),
        "final_loss": {"reg": history[-1][0], "phys": history[-1][1]},
        "train_seconds": elapsed,
    }
    return LearnedModel(arch=arch, features=features, module=module, meta=meta)
