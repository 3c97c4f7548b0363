"""Rollouts of a policy in a Gymnasium environment (Algorithm 1, line 8).

A policy is given to `rollout` as an `ActionFn`: `(obs (obs_dim,), step) -> action
(act_dim,)`, so the same loop runs a Gaussian MLP, a DMP with feedback, or a robot that
keeps still. Randomness is explicit: the environment's reset is seeded per rollout
(`env.reset(seed=...)`), and a stochastic policy samples from a `torch.Generator` the
caller seeds; nothing touches a global RNG. Seeds of rollout i of update k of run `seed`
come from `rollout_seeds(seed, k, n)` (numpy `SeedSequence`), so a resumed run redraws
exactly the rollouts of an uninterrupted one.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    import gymnasium as gym
    import torch

    from artic.control.tracking import JointTracker
    from artic.policies.dmp import DMPConfig, DMPParams
    from artic.policies.gaussian_mlp import GaussianMLPPolicy

#: (observation (obs_dim,), step index) -> action (act_dim,)
ActionFn = Callable[[NDArray[np.float64], int], NDArray[np.float64]]


@dataclass(frozen=True)
class Trajectory:
    """One episode.

    observations: (T, obs_dim) float64, the state s_t before action t;
    actions: (T, act_dim) float64, the actions the policy chose (before the environment
    clips them to its action space; these are what the policy's likelihood is of);
    rewards: (T,) float64 (Eq. 5.1 in the task environments); success: the environment's
    `info["success"]` at the last step; reset_seed: the seed of `env.reset`; touched: its
    `info["touched"]` at the last step (the robot touched the object; False if the
    environment does not say).
    """

    observations: NDArray[np.float64]
    actions: NDArray[np.float64]
    rewards: NDArray[np.float64]
    success: bool
    reset_seed: int
    touched: bool = False

    @property
    def total_return(self) -> float:
        """Undiscounted return sum_t r_t."""
        return float(self.rewards.sum())

    def __len__(self) -> int:
        return len(self.rewards)


def rollout_seeds(seed: int, update: int, n: int, stream: int = 0) -> list[int]:
    """n reset seeds for update `update` of run `seed`; `stream` separates independent
    uses (0: exploration rollouts, 1: evaluation rollouts, ...)."""
    state = np.random.SeedSequence([seed, update, stream]).generate_state(n)
    return [int(s) for s in state]


def torch_generator(seed: int, update: int, stream: int = 0) -> torch.Generator:
    """A `torch.Generator` seeded from (seed, update, stream)."""
    import torch

    gen = torch.Generator()
    gen.manual_seed(rollout_seeds(seed, update, 1, 100 + stream)[0])
    return gen


def rollout(env: gym.Env[Any, Any], act: ActionFn, reset_seed: int) -> Trajectory:
    """Run one episode of `act` from `env.reset(seed=reset_seed)` until terminated or
    truncated. Actions are clipped to a Box action space before `env.step`."""
    obs, info = env.reset(seed=reset_seed)
    low = getattr(env.action_space, "low", None)
    high = getattr(env.action_space, "high", None)
    observations, actions, rewards = [], [], []
    step, done = 0, False
    while not done:
        o = np.asarray(obs, dtype=np.float64)
        a = np.asarray(act(o, step), dtype=np.float64)
        applied = np.clip(a, low, high) if low is not None else a
        obs, reward, terminated, truncated, info = env.step(applied.astype(np.float32))
        observations.append(o)
        actions.append(a)
        rewards.append(float(reward))
        done = bool(terminated or truncated)
        step += 1
    return Trajectory(
        np.stack(observations),
        np.stack(actions),
        np.asarray(rewards),
        bool(info.get("success", False)),
        reset_seed,
        bool(info.get("touched", False)),
    )


def rollouts(env: gym.Env[Any, Any], act: ActionFn, reset_seeds: Sequence[int]) -> list[Trajectory]:
    """One `rollout` per reset seed."""
    return [rollout(env, act, s) for s in reset_seeds]


def idle_action(act_dim: int) -> ActionFn:
    """The robot that keeps still: zero joint velocities (the R_idle reference)."""
    zero = np.zeros(act_dim)
    return lambda obs, step: zero


def gaussian_actor(policy: GaussianMLPPolicy, generator: torch.Generator | None = None) -> ActionFn:
    """`ActionFn` of a Gaussian MLP policy: a sample drawn from `generator`, or the mean
    action when `generator` is None (evaluation)."""
    import torch

    def act(obs: NDArray[np.float64], step: int) -> NDArray[np.float64]:
        x = torch.as_tensor(obs, dtype=torch.float32)[None]
        if generator is None:
            with torch.no_grad():
                return policy.mean(x)[0].double().numpy()
        return policy.sample(x, generator)[0].double().numpy()

    return act


def returns_of(trajectories: Sequence[Trajectory]) -> NDArray[np.float64]:
    """(n,) undiscounted returns."""
    return np.array([t.total_return for t in trajectories], dtype=np.float64)


def touch_rate(trajectories: Sequence[Trajectory]) -> float:
    """Share of `trajectories` in which the robot touched the object."""
    return float(np.mean([t.touched for t in trajectories]))


def normalised_return(returns: NDArray[np.float64], idle: NDArray[np.float64]) -> float:
    """1 - mean(R) / mean(R_idle): 0 = no better than keeping still, 1 = zero cost
    (returns are non-positive under Eq. 5.1). R_idle must be negative."""
    ref = float(np.mean(idle))
    if ref >= 0:
        raise ValueError(f"idle return must be negative (got {ref}); the goal is already met")
    return 1.0 - float(np.mean(returns)) / ref


def dmp_actor(params: DMPParams, cfg: DMPConfig, dt: float, steps: int, k_p: float) -> JointTracker:
    """The `ActionFn` of a DMP policy: the DMP is integrated open-loop in time over
    `steps` control periods of `dt` s (Eq. 2.4-2.6), and the action at step k tracks it
    with feedback on the measured joints, a_k = yd_k + k_p (y_k - q_R)
    (`artic.control.tracking.JointTracker`)."""
    from artic.control.tracking import JointTracker
    from artic.policies.dmp import rollout_dmp

    traj = rollout_dmp(params, cfg, dt, steps)
    return JointTracker(traj.y, traj.yd, k_p)


def dmp_rollouts(
    env: gym.Env[Any, Any],
    params: DMPParams,
    cfg: DMPConfig,
    reset_seeds: Sequence[int],
    dt: float,
    steps: int,
    k_p: float,
) -> list[Trajectory]:
    """One rollout of the DMP policy `params` per reset seed (see `dmp_actor`)."""
    return rollouts(env, dmp_actor(params, cfg, dt, steps, k_p), reset_seeds)
