"""VICES: variable impedance control in end-effector space (thesis Eq. 6.1 = Eq. 2.8,
section 2.1.2; Martin-Martin et al. 2019), the operational-space controller of Chapter 6.

An action a in [-1, 1]^12 is (delta position, delta rotation (axis-angle), k_p^pos,
k_p^ori): `vices_command` scales it to a goal pose (delta p at most `position_scale` m,
delta r at most `rotation_scale` rad, composed with the current end-effector pose) and
stiffnesses in [kp_min, kp_max], with k_d = 2 sqrt(k_p) (critical damping of a unit
mass). `vices_torque` turns the command into joint torques (Khatib's operational space
control):

    a_d = [k_p^pos (p_g - p) - k_d^pos v ;  k_p^ori e_r(R, R_g) - k_d^ori omega]
    tau = J^T Lambda a_d + (I - J^T Jbar^T) M (k_null (q_0 - q) - d_null q') + C q' + g

with Lambda = (J M^-1 J^T)^-1 the 6 x 6 end-effector inertia (Eq. 6.1 writes its
position and orientation blocks; the coupled matrix is used here, so that J q'' = a_d
exactly, which the RMP form reproduces, see `artic.control.rmp`), Jbar = M^-1 J^T
Lambda the dynamically consistent inverse and the null-space posture term of section
2.1.2. Pure numpy; the simulator supplies the `ArmState`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from artic.config.schemas import Strict

F64 = NDArray[np.float64]
ACTION_DIM = 12


class VicesConfig(Strict):
    """The VICES action space and its operational-space controller."""

    position_scale: float = Field(0.05, gt=0, description="largest goal displacement, m")
    rotation_scale: float = Field(0.5, gt=0, description="largest goal rotation, rad")
    kp_min: float = Field(10.0, gt=0, description="smallest stiffness k_p (action -1)")
    kp_max: float = Field(300.0, gt=0, description="largest stiffness k_p (action +1)")
    damping_ratio: float = Field(
        1.0, gt=0, description="k_d = 2 ratio sqrt(k_p); 1: critically damped"
    )
    null_kp: float = Field(10.0, ge=0, description="null-space posture stiffness, 1/s^2")
    null_damping_ratio: float = Field(1.0, ge=0, description="null-space k_d = 2 ratio sqrt(k)")

    @model_validator(mode="after")
    def _kp_range(self) -> VicesConfig:
        if self.kp_min > self.kp_max:
            raise ValueError(f"kp_min {self.kp_min} exceeds kp_max {self.kp_max}")
        return self


class ArmState(NamedTuple):
    """What the controllers read of the arm, world frame, SI units.

    q, qd: (7,) joint positions and velocities; mass: (7, 7) M(q); bias: (7,) C q' + g;
    ee_position: (3,); ee_rotation: (3, 3); ee_jacobian: (6, 7) [linear; angular] of the
    end-effector point; ee_jdot_qdot: (6,) its J' q'."""

    q: F64
    qd: F64
    mass: F64
    bias: F64
    ee_position: F64
    ee_rotation: F64
    ee_jacobian: F64
    ee_jdot_qdot: F64


class VicesCommand(NamedTuple):
    """The impedance set-point of one action: goal position (3,) m and rotation (3, 3);
    stiffness and damping (3,) each for position and orientation."""

    goal_position: F64
    goal_rotation: F64
    kp_pos: F64
    kp_ori: F64
    kd_pos: F64
    kd_ori: F64


def cross(a: F64, b: F64) -> F64:
    """Row-wise cross products of (..., 3) arrays (`np.cross`'s overhead dominates at
    this size, and the controllers run at every 240 Hz substep)."""
    a, b = np.asarray(a), np.asarray(b)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def skew(v: F64) -> F64:
    """(3, 3) cross-product matrix of v (3,): skew(v) w = v x w."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def axis_angle_matrix(rotvec: F64) -> F64:
    """(3, 3) rotation of the axis-angle vector rotvec (3,) (Rodrigues' formula)."""
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-12:
        return np.eye(3) + skew(rotvec)
    k = skew(np.asarray(rotvec) / angle)
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def orientation_error(rotation: F64, goal: F64) -> F64:
    """Eq. 6.3: e_r(r, r_g) = 1/2 (r_x x r_gx + r_y x r_gy + r_z x r_gz), (3,).

    rotation, goal: (3, 3) with the frame axes as columns. For goal = Rot(u, theta)
    rotation, e_r = sin(theta) u: it points from the current orientation to the goal."""
    return 0.5 * cross(rotation.T, goal.T).sum(axis=0)


