"""RMP algebra in closed form (section 6.2.2), the collision damper (Eq. 6.5) and the
reduction of RMP-VICES to VICES without obstacles (section 6.3.2)."""

from __future__ import annotations

import numpy as np

from artic.control.osc import (
    ArmState,
    VicesConfig,
    axis_angle_matrix,
    joint_acceleration,
    vices_command,
    vices_torque,
)
from artic.control.rmp import (
    CollisionRmpConfig,
    ControlPoints,
    JointLimitRmpConfig,
    Plane,
    Rmp,
    RmpConfig,
    Sphere,
    collision_damper,
    collision_metric,
    combine,
    pullback,
    resolve,
    rmp_vices_acceleration,
)


def _spd(rng, n):
    a = rng.normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


def test_one_leaf_on_the_identity_map_resolves_to_its_own_acceleration():
    rng = np.random.default_rng(0)
    M, a = _spd(rng, 4), rng.normal(size=4)
    pulled = pullback(Rmp(M @ a, M), np.eye(4))
    assert np.allclose(resolve(pulled), a)


def test_two_leaves_on_one_map_give_the_metric_weighted_mean():
    rng = np.random.default_rng(1)
    M1, M2 = _spd(rng, 3), _spd(rng, 3)
    a1, a2 = rng.normal(size=3), rng.normal(size=3)
    both = combine([Rmp(M1 @ a1, M1), Rmp(M2 @ a2, M2)])
    expected = np.linalg.solve(M1 + M2, M1 @ a1 + M2 @ a2)
    assert np.allclose(resolve(both), expected)


def test_a_linear_map_pulls_back_to_At_f_and_At_M_A():
    rng = np.random.default_rng(2)
    A, M, f = rng.normal(size=(3, 5)), _spd(rng, 3), rng.normal(size=3)
    pulled = pullback(Rmp(f, M), A)
    assert np.allclose(pulled.f, A.T @ f)
    assert np.allclose(pulled.M, A.T @ M @ A)
    # the curvature term enters as -M J'q'
    jdot = rng.normal(size=3)
    assert np.allclose(pullback(Rmp(f, M), A, jdot).f, A.T @ (f - M @ jdot))


def test_a_zero_metric_adds_nothing_and_a_singular_metric_gives_no_nan():
    rng = np.random.default_rng(3)
    M, a = _spd(rng, 3), rng.normal(size=3)
    base = Rmp(M @ a, M)
    zero = Rmp(np.zeros(3), np.zeros((3, 3)))
    assert np.allclose(resolve(combine([base, zero])), resolve(base))
    singular = pullback(Rmp(np.ones(2), np.eye(2)), rng.normal(size=(2, 5)))  # rank 2 of 5
    qdd = resolve(singular)
    assert np.all(np.isfinite(qdd))
    assert np.all(np.isfinite(resolve(zero)))


def test_collision_metric_is_zero_receding_and_grows_approaching():
    cfg = CollisionRmpConfig(repulsion=0.0)  # Eq. 6.5's damper alone
    y = np.array([0.2, 0.2, 0.1, 0.05])
    yd = np.array([0.1, -0.1, -0.1, -0.1])
    m = collision_metric(y, yd, cfg)
    assert m[0] == 0.0  # receding: off (the thesis' max(y', 0) would be on here)
    assert 0 < m[1] < m[2] < m[3]
    f, _ = collision_damper(y, yd, cfg)
    assert f[0] == 0.0 and np.all(f[1:] > 0)  # damping opposes the approach


def test_a_point_attracted_through_a_sphere_stops_short_of_its_surface():
    """A point in R^3 attracted to a goal behind a sphere (k_p = 100, metric I), with the
    Eq. 6.5 damper (alone) on its distance to the sphere: it never reaches the surface."""
    cfg = CollisionRmpConfig(repulsion=0.0)
    centre, radius = np.zeros(3), 0.05
    x, v, goal, dt = np.array([-0.3, 0.0, 0.0]), np.zeros(3), np.array([0.3, 0, 0]), 1e-3
    closest = np.inf
    for _ in range(5000):
        rel = x - centre
        dist = float(np.linalg.norm(rel))
        u = rel / dist
        y, yd = dist - radius, float(u @ v)
        curvature = (v @ v - yd**2) / dist
        f, m = collision_damper(np.array([y]), np.array([yd]), cfg)
        leaves = [
            Rmp(100 * (goal - x) - 20 * v, np.eye(3)),
            pullback(Rmp(f, np.array([[m[0]]])), u[None, :], np.array([curvature])),
        ]
        a = resolve(combine(leaves))
        v = v + a * dt
        x = x + v * dt
        closest = min(closest, float(np.linalg.norm(x - centre)) - radius)
    assert closest > 0.0


