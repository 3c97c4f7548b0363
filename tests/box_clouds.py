"""Point clouds on the surfaces of boxes for the Chapter 4 tests: one box (`box_surface`)
and a three-part cabinet (`box_cloud`).

A module (not a conftest fixture) so tests in several folders import one copy.
"""

from __future__ import annotations

import numpy as np

# a cabinet body, a door in front of it, a lid on top: (centre, size), metres
BOXES = (
    ((0.0, 0.0, 0.4), (0.4, 0.5, 0.8)),
    ((-0.215, 0.0, 0.4), (0.02, 0.46, 0.76)),
    ((0.0, 0.0, 0.815), (0.38, 0.48, 0.02)),
)


def box_cloud(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) float32 points on the surfaces of BOXES and (n,) int64 part ids."""
    rng = np.random.default_rng(seed)
    part = rng.integers(0, len(BOXES), n)
    points = np.empty((n, 3))
    for k, (centre, size) in enumerate(BOXES):
        idx = np.flatnonzero(part == k)
        u = rng.uniform(-0.5, 0.5, (len(idx), 3))
        face = rng.integers(0, 3, len(idx))
        u[np.arange(len(idx)), face] = np.sign(u[np.arange(len(idx)), face]) * 0.5
        points[idx] = np.asarray(centre) + u * np.asarray(size)
    return points.astype(np.float32), part.astype(np.int64)


def box_surface(lo: list[float], hi: list[float], n: int, rng: np.random.Generator) -> np.ndarray:
    """n points uniformly on the surface of the axis-aligned box [lo, hi] (metres)."""
    lo_a, hi_a = np.asarray(lo, float), np.asarray(hi, float)
    size = hi_a - lo_a
    areas = np.array([size[1] * size[2], size[0] * size[2], size[0] * size[1]])
    axis = rng.choice(3, size=n, p=areas / areas.sum())
    points = lo_a + rng.random((n, 3)) * size
    side = rng.integers(0, 2, size=n)
    points[np.arange(n), axis] = np.where(side == 1, hi_a[axis], lo_a[axis])
    return points