def _clip_norm(v: F64, limit: float) -> F64:
    norm = float(np.linalg.norm(v))
    return v if norm <= limit else v * (limit / norm)


def stiffness(action: F64, cfg: VicesConfig) -> F64:
    """k_p (n,) from actions in [-1, 1] (n,), linearly onto [kp_min, kp_max]."""
    a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    return cfg.kp_min + 0.5 * (a + 1.0) * (cfg.kp_max - cfg.kp_min)


def vices_command(action: F64, position: F64, rotation: F64, cfg: VicesConfig) -> VicesCommand:
    """The set-point of action (12,) in [-1, 1] (clipped) at the end-effector pose
    (position (3,), rotation (3, 3)): p_g = p + dp, R_g = exp(dr) R with |dp| <=
    position_scale (dp = position_scale a[:3], its norm clipped) and likewise dr."""
    a = np.clip(np.asarray(action, dtype=np.float64).reshape(-1), -1.0, 1.0)
    if a.shape != (ACTION_DIM,):
        raise ValueError(f"VICES action: expected {ACTION_DIM} values, got {a.shape}")
    dp = _clip_norm(cfg.position_scale * a[:3], cfg.position_scale)
    dr = _clip_norm(cfg.rotation_scale * a[3:6], cfg.rotation_scale)
    kp_pos, kp_ori = stiffness(a[6:9], cfg), stiffness(a[9:12], cfg)
    ratio = 2.0 * cfg.damping_ratio
    return VicesCommand(
        goal_position=np.asarray(position, dtype=np.float64) + dp,
        goal_rotation=axis_angle_matrix(dr) @ rotation,
        kp_pos=kp_pos,
        kp_ori=kp_ori,
        kd_pos=ratio * np.sqrt(kp_pos),
        kd_ori=ratio * np.sqrt(kp_ori),
    )


def task_acceleration(state: ArmState, command: VicesCommand) -> F64:
    """a_d (6,): the impedance law of Eq. 6.1 / 6.2 / 6.4 (sign as Eq. 2.8: toward the
    goal), [k_p (p_g - p) - k_d v ; k_p e_r(R, R_g) - k_d omega]."""
    twist = state.ee_jacobian @ state.qd
    linear = command.kp_pos * (command.goal_position - state.ee_position)
    angular = command.kp_ori * orientation_error(state.ee_rotation, command.goal_rotation)
    return np.concatenate(
        [linear - command.kd_pos * twist[:3], angular - command.kd_ori * twist[3:]]
    )


def posture_acceleration(state: ArmState, rest: F64, cfg: VicesConfig) -> F64:
    """(7,) joint acceleration of the null-space posture term toward `rest` (7,)."""
    d = 2.0 * cfg.null_damping_ratio * np.sqrt(cfg.null_kp)
    return cfg.null_kp * (np.asarray(rest) - state.q) - d * state.qd


def vices_torque(state: ArmState, command: VicesCommand, rest: F64, cfg: VicesConfig) -> F64:
    """Joint torques (7,) of Eq. 6.1 with the null-space posture term toward `rest` (7,)
    and gravity / Coriolis compensation (module docstring). Unclipped."""
    jac, mass = state.ee_jacobian, state.mass
    mass_inv = np.linalg.inv(mass)
    lam = inverse(jac @ mass_inv @ jac.T)
    force = lam @ task_acceleration(state, command)
    jbar = mass_inv @ jac.T @ lam
    null = np.eye(len(state.q)) - jac.T @ jbar.T
    posture = mass @ posture_acceleration(state, rest, cfg)
    return jac.T @ force + null @ posture + state.bias


def inverse(matrix: F64) -> F64:
    """The inverse of a square matrix; the pseudo-inverse if it is singular (the arm at
    a kinematic singularity). LU, not SVD: this runs every substep."""
    try:
        return np.asarray(np.linalg.inv(matrix), np.float64)
    except np.linalg.LinAlgError:
        return np.asarray(np.linalg.pinv(matrix), np.float64)


def joint_acceleration(state: ArmState, torque: F64) -> F64:
    """q'' (7,) = M^-1 (tau - C q' - g): the free-space response to `torque` (7,)."""
    return np.asarray(np.linalg.solve(state.mass, np.asarray(torque) - state.bias), np.float64)
