"""NPG and DAPG on a tiny point-mass task defined here; rollout records; determinism."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch

from artic.learning.npg import (
    NPG,
    NPGConfig,
    conjugate_gradient,
    discounted_returns,
    gae_advantages,
)
from artic.learning.rollout import (
    gaussian_actor,
    idle_action,
    normalised_return,
    returns_of,
    rollout,
    rollout_seeds,
    rollouts,
    torch_generator,
)
from artic.policies.gaussian_mlp import BCConfig, GaussianMLPPolicy, behaviour_clone

GOAL = np.array([0.6, -0.4])


class PointMass(gym.Env[np.ndarray, np.ndarray]):
    """2-D point driven by velocity commands to a fixed goal; reward as Eq. 5.1."""

    def __init__(self, horizon: int = 20, dt: float = 0.1) -> None:
        self.horizon, self.dt = horizon, dt
        self.observation_space = gym.spaces.Box(-5, 5, (2,), np.float32)
        self.action_space = gym.spaces.Box(-1, 1, (2,), np.float32)

    def reset(self, *, seed: int | None = None, options: Any = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.x = self.np_random.uniform(-0.1, 0.1, 2)
        self.t = 0
        return self.x.astype(np.float32), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        a = np.asarray(action, dtype=np.float64)
        self.x = self.x + self.dt * a
        self.t += 1
        err = GOAL - self.x
        reward = -float(err @ err) - 1e-3 * float(a @ a)
        success = bool(np.linalg.norm(err) < 0.05)
        return (
            self.x.astype(np.float32),
            reward,
            False,
            self.t >= self.horizon,
            {"success": success},
        )


def expert(obs: np.ndarray, step: int) -> np.ndarray:
    return np.clip(3.0 * (GOAL - obs), -1, 1)


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


def _train(policy: GaussianMLPPolicy, npg: NPG, seed: int, updates: int, n: int) -> list[float]:
    env = PointMass()
    curve = []
    for k in range(updates):
        act = gaussian_actor(policy, torch_generator(seed, k))
        trajs = rollouts(env, act, rollout_seeds(seed, k, n))
        curve.append(npg.update(trajs).mean_return)
    return curve


def _evaluate(policy: GaussianMLPPolicy) -> float:
    return float(returns_of(rollouts(PointMass(), gaussian_actor(policy), range(10))).mean())


def test_rollout_records_shapes_and_seeded_resets():
    env = PointMass()
    traj = rollout(env, expert, reset_seed=3)
    assert traj.observations.shape == (20, 2) and traj.actions.shape == (20, 2)
    assert traj.rewards.shape == (20,) and len(traj) == 20 and traj.success
    assert traj.total_return == pytest.approx(traj.rewards.sum())
    again = rollout(env, expert, reset_seed=3)
    assert np.array_equal(traj.observations, again.observations)
    other = rollout(env, expert, reset_seed=4)
    assert not np.array_equal(traj.observations[0], other.observations[0])
    assert rollout_seeds(0, 1, 3) == rollout_seeds(0, 1, 3) != rollout_seeds(0, 2, 3)


def test_normalised_return_is_zero_for_idle_and_one_for_zero_cost():
    idle = returns_of(rollouts(PointMass(), idle_action(2), range(4)))
    assert normalised_return(idle, idle) == pytest.approx(0.0)
    assert normalised_return(np.zeros(4), idle) == pytest.approx(1.0)
    good = returns_of(rollouts(PointMass(), expert, range(4)))
    assert 0.3 < normalised_return(good, idle) < 1.0
    with pytest.raises(ValueError):
        normalised_return(good, np.zeros(4))


def test_returns_gae_and_conjugate_gradient():
    r = np.array([1.0, 0.0, 2.0])
    assert np.allclose(discounted_returns(r, 0.5), [1.5, 1.0, 2.0])
    # lambda = 1 with any values: advantage = Monte-Carlo return - value
    v = np.array([0.3, -0.2, 0.7])
    assert np.allclose(gae_advantages(r, v, 0.9, 1.0), discounted_returns(r, 0.9) - v)
    a = torch.tensor([[4.0, 1.0], [1.0, 3.0]])
    b = torch.tensor([1.0, 2.0])
    x = conjugate_gradient(lambda p: a @ p, b, 10)
    assert torch.allclose(a @ x, b, atol=1e-5)


def test_npg_improves_the_mean_return_from_random_init():
    policy = GaussianMLPPolicy(2, 2, generator=torch.Generator().manual_seed(0))
    npg = NPG(policy, NPGConfig(step_size=0.1, gamma=0.99, gae_lambda=0.97))
    start = _evaluate(policy)
    curve = _train(policy, npg, seed=0, updates=12, n=8)
    assert np.mean(curve[-3:]) > np.mean(curve[:3])
    assert _evaluate(policy) > start + 0.3 * abs(start)


def test_npg_with_mlp_baseline_runs_and_improves():
    policy = GaussianMLPPolicy(2, 2, generator=torch.Generator().manual_seed(0))
    npg = NPG(policy, NPGConfig(step_size=0.1, baseline="mlp", baseline_epochs=5))
    start = _evaluate(policy)
    _train(policy, npg, seed=1, updates=8, n=8)
    assert _evaluate(policy) > start


def _demo_tensors() -> tuple[torch.Tensor, torch.Tensor]:
    demos = rollouts(PointMass(), expert, range(100, 105))
    obs = torch.as_tensor(np.vstack([d.observations for d in demos]), dtype=torch.float32)
    act = torch.as_tensor(np.vstack([d.actions for d in demos]), dtype=torch.float32)
    return obs, act


def test_dapg_from_behaviour_cloning_starts_better_and_improves():
    obs, act = _demo_tensors()
    random = GaussianMLPPolicy(2, 2, generator=torch.Generator().manual_seed(0))
    cloned = GaussianMLPPolicy(2, 2, generator=torch.Generator().manual_seed(0))
    behaviour_clone(cloned, obs, act, BCConfig(epochs=30, batch_size=16, lr=3e-3),
                    torch.Generator().manual_seed(0))  # fmt: skip
    assert _evaluate(cloned) > _evaluate(random)
    npg = NPG(cloned, NPGConfig(step_size=0.05, dapg_lambda0=0.1), demos=(obs, act))
    assert npg.demo_weight() == pytest.approx(0.1)
    curve = _train(cloned, npg, seed=0, updates=6, n=8)
    assert npg.demo_weight() == pytest.approx(0.1 * 0.95**6)
    random_curve = _train(random, NPG(random, NPGConfig(step_size=0.05)), seed=0, updates=6, n=8)
    assert all(c > r for c, r in zip(curve, random_curve, strict=True)), "bootstrap ahead"
    assert max(curve[1:]) > curve[0]


def test_npg_is_deterministic_and_resumable():
    def run(updates: int, state: dict | None = None, start: int = 0) -> tuple[NPG, list[float]]:
        policy = GaussianMLPPolicy(2, 2, generator=torch.Generator().manual_seed(5))
        npg = NPG(policy, NPGConfig(step_size=0.1))
        if state is not None:
            npg.load_state_dict(state)
        env, curve = PointMass(), []
        for k in range(start, updates):
            act = gaussian_actor(policy, torch_generator(7, k))
            curve.append(npg.update(rollouts(env, act, rollout_seeds(7, k, 4))).mean_return)
        return npg, curve

    full, curve = run(4)
    again, curve_again = run(4)
    assert curve == curve_again
    vec = lambda n: torch.nn.utils.parameters_to_vector(n.policy.parameters())  # noqa: E731
    assert torch.equal(vec(full), vec(again))
    half, first = run(2)
    resumed, rest = run(4, state=half.state_dict(), start=2)
    assert first + rest == curve and torch.equal(vec(resumed), vec(full))


def test_dmp_rollout_tracks_a_dmp_to_the_goal():
    from artic.learning.rollout import dmp_rollouts
    from artic.policies.dmp import DMPConfig, DMPParams

    cfg = DMPConfig(n_basis=5)
    params = DMPParams(np.zeros((2, 5)), np.zeros(2), GOAL.copy(), tau=1.5)
    trajs = dmp_rollouts(PointMass(), params, cfg, [0, 1], dt=0.1, steps=20, k_p=5.0)
    assert len(trajs) == 2 and trajs[0].actions.shape == (20, 2)
    assert all(t.success for t in trajs)
    idle = returns_of(rollouts(PointMass(), idle_action(2), [0, 1]))
    assert normalised_return(returns_of(trajs), idle) > 0.5


def test_npg_update_writes_into_the_parameters_own_storage():
    """The step is added in place: each parameter keeps its own (aligned) storage.
    `vector_to_parameters` made them views into one flat vector at unaligned offsets,
    where MKL's products differ from a resumed policy's fresh tensors on AVX-512 CPUs."""
    policy = GaussianMLPPolicy(2, 2, generator=torch.Generator().manual_seed(5))
    npg = NPG(policy, NPGConfig(step_size=0.1))
    storage = [(p.data_ptr(), p.untyped_storage().nbytes()) for p in policy.parameters()]
    before = [p.detach().clone() for p in policy.parameters()]
    act = gaussian_actor(policy, torch_generator(7, 0))
    step = npg.update(rollouts(PointMass(), act, rollout_seeds(7, 0, 4)))
    assert step.alpha > 0
    assert [(p.data_ptr(), p.untyped_storage().nbytes()) for p in policy.parameters()] == storage
    assert any(not torch.equal(a, p) for a, p in zip(before, policy.parameters(), strict=True))
