"""The grasp candidates G and the initiation set I_c (planning/cip_grasps.py; thesis
section 7.2.1, Algorithm 3 lines 1-3 and 6-9): the handle's cloud and normals, sampled
grasps, the reachability / collision / contact filters, the JSON record, and the head's
choice under the settings of section 7.3."""

from __future__ import annotations

import json

import numpy as np
import pytest

from artic.errors import InputError
from artic.learning.bandits import UCB1
from artic.planning.cip_grasps import (
    FRONT,
    FilterCounts,
    GraspCandidatesConfig,
    InitiationSet,
    bar_axis,
    build_initiation_set,
    holds_handle,
    ik_seeds,
    in_collision,
    nominal_task,
    part_cloud,
    reachable_solutions,
    report_outcome,
    robot_ik,
    sample_grasps,
    score_solutions,
    select_start,
    tool_jacobian,
)
from artic.planning.grasp_score import GraspScoreConfig
from artic.render.scan import object_frame_meshes
from artic.sim.cip_envs import CipEnv
from artic.sim.cip_tasks import get_cip_task
from artic.sim.robot import IKSettings, rotation_error

SCENE = 0  # the seed of the filtering scene
N = 12  # grasps sampled in the tests (the stage's default is 100)


@pytest.fixture(scope="module")
def env():
    """The filtering scene: the door at its nominal pose."""
    env = CipEnv(nominal_task(get_cip_task("door")))
    yield env
    env.close()


@pytest.fixture(scope="module")
def cloud(env):
    return part_cloud(env.object_model(env.draw_pose(SCENE)), np.random.default_rng(0))


@pytest.fixture(scope="module")
def initiation_set():
    return build_initiation_set("door", np.random.default_rng(0), n=N)


@pytest.fixture(scope="module")
def reference(env):
    """The task's reference grasp at the scene's pose and its IK solutions."""
    env.reset(seed=SCENE)
    target = env.handle_grasp(env.draw_pose(SCENE))
    low, high = env.limits
    seeds = ik_seeds(env.rest_q, low, high, np.random.default_rng(0))
    margin = env.task.safety.limit_threshold
    return target, reachable_solutions(env.robot, target, seeds, margin)


def in_object(env: CipEnv, world: np.ndarray) -> np.ndarray:
    return np.linalg.inv(env.draw_pose(SCENE)) @ world


# -- the part's cloud and the sampled grasps ---------------------------------------------


def test_the_part_cloud_is_the_handle_with_outward_normals(env, cloud):
    model = env.object_model(env.draw_pose(SCENE))
    vertices, _ = object_frame_meshes(model, np.zeros(1))[model.link_index("handle_0")]
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    inside = np.all((cloud.points >= low - 0.005) & (cloud.points <= high + 0.005), axis=1)
    assert len(cloud.points) > 100 and inside.mean() > 0.98
    assert np.allclose(np.linalg.norm(cloud.normals, axis=1), 1.0)
    front = cloud.points[:, 0] < low[0] + 0.003  # the bar's front face (facing -x)
    assert front.sum() > 50 and (cloud.normals[front, 0] < -0.5).mean() > 0.85
    assert len(cloud.viewpoints) == 6 and np.all(cloud.viewpoints[:, 0] < 0.0)  # in front


def test_grasps_approach_into_the_surface_with_the_fingers_across_the_bar(env, cloud):
    grasps = sample_grasps(cloud.points, cloud.normals, np.random.default_rng(1), 50)
    poses, normals = grasps.poses, cloud.normals[grasps.source]
    assert poses.shape == (50, 4, 4)
    rotations = poses[:, :3, :3]
    assert np.allclose(rotations.transpose(0, 2, 1) @ rotations, np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(rotations), 1.0)
    approach, closing = poses[:, :3, 2], poses[:, :3, 1]
    cosine = -np.einsum("nd,nd->n", approach, normals)
    assert np.all(cosine >= np.cos(np.radians(30.0)) - 1e-12)
    axis = bar_axis(cloud.points, FRONT)
    assert np.all(np.abs(closing @ axis) < 1e-9)
    assert abs(axis[2]) > 0.99  # the door's bar stands upright
    # the tool point lies half a bar thickness behind its point (on the bar's centre line),
    # less where the part behind the point is too shallow for the fingers
    thickness = env.parts.handle_thickness
    offset = np.linalg.norm(poses[:, :3, 3] - cloud.points[grasps.source], axis=1)
    assert np.all(offset <= thickness / 2 + 1e-12)
    assert np.median(offset) == pytest.approx(thickness / 2)
    centre = in_object(env, env.handle_grasp(env.draw_pose(SCENE)))[:3, 3]
    d = poses[:, :3, 3] - centre
    off_line = np.linalg.norm(d - np.outer(d @ axis, axis), axis=1)
    assert np.median(off_line) < 0.005


