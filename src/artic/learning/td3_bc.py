"""TD3 with demonstrations and the Q-filtered behaviour-cloning loss: the learner of the
CIP's contact policy pi_c (thesis section 7.3; issue 21, part 6). Nair et al. 2018,
"Overcoming Exploration in Reinforcement Learning with Demonstrations" (ICRA,
arXiv:1709.10089), on stable-baselines3's TD3 (Fujimoto et al. 2018):

- each gradient step samples `batch_size` replay and `demo_batch_size` demonstration
  transitions (uniformly, with replacement); the twin critics train on both, as in TD3;
- the actor minimises -Q1(s, pi(s)) over that joint batch plus `bc_weight` times
  `q_filtered_bc_loss` over its demonstration rows: mean_i 1[Q1(s_i, a_i) > Q1(s_i,
  pi(s_i))] ||pi(s_i) - a_i||^2, cloning only where the critic rates the demonstrated
  action above the policy's (the Q-filter);
- the demonstrations live in a buffer of their own (`Td3Bc.demo_buffer`). Nair et al.
  keep them in the replay buffer for good; a separate buffer sampled every step keeps
  them from being overwritten by SB3's ring buffer and fixes their share of each batch
  (theirs: 128 besides 1,024 replay transitions).

Without demonstrations (none loaded, or `demo_batch_size` 0) an update is SB3's TD3 bit
for bit; `bc_weight` 0 drops only the BC term. Demonstrations are given in the
environment's units and stored scaled to [-1, 1], as SB3 stores actions.

Training runs in epochs of `steps_per_epoch` steps (as `rmp_train`): epoch k reseeds the
environment from (seed, k) and resets it, cutting the episode in progress. The
`checkpoint` after an epoch holds the networks, optimisers, counters, both buffers and
the generators the next epoch draws from: torch's (target smoothing), numpy's global one
(exploration noise: SB3's `NormalActionNoise` draws from it; batch indices), the action
space's (warm-up actions) and Python's; resuming from it gives an uninterrupted run's
bytes. It is tensors and plain data (`artifacts.model_file.save_torch_file`). Imports
torch and SB3: a stage imports this module inside the function that trains.
"""

from __future__ import annotations

import copy
import random
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import torch
from gymnasium import spaces
from numpy.typing import NDArray
from stable_baselines3 import TD3
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.noise import NormalActionNoise
from stable_baselines3.common.type_aliases import ReplayBufferSamples
from stable_baselines3.common.utils import polyak_update
from torch.nn import functional as F

from artic.errors import InputError
from artic.learning.td3_settings import Demonstrations, Td3Config

Checkpoint = dict[str, Any]
BUFFER_ARRAYS = ("observations", "next_observations", "actions", "rewards", "dones", "timeouts")


class BcLoss(NamedTuple):
    """`q_filtered_bc_loss`'s result: loss () and mask (N,), 1.0 where the filter passes."""

    loss: torch.Tensor
    mask: torch.Tensor


def q_filtered_bc_loss(
    actions_pi: torch.Tensor, actions_demo: torch.Tensor, q_pi: torch.Tensor, q_demo: torch.Tensor
) -> BcLoss:
    """Nair et al.'s Q-filtered BC loss: mean_i m_i ||pi(s_i) - a_i||^2 with m_i =
    1[Q(s_i, a_i) > Q(s_i, pi(s_i))]. actions_pi, actions_demo: (N, A); q_pi, q_demo: (N,)
    or (N, 1). The gradient flows into actions_pi only (the mask is a constant)."""
    mask = (q_demo.detach() > q_pi.detach()).reshape(-1).to(actions_pi.dtype)
    squared = ((actions_pi - actions_demo) ** 2).sum(dim=1)
    return BcLoss((mask * squared).mean(), mask)


def _joined(replay: ReplayBufferSamples, demos: ReplayBufferSamples) -> ReplayBufferSamples:
    """One batch: the replay rows, then the demonstration rows."""
    return ReplayBufferSamples(
        torch.cat([replay.observations, demos.observations]),
        torch.cat([replay.actions, demos.actions]),
        torch.cat([replay.next_observations, demos.next_observations]),
        torch.cat([replay.dones, demos.dones]),
        torch.cat([replay.rewards, demos.rewards]),
    )


