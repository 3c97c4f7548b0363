"""The safety envelope sigma (thesis section 7.2.1): the null-space torque leaves the
end effector unaccelerated and moves the joint away from its limit, the push inside
sigma2 points away, far from the limits the command passes through (clipped), k_p is
capped, and the thresholds are validated.

M(q) and J(q) are the iiwa's, from PyBullet (as tests/sim/test_torque.py), at random
configurations within its joint limits."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from artic.control.osc import ArmState, VicesConfig, vices_command
from artic.control.safety import (
    SafetyConfig,
    braked_distance,
    cap_stiffness,
    envelope_torque,
    limit_distance,
    null_space_torque,
    stopping_acceleration,
)
from artic.sim.bullet import connect_direct
from artic.sim.robot import (
    IIWA7_TORQUE_LIMITS,
    N_JOINTS,
    TOOL_LINK,
    Robot,
    bias_forces,
    mass_matrix,
    point_jacobian,
)
from artic.sim.tasks import RobotConfig

LIMITS = np.asarray(IIWA7_TORQUE_LIMITS)
ELBOW = 3  # joint 4 of the iiwa


@pytest.fixture(scope="module")
def robot():
    client = connect_direct()
    client.setGravity(0.0, 0.0, -9.81)
    robot = Robot.load(client, RobotConfig())
    yield robot
    client.disconnect()


def arm_state(robot: Robot, q: np.ndarray, qd: np.ndarray | None = None) -> ArmState:
    qd = np.zeros(N_JOINTS) if qd is None else qd
    inertial = robot.client.getLinkState(robot.body, TOOL_LINK)[2]
    return ArmState(
        q=q,
        qd=qd,
        mass=mass_matrix(robot, q),
        bias=bias_forces(robot, q, qd),
        ee_position=np.zeros(3),
        ee_rotation=np.eye(3),
        ee_jacobian=point_jacobian(robot, TOOL_LINK, np.asarray(inertial), q),
        ee_jdot_qdot=np.zeros(6),
    )


def random_q(robot: Robot, rng: np.random.Generator, margin: float = 0.4) -> np.ndarray:
    low, high = robot.limits
    return rng.uniform(low + margin, high - margin)


def test_null_space_torque_gives_no_end_effector_acceleration(robot):
    rng = np.random.default_rng(0)
    for _ in range(20):
        state = arm_state(robot, random_q(robot, rng))
        tau_0 = rng.normal(scale=20.0, size=N_JOINTS)
        tau = null_space_torque(state.ee_jacobian, state.mass, tau_0)
        ee_acc = state.ee_jacobian @ np.linalg.solve(state.mass, tau)
        assert np.max(np.abs(ee_acc)) < 1e-6
        assert np.linalg.norm(tau) > 1e-3  # a 7-DoF arm keeps a 1-D null space


@pytest.mark.parametrize("upper", [False, True])
def test_inside_sigma1_the_joint_accelerates_away_and_the_end_effector_does_not(robot, upper):
    cfg = SafetyConfig()
    low, high = robot.limits
    rng = np.random.default_rng(1 + upper)
    command = rng.normal(scale=50.0, size=N_JOINTS)  # whatever the policy asked
    for joint in range(N_JOINTS):
        q = random_q(robot, rng)
        depth = 0.25  # between sigma2 and sigma1
        q[joint] = high[joint] - depth if upper else low[joint] + depth
        state = arm_state(robot, q)
        out = envelope_torque(state, command, low, high, LIMITS, cfg)
        assert out.mode == "null_space" and out.joints == (joint,)
        assert np.all(np.abs(out.torque) <= LIMITS)
        acc = np.linalg.solve(state.mass, out.torque - state.bias)
        assert np.max(np.abs(state.ee_jacobian @ acc)) < 1e-6
        away = -1.0 if upper else 1.0
        if joint == ELBOW:  # fixed by the shoulder-wrist distance: no null-space motion
            assert abs(acc[joint]) < 1e-9
        else:
            assert acc[joint] * away > 0.0


def test_the_elbow_is_outside_the_null_space(robot):
    """The iiwa is a spherical-shoulder, spherical-wrist arm: its one-dimensional null
    space (the elbow's swivel) never changes joint 4, so the null-space mode cannot move
    it; the sigma2 push is what keeps the elbow off its limits (docs/cip.md)."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        state = arm_state(robot, random_q(robot, rng))
        for joint in range(N_JOINTS):
            tau = null_space_torque(state.ee_jacobian, state.mass, np.eye(N_JOINTS)[joint])
            acc = np.linalg.solve(state.mass, tau)
            if joint == ELBOW:
                assert abs(acc[joint]) < 1e-9
            else:
                assert acc[joint] > 0.0


def test_inside_sigma2_the_torque_points_away_from_the_limit(robot):
    cfg = SafetyConfig()
    low, high = robot.limits
    rng = np.random.default_rng(3)
    for joint in range(N_JOINTS):
        for upper in (False, True):
            q = random_q(robot, rng)
            q[joint] = high[joint] - 0.15 if upper else low[joint] + 0.15
            qd = rng.normal(scale=0.5, size=N_JOINTS)
            state = arm_state(robot, q, qd)
            out = envelope_torque(state, np.full(N_JOINTS, 1e3), low, high, LIMITS, cfg)
            assert out.mode == "push" and out.joints == (joint,)
            assert np.all(np.abs(out.torque) <= LIMITS)
            away = -1.0 if upper else 1.0
            assert (out.torque - state.bias)[joint] * away > 0.0
            acc = np.linalg.solve(state.mass, out.torque - state.bias)
            assert acc[joint] * away > 0.0


def test_far_from_the_limits_the_command_passes_through_clipped(robot):
    cfg = SafetyConfig()
    low, high = robot.limits
    rng = np.random.default_rng(4)
    state = arm_state(robot, random_q(robot, rng, margin=cfg.sigma1 + 0.05))
    small = rng.uniform(-0.9, 0.9, size=N_JOINTS) * LIMITS
    out = envelope_torque(state, small, low, high, LIMITS, cfg)
    assert out.mode == "pass" and out.joints == ()
    assert np.array_equal(out.torque, small)
    big = 3.0 * LIMITS * np.sign(rng.normal(size=N_JOINTS))
    assert np.array_equal(envelope_torque(state, big, low, high, LIMITS, cfg).torque, big / 3.0)


def test_without_the_envelope_torques_are_only_clipped(robot):
    cfg = SafetyConfig(enabled=False)
    low, high = robot.limits
    q = random_q(robot, np.random.default_rng(5))
    q[3] = low[3] + 0.05  # inside sigma2
    state = arm_state(robot, q)
    command = np.linspace(-300.0, 300.0, N_JOINTS)
    out = envelope_torque(state, command, low, high, LIMITS, cfg)
    assert out.mode == "pass"
    assert np.array_equal(out.torque, np.clip(command, -LIMITS, LIMITS))


def test_limit_distance_and_direction():
    low, high = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    d = limit_distance(np.array([-0.9, 0.7]), low, high)
    assert np.allclose(d.distance, [0.1, 0.3])
    assert np.array_equal(d.away, [1.0, -1.0])


def test_stiffness_is_capped_and_the_damping_ratio_kept():
    vices, cfg = VicesConfig(), SafetyConfig()
    assert vices.kp_max == 300.0 and cfg.kp_max == 150.0  # without / with the envelope
    rng = np.random.default_rng(6)
    for _ in range(20):
        command = vices_command(rng.uniform(-1, 1, size=12), np.zeros(3), np.eye(3), vices)
        capped = cap_stiffness(command, cfg.kp_max)
        for kp, kd, kp0 in (
            (capped.kp_pos, capped.kd_pos, command.kp_pos),
            (capped.kp_ori, capped.kd_ori, command.kp_ori),
        ):
            assert np.all(kp <= cfg.kp_max)
            assert np.allclose(kp, np.minimum(kp0, cfg.kp_max))
            assert np.allclose(kd, 2.0 * np.sqrt(kp))
        assert np.array_equal(capped.goal_position, command.goal_position)


@pytest.mark.parametrize(
    ("fields", "name"),
    [
        ({"sigma1": 0.2, "sigma2": 0.2}, "sigma1"),
        ({"sigma1": 0.15, "sigma2": 0.2}, "sigma1"),
        ({"sigma2": 0.1}, "sigma2"),
        ({"sigma2": 0.08, "sigma1": 0.3}, "sigma2"),
    ],
)
def test_thresholds_out_of_order_are_refused_naming_the_field(fields, name):
    with pytest.raises(ValidationError) as error:
        SafetyConfig(**fields)
    assert error.value.errors()[0]["loc"] == (name,)


def test_the_envelope_is_deterministic(robot):
    low, high = robot.limits
    q = random_q(robot, np.random.default_rng(9))
    q[1] = high[1] - 0.25
    state = arm_state(robot, q, np.full(N_JOINTS, 0.1))
    a = envelope_torque(state, np.ones(N_JOINTS), low, high, LIMITS, SafetyConfig())
    b = envelope_torque(state, np.ones(N_JOINTS), low, high, LIMITS, SafetyConfig())
    assert a.torque.tobytes() == b.torque.tobytes()


@pytest.mark.parametrize("upper", [False, True])
@pytest.mark.parametrize("joint", range(N_JOINTS))
def test_in_closed_loop_the_envelope_keeps_a_driven_joint_off_its_limit(joint, upper):
    """PyBullet at 240 Hz, 1 s: joint `joint` starts 0.35 rad from a limit moving toward
    it at 2 rad/s, and the command keeps accelerating it toward the limit (10
    rad/s^2). With the envelope it stays beyond the 0.1 rad termination threshold;
    without, it reaches the limit."""
    from artic.sim.robot import command_torque, release_motors

    def closest(cfg: SafetyConfig) -> float:
        client = connect_direct()
        client.setGravity(0.0, 0.0, -9.81)
        client.setTimeStep(1.0 / 240.0)
        robot = Robot.load(client, RobotConfig())
        low, high = robot.limits
        q = np.array([0.1, 0.6, -0.2, -1.3, 0.3, 1.2, 0.1])
        away = -1.0 if upper else 1.0
        q[joint] = high[joint] - 0.35 if upper else low[joint] + 0.35
        qd = np.zeros(N_JOINTS)
        qd[joint] = -2.0 * away
        robot.set_state(q, qd)
        release_motors(robot)
        nearest = np.inf
        for _ in range(240):
            state = arm_state(robot, robot.q(), robot.qd())
            command = state.bias - 10.0 * away * state.mass[:, joint]
            command_torque(robot, envelope_torque(state, command, low, high, LIMITS, cfg).torque)
            client.stepSimulation()
            nearest = min(nearest, float(limit_distance(robot.q(), low, high).distance[joint]))
        client.disconnect()
        return nearest

    cfg = SafetyConfig()
    assert closest(cfg) > cfg.limit_threshold
    assert closest(SafetyConfig(enabled=False)) < cfg.limit_threshold


def test_the_braked_distance_is_what_is_left_after_stopping():
    limits = limit_distance(np.array([0.5, 0.5, -0.5]), np.full(3, -1.0), np.full(3, 1.0))
    qd = np.array([0.0, 2.0, 2.0])  # at rest; toward the upper limit; away from the lower
    braked = braked_distance(limits, qd, 20.0)
    assert braked == pytest.approx([0.5, 0.5 - 4.0 / 40.0, 0.5])


def test_a_fast_joint_meets_the_envelope_early(robot):
    """0.4 rad from its limit (outside sigma1) the joint passes at rest, and is pushed
    when moving toward the limit at 3 rad/s (braked: 0.4 - 9 / 40 = 0.175 < sigma2)."""
    low, high = robot.limits
    q = random_q(robot, np.random.default_rng(3))
    q[5] = high[5] - 0.4
    qd = np.zeros(N_JOINTS)
    at_rest = envelope_torque(arm_state(robot, q, qd), np.zeros(N_JOINTS), low, high, LIMITS,
                              SafetyConfig())  # fmt: skip
    qd[5] = 3.0
    moving = envelope_torque(arm_state(robot, q, qd), np.zeros(N_JOINTS), low, high, LIMITS,
                             SafetyConfig())  # fmt: skip
    qd[5] = -3.0
    leaving = envelope_torque(arm_state(robot, q, qd), np.zeros(N_JOINTS), low, high, LIMITS,
                              SafetyConfig())  # fmt: skip
    assert (at_rest.mode, moving.mode, leaving.mode) == ("pass", "push", "pass")
    assert moving.joints == (5,)


def test_the_push_stops_a_joint_halfway_and_pushes_hardest_past_that():
    cfg = SafetyConfig()  # stop point: (0.1 + 0.2) / 2 = 0.15 rad from the limit
    limits = limit_distance(np.array([0.82, 0.82, 0.87, 0.9]), np.full(4, -1.0), np.full(4, 1.0))
    qd = np.array([0.0, 1.0, 1.0, -1.0])  # rest 0.18; toward at 0.18 / 0.13; away at 0.1
    accel = stopping_acceleration(limits, qd, cfg)
    assert accel[0] == cfg.push_acceleration  # at rest
    assert accel[1] == pytest.approx(max(1.0 / (2 * 0.03), cfg.push_acceleration))
    assert accel[2] == cfg.max_push_acceleration  # past the stop point, whatever its speed
    assert accel[3] == cfg.max_push_acceleration


def test_the_push_is_each_joints_own_torque(robot):
    low, high = robot.limits
    q = random_q(robot, np.random.default_rng(5))
    q[4] = low[4] + 0.18
    state = arm_state(robot, q)
    safe = envelope_torque(state, np.ones(N_JOINTS), low, high, LIMITS, SafetyConfig())
    extra = safe.torque - state.bias
    assert safe.mode == "push" and safe.joints == (4,)
    assert extra[4] == pytest.approx(SafetyConfig().push_acceleration * state.mass[4, 4])
    assert np.allclose(np.delete(extra, 4), 0.0)
