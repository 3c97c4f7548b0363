"""The CIP stages before learning (issue 21 parts 4-5): the configs of `grasp-candidates`
(G and I_c, Algorithm 3 lines 1-3: `cip_grasps.build_initiation_set`) and `cip-demos`
(ten expert demonstrations, section 7.3), an initiation set read back from a
grasp-candidates folder, and the demonstrations recorded from CIP starts.

Where demonstration k starts: the episode is reset with `demo_seed(seed, k)` (its object
pose jittered as in training); each grasp's stored solutions are re-solved at that pose,
best score first (`select_start` under `mv`), and of those starts the expert takes the
one whose grasp path to its goal keeps every joint farthest from its limits
(`cip_expert.grasp_path_margin`): the expert holds its grasp rigidly and knows the
object's kinematics. Not UCB1's grasp: before learning the bandit knows nothing, and
its first pulls go through the grasps in index order, an order of sampling with no
meaning. Not the best-scored grasp (w P, Eq. 7.1, at the start only): on the slide and
the lever it gave 0 of 10 successful demonstrations (the path ran into sigma1, where the
envelope holds the arm; docs/cip.md). The choice is deterministic: the same initiation
set and seed give the same starts and the same demonstrations.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from artic.artifacts.formats import read_json
from artic.artifacts.manifest import read_manifest, verify_file
from artic.config.schemas import StageConfig
from artic.learning.cip_train import DEMO_ARRAYS, check_input_task, make_env, start_margin
from artic.planning.cip_expert import (
    ExpertConfig,
    demonstrate,
    demonstrate_from_home,
    grasp_path_margin,
)
from artic.planning.cip_grasps import (
    GraspCandidatesConfig,
    InitiationSet,
    Start,
    robot_ik,
    select_start,
)
from artic.sim.cip_envs import CipEnv
from artic.sim.cip_tasks import CipTaskConfig

INITIATION_SET = "initiation_set.json"


class GraspCandidatesStageConfig(StageConfig):
    """The config of `artic grasp-candidates` (conf/grasp_candidates/config.yaml)."""

    task: CipTaskConfig
    grasps: int = Field(100, ge=1, description="grasps sampled on the handle (issue 21: 100)")
    candidates: GraspCandidatesConfig = Field(
        default_factory=GraspCandidatesConfig, description="the scan, sampling and filters"
    )


class CipDemosConfig(StageConfig):
    """The config of `artic cip-demos` (conf/cip_demos/config.yaml)."""

    task: CipTaskConfig
    initiation_set: str = Field(description="a grasp-candidates output folder of the task")
    demos: int = Field(10, ge=1, description="expert episodes from CIP starts (thesis: ten)")
    home_demos: int = Field(
        10, ge=0, description="expert episodes from home, for E2E+BC (the reach planned)"
    )
    expert: ExpertConfig = Field(default_factory=ExpertConfig, description="the expert")


def initiation_set_stats(initiation_set: InitiationSet) -> dict[str, float | int | str]:
    """The manifest's stats of a grasp-candidates output: each filter's count, the IK
    solutions kept and the best score."""
    best = max(float(s.max()) for s in initiation_set.scores)
    return {"task": initiation_set.task, **initiation_set.counts._asdict(),
            "ik solutions": sum(len(s) for s in initiation_set.solutions),
            "best score (w P)": f"{best:.4f}"}  # fmt: skip


def read_initiation_set(folder: Path, task: CipTaskConfig) -> InitiationSet:
    """The initiation set of the grasp-candidates output `folder`, checked to be made
    for `task` (InputError naming the folder or the file's field otherwise)."""
    manifest = read_manifest(folder, expected_stage="grasp-candidates")
    check_input_task("initiation_set", folder, manifest, task)
    path = verify_file(folder, manifest, INITIATION_SET)
    return InitiationSet.from_dict(read_json(path), str(path))


def demo_seed(seed: int, demo: int) -> int:
    """The reset seed of demonstration `demo` (distinct from training's episode seeds)."""
    return int(np.random.SeedSequence([seed, demo, 13]).generate_state(1)[0] % (2**31 - 1))


def grasp_order(initiation_set: InitiationSet) -> list[int]:
    """The grasps by their best solution's score, best first (ties: lower index)."""
    best = np.array([s.max() for s in initiation_set.scores])
    return [int(g) for g in np.argsort(-best, kind="stable")]


def demo_start(
    initiation_set: InitiationSet, env: CipEnv, seed: int, overshoot: float
) -> Start | None:
    """The start of the demonstration reset with `seed` (module docstring): of each
    grasp's best-scored IK solution re-solved at that episode's object pose, the one
    whose grasp path to `overshoot` x beta_c's threshold keeps every joint farthest from
    its limits (`grasp_path_margin`: the expert knows the object's kinematics); None
    when no grasp's IK reaches there."""
    pose = env.draw_pose(seed)
    ik = robot_ik(env.robot, start_margin(env.task, "cip_bc"))  # the starts CIP+BC learns from
    rng = np.random.default_rng(0)  # unused: the grasp is given
    best, margin = None, -np.inf
    for grasp in grasp_order(initiation_set):
        start = select_start(initiation_set, "mv", pose, rng, ik, grasp)
        if start.q is None:
            continue
        upto = overshoot * env.task.success
        m = grasp_path_margin(env, pose, start.q, upto, tool=start.target)
        if m > margin:
            best, margin = start, m
    return best


class DemoRecording(NamedTuple):
    """cip-demos' outputs: arrays (demos.npz: `DEMO_ARRAYS`, then seed (E,) and grasp
    (E,), -1 where no start was found) and one JSON-able record per episode."""

    arrays: dict[str, NDArray[Any]]
    episodes: list[dict[str, Any]]


def record_demos(cfg: CipDemosConfig, initiation_set: InitiationSet) -> DemoRecording:
    """`cfg.demos` expert episodes (`cip_expert.demonstrate`) from CIP starts in the
    environment of the cip and cip_bc settings (envelope and B's lost contact on), then
    `cfg.home_demos` from home (`cip_expert.demonstrate_from_home`) in E2E+BC's (neither),
    each reaching for its seed's CIP start. Episode k is reset from (seed, k)."""
    env, home_env = make_env(cfg.task, "cip_bc"), make_env(cfg.task, "e2e_bc")
    obs, act = tuple(env.observation_space.shape or ()), tuple(env.action_space.shape or ())
    columns: list[list[NDArray[Any]]] = [
        [np.zeros((0, *obs), np.float32)], [np.zeros((0, *act), np.float32)], [np.zeros(0)],
        [np.zeros((0, *obs), np.float32)], [np.zeros(0, bool)], [np.zeros(0, np.int64)],
    ]  # fmt: skip
    episodes: list[dict[str, Any]] = []
    try:
        for k in range(cfg.demos + cfg.home_demos):
            seed, from_home = demo_seed(cfg.seed, k), k >= cfg.demos
            start = demo_start(initiation_set, env, seed, cfg.expert.overshoot)
            record = {"episode": k, "seed": seed, "from_home": from_home, "grasp": -1,
                      "solution": -1, "steps": 0, "return": 0.0, "success": False}  # fmt: skip
            if start is None or start.q is None:
                episodes.append(record)
                continue
            if from_home:
                demo = demonstrate_from_home(home_env, seed, start.q, cfg.expert)
            else:
                demo = demonstrate(env, seed, start.q, cfg.expert)
            steps = len(demo.actions)
            parts: list[NDArray[Any]] = [demo.obs, demo.actions, demo.rewards, demo.next_obs,
                                         demo.dones, np.full(steps, k)]  # fmt: skip
            for column, part in zip(columns, parts, strict=True):
                column.append(part)
            episodes.append({**record, "grasp": start.grasp, "solution": start.solution,
                             "steps": steps, "return": float(demo.rewards.sum()),
                             "success": demo.success})  # fmt: skip
    finally:
        env.close()
        home_env.close()
    arrays = {name: np.concatenate(c) for name, c in zip(DEMO_ARRAYS[:6], columns, strict=True)}
    arrays["success"] = np.array([e["success"] for e in episodes], dtype=bool)
    arrays["from_home"] = np.array([e["from_home"] for e in episodes], dtype=bool)
    arrays["seed"] = np.array([e["seed"] for e in episodes], dtype=np.int64)
    arrays["grasp"] = np.array([e["grasp"] for e in episodes], dtype=np.int64)
    return DemoRecording(arrays, episodes)
