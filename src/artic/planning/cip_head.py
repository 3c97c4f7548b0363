"""The head of a CIP in the learning loop (Algorithm 3 lines 6-10, 14): the
`learning.cip_train.Starts` of the settings that start at a grasp (head, safety, mv,
cip; cip_bc starts as cip), over an initiation set (`planning/cip_grasps.py`).

Each episode: the grasp the setting picks (uniformly at random, or UCB1's under cip),
moved with the episode's object pose, its IK warm-started from the stored solutions in
the setting's order (the first found: "naive IK"; best-scored first under mv and cip);
the arm teleported there and the gripper closed (`head.execute=teleport`, the only
mode so far; docs/cip.md). The random draws come from the episode's seed, so a run's
starts need no generator state of their own; the bandit's counts are the state. An
evaluation episode (no exploration) under cip takes the grasp of highest success rate
(ties: the lowest index), others draw as in training. A grasp whose stored solutions all
fail at the episode's pose counts as a failed episode of that grasp; the episode then
starts at home.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from artic.learning.cip_train import Setting
from artic.planning.cip_grasps import (
    HeadSetting,
    InitiationSet,
    report_outcome,
    robot_ik,
    select_start,
)
from artic.sim.cip_envs import CipEnv


class GraspStarts:
    """`Starts` over `initiation_set` for `setting` (module docstring)."""

    def __init__(self, initiation_set: InitiationSet, setting: Setting, margin: float) -> None:
        if setting in ("e2e", "e2e_bc"):
            raise ValueError(f"setting {setting} starts at home, not at a grasp")
        self.initiation_set = initiation_set
        self.setting: HeadSetting = "cip" if setting == "cip_bc" else setting  # type: ignore[assignment]
        self.margin = margin
        self._grasp: int | None = None

    def choose(self, env: CipEnv, seed: int, explore: bool) -> dict[str, Any] | None:
        rng = np.random.default_rng([seed, 17])
        ik = robot_ik(env.robot, self.margin)
        setting, grasp = self.setting, None
        if not explore and setting == "cip":  # greedy: the best success rate so far
            grasp = int(np.argmax(self.initiation_set.bandit.success_rates()))
        pose = env.draw_pose(seed)
        start = select_start(self.initiation_set, setting, pose, rng, ik, grasp)
        self._grasp = start.grasp if explore else None
        if start.q is None:
            if explore:
                report_outcome(self.initiation_set, start.grasp, False)
            self._grasp = None
            return None
        return {"start_q": start.q, "grasp": True}

    def report(self, success: bool) -> None:
        if self._grasp is not None:
            report_outcome(self.initiation_set, self._grasp, success)
            self._grasp = None

    def state(self) -> dict[str, Any]:
        return {"bandit": self.initiation_set.bandit.to_dict()}

    def load(self, state: dict[str, Any]) -> None:
        from artic.learning.bandits import UCB1

        self.initiation_set.bandit = UCB1.from_dict(state["bandit"], "starts.bandit")
