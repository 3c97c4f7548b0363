"""TD3 with demonstrations and the Q-filtered BC loss (section 7.3; Nair et al. 2018)."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3 import TD3
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.noise import NormalActionNoise

from artic.artifacts.model_file import load_torch_file, save_torch_file
from artic.errors import InputError
from artic.learning.td3_bc import (
    Demonstrations,
    Td3Config,
    load_demonstrations,
    q_filtered_bc_loss,
    td3_model,
    train_epochs,
)

TINY = Td3Config(batch_size=32, learning_starts=50, steps_per_epoch=120, demo_batch_size=8)


@pytest.fixture(autouse=True)
def one_thread():
    """One torch thread, as `train_epochs` sets it (Td3Config.threads), then as before."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def parameter_bytes(model) -> bytes:
    return b"".join(t.numpy().tobytes() for t in model.policy.state_dict().values())


def pendulum_demos(n: int = 40, seed: int = 0) -> Demonstrations:
    """n transitions of Pendulum-v1 under a constant torque of 1 N m."""
    env = gym.make("Pendulum-v1")
    obs, _ = env.reset(seed=seed)
    rows = []
    for _ in range(n):
        next_obs, reward, terminated, _, _ = env.step(np.array([1.0], dtype=np.float32))
        rows.append((obs, [1.0], reward, next_obs, float(terminated)))
        obs = next_obs
    return Demonstrations(*(np.array(column) for column in zip(*rows, strict=True)))


class TargetAction(gym.Env):
    """A 1-D toy problem of one-step episodes, x ~ U(-1, 1): the reward is -(a - 0.5)^2
    (dense) or 1 within 0.1 of a = 0.5 and 0 elsewhere (sparse)."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, sparse: bool) -> None:
        self.sparse = sparse

    def reward(self, action: float) -> float:
        return float(abs(action - 0.5) < 0.1) if self.sparse else -((action - 0.5) ** 2)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self._x = self.np_random.uniform(-1, 1, size=1).astype(np.float32)
        return self._x, {}

    def step(self, action):
        return self._x, self.reward(float(action[0])), True, False, {}


# --- the loss in closed form -----------------------------------------------------------


def test_the_q_filter_clones_only_where_the_demonstration_is_rated_higher():
    actions_pi = torch.tensor([[0.0, 0.0], [1.0, 1.0], [0.5, -0.5]], requires_grad=True)
    actions_demo = torch.tensor([[1.0, 0.0], [0.0, 0.0], [0.5, 0.5]])
    q_pi = torch.tensor([[1.0], [2.0], [0.0]], requires_grad=True)
    q_demo = torch.tensor([[2.0], [1.0], [0.0]])  # better, worse, a tie (strict: no)
    loss, mask = q_filtered_bc_loss(actions_pi, actions_demo, q_pi, q_demo)
    assert mask.tolist() == [1.0, 0.0, 0.0]
    assert loss.item() == pytest.approx(1.0 / 3)  # (1^2 + 0^2) / 3 rows
    loss.backward()
    # d/d pi of mean_i m_i ||pi_i - a_i||^2 = 2 m_i (pi_i - a_i) / N; nothing into Q
    expected = 2 * mask[:, None] * (actions_pi - actions_demo).detach() / 3
    assert torch.equal(actions_pi.grad, expected)
    assert q_pi.grad is None


def test_an_all_false_mask_gives_zero_loss_and_zero_gradient():
    actions_pi = torch.tensor([[0.3], [-0.7]], requires_grad=True)
    loss, mask = q_filtered_bc_loss(
        actions_pi, torch.tensor([[1.0], [1.0]]), torch.tensor([5.0, 1.0]), torch.tensor([4.0, 1.0])
    )
    assert mask.tolist() == [0.0, 0.0]
    assert loss.item() == 0.0
    loss.backward()
    assert torch.count_nonzero(actions_pi.grad) == 0


# --- the learner -----------------------------------------------------------------------


def test_the_config_holds_the_thesis_settings_and_the_model_uses_them():
    cfg = Td3Config()
    assert (cfg.hidden, cfg.lr, cfg.action_noise, cfg.gamma) == ([64, 64], 1e-4, 0.05, 0.99)
    assert (cfg.policy_delay, cfg.target_policy_noise, cfg.target_noise_clip) == (2, 0.2, 0.5)
    assert cfg.threads == 1
    model = td3_model(cfg, gym.make("Pendulum-v1"), seed=0)
    widths = [m.out_features for m in model.actor.mu if isinstance(m, torch.nn.Linear)]
    assert widths == [64, 64, 1]
    assert model.actor.optimizer.param_groups[0]["lr"] == 1e-4
    assert model.critic.optimizer.param_groups[0]["lr"] == 1e-4
    assert np.all(model.action_noise._sigma == 0.05)
    with pytest.raises(ValueError, match="bc_weigth"):
        Td3Config(bc_weigth=1.0)


def plain_td3(cfg: Td3Config, seed: int) -> TD3:
    """SB3's TD3 with the settings `Td3Config` documents, written out independently."""
    model = TD3("MlpPolicy", gym.make("Pendulum-v1"), learning_rate=cfg.lr,
                buffer_size=cfg.buffer_size, learning_starts=cfg.learning_starts,
                batch_size=cfg.batch_size, tau=cfg.tau, gamma=cfg.gamma,
                action_noise=NormalActionNoise(np.zeros(1), np.full(1, cfg.action_noise)),
                policy_kwargs={"net_arch": [64, 64]}, seed=seed, device="cpu")  # fmt: skip
    model.set_logger(Logger(None, []))
    return model


