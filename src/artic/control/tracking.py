"""Joint-velocity tracking of a reference trajectory (thesis sections 5.2.1 and 5.3.1).

The Chapter 5 robot is commanded in joint velocities q_R'. A reference (y_k, yd_k), k =
0..T-1 (a DMP rollout, Eq. 2.4-2.6, or a planned demo, Algorithm 2) is tracked with
velocity feed-forward plus proportional feedback on the measured joints:

    a_k = yd_k + k_p (y_k - q_R)                               (section 5.3.1)

k_p in 1/s (k_p dt <= 1 avoids overshoot). After the reference's last sample the
target is held: y = y_{T-1}, yd = 0. Used by policy search (the DMP policies' actions)
and by plan-demos (executing a planned demo in the simulator).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from artic.errors import InputError

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class JointTracker:
    """a_k = yd_k + k_p (y_k - q_R): y (T, J) rad, yd (T, J) rad/s, k_p >= 0 (1/s).

    Callable as a rollout `ActionFn` (`artic.learning.rollout`): `tracker(obs, k)` reads
    q_R from obs[:J] (observations [q_R, q_O])."""

    y: F64
    yd: F64
    k_p: float = 5.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.k_p) and self.k_p >= 0):
            raise InputError(f"tracking controller k_p: expected >= 0, got {self.k_p}")
        if self.y.ndim != 2 or self.yd.shape != self.y.shape or len(self.y) == 0:
            raise InputError(
                f"tracking controller: y and yd must both be (T, J), got {self.y.shape} "
                f"and {self.yd.shape}"
            )

    @property
    def n_joints(self) -> int:
        return int(self.y.shape[1])

    def reference(self, k: int) -> tuple[F64, F64]:
        """(y_k, yd_k) of step k; past the end, the last sample held at rest."""
        if k < self.y.shape[0]:
            return self.y[k], self.yd[k]
        return self.y[-1], np.zeros_like(self.y[-1])

    def action(self, k: int, q_robot: F64) -> F64:
        """a_k: (J,) rad/s for the measured robot configuration q_robot (J,) rad."""
        y, yd = self.reference(k)
        q = np.asarray(q_robot, dtype=np.float64)
        if q.shape != y.shape:
            raise InputError(f"tracking controller: q_robot must be {y.shape}, got {q.shape}")
        return yd + self.k_p * (y - q)

    def __call__(self, obs: F64, step: int) -> F64:
        return self.action(step, np.asarray(obs, dtype=np.float64)[: self.n_joints])


def computed_torque(
    mass: F64, bias: F64, q: F64, qd: F64, q_ref: F64, qd_ref: F64, k_p: float, k_d: float
) -> F64:
    """Joint torques (J,) of the computed-torque law for a torque-controlled arm (the
    Chapter 7 head and tail): tau = M (k_p (q_ref - q) + k_d (qd_ref - qd)) + bias, with
    M (J, J) the mass matrix and bias (J,) = C q' + g at the measured state, k_p in 1/s^2
    and k_d in 1/s (critically damped: k_d = 2 sqrt(k_p)). Each joint's error then obeys
    e'' + k_d e' + k_p e = 0 when the model is exact."""
    error = k_p * (np.asarray(q_ref) - q) + k_d * (np.asarray(qd_ref) - qd)
    return np.asarray(mass @ error + bias, dtype=np.float64)
