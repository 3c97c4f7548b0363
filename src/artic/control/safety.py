"""The safety envelope sigma of a CIP (thesis section 7.2.1, "Safety envelope"): capped
stiffness, clipped torques and the two-threshold guard against joint limits.

Given the torque a controller commands (VICES, `artic.control.osc`) and the arm's state,
`envelope_torque` returns the torque to apply, by the distance d_i of each joint to its
nearer limit once braked: the distance left when the joint, moving toward that limit,
is stopped at `push_acceleration` (`braked_distance`: d_i - v_i^2 / (2 a); at rest, the
distance itself), so a fast joint meets the guard early enough to stop short of B's
threshold (stateless: the mode follows from q and q'):

- every d_i >= sigma1: the command, passed through (clipped to the torque limits);
- some d_i < sigma1, none < sigma2: a null-space controller (Khatib 1987) replaces the
  command: tau = J^T Lambda (-hold_damping x') + (I - J^T Jbar^T) tau_0 + C q' + g, with
  tau_0 = sum_i null_gain M_ii (sigma1 - d_i) s_i e_i - null_damping M q' (s_i = +1 at
  the lower limit, -1 at the upper: away from it), Lambda = (J M^-1 J^T)^-1 and
  Jbar = M^-1 J^T Lambda the dynamically consistent inverse. The first term brakes the
  end effector (the thesis: "without changing the end-effector pose"; keeping the
  command's end-effector force instead let a policy drive the joint to its limit,
  docs/cip.md). The null-space term gives no end-effector acceleration
  (J M^-1 (I - J^T Jbar^T) = 0) and, at rest, accelerates joint i away from its limit:
  its acceleration is null_gain M_ii (sigma1 - d_i) s_i [M^-1 - Jbar J M^-1]_ii and the
  bracket is positive semi-definite (zero only if joint i cannot move without moving
  the end effector: the iiwa's elbow, joint 4, whose angle the shoulder-wrist distance
  fixes);
- some d_i < sigma2: tau = C q' + g + a_i M_ii s_i on each such joint (nothing more on
  the others): a torque away from the limit, scaled by the joint's own inertia, with
  a_i (`stopping_acceleration`) at least push_acceleration, what stops a joint moving
  toward its limit halfway between B's threshold and sigma2, and the most allowed
  (max_push_acceleration, then the torque limits) once past that point. Only the joint's
  own torque: the whole column M e_i (a free arm's acceleration of joint i alone) moved
  the other joints too, and with the hand on a handle a closing finger then pressed the
  wrist on into its limit against 6.5 N m (docs/cip.md); "until safe again": once
  d_i >= sigma2 the null-space controller takes over until d_i >= sigma1.

The stiffness cap (`cap_stiffness`) limits the VICES command's k_p (k_d follows, same
damping ratio). Torque limits and joint limits are passed in (the iiwa's are in
`artic.sim.robot`, a higher floor). Pure numpy.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, ValidationInfo, field_validator

from artic.config.schemas import Strict
from artic.control.osc import ArmState, VicesCommand, inverse

F64 = NDArray[np.float64]
EnvelopeMode = Literal["pass", "null_space", "push"]


class SafetyConfig(Strict):
    """The safety envelope sigma. Fields are declared threshold first so that each
    threshold's check sees the one below it (sigma1 > sigma2 > limit_threshold)."""

    enabled: bool = Field(True, description="apply the envelope; off: torques clipped only")
    limit_threshold: float = Field(
        0.1, gt=0, description="B's joint-limit distance ending an episode, rad (thesis: 5 deg)"
    )
    sigma2: float = Field(
        0.2, gt=0, description="joint-limit distance below which a torque pushes away, rad"
    )
    sigma1: float = Field(
        0.3,
        gt=0,
        description="joint-limit distance below which the null-space controller runs, rad",
    )
    kp_max: float = Field(
        150.0, gt=0, description="stiffness cap k_p under the envelope (VICES kp_max without it)"
    )
    null_gain: float = Field(
        200.0, ge=0, description="null-space push per rad inside sigma1, times M_ii, 1/s^2"
    )
    null_damping: float = Field(10.0, ge=0, description="null-space joint damping, 1/s")
    hold_damping: float = Field(
        20.0, ge=0, description="end-effector braking in the null-space mode, 1/s"
    )
    push_acceleration: float = Field(
        20.0,
        gt=0,
        description="least joint acceleration away from the limit inside sigma2, rad/s^2",
    )
    max_push_acceleration: float = Field(
        5000.0, gt=0, description="largest push acceleration, rad/s^2 (then the torque limits)"
    )

    @field_validator("sigma2")
    @classmethod
    def _sigma2_above_threshold(cls, sigma2: float, info: ValidationInfo) -> float:
        threshold = info.data.get("limit_threshold")
        if threshold is not None and sigma2 <= threshold:
            raise ValueError(f"sigma2 {sigma2} must exceed limit_threshold {threshold}")
        return sigma2

    @field_validator("sigma1")
    @classmethod
    def _sigma1_above_sigma2(cls, sigma1: float, info: ValidationInfo) -> float:
        sigma2 = info.data.get("sigma2")
        if sigma2 is not None and sigma1 <= sigma2:
            raise ValueError(f"sigma1 {sigma1} must exceed sigma2 {sigma2}")
        return sigma1


