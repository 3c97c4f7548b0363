"""Chapter 7 environments: Gymnasium API, determinism, the object frame, beta_c and the
shaped reward, B (joint limits, lost contact), the grasp at reset and the envelope."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from artic.sim.cip_envs import CipEnv
from artic.sim.cip_tasks import get_cip_task
from artic.sim.robot import IKSettings, solve_ik

TASKS = ["door", "drawer", "slide", "lever"]


def grasp_configuration(env: CipEnv, seed: int) -> np.ndarray:
    """An IK solution of the task's handle grasp for `reset(seed)`'s pose, the one of 8
    farthest from the joint limits (the MV setting's idea, here only for the tests)."""
    target = env.handle_grasp(env.draw_pose(seed))
    rng = np.random.default_rng(0)
    low, high = env.limits
    best, margin = None, -np.inf
    for k in range(8):
        start = env.rest_q if k == 0 else rng.uniform(low, high)
        q = solve_ik(env.robot, target, start, IKSettings(rounds=30))
        if q is None:
            continue
        distance = np.minimum(q - low, high - q).min()
        if distance > margin:
            best, margin = q, distance
    assert best is not None
    return best


@pytest.mark.parametrize("task", TASKS)
def test_passes_gymnasium_check_env(task):
    env = CipEnv(task, seed=0)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_env(env, skip_render_check=True)
    finally:
        env.close()


def _episode(task: str, seed: int, options=None, steps: int = 6) -> bytes:
    env = CipEnv(task)
    rng = np.random.default_rng(seed)
    try:
        obs, _ = env.reset(seed=seed, options=options)
        out = [obs.tobytes()]
        for _ in range(steps):
            obs, reward, terminated, _, _ = env.step(rng.uniform(-1, 1, 13).astype(np.float32))
            out += [obs.tobytes(), np.float64(reward).tobytes()]
            if terminated:
                break
        return b"".join(out)
    finally:
        env.close()


@pytest.mark.parametrize("task", TASKS)
def test_same_seed_same_bytes(task):
    assert _episode(task, 3) == _episode(task, 3)
    assert _episode(task, 3) != _episode(task, 4)


def test_the_object_pose_is_jittered_within_its_bounds_and_predictable():
    env = CipEnv("door")
    o = env.task.object
    try:
        for seed in range(5):
            expected = env.draw_pose(seed)
            env.reset(seed=seed)
            assert np.array_equal(env.object_pose, expected)
            assert abs(expected[0, 3] - o.x) <= o.jitter_xy
            assert abs(expected[1, 3] - o.y) <= o.jitter_xy
            assert abs(np.arctan2(expected[1, 0], expected[0, 0])) <= o.jitter_yaw
    finally:
        env.close()


def test_actions_are_given_in_the_object_frame():
    env = CipEnv("door")
    try:
        env.reset(seed=1)
        a = np.zeros(13)
        a[0], a[5] = 1.0, 0.5  # +x of the object, a turn about its z
        world = env.to_world(a)
        rotation = env.object_pose[:3, :3]
        assert np.allclose(world[:3], rotation[:, 0]) and np.allclose(
            world[3:6], 0.5 * rotation[:, 2]
        )
        assert env.observation_space.contains(env.reset(seed=1)[0])
    finally:
        env.close()


@pytest.mark.parametrize("task", TASKS)
def test_the_grasp_at_reset_holds_the_handle_between_both_fingers(task):
    env = CipEnv(task)
    try:
        q = grasp_configuration(env, seed=1)
        env.reset(seed=1, options={"start_q": q, "grasp": True})
        tool, _ = env.tool_in_object()
        target = np.linalg.inv(env.object_pose) @ env.handle_grasp()
        assert np.linalg.norm(tool - target[:3, 3]) < 0.01
        hold = np.zeros(13, dtype=np.float32)
        hold[12] = 1.0
        touches = []
        for _ in range(5):
            env.step(hold)
            touches.append(env.touching())
        per_finger = np.median([[t[:3].sum(), t[3:].sum()] for t in touches], axis=0)
        assert np.all(per_finger > 0.5)  # both fingers press
        thickness = env.parts.handle_thickness
        assert env.gripper.width() == pytest.approx(thickness, abs=4e-3)
    finally:
        env.close()


def test_pulling_the_grasped_drawer_succeeds_with_the_shaped_reward():
    """A scripted pull (-x of the object) opens the drawer to beta_c; every reward is
    1{success} + gamma Phi(s') - Phi(s), Phi = q_O / q_O*."""
    env = CipEnv("drawer")
    gamma, goal = env.task.gamma, env.task.success
    try:
        q = grasp_configuration(env, seed=0)
        env.reset(seed=0, options={"start_q": q, "grasp": True})
        phi = env.object_joint()[0] / goal
        action = np.zeros(13, dtype=np.float32)
        action[0], action[12] = -0.6, 1.0
        for _ in range(env.task.horizon):
            _, reward, terminated, truncated, info = env.step(action)
            phi_next = env.object_joint()[0] / goal
            assert reward == pytest.approx(float(info["success"]) + gamma * phi_next - phi)
            phi = phi_next
            if terminated or truncated:
                break
        assert info["success"] and terminated
        assert env.object_joint()[0] >= goal
    finally:
        env.close()


def test_a_joint_at_its_limit_ends_the_episode():
    env = CipEnv("door", safety=False, contact_termination=False)
    try:
        low, _ = env.limits
        q = np.array(get_cip_task("door").robot.start_q)
        q[3] = low[3] + 0.05  # the elbow 0.05 rad from its limit (threshold 0.1)
        env.reset(seed=0, options={"start_q": q})
        _, _, terminated, _, info = env.step(np.zeros(13, dtype=np.float32))
        assert terminated and info["joint_limit"] and not info["success"]
    finally:
        env.close()


def test_the_envelope_takes_over_between_sigma1_and_its_threshold():
    env = CipEnv("door", safety=True, contact_termination=False)
    try:
        low, _ = env.limits
        q = np.array(get_cip_task("door").robot.start_q)
        q[0] = low[0] + 0.25  # inside sigma1 (0.3), outside sigma2 (0.2)
        env.reset(seed=0, options={"start_q": q})
        _, _, _, _, info = env.step(np.zeros(13, dtype=np.float32))
        assert info["envelope"]["null_space"] > 0
    finally:
        env.close()


@pytest.mark.parametrize(("contact_termination", "ends"), [(True, True), (False, False)])
def test_losing_contact_ends_the_episode_unless_e2e(contact_termination, ends):
    env = CipEnv("door", contact_termination=contact_termination)
    try:
        env.reset(seed=0)  # home: no contact
        steps = env.task.contact_loss_steps
        for k in range(steps):
            _, _, terminated, _, info = env.step(np.zeros(13, dtype=np.float32))
            assert terminated == (ends and k == steps - 1)
        assert info["contact_lost"] == ends
    finally:
        env.close()


def test_a_bad_start_is_refused():
    env = CipEnv("door")
    try:
        with pytest.raises(ValueError, match="start_q"):
            env.reset(seed=0, options={"start_q": [0.0, 1.0]})
    finally:
        env.close()


def test_joint_speeds_stay_near_the_iiwas_limits():
    """Random actions without the envelope (the stiffest commands), 3 episodes: PyBullet
    holds every joint near its datasheet speed (`cap_joint_speeds`; its solver's clamp
    lets a step end up to about 30% above); without the cap the wrist reached 14x."""
    env = CipEnv("door", safety=False, contact_termination=False)
    worst = np.zeros(7)
    try:
        for episode in range(3):
            rng = np.random.default_rng(episode)
            env.reset(seed=episode)
            for _ in range(150):
                terminated = env.step(rng.uniform(-1.0, 1.0, 13).astype(np.float32))[2]
                worst = np.maximum(worst, np.abs(env.robot.qd()) / env.robot.velocity_limits)
                if terminated:
                    break
    finally:
        env.close()
    assert worst.max() < 1.5
