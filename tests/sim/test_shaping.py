"""Potential-based shaping of the CIP reward (section 7.3): Phi = q_O / q_O*."""

from __future__ import annotations

import numpy as np
import pytest

from artic.sim.shaping import potential, shaped_rewards, shaping_terms


def test_with_gamma_one_the_shaping_telescopes():
    rng = np.random.default_rng(0)
    for _ in range(20):
        q_object = np.cumsum(rng.normal(scale=0.02, size=251))  # an episode of 250 steps
        phi = potential(q_object, goal=0.3)
        assert shaping_terms(phi, 1.0).sum() == pytest.approx(phi[-1] - phi[0], abs=1e-12)
        sparse = (q_object[1:] >= 0.3).astype(float)
        total = shaped_rewards(sparse, phi, 1.0).sum()
        assert total == pytest.approx(sparse.sum() + phi[-1] - phi[0], abs=1e-12)


def test_with_gamma_below_one_the_discounted_sum_telescopes():
    rng = np.random.default_rng(1)
    phi, gamma = rng.uniform(size=31), 0.99
    discounted = np.sum(gamma ** np.arange(30) * shaping_terms(phi, gamma))
    assert discounted == pytest.approx(gamma**30 * phi[-1] - phi[0], abs=1e-12)


def test_potential_is_one_at_the_goal_and_zero_at_rest():
    assert potential(0.3, 0.3) == pytest.approx(1.0)
    assert potential(np.zeros(3), 1.57).tolist() == [0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="goal"):
        potential(0.1, 0.0)


def test_rewards_and_potentials_must_match():
    with pytest.raises(ValueError, match="3 rewards need 4 potentials"):
        shaped_rewards(np.zeros(3), np.zeros(3), 1.0)