@pytest.mark.parametrize(
    ("bc_weight", "demo_batch_size", "with_demos"),
    [(0.0, 8, False), (1.0, 8, False), (0.0, 0, True), (1.0, 0, True)],
)
def test_without_demonstrations_it_is_sb3_td3_bit_for_bit(bc_weight, demo_batch_size, with_demos):
    cfg = TINY.model_copy(update={"bc_weight": bc_weight, "demo_batch_size": demo_batch_size})
    # one after the other: both draw from the global generators their seed sets
    ours = td3_model(cfg, gym.make("Pendulum-v1"), seed=3)
    if with_demos:
        load_demonstrations(ours, pendulum_demos())
    start = parameter_bytes(ours)
    ours.learn(200)
    theirs = plain_td3(cfg, seed=3)
    assert parameter_bytes(theirs) == start
    theirs.learn(200)
    assert ours._n_updates == theirs._n_updates == 150
    assert parameter_bytes(ours) != start  # it trained
    assert parameter_bytes(ours) == parameter_bytes(theirs)


def test_with_demonstrations_the_update_differs_from_td3():
    ours = td3_model(TINY, gym.make("Pendulum-v1"), seed=3)
    load_demonstrations(ours, pendulum_demos())
    ours.learn(200)
    theirs = plain_td3(TINY, seed=3)
    theirs.learn(200)
    assert parameter_bytes(ours) != parameter_bytes(theirs)


def actor_on(model, states: np.ndarray) -> np.ndarray:
    with torch.no_grad():
        return model.actor(torch.as_tensor(states, dtype=torch.float32)).numpy()[:, 0]


class ToyRun(NamedTuple):
    """The actor's actions (64,) on the demonstrated states, Q1 of them and of the
    demonstrated action there (64,)."""

    actions: np.ndarray
    q_pi: np.ndarray
    q_demo: np.ndarray


def toy_run(sparse: bool, bc_weight: float, demo_action: float, steps: int,
            demo_reward: float | None = None) -> ToyRun:  # fmt: skip
    """TD3 on `TargetAction` with 64 demonstrations of the constant `demo_action`
    (rewarded as the environment would, or with `demo_reward`)."""
    cfg = Td3Config(lr=1e-3, batch_size=32, learning_starts=32, demo_batch_size=32,
                    bc_weight=bc_weight, policy_delay=1)  # fmt: skip
    env = TargetAction(sparse)
    model = td3_model(cfg, env, seed=0)
    states = np.linspace(-1, 1, 64, dtype=np.float32)[:, None]
    rewards = np.full(64, env.reward(demo_action) if demo_reward is None else demo_reward)
    actions = np.full((64, 1), demo_action)
    load_demonstrations(model, Demonstrations(states, actions, rewards, states, np.ones(64)))
    model.learn(steps)
    with torch.no_grad():
        obs, demo = torch.as_tensor(states), torch.as_tensor(actions, dtype=torch.float32)
        pi = model.actor(obs)
        q_pi, q_demo = model.critic.q1_forward(obs, pi), model.critic.q1_forward(obs, demo)
    return ToyRun(pi.numpy()[:, 0], q_pi.numpy()[:, 0], q_demo.numpy()[:, 0])


def test_the_critic_learns_from_the_demonstrations():
    # the environment's rewards are <= 0; only the demonstrations carry a reward of 10
    run = toy_run(sparse=False, bc_weight=0.0, demo_action=-0.6, steps=150, demo_reward=10.0)
    assert run.q_demo.mean() > 2.0


