"""Gaussian multi-layer perceptron policy and behaviour cloning (thesis section 5.2.1).

`pi(a | s) = N(mu_theta(s), diag(exp(log_std))^2)`: the mean is an MLP (hidden (32, 32),
tanh, as in section 5.3.1's microwave experiment), the log standard deviation is one
state-independent parameter per action dimension (Rajeswaran et al. 2017, mjrl's
`MLP` policy). Observations are standardised by fixed buffers `obs_shift`/`obs_scale`
(set from the demonstrations by behaviour cloning, identity otherwise).

Behaviour cloning maximises the likelihood of the demonstration actions under the policy
for E epochs (thesis: 10) with Adam; the minibatch order of epoch e is a permutation
drawn from the caller's `torch.Generator`, so the same generator state gives the same
weights.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import torch
from pydantic import BaseModel, ConfigDict, Field
from torch import nn


class GaussianMLPPolicy(nn.Module):
    """Diagonal Gaussian policy with an MLP mean and a state-independent log-std.

    obs_dim: observation size (`[q_R, q_O]`: 7 + dof); act_dim: action size (7 joint
    velocities, rad/s). `init_log_std` is the initial log-std of every action dimension
    and `min_log_std` the floor it is clamped to after updates (`clamp_log_std`).

    Initialisation ("random" policy of the thesis' baselines): PyTorch's default layer
    initialisation drawn from `generator`, then the output layer's weights scaled by
    `out_scale` (0.01, as mjrl) and its bias zeroed, so the initial mean action is close
    to zero everywhere and exploration comes from the log-std.
    """

    obs_shift: torch.Tensor
    obs_scale: torch.Tensor

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: tuple[int, ...] = (32, 32),
        init_log_std: float = -0.5,
        min_log_std: float = -3.0,
        out_scale: float = 0.01,
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        if obs_dim <= 0 or act_dim <= 0:
            raise ValueError(f"obs_dim and act_dim must be positive, got {obs_dim}, {act_dim}")
        self.obs_dim, self.act_dim, self.hidden = obs_dim, act_dim, tuple(hidden)
        self.min_log_std = min_log_std
        sizes = [obs_dim, *self.hidden, act_dim]
        self.layers = nn.ModuleList(nn.Linear(a, b) for a, b in itertools.pairwise(sizes))
        self.log_std = nn.Parameter(torch.full((act_dim,), float(init_log_std)))
        self.register_buffer("obs_shift", torch.zeros(obs_dim))
        self.register_buffer("obs_scale", torch.ones(obs_dim))
        self._init_weights(out_scale, generator)

    def _init_weights(self, out_scale: float, generator: torch.Generator | None) -> None:
        with torch.no_grad():
            for layer in self._linear():
                bound = 1.0 / math.sqrt(layer.in_features)  # nn.Linear's default range
                layer.weight.uniform_(-bound, bound, generator=generator)
                layer.bias.uniform_(-bound, bound, generator=generator)
            out = self._linear()[-1]
            out.weight.mul_(out_scale)
            out.bias.zero_()

    def _linear(self) -> list[nn.Linear]:
        return [layer for layer in self.layers if isinstance(layer, nn.Linear)]

    @property
    def hparams(self) -> dict[str, object]:
        """Constructor arguments that rebuild this architecture."""
        return {
            "obs_dim": self.obs_dim,
            "act_dim": self.act_dim,
            "hidden": list(self.hidden),
            "min_log_std": self.min_log_std,
        }

    def mean(self, obs: torch.Tensor) -> torch.Tensor:
        """obs: (N, obs_dim) -> mean action (N, act_dim)."""
        x = (obs - self.obs_shift) / self.obs_scale
        for layer in self.layers[:-1]:
            x = torch.tanh(layer(x))
        out: torch.Tensor = self.layers[-1](x)
        return out

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.mean(obs)

    def log_prob(self, obs: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """log pi(a | s) of each pair: obs (N, obs_dim), actions (N, act_dim) -> (N,)."""
        return gaussian_log_prob(self.mean(obs), self.log_std, actions)

    def sample(self, obs: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """Actions a ~ pi(. | s) for obs (N, obs_dim) -> (N, act_dim), drawn from `generator`."""
        with torch.no_grad():
            mu = self.mean(obs)
            noise = torch.randn(mu.shape, generator=generator, dtype=mu.dtype)
            return mu + noise * self.log_std.exp()

    def clamp_log_std(self) -> None:
        """Keep log-std above `min_log_std` (after an update step)."""
        with torch.no_grad():
            self.log_std.clamp_(min=self.min_log_std)

    def set_obs_normalisation(self, obs: torch.Tensor) -> None:
        """Standardise inputs with the mean and std of `obs` (N, obs_dim); constant
        dimensions keep scale 1."""
        with torch.no_grad():
            std = obs.std(dim=0, unbiased=False) if len(obs) > 1 else torch.ones(self.obs_dim)
            self.obs_shift.copy_(obs.mean(dim=0))
            self.obs_scale.copy_(torch.where(std > 1e-6, std, torch.ones_like(std)))


def gaussian_log_prob(mean: torch.Tensor, log_std: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """Log density of a diagonal Gaussian: mean (N, D), log_std (D,), x (N, D) -> (N,)."""
    z = (x - mean) / log_std.exp()
    return -0.5 * (z**2).sum(-1) - log_std.sum() - 0.5 * mean.shape[-1] * math.log(2 * math.pi)


class BCConfig(BaseModel):
    """Behaviour cloning by maximum likelihood (section 5.2.1). In a stage config the
    fields are `bc_epochs`, `bc_batch_size`, `bc_lr` (policy-search's `mlp_policy`)."""

    model_config = ConfigDict(
        frozen=True, extra="forbid", validate_by_name=True, validate_by_alias=True
    )

    epochs: int = Field(10, ge=0, alias="bc_epochs", description="epochs (thesis: 10)")
    batch_size: int = Field(64, gt=0, alias="bc_batch_size", description="minibatch size")
    lr: float = Field(1e-3, gt=0, alias="bc_lr", description="Adam learning rate")
    normalise_obs: bool = Field(True, description="standardise inputs with the demo states")


@dataclass(frozen=True)
class BCResult:
    """Mean NLL over the dataset before training (before the input standardisation is
    set) and after each epoch: (epochs + 1,)."""

    nll: list[float]


def mean_nll(policy: GaussianMLPPolicy, obs: torch.Tensor, actions: torch.Tensor) -> float:
    """Mean negative log-likelihood of the (obs, action) pairs under the policy."""
    with torch.no_grad():
        return float(-policy.log_prob(obs, actions).mean())


def behaviour_clone(
    policy: GaussianMLPPolicy,
    obs: torch.Tensor,
    actions: torch.Tensor,
    cfg: BCConfig,
    generator: torch.Generator,
) -> BCResult:
    """Fit `policy` in place to demonstrations by maximum likelihood.

    obs: (N, obs_dim) states `[q_R, q_O]`; actions: (N, act_dim) demonstrated joint
    velocities (rad/s). Minibatch order of each epoch: `torch.randperm(N, generator)`.
    """
    if obs.ndim != 2 or actions.ndim != 2 or len(obs) != len(actions) or len(obs) == 0:
        raise ValueError(
            f"behaviour_clone: obs (N, D) and actions (N, A) with N > 0 expected, got "
            f"{tuple(obs.shape)} and {tuple(actions.shape)}"
        )
    history = [mean_nll(policy, obs, actions)]
    if cfg.normalise_obs:
        policy.set_obs_normalisation(obs)
    optimizer = torch.optim.Adam(policy.parameters(), lr=cfg.lr)
    for _ in range(cfg.epochs):
        order = torch.randperm(len(obs), generator=generator)
        for start in range(0, len(obs), cfg.batch_size):
            idx = order[start : start + cfg.batch_size]
            loss = -policy.log_prob(obs[idx], actions[idx]).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            policy.clamp_log_std()
        history.append(mean_nll(policy, obs, actions))
    return BCResult(history)
