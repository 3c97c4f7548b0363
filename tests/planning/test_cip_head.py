"""The CIP head in the learning loop: grasp starts per setting, the bandit hears the
training episodes, greedy evaluation, and a tiny CIP run that resumes to the same bytes."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest

from artic.learning.cip_train import CipTrainConfig, HeadConfig, train_run
from artic.learning.td3_settings import Td3Config
from artic.planning.cip_grasps import build_initiation_set
from artic.planning.cip_head import GraspStarts
from artic.sim.cip_envs import CipEnv
from artic.sim.cip_tasks import get_cip_task

TASK = get_cip_task("drawer").model_copy(update={"horizon": 20})


@pytest.fixture(scope="module")
def initiation_set():
    return build_initiation_set(TASK, np.random.default_rng(0), n=12)


def test_grasp_starts_put_the_gripper_on_the_handle(initiation_set):
    env = CipEnv(TASK)
    try:
        for setting in ("head", "mv", "cip"):
            starts = GraspStarts(copy.deepcopy(initiation_set), setting, margin=0.1)
            options = starts.choose(env, seed=5, explore=True)
            assert options is not None and options["grasp"]
            env.reset(seed=5, options=options)
            assert env.touching().sum() > 0
    finally:
        env.close()


def test_the_bandit_hears_training_episodes_not_evaluations(initiation_set):
    env = CipEnv(TASK)
    starts = GraspStarts(copy.deepcopy(initiation_set), "cip", margin=0.1)
    try:
        starts.choose(env, seed=1, explore=True)
        starts.report(True)
        assert starts.initiation_set.bandit.total == 1
        starts.choose(env, seed=2, explore=False)
        starts.report(False)  # an evaluation's outcome: not heard
        assert starts.initiation_set.bandit.total == 1
    finally:
        env.close()


def test_evaluation_under_cip_takes_the_most_successful_grasp(initiation_set):
    env = CipEnv(TASK)
    chosen = copy.deepcopy(initiation_set)
    for arm in range(chosen.bandit.n_arms):
        chosen.bandit.update(arm, 0.0)
    best = chosen.bandit.n_arms - 1
    chosen.bandit.update(best, 1.0)
    starts = GraspStarts(chosen, "cip_bc", margin=0.1)
    try:
        options = starts.choose(env, seed=3, explore=False)
        assert options is not None
        env.reset(seed=3, options=options)
        expected = env.object_pose @ chosen.grasps[best]
        tool, _ = env.tool_in_object()
        assert np.linalg.norm(env.object_pose[:3, :3] @ tool + env.object_pose[:3, 3]
                              - expected[:3, 3]) < 0.02  # fmt: skip
    finally:
        env.close()


def test_e2e_has_no_grasp_head(initiation_set):
    with pytest.raises(ValueError, match="home"):
        GraspStarts(initiation_set, "e2e", margin=0.1)


def test_a_tiny_cip_run_resumes_to_the_same_bytes(initiation_set):
    cfg = CipTrainConfig(episodes=4, eval_every=2, eval_rollouts=2,
                         td3=Td3Config(learning_starts=10, batch_size=32))  # fmt: skip

    def run(state: dict[str, Any] | None = None) -> tuple[list[Any], list[dict[str, Any]]]:
        saved: list[dict[str, Any]] = []
        starts = GraspStarts(copy.deepcopy(initiation_set), "cip", margin=0.1)
        return train_run(TASK, "cip", 0, cfg, starts, state=state, save=saved.append), saved

    rows, saved = run()
    assert (
        saved[-1]["starts"]["bandit"]["pulls"] and sum(saved[-1]["starts"]["bandit"]["pulls"]) >= 4
    )
    resumed, again = run(saved[0])
    assert resumed == rows and again[-1]["starts"] == saved[-1]["starts"]
    policy = [t.numpy().tobytes() for t in saved[-1]["td3"]["policy"].values()]
    assert [t.numpy().tobytes() for t in again[-1]["td3"]["policy"].values()] == policy


def test_a_tracked_head_plans_from_home_and_ends_on_the_handle(initiation_set):
    """head.execute=track: the reference starts at home, and the arm tracked along it
    from there ends at the grasp the teleporting head resets to, the fingers on the
    handle; the same seed gives the same reference."""
    env = CipEnv(TASK)
    try:
        teleport = GraspStarts(copy.deepcopy(initiation_set), "mv", margin=0.1)
        options = teleport.choose(env, seed=5, explore=True)
        assert options is not None
        track = GraspStarts(copy.deepcopy(initiation_set), "mv", margin=0.1,
                            head=HeadConfig(execute="track"))  # fmt: skip
        tracked = track.choose(env, seed=5, explore=True)
        assert tracked is not None and tracked["grasp"] and "start_q" not in tracked
        reference = tracked["track"]
        np.testing.assert_allclose(reference["q"][0], TASK.robot.start_q, atol=1e-9)
        np.testing.assert_allclose(reference["q"][-1], options["start_q"], atol=1e-9)
        again = track.choose(env, seed=5, explore=True)
        assert again is not None and again["track"]["q"].tobytes() == reference["q"].tobytes()
        _, info = env.reset(seed=5, options=tracked)
        assert info["head_error"] < 0.01
        assert env.touching()[:3].sum() > 0 and env.touching()[3:].sum() > 0
    finally:
        env.close()


def test_a_head_without_a_plan_is_a_failed_episode_of_its_grasp(initiation_set):
    """A plan that cannot be found (one validity check allowed) starts the episode at
    home and counts against the grasp, as a grasp without an IK solution does."""
    env = CipEnv(TASK)
    try:
        head = HeadConfig(execute="track", plan_checks=1)
        starts = GraspStarts(copy.deepcopy(initiation_set), "cip", margin=0.1, head=head)
        assert starts.choose(env, seed=5, explore=True) is None
        assert starts.initiation_set.bandit.total == 1
        assert starts.initiation_set.bandit.success_rates().max() == 0.0
    finally:
        env.close()
