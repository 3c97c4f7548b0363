"""The kinematic expert of `cip-demos`: from a CIP start it opens the door and the drawer
and turns the lever to beta_c along Chapter 5's grasp path, and the task geometry leaves
it room (the slide: not yet, docs/cip.md)."""

from __future__ import annotations

import numpy as np
import pytest

from artic.planning.cip_expert import ExpertConfig, demonstrate, grasp_path_margin
from artic.sim.cip_envs import OBS_SIZE, CipEnv
from artic.sim.robot import IKSettings, solve_ik

CFG = ExpertConfig()


def best_start(env: CipEnv, seed: int, tries: int = 8) -> tuple[np.ndarray, float]:
    """Of `tries` IK solutions of the handle grasp for `reset(seed)`, the one whose grasp
    path to the expert's goal stays farthest from the joint limits, and that margin."""
    pose = env.draw_pose(seed)
    target = env.handle_grasp(pose)
    low, high = env.limits
    rng = np.random.default_rng(seed)
    best, margin = None, -np.inf
    for k in range(tries):
        q = solve_ik(env.robot, target, env.rest_q if k == 0 else rng.uniform(low, high),
                     IKSettings(rounds=30))  # fmt: skip
        if q is None:
            continue
        m = grasp_path_margin(env, pose, q, CFG.overshoot * env.task.success)
        if m > margin:
            best, margin = q, m
    assert best is not None
    return best, margin


@pytest.mark.parametrize("task", ["door", "drawer", "lever"])
def test_the_expert_opens_the_object_from_a_cip_start(task):
    env = CipEnv(task)
    try:
        for seed in (0, 1):
            start, margin = best_start(env, seed)
            # the task's placement leaves the grasp path outside the envelope's sigma1
            assert margin > env.task.safety.sigma1
            demo = demonstrate(env, seed, start, CFG)
            steps = len(demo.actions)
            assert demo.success and demo.dones[-1] and not demo.dones[:-1].any()
            assert demo.obs.shape == demo.next_obs.shape == (steps, OBS_SIZE)
            assert demo.actions.shape == (steps, 13) and np.all(np.abs(demo.actions) <= 1)
            assert np.all(demo.actions[:, 12] > 0)  # the gripper stays closed
            assert np.array_equal(demo.obs[1:], demo.next_obs[:-1])
            assert demo.rewards[-1] >= 1.0  # beta_c's reward on the last step
            assert env.object_joint()[0] >= env.task.success
    finally:
        env.close()


def test_a_demonstration_is_deterministic():
    env = CipEnv("drawer")
    try:
        start, _ = best_start(env, 2)
        a, b = demonstrate(env, 2, start, CFG), demonstrate(env, 2, start, CFG)
        assert a.obs.tobytes() == b.obs.tobytes() and a.actions.tobytes() == b.actions.tobytes()
    finally:
        env.close()
