"""ArticTaskEnv: Gymnasium API, Eq. 5.1 reward, seeded resets, registration."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from artic.errors import InputError
from artic.sim.envs import ENV_IDS, ArticTaskEnv, kinematic_reward, register_envs
from artic.sim.tasks import get_task


@pytest.fixture(scope="module")
def drawer_env():
    env = ArticTaskEnv("drawer", seed=0)
    yield env
    env.close()


@pytest.mark.parametrize("task", ["drawer", "microwave", "tball"])
def test_passes_gymnasium_check_env_in_physical_units(task):
    env = ArticTaskEnv(task, seed=0)
    try:
        with warnings.catch_warnings():
            # the rad/s box is kept on purpose (normalised_actions=True gives [-1, 1]:
            # tests/sim/test_gym.py checks that mode with every warning an error)
            warnings.filterwarnings("ignore", message=".*symmetric and normalized.*")
            check_env(env, skip_render_check=True)
    finally:
        env.close()


def test_observation_is_robot_then_object_configuration(drawer_env):
    obs, info = drawer_env.reset(seed=3)
    assert obs.dtype == np.float32 and obs.shape == (8,)
    assert drawer_env.observation_space.contains(obs)
    np.testing.assert_allclose(obs[:7], drawer_env.world.robot_q(), atol=1e-6)
    np.testing.assert_allclose(obs[7:], drawer_env.world.object_q(), atol=1e-6)
    assert drawer_env.action_space.shape == (7,)
    start_q = np.asarray(drawer_env.task.robot.start_q)
    assert 0 < np.abs(obs[:7] - start_q).max() < 5 * drawer_env.task.robot.start_noise
    assert info["success"] is False and info["q_object"].shape == (1,)


def test_reward_is_eq_5_1(drawer_env):
    drawer_env.reset(seed=0)
    action = np.array([0.3, -0.2, 0.1, 0.5, 0.0, -0.4, 0.2], dtype=np.float32)
    _, reward, terminated, truncated, info = drawer_env.step(action)
    q_object, goal = info["q_object"], np.asarray(drawer_env.task.goal)
    by_hand = -60.0 * float(np.sum((goal - q_object) ** 2)) - 0.001 * float(
        np.sum(action.astype(np.float64) ** 2)
    )
    assert reward == pytest.approx(by_hand, rel=1e-12)
    assert kinematic_reward(np.array([0.25]), np.array([0.25]), np.zeros(7), 60.0, 0.001) == 0.0
    assert kinematic_reward(
        np.array([0.0]), np.array([1.0]), np.ones(7), 60.0, 0.001
    ) == pytest.approx(-60.007)
    assert terminated is False and truncated is False


def test_truncated_at_the_horizon_never_terminated():
    task = get_task("tball").model_copy(update={"horizon": 3})
    env = ArticTaskEnv(task, seed=0)
    try:
        env.reset(seed=0)
        flags = [env.step(np.zeros(7, dtype=np.float32))[2:4] for _ in range(3)]
        assert flags == [(False, False), (False, False), (False, True)]
    finally:
        env.close()


def test_same_seed_same_trajectory_bytes(drawer_env):
    actions = np.random.default_rng(7).uniform(-1.0, 1.0, size=(12, 7)).astype(np.float32)

    def rollout(env: ArticTaskEnv, seed: int) -> bytes:
        obs, _ = env.reset(seed=seed)
        out = [obs]
        rewards = []
        for a in actions:
            obs, reward, *_ = env.step(a)
            out.append(obs)
            rewards.append(reward)
        return np.stack(out).tobytes() + np.asarray(rewards).tobytes()

    first = rollout(drawer_env, 11)
    assert rollout(drawer_env, 12) != first  # another seed, another start
    assert rollout(drawer_env, 11) == first  # after a different episode
    other = ArticTaskEnv("drawer", seed=99)
    try:
        assert rollout(other, 11) == first  # in a fresh environment
    finally:
        other.close()


def test_success_flag_uses_the_task_threshold():
    task = get_task("microwave").model_copy(update={"object_start": [0.05]})
    env = ArticTaskEnv(task, seed=0)
    try:
        _, info = env.reset(seed=0)
        assert info["success"] is True  # 0.05 rad from a closed door, threshold 0.1
    finally:
        env.close()


@pytest.mark.parametrize("task", ["drawer", "microwave", "tball"])
def test_a_robot_keeping_still_never_touches_the_object(task):
    """`info["touched"]` counts contact, not the object settling: idle, it stays False
    (and a new episode starts untouched)."""
    env = ArticTaskEnv(task, seed=0)
    try:
        for seed in (0, 1):
            _, info = env.reset(seed=seed)
            assert info["touched"] is False
            for _ in range(env.task.horizon):
                *_, info = env.step(np.zeros(7, dtype=np.float32))
            assert info["touched"] is False
    finally:
        env.close()


def test_unknown_task_is_an_input_error():
    with pytest.raises(InputError, match="known tasks"):
        ArticTaskEnv("teapot")


def test_import_of_artic_registers_nothing_and_the_envs_module_registers_the_ids():
    code = (
        "import gymnasium, artic; "
        "assert not any(i.startswith('artic/') for i in gymnasium.registry); "
        "import artic.sim.envs; "
        "assert [i for i in gymnasium.registry if i.startswith('artic/')] == "
        "artic.sim.envs.ENV_IDS"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    assert register_envs() == list(ENV_IDS) == register_envs()
    env = gym.make("artic/TBall-v0", seed=0)
    try:
        obs, _ = env.reset(seed=0)
        assert obs.shape == (8,)
        assert env.unwrapped.task.name == "tball"
    finally:
        env.close()
