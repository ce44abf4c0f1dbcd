"""The 2R2C as a planner model: :class:`RCBatchModel` declares the rollout interface
(:class:`pinn_mpc.models.rollout.BatchDynamics`) of the learned ensembles."""

from __future__ import annotations

import numpy as np
import torch

from pinn_mpc.actuator import ActuatorSpec
from pinn_mpc.models.rollout import BatchDynamics, Rollout
from pinn_mpc.physics import RCParams, discretise

__all__ = ["RCBatchModel"]


class RCBatchModel(BatchDynamics):
    """The 2R2C physics as a one-member batch model (exact ZOH over each control interval).

    The backup thermostat is approximated per interval by clipping on the room temperature at
    the start of the interval (full power below ``backup_low_c``, off above ``backup_high_c``
    for a heater; mirrored for cooling). The hidden ``T_m`` now is taken from ``history['T_m']``
    when present (simulated data), else reconstructed from the last interval by inverting the
    T_r row of the discrete model (exact for noise-free data without a backup override).
    ``actuator`` is the building's (its bounds the backup's full and off power, its efficiency
    the COP at each interval's T_a, as the simulator has them; it heats where ``params``
    heats); powers in and out stay electrical.
    """

    n_members = 1
    depth = 0
    exog_names: tuple[str, ...] = ("T_a", "G", "I_g")
    affine_in_plan = False  # the backup thermostat's clipping

    def __init__(
        self,
        params: RCParams,
        *,
        dt_s: float,
        actuator: ActuatorSpec,
        backup_low_c: float = 17.0,
        backup_high_c: float = 20.5,
    ):
        if actuator.heats != params.heating:
            raise ValueError(
                f"RCBatchModel: the actuator {'heats' if actuator.heats else 'cools'} but params.eta "
                f"= {params.eta:g}; give a heater with eta > 0, a cooling machine with eta < 0"
            )
        if not backup_low_c < backup_high_c:
            raise ValueError(
                f"RCBatchModel backup limits need low < high, got {backup_low_c}, {backup_high_c}"
            )
        self.params = params
        self.actuator, self._dt_s = actuator, dt_s
        self.backup_low_c, self.backup_high_c = backup_low_c, backup_high_c
        self.ad, self.bd = discretise(params, dt_s)
        if params.unmeasured_gains_w:  # the schedule's blocks need the calendar
            self.exog_names = ("T_a", "G", "I_g", "time_of_day_h", "day_of_week")

    @property
    def eta(self) -> float:
        return self.params.eta

    @property
    def dt_s(self) -> float:
        return self._dt_s

    def state_now(self, history: dict[str, np.ndarray]) -> tuple[float, float]:
        """Current ``(T_r, T_m)`` [C] from the history (see the class docstring).

        The reconstruction reads the interval that just ended: ``T_r`` at its start and end,
        its delivered power and its exogenous inputs (the second-to-last exogenous values).
        """
        t_r = np.asarray(history["T_r"], dtype=float)
        if "T_m" in history:
            return float(t_r[-1]), float(np.asarray(history["T_m"])[-1])
        zeros = np.zeros_like(t_r)
        t_a_last = float(np.asarray(history.get("T_a", zeros), dtype=float)[-2])
        d = np.array(
            [
                np.asarray(history["u_phys"], dtype=float)[-1] * float(self.actuator.gain(t_a_last)),
                *(np.asarray(history.get(name, zeros), dtype=float)[-2] for name in self.exog_names[:3]),
            ]
        )
        if self.params.unmeasured_gains_w:
            d[3] = self.params.gains_w(
                d[3], np.asarray(history.get("time_of_day_h", zeros), dtype=float)[-2],
                np.asarray(history["day_of_week"], dtype=float)[-2] if "day_of_week" in history else None,
            )
        (a00, a01), (a10, a11) = self.ad
        t_m_prev = (t_r[-1] - a00 * t_r[-2] - self.bd[0] @ d) / a01
        return float(t_r[-1]), float(a10 * t_r[-2] + a11 * t_m_prev + self.bd[1] @ d)

    def rollout(
        self, history: dict[str, np.ndarray], u_w: torch.Tensor, exog: dict[str, np.ndarray]
    ) -> Rollout:
        """u_w (N, H) [W] -> end-of-interval T_r and T_m of the one zone, tensors (1, N, H, 1),
        and the delivered power (1, N, H)."""
        n, h = u_w.shape
        t_r0, t_m0 = self.state_now(history)
        d = np.stack([np.asarray(exog[k], dtype=float)[:h] for k in self.exog_names[:3]], axis=1)
        if self.params.unmeasured_gains_w:
            d[:, 2] = self.params.gains_w(
                d[:, 2], np.asarray(exog["time_of_day_h"], dtype=float)[:h],
                np.asarray(exog["day_of_week"], dtype=float)[:h],
            )
        drift = torch.as_tensor(d @ self.bd[:, 1:].T, dtype=u_w.dtype)  # (H, 2)
        (a00, a01), (a10, a11) = self.ad.tolist()
        b0, b1 = self.bd[:, 0].tolist()
        gain = self.actuator.gain(d[:, 0]).tolist()  # heat per electrical W of each interval
        t_r = torch.full((n,), t_r0, dtype=u_w.dtype)
        t_m = torch.full((n,), t_m0, dtype=u_w.dtype)
        on, off = (self.backup_low_c, self.backup_high_c)
        full_w, off_w = self.actuator.upper_w, self.actuator.lower_w
        out_r, out_m, out_u = [], [], []
        for j in range(h):
            force_on, force_off = (t_r < on, t_r > off)
            if not self.actuator.heats:
                force_on, force_off = force_off, force_on
            p = torch.where(force_on, full_w, torch.where(force_off, off_w, u_w[:, j]))
            heat = p * gain[j]
            t_r, t_m = (
                a00 * t_r + a01 * t_m + b0 * heat + drift[j, 0],
                a10 * t_r + a11 * t_m + b1 * heat + drift[j, 1],
            )
            out_r.append(t_r)
            out_m.append(t_m)
            out_u.append(p)
        return Rollout.of_one_zone(
            torch.stack(out_r, 1)[None], torch.stack(out_u, 1)[None], torch.stack(out_m, 1)[None]
        )
