"""Gaussian MLP policy: shapes, likelihood, behaviour cloning, determinism."""

from __future__ import annotations

import math

import pytest
import torch

from artic.policies.gaussian_mlp import (
    BCConfig,
    GaussianMLPPolicy,
    behaviour_clone,
    gaussian_log_prob,
    mean_nll,
)


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


def _demos(n: int = 200) -> tuple[torch.Tensor, torch.Tensor]:
    gen = torch.Generator().manual_seed(0)
    obs = torch.rand((n, 8), generator=gen) * 2 - 1
    actions = torch.tanh(obs[:, :7] * 2.0) * 0.5 + 0.1 * obs[:, 7:]
    return obs, actions


def test_shapes_and_initial_mean_is_near_zero():
    policy = GaussianMLPPolicy(8, 7, generator=torch.Generator().manual_seed(1))
    obs = torch.randn(5, 8)
    assert policy.mean(obs).shape == (5, 7)
    assert policy.log_prob(obs, torch.zeros(5, 7)).shape == (5,)
    sample = policy.sample(obs, torch.Generator().manual_seed(2))
    assert sample.shape == (5, 7)
    assert policy.mean(obs).abs().max() < 0.05, "output layer scaled by 0.01"
    assert [layer.out_features for layer in policy.layers] == [32, 32, 7]


def test_log_prob_matches_torch_normal():
    mean, log_std, x = torch.randn(4, 3), torch.randn(3) * 0.3, torch.randn(4, 3)
    expected = torch.distributions.Normal(mean, log_std.exp()).log_prob(x).sum(-1)
    assert torch.allclose(gaussian_log_prob(mean, log_std, x), expected, atol=1e-5)


def test_samples_follow_the_policy_std():
    policy = GaussianMLPPolicy(2, 3, init_log_std=math.log(0.3))
    obs = torch.zeros(4000, 2)
    a = policy.sample(obs, torch.Generator().manual_seed(0))
    assert torch.allclose(a.std(0), torch.full((3,), 0.3), atol=0.02)


def test_behaviour_cloning_reduces_the_nll_of_the_demos():
    obs, actions = _demos()
    policy = GaussianMLPPolicy(8, 7, generator=torch.Generator().manual_seed(0))
    before = mean_nll(policy, obs, actions)
    result = behaviour_clone(policy, obs, actions, BCConfig(epochs=10, lr=3e-3),
                             torch.Generator().manual_seed(0))  # fmt: skip
    assert len(result.nll) == 11 and result.nll[0] == pytest.approx(before)
    assert result.nll[-1] < before - 2.0
    assert result.nll[-1] == pytest.approx(mean_nll(policy, obs, actions))
    # the mean actions moved towards the demonstrations
    err_after = (policy.mean(obs) - actions).pow(2).mean()
    assert err_after < actions.pow(2).mean() * 0.5


def test_behaviour_cloning_is_deterministic_given_the_generator():
    obs, actions = _demos(100)

    def fit(seed: int) -> torch.Tensor:
        policy = GaussianMLPPolicy(8, 7, generator=torch.Generator().manual_seed(0))
        behaviour_clone(policy, obs, actions, BCConfig(epochs=2, batch_size=16),
                        torch.Generator().manual_seed(seed))  # fmt: skip
        return torch.nn.utils.parameters_to_vector(policy.parameters()).detach()

    assert torch.equal(fit(3), fit(3))
    assert not torch.equal(fit(3), fit(4)), "another minibatch order, other weights"


def test_log_std_is_clamped_and_bad_data_raises():
    policy = GaussianMLPPolicy(2, 1, min_log_std=-1.0)
    with torch.no_grad():
        policy.log_std.fill_(-5.0)
    policy.clamp_log_std()
    assert float(policy.log_std.detach()) == -1.0
    with pytest.raises(ValueError, match="behaviour_clone"):
        behaviour_clone(policy, torch.zeros(3, 2), torch.zeros(4, 1), BCConfig(),
                        torch.Generator())  # fmt: skip
    with pytest.raises(ValueError):
        GaussianMLPPolicy(0, 1)
