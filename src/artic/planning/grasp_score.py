"""optimize_manipulability of Algorithm 3 (thesis section 7.2.1): the score of a joint
configuration theta and the choice among a grasp's IK solutions (the MV setting).

score(theta) = w(theta) P(theta), with Yoshikawa's (1985) manipulability index
w = sqrt(det(J J^T)), J the end-effector Jacobian at theta, computed as the product of
J's singular values (the same number, and >= 0 at a singularity where the determinant
rounds below zero), and Tsai's (1986) joint-limit penalty, Eq. 7.1:

    P(theta) = 1 - exp(-k prod_j (theta_j - l_j^-)(l_j^+ - theta_j) / (l_j^+ - l_j^-)^2)

Each factor of the product lies in [0, 1/4] (maximal mid-range), so P is 0 at any
limit, largest at the middle of every range, 1 - exp(-k / 4^n), and below 1. Pure numpy:
the caller supplies the Jacobians (`artic.sim.robot.point_jacobian`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from artic.config.schemas import Strict

F64 = NDArray[np.float64]


class GraspScoreConfig(Strict):
    """How IK solutions of a grasp are scored (Eq. 7.1)."""

    joint_limit_gain: float = Field(1e5, gt=0, description="k of Eq. 7.1 (thesis: 1e5)")


class ManipulabilityChoice(NamedTuple):
    """The chosen IK solution: its position among the candidates, q (n,), its score,
    and every candidate's score (m,)."""

    position: int
    q: F64
    score: float
    scores: F64


def joint_limit_penalty(q: F64, low: F64, high: F64, k: float) -> F64:
    """P of Eq. 7.1 for configurations q (..., n) within limits low, high (n,): (...,),
    in [0, 1). Outside the limits the product is clipped to 0 (P = 0)."""
    q = np.asarray(q, dtype=np.float64)
    low, high = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    factors = np.clip((q - low) * (high - q) / (high - low) ** 2, 0.0, None)
    return np.asarray(-np.expm1(-k * np.prod(factors, axis=-1)), np.float64)


def manipulability(jacobian: F64) -> F64:
    """w = sqrt(det(J J^T)) for Jacobians (..., 6, n), n >= 6: the product of J's
    singular values, (...,)."""
    singular = np.linalg.svd(np.asarray(jacobian, dtype=np.float64), compute_uv=False)
    return np.asarray(np.prod(singular, axis=-1), np.float64)


def manipulability_score(q: F64, jacobian: F64, low: F64, high: F64, cfg: GraspScoreConfig) -> F64:
    """w P (...,) of configurations q (..., n) with their Jacobians (..., 6, n)."""
    return manipulability(jacobian) * joint_limit_penalty(q, low, high, cfg.joint_limit_gain)


def best_ik_solution(
    solutions: F64, jacobians: F64, low: F64, high: F64, cfg: GraspScoreConfig
) -> ManipulabilityChoice:
    """The IK solution (of solutions (m, n), Jacobians (m, 6, n)) with the largest score
    (line 8 of Algorithm 3); ties to the lowest index."""
    solutions = np.asarray(solutions, dtype=np.float64)
    if solutions.ndim != 2 or len(solutions) == 0:
        raise ValueError(
            f"IK solutions: expected an (m, n) array with m >= 1, got {solutions.shape}"
        )
    scores = manipulability_score(solutions, jacobians, low, high, cfg)
    index = int(np.argmax(scores))
    return ManipulabilityChoice(index, solutions[index], float(scores[index]), scores)
