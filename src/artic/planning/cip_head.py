"""The head of a CIP in the learning loop (Algorithm 3 lines 6-10, 14): the
`learning.cip_train.Starts` of the settings that start at a grasp (head, safety, mv,
cip; cip_bc starts as cip), over an initiation set (`planning/cip_grasps.py`).

Each episode: the grasp the setting picks (uniformly at random, or UCB1's under cip),
moved with the episode's object pose, its IK warm-started from the stored solutions in
the setting's order (the first found: "naive IK"; best-scored first under mv and cip);
then, with `head.execute=teleport`, the arm reset there; with `track`, an OMPL
RRTConnect plan from home to it in the episode's own scene (the environment is reset to
it first: the pose comes from the seed), time-parameterised and tracked by computed
torque with the hand open (`CipEnv.follow`); the gripper closed at the end (Gamma). The
random draws come from the episode's seed, so a run's starts need no generator state of
their own; the bandit's counts are the state. An evaluation episode (no exploration)
under cip takes the grasp of highest success rate (ties: the lowest index), others draw
as in training. A grasp whose stored solutions all fail at the episode's pose, or whose
plan fails (`track`), counts as a failed episode of that grasp; the episode then starts
at home.

`plan_head` and `timed_path` are the head's plan and reference, shared with `compose`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from artic.learning.cip_train import HeadConfig, HeadMotion, Setting
from artic.planning.cip_grasps import (
    HeadSetting,
    InitiationSet,
    in_collision,
    report_outcome,
    robot_ik,
    select_start,
)
from artic.planning.ompl_adapter import PlanResult, plan_path
from artic.planning.trajectory import Timed, time_parameterize
from artic.sim.cip_envs import CipEnv

F64 = NDArray[np.float64]


def plan_head(
    env: CipEnv,
    start: F64,
    goal: F64,
    motion: HeadMotion,
    seed: int,
    obstacles: list[int] | None = None,
) -> PlanResult:
    """OMPL RRTConnect from `start` to `goal` (7,) within the joint limits, every state
    clear of `obstacles` (default: the env's object) and the ground by
    `motion.clearance_m` with the hand open (`in_collision`, kinematic: it moves the
    arm), stopped after `motion.plan_checks` validity checks."""
    low, high = env.limits
    bodies = None if obstacles is None else tuple(obstacles)
    return plan_path(
        low, high, start, goal, lambda q: not in_collision(env, q, motion.clearance_m, bodies),
        "rrtconnect", motion.plan_time_s, seed=seed, resolution=motion.resolution,
        max_checks=motion.plan_checks,
    )  # fmt: skip


def timed_path(waypoints: F64, dt: float, speed: float, settle_s: float) -> Timed:
    """The reference a head tracks: `waypoints` (K, 7) at most `speed` rad/s per joint,
    sampled every `dt`, smoothed over 0.1 s, held `settle_s` at its end."""
    return time_parameterize(waypoints, dt, speed, smoothing_s=0.1, hold_s=settle_s)


class GraspStarts:
    """`Starts` over `initiation_set` for `setting` (module docstring)."""

    def __init__(
        self,
        initiation_set: InitiationSet,
        setting: Setting,
        margin: float,
        head: HeadConfig | None = None,
    ) -> None:
        if setting in ("e2e", "e2e_bc"):
            raise ValueError(f"setting {setting} starts at home, not at a grasp")
        self.initiation_set = initiation_set
        self.setting: HeadSetting = "cip" if setting == "cip_bc" else setting  # type: ignore[assignment]
        self.margin = margin
        self.head = HeadConfig() if head is None else head
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
            self._failed(explore, start.grasp)
            return None
        if self.head.execute == "track":
            return self._tracked(env, start.q, seed, explore, start.grasp)
        return {"start_q": start.q, "grasp": True}

    def _tracked(
        self, env: CipEnv, goal: F64, seed: int, explore: bool, grasp: int
    ) -> dict[str, Any] | None:
        """The `track` head's reset options: the plan from home to `goal` in the
        episode's scene (`env` reset with `seed`), as a timed reference."""
        env.reset(seed=seed)
        home = np.asarray(env.task.robot.start_q, dtype=np.float64)
        plan = plan_head(env, home, goal, self.head, seed)
        if not plan.solved:
            self._failed(explore, grasp)
            return None
        timed = timed_path(plan.path, env.task.physics_dt, self.head.speed, self.head.settle_s)
        return {"track": {"q": timed.q, "qd": timed.qd, "k_p": self.head.k_p}, "grasp": True}

    def _failed(self, explore: bool, grasp: int) -> None:
        """No start for `grasp` (no IK solution or no plan): a failed episode of it;
        the episode starts at home."""
        if explore:
            report_outcome(self.initiation_set, grasp, False)
        self._grasp = None

    def report(self, success: bool) -> None:
        if self._grasp is not None:
            report_outcome(self.initiation_set, self._grasp, success)
            self._grasp = None

    def state(self) -> dict[str, Any]:
        return {"bandit": self.initiation_set.bandit.to_dict()}

    def load(self, state: dict[str, Any]) -> None:
        from artic.learning.bandits import UCB1

        self.initiation_set.bandit = UCB1.from_dict(state["bandit"], "starts.bandit")
