"""RMP-VICES (thesis section 6.3, Fig. 6.1): the VICES impedance command as attractor
RMPs, blended with collision-avoidance and joint-limit RMPs by RMPflow.

The algebra (Cheng et al. 2021, "RMPflow"; thesis section 6.2.2), in natural form: a
leaf on a task space y = phi(q) returns a force f_i = M_i a_i and a metric M_i; the
pullback through J = d phi / dq gives

    f = sum_i J_i^T (f_i - M_i J_i' q'),    M = sum_i J_i^T M_i J_i,    q'' = M^+ f

(`pullback`, `resolve`: the Moore-Penrose inverse, so a singular M gives no NaN).

Leaves of the tree (`rmp_vices_acceleration`):
- R^3 attractor on the end-effector point, a = k_p (x_g - x) - k_d x', metric I (Eq.
  6.2, with the sign fixed: the thesis prints k_p (x - x_g), which repels);
- SO(3) attractor on its angular velocity, a = k_p e_r(R, R_g) - k_d omega, metric I
  (Eq. 6.4, e_r of Eq. 6.3);
- one damper per (control point, obstacle) on the distance y to a plane or a sphere
  (minus the point's radius): metric m = s max(-y', 0)^2 / y^4 (Eq. 6.5 with the sign
  fixed: the thesis prints max(y', 0), which switches on while the distance grows) and
  a = -eta y': no repulsion, only the approach is damped (section 6.3.3); on the
  spheres (not on the task's planes, unless `repulsion_planes`) a barrier after
  RMPflow's collision RMP joins it (`repulsion` k_r, ours; 0: Eq. 6.5 alone);
- joint-limit leaves on each joint's distance to its lower and upper limit (after Cheng
  et al. 2021's joint-limit RMP, our constants): m = lambda exp(-x / l), a = k_p exp(-x /
  l) - k_d x';
- the null-space posture term of VICES (section 2.1.2), projected into the null space of
  the end-effector Jacobian after the resolve, so that without obstacles and with a zero
  joint-limit metric the tree gives VICES' end-effector acceleration (Eq. 6.1).
Torques: tau = M(q) q'' + C q' + g (section 6.3.4).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from artic.config.schemas import Strict
from artic.control.osc import (
    ArmState,
    VicesCommand,
    VicesConfig,
    inverse,
    orientation_error,
    posture_acceleration,
)

F64 = NDArray[np.float64]


class CollisionRmpConfig(Strict):
    """The collision dampers (Eq. 6.5, section 6.3.3)."""

    eta: float = Field(20.0, ge=0, description="damping coefficient eta of a = -eta y', 1/s")
    metric_scale: float = Field(1.0, ge=0, description="s of m = s max(-y', 0)^2 / y^4")
    min_distance: float = Field(
        0.005, gt=0, description="distances are floored here in the metric (contact), m"
    )
    repulsion: float = Field(
        20.0,
        ge=0,
        description="k_r of a barrier a += k_r exp(-y / l_r), m/s^2, with metric "
        "w exp(-y / l_r) (RMPflow's collision RMP; ours); 0: Eq. 6.5's damper alone",
    )
    repulsion_length: float = Field(0.03, gt=0, description="l_r of the barrier, m")
    repulsion_metric: float = Field(3.0, ge=0, description="w of the barrier's metric")
    repulsion_planes: bool = Field(
        False,
        description="the barrier also on the planes (the table, the door panel: surfaces "
        "the task works at); false: on the spheres only",
    )


class JointLimitRmpConfig(Strict):
    """The joint-limit leaves (after Cheng et al. 2021; constants ours, docs/rmp.md)."""

    metric: float = Field(10.0, ge=0, description="lambda of m = lambda exp(-x / l); 0: off")
    length_scale: float = Field(0.2, gt=0, description="l, rad")
    kp: float = Field(20.0, ge=0, description="repulsion k_p of a = k_p exp(-x / l), rad/s^2")
    kd: float = Field(5.0, ge=0, description="damping k_d of a = ... - k_d x', 1/s")


class RmpConfig(Strict):
    """The RMP-VICES tree (section 6.3)."""

    collision: CollisionRmpConfig = Field(default_factory=CollisionRmpConfig)
    joint_limit: JointLimitRmpConfig = Field(default_factory=JointLimitRmpConfig)
    rcond: float = Field(1e-8, gt=0, description="relative cutoff of the pseudo-inverse of M")


class Rmp(NamedTuple):
    """An RMP in natural form on an n-dimensional space: force f (n,) = M a, metric M
    (n, n)."""

    f: F64
    M: F64


class ControlPoints(NamedTuple):
    """Points fixed to the arm's links, world frame: positions (P, 3) m, velocities (P,
    3) m/s, jacobians (P, 3, 7), jdot_qdot (P, 3) m/s^2, radii (P,) m (the link's
    thickness around the point)."""

    positions: F64
    velocities: F64
    jacobians: F64
    jdot_qdot: F64
    radii: F64


class Plane(NamedTuple):
    """The half-space n . x >= offset is free: normal (3,) unit, offset m."""

    normal: F64
    offset: float


class Sphere(NamedTuple):
    """A ball: centre (3,) m, radius m."""

    centre: F64
    radius: float


# -- algebra ---------------------------------------------------------------------------


def pullback(rmp: Rmp, jacobian: F64, jdot_qdot: F64 | None = None) -> Rmp:
    """The RMP (f, M) of a child space pulled back through its map's Jacobian J (n, d):
    (J^T (f - M J' q'), J^T M J); jdot_qdot (n,) is J' q' (None: 0, a linear map)."""
    f = rmp.f if jdot_qdot is None else rmp.f - rmp.M @ jdot_qdot
    return Rmp(jacobian.T @ f, jacobian.T @ rmp.M @ jacobian)


def combine(rmps: Sequence[Rmp]) -> Rmp:
    """The sum of RMPs on one space (the pullback's sum over children)."""
    return Rmp(sum(r.f for r in rmps), sum(r.M for r in rmps))  # type: ignore[arg-type]


def resolve(rmp: Rmp, rcond: float = 1e-8) -> F64:
    """The acceleration a = M^+ f (Moore-Penrose; finite for a singular M): from the
    eigendecomposition of the symmetric metric, eigenvalues below rcond x the largest
    treated as 0 (what `np.linalg.pinv(hermitian=True)` does, without its overhead)."""
    values, vectors = np.linalg.eigh(rmp.M)
    top = float(np.max(np.abs(values))) if len(values) else 0.0
    keep = np.abs(values) > rcond * top
    if not keep.any():
        return np.zeros(len(rmp.f))
    kept = vectors[:, keep]
    return np.asarray(kept @ ((kept.T @ rmp.f) / values[keep]), np.float64)


# -- leaves ----------------------------------------------------------------------------


def attractor(x: F64, xd: F64, goal: F64, kp: F64, kd: F64) -> Rmp:
    """Eq. 6.2 (sign fixed): a = k_p (x_g - x) - k_d x', metric I; all (n,)."""
    a = kp * (goal - x) - kd * xd
    return Rmp(a, np.eye(len(a)))


def rotation_attractor(rotation: F64, omega: F64, goal: F64, kp: F64, kd: F64) -> Rmp:
    """Eq. 6.4: a = k_p e_r(R, R_g) - k_d omega on the angular velocity, metric I."""
    a = kp * orientation_error(rotation, goal) - kd * omega
    return Rmp(a, np.eye(3))


def collision_metric(y: F64, yd: F64, cfg: CollisionRmpConfig) -> F64:
    """Eq. 6.5 (sign fixed): m = s max(-y', 0)^2 / y^4, y floored at min_distance; (n,)."""
    y = np.maximum(np.asarray(y, dtype=np.float64), cfg.min_distance)
    approach = np.maximum(-np.asarray(yd, dtype=np.float64), 0.0)
    return cfg.metric_scale * approach**2 / y**4


def collision_damper(
    y: F64, yd: F64, cfg: CollisionRmpConfig, barrier: bool = True
) -> tuple[F64, F64]:
    """Scalar leaves on distances y (n,) with rates yd (n,): (forces m a (n,), metrics m
    (n,)) with a = -eta y' (section 6.3.3: damping only, no repulsion). With `barrier`
    and `cfg.repulsion` > 0 a barrier joins it: a += k_r exp(-y / l_r), m += w exp(-y /
    l_r) (y floored at 0), which holds a point off an obstacle it creeps toward, where the
    damper's metric vanishes with y'."""
    m = collision_metric(y, yd, cfg)
    a = -cfg.eta * np.asarray(yd)
    if barrier and cfg.repulsion > 0:
        decay = np.exp(-np.maximum(np.asarray(y, dtype=np.float64), 0.0) / cfg.repulsion_length)
        a = a + cfg.repulsion * decay
        m = m + cfg.repulsion_metric * decay
    return m * a, m


class Distances(NamedTuple):
    """Distances of control points to one obstacle: y (P,) m (surface to surface),
    rates yd (P,), gradients (P, 3) (d y / d x), curvature (P,) (the part of y'' from
    the map's own curvature at the point's velocity)."""

    y: F64
    yd: F64
    gradient: F64
    curvature: F64


def plane_distances(points: ControlPoints, plane: Plane) -> Distances:
    """y = n . x - offset - radius (a linear map: no curvature)."""
    n = np.asarray(plane.normal, dtype=np.float64)
    y = points.positions @ n - plane.offset - points.radii
    gradient = np.broadcast_to(n, points.positions.shape)
    return Distances(y, points.velocities @ n, gradient, np.zeros(len(y)))


def sphere_distances(points: ControlPoints, sphere: Sphere) -> Distances:
    """y = |x - c| - R - radius; its Hessian (I - u u^T) / |x - c| gives the curvature
    x'^T (I - u u^T) x' / |x - c|."""
    rel = points.positions - np.asarray(sphere.centre)
    norm = np.maximum(np.linalg.norm(rel, axis=1), 1e-9)
    u = rel / norm[:, None]
    v = points.velocities
    yd = np.einsum("pi,pi->p", u, v)
    curvature = (np.einsum("pi,pi->p", v, v) - yd**2) / norm
    return Distances(norm - sphere.radius - points.radii, yd, u, curvature)


def collision_rmp(
    points: ControlPoints, distances: Distances, cfg: CollisionRmpConfig, barrier: bool = True
) -> Rmp:
    """The dampers (and with `barrier` the barrier) on every control point for one
    obstacle, pulled back to joint space (7,): J_y = u^T J_x, J_y' q' = u^T J_x' q' +
    curvature."""
    f, m = collision_damper(distances.y, distances.yd, cfg, barrier)
    jy = np.einsum("pi,pij->pj", distances.gradient, points.jacobians)  # (P, 7)
    jdot = np.einsum("pi,pi->p", distances.gradient, points.jdot_qdot) + distances.curvature
    force = jy.T @ (f - m * jdot)
    metric = (jy * m[:, None]).T @ jy
    return Rmp(force, metric)


def joint_limit_rmp(q: F64, qd: F64, low: F64, high: F64, cfg: JointLimitRmpConfig) -> Rmp:
    """Joint-limit leaves on x = q - low (J = I) and x = high - q (J = -I), pulled back
    and summed: a diagonal metric (7, 7)."""
    force = np.zeros(len(q))
    metric = np.zeros(len(q))
    for x, xd, sign in ((q - low, qd, 1.0), (high - q, -qd, -1.0)):
        w = np.exp(-np.maximum(x, 0.0) / cfg.length_scale)
        m = cfg.metric * w
        a = cfg.kp * w - cfg.kd * xd
        force += sign * m * a
        metric += m
    return Rmp(force, np.diag(metric))


# -- the tree --------------------------------------------------------------------------


def rmp_vices_acceleration(
    state: ArmState,
    command: VicesCommand,
    rest: F64,
    limits: tuple[F64, F64],
    points: ControlPoints | None,
    obstacles: Sequence[Plane | Sphere],
    vices: VicesConfig,
    cfg: RmpConfig,
) -> F64:
    """q'' (7,) of the RMP-VICES tree (module docstring): the end-effector attractors of
    `command`, the dampers of `points` against `obstacles`, the joint-limit leaves of
    `limits` (low (7,), high (7,)) and VICES' null-space posture toward `rest`."""
    jac, jdot = state.ee_jacobian, state.ee_jdot_qdot
    twist = jac @ state.qd
    leaves = [
        pullback(
            attractor(
                state.ee_position, twist[:3], command.goal_position, command.kp_pos, command.kd_pos
            ),
            jac[:3],
            jdot[:3],
        ),
        pullback(
            rotation_attractor(
                state.ee_rotation, twist[3:], command.goal_rotation, command.kp_ori, command.kd_ori
            ),
            jac[3:],
            jdot[3:],
        ),
    ]
    if cfg.joint_limit.metric > 0:
        leaves.append(joint_limit_rmp(state.q, state.qd, *limits, cfg.joint_limit))
    if points is not None and len(points.radii) and cfg.collision.metric_scale > 0:
        for obstacle in obstacles:
            if isinstance(obstacle, Plane):
                distances, barrier = (
                    plane_distances(points, obstacle),
                    cfg.collision.repulsion_planes,
                )
            else:
                distances, barrier = sphere_distances(points, obstacle), True
            leaves.append(collision_rmp(points, distances, cfg.collision, barrier))
    qdd = resolve(combine(leaves), cfg.rcond)
    null = np.eye(len(state.q)) - jac.T @ inverse(jac @ jac.T) @ jac  # I - J^+ J
    return qdd + null @ posture_acceleration(state, rest, vices)


def rmp_torque(state: ArmState, qdd: F64) -> F64:
    """Section 6.3.4: tau = M(q) q'' + C(q, q') q' + g(q), (7,). Unclipped."""
    return state.mass @ qdd + state.bias