class LimitDistance(NamedTuple):
    """distance: (n,) rad from each joint to its nearer limit (negative beyond it);
    away: (n,) +1 where the nearer limit is the lower one, -1 the upper."""

    distance: F64
    away: F64


class SafeTorque(NamedTuple):
    """torque: (n,) N m to apply, within the torque limits; mode: which branch of the
    envelope produced it; joints: the joints that triggered it (inside sigma1 or
    sigma2), ascending."""

    torque: F64
    mode: EnvelopeMode
    joints: tuple[int, ...]


def limit_distance(q: F64, low: F64, high: F64) -> LimitDistance:
    """Each joint's distance to its nearer limit and the direction away from it."""
    q = np.asarray(q, dtype=np.float64)
    to_low, to_high = q - np.asarray(low), np.asarray(high) - q
    away = np.where(to_low <= to_high, 1.0, -1.0)
    return LimitDistance(np.minimum(to_low, to_high), away)


def braked_distance(limits: LimitDistance, qd: F64, deceleration: float) -> F64:
    """(n,) each joint's distance to its nearer limit once braked to rest at
    `deceleration` rad/s^2: d_i - max(v_i, 0)^2 / (2 deceleration), v_i its speed toward
    that limit (negative: beyond reach of a stop before it). At rest, d_i."""
    toward = np.maximum(-limits.away * np.asarray(qd, dtype=np.float64), 0.0)
    return np.asarray(limits.distance - toward**2 / (2.0 * deceleration), np.float64)


def stopping_acceleration(limits: LimitDistance, qd: F64, cfg: SafetyConfig) -> F64:
    """(n,) the push's acceleration away from each joint's nearer limit, rad/s^2: at
    least `push_acceleration`, and for a joint moving toward its limit what stops it
    halfway between B's threshold and sigma2, v^2 / (2 (d - stop)); past that point,
    whatever its speed, `max_push_acceleration`, the most allowed (then the torque
    limits): a disturbance, the hand's contact pressing the wrist on, meets the full
    push rather than one that grows only with its speed."""
    toward = np.maximum(-limits.away * np.asarray(qd, dtype=np.float64), 0.0)
    room = limits.distance - 0.5 * (cfg.limit_threshold + cfg.sigma2)
    with np.errstate(divide="ignore"):
        needed = np.where(room > 0, toward**2 / (2.0 * np.maximum(room, 1e-12)), np.inf)
    return np.clip(needed, cfg.push_acceleration, cfg.max_push_acceleration)


