"""A trained ensemble: the module of network and physics block, the typed model record, and
:class:`LearnedModel`, which predicts and rolls out through its architecture."""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, NamedTuple

import numpy as np
import pandas as pd
import torch
from torch import nn

from pinn_mpc import physics
from pinn_mpc.actuator import CopCurve
from pinn_mpc.errors import InternalError
from pinn_mpc.features import FeatureConfig, make_windows
from pinn_mpc.models.base import Architecture, NetParts, RolloutInputs
from pinn_mpc.models.physics_block import Physics
from pinn_mpc.models.registry import get_architecture
from pinn_mpc.models.rollout import BatchDynamics, FittedModel, Rollout, StackedDynamics

__all__ = ["MAX_MEMBERS", "EnsembleModule", "LearnedModel", "ModelRecord", "Scaling"]

#: Most ensemble members: far beyond the paper's 20; bounds what training or a model.json can
#: make the program allocate.
MAX_MEMBERS = 1000


class EnsembleModule(nn.Module):
    """Network plus (for the architectures that have one) the learnable physics block."""

    def __init__(
        self,
        arch: str,
        *,
        features: FeatureConfig,
        n_members: int,
        prior: physics.RCParams,
        generators: Sequence[torch.Generator],
        cop_curve: CopCurve | None = None,
    ):
        super().__init__()
        self.architecture: Architecture = get_architecture(arch)
        self.n_members = n_members
        self.physics = (
            Physics(prior, n_members=n_members, exog_names=features.exog_names)
            if self.architecture.has_physics
            else None
        )
        self.net = self.architecture.build_net(
            NetParts(features, n_members, generators, self.physics, prior, cop_curve)
        )


@dataclass(kw_only=True)
class ModelRecord:
    """What a model was trained with and on: the training record of ``model.json``.

    ``extra`` holds the fields of a loaded ``model.json`` beyond the training record (format
    version, features, learned coefficients, tensor shapes, checksum). :meth:`to_dict` gives
    the JSON object, :meth:`from_dict` reads one (fields an older file lacks take defaults).
    """

    package_version: str = ""
    arch: str
    n_members: int
    seeds: list[int] = field(default_factory=list)
    recipe: str = ""
    hyperparameters: dict[str, float] = field(default_factory=dict)
    residual: str = "exact"
    residual_weight: float | None = None
    anchor_weight: float | None = None
    eta: float = 1.0
    prior: dict[str, Any]
    cop_curve: dict[str, Any] | None = None
    identified_rc: dict[str, Any] | None = None
    data_warnings: list[str] = field(default_factory=list)
    u_phys_range_w: list[float]
    training_data: dict[str, Any] = field(default_factory=dict)
    final_loss: dict[str, float] = field(default_factory=dict)
    train_seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The record as ``model.json`` holds it (the architecture's optional weights only
        where it has them), then ``extra``."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "extra"}
        for name in ("residual_weight", "anchor_weight"):
            if out[name] is None:
                del out[name]
        return out | self.extra

    @classmethod
    def from_dict(cls, meta: dict[str, Any]) -> ModelRecord:
        """The record of a ``model.json`` object (keys it does not know go to ``extra``)."""
        known = {f.name for f in fields(cls)} - {"extra"}
        return cls(
            **{k: v for k, v in meta.items() if k in known},
            extra={k: v for k, v in meta.items() if k not in known},
        )


class Scaling(NamedTuple):
    """The scaled outputs' conversions: T_r increment = ``dt_ratio`` obs + ``dt_offset`` (in
    units of the temperature scale); scaled u_phys clipped to ``p_lo`` .. ``p_hi``, the range
    seen in training."""

    dt_ratio: float
    dt_offset: float
    p_lo: float
    p_hi: float


