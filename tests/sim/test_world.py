"""TaskWorld: index mapping, kinematic queries, grasp and contact dynamics (section 5.3.1)."""

from __future__ import annotations

import numpy as np
import pytest

from artic.sim.robot import pose_matrix, rotation_error
from artic.sim.tasks import ArticulatedScene, GraspConfig, get_task
from artic.sim.world import TaskWorld, sample_scene


def frame(direction, position) -> np.ndarray:
    """(4, 4) tool pose whose z axis (approach) is `direction`, at `position`."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    y = np.cross(d, [0.0, 0.0, 1.0])
    y /= np.linalg.norm(y)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([np.cross(y, d), y, d], axis=1)
    pose[:3, 3] = position
    return pose


def track(world: TaskWorld, targets) -> None:
    """Drive the tool through the poses `targets` (one per control step) with IK."""
    for target in targets:
        q = world.robot_q()
        goal = world.ik(target, q)
        world.apply_action(np.zeros(7) if goal is None else (goal - q) / world.dt)
        world.step()


def grasp_world_point(world: TaskWorld, q_object) -> np.ndarray:
    model = world.kinematic_model()
    pose = model.link_poses(np.asarray(q_object))[world.grasp_target_link]
    return (pose @ np.append(world.grasp_point, 1.0))[:3]


@pytest.fixture(scope="module")
def drawer():
    with TaskWorld.create(get_task("drawer")) as world:
        yield world


@pytest.fixture(scope="module")
def microwave():
    with TaskWorld.create(get_task("microwave")) as world:
        yield world


@pytest.fixture(scope="module")
def tball():
    with TaskWorld.create(get_task("tball")) as world:
        yield world


def start(world: TaskWorld) -> tuple[np.ndarray, np.ndarray]:
    q_robot, q_object = np.asarray(world.cfg.robot.start_q), np.asarray(world.cfg.object_start)
    world.reset(q_robot, q_object)
    return q_robot, q_object


@pytest.mark.parametrize("name", ["drawer", "microwave"])
def test_pybullet_links_match_the_kinematic_model(name, request):
    world = request.getfixturevalue(name)
    q_object = np.array([0.2])
    world.reset(np.asarray(world.cfg.robot.start_q), q_object)
    np.testing.assert_allclose(world.object_q(), q_object, atol=1e-9)
    model = world.kinematic_model()
    poses = model.link_poses(q_object)
    client, body = world._sim_client, world._sim.target
    assert client.getNumJoints(body) == len(model.joints)
    for j, joint in enumerate(model.joints):  # PyBullet joint/link j = joints[j], links[j + 1]
        state = client.getLinkState(body, j, computeForwardKinematics=True)
        np.testing.assert_allclose(pose_matrix(state[4], state[5]), poses[j + 1], atol=1e-6)
        assert joint.child == model.links[j + 1].name
    assert model.links[world.grasp_target_link].role == "handle"


def test_reset_sets_the_state_and_queries_leave_it_alone(drawer):
    q_robot, q_object = start(drawer)
    np.testing.assert_allclose(drawer.robot_q(), q_robot, atol=1e-12)
    np.testing.assert_allclose(drawer.robot_qd(), 0.0)
    before = drawer.ee_pose()
    other = q_robot + 0.3
    np.testing.assert_allclose(drawer.ee_pose(q_robot), before, atol=1e-9)
    assert not np.allclose(drawer.ee_pose(other), before)
    drawer.in_collision(other, np.array([0.1]))
    drawer.ik(drawer.ee_pose(other), q_robot)
    np.testing.assert_allclose(drawer.robot_q(), q_robot, atol=1e-12)  # sim untouched
    np.testing.assert_allclose(drawer.object_q(), q_object, atol=1e-12)


def test_tool_frame_is_offset_along_the_last_link(drawer):
    q_robot, _ = start(drawer)
    tool = drawer.ee_pose(q_robot)
    link = drawer._query.robot.link_frame()
    np.testing.assert_allclose(tool[:3, :3], link[:3, :3], atol=1e-9)
    offset = tool[:3, 3] - link[:3, 3]
    np.testing.assert_allclose(offset, drawer.cfg.robot.tool_offset * link[:3, 2], atol=1e-9)


def test_ik_reaches_a_reachable_pose_and_rejects_an_unreachable_one(drawer):
    q_robot, _ = start(drawer)
    rng = np.random.default_rng(0)
    for _ in range(3):
        target = drawer.ee_pose(q_robot + rng.normal(0.0, 0.2, 7))
        solution = drawer.ik(target, q_robot)
        assert solution is not None
        reached = drawer.ee_pose(solution)
        assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 0.01
        assert rotation_error(reached[:3, :3], target[:3, :3]) < 0.05
        low, high = drawer.robot_limits()
        assert np.all(solution >= low) and np.all(solution <= high)
    assert drawer.ik(frame([1, 0, 0], [2.0, 0.0, 0.5]), q_robot) is None


def test_in_collision_false_at_start_true_when_penetrating(drawer):
    q_robot, q_object = start(drawer)
    assert not drawer.in_collision(q_robot, q_object)
    # tool at the closed handle's bar centre: free with the drawer closed ...
    grasp = drawer.ik(frame([1, 0, 0], grasp_world_point(drawer, [0.0])), q_robot)
    assert grasp is not None and not drawer.in_collision(grasp, np.array([0.0]))
    # ... but with the drawer pulled out 25 cm, the drawer box passes through the arm
    assert drawer.in_collision(grasp, np.array([0.25]))
    # a configuration where the tool sits 10 cm below the bar, in front of the drawer face
    low = drawer.ik(frame([1, 0, 0], grasp_world_point(drawer, [0.0]) - [0.0, 0.0, 0.1]), q_robot)
    assert low is not None and not drawer.in_collision(low, np.array([0.0]))


def test_in_collision_detects_ground_and_self_collision(tball):
    assert tball.in_collision(np.array([-1.57, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0]), np.zeros(1))
    assert tball.in_collision(np.array([-1.57, 0.0, 0.0, 0.0, 0.0, 2.05, 0.0]), np.zeros(1))
    assert not tball.in_collision(np.array([-1.57, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), np.zeros(1))


def test_same_commands_after_reset_give_the_same_bytes(drawer):
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1.0, 1.0, size=(15, 7))

    def run() -> bytes:
        start(drawer)
        out = []
        for a in actions:
            drawer.apply_action(a)
            drawer.step()
            out.append(np.concatenate([drawer.robot_q(), drawer.object_q()]))
        return np.stack(out).tobytes()

    first = run()
    for a in actions[::-1]:  # a different episode in between
        drawer.apply_action(2 * a)
        drawer.step()
    assert run() == first


def test_actions_are_clipped_to_the_velocity_limits(tball):
    start(tball)
    command = tball.apply_action(np.full(7, 100.0))
    np.testing.assert_allclose(command, tball.velocity_limits())
    with pytest.raises(ValueError):
        tball.apply_action(np.full(7, np.nan))


def test_grasp_pulls_the_drawer_open_and_a_violent_pull_slips(drawer):
    start(drawer)
    handle = grasp_world_point(drawer, [0.0])
    tool0 = drawer.ee_pose()[:3, 3]
    approach = [
        frame([1, 0, 0], tool0 + (handle - tool0) * min(1.0, (k + 1) / 12)) for k in range(16)
    ]
    track(drawer, approach)
    assert drawer.grasp_held
    pull = [frame([1, 0, 0], handle - [min(0.2, 0.01 * (k + 1)), 0.0, 0.0]) for k in range(20)]
    track(drawer, pull)
    assert drawer.grasp_held
    assert drawer.object_q()[0] > 0.05  # opened by more than 5 cm
    # grasp, then yank at 2 m/s: the force limit is exceeded and the handle slips out
    start(drawer)
    track(drawer, approach)
    assert drawer.grasp_held
    track(
        drawer, [frame([1, 0, 0], handle - [min(0.3, 0.1 * (k + 1)), 0.0, 0.0]) for k in range(6)]
    )
    assert not drawer.grasp_held
    assert drawer.object_q()[0] < 0.29


def test_without_the_grasp_the_same_motion_leaves_the_drawer_closed():
    cfg = get_task("drawer").model_copy(update={"grasp": GraspConfig(enabled=False)})
    with TaskWorld.create(cfg) as world:
        start(world)
        handle = grasp_world_point(world, [0.0])
        tool0 = world.ee_pose()[:3, 3]
        track(
            world,
            [
                frame([1, 0, 0], tool0 + (handle - tool0) * min(1.0, (k + 1) / 12))
                for k in range(16)
            ],
        )
        track(
            world,
            [frame([1, 0, 0], handle - [min(0.2, 0.01 * (k + 1)), 0.0, 0.0]) for k in range(20)],
        )
        assert world.object_q()[0] < 0.01


def test_microwave_handle_reachable_open_but_not_closed(microwave):
    q_robot, q_object = start(microwave)
    assert not microwave.in_collision(q_robot, q_object)
    directions = ([1, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, -1], [1, 1, -1])
    seeds = [q_robot, np.array([0.0, 0.5, 0.0, -1.5, 0.0, 1.0, 0.0])]

    def reachable(q_door: float) -> bool:
        point = grasp_world_point(microwave, [q_door])
        return any(
            microwave.ik(frame(d, point), seed) is not None for d in directions for seed in seeds
        )

    assert reachable(q_object[0])
    assert not reachable(0.0)


def test_pushing_the_open_microwave_door_closes_it(microwave):
    start(microwave)
    model = microwave.kinematic_model()
    q0 = microwave.object_q()[0]

    def face(q_door: float, standoff: float) -> np.ndarray:
        door = model.link_poses(np.array([q_door]))[1]
        point = (door @ np.array([-0.02 - standoff, 0.3, 0.175, 1.0]))[:3]
        return frame(door[:3, :3] @ np.array([1.0, 0.0, 0.0]), point)

    track(microwave, [face(q0, 0.05 * (1 - (k + 1) / 15) + 0.005) for k in range(15)])
    assert microwave.object_q()[0] > q0 - 0.05  # approached without slamming it
    for _ in range(15):
        track(microwave, [face(max(microwave.object_q()[0] - 0.25, 0.0), 0.0)])
    assert microwave.object_q()[0] < q0 - 0.5


def test_tball_ball_rests_then_flies_along_y(tball):
    start(tball)
    for _ in range(10):
        tball.apply_action(np.zeros(7))
        tball.step()
    assert abs(tball.object_q()[0]) < 1e-3  # at rest on the tee
    model = tball.kinematic_model()
    ball = model.link_poses(np.zeros(1))[tball.grasp_target_link][:3, 3]
    np.testing.assert_allclose(
        model.link_poses(np.array([0.3]))[1][:3, 3], ball + np.array([0.0, 0.3, 0.0]), atol=1e-12
    )
    tool0 = tball.ee_pose()[:3, 3]
    swing = [
        frame([0, 1, 0], [ball[0], min(tool0[1] + 0.1 * (k + 1), ball[1] + 0.15), ball[2]])
        for k in range(25)
    ]
    track(tball, swing)
    assert tball.object_q()[0] > 0.2


def test_geometry_jitter_samples_from_the_rng():
    scene = get_task("drawer").scene
    assert isinstance(scene, ArticulatedScene)
    jittered = scene.model_copy(update={"geometry_jitter": 0.1})
    a = sample_scene(jittered, np.random.default_rng(3))
    b = sample_scene(jittered, np.random.default_rng(3))
    assert a == b and a.depth != scene.depth
    assert abs(a.depth / scene.depth - 1.0) <= 0.1
    front = a.pose.x - a.depth / 2
    assert abs(front - (scene.pose.x - scene.depth / 2)) < 1e-12
    assert sample_scene(scene, np.random.default_rng(3)) == scene


def test_goal_of_the_wrong_size_is_an_input_error():
    from artic.errors import InputError

    cfg = get_task("tball").model_copy(update={"goal": [1.0, 0.0], "object_start": [0.0, 0.0]})
    with pytest.raises(InputError, match=r"task\.goal"):
        TaskWorld.create(cfg)