def test_sampling_is_deterministic_and_refuses_an_impossible_approach(cloud):
    a = sample_grasps(cloud.points, cloud.normals, np.random.default_rng(3), 10)
    b = sample_grasps(cloud.points, cloud.normals, np.random.default_rng(3), 10)
    assert a.poses.tobytes() == b.poses.tobytes()
    along = np.tile(bar_axis(cloud.points, FRONT), (len(cloud.points), 1))  # normals on the axis
    with pytest.raises(InputError, match="no normal within 30"):
        sample_grasps(cloud.points, along, np.random.default_rng(0), 5)


# -- the filters ---------------------------------------------------------------------------


def test_ik_seeds_are_home_then_within_the_limits(env):
    low, high = env.limits
    seeds = ik_seeds(env.rest_q, low, high, np.random.default_rng(0))
    assert seeds.shape == (16, 7) and np.array_equal(seeds[0], env.rest_q)
    assert np.all((seeds[1:] >= low) & (seeds[1:] <= high))


def test_reachable_solutions_reach_the_pose_and_are_distinct(env, reference):
    target, solutions = reference
    assert len(solutions) >= 2
    low, high = env.limits
    margin = env.task.safety.limit_threshold
    settings = IKSettings()
    for q in solutions:
        reached = env.robot.tool_pose_at(q)
        assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) <= settings.position_tolerance
        assert rotation_error(reached[:3, :3], target[:3, :3]) <= settings.rotation_tolerance
        assert np.minimum(q - low, high - q).min() > margin
    gaps = np.abs(solutions[:, None] - solutions[None]).max(axis=2)
    assert np.all(gaps[~np.eye(len(solutions), dtype=bool)] > 0.1)


def test_the_collision_filter_rejects_a_grasp_inside_the_body(env, reference):
    target, solutions = reference
    assert not all(in_collision(env, q) for q in solutions)  # the reference grasp is clear
    inside = target.copy()
    inside[:3, 3] += 0.1 * target[:3, 2]  # 10 cm on along the approach: through the door
    low, high = env.limits
    seeds = ik_seeds(env.rest_q, low, high, np.random.default_rng(0))
    found = reachable_solutions(env.robot, inside, seeds, env.task.safety.limit_threshold)
    assert len(found) > 0
    assert all(in_collision(env, q) for q in found)


def test_the_contact_filter_passes_the_reference_grasp_and_not_a_grasp_of_air(env, reference):
    target, solutions = reference
    q = next(q for q in solutions if not in_collision(env, q))
    assert holds_handle(env, q, SCENE)
    env.reset(seed=SCENE)
    air = target.copy()
    air[:3, 3] -= 0.1 * target[:3, 2]  # 10 cm in front of the handle
    low, high = env.limits
    seeds = ik_seeds(env.rest_q, low, high, np.random.default_rng(0))
    found = reachable_solutions(env.robot, air, seeds, env.task.safety.limit_threshold)
    assert len(found) > 0
    assert not holds_handle(env, found[0], SCENE)


@pytest.mark.parametrize("task", ["door", "drawer"])
def test_the_reference_grasp_of_each_task_passes_every_filter(task):
    env = CipEnv(nominal_task(get_cip_task(task)))
    try:
        env.reset(seed=SCENE)
        low, high = env.limits
        seeds = ik_seeds(env.rest_q, low, high, np.random.default_rng(0))
        target = env.handle_grasp()
        found = reachable_solutions(env.robot, target, seeds, env.task.safety.limit_threshold)
        clear = [q for q in found if not in_collision(env, q)]
        assert clear
        assert holds_handle(env, clear[0], SCENE)
    finally:
        env.close()


def test_the_tool_jacobian_gives_the_tool_points_velocity(env):
    q = np.array([0.3, 0.7, -0.2, -1.2, 0.4, 0.9, 0.5])
    jacobian = tool_jacobian(env.robot, q)
    h = 1e-4  # PyBullet's link states are about float precision
    for j in range(7):
        step = np.eye(7)[j] * h
        ahead, behind = env.robot.tool_pose_at(q + step), env.robot.tool_pose_at(q - step)
        velocity = (ahead[:3, 3] - behind[:3, 3]) / (2 * h)
        assert np.allclose(jacobian[:3, j], velocity, atol=2e-3)


