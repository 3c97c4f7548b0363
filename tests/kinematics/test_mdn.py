"""The ResNet-18 backbone, the mixture operations and the MDN of section 3.2."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy import stats

from artic.kinematics.mdn import (
    KinematicsMDN,
    MDNHead,
    Mixture,
    densest,
    marginal_cdf,
    marginal_interval,
    marginal_intervals,
    mdn_nll,
    mixture_log_prob,
    most_likely,
    sample,
)
from artic.kinematics.preprocess import SIDE_FEATURES
from artic.kinematics.resnet import ResNet18

Z95 = 1.6448536269514722  # standard normal 0.95 quantile


def n_params(model: torch.nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


def random_mixture(
    batch: int, m: int, d: int, seed: int = 0, dtype: torch.dtype = torch.float32
) -> Mixture:
    g = torch.Generator().manual_seed(seed)
    log_pi = torch.log_softmax(torch.randn(batch, m, generator=g, dtype=dtype), dim=-1)
    mu = torch.randn(batch, m, d, generator=g, dtype=dtype) * 2
    sigma = torch.rand(batch, m, d, generator=g, dtype=dtype) * 1.5 + 0.2
    return Mixture(log_pi, mu, sigma)


def mixture_of(pi: list[float], mu: list[list[float]], sigma: list[list[float]]) -> Mixture:
    """One mixture (B = 1) from weights (m,), means and stds (m, D)."""
    return Mixture(torch.tensor([pi]).log(), torch.tensor([mu]), torch.tensor([sigma]))


# --- ResNet-18 ---


def test_resnet18_parameter_count_matches_torchvision_without_fc():
    assert n_params(ResNet18(in_channels=3, width=64)) == 11_176_512
    assert n_params(ResNet18(in_channels=1, width=64)) == 11_170_240
    assert ResNet18().out_features == 512


@pytest.mark.parametrize("size", [128, 64])
def test_resnet18_output_shape(size):
    model = ResNet18(in_channels=1, width=8).eval()
    with torch.no_grad():
        out = model(torch.randn(2, 1, size, size))
    assert out.shape == (2, model.out_features) == (2, 64)


def test_resnet18_residual_branches_start_as_identity():
    model = ResNet18(width=8)
    last_gammas = [m.bn2.weight for m in model.modules() if hasattr(m, "bn2")]
    assert len(last_gammas) == 8 and all(bool((w == 0).all()) for w in last_gammas)


def test_resnet18_channels_last_matches_contiguous():
    torch.manual_seed(0)
    model = ResNet18(in_channels=1, width=8).eval()
    for bn in (m for m in model.modules() if isinstance(m, torch.nn.BatchNorm2d)):
        # random statistics, so that the residual branches (zero gamma at init) count too
        bn.weight.data.uniform_(0.5, 1.5)
        bn.bias.data.normal_(0, 0.1)
        bn.running_mean.normal_(0, 0.1)
        bn.running_var.uniform_(0.5, 1.5)
    x = torch.randn(2, 1, 64, 64)
    with torch.no_grad():
        expected = model(x)
        model = model.to(memory_format=torch.channels_last)
        got = model(x.to(memory_format=torch.channels_last))
    torch.testing.assert_close(got, expected, rtol=1e-4, atol=1e-5)


# --- negative log-likelihood ---


def reference_nll(mix: Mixture, y: torch.Tensor) -> np.ndarray:
    """-log sum_i pi_i prod_d N(y_d | mu_id, sigma_id), directly in float64."""
    pi = mix.log_pi.double().exp().numpy()
    mu, sigma = mix.mu.double().numpy(), mix.sigma.double().numpy()
    density = stats.norm.pdf(y.double().numpy()[:, None], mu, sigma).prod(-1)  # (B, m)
    return -np.log((pi * density).sum(-1))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_mdn_nll_matches_direct_float64_computation(dtype):
    mix = random_mixture(16, 5, 3, seed=1, dtype=dtype)
    y = torch.randn(16, 3, generator=torch.Generator().manual_seed(2), dtype=dtype) * 2
    expected = reference_nll(mix, y)
    tol = 1e-12 if dtype == torch.float64 else 1e-5
    np.testing.assert_allclose(mdn_nll(mix, y, "none").double().numpy(), expected, rtol=tol)
    np.testing.assert_allclose(float(mdn_nll(mix, y)), expected.mean(), rtol=tol)
    np.testing.assert_allclose(float(mdn_nll(mix, y, "sum")), expected.sum(), rtol=tol)
    assert mdn_nll(mix, y, "none").shape == (16,)


def test_mdn_nll_rejects_unknown_reduction():
    mix = random_mixture(2, 3, 2)
    with pytest.raises(ValueError, match="reduction"):
        mdn_nll(mix, torch.zeros(2, 2), "max")  # type: ignore[arg-type]


def test_mdn_nll_is_finite_with_finite_gradients_far_from_every_component():
    mix = random_mixture(4, 5, 3, seed=3)
    params = [t.detach().requires_grad_() for t in mix]
    far = Mixture(*params)
    y = torch.full((4, 3), 1e3 * float(mix.sigma.max()))
    loss = mdn_nll(far, y)
    loss.backward()
    assert torch.isfinite(loss) and float(loss.detach()) > 1e5
    for p in params:
        assert p.grad is not None and torch.isfinite(p.grad).all()


def test_mixture_log_prob_of_several_points_matches_nll():
    mix = random_mixture(3, 4, 2, seed=4)
    y = torch.randn(3, 7, 2, generator=torch.Generator().manual_seed(5))
    log_p = mixture_log_prob(mix, y)
    assert log_p.shape == (3, 7)
    for k in range(7):
        torch.testing.assert_close(-log_p[:, k], mdn_nll(mix, y[:, k], "none"))


# --- estimators and sampling ---


def test_most_likely_picks_the_heaviest_component_densest_the_densest():
    mix = mixture_of([0.1, 0.6, 0.3], [[-10.0, 0.0], [0.0, 5.0], [10.0, -5.0]], [[1.0, 1.0]] * 3)
    torch.testing.assert_close(most_likely(mix), torch.tensor([[0.0, 5.0]]))
    torch.testing.assert_close(densest(mix), torch.tensor([[0.0, 5.0]]))
    # weight against density: a heavy broad component and a light narrow one disagree
    mix = mixture_of([0.7, 0.3], [[0.0], [20.0]], [[10.0], [0.5]])
    torch.testing.assert_close(most_likely(mix), torch.tensor([[0.0]]))
    torch.testing.assert_close(densest(mix), torch.tensor([[20.0]]))


def test_estimators_of_a_single_component_are_its_mean():
    mix = random_mixture(5, 1, 4, seed=6)
    torch.testing.assert_close(most_likely(mix), mix.mu[:, 0])
    torch.testing.assert_close(densest(mix), mix.mu[:, 0])


def test_sample_shape_and_reproducibility():
    mix = random_mixture(3, 4, 2, seed=7)
    a = sample(mix, 50, torch.Generator().manual_seed(8))
    b = sample(mix, 50, torch.Generator().manual_seed(8))
    c = sample(mix, 50, torch.Generator().manual_seed(9))
    assert a.shape == (3, 50, 2)
    torch.testing.assert_close(a, b, rtol=0, atol=0)
    assert not torch.equal(a, c)


def test_sample_statistics_of_a_two_component_mixture():
    pi, mu, sigma = np.array([0.3, 0.7]), np.array([-2.0, 1.0]), np.array([0.5, 1.0])
    mix = mixture_of(pi.tolist(), mu[:, None].tolist(), sigma[:, None].tolist())
    draws = sample(mix, 20_000, torch.Generator().manual_seed(10))[0, :, 0].double().numpy()
    mean = (pi * mu).sum()
    std = np.sqrt((pi * (sigma**2 + mu**2)).sum() - mean**2)
    assert abs(draws.mean() - mean) < 0.05
    assert abs(draws.std() - std) < 0.05
    assert abs((draws < -0.5).mean() - (pi * stats.norm.cdf(-0.5, mu, sigma)).sum()) < 0.015


# --- marginals and calibration ---


def test_interval_of_a_single_gaussian_is_mu_plus_minus_1_645_sigma():
    mix = random_mixture(6, 1, 3, seed=11)
    lo, hi = marginal_interval(mix, 0.9)
    mu, sigma = mix.mu[:, 0], mix.sigma[:, 0]
    torch.testing.assert_close(lo, mu - Z95 * sigma, rtol=0, atol=1e-4)
    torch.testing.assert_close(hi, mu + Z95 * sigma, rtol=0, atol=1e-4)


def test_marginal_cdf_matches_scipy_and_hits_the_interval_levels():
    mix = random_mixture(8, 5, 3, seed=12)
    y = torch.randn(8, 3, generator=torch.Generator().manual_seed(13))
    pi = mix.log_pi.double().exp().numpy()[:, :, None]
    expected = (pi * stats.norm.cdf(y.numpy()[:, None], mix.mu.numpy(), mix.sigma.numpy())).sum(1)
    np.testing.assert_allclose(marginal_cdf(mix, y).numpy(), expected, atol=1e-6)
    lo, hi = marginal_interval(mix, 0.9)
    assert lo.shape == hi.shape == (8, 3) and bool((lo < hi).all())
    torch.testing.assert_close(marginal_cdf(mix, lo), torch.full((8, 3), 0.05), atol=1e-5, rtol=0)
    torch.testing.assert_close(marginal_cdf(mix, hi), torch.full((8, 3), 0.95), atol=1e-5, rtol=0)


def test_marginal_intervals_at_many_levels_equal_each_levels_bisection_alone():
    """One bisection for every level's two tails (`marginal_intervals`, what `describe` and
    `evaluate mdn` compute) gives each bound bit for bit as a bisection of its own."""

    def alone(mix: Mixture, q: float) -> torch.Tensor:
        lo = (mix.mu - 10 * mix.sigma).amin(dim=1)
        hi = (mix.mu + 10 * mix.sigma).amax(dim=1)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            below = marginal_cdf(mix, mid) < q
            lo, hi = torch.where(below, mid, lo), torch.where(below, hi, mid)
        return 0.5 * (lo + hi)

    levels = (*(round(0.05 * k, 2) for k in range(1, 20)), 0.99)
    for batch, seed in ((1, 21), (64, 22)):
        mix = random_mixture(batch, 20, 11, seed=seed)
        bounds = marginal_intervals(mix, levels)
        assert list(bounds) == list(levels)
        for level, (lo, hi) in bounds.items():
            assert torch.equal(lo, alone(mix, 0.5 * (1 - level)))
            assert torch.equal(hi, alone(mix, 0.5 * (1 + level)))
    assert marginal_intervals(mix, ()) == {}
    with pytest.raises(ValueError, match="level must be in"):
        marginal_intervals(mix, (0.5, 1.0))


def test_marginal_interval_is_calibrated_on_draws_from_the_mixture():
    mix = random_mixture(20_000, 5, 3, seed=14)
    y = sample(mix, 1, torch.Generator().manual_seed(15))[:, 0]
    lo, hi = marginal_interval(mix, 0.9)
    inside = ((y >= lo) & (y <= hi)).double().mean(dim=0)
    np.testing.assert_allclose(inside.numpy(), 0.9, atol=0.015)


def test_marginal_interval_rejects_a_level_outside_0_1():
    with pytest.raises(ValueError, match="level"):
        marginal_interval(random_mixture(1, 2, 1), 1.0)


# --- the network ---


def test_head_starts_broad_and_safe():
    torch.manual_seed(0)
    head = MDNHead(64, out_dim=3, components=20)
    with torch.no_grad():
        mix = head(torch.rand(4, 64))
    assert mix.log_pi.shape == (4, 20) and mix.mu.shape == mix.sigma.shape == (4, 20, 3)
    torch.testing.assert_close(mix.log_pi.exp().sum(-1), torch.ones(4))
    assert float(mix.log_pi.exp().max()) < 2 / 20, "weights start near uniform"
    assert float(mix.sigma.min()) > 0.8 and float(mix.sigma.max()) < 1.2
    assert float(mix.mu.std(dim=1).min()) > 0.3, "components start spread out"


def test_sigma_never_goes_below_the_floor():
    head = MDNHead(8, out_dim=2, components=3, sigma_floor=0.01)
    floor = torch.tensor(0.01)  # in float32, as the network computes it
    for features in (torch.full((2, 8), -1e4), torch.full((2, 8), 1e4)):
        assert bool((head(features).sigma >= floor).all())


def test_kinematics_mdn_hparams_rebuild_the_model():
    model = KinematicsMDN(out_dim=3, components=5, width=8)
    again = KinematicsMDN(**model.hparams)
    again.load_state_dict(model.state_dict())
    assert again.hparams == {
        "out_dim": 3,
        "components": 5,
        "width": 8,
        "in_channels": 1,
        "sigma_floor": 1e-3,
        "side_features": SIDE_FEATURES,
        "input_size": 64,
    }


def overfit_losses(steps: int = 150) -> list[float]:
    torch.manual_seed(0)
    x, y = torch.rand(8, 1, 32, 32), torch.randn(8, 3)
    side = torch.randn(8, SIDE_FEATURES)
    model = KinematicsMDN(out_dim=3, components=5, width=8, input_size=32)
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-3)
    losses = []
    for _ in range(steps):
        loss = mdn_nll(model(x, side), y)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(float(loss.detach()))
    return losses


def test_tiny_model_overfits_a_fixed_batch_deterministically():
    losses = overfit_losses()
    assert losses == overfit_losses(), "same seed, same losses"
    assert all(np.isfinite(losses))
    assert losses[-1] < losses[0] - 5.0, (losses[0], losses[-1])