class Td3Bc(TD3):
    """SB3's TD3 with a demonstration buffer and the Q-filtered BC loss (module docstring)."""

    def __init__(self, *args: Any, bc_weight: float = 0.0, demo_batch_size: int = 0,
                 **kwargs: Any) -> None:  # fmt: skip
        self.bc_weight = bc_weight
        self.demo_batch_size = demo_batch_size
        self.demo_buffer: ReplayBuffer | None = None
        super().__init__(*args, **kwargs)

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "demo_buffer"]

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        """`gradient_steps` TD3 updates on joint replay + demonstration batches."""
        assert self.replay_buffer is not None
        self.policy.set_training_mode(True)
        self._update_learning_rate([self.actor.optimizer, self.critic.optimizer])
        demo_buffer = self.demo_buffer if self.demo_batch_size > 0 else None
        passed = []  # the fraction of demonstrations the Q-filter passes, per actor step
        for _ in range(gradient_steps):
            self._n_updates += 1
            replay = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)
            demos = None if demo_buffer is None else demo_buffer.sample(self.demo_batch_size)
            batch = replay if demos is None else _joined(replay, demos)
            self._critic_step(batch)
            if self._n_updates % self.policy_delay == 0:
                mask = self._actor_step(batch, demos)
                if mask is not None:
                    passed.append(float(mask.mean()))
                polyak_update(self.critic.parameters(), self.critic_target.parameters(), self.tau)
                polyak_update(self.actor.parameters(), self.actor_target.parameters(), self.tau)
                # (SB3 also copies batch-norm statistics here; an MlpPolicy has none)
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        if passed:
            self.logger.record("train/q_filter_pass", np.mean(passed))

    def _critic_step(self, batch: ReplayBufferSamples) -> None:
        """One Adam step of both critics towards the clipped double-Q target."""
        with torch.no_grad():
            noise = torch.empty_like(batch.actions).normal_(0, self.target_policy_noise)
            noise = noise.clamp(-self.target_noise_clip, self.target_noise_clip)
            next_actions = (self.actor_target(batch.next_observations) + noise).clamp(-1, 1)
            next_q = torch.cat(self.critic_target(batch.next_observations, next_actions), dim=1)
            next_q, _ = torch.min(next_q, dim=1, keepdim=True)
            target = batch.rewards + (1 - batch.dones) * self.gamma * next_q
        current = self.critic(batch.observations, batch.actions)
        loss = torch.stack([F.mse_loss(q, target) for q in current]).sum()
        self.critic.optimizer.zero_grad()
        loss.backward()
        self.critic.optimizer.step()

    def _actor_step(
        self, batch: ReplayBufferSamples, demos: ReplayBufferSamples | None
    ) -> torch.Tensor | None:
        """One Adam step of the actor: -mean Q1(s, pi(s)) over the batch, plus bc_weight
        times the Q-filtered BC loss over its last len(demos) rows; the filter's mask."""
        actions_pi = self.actor(batch.observations)
        q_pi = self.critic.q1_forward(batch.observations, actions_pi)
        loss = -q_pi.mean()
        mask = None
        if demos is not None and self.bc_weight > 0:
            n = demos.actions.shape[0]
            with torch.no_grad():
                q_demo = self.critic.q1_forward(demos.observations, demos.actions)
            bc = q_filtered_bc_loss(actions_pi[-n:], demos.actions, q_pi[-n:], q_demo)
            loss = loss + self.bc_weight * bc.loss
            mask = bc.mask
        self.actor.optimizer.zero_grad()
        loss.backward()
        self.actor.optimizer.step()
        return mask


