"""Plans as room-temperature setpoint schedules, turned into powers by tracking them through the model.

Sampling powers directly plateaus about 10 % above the optimum: the optimum rides the comfort
band's edge within millikelvin, and a noisy power sequence never does. In setpoint space the
band edge is the origin: a plan is an offset [K] per step above the band's lower edge (heating)
or below its upper edge (cooling), and every offset schedule is mapped to the powers that make
the model's room temperature follow it.

The tracking uses the model linearised around the warm start: one batch of probes (the
warm start and copies with one step moved, :func:`controllers.lp_polish.probes`) gives the
predicted ``T_r`` at the warm start and its sensitivity to every step's power. Forward
substitution then finds, step by step, the power that puts the linearised ``T_r`` at the
setpoint given the powers already chosen, clipped to the actuator's range. For a model linear
in power (the 2R2C, a hybrid away from its learned backup thermostat) this is exact tracking.
"""

from __future__ import annotations

import torch

from controllers.lp_polish import RolloutFn, jacobians, probes
from pinn_mpc.actuator import ActuatorSpec

__all__ = ["SetpointSpace"]


class SetpointSpace:
    """The affine model around a warm start and the map offsets (N, H) [K] -> powers (N, H) [W].

    ``edge_c`` (H,) is the band edge the offsets count from (lower edge when ``actuator``
    heats, upper when it cools); offsets count into the band, and the powers stay within the
    actuator's bounds. Built by :meth:`probe`, which also returns what the probes cost.
    """

    def __init__(
        self,
        t0: torch.Tensor,
        jr: torch.Tensor,
        u0: torch.Tensor,
        edge_c: torch.Tensor,
        *,
        actuator: ActuatorSpec,
    ):
        self.t0, self.jr, self.u0 = t0, jr, u0
        self.edge_c, self.sign, self.actuator = edge_c, actuator.sign, actuator

    @classmethod
    def probe(
        cls,
        rollout: RolloutFn,
        u0: torch.Tensor,
        edge_c: torch.Tensor,
        *,
        actuator: ActuatorSpec,
        stride: int,
        delta_frac: float = 0.02,
    ) -> tuple[SetpointSpace, torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        """Linearise the model around ``u0`` (H,) with one rollout of 1 + ceil(H/stride) plans
        (each probe ``delta_frac`` of the actuator's range); the space, the probe batch and
        its predictions (so the caller can score them)."""
        batch, step = probes(u0, delta_frac * actuator.span_w, actuator.upper_w, stride)
        t_r, u_phys = rollout(batch)
        t0, _p0, jr, _jp = jacobians(t_r, u_phys, step)
        dtype = u0.dtype
        space = cls(
            torch.as_tensor(t0.mean(0), dtype=dtype),
            torch.as_tensor(jr.mean(0), dtype=dtype),
            u0,
            edge_c.to(dtype),
            actuator=actuator,
        )
        return space, batch, (t_r, u_phys)

    def offsets_of_warm_start(self) -> torch.Tensor:
        """The offsets (H,) [K] the warm start's predicted T_r has from the edge."""
        return self.sign * (self.t0 - self.edge_c)

    def powers(self, offsets_k: torch.Tensor) -> torch.Tensor:
        """Offsets (N, H) [K] -> the powers (N, H) [W] that track ``edge + offset`` on the
        linearised model (forward substitution, each step clipped to the actuator's bounds)."""
        n, h = offsets_k.shape
        setpoint = self.edge_c + self.sign * offsets_k
        du = torch.zeros((n, h), dtype=offsets_k.dtype)
        u = torch.empty_like(du)
        for k in range(h):
            predicted = self.t0[k] + du[:, :k] @ self.jr[k, :k]
            gain = float(self.jr[k, k])
            if abs(gain) < 1e-12:  # the power has no effect (a backup override): keep the warm start
                u[:, k] = self.u0[k]
                continue
            u[:, k] = (self.u0[k] + (setpoint[:, k] - predicted) / gain).clamp(
                self.actuator.lower_w, self.actuator.upper_w
            )
            du[:, k] = u[:, k] - self.u0[k]
        return u
