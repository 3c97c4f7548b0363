"""Mixture density network of section 3.2 and the operations on its output mixture.

Eq. 3.1: p(y | x) = sum_i pi_i(x) N(y | mu_i(x), diag(sigma_i(x)^2)), i = 1..m, with a
ResNet-18 backbone on an object-centred crop (preprocess.py) and one fully connected
head for each of pi, mu and sigma. It is trained by the negative log-likelihood
(Eq. 3.2, `mdn_nll`). All quantities are in the units of the standardised targets (zero
mean, unit variance per column; see targets.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal, NamedTuple

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from artic.kinematics.preprocess import SIDE_FEATURES
from artic.kinematics.resnet import ResNet18

_LOG_2PI = math.log(2.0 * math.pi)
#: softplus(_SIGMA_BIAS) = 1: components start with unit standard deviation
_SIGMA_BIAS = math.log(math.e - 1.0)
#: standard deviation of the head weights, times 1 / sqrt(in_features)
_HEAD_WEIGHT_STD = 0.1
#: width of the layer that embeds the crop's position
_SIDE_HIDDEN = 64

Reduction = Literal["mean", "sum", "none"]


class Mixture(NamedTuple):
    """A batch of diagonal Gaussian mixtures with m components in D dimensions."""

    log_pi: Tensor  # (B, m) log mixture weights, log_softmax-normalised
    mu: Tensor  # (B, m, D) component means
    sigma: Tensor  # (B, m, D) component standard deviations, > 0


class MDNHead(nn.Module):
    """Features (B, F) -> Mixture: three linear heads for pi logits, mu and sigma."""

    def __init__(
        self, in_features: int, out_dim: int, components: int = 20, sigma_floor: float = 1e-3
    ) -> None:
        super().__init__()
        self.components = components
        self.out_dim = out_dim
        self.sigma_floor = sigma_floor
        self.logits = nn.Linear(in_features, components)
        self.mu = nn.Linear(in_features, components * out_dim)
        self.sigma = nn.Linear(in_features, components * out_dim)
        self._init_weights(in_features)

    def _init_weights(self, in_features: int) -> None:
        """A broad start: near-uniform weights, unit sigmas, means spread like the targets."""
        for layer in (self.logits, self.mu, self.sigma):
            nn.init.normal_(layer.weight, std=_HEAD_WEIGHT_STD / math.sqrt(in_features))
        nn.init.zeros_(self.logits.bias)
        nn.init.normal_(self.mu.bias)
        nn.init.constant_(self.sigma.bias, _SIGMA_BIAS)

    def forward(self, features: Tensor) -> Mixture:
        """(B, F) -> Mixture with log_pi (B, m), mu and sigma (B, m, D)."""
        shape = (features.shape[0], self.components, self.out_dim)
        log_pi = F.log_softmax(self.logits(features), dim=-1)
        mu = self.mu(features).reshape(shape)
        sigma = F.softplus(self.sigma(features)).reshape(shape) + self.sigma_floor
        return Mixture(log_pi, mu, sigma)


class KinematicsMDN(nn.Module):
    """Object crop (B, C, S, S) and where it is (B, K) -> Mixture over the D targets.

    The crop goes through the ResNet-18; the crop's position (preprocess.py) through one
    linear layer with ReLU; the heads read both, and the raw position vector, so a
    camera-frame quantity can be the crop's content plus where the crop is.
    """

    def __init__(
        self,
        out_dim: int,
        components: int = 20,
        width: int = 64,
        in_channels: int = 1,
        sigma_floor: float = 1e-3,
        side_features: int = SIDE_FEATURES,
        input_size: int = 64,
    ) -> None:
        super().__init__()
        self.hparams: dict[str, Any] = {
            "out_dim": out_dim,
            "components": components,
            "width": width,
            "in_channels": in_channels,
            "sigma_floor": sigma_floor,
            "side_features": side_features,
            "input_size": input_size,
        }
        self.backbone = ResNet18(in_channels, width)
        self.side = nn.Sequential(nn.Linear(side_features, _SIDE_HIDDEN), nn.ReLU())
        features = self.backbone.out_features + _SIDE_HIDDEN + side_features
        self.head = MDNHead(features, out_dim, components, sigma_floor)

    def forward(self, image: Tensor, side: Tensor) -> Mixture:
        """(B, C, S, S) crops and (B, K) crop positions -> Mixture (B, m, D)."""
        features = torch.cat([self.backbone(image), self.side(side), side], dim=1)
        mix: Mixture = self.head(features)
        return mix


def mixture_log_prob(mix: Mixture, y: Tensor) -> Tensor:
    """log p(y) of K query points per batch item: y (B, K, D) -> (B, K)."""
    z = (y[:, :, None, :] - mix.mu[:, None]) / mix.sigma[:, None]  # (B, K, m, D)
    log_n = -0.5 * z.square() - mix.sigma[:, None].log() - 0.5 * _LOG_2PI
    return torch.logsumexp(mix.log_pi[:, None] + log_n.sum(-1), dim=-1)


def mdn_nll(mix: Mixture, y: Tensor, reduction: Reduction = "mean") -> Tensor:
    """Negative log-likelihood (Eq. 3.2) of targets y (B, D): scalar, or (B,) for "none"."""
    nll = -mixture_log_prob(mix, y[:, None])[:, 0]
    if reduction == "mean":
        return nll.mean()
    if reduction == "sum":
        return nll.sum()
    if reduction == "none":
        return nll
    raise ValueError(f"reduction must be 'mean', 'sum' or 'none', not {reduction!r}")


def most_likely(mix: Mixture) -> Tensor:
    """The thesis' "maximum likelihood sample" (section 3.3.1): the mean of the component
    with the largest mixing weight pi_i, the most likely component (B, D). This is the
    estimate the thesis' evaluation code reports (docs/kinematics.md)."""
    return _component_means(mix, mix.log_pi.argmax(dim=-1))