def test_scores_are_manipulability_times_the_joint_limit_penalty(env, reference):
    _, solutions = reference
    scores = score_solutions(env.robot, solutions, GraspScoreConfig())
    assert scores.shape == (len(solutions),) and np.all(scores > 0.0)
    assert len(score_solutions(env.robot, np.zeros((0, 7)), GraspScoreConfig())) == 0


# -- I_c -----------------------------------------------------------------------------------


def test_the_initiation_set_keeps_what_passed_every_filter(env, initiation_set):
    s = initiation_set
    c = s.counts
    assert c.sampled == N and c.sampled >= c.reachable >= c.collision_free >= c.holding >= 1
    assert len(s.grasps) == c.holding == s.bandit.n_arms == len(s.solutions) == len(s.scores)
    assert np.array_equal(s.object_pose, env.draw_pose(SCENE))
    env.reset(seed=SCENE)
    for grasp, solutions, scores in zip(s.grasps, s.solutions, s.scores, strict=True):
        target = s.object_pose @ grasp
        assert len(solutions) == len(scores) >= 1
        assert np.allclose(scores, score_solutions(env.robot, solutions, GraspScoreConfig()))
        for q in solutions:
            assert np.linalg.norm(env.robot.tool_pose_at(q)[:3, 3] - target[:3, 3]) <= 0.005
            assert not in_collision(env, q)


def test_the_same_seed_gives_the_same_initiation_set(initiation_set):
    again = build_initiation_set(get_cip_task("door"), np.random.default_rng(0), n=N)
    assert again.to_json() == initiation_set.to_json()


def test_no_grasp_left_is_an_input_error_with_the_counts():
    cfg = GraspCandidatesConfig(clearance_m=1.0)  # nothing is a metre clear of the door
    with pytest.raises(InputError, match=r"no grasp left after filtering: 6 sampled, \d+ reach"):
        build_initiation_set("door", np.random.default_rng(0), n=6, cfg=cfg)


def test_json_round_trip(initiation_set):
    learned = InitiationSet.from_json(initiation_set.to_json())
    learned.bandit.update(0, 1.0)
    text = learned.to_json()
    back = InitiationSet.from_json(text)
    assert back.to_json() == text
    assert back.counts == initiation_set.counts and back.task == "door"
    assert np.array_equal(back.grasps, initiation_set.grasps)
    for a, b in zip(back.solutions, initiation_set.solutions, strict=True):
        assert np.array_equal(a, b)
    assert back.bandit.pulls.tolist() == [1] + [0] * (len(back.grasps) - 1)


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d.pop("grasps"), "grasps"),
        (lambda d: d["grasps"][0]["solutions"][0].pop(), "grasps.0.solutions.0"),
        (lambda d: d["grasps"][0]["pose"][1].__setitem__(2, float("nan")), "grasps.0.pose.1.2"),
        (lambda d: d["grasps"][0]["pose"][0].__setitem__(0, 2.0), "grasps.0.pose"),
        (lambda d: d["grasps"][0]["scores"].append(1.0), "grasps.0.scores"),
        (lambda d: d["counts"].__setitem__("holding", -1), "counts.holding"),
        (lambda d: d["bandit"]["pulls"].append(0), "bandit: .*rewards"),
        (lambda d: d["bandit"].update(pulls=[0] * 9, rewards=[0.0] * 9), "bandit.pulls"),
    ],
)
def test_malformed_json_is_an_input_error_naming_the_field(initiation_set, edit, field):
    data = json.loads(initiation_set.to_json())
    edit(data)
    with pytest.raises(InputError, match=rf"^initiation_set.json: {field}"):
        InitiationSet.from_json(json.dumps(data))
    with pytest.raises(InputError, match="not JSON"):
        InitiationSet.from_json("{")


# -- the head ------------------------------------------------------------------------------


def toy_set(scores: list[list[float]]) -> InitiationSet:
    """Grasps g = 0.. one cm apart, solution k of grasp g filled with 10 g + k."""
    grasps = np.stack([np.eye(4)] * len(scores))
    grasps[:, 0, 3] = 0.01 * np.arange(len(scores))
    solutions = [np.full((len(s), 7), 10.0 * g) + np.arange(len(s))[:, None]
                 for g, s in enumerate(scores)]  # fmt: skip
    return InitiationSet(
        task="door", object_pose=np.eye(4), grasps=grasps, solutions=solutions,
        scores=[np.array(s) for s in scores], counts=FilterCounts(9, 8, 7, len(scores)),
        bandit=UCB1(len(scores)),
    )  # fmt: skip


def echo_ik(target: np.ndarray, seed: np.ndarray) -> np.ndarray:
    return seed.copy()


