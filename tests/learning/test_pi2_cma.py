"""PI^2-CMA (Stulp and Sigaud 2012): convergence, determinism, covariance bounds, resume."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pydantic import ValidationError

from artic.errors import InputError
from artic.learning.pi2_cma import PI2CMA, PI2CMAConfig, probability_weights

D = 10
A = np.logspace(0, 2, D)  # condition number 100
TARGET = np.linspace(-1.0, 2.0, D)
SHIFT = np.full(D, 3.0)
CFG = PI2CMAConfig(n_samples=20, h=10.0, covariance_learning_rate=0.2, min_eigenvalue=1e-6)


def quadratic(x: np.ndarray) -> np.ndarray:
    return ((x - TARGET) ** 2 * A).sum(axis=-1)


def sphere(x: np.ndarray) -> np.ndarray:
    return ((x - SHIFT) ** 2).sum(axis=-1)


def run(opt: PI2CMA, cost, rng: np.random.Generator, updates: int) -> list[float]:
    history = []
    for _ in range(updates):
        samples = opt.ask(rng)
        opt.tell(samples, cost(samples))
        history.append(float(cost(opt.mean_)))
    return history


@pytest.mark.parametrize(("cost", "updates"), [(quadratic, 200), (sphere, 150)])
@pytest.mark.parametrize("seed", [0, 1])
def test_minimises_quadratics(cost, updates, seed):
    opt = PI2CMA(np.zeros(D), CFG, sigma0=1.0)
    start = float(cost(np.zeros(D)))
    history = run(opt, cost, np.random.default_rng(seed), updates)
    assert history[-1] < 1e-3, history[-1]
    assert history[-1] < 1e-4 * start
    assert opt.n_updates_ == updates


def test_probability_weights():
    p = probability_weights(np.array([3.0, 1.0, 2.0]), h=10.0)
    assert np.isclose(p.sum(), 1.0) and p.argmax() == 1
    assert np.isclose(p[0] / p[1], np.exp(-10.0))
    assert np.allclose(probability_weights(np.full(4, 7.0), 10.0), 0.25)


def test_update_is_the_weighted_mean_and_covariance():
    cfg = PI2CMAConfig(n_samples=4, min_eigenvalue=1e-12)
    opt = PI2CMA(np.zeros(3), cfg, sigma0=np.array([1.0, 2.0, 0.5]))
    rng = np.random.default_rng(0)
    x = opt.ask(rng)
    costs = np.array([1.0, 0.0, 3.0, 2.0])
    rec = opt.tell(x, costs)
    p = probability_weights(costs, cfg.h)
    assert np.allclose(rec.weights, p) and np.allclose(opt.mean_, p @ x)
    assert np.allclose(opt.cov_, sum(pk * np.outer(xk, xk) for pk, xk in zip(p, x, strict=True)))
    assert rec.update == 1 and rec.cost_min == 0.0 and rec.cost_max == 3.0


def test_same_seed_same_sequence():
    a = PI2CMA(np.zeros(D), CFG, sigma0=1.0)
    b = PI2CMA(np.zeros(D), CFG, sigma0=1.0)
    ha = run(a, sphere, np.random.default_rng(7), 20)
    hb = run(b, sphere, np.random.default_rng(7), 20)
    assert ha == hb and np.array_equal(a.cov_, b.cov_)
    c = PI2CMA(np.zeros(D), CFG, sigma0=1.0)
    assert run(c, sphere, np.random.default_rng(8), 20) != ha


@pytest.mark.parametrize("diagonal_only", [False, True])
def test_covariance_stays_symmetric_psd_and_within_bounds(diagonal_only):
    cfg = PI2CMAConfig(
        n_samples=6, min_eigenvalue=1e-2, max_eigenvalue=2.0, diagonal_only=diagonal_only
    )
    sigma0 = np.linspace(0.1, 3.0, D)  # mixed scales: bounds are relative to Sigma_0
    opt = PI2CMA(np.zeros(D), cfg, sigma0=sigma0)
    rng = np.random.default_rng(3)
    for _ in range(40):
        x = opt.ask(rng)
        rec = opt.tell(x, sphere(x))
        assert np.array_equal(opt.cov_, opt.cov_.T)
        assert np.linalg.eigvalsh(opt.cov_).min() > 0
        rel = opt.relative_eigenvalues()
        assert rel.min() >= 1e-2 * (1 - 1e-9) and rel.max() <= 2.0 * (1 + 1e-9)
        assert rec.eigenvalues_rel[0] >= 1e-2 * (1 - 1e-9)
    if diagonal_only:
        assert np.count_nonzero(opt.cov_ - np.diag(np.diag(opt.cov_))) == 0
    # without exploration pressure the floor is reached: the covariance collapses onto it
    assert rel.min() == pytest.approx(1e-2, rel=1e-6)


@pytest.mark.parametrize("via_json", [False, True])
def test_resume_from_saved_state_is_bit_exact(via_json):
    rng = np.random.default_rng(11)
    full = PI2CMA(np.zeros(D), CFG, sigma0=1.0)
    expected = run(full, quadratic, rng, 12)

    rng = np.random.default_rng(11)
    first = PI2CMA(np.zeros(D), CFG, sigma0=1.0)
    got = run(first, quadratic, rng, 5)
    rng_state = json.loads(json.dumps(rng.bit_generator.state))
    if via_json:
        resumed = PI2CMA.from_json_dict(json.loads(json.dumps(first.to_json_dict())))
    else:
        resumed = PI2CMA.from_state_dict(dict(first.state_dict()), CFG)
    del first
    rng2 = np.random.default_rng()
    rng2.bit_generator.state = rng_state
    got += run(resumed, quadratic, rng2, 7)
    assert got == expected
    assert np.array_equal(resumed.mean_, full.mean_) and np.array_equal(resumed.cov_, full.cov_)
    assert resumed.n_updates_ == 12


def test_bad_config_and_input_raise():
    with pytest.raises(ValidationError):
        PI2CMAConfig(n_samples=1)
    with pytest.raises(ValidationError):
        PI2CMAConfig(h=0.0)
    with pytest.raises(ValidationError):
        PI2CMAConfig(min_eigenvalue=0.0)
    with pytest.raises(ValidationError):
        PI2CMAConfig(covariance_learning_rate=1.5)
    with pytest.raises(ValidationError, match="max_eigenvalue"):
        PI2CMAConfig(min_eigenvalue=0.5, max_eigenvalue=0.1)
    with pytest.raises(ValidationError):
        PI2CMAConfig(unknown=1)  # type: ignore[call-arg]
    with pytest.raises(InputError, match="exactly one"):
        PI2CMA(np.zeros(3))
    with pytest.raises(InputError, match="exactly one"):
        PI2CMA(np.zeros(3), sigma0=1.0, cov=np.eye(3))
    with pytest.raises(InputError, match="sigma0"):
        PI2CMA(np.zeros(3), sigma0=np.ones(4))
    with pytest.raises(InputError, match="sigma0"):
        PI2CMA(np.zeros(3), sigma0=-1.0)
    with pytest.raises(InputError, match="positive definite"):
        PI2CMA(np.zeros(2), cov=np.array([[1.0, 2.0], [2.0, 1.0]]))
    with pytest.raises(InputError, match="mean"):
        PI2CMA(np.array([0.0, np.nan]), sigma0=1.0)
    opt = PI2CMA(np.zeros(3), PI2CMAConfig(n_samples=4), sigma0=1.0)
    x = opt.ask(np.random.default_rng(0))
    with pytest.raises(InputError, match="costs"):
        opt.tell(x, np.zeros(3))
    with pytest.raises(InputError, match="finite"):
        opt.tell(x, np.array([0.0, np.nan, 1.0, 2.0]))
    with pytest.raises(InputError, match="samples"):
        opt.tell(x[:, :2], np.zeros(4))
    with pytest.raises(InputError, match="state"):
        PI2CMA.from_state_dict({"mean": np.zeros(3)}, PI2CMAConfig())
