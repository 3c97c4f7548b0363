"""Gymnasium environments of the Chapter 5 tasks (section 5.3.1).

`ArticTaskEnv(task, seed, render_mode, normalised_actions, camera)` wraps a `TaskWorld`:
- observation s_t = [q_R, q_O] (float32, 7 + dof), clipped to `observation_space`
  (robot joint limits widened by `JOINT_MARGIN`, since PyBullet's limits are soft;
  object within `OBJECT_BOUND` of its range);
- action a_t = commanded joint velocities (7,), rad/s; the simulator receives them
  clipped to the velocity limits (`action_space`). With `normalised_actions=True` the
  action space is [-1, 1]^7 instead (what `check_env` and most RL libraries expect),
  and a_t = (given action) * (velocity limits) is what the simulator receives and the
  reward sees, so returns are the same in both modes for the same joint velocities;
- reward Eq. 5.1, r_t = -c ||q_O* - q_O||^2 - a_t^T R a_t with R = r I, evaluated on
  the object state after the step and a_t as given (before clipping), in rad/s;
- `terminated` is always False; `truncated` once `horizon` steps are taken;
- `info`: `success` (||q_O - q_O*|| <= success_threshold), `q_object`, and `touched`:
  whether the robot has touched the object since the reset (the grasp has held it, or
  the object has moved more than `TOUCH_DISTANCE` from where it started: its joint
  values, m or rad, or the t-ball's ball centre, m), which `artic policy-search` counts
  to report how often a policy reaches the object;
- `render_mode="rgb_array"`: `render()` returns a (height, width, 3) uint8 frame of
  `artic.sim.camera.SceneCamera` (PyBullet's TinyRenderer, deterministic), whose client
  is made at the first `render()`; `render_mode=None` never renders (`render()` returns
  None). Rendering never changes the simulation.
`reset(seed=...)` draws the start configuration q_R(0) = start_q + N(0, start_noise^2)
(clipped to the joint limits) from the environment's generator; the same seed gives the
same trajectory, bit for bit.

Importing this module registers every task of `artic.sim.tasks.TASKS` with Gymnasium
(`register_envs`): `artic/Drawer-v0`, `artic/Microwave-v0`, `artic/TBall-v0`, each with
`max_episode_steps` = its horizon, so `gym.make("artic/Drawer-v0")` works after
`import artic.sim.envs`, and `gym.make("artic.sim.envs:artic/Drawer-v0")` imports it
itself. `import artic` alone registers nothing (and loads no simulator).
"""

from __future__ import annotations

import time
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from artic.sim.camera import CameraConfig, SceneCamera
from artic.sim.tasks import TASKS, TaskConfig, TBallScene, get_task
from artic.sim.world import TaskWorld

JOINT_MARGIN = 0.1  # rad beyond the URDF limits still inside the observation space
OBJECT_BOUND = 10.0  # m or rad beyond the object range still inside the observation space
TOUCH_DISTANCE = 0.005  # m or rad the object moves before an episode counts as touching it

#: Gymnasium names of tasks whose name is not simply capitalised (`env_id`)
ENV_NAMES = {"tball": "TBall"}


def env_id(task: str) -> str:
    """The Gymnasium id of task `task`: `artic/<Name>-v0` (`ENV_NAMES`, else the task
    name with its first letter capitalised)."""
    return f"artic/{ENV_NAMES.get(task, task[:1].upper() + task[1:])}-v0"


def kinematic_reward(
    q_object: NDArray[np.float64],
    goal: NDArray[np.float64],
    action: NDArray[np.float64],
    c: float,
    r: float,
) -> float:
    """Eq. 5.1: -c ||q_O* - q_O||^2 - a^T (r I) a. q_object, goal: (dof,); action: (7,)."""
    error = np.asarray(goal, dtype=np.float64) - np.asarray(q_object, dtype=np.float64)
    a = np.asarray(action, dtype=np.float64)
    return float(-c * error @ error - r * a @ a)


def _object_range(cfg: TaskConfig) -> tuple[float, float]:
    scene = cfg.scene
    if isinstance(scene, TBallScene):
        return scene.travel
    return scene.joint_limits


