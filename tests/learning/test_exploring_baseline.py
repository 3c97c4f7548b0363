"""The random baselines of policy search (issue 23): `baseline=exploring`, a DMP towards a
random reachable tool goal near the object with weights on the scale of fitted ones, and
`baseline=centred`, the DMP around keeping still."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from artic.config.compose import compose, validate
from artic.errors import InputError
from artic.learning.rollout import dmp_actor
from artic.learning.search import (
    PolicySearchConfig,
    approach_pose,
    random_dmp,
    run_seed,
    target_point,
)
from artic.sim.envs import ArticTaskEnv

SEEDS = range(24)  # seeds 3, 13, 19 and 22 grasp the handle
REACH = 0.05  # m: "reaches the handle": the tool point within 5 cm of the grasp point


def config(*overrides: str) -> PolicySearchConfig:
    return validate(PolicySearchConfig, compose("policy_search", ["init=random", *overrides]))


def tool_paths(cfg: PolicySearchConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(tool positions (seeds, horizon, 3), target point (3,), whether the environment
    says the rollout touched the object (seeds,)) of one rollout of each seed's initial
    random DMP on the drawer, from reset seed = the seed."""
    p, task = cfg.pi2cma_policy, cfg.task
    env = ArticTaskEnv(task, seed=None)
    try:
        paths, touched = [], []
        for i in SEEDS:
            act = dmp_actor(random_dmp(cfg, run_seed(cfg.seed, i)), p.basis, task.control_dt,
                            task.horizon, p.k_p)  # fmt: skip
            obs, _ = env.reset(seed=i)
            path = []
            for k in range(task.horizon):
                action = np.clip(act(obs.astype(np.float64), k), env.action_space.low,
                                 env.action_space.high)  # fmt: skip
                obs, _, _, _, info = env.step(action.astype(np.float32))
                path.append(env.world.ee_pose()[:3, 3])
            paths.append(path)
            touched.append(info["touched"])
        return np.asarray(paths), target_point(env.world), np.asarray(touched)
    finally:
        env.close()


@pytest.fixture(scope="module")
def exploring() -> PolicySearchConfig:
    return config("task=drawer")


def test_exploring_is_the_default_and_centred_stays_selectable(exploring):
    assert exploring.baseline == "exploring"
    assert config("baseline=centred").baseline == "centred"
    with pytest.raises(InputError, match="baseline"):
        config("baseline=flailing")
    with pytest.raises(ValidationError, match="explore_half_extent"):
        PolicySearchConfig.model_validate(
            {**exploring.model_dump(), "pi2cma_policy": {"explore_half_extent": [0.1, 0.1]}}
        )


def test_exploring_rollouts_cover_the_handles_neighbourhood(exploring):
    paths, handle, touched = tool_paths(exploring)
    distance = np.linalg.norm(paths - handle, axis=-1)  # (seeds, horizon)
    assert distance.min(axis=1).min() <= REACH  # some rollout reaches the handle
    # ... and the environment counts those that grasp or move the drawer as touching it;
    # a tool that never came within 10 cm of the handle cannot have
    assert touched.any() and not touched[distance.min(axis=1) > 0.1].any()
    assert (distance[:, -1] <= REACH + 0.03).any()  # ... and ends beside it
    # every rollout ends near its goal: in the box around the handle (tracking and the
    # forcing term's remainder add a few cm)
    half = np.asarray(exploring.pi2cma_policy.explore_half_extent)
    assert np.all(np.abs(paths[:, -1] - handle) <= half + 0.05)


def test_centred_rollouts_stay_near_the_start(exploring):
    centred = exploring.model_copy(update={"baseline": "centred"})
    paths, handle, touched = tool_paths(centred)
    assert np.linalg.norm(paths - handle, axis=-1).min() > 0.15 and not touched.any()
    assert np.linalg.norm(paths - paths[:, :1], axis=-1).max() < 0.15


def test_exploring_dmp_is_seeded_and_fitted_in_scale(exploring):
    a, b = random_dmp(exploring, 7), random_dmp(exploring, 7)
    assert a.to_vector().tobytes() == b.to_vector().tobytes()
    other = random_dmp(exploring, 8)
    assert not np.array_equal(a.goal, other.goal)
    start = np.asarray(exploring.task.robot.start_q)
    np.testing.assert_array_equal(a.y0, start)
    assert np.abs(a.goal - start).max() > 0.05  # goes somewhere, unlike centred
    std = exploring.pi2cma_policy.explore_weight_std
    assert 0.7 * std < a.weights_.std() < 1.3 * std
    centred = random_dmp(exploring.model_copy(update={"baseline": "centred"}), 7)
    np.testing.assert_array_equal(centred.goal, start)


def test_exploring_goal_reaches_the_tball_ball():
    cfg = config("task=tball")
    params = random_dmp(cfg, run_seed(cfg.seed, 0))
    env = ArticTaskEnv(cfg.task, seed=None)
    try:
        tool = env.world.ee_pose(params.goal)[:3, 3]
        ball = target_point(env.world)
    finally:
        env.close()
    half = np.asarray(cfg.pi2cma_policy.explore_half_extent)
    assert np.all(np.abs(tool - ball) <= half + 0.005)  # IK within 5 mm of a goal in the box


def test_approach_pose_points_away_from_the_robot_and_is_a_rotation():
    pose = approach_pose(np.array([0.6, 0.6, 0.4]))
    np.testing.assert_allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(pose[:3, :3]), 1.0)
    np.testing.assert_allclose(pose[:3, 2], [np.sqrt(0.5), np.sqrt(0.5), 0.0])
    np.testing.assert_allclose(pose[:3, 3], [0.6, 0.6, 0.4])
