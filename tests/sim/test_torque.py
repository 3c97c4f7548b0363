"""The torque interface of the iiwa (Chapter 6): gravity compensation, torque limits,
mass matrix, Jacobians and their velocity-product terms."""

from __future__ import annotations

import numpy as np
import pytest

from artic.sim.bullet import connect_direct
from artic.sim.robot import (
    IIWA7_TORQUE_LIMITS,
    N_JOINTS,
    Robot,
    bias_forces,
    command_torque,
    link_kinematics,
    mass_matrix,
    point_jacobian,
    release_motors,
)
from artic.sim.tasks import RobotConfig

Q0 = np.array([0.1, 0.6, -0.2, -1.3, 0.3, 1.2, 0.1])


@pytest.fixture()
def robot():
    client = connect_direct()
    client.setGravity(0.0, 0.0, -9.81)
    client.setTimeStep(1.0 / 240.0)
    robot = Robot.load(client, RobotConfig(start_q=Q0.tolist()))
    yield robot
    client.disconnect()


def test_bias_torques_hold_the_released_arm_still(robot):
    release_motors(robot)
    for _ in range(240):
        command_torque(robot, bias_forces(robot, robot.q(), robot.qd()))
        robot.client.stepSimulation()
    assert np.max(np.abs(robot.q() - Q0)) < 1e-3


def test_released_arm_without_torque_falls(robot):
    release_motors(robot)
    for _ in range(120):
        command_torque(robot, np.zeros(N_JOINTS))
        robot.client.stepSimulation()
    assert np.max(np.abs(robot.q() - Q0)) > 0.05


def test_torques_are_clipped_to_the_iiwa7_limits(robot):
    applied = command_torque(robot, np.full(N_JOINTS, 1000.0))
    assert np.allclose(applied, IIWA7_TORQUE_LIMITS)
    applied = command_torque(robot, np.full(N_JOINTS, -1000.0))
    assert np.allclose(applied, -np.asarray(IIWA7_TORQUE_LIMITS))


def test_mass_matrix_is_symmetric_positive_definite(robot):
    M = mass_matrix(robot, Q0)
    assert M.shape == (7, 7)
    assert np.allclose(M, M.T)
    assert np.all(np.linalg.eigvalsh(M) > 0)


def test_jacobian_and_its_velocity_product_match_finite_differences(robot):
    """J q' is the frame origin's velocity and J'q' the derivative of J along q'."""
    qd = np.array([0.3, -0.2, 0.4, 0.1, -0.5, 0.2, 0.3])
    robot.set_state(Q0, qd)
    kin = link_kinematics(robot, [3, 6], Q0, qd)
    h = 1e-5
    for row, link in enumerate([3, 6]):
        J = kin.jacobian[row]
        com = robot.client.getLinkState(robot.body, link)[2]
        assert np.allclose(J, point_jacobian(robot, link, com, Q0))

        def centre(q, link=link):
            robot.set_state(q)
            return np.array(
                robot.client.getLinkState(robot.body, link, computeForwardKinematics=1)[0]
            )

        velocity = (centre(Q0 + h * qd) - centre(Q0 - h * qd)) / (2 * h)
        assert np.allclose(J[:3] @ qd, velocity, atol=1e-6)
        assert np.allclose(kin.com[row], centre(Q0))
        J_ahead = point_jacobian(robot, link, com, Q0 + h * qd)
        J_behind = point_jacobian(robot, link, com, Q0 - h * qd)
        assert np.allclose(kin.jdot_qdot[row], (J_ahead - J_behind) @ qd / (2 * h), atol=1e-4)