def td3_model(cfg: Td3Config, env: Any, seed: int) -> Td3Bc:
    """`Td3Bc` on `env` (one environment, Box actions) set from `cfg`, seeded with `seed`:
    the same seed gives the same initial weights, byte for byte. No demonstrations yet."""
    dim = int(np.prod(env.action_space.shape))
    noise = NormalActionNoise(np.zeros(dim), np.full(dim, cfg.action_noise))
    model = Td3Bc("MlpPolicy", env, learning_rate=cfg.lr, buffer_size=cfg.buffer_size,
                  learning_starts=cfg.learning_starts, batch_size=cfg.batch_size, tau=cfg.tau,
                  gamma=cfg.gamma, train_freq=1, gradient_steps=1, action_noise=noise,
                  policy_delay=cfg.policy_delay, target_policy_noise=cfg.target_policy_noise,
                  target_noise_clip=cfg.target_noise_clip,
                  policy_kwargs={"net_arch": list(cfg.hidden)}, seed=seed, device="cpu",
                  verbose=0, bc_weight=cfg.bc_weight,
                  demo_batch_size=cfg.demo_batch_size)  # fmt: skip
    model.set_logger(Logger(None, []))  # no SB3-<time> folders in the temporary folder
    return model


def _array(name: str, value: Any, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """`value` as a finite float array of `shape`; else InputError naming the field."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"demonstrations.{name}: not an array of numbers") from None
    if name == "actions" and array.ndim == 2 and array.shape[1] != shape[1]:
        raise InputError(f"demonstrations.actions: action dimension {array.shape[1]} differs "
                         f"from the environment's {shape[1]}")  # fmt: skip
    if array.shape != shape:
        raise InputError(f"demonstrations.{name}: shape {array.shape}, expected {shape}")
    if not np.isfinite(array).all():
        raise InputError(f"demonstrations.{name}: NaN or infinite values")
    return array


def load_demonstrations(model: Td3Bc, demos: Demonstrations) -> None:
    """Check `demos` against the model's spaces and make them its demonstration buffer (N
    transitions, replacing any earlier ones); a bad field is an InputError naming it."""
    obs_shape, space = tuple(model.observation_space.shape or ()), model.action_space
    assert isinstance(space, spaces.Box)
    n = int(np.shape(demos.obs)[0]) if np.ndim(demos.obs) else 0
    if n == 0:
        raise InputError("demonstrations.obs: no transitions")
    obs = _array("obs", demos.obs, (n, *obs_shape))
    actions = _array("actions", demos.actions, (n, int(np.prod(space.shape))))
    rewards = _array("rewards", demos.rewards, (n,))
    next_obs = _array("next_obs", demos.next_obs, (n, *obs_shape))
    dones = _array("dones", demos.dones, (n,))
    low, high = space.low.reshape(-1), space.high.reshape(-1)
    if np.any(actions < low) or np.any(actions > high):
        raise InputError(f"demonstrations.actions: outside the action space's bounds "
                         f"{low.tolist()} to {high.tolist()}")  # fmt: skip
    if not np.isin(dones, (0.0, 1.0)).all():
        raise InputError("demonstrations.dones: values other than 0 and 1")
    buffer = _demo_buffer(model, n)
    buffer.observations[:, 0] = obs
    buffer.next_observations[:, 0] = next_obs
    buffer.actions[:, 0] = model.policy.scale_action(actions)
    buffer.rewards[:, 0], buffer.dones[:, 0] = rewards, dones
    buffer.full = True
    model.demo_buffer = buffer


def _demo_buffer(model: Td3Bc, size: int) -> ReplayBuffer:
    """An empty demonstration buffer of `size` transitions (no time-limit bookkeeping)."""
    return ReplayBuffer(size, model.observation_space, model.action_space, device=model.device,
                        handle_timeout_termination=False)  # fmt: skip


def _buffer_state(buffer: ReplayBuffer) -> dict[str, Any]:
    """The filled rows of `buffer` as tensors, with its size, position and fullness."""
    rows = buffer.buffer_size if buffer.full else buffer.pos
    state: dict[str, Any] = {"buffer_size": buffer.buffer_size, "pos": buffer.pos,
                             "full": buffer.full}  # fmt: skip
    for name in BUFFER_ARRAYS:
        state[name] = torch.from_numpy(getattr(buffer, name)[:rows].copy())
    return state


def _restore_buffer(buffer: ReplayBuffer, state: dict[str, Any]) -> None:
    if buffer.buffer_size != state["buffer_size"]:
        raise InputError(f"checkpoint: a buffer of {state['buffer_size']} transitions, the "
                         f"config's holds {buffer.buffer_size}")  # fmt: skip
    for name in BUFFER_ARRAYS:
        rows = state[name]
        getattr(buffer, name)[: len(rows)] = rows.numpy()
    buffer.pos, buffer.full = int(state["pos"]), bool(state["full"])


def checkpoint(model: Td3Bc, epochs: int) -> Checkpoint:
    """Everything the next epoch depends on, after `epochs` epochs (module docstring): a
    copy (training on does not change it), tensors and plain data."""
    assert model.replay_buffer is not None
    numpy_state = np.random.get_state(legacy=False)
    numpy_state["state"]["key"] = numpy_state["state"]["key"].tolist()
    version, internal, gauss = random.getstate()
    state = {
        "epochs": epochs,
        "policy": model.policy.state_dict(),
        "actor_optimizer": model.actor.optimizer.state_dict(),
        "critic_optimizer": model.critic.optimizer.state_dict(),
        "num_timesteps": int(model.num_timesteps),
        "n_updates": int(model._n_updates),
        "episode_num": int(model._episode_num),
        "replay": _buffer_state(model.replay_buffer),
        "demos": None if model.demo_buffer is None else _buffer_state(model.demo_buffer),
        "rng": {"torch": torch.get_rng_state(), "python": [version, list(internal), gauss],
                "numpy": numpy_state,
                "action_space": model.action_space.np_random.bit_generator.state},
    }  # fmt: skip
    return copy.deepcopy(state)


def restore(model: Td3Bc, state: Checkpoint) -> None:
    """Put a `checkpoint` into `model` (made by `td3_model` from the same config)."""
    assert model.replay_buffer is not None
    model.policy.load_state_dict(state["policy"])
    model.actor.optimizer.load_state_dict(state["actor_optimizer"])
    model.critic.optimizer.load_state_dict(state["critic_optimizer"])
    model.num_timesteps = int(state["num_timesteps"])
    model._n_updates = int(state["n_updates"])
    model._episode_num = int(state["episode_num"])
    _restore_buffer(model.replay_buffer, state["replay"])
    model.demo_buffer = None
    if state["demos"] is not None:
        model.demo_buffer = _demo_buffer(model, int(state["demos"]["buffer_size"]))
        _restore_buffer(model.demo_buffer, state["demos"])
    rng = state["rng"]
    torch.set_rng_state(rng["torch"])
    version, internal, gauss = rng["python"]
    random.setstate((int(version), tuple(internal), gauss))
    numpy_state = copy.deepcopy(rng["numpy"])
    numpy_state["state"]["key"] = np.asarray(numpy_state["state"]["key"], dtype=np.uint32)
    np.random.set_state(numpy_state)
    model.action_space.np_random.bit_generator.state = rng["action_space"]


def env_seed(seed: int, epoch: int) -> int:
    """The environment's seed in epoch `epoch` of run `seed`."""
    return int(np.random.SeedSequence([seed, epoch, 7]).generate_state(1)[0] % (2**31 - 1))


def train_epochs(
    model: Td3Bc,
    cfg: Td3Config,
    seed: int,
    epochs: int,
    state: Checkpoint | None = None,
    save: Callable[[Checkpoint], None] | None = None,
) -> Td3Bc:
    """Train `model` (`td3_model(cfg, env, seed)`, demonstrations loaded) for `epochs`
    epochs of `cfg.steps_per_epoch` steps. `state`: a `checkpoint` to resume from (None:
    from the start); `save` gets one after every epoch. Returns `model`."""
    assert model.env is not None
    torch.set_num_threads(cfg.threads)
    done = 0
    if state is not None:
        restore(model, state)
        done = int(state["epochs"])
    for epoch in range(done, epochs):
        model.env.seed(env_seed(seed, epoch))
        model._last_obs = None  # learn() then resets the environment (seeded above)
        model.learn(cfg.steps_per_epoch, reset_num_timesteps=False)
        if save is not None:
            save(checkpoint(model, epoch + 1))
    return model