class ArticTaskEnv(gym.Env[NDArray[np.float32], NDArray[np.float32]]):
    """One Chapter 5 task as a Gymnasium environment (see the module docstring)."""

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 20}  # noqa: RUF012

    def __init__(
        self,
        task: str | TaskConfig = "drawer",
        seed: int | None = None,
        render_mode: str | None = None,
        normalised_actions: bool = False,
        camera: CameraConfig | None = None,
    ) -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.task = get_task(task) if isinstance(task, str) else task
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.task.control_dt)}
        self.camera_cfg = camera or CameraConfig()
        self._camera: SceneCamera | None = None
        self.world = TaskWorld.create(self.task, np.random.default_rng(seed))
        low, high = self.world.robot_limits()
        lo, hi = _object_range(self.task)
        dof = self.world.dof_object
        self._observation_box = gym.spaces.Box(
            low=np.concatenate([low - JOINT_MARGIN, np.full(dof, lo - OBJECT_BOUND)]).astype(
                np.float32
            ),
            high=np.concatenate([high + JOINT_MARGIN, np.full(dof, hi + OBJECT_BOUND)]).astype(
                np.float32
            ),
            dtype=np.float32,
        )
        limit = self.world.velocity_limits().astype(np.float32)
        self.observation_space = self._observation_box
        self.action_box = gym.spaces.Box(low=-limit, high=limit, dtype=np.float32)
        """The joint speed limits, rad/s: the action space unless `normalised_actions`."""
        self.normalised_actions = normalised_actions
        self._action_scale = self.world.velocity_limits() if normalised_actions else None
        self.action_space = (
            gym.spaces.Box(low=-1.0, high=1.0, shape=(7,), dtype=np.float32)
            if normalised_actions
            else self.action_box
        )
        self._rng = np.random.default_rng(seed)
        self._steps = 0
        self._touched = False
        self._object_start = self._object_state()

    def _observation(self) -> NDArray[np.float32]:
        state = np.concatenate([self.world.robot_q(), self.world.object_q()]).astype(np.float32)
        box = self._observation_box
        return np.clip(state, box.low, box.high)

    def start_configuration(self) -> NDArray[np.float64]:
        """Draw q_R(0) (7,): start_q plus Gaussian noise, within the joint limits."""
        robot = self.task.robot
        low, high = self.world.robot_limits()
        noise = self._rng.normal(0.0, robot.start_noise, size=7) if robot.start_noise > 0 else 0.0
        return np.clip(np.asarray(robot.start_q) + noise, low, high)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Start an episode; `seed` re-seeds the start-noise generator."""
        super().reset(seed=seed)
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.world.reset(self.start_configuration(), np.asarray(self.task.object_start))
        self._steps = 0
        self._touched = False
        self._object_start = self._object_state()
        return self._observation(), self._info()

    def _object_state(self) -> NDArray[np.float64]:
        """What moves when the robot touches the object: the ball's centre (3,), m, or
        the object's joint values (dof,)."""
        ball = self.world.ball_position()
        return ball if ball is not None else self.world.object_q()

    def _info(self) -> dict[str, Any]:
        q_object = self.world.object_q()
        error = float(np.linalg.norm(q_object - self.world.goal))
        return {
            "success": error <= self.task.success_threshold,
            "q_object": q_object,
            "touched": self._touched,
        }

    def step(
        self, action: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], SupportsFloat, bool, bool, dict[str, Any]]:
        """Apply a_t for one control period; returns (s_t+1, r_t, False, truncated, info)."""
        a: NDArray[np.float64] = np.asarray(action, dtype=np.float64).reshape(-1)
        if self._action_scale is not None:
            a = a * self._action_scale  # [-1, 1] -> rad/s
        self.world.apply_action(a)
        self.world.step()
        self._steps += 1
        moved = float(np.max(np.abs(self._object_state() - self._object_start)))
        self._touched = self._touched or self.world.grasp_held or moved > TOUCH_DISTANCE
        info = self._info()
        reward = kinematic_reward(
            info["q_object"], self.world.goal, a, self.task.reward.c, self.task.reward.r
        )
        truncated = self._steps >= self.world.horizon
        return self._observation(), reward, False, truncated, info

    def render(self) -> NDArray[np.uint8] | None:
        """The current frame (height, width, 3) uint8 in `rgb_array` mode; None otherwise."""
        if self.render_mode != "rgb_array":
            return None
        if self._camera is None:
            self._camera = SceneCamera(self.world, self.camera_cfg)
        return self._camera.render()

    def close(self) -> None:
        if self._camera is not None:
            self._camera.close()
            self._camera = None
        self.world.close()
        super().close()


def register_envs() -> list[str]:
    """Register every task of `artic.sim.tasks.TASKS` with Gymnasium as `env_id(task)`,
    with `max_episode_steps` = the task's horizon; returns the ids. Idempotent: an id
    already registered is left as it is (no warning). `gym.make(id, seed=...,
    render_mode=..., normalised_actions=...)` then builds the env (a `task=` config of
    another horizon needs `max_episode_steps=` too)."""
    ids = []
    for task in TASKS:
        name = env_id(task)
        if name not in gym.registry:
            gym.register(
                id=name,
                entry_point="artic.sim.envs:ArticTaskEnv",
                kwargs={"task": task},
                max_episode_steps=get_task(task).horizon,
            )
        ids.append(name)
    return ids


def measure_steps_per_second(task: str | TaskConfig, n: int = 500, seed: int = 0) -> float:
    """Control steps per second (wall clock) of random actions on `task`, resets
    included whenever an episode ends. A benchmark helper, not used by tests."""
    env = ArticTaskEnv(task, seed=seed)
    try:
        rng = np.random.default_rng(seed)
        env.reset(seed=seed)
        scale = env.action_box.high
        start = time.perf_counter()
        for _ in range(n):
            action = (rng.uniform(-1.0, 1.0, size=7) * scale).astype(np.float32)
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        return n / (time.perf_counter() - start)
    finally:
        env.close()


ENV_IDS = register_envs()
"""The Gymnasium ids registered at import, in task order."""