def densest(mix: Mixture) -> Tensor:
    """The component mean with the highest mixture density, p(mu_i) (B, D): the mixture's
    mode when the components are well separated. In many label dimensions a narrow
    component of small weight wins (docs/kinematics.md has the measured comparison)."""
    return _component_means(mix, mixture_log_prob(mix, mix.mu).argmax(dim=-1))


def _component_means(mix: Mixture, component: Tensor) -> Tensor:
    """The mean of component `component[b]` (B,) of each batch item: (B, D)."""
    return mix.mu[torch.arange(len(component), device=component.device), component]


def sample(mix: Mixture, n: int, generator: torch.Generator | None = None) -> Tensor:
    """n draws per batch item: (B, n, D); reproducible with a seeded generator."""
    component = torch.multinomial(mix.log_pi.exp(), n, replacement=True, generator=generator)
    rows = torch.arange(len(component), device=component.device)[:, None]
    mu, sigma = mix.mu[rows, component], mix.sigma[rows, component]  # (B, n, D)
    noise = torch.randn(mu.shape, generator=generator, dtype=mu.dtype, device=mu.device)
    return mu + sigma * noise


def marginal_cdf(mix: Mixture, y: Tensor) -> Tensor:
    """P(Y_d <= y_d) under each 1-D marginal of the mixture: y (..., B, D) -> (..., B, D)."""
    phi = torch.special.ndtr((y[..., None, :] - mix.mu) / mix.sigma)  # (..., B, m, D)
    return (mix.log_pi.exp()[:, :, None] * phi).sum(dim=-2)


@torch.no_grad()
def marginal_quantiles(mix: Mixture, qs: Sequence[float], iterations: int = 60) -> Tensor:
    """Each q-quantile of `qs` of each 1-D marginal, (Q, B, D), by bisection on
    `marginal_cdf`, all of them in one bisection (each the same numbers as alone)."""
    q = torch.tensor(list(qs), dtype=mix.mu.dtype)[:, None, None]
    lo = (mix.mu - 10 * mix.sigma).amin(dim=1).expand(len(q), -1, -1)
    hi = (mix.mu + 10 * mix.sigma).amax(dim=1).expand(len(q), -1, -1)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        below = marginal_cdf(mix, mid) < q
        lo = torch.where(below, mid, lo)
        hi = torch.where(below, hi, mid)
    return 0.5 * (lo + hi)


def marginal_quantile(mix: Mixture, q: float, iterations: int = 60) -> Tensor:
    """The q-quantile of each 1-D marginal, (B, D) (`marginal_quantiles`)."""
    return marginal_quantiles(mix, [q], iterations)[0]


def marginal_intervals(mix: Mixture, levels: Sequence[float]) -> dict[float, tuple[Tensor, Tensor]]:
    """Central interval of each 1-D marginal at each of `levels`: level -> (lower, upper),
    each (B, D), from one bisection (`marginal_quantiles`)."""
    for level in levels:
        if not 0.0 < level < 1.0:
            raise ValueError(f"level must be in (0, 1), not {level}")
    if not levels:
        return {}
    bounds = marginal_quantiles(mix, [t for lv in levels for t in (0.5 * (1 - lv), 0.5 * (1 + lv))])
    return {level: (bounds[2 * k], bounds[2 * k + 1]) for k, level in enumerate(levels)}


def marginal_interval(mix: Mixture, level: float) -> tuple[Tensor, Tensor]:
    """Central `level` interval of each 1-D marginal: (lower, upper), each (B, D)."""
    return marginal_intervals(mix, [level])[level]
