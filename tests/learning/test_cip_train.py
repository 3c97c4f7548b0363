"""The CIP learning loop: the settings' table, episode seeds, best-to-date rows, the
head's reports, and a tiny TD3 run: deterministic, and resumed = uninterrupted."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from artic.errors import InputError
from artic.learning.cip_train import (
    SETTING_NAMES,
    SETTINGS,
    CipEpisodes,
    CipTrainConfig,
    EpisodeRecord,
    HomeStarts,
    curve_row,
    episode_seed,
    make_env,
    start_margin,
    train_run,
)
from artic.learning.td3_settings import Td3Config
from artic.sim.cip_tasks import get_cip_task

TASK = get_cip_task("drawer").model_copy(update={"horizon": 20})
CFG = CipTrainConfig(episodes=4, eval_every=2, eval_rollouts=2,
                     td3=Td3Config(learning_starts=10, batch_size=32))  # fmt: skip


def test_the_settings_add_structure_in_the_thesis_order():
    assert tuple(SETTINGS) == SETTING_NAMES
    e2e, head, safety, mv, cip, cip_bc, e2e_bc = (SETTINGS[s] for s in SETTING_NAMES)
    assert e2e.grasp == "home" and not e2e.safety and not e2e.contact_termination
    assert head.grasp == "random" and head.ik == "naive" and not head.safety
    assert safety == head._replace(safety=True)
    assert mv == safety._replace(ik="best")
    assert cip == mv._replace(grasp="ucb")
    assert cip_bc == cip._replace(demos=True) and e2e_bc == e2e._replace(demos=True)


def test_episode_seeds_are_fixed_and_distinct():
    seeds = [episode_seed(0, k) for k in range(-50, 50)]
    assert len(set(seeds)) == len(seeds)
    assert episode_seed(3, 7) == episode_seed(3, 7) != episode_seed(4, 7)


def test_best_to_date_never_falls():
    win, lose = EpisodeRecord(1.0, True, False), EpisodeRecord(0.0, False, True)
    row = curve_row("cip", 0, 10, [win, lose], [lose], best=0.0)
    assert (row.success, row.success_best, row.violation_rate, row.violation_rate_train) == (
        0.5, 0.5, 0.5, 1.0)  # fmt: skip
    later = curve_row("cip", 0, 20, [lose, lose], [], best=row.success_best)
    assert later.success == 0.0 and later.success_best == 0.5 and later.violation_rate_train == 0


class Counting(HomeStarts):
    def __init__(self) -> None:
        self.reports: list[bool] = []

    def report(self, success: bool) -> None:
        self.reports.append(success)


@pytest.mark.parametrize("explore", [True, False])
def test_the_head_hears_training_episodes_only(explore):
    starts = Counting()
    env = CipEpisodes(make_env(TASK.model_copy(update={"horizon": 3}), "e2e"), starts, 0, explore)
    try:
        for _ in range(2):
            env.reset()
            done = False
            while not done:
                _, _, terminated, truncated, _ = env.step(np.zeros(13, dtype=np.float32))
                done = terminated or truncated
        assert len(env.finished) == 2 and env.episode == 2
        assert starts.reports == ([False, False] if explore else [])
    finally:
        env.close()


def _policy_bytes(state: dict[str, Any]) -> bytes:
    return b"".join(t.numpy().tobytes() for t in state["td3"]["policy"].values())


def test_a_tiny_run_is_deterministic_and_resumes_to_the_same_bytes():
    first: list[dict[str, Any]] = []
    rows = train_run(TASK, "e2e", 0, CFG, HomeStarts(), save=first.append)
    assert [r.episode for r in rows] == [2, 4] and len(first) == 2
    again: list[dict[str, Any]] = []
    assert train_run(TASK, "e2e", 0, CFG, HomeStarts(), save=again.append) == rows
    assert _policy_bytes(again[-1]) == _policy_bytes(first[-1])
    resumed: list[dict[str, Any]] = []
    assert train_run(TASK, "e2e", 0, CFG, HomeStarts(), state=first[0], save=resumed.append) == rows
    assert _policy_bytes(resumed[-1]) == _policy_bytes(first[-1])


def test_a_bc_setting_without_demonstrations_is_bad_input():
    with pytest.raises(InputError, match="demos: setting e2e_bc"):
        train_run(TASK, "e2e_bc", 0, CFG, HomeStarts())


def test_episodes_must_fill_whole_evaluation_blocks():
    with pytest.raises(ValueError, match="episodes"):
        CipTrainConfig(episodes=15, eval_every=10)


def test_starts_under_the_envelope_keep_out_of_sigma1():
    task = get_cip_task("door")
    for setting in ("safety", "mv", "cip", "cip_bc"):
        assert start_margin(task, setting) == task.safety.sigma1
    for setting in ("e2e", "head", "e2e_bc"):
        assert start_margin(task, setting) == task.safety.limit_threshold
