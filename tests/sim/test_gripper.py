"""The parallel-jaw gripper of Chapter 7: held on the flange, Gamma opens and closes it
within its stroke, a grasped bar reads on the tactile zones, and its mass is in the
controller's model."""

from __future__ import annotations

import numpy as np
import pytest

from artic.sim.bullet import connect_direct
from artic.sim.gripper import Gripper, GripperConfig
from artic.sim.robot import TOOL_LINK, Robot, bias_forces, mass_matrix
from artic.sim.tasks import RobotConfig

Q = np.array([0.1, 0.6, -0.2, -1.3, 0.3, 1.2, 0.1])


@pytest.fixture
def world():
    client = connect_direct()
    client.setGravity(0, 0, -9.81)
    client.setTimeStep(1 / 240)
    robot = Robot.load(client, RobotConfig(start_q=Q.tolist()))
    gripper = Gripper(client, robot)
    yield client, robot, gripper
    client.disconnect()


def _palm_error(gripper: Gripper) -> float:
    pos, _ = gripper.palm_pose()
    actual, _ = gripper.client.getBasePositionAndOrientation(gripper.body)
    return float(np.linalg.norm(np.subtract(actual, pos)))


def test_the_gripper_stays_on_the_flange_while_the_arm_holds_and_moves(world):
    client, robot, gripper = world
    assert _palm_error(gripper) < 1e-9
    for k in range(240):  # the arm's velocity motors hold it, then turn joint 1
        if k == 120:
            robot.command_velocity(np.array([0.5, 0, 0, 0, 0, 0, 0.0]))
        client.stepSimulation()
    assert _palm_error(gripper) < 2e-3


def test_gamma_closes_and_opens_within_the_stroke(world):
    client, _, gripper = world
    cfg = gripper.cfg
    assert gripper.width() == pytest.approx(2 * cfg.travel)
    gripper.command(close=True)
    for _ in range(240):
        client.stepSimulation()
    assert gripper.width() < 2e-3 and gripper.closing
    gripper.command(close=False)
    for _ in range(240):
        client.stepSimulation()
    assert gripper.width() == pytest.approx(2 * cfg.travel, abs=2e-3)
    assert np.all(gripper.tactile() == 0.0)  # nothing touched


def test_a_bar_between_the_fingers_reads_on_both_fingers_middle_zones(world):
    client, robot, gripper = world
    cfg = gripper.cfg
    state = client.getLinkState(robot.body, TOOL_LINK, computeForwardKinematics=1)
    rotation = np.reshape(client.getMatrixFromQuaternion(state[5]), (3, 3))
    tool = np.asarray(state[4]) + rotation[:, 2] * cfg.tool_offset
    shape = client.createCollisionShape(client.GEOM_BOX, halfExtents=[0.05, 0.01, 0.004])
    # a fixed bar 2 cm thick across the fingers' closing direction, 8 mm tall, at the
    # pads' middle (a finger is 5 cm long: zones of 1.7 cm)
    _, orn = gripper.palm_pose()
    client.createMultiBody(0.0, shape, -1, tool.tolist(), orn)
    gripper.command(close=True)
    for _ in range(240):
        client.stepSimulation()
    touch = gripper.tactile(exclude=(robot.body,))
    assert gripper.width() == pytest.approx(0.02, abs=3e-3)  # stopped by the bar
    left, right = touch[:3], touch[3:]
    assert left[1] > 0 and right[1] > 0 and touch[[0, 2, 3, 5]].sum() == 0  # middle zones only
    # each finger presses with its motor's force
    assert left.sum() == pytest.approx(cfg.force, rel=0.1)
    assert right.sum() == pytest.approx(cfg.force, rel=0.1)


def test_the_payload_is_the_gripper_mass_in_the_model(world):
    client, robot, gripper = world
    payload = gripper.payload(Q)
    assert payload.mass.shape == (7, 7) and np.allclose(payload.mass, payload.mass.T)
    assert np.all(np.linalg.eigvalsh(payload.mass) > -1e-12)
    # holding still with the model's gravity term (arm + payload): the arm does not sag
    from artic.sim.robot import command_torque, release_motors

    release_motors(robot)
    for _ in range(240):
        q, qd = robot.q(), robot.qd()
        hold = (
            bias_forces(robot, q, qd) + gripper.payload(q).bias - mass_matrix(robot, q) @ (10 * qd)
        )
        command_torque(robot, hold)
        client.stepSimulation()
    with_payload = np.abs(robot.q() - Q).max()
    robot.set_state(Q)
    gripper.follow()
    for _ in range(240):
        q, qd = robot.q(), robot.qd()
        command_torque(robot, bias_forces(robot, q, qd) - mass_matrix(robot, q) @ (10 * qd))
        client.stepSimulation()
    without = np.abs(robot.q() - Q).max()
    assert with_payload < 0.2 * without


def test_a_lighter_gripper_weighs_less_in_the_model(world):
    client, robot, _ = world
    light = Gripper(client, robot, GripperConfig(palm_mass=0.1))
    heavy = Gripper(client, robot, GripperConfig(palm_mass=1.0))
    assert np.abs(light.payload(Q).bias).sum() < np.abs(heavy.payload(Q).bias).sum()