def test_on_a_sparse_reward_the_filtered_bc_pulls_the_actor_to_the_demonstrations():
    # demonstrations of the rewarded action 0.5: the critic rates them above the policy's
    # action (the filter passes), and the BC term moves the actor there faster than the
    # Q term alone does (the demonstrations fill the critic's batches in both runs)
    with_bc = toy_run(sparse=True, bc_weight=1.0, demo_action=0.5, steps=150)
    without_bc = toy_run(sparse=True, bc_weight=0.0, demo_action=0.5, steps=150)
    assert np.mean(with_bc.q_demo > with_bc.q_pi) > 0.5
    assert np.abs(with_bc.actions - 0.5).mean() < 0.2
    assert np.abs(with_bc.actions - 0.5).mean() < 0.5 * np.abs(without_bc.actions - 0.5).mean()


def test_the_filter_keeps_the_actor_from_cloning_bad_demonstrations():
    # dense reward -(a - 0.5)^2, demonstrations of -0.6: Q(s, a_demo) < Q(s, pi(s))
    run = toy_run(sparse=False, bc_weight=1.0, demo_action=-0.6, steps=300)
    assert np.all(run.q_demo <= run.q_pi)
    assert np.all(np.abs(run.actions - 0.5) < np.abs(run.actions + 0.6))


def trained(seed: int, epochs: int, cfg: Td3Config = TINY, state=None, saved=None):
    model = td3_model(cfg, gym.make("Pendulum-v1"), seed)
    if state is None:
        load_demonstrations(model, pendulum_demos())
    return train_epochs(model, cfg, seed, epochs, state, None if saved is None else saved.append)


def test_the_same_seed_gives_the_same_bytes():
    assert parameter_bytes(trained(5, 2)) == parameter_bytes(trained(5, 2))
    assert parameter_bytes(trained(5, 2)) != parameter_bytes(trained(6, 2))


def test_an_interrupted_and_resumed_run_equals_an_uninterrupted_one(tmp_path: Path):
    # the warm-up crosses the first checkpoint; 89 updates (odd) before the second
    cfg = TINY.model_copy(update={"learning_starts": 151})
    saved: list = []
    whole = trained(5, 3, cfg, saved=saved)
    assert [s["epochs"] for s in saved] == [1, 2, 3]
    assert [s["n_updates"] for s in saved] == [0, 89, 209]
    for epochs, checkpoint in enumerate(saved[:2], start=1):
        save_torch_file(tmp_path / "checkpoint.pt", checkpoint)  # tensors and plain data
        state = load_torch_file(tmp_path / "checkpoint.pt", "checkpoint")
        resumed = trained(5, 3, cfg, state=state)  # no demonstrations loaded: from `state`
        assert parameter_bytes(resumed) == parameter_bytes(whole), f"resumed after {epochs}"
        for ours, theirs in ((resumed.actor, whole.actor), (resumed.critic, whole.critic)):
            assert str(ours.optimizer.state_dict()) == str(theirs.optimizer.state_dict())
        assert np.array_equal(resumed.replay_buffer.rewards, whole.replay_buffer.rewards)
    # what makes it exact: without the saved numpy state (exploration noise, batches)
    # the resumed run takes other steps
    state["rng"]["numpy"] = saved[0]["rng"]["numpy"]
    assert parameter_bytes(trained(5, 3, cfg, state=state)) != parameter_bytes(whole)


# --- bad demonstrations ----------------------------------------------------------------


def bad(field: str, value) -> Demonstrations:
    return pendulum_demos(5)._replace(**{field: value})


@pytest.mark.parametrize(
    ("demos", "field"),
    [
        (bad("actions", np.ones((5, 2))), "actions: action dimension 2"),
        (bad("actions", np.full((5, 1), 3.0)), "actions: outside the action space"),
        (bad("obs", np.full((5, 3), np.nan)), "obs: NaN"),
        (bad("rewards", [0, 0, np.nan, 0, 0]), "rewards: NaN"),
        (bad("next_obs", np.zeros((4, 3))), "next_obs: shape (4, 3), expected (5, 3)"),
        (bad("obs", np.zeros((5, 2))), "obs: shape (5, 2), expected (5, 3)"),
        (bad("dones", np.full(5, 0.5)), "dones: values other than 0 and 1"),
        (bad("rewards", ["a"] * 5), "rewards: not an array of numbers"),
        (bad("obs", np.zeros((0, 3))), "obs: no transitions"),
    ],
)
def test_bad_demonstrations_are_input_errors_naming_the_field(demos, field):
    model = td3_model(TINY, gym.make("Pendulum-v1"), seed=0)
    with pytest.raises(InputError) as error:
        load_demonstrations(model, demos)
    assert f"demonstrations.{field}" in str(error.value)
    assert "\n" not in str(error.value)
    assert model.demo_buffer is None
