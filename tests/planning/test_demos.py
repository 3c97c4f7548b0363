"""Algorithm 2 on artic objects with an analytic toy robot (no simulator)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from artic.geometry.transforms import make_transform
from artic.objects.categories import build
from artic.objects.model import ArticulatedObject, Inertial, Joint, Link, TriangleMesh
from artic.objects.spec import ObjectSpec, PartsConfig, Pose
from artic.planning.demos import (
    DemoProblem,
    GraspSettings,
    NoiseSettings,
    PlannerSettings,
    RobotFunctions,
    TimingSettings,
    perturbed_problem,
    plan_demo,
)
from artic.planning.grasp import estimate_grasp, grasp_path, interpolate_poses, pregrasp_pose
from artic.planning.models import axis_in_world, perturb_model
from artic.planning.trajectory import time_parameterize

DT = 0.05


def make_object(category: str, limits: tuple[float, float]) -> ArticulatedObject:
    spec = ObjectSpec(
        category=category,
        index=0,
        dof=1,
        joint_type="prismatic" if category == "drawer" else "revolute",
        depth=0.5,
        width=0.5,
        height=0.3,
        chirality=1,
        pose=Pose(x=0.9, y=0.0, z=0.2, yaw=0.0),
        joint_limits=(limits,),
        parts=PartsConfig(),
    )
    return build(spec)


@pytest.fixture(scope="module")
def drawer() -> ArticulatedObject:
    return make_object("drawer", (0.0, 0.3))


@pytest.fixture(scope="module")
def microwave() -> ArticulatedObject:
    return make_object("microwave", (0.0, 1.5))


def ball_model() -> ArticulatedObject:
    """A 0.04 m cube 'ball' on a prismatic joint along world +y."""
    v = np.array([[x, y, z] for x in (-0.02, 0.02) for y in (-0.02, 0.02) for z in (-0.02, 0.02)])
    mesh = TriangleMesh(v, np.zeros((0, 3), dtype=np.int32))
    inertial = Inertial(0.1, np.zeros(3), np.eye(3) * 1e-5)
    links = (Link("tee", "body", mesh, inertial), Link("ball", "ball", mesh, inertial))
    origin = make_transform(translation=np.array([0, 0, 0.3]))
    joint = Joint("joint_0", "prismatic", "tee", "ball", origin, np.array([0.0, 1.0, 0.0]), (-2, 2))
    return ArticulatedObject(
        "ball", links, (joint,), make_transform(translation=np.array([0.6, 0, 0]))
    )


def toy_robot(
    reach: float = 10.0, obstacle: tuple[np.ndarray, float] | None = None
) -> RobotFunctions:
    """A free-flying hand: q = (position (3,), rotation vector (3,)); exact IK within
    `reach` of the origin; collision = the hand inside a sphere (centre, radius)."""

    def ee_pose(q: np.ndarray) -> np.ndarray:
        return make_transform(Rotation.from_rotvec(q[3:]).as_matrix(), q[:3])

    def ik(pose: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
        if np.linalg.norm(pose[:3, 3]) > reach:
            return None
        return np.concatenate([pose[:3, 3], Rotation.from_matrix(pose[:3, :3]).as_rotvec()])

    def in_collision(q: np.ndarray, q_object: np.ndarray) -> bool:
        return obstacle is not None and float(np.linalg.norm(q[:3] - obstacle[0])) < obstacle[1]

    low = np.array([-2.0, -2.0, -2.0, -np.pi, -np.pi, -np.pi])
    return RobotFunctions(ik, in_collision, ee_pose, low, -low, np.full(6, 1.0))


def problem(model: ArticulatedObject, goal: float, start: float = 0.0) -> DemoProblem:
    return DemoProblem(
        model=model,
        link=model.link_index("handle_0") if model.name != "ball" else 1,
        q_robot_start=np.array([0.3, 0.0, 0.6, 0.0, 0.0, 0.0]),
        q_object_start=np.array([start]),
        q_object_goal=np.array([goal]),
        dt=DT,
    )


SETTINGS = (PlannerSettings(), GraspSettings(), TimingSettings())


# -- EstimateGrasp and GraspPath --------------------------------------------------------


def test_handle_grasp_is_the_bar_centre_approached_from_the_front(
    drawer: ArticulatedObject,
) -> None:
    link = drawer.link_index("handle_0")
    grasp = estimate_grasp(drawer, link, np.zeros(1), "handle")
    ee = drawer.link_poses(np.zeros(1))[link] @ grasp.offset
    v = drawer.links[link].mesh.vertices
    lo, hi = v.min(axis=0), v.max(axis=0)
    bar_centre = np.array([lo[0] + 0.015 / 2, 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])])
    expected = drawer.link_poses(np.zeros(1))[link] @ np.append(bar_centre, 1.0)
    np.testing.assert_allclose(ee[:3, 3], expected[:3], atol=1e-9)
    np.testing.assert_allclose(ee[:3, 2], [1.0, 0.0, 0.0], atol=1e-9)  # into the front face
    np.testing.assert_allclose(np.abs(ee[:3, 0]), [0.0, 1.0, 0.0], atol=1e-9)  # along the bar
    np.testing.assert_allclose(ee[:3, :3].T @ ee[:3, :3], np.eye(3), atol=1e-12)
    # the standoff moves the tool point out of the face, towards the robot
    away = estimate_grasp(drawer, link, np.zeros(1), "handle", standoff=0.02)
    np.testing.assert_allclose(away.offset[:3, 3] - grasp.offset[:3, 3], [-0.02, 0, 0], atol=1e-12)


def test_grasp_path_follows_the_prismatic_forward_kinematics(drawer: ArticulatedObject) -> None:
    link = drawer.link_index("handle_0")
    grasp = estimate_grasp(drawer, link, np.zeros(1), "handle")
    q = np.linspace(0.0, 0.3, 31)[:, None]
    poses = grasp_path(drawer, grasp, q)
    assert poses.shape == (31, 4, 4)
    steps = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
    np.testing.assert_allclose(steps, 0.01, atol=1e-12)  # |dq| per step, m
    np.testing.assert_allclose(poses[-1], drawer.link_poses(np.array([0.3]))[link] @ grasp.offset)
    np.testing.assert_allclose(poses[-1][:3, 3] - poses[0][:3, 3], [-0.3, 0, 0], atol=1e-12)
    assert np.allclose(poses[:, :3, :3], poses[0, :3, :3])  # a drawer translates


def test_grasp_path_follows_the_revolute_forward_kinematics(microwave: ArticulatedObject) -> None:
    link = microwave.link_index("handle_0")
    grasp = estimate_grasp(microwave, link, np.array([1.2]), "handle")
    q = np.linspace(1.2, 0.0, 61)[:, None]
    poses = grasp_path(microwave, grasp, q)
    origin, direction = axis_in_world(microwave, np.zeros(1))
    p = poses[:, :3, 3] - origin
    radius = np.linalg.norm(p - np.outer(p @ direction, direction), axis=1)
    np.testing.assert_allclose(radius, radius[0], atol=1e-9)  # on a circle about the hinge
    chord = 2 * radius[0] * np.sin(0.02 / 2)  # 0.02 rad per step
    np.testing.assert_allclose(np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1), chord)
    np.testing.assert_allclose(
        poses[-1], microwave.link_poses(np.zeros(1))[link] @ grasp.offset, atol=1e-12
    )


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_push_grasp_stands_behind_the_ball(direction: float) -> None:
    model = ball_model()
    grasp = estimate_grasp(model, 1, np.zeros(1), "push", standoff=0.01, direction=direction)
    ee = model.link_poses(np.zeros(1))[1] @ grasp.offset
    np.testing.assert_allclose(ee[:3, 2], [0.0, direction, 0.0], atol=1e-12)
    np.testing.assert_allclose(ee[:3, 3], [0.6, -direction * 0.03, 0.3], atol=1e-12)


def test_pitched_push_strikes_from_above_with_the_lower_rim() -> None:
    model = ball_model()  # a 0.04 m cube centred at (0.6, 0, 0.3)
    pitch, lift, standoff = 0.5, 0.03, 0.01
    grasp = estimate_grasp(model, 1, np.zeros(1), "push", standoff, 1.0, pitch, lift)
    ee = model.link_poses(np.zeros(1))[1] @ grasp.offset
    d = np.array([0.0, np.cos(pitch), -np.sin(pitch)])  # +y tilted down
    up = np.array([0.0, np.sin(pitch), np.cos(pitch)])  # in the end face, towards world up
    np.testing.assert_allclose(ee[:3, 2], d, atol=1e-12)
    np.testing.assert_allclose(ee[:3, 0], up, atol=1e-12)
    # the contact is the cube's support point along -d: a back corner row, 0.02 (cos + sin)
    reach = 0.02 * (np.cos(pitch) + np.sin(pitch))
    centre = np.array([0.6, 0.0, 0.3])
    np.testing.assert_allclose(ee[:3, 3], centre - d * (reach + standoff) + up * lift, atol=1e-12)
    np.testing.assert_allclose(grasp.approach, d, atol=1e-12)


def test_pregrasp_and_pose_interpolation() -> None:
    a = make_transform(Rotation.from_rotvec([0, 0, 0.5]).as_matrix(), np.array([1.0, 0.0, 0.0]))
    back = pregrasp_pose(a, 0.1)
    np.testing.assert_allclose(back[:3, 3], [1.0, 0.0, -0.1])
    poses = interpolate_poses(back, a, 0.03)
    assert len(poses) == 5
    np.testing.assert_allclose(poses[0], back)
    np.testing.assert_allclose(poses[-1], a, atol=1e-12)


# -- kinematic model sources -------------------------------------------------------------


def test_noisy_model_errors_have_the_configured_magnitude(drawer: ArticulatedObject) -> None:
    same = perturb_model(drawer, 0.0, 0.0, np.random.default_rng(0))
    for q in (0.0, 0.2):
        for a, b in zip(
            same.model.link_poses(np.array([q])), drawer.link_poses(np.array([q])), strict=True
        ):
            np.testing.assert_allclose(a, b)
    rng = np.random.default_rng(1)
    draws = [perturb_model(drawer, 0.05, 0.01, rng) for _ in range(400)]
    angles = np.array([d.direction_error_rad[0] for d in draws])
    offsets = np.array([d.origin_error_m[0] for d in draws])
    assert abs(np.sqrt(np.mean(angles**2)) / (0.05 * np.sqrt(2)) - 1) < 0.15
    assert abs(np.sqrt(np.mean(offsets**2)) / (0.01 * np.sqrt(3)) - 1) < 0.15
    # the recorded errors are the ones in the model
    noisy = draws[0]
    _, d_true = axis_in_world(drawer, np.zeros(1))
    _, d_noisy = axis_in_world(noisy.model, np.zeros(1))
    angle = np.arccos(np.clip(d_true @ d_noisy, -1, 1))
    np.testing.assert_allclose(angle, noisy.direction_error_rad[0], atol=1e-9)
    moved = (
        noisy.model.joint_frames(np.zeros(1))[0][:3, 3] - drawer.joint_frames(np.zeros(1))[0][:3, 3]
    )
    np.testing.assert_allclose(np.linalg.norm(moved), noisy.origin_error_m[0], atol=1e-12)
    assert noisy.model.movable_joints[0].limits == drawer.movable_joints[0].limits
    again = perturb_model(drawer, 0.05, 0.01, np.random.default_rng(1))
    np.testing.assert_array_equal(again.model.joints[0].axis, noisy.model.joints[0].axis)


# -- time-parameterisation ---------------------------------------------------------------


def test_time_parameterisation_respects_velocity_limits() -> None:
    w = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    vmax = np.array([1.0, 0.5])
    for smoothing in (0.0, 0.1):
        r = time_parameterize(w, DT, vmax, np.array([[0.0], [0.0], [2.0]]), [4.0], smoothing, 0.2)
        np.testing.assert_allclose(np.diff(r.t), DT)
        assert np.all(np.abs(r.qd) <= vmax + 1e-9)
        np.testing.assert_allclose(r.q[0], w[0], atol=1e-9)
        np.testing.assert_allclose(r.q[-1], w[-1], atol=1e-6)
        np.testing.assert_array_equal(r.qd[-1], 0.0)
        np.testing.assert_allclose(r.extra[-1], [2.0], atol=1e-6)
        np.testing.assert_allclose(r.q[:-1] + r.qd[:-1] * DT, r.q[1:], atol=1e-12)
        assert r.t[-1] >= 1.0 / 1.0 + 1.0 / 0.5  # never faster than the limits allow


# -- Algorithm 2 -------------------------------------------------------------------------


def test_plan_demo_drawer_with_a_toy_robot(drawer: ArticulatedObject) -> None:
    robot = toy_robot()
    out = plan_demo(problem(drawer, 0.25), robot, *SETTINGS, None, np.random.default_rng(0))
    assert out.status == "ok" and out.reason == "" and out.planning_time_s > 0
    demo = out.demo
    assert demo is not None
    n = len(demo.t)
    assert demo.q_robot.shape == (n, 6) and demo.qd_robot.shape == (n, 6)
    assert demo.q_object.shape == (n, 1) and demo.ee_pose.shape == (n, 4, 4)
    np.testing.assert_allclose(np.diff(demo.t), DT)
    assert np.all(demo.q_robot >= robot.low - 1e-9) and np.all(demo.q_robot <= robot.high + 1e-9)
    assert np.all(np.abs(demo.qd_robot) <= 0.5 * robot.max_velocity + 1e-9)
    np.testing.assert_allclose(demo.q_robot[0], [0.3, 0.0, 0.6, 0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(demo.q_object[0], [0.0])
    np.testing.assert_allclose(demo.q_object[-1], [0.25], atol=1e-6)
    assert demo.reached_fraction == 1.0 and 0 < demo.grasp_step < n
    link = drawer.link_index("handle_0")
    grasp = estimate_grasp(drawer, link, np.zeros(1), "handle")
    end = drawer.link_poses(np.array([0.25]))[link] @ grasp.offset
    np.testing.assert_allclose(demo.ee_pose[-1], end, atol=1e-5)
    np.testing.assert_allclose(demo.ee_pose[5], robot.ee_pose(demo.q_robot[5]))
    again = plan_demo(problem(drawer, 0.25), robot, *SETTINGS, None, np.random.default_rng(0))
    assert again.demo is not None
    np.testing.assert_array_equal(again.demo.q_robot, demo.q_robot)


def test_perturbed_demos_differ_and_stay_in_limits(drawer: ArticulatedObject) -> None:
    robot, noise = toy_robot(), NoiseSettings(start_robot_rad=0.05, plan=0.02, grasp_m=0.01)
    demos = []
    for i in range(2):
        rng = np.random.default_rng([0, i])
        p = perturbed_problem(problem(drawer, 0.25), noise, robot, rng)
        out = plan_demo(p, robot, *SETTINGS, noise, rng)
        assert out.demo is not None
        assert np.all(out.demo.q_object >= 0.0) and np.all(out.demo.q_object <= 0.3)
        demos.append(out.demo)
    assert not np.allclose(demos[0].q_robot[0], demos[1].q_robot[0])


def test_reach_truncates_the_plan_or_fails_it(microwave: ArticulatedObject) -> None:
    # close the door from 1.2 rad; the hand reaches only part of the handle's arc
    link = microwave.link_index("handle_0")
    grasp = estimate_grasp(microwave, link, np.array([1.2]), "handle")
    arc = grasp_path(microwave, grasp, np.linspace(1.2, 0.0, 13)[:, None])
    reach = float(np.linalg.norm(arc[6, :3, 3]))  # about half way
    robot = toy_robot(reach=reach)
    out = plan_demo(
        problem(microwave, 0.0, start=1.2), robot, *SETTINGS, None, np.random.default_rng(0)
    )
    assert out.status == "ok" and out.demo is not None
    assert 0.2 < out.demo.reached_fraction < 0.8
    assert out.demo.q_object[-1, 0] > 0.2  # stopped before closing
    strict = GraspSettings(min_reach_fraction=0.9)
    out = plan_demo(
        problem(microwave, 0.0, start=1.2),
        robot,
        SETTINGS[0],
        strict,
        SETTINGS[2],
        None,
        np.random.default_rng(0),
    )
    assert out.status == "failed" and out.demo is None and "IK" in out.reason


def test_blocked_pregrasp_fails_with_a_reason(drawer: ArticulatedObject) -> None:
    link = drawer.link_index("handle_0")
    grasp = estimate_grasp(drawer, link, np.zeros(1), "handle")
    pre = pregrasp_pose(drawer.link_poses(np.zeros(1))[link] @ grasp.offset, 0.08)
    robot = toy_robot(obstacle=(pre[:3, 3], 0.05))
    out = plan_demo(problem(drawer, 0.25), robot, *SETTINGS, None, np.random.default_rng(0))
    assert out.status == "failed" and out.reason == "pre-grasp configuration in collision"


def test_obstacle_between_start_and_pregrasp_is_avoided(drawer: ArticulatedObject) -> None:
    start = np.array([0.3, 0.0, 0.6])
    link = drawer.link_index("handle_0")
    grasp = estimate_grasp(drawer, link, np.zeros(1), "handle")
    pre = pregrasp_pose(drawer.link_poses(np.zeros(1))[link] @ grasp.offset, 0.08)
    centre = 0.5 * (start + pre[:3, 3])
    robot = toy_robot(obstacle=(centre, 0.1))
    out = plan_demo(problem(drawer, 0.25), robot, *SETTINGS, None, np.random.default_rng(0))
    assert out.demo is not None
    approach = out.demo.q_robot[: out.demo.grasp_step]
    assert min(np.linalg.norm(approach[:, :3] - centre, axis=1)) >= 0.1 - 0.02  # smoothing