@pytest.mark.parametrize(("setting", "solution"), [("head", 0), ("safety", 0), ("mv", 2)])
def test_head_and_mv_draw_the_grasp_and_take_the_first_or_best_solution(setting, solution):
    s = toy_set([[0.1, 0.2, 0.9, 0.3]] * 3)
    pose = np.eye(4)
    pose[:3, 3] = [1.0, 0.0, 0.2]
    rng, again = np.random.default_rng(5), np.random.default_rng(5)
    picked = []
    for _ in range(60):
        start = select_start(s, setting, pose, rng, echo_ik)
        assert start.grasp == int(again.integers(3))  # uniform, from the episode's rng
        assert start.solution == solution
        assert np.array_equal(start.q, s.solutions[start.grasp][solution])
        assert np.allclose(start.target, pose @ s.grasps[start.grasp])
        picked.append(start.grasp)
    assert set(picked) == {0, 1, 2}
    assert s.bandit.total == 0  # choosing is not reporting


def test_cip_takes_ucbs_grasp_and_its_best_solution():
    s = toy_set([[0.5, 0.1], [0.2, 0.7], [0.3, 0.3]])
    rng = np.random.default_rng(0)
    for grasp, best in [(0, 0), (1, 1), (2, 0)]:  # untried grasps first, in order
        start = select_start(s, "cip", np.eye(4), rng, echo_ik)
        assert (start.grasp, start.solution) == (grasp, best)
        report_outcome(s, start.grasp, success=grasp == 1)
    assert select_start(s, "cip", np.eye(4), rng, echo_ik).grasp == 1


def test_the_head_falls_back_to_the_next_solution_then_gives_up():
    s = toy_set([[0.1, 0.9, 0.5]])

    def only_the_first(target: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
        return seed.copy() if seed[0] == 0.0 else None

    start = select_start(s, "mv", np.eye(4), np.random.default_rng(0), only_the_first)
    assert (start.solution, start.q[0]) == (0, 0.0)  # best (1), then 2, then 0
    none = select_start(s, "cip", np.eye(4), np.random.default_rng(0), lambda t, q: None)
    assert (none.grasp, none.solution, none.q) == (0, -1, None)
    with pytest.raises(InputError, match="setting"):
        select_start(s, "e2e", np.eye(4), np.random.default_rng(0), echo_ik)  # type: ignore[arg-type]


def test_ucb_concentrates_on_the_grasp_that_always_succeeds():
    s = toy_set([[1.0]] * 4)
    rng = np.random.default_rng(0)
    for _ in range(200):
        start = select_start(s, "cip", np.eye(4), rng, echo_ik)
        report_outcome(s, start.grasp, success=start.grasp == 2)
    pulls = s.bandit.pulls
    assert pulls.sum() == 200 and pulls[2] > 0.85 * 200
    assert s.bandit.success_rates()[2] == 1.0


def test_the_head_reaches_the_grasp_on_a_jittered_object(initiation_set):
    """An episode's object pose differs from the scene's: the stored grasp moves with
    it and IK, warm-started from the stored solution, reaches it."""
    env = CipEnv("door")
    try:
        ik = robot_ik(env.robot, env.task.safety.limit_threshold)
        rng = np.random.default_rng(0)
        for episode, setting in enumerate(["head", "safety", "mv", "cip"] * 2):
            pose = env.draw_pose(episode)
            assert not np.allclose(pose, initiation_set.object_pose)
            start = select_start(initiation_set, setting, pose, rng, ik)
            assert start.q is not None and start.solution >= 0
            reached = env.robot.tool_pose_at(start.q)
            assert np.allclose(start.target, pose @ initiation_set.grasps[start.grasp])
            assert np.linalg.norm(reached[:3, 3] - start.target[:3, 3]) <= 0.005
            assert rotation_error(reached[:3, :3], start.target[:3, :3]) <= 0.05
    finally:
        env.close()


def test_a_knob_as_deep_as_it_is_long_gets_the_long_side_of_its_face():
    """The lever's knob (2.5 cm across, 4 cm along the arm, 4 cm deep): without the
    front, the principal direction of its cloud could point into the object."""
    knob = CipEnv(nominal_task(get_cip_task("lever")))
    try:
        pose = knob.draw_pose(0)
        points = part_cloud(knob.object_model(pose), np.random.default_rng(0)).points
        axis = bar_axis(points, FRONT)
        assert abs(axis[0]) < 1e-9 and abs(axis[2]) > 0.9  # along the arm (up at q = 0)
    finally:
        knob.close()
