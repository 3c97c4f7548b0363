"""The kinematic expert of `cip-demos` (issue 21 part 5; thesis section 7.3, "Ten
demonstrations from an expert policy"): Chapter 5's grasp path (`planning/grasp.py`,
Algorithm 2's GraspPath) along the object's motion, played as VICES actions at a fixed
stiffness through `CipEnv`.

From a CIP start (the gripper closed on the handle): the grasp is the tool pose held
fixed to the handle's link at the current opening; every action asks for the tool pose
that grasp has `lead` m further along its path (toward beta_c and beyond), as a
displacement and rotation in the object's frame (the environment's action frame),
scaled to the action range, at the fixed stiffness `stiffness_action`.

From home (`demonstrate_from_home`, the E2E+BC setting's episodes): first the reach, an
OMPL RRTConnect plan from home to the CIP start in the episode's scene (the hand open,
`reach_clearance` m from the object), time-parameterised at `reach_speed` rad/s and its
tool poses played as VICES targets at `reach_stiffness` with the hand open; then
`settle_actions` actions holding the plan's last pose and `close_actions` closing the
hand there; then the expert as above. A straight reach from home instead ran a joint
into its limit on 2 of 6 episodes and never grasped (docs/cip.md).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field
from scipy.spatial.transform import Rotation

from artic.config.schemas import Strict
from artic.planning.grasp import Grasp, grasp_from_world_pose, grasp_path
from artic.sim.cip_envs import CipEnv
from artic.sim.robot import IKSettings, solve_ik

F64 = NDArray[np.float64]


class ExpertConfig(Strict):
    """The expert's constants (ours)."""

    lead: float = Field(0.04, gt=0, description="target ahead along the tool's path, m")
    overshoot: float = Field(1.3, ge=1, description="drive the joint to this x the success value")
    stiffness_action: float = Field(
        0.0, ge=-1, le=1, description="the 6 stiffness actions (0: mid-range k_p)"
    )
    reach_speed: float = Field(0.8, gt=0, description="from home: the reach's joint speed, rad/s")
    reach_stiffness: float = Field(
        1.0, ge=-1, le=1, description="from home: the stiffness actions of the reach"
    )
    reach_clearance: float = Field(
        0.002, ge=0, description="from home: the planned reach's distance to the object, m"
    )
    reach_checks: int = Field(
        100_000, ge=1, description="from home: RRTConnect's validity checks at most"
    )
    settle_actions: int = Field(10, ge=0, description="from home: holding the reach's end")
    close_actions: int = Field(10, ge=1, description="from home: closing the hand there")


class Demonstration(NamedTuple):
    """One episode of transitions: obs (T, 30), actions (T, 13), rewards (T,), next_obs
    (T, 30), dones (T,) (terminated, not truncated); success of the episode."""

    obs: NDArray[np.float32]
    actions: NDArray[np.float32]
    rewards: F64
    next_obs: NDArray[np.float32]
    dones: NDArray[np.bool_]
    success: bool


def _tool_world(env: CipEnv) -> F64:
    tool, rotation = env.tool_in_object()
    local = np.eye(4)
    local[:3, :3], local[:3, 3] = rotation, tool
    return env.object_pose @ local


def pose_action(env: CipEnv, target: F64, stiffness: float, close: bool) -> NDArray[np.float32]:
    """(13,) action moving the tool toward the world pose `target` (4, 4): displacement
    and rotation in the object's frame over the VICES scales, clipped to [-1, 1]."""
    cfg = env.task.vices
    current = _tool_world(env)
    to_object = env.object_pose[:3, :3].T
    dp = to_object @ (target[:3, 3] - current[:3, 3])
    dr = to_object @ Rotation.from_matrix(target[:3, :3] @ current[:3, :3].T).as_rotvec()
    action = np.full(13, stiffness)
    action[:3] = np.clip(dp / cfg.position_scale, -1.0, 1.0)
    action[3:6] = np.clip(dr / cfg.rotation_scale, -1.0, 1.0)
    action[12] = 1.0 if close else -1.0
    return action.astype(np.float32)


def held_grasp(env: CipEnv) -> Grasp:
    """The grasp the tool holds now: its pose fixed to the handle's link at q_O."""
    link = env.model.link_index("handle_0")
    q_o, _ = env.object_joint()
    return grasp_from_world_pose(env.model, link, np.array([q_o]), _tool_world(env), "handle")


def expert_action(env: CipEnv, grasp: Grasp, cfg: ExpertConfig) -> NDArray[np.float32]:
    """The action toward the pose `grasp` has when the tool point has moved `lead` m
    further along its path (the object's joint advanced by lead / the point's speed
    along it), the joint at most `overshoot` x beta_c's threshold."""
    q_o, _ = env.object_joint()
    goal = max(cfg.overshoot * env.task.success, q_o)
    step = 1e-3
    here, there = grasp_path(env.model, grasp, np.array([[q_o], [q_o + step]]))
    speed = float(np.linalg.norm(there[:3, 3] - here[:3, 3])) / step  # m per joint unit
    ahead = min(q_o + cfg.lead / max(speed, 1e-6), goal)
    target = grasp_path(env.model, grasp, np.array([[ahead]]))[0]
    return pose_action(env, target, cfg.stiffness_action, close=True)


