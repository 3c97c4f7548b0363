"""The settings of TD3 with demonstrations (`learning/td3_bc.py`) and the records it
reads, without importing torch or stable-baselines3 (configs load fast)."""

from __future__ import annotations

from typing import Any, NamedTuple

from numpy.typing import NDArray
from pydantic import Field

from artic.config.schemas import Strict


class Td3Config(Strict):
    """TD3 + demonstrations + Q-filtered BC (section 7.3); unmarked values: SB3's defaults."""

    hidden: list[int] = Field(default_factory=lambda: [64, 64], description="MLP widths (ReLU)")
    lr: float = Field(1e-4, gt=0, description="Adam step size (actor and critics)")
    action_noise: float = Field(0.05, ge=0, description="exploration noise std, in [-1, 1]")
    gamma: float = Field(0.99, gt=0, le=1, description="discount")
    batch_size: int = Field(256, ge=1, description="replay transitions per gradient step")
    buffer_size: int = Field(1_000_000, ge=1, description="replay buffer capacity (transitions)")
    learning_starts: int = Field(100, ge=0, description="uniform random steps before updates")
    tau: float = Field(0.005, gt=0, le=1, description="Polyak step of the target networks")
    policy_delay: int = Field(2, ge=1, description="critic updates per actor/target update")
    target_policy_noise: float = Field(0.2, ge=0, description="std of target policy smoothing")
    target_noise_clip: float = Field(0.5, ge=0, description="clip of target policy smoothing")
    bc_weight: float = Field(1.0, ge=0, description="lambda of the Q-filtered BC loss (0: none)")
    demo_batch_size: int = Field(32, ge=0, description="demo transitions added to each batch")
    steps_per_epoch: int = Field(1000, ge=1, description="environment steps per checkpoint")
    threads: int = Field(1, ge=1, description="torch threads per run (part of the result)")


class Demonstrations(NamedTuple):
    """N demonstrated transitions, in the environment's units: obs and next_obs (N, *obs
    shape), actions (N, A) within the action space, rewards (N,), dones (N,) 1 where the
    episode terminated (0 at a time limit: the target bootstraps there)."""

    obs: NDArray[Any]
    actions: NDArray[Any]
    rewards: NDArray[Any]
    next_obs: NDArray[Any]
    dones: NDArray[Any]