def cap_stiffness(command: VicesCommand, kp_max: float) -> VicesCommand:
    """The command with k_p clipped to kp_max and k_d scaled by sqrt(k_p' / k_p), which
    keeps the damping ratio of each axis."""
    kp_pos, kp_ori = np.minimum(command.kp_pos, kp_max), np.minimum(command.kp_ori, kp_max)
    return command._replace(
        kp_pos=kp_pos,
        kp_ori=kp_ori,
        kd_pos=command.kd_pos * np.sqrt(kp_pos / command.kp_pos),
        kd_ori=command.kd_ori * np.sqrt(kp_ori / command.kp_ori),
    )


def null_space_torque(jacobian: F64, mass: F64, tau_0: F64) -> F64:
    """(I - J^T Jbar^T) tau_0 (n,): the part of tau_0 (n,) that gives the end effector
    (J: (6, n)) no acceleration, with the dynamically consistent inverse Jbar = M^-1 J^T
    (J M^-1 J^T)^-1 (Khatib 1987; M: (n, n))."""
    mass_inv = np.linalg.inv(mass)
    lam = inverse(jacobian @ mass_inv @ jacobian.T)
    jbar = mass_inv @ jacobian.T @ lam
    return np.asarray(tau_0 - jacobian.T @ (jbar.T @ tau_0), np.float64)


def limit_avoidance_torque(
    state: ArmState, limits: LimitDistance, joints: NDArray[np.bool_], cfg: SafetyConfig
) -> F64:
    """tau_0 (n,) of the null-space mode: a torque away from the limit on each joint i
    inside sigma1 (`joints`: boolean (n,)), null_gain M_ii (sigma1 - d_i) (scaled by the
    joint's own inertia, so that the wrist and the shoulder move alike), and
    mass-weighted damping of the joint velocities."""
    depth = np.where(joints, cfg.sigma1 - limits.distance, 0.0)
    push = cfg.null_gain * np.diag(state.mass) * depth * limits.away
    return push - cfg.null_damping * (state.mass @ state.qd)


def envelope_torque(
    state: ArmState,
    command: F64,
    low: F64,
    high: F64,
    torque_limits: F64,
    cfg: SafetyConfig,
) -> SafeTorque:
    """The torque (n,) the envelope applies for the commanded torque `command` (n,) at
    `state`, joint limits low, high (n,) rad and torque limits (n,) N m (module
    docstring). Without the envelope (`cfg.enabled` false): the command, clipped."""
    limit = np.asarray(torque_limits, dtype=np.float64)
    command = np.asarray(command, dtype=np.float64)
    limits = limit_distance(state.q, low, high)
    ahead = braked_distance(limits, state.qd, cfg.push_acceleration)
    inside2, inside1 = ahead < cfg.sigma2, ahead < cfg.sigma1
    if not cfg.enabled or not inside1.any():
        return SafeTorque(np.clip(command, -limit, limit), "pass", ())
    if inside2.any():
        accel = stopping_acceleration(limits, state.qd, cfg)
        push = np.diag(state.mass) * np.where(inside2, accel * limits.away, 0.0)
        torque = np.clip(state.bias + push, -limit, limit)
        return SafeTorque(torque, "push", tuple(int(i) for i in np.flatnonzero(inside2)))
    jac = state.ee_jacobian
    mass_inv = np.linalg.inv(state.mass)
    lam = inverse(jac @ mass_inv @ jac.T)
    hold = jac.T @ (lam @ (-cfg.hold_damping * (jac @ state.qd)))
    tau_0 = limit_avoidance_torque(state, LimitDistance(ahead, limits.away), inside1, cfg)
    torque = hold + null_space_torque(jac, state.mass, tau_0) + state.bias
    joints = tuple(int(i) for i in np.flatnonzero(inside1))
    return SafeTorque(np.clip(torque, -limit, limit), "null_space", joints)