Row = tuple[NDArray[np.float32], NDArray[np.float32], float, NDArray[np.float32], bool]


class _Episode:
    """Transitions recorded as they are taken."""

    def __init__(self, env: CipEnv, obs: NDArray[np.float32]) -> None:
        self.env, self.obs, self.rows = env, obs, list[Row]()
        self.done = self.success = False

    def step(self, action: NDArray[np.float32]) -> None:
        next_obs, reward, terminated, truncated, info = self.env.step(action)
        self.rows.append((self.obs, action, float(reward), next_obs, bool(terminated)))
        self.obs, self.done = next_obs, bool(terminated or truncated)
        self.success = bool(info["success"])

    def finish_with_expert(self, cfg: ExpertConfig) -> Demonstration:
        grasp = held_grasp(self.env)
        while not self.done:
            self.step(expert_action(self.env, grasp, cfg))
        if not self.rows:
            empty = np.zeros((0, *self.obs.shape), np.float32)
            return Demonstration(empty, np.zeros((0, 13), np.float32), np.zeros(0), empty,
                                 np.zeros(0, bool), False)  # fmt: skip
        o, a, r, n, d = zip(*self.rows, strict=True)
        return Demonstration(np.array(o), np.array(a), np.array(r), np.array(n), np.array(d),
                             self.success)  # fmt: skip


def demonstrate(env: CipEnv, seed: int, start_q: F64, cfg: ExpertConfig) -> Demonstration:
    """One expert episode from a CIP start: `env.reset(seed=seed)` with the arm at
    `start_q` (7,) and the gripper closed on the handle there, then `expert_action`
    until the episode ends."""
    obs, _ = env.reset(seed=seed, options={"start_q": start_q, "grasp": True})
    return _Episode(env, obs).finish_with_expert(cfg)


def reach_poses(env: CipEnv, seed: int, start_q: F64, cfg: ExpertConfig) -> list[F64] | None:
    """The tool poses (world, one per action) of the reach from home to `start_q` in
    the scene of `env.reset(seed=seed)` (module docstring); None when OMPL finds no plan.
    Leaves the environment to be reset."""
    from artic.planning.cip_grasps import in_collision
    from artic.planning.ompl_adapter import plan_path
    from artic.planning.trajectory import time_parameterize

    env.reset(seed=seed)
    low, high = env.limits
    plan = plan_path(low, high, env.rest_q, start_q,
                     lambda q: not in_collision(env, q, cfg.reach_clearance), "rrtconnect",
                     60.0, seed=seed, resolution=0.02, max_checks=cfg.reach_checks)  # fmt: skip
    if not plan.solved:
        return None
    timed = time_parameterize(plan.path, env.task.control_dt, cfg.reach_speed, smoothing_s=0.1)
    return [env.robot.tool_pose_at(q) for q in timed.q[1:]]


def demonstrate_from_home(env: CipEnv, seed: int, start_q: F64, cfg: ExpertConfig) -> Demonstration:
    """One expert episode from home (E2E+BC): the reach to `start_q` (7,), the hand
    closed there, then `expert_action` until the episode ends (module docstring). No
    plan: an episode of no transitions, not a success."""
    poses = reach_poses(env, seed, start_q, cfg)
    obs, _ = env.reset(seed=seed)
    episode = _Episode(env, obs)
    if poses is None:
        episode.done = True
        return episode.finish_with_expert(cfg)
    hold = [(poses[-1], False)] * cfg.settle_actions + [(poses[-1], True)] * cfg.close_actions
    for target, close in [(p, False) for p in poses] + hold:
        if episode.done:
            break
        episode.step(pose_action(env, target, cfg.reach_stiffness, close))
    return episode.finish_with_expert(cfg)


def grasp_path_margin(
    env: CipEnv, pose: F64, q: F64, upto: float, points: int = 8, tool: F64 | None = None
) -> float:
    """The least distance (rad) of any joint to its limits while the arm, started at q
    (7,) holding the tool pose `tool` (4, 4, world; default the reference handle grasp)
    on the closed object at `pose` (4, 4), follows that grasp's path to the opening
    `upto` (IK of `points` poses, warm-started); -inf where IK fails. The expert's
    choice among start configurations."""
    model = env.object_model(pose)
    link = model.link_index("handle_0")
    held = env.handle_grasp(pose) if tool is None else tool
    grasp = grasp_from_world_pose(model, link, np.zeros(1), held, "handle")
    low, high = env.limits
    margin = np.inf
    for opening in np.linspace(0.0, upto, points):
        target = grasp_path(model, grasp, np.array([[opening]]))[0]
        solved = solve_ik(env.robot, target, q, IKSettings(rounds=20))
        if solved is None:
            return -np.inf
        q = solved
        margin = min(margin, float(np.minimum(q - low, high - q).min()))
    return margin
