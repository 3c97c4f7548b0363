"""Point clouds on the surfaces of boxes: a three-part cabinet for the Chapter 4 tests.

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
