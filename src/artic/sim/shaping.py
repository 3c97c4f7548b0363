"""Potential-based reward shaping of the CIP tasks (thesis section 7.3; Ng et al. 1999):

    r'(s, a, s') = r + gamma Phi(s') - Phi(s),   Phi(s) = q_O / q_O*

q_O the object's joint position and q_O* the success threshold of beta_c, so Phi = 1
where the task succeeds. Shaping of this form leaves the optimal policy of the sparse
success reward unchanged; with gamma = 1 the shaping terms of an episode telescope to
Phi(s_T) - Phi(s_0). Pure numpy.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def potential(q_object: float | F64, goal: float) -> F64:
    """Phi = q_O / q_O* (any shape); goal q_O* (rad or m) must be nonzero."""
    if goal == 0.0:
        raise ValueError("the potential's goal q_O* must be nonzero")
    return np.asarray(q_object, dtype=np.float64) / goal


def shaping_terms(potentials: F64, gamma: float) -> F64:
    """gamma Phi(s_{t+1}) - Phi(s_t) (T,) of an episode's potentials Phi(s_0..s_T) (T+1,)."""
    phi = np.asarray(potentials, dtype=np.float64)
    return np.asarray(gamma * phi[1:] - phi[:-1], np.float64)


def shaped_rewards(rewards: F64, potentials: F64, gamma: float) -> F64:
    """r_t + gamma Phi(s_{t+1}) - Phi(s_t) (T,) for rewards (T,) and potentials (T+1,)."""
    rewards = np.asarray(rewards, dtype=np.float64)
    if np.shape(potentials) != (len(rewards) + 1,):
        raise ValueError(
            f"shaping: {len(rewards)} rewards need {len(rewards) + 1} potentials, "
            f"got shape {np.shape(potentials)}"
        )
    return rewards + shaping_terms(potentials, gamma)