class LearnedModel(FittedModel):
    """A trained seed ensemble (eval mode), ready to predict and roll out (a planner's
    :class:`~pinn_mpc.models.rollout.BatchDynamics`, not affine in the plan; a
    :class:`~pinn_mpc.models.rollout.FittedModel` of its architecture's family).

    ``arch``, ``depth``, ``n_members``, ``exog_names`` describe it; ``record`` holds the
    training record that :mod:`pinn_mpc.artifacts` stores in ``model.json`` (``meta``: the
    same as a dict).
    """

    affine_in_plan = False

    def __init__(self, *, features: FeatureConfig, module: EnsembleModule, record: ModelRecord):
        self.arch = record.arch
        self.architecture = module.architecture
        self.features = features
        self.module = module.eval()
        self.record = record
        lo, hi = record.u_phys_range_w
        p = features.power
        t, dlt = features.temperature, features.delta_t_r
        self.scaling = Scaling(
            dt_ratio=dlt.std / t.std,
            dt_offset=dlt.mean / t.std,
            p_lo=(lo - p.mean) / p.std,
            p_hi=(hi - p.mean) / p.std,
        )
        self._constants: tuple[torch.Tensor, Any] | None = None

    @property
    def depth(self) -> int:
        """History intervals the model reads before now (its feature windows' depth)."""
        return self.features.depth

    @property
    def n_members(self) -> int:
        return self.module.n_members

    @property
    def exog_names(self) -> tuple[str, ...]:
        return self.features.model_exog_names

    @property
    def family(self) -> str:
        """The architecture (:class:`~pinn_mpc.models.rollout.FittedModel`)."""
        return self.arch

    @property
    def identified_rc(self) -> dict[str, Any] | None:
        """The RC identified from the training data (the training record's)."""
        return self.record.identified_rc

    @property
    def training_data(self) -> dict[str, Any]:
        """The training data's summary (the training record's)."""
        return self.record.training_data

    @property
    def meta(self) -> dict[str, Any]:
        """The training record as the dict ``model.json`` holds."""
        return self.record.to_dict()

    @property
    def eta(self) -> float:
        """Heat per W of actuator power the model was trained with: > 0 heating, < 0 cooling."""
        return float(self.record.eta)

    @property
    def dt_s(self) -> float:
        """The control interval [s] the model predicts one step of."""
        return self.features.dt_s

    def _step(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
        """Scaled features (M, B, F) -> scaled (T_r,i+1, u_phys,i, T_m,i), each (M, B)."""
        obs, z = self.module.net(x)
        k = self.depth
        s = self.scaling
        t_next = x[..., k] + obs[..., 0] * s.dt_ratio + s.dt_offset
        p = obs[..., 1].clamp(s.p_lo, s.p_hi)
        return t_next, p, z

    def rollout_constants(self) -> Any:
        """The architecture's :meth:`~pinn_mpc.models.base.Architecture.rollout_constants`,
        kept while the weights stay the same (a decision rolls out several times). The weights
        are compared by value, so changing them in place is seen."""
        with torch.no_grad():
            weights = [t.reshape(-1) for t in (*self.module.parameters(), *self.module.buffers())]
            key = torch.cat(weights)
        cached = self._constants
        if cached is None or not torch.equal(cached[0], key):
            cached = self._constants = (key, self.architecture.rollout_constants(self.module.net))
        return cached[1]

    def unscale_t(self, v: torch.Tensor) -> torch.Tensor:
        """Scaled temperatures -> [C]."""
        return v * self.features.temperature.std + self.features.temperature.mean

    def rollout_scaled(
        self,
        t_win: torch.Tensor,
        p_win: torch.Tensor,
        e_seq: torch.Tensor,
        u_s: torch.Tensor,
        tod: torch.Tensor,
    ) -> Rollout:
        """Batched recursive rollout in scaled units, N plans (or starts) of H steps.

        ``t_win``, ``p_win`` (N0, k+1) scaled T_r,i-k..T_r,i and u_phys,i-k-1..u_phys,i-1;
        ``e_seq`` (N0, n_series, k+H) scaled exogenous series from i-k to i+H-1; ``u_s`` (N, H)
        scaled demand; ``tod`` (N0, H, 2) encoded time of day. N0 is 1 or N.
        """
        return self.architecture.rollout_scaled(self, RolloutInputs(t_win, p_win, e_seq, u_s, tod))

    def rollout(
        self, history: dict[str, np.ndarray], u_w: torch.Tensor, exog: dict[str, np.ndarray]
    ) -> Rollout:
        """Roll N demand plans forward H intervals, recursively, for all M members at once.

        ``history``: ``T_r`` (>= depth+1,) measured up to and including now [C]; ``u_phys``
        (>= depth+1,) past delivered power [W] (last = previous interval); each exogenous
        series of ``exog_names`` but time of day (``T_a`` ...) (>= depth+1,) up to now.
        ``u_w`` (N, H) demanded power [W]. ``exog``: one array (>= H,) per name in
        ``exog_names`` for the next H intervals (``time_of_day_h`` at each interval start;
        ``day_of_week`` too where the features have the calendar).
        Returns a :class:`~pinn_mpc.models.rollout.Rollout` of the model's one zone, tensors
        (M, N, H, 1) (the power (M, N, H)): one batched forward per horizon step.
        """
        k1 = self.depth + 1
        f = self.features
        hist = {
            n: np.asarray(history[n], dtype=float)
            for n in ("T_r", "u_phys", *f.exog_series)
            if n in history
        }
        short = {n: len(hist.get(n, ())) for n in ("T_r", "u_phys", *f.exog_series)}
        short = {n: v for n, v in short.items() if v < k1}
        if short:
            raise InternalError(
                f"rollout needs at least depth+1={k1} past values of T_r, u_phys and "
                f"{', '.join(f.exog_series)}; got {short}"
            )
        u_w = torch.as_tensor(u_w, dtype=torch.float32)
        if u_w.ndim != 2:
            raise InternalError(f"rollout u_w must have shape (N, H), got {tuple(u_w.shape)}")
        h_len = u_w.shape[1]
        for name in self.exog_names:
            if name not in exog or np.shape(exog[name])[0] < h_len:
                raise InternalError(f"rollout exog[{name!r}] must have at least H={h_len} values")
        t_win = (hist["T_r"][-k1:] - f.temperature.mean) / f.temperature.std
        p_win = (hist["u_phys"][-k1:] - f.power.mean) / f.power.std
        seq = {
            n: np.concatenate([hist[n][-k1:-1], np.asarray(exog[n], dtype=float)[:h_len]])
            for n in f.exog_series
        }
        if f.gain_schedule_w:  # the measured gains (0 where none) plus the schedule's
            past = {n: np.asarray(history[n], dtype=float)[-k1:-1] for n in ("time_of_day_h", "day_of_week")}
            clock = {n: np.concatenate([past[n], np.asarray(exog[n], dtype=float)[:h_len]]) for n in past}
            seq["I_g"] = f.gains_w(seq["I_g"], clock["time_of_day_h"], clock["day_of_week"])
        return self.rollout_scaled(
            torch.as_tensor(t_win, dtype=torch.float32)[None],
            torch.as_tensor(p_win, dtype=torch.float32)[None],
            torch.from_numpy(f.scale_exog(seq))[None],
            (u_w - f.power.mean) / f.power.std,
            torch.from_numpy(
                f.encode_clock(
                    np.asarray(exog["time_of_day_h"])[:h_len],
                    np.asarray(exog["day_of_week"])[:h_len] if f.calendar else None,
                )
            )[None],
        )

    @property
    def stack_key(self) -> Hashable | None:
        """The architecture's :meth:`~pinn_mpc.models.base.Architecture.stack_key` of this model."""
        return self.architecture.stack_key(self)

    def stacked(self, models: Sequence[BatchDynamics], members: int) -> StackedDynamics:
        """``models`` (learned models of this model's stack key) in one batch of buildings."""
        learned = [m for m in models if isinstance(m, LearnedModel)]
        if len(learned) != len(models):
            raise InternalError("LearnedModel.stacked: every model of the batch must be a learned model")
        return self.architecture.stacked(learned, members)

    def predict_one_step(self, df: pd.DataFrame) -> dict[str, Any]:
        """One-step predictions for every sample of a frame.

        Returns ``T_r_next`` (M, n) [C] (T_r,i+1), ``u_phys`` (M, n) [W] (u_phys,i), ``T_m``
        (M, n) [C] (T_m,i) or None for mlp, and ``row`` (n,) the row index i of each sample.
        """
        win = make_windows(df, self.features)
        x = torch.from_numpy(win.x).expand(self.n_members, -1, -1)
        with torch.no_grad():
            t_next, p, z = self._step(x)
        f = self.features
        return {
            "T_r_next": self.unscale_t(t_next).numpy().astype(float),
            "u_phys": (p * f.power.std + f.power.mean).numpy().astype(float),
            "T_m": self.unscale_t(z).numpy().astype(float) if z is not None else None,
            "row": win.rows,
        }

    def physics_coefficients(self) -> physics.Coefficients | None:
        """Learned coefficients (per second), geometric mean over members (``a11 = a12 + c13``,
        ``a22 = a21`` kept); None for mlp."""
        if self.module.physics is None:
            return None
        with torch.no_grad():
            coef = self.module.physics.coefficients()

        def mean(v: torch.Tensor) -> float:
            v = v.double()
            if torch.all(v > 0):
                return float(v.log().mean().exp())
            if torch.all(v < 0):
                return -float((-v).log().mean().exp())
            return float(v.mean())

        values = {
            name: mean(getattr(coef, name)) for name in physics.Coefficients.__dataclass_fields__
        }
        # Keep the structure of the 2R2C exact after averaging.
        values["a11"] = values["a12"] + values["c13"]
        values["a22"] = values["a21"]
        return physics.Coefficients(**values)

    def member_coefficients(self) -> list[dict[str, float]]:
        """Learned coefficients of each member, as dicts (empty for mlp)."""
        if self.module.physics is None:
            return []
        with torch.no_grad():
            coef = self.module.physics.coefficients()
        names = list(physics.Coefficients.__dataclass_fields__)
        return [{n: float(getattr(coef, n)[m]) for n in names} for m in range(self.n_members)]
