"""Composition of CIPs (`artic.planning.compose`): turning a skill's scene about the
base's vertical axis leaves what the skill observes, perceived frames anchored at the
handle round-trip, grasps are taken best first, and a sequence's tail ends where the
next head starts."""

from __future__ import annotations

import numpy as np
import pytest

from artic.control.tracking import computed_torque
from artic.learning.bandits import UCB1
from artic.planning.cip_grasps import (
    FilterCounts,
    InitiationSet,
    ik_seeds,
    nominal_task,
    reachable_solutions,
)
from artic.planning.compose import (
    ComposeEnv,
    MotionConfig,
    Placement,
    Skill,
    anchored_frame,
    bearing,
    grasp_order,
    layout,
    rot_about_base,
    run_sequence,
)
from artic.sim.cip_envs import CipEnv, task_object, yaw_pose
from artic.sim.cip_tasks import get_cip_task

TURN = np.radians(15.0)


def test_bearing_is_the_turn_about_the_base():
    for angle in (-0.5, 0.0, TURN):
        frame = rot_about_base(angle) @ yaw_pose(1.1, 0.0, 0.15, 0.05)
        assert bearing(frame) == pytest.approx(angle, abs=1e-12)
        assert frame[2, 3] == 0.15 and np.allclose(frame[:3, 2], [0, 0, 1])


@pytest.mark.parametrize("name", ["door", "drawer"])
def test_a_frame_anchored_at_the_handle_round_trips(name):
    task = get_cip_task(name)
    pose = rot_about_base(-TURN) @ yaw_pose(1.12, 0.01, 0.15, 0.07)
    assert np.allclose(anchored_frame(task, task_object(task, pose)), pose, atol=1e-9)


def test_a_scene_turned_about_the_base_is_observed_as_the_training_scene():
    """Joint 1 turned with the scene and read from the object's bearing: the same
    observation, then the same motion under the same actions (PyBullet is not exactly
    symmetric: 1e-3); without reading joint 1 from the bearing, obs[2] is off by the turn."""
    task = nominal_task(get_cip_task("door"))
    plain = CipEnv(task)
    frame = rot_about_base(TURN) @ plain.object_pose
    turned = ComposeEnv([Placement(task, task_object(task, frame), frame)])
    try:
        q = np.asarray(task.robot.start_q, dtype=np.float64)
        a, _ = plain.reset(seed=0, options={"start_q": q})
        b, _ = turned.reset(seed=0, options={"start_q": q + TURN * np.eye(7)[0]})
        assert abs(float(b[2] - a[2]) - TURN) < 1e-6  # not yet read from the bearing
        turned.activate(0)
        b = turned.observe()
        assert np.allclose(a, b, atol=1e-5)
        action = np.zeros(13, dtype=np.float32)
        action[[0, 2, 6]] = 0.5, -0.5, 1.0
        for _ in range(5):
            a = plain.step(action)[0]
            b = turned.step(action)[0]
        assert np.allclose(a, b, atol=1e-3)
    finally:
        plain.close()
        turned.close()


def test_grasps_are_taken_best_first():
    bandit = UCB1(4, 1.0)
    for arm, reward in [(0, 0.0), (1, 1.0), (1, 0.0), (2, 1.0), (3, 1.0), (3, 1.0)]:
        bandit.update(arm, reward)
    iset = InitiationSet("door", np.eye(4), np.tile(np.eye(4), (4, 1, 1)), [np.zeros((1, 7))] * 4,
                         [np.ones(1)] * 4, FilterCounts(4, 4, 4, 4), bandit)  # fmt: skip
    assert grasp_order(iset) == [2, 3, 1, 0]  # rates 0, .5, 1, 1: ties by index


def test_computed_torque_gives_the_error_dynamics():
    rng = np.random.default_rng(0)
    root = rng.normal(size=(7, 7))
    mass, bias = root @ root.T + 7 * np.eye(7), rng.normal(size=7)
    q, qd, q_ref, qd_ref = rng.normal(size=(4, 7))
    tau = computed_torque(mass, bias, q, qd, q_ref, qd_ref, 400.0, 40.0)
    accel = np.linalg.solve(mass, tau - bias)  # M q'' + bias = tau
    assert np.allclose(accel, 400.0 * (q_ref - q) + 40.0 * (qd_ref - qd))


def _reference_set(name: str) -> InitiationSet:
    """One grasp: the task's reference grasp, its IK solution farthest from the limits
    also with joint 1 turned by +-TURN (as the head turns it)."""
    task = nominal_task(get_cip_task(name))
    env = CipEnv(task)
    try:
        world = env.handle_grasp()
        low, high = env.limits
        seeds = ik_seeds(np.asarray(task.robot.start_q), low, high, np.random.default_rng(0))
        found = reachable_solutions(env.robot, world, seeds, 0.1)
        turned = [found + sign * TURN * np.eye(7)[0] for sign in (-1, 1)]
        margin = np.min([np.minimum(t - low, high - t).min(axis=1) for t in turned], axis=0)
        q = found[int(np.argmax(margin))]
        grasp = np.linalg.inv(env.object_pose) @ world
        return InitiationSet(name, env.object_pose, grasp[None], [q[None]], [np.ones(1)],
                             FilterCounts(1, 1, 1, 1), UCB1(1, 1.0))  # fmt: skip
    finally:
        env.close()


def test_a_sequence_chains_heads_and_tails():
    """Two skills side by side (a policy that only holds on, 3 actions): both heads find
    a grasp and a plan, each tail ends where the next head starts, and the same seed
    gives the same sequence."""
    tasks = [get_cip_task(n).model_copy(update={"horizon": 3}) for n in ("door", "drawer")]
    sets = [_reference_set(n) for n in ("door", "drawer")]

    def hold(obs: np.ndarray) -> np.ndarray:
        return np.r_[np.zeros(12), 1.0].astype(np.float32)

    skills = [Skill(t, hold, s, 0.1) for t, s in zip(tasks, sets, strict=True)]

    def run() -> list:
        scene = layout(tasks, [TURN, -TURN], np.random.default_rng(3))
        sim, plan_env = ComposeEnv(scene), ComposeEnv(scene)
        try:
            return run_sequence(skills, sim, plan_env, [p.frame for p in scene],
                                MotionConfig(plan_checks=50_000), seed=3)  # fmt: skip
        finally:
            sim.close()
            plan_env.close()

    first = run()
    assert [o.task for o in first] == ["door", "drawer"]
    assert [o.grasp for o in first] == [0, 0]
    assert all(o.end not in ("no_grasp", "no_plan") and o.steps == 3 for o in first)
    assert all(o.tracking_error < 0.02 for o in first)
    assert np.array_equal(first[1].head_start, first[0].tail_end)
    again = run()
    assert all(np.array_equal(a.tail_end, b.tail_end) for a, b in zip(first, again, strict=True))
