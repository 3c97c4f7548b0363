"""Eq. 7.1's joint-limit penalty, Yoshikawa's manipulability and the MV choice among IK
solutions (Algorithm 3, line 8); Jacobians of the iiwa from PyBullet."""

from __future__ import annotations

import numpy as np
import pytest

from artic.planning.grasp_score import (
    GraspScoreConfig,
    best_ik_solution,
    joint_limit_penalty,
    manipulability,
    manipulability_score,
)
from artic.sim.bullet import connect_direct
from artic.sim.robot import N_JOINTS, TOOL_LINK, Robot, point_jacobian
from artic.sim.tasks import RobotConfig

K = GraspScoreConfig().joint_limit_gain


@pytest.fixture(scope="module")
def robot():
    client = connect_direct()
    robot = Robot.load(client, RobotConfig())
    yield robot
    client.disconnect()


def tool_jacobian(robot: Robot, q: np.ndarray) -> np.ndarray:
    inertial = np.asarray(robot.client.getLinkState(robot.body, TOOL_LINK)[2])
    return point_jacobian(robot, TOOL_LINK, inertial, q)


def test_gain_is_the_thesis_value():
    assert K == 1e5


def test_penalty_is_zero_at_a_limit_maximal_mid_range_and_below_one(robot):
    low, high = robot.limits
    mid = 0.5 * (low + high)
    assert joint_limit_penalty(mid, low, high, K) == pytest.approx(-np.expm1(-K / 4**N_JOINTS))
    rng = np.random.default_rng(0)
    q = rng.uniform(low, high, size=(2000, N_JOINTS))
    p = joint_limit_penalty(q, low, high, K)
    assert np.all((p >= 0.0) & (p < 1.0))
    assert np.all(p <= joint_limit_penalty(mid, low, high, K))
    for j in range(N_JOINTS):
        for limit in (low[j], high[j]):
            at = mid.copy()
            at[j] = limit
            assert joint_limit_penalty(at, low, high, K) == 0.0
    beyond = mid.copy()
    beyond[0] = high[0] + 0.1
    assert joint_limit_penalty(beyond, low, high, K) == 0.0


def test_penalty_grows_towards_mid_range_along_one_joint(robot):
    low, high = robot.limits
    mid = 0.5 * (low + high)
    path = np.repeat(mid[None], 50, axis=0)
    path[:, 2] = np.linspace(low[2], mid[2], 50)
    assert np.all(np.diff(joint_limit_penalty(path, low, high, K)) > 0)


def test_manipulability_is_the_product_of_singular_values_and_sqrt_det(robot):
    rng = np.random.default_rng(1)
    low, high = robot.limits
    for _ in range(10):
        jac = tool_jacobian(robot, rng.uniform(low, high))
        w = manipulability(jac)
        assert w == pytest.approx(np.prod(np.linalg.svd(jac, compute_uv=False)))
        assert w == pytest.approx(np.sqrt(np.linalg.det(jac @ jac.T)), rel=1e-8)
        assert w > 1e-4


def test_manipulability_is_zero_at_the_straight_arm(robot):
    """q = 0: the iiwa stands straight up, joints 1, 3, 5 and 7 on one axis: singular."""
    jac = tool_jacobian(robot, np.zeros(N_JOINTS))
    assert np.linalg.matrix_rank(jac, tol=1e-9) < 6
    assert manipulability(jac) < 1e-12


def test_mv_picks_the_argmax_of_w_times_p(robot):
    low, high = robot.limits
    rng = np.random.default_rng(2)
    cfg = GraspScoreConfig()
    solutions = rng.uniform(low, high, size=(16, N_JOINTS))
    solutions[3] = 0.0  # singular: scores 0
    jacobians = np.array([tool_jacobian(robot, q) for q in solutions])
    choice = best_ik_solution(solutions, jacobians, low, high, cfg)
    expected = [
        manipulability(j) * joint_limit_penalty(q, low, high, K)
        for q, j in zip(solutions, jacobians, strict=True)
    ]
    assert choice.position == int(np.argmax(expected))
    assert np.array_equal(choice.q, solutions[choice.position])
    assert choice.score == pytest.approx(max(expected))
    assert np.allclose(choice.scores, expected)
    assert choice.scores[3] < 1e-12
    assert np.allclose(manipulability_score(solutions, jacobians, low, high, cfg), expected)


def test_ties_go_to_the_first_solution_and_no_solution_is_refused(robot):
    low, high = robot.limits
    q = 0.5 * (low + high)
    jac = tool_jacobian(robot, q)
    choice = best_ik_solution(np.stack([q, q]), np.stack([jac, jac]), low, high, GraspScoreConfig())
    assert choice.position == 0
    with pytest.raises(ValueError, match="IK solutions"):
        best_ik_solution(
            np.zeros((0, N_JOINTS)), np.zeros((0, 6, N_JOINTS)), low, high, GraspScoreConfig()
        )