def _closest_approach(cfg: CollisionRmpConfig, kp: float, seconds: float) -> float:
    """A point pulled toward a sphere's centre by an attractor (metric 1, critically
    damped) along a line, with the collision leaf on its distance: the least distance
    to the surface over `seconds`, m."""
    radius, x, v, dt = 0.05, -0.3, 0.0, 1e-3
    closest = np.inf
    for _ in range(round(seconds / dt)):
        y, yd = -x - radius, -v
        f, m = collision_damper(np.array([y]), np.array([yd]), cfg)
        leaves = [Rmp(np.array([kp * (0.0 - x) - 2 * np.sqrt(kp) * v]), np.eye(1)),
                  pullback(Rmp(f, np.array([[m[0]]])), -np.eye(1))]  # fmt: skip
        v += float(resolve(combine(leaves))[0]) * dt
        x += v * dt
        closest = min(closest, -x - radius)
    return closest


def test_a_barrier_holds_off_what_the_damper_alone_lets_creep_onto_the_surface():
    """Pressed toward a sphere for 40 s (k_p 300), the damper alone (Eq. 6.5, metric 0
    at rest) lets the point creep into it (measured: 1.6 cm deep); with the barrier
    (the default, repulsion 20) it rests 3 cm off; the barrier adds nothing when switched
    off."""
    damper = CollisionRmpConfig(repulsion=0.0)
    barrier = CollisionRmpConfig()
    assert _closest_approach(damper, 300.0, 40.0) < 0.0
    assert _closest_approach(barrier, 300.0, 40.0) > 0.02
    y, yd = np.array([0.01, 0.2]), np.array([0.0, 0.0])
    for f, m in (collision_damper(y, yd, damper), collision_damper(y, yd, barrier, False)):
        assert np.all(f == 0) and np.all(m == 0)
    f, m = collision_damper(y, yd, barrier)
    assert np.all(f > 0) and np.all(m > 0) and f[0] > f[1]


def test_the_barrier_acts_on_spheres_and_on_planes_only_when_asked():
    """A control point at rest 1 cm from a plane or a sphere: the sphere's barrier changes
    q''; the plane's (the table, the door panel) only with `repulsion_planes`."""
    rng = np.random.default_rng(7)
    state = _random_state(rng)
    vices = VicesConfig()
    cmd = vices_command(np.zeros(12), state.ee_position, state.ee_rotation, vices)
    limits = (np.full(7, -3.0), np.full(7, 3.0))
    jac = rng.normal(size=(1, 3, 7))
    points = ControlPoints(
        positions=np.array([[0.0, 0.0, 0.06]]),
        velocities=np.zeros((1, 3)),
        jacobians=jac,
        jdot_qdot=np.zeros((1, 3)),
        radii=np.array([0.05]),
    )
    plane, sphere = Plane(np.array([0.0, 0.0, 1.0]), 0.0), Sphere(np.array([0.0, 0.0, 0.16]), 0.05)

    def qdd(obstacle, **collision):
        cfg = RmpConfig(collision=CollisionRmpConfig(**collision))
        return rmp_vices_acceleration(state, cmd, state.q, limits, points, [obstacle], vices, cfg)

    assert np.array_equal(qdd(plane), qdd(plane, repulsion=0.0))
    assert not np.allclose(qdd(plane, repulsion_planes=True), qdd(plane, repulsion=0.0))
    assert not np.allclose(qdd(sphere), qdd(sphere, repulsion=0.0))


def _random_state(rng, at_rest=True):
    n = 7
    a = rng.normal(size=(n, n))
    mass = a @ a.T + np.eye(n)
    return ArmState(
        q=rng.uniform(-1, 1, n),
        qd=np.zeros(n) if at_rest else rng.normal(size=n),
        mass=mass,
        bias=rng.normal(size=n),
        ee_position=rng.normal(size=3),
        ee_rotation=axis_angle_matrix(rng.normal(size=3)),
        ee_jacobian=rng.normal(size=(6, n)),
        ee_jdot_qdot=np.zeros(6) if at_rest else rng.normal(size=6),
    )


def test_without_obstacles_rmp_vices_gives_vices_end_effector_acceleration():
    """No obstacles, joint-limit metric 0, at rest: the same J q'' (1e-6) at 20 random
    configurations (section 6.3.2: the tree then reduces to VICES)."""
    rng = np.random.default_rng(4)
    vices = VicesConfig()
    cfg = RmpConfig(joint_limit=JointLimitRmpConfig(metric=0.0))
    limits = (np.full(7, -3.0), np.full(7, 3.0))
    for _ in range(20):
        state = _random_state(rng)
        cmd = vices_command(rng.uniform(-1, 1, 12), state.ee_position, state.ee_rotation, vices)
        rest = rng.uniform(-1, 1, 7)
        qdd_vices = joint_acceleration(state, vices_torque(state, cmd, rest, vices))
        qdd_rmp = rmp_vices_acceleration(state, cmd, rest, limits, None, [], vices, cfg)
        J = state.ee_jacobian
        assert np.allclose(J @ qdd_rmp, J @ qdd_vices, atol=1e-6)
