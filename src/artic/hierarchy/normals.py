"""Surface normals of a point cloud, as per-point input features of the segmenter.

`estimate_normals`: local PCA (the normal of a surface patch is the direction of least
variance of its points, Hoppe et al. 1992) over each point's k nearest neighbours
(`scipy.spatial.cKDTree`), then a sign rule:

- default: away from the cloud's centroid (`dot(n, p - centroid) >= 0`). It needs nothing
  but the points, is invariant to translation and equivariant under every rotation (the
  centroid moves with the cloud), so rotating a training cloud about z rotates its normals;
  on a closed convex shape it is the outward normal. It can point inward on concave parts
  (the inside of an open drawer), consistently so for the same geometry.
- with `viewpoint` (the sensor position, when known): toward the sensor (`dot(n, v - p)
  >= 0`), the usual rule for single-view scans.

Deterministic: the same points in the same order give the same bytes.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from artic.errors import InputError


def estimate_normals(
    points: ArrayLike, k: int = 16, viewpoint: ArrayLike | None = None
) -> NDArray[np.float32]:
    """Unit normals of `points` (N, 3) by PCA over each point's `k` nearest neighbours
    (itself included), oriented away from the centroid, or toward `viewpoint` (3,) when
    given (module docstring).

    -> (N, 3) float32. A point whose neighbourhood is degenerate (all neighbours at one
    place) gets an arbitrary but deterministic unit vector. InputError for fewer than 3
    points, non-finite points or k < 3.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"normals: points must be (N, 3), got shape {pts.shape}")
    if len(pts) < 3:
        raise InputError(f"normals: need at least 3 points, got {len(pts)}")
    if not np.isfinite(pts).all():
        raise InputError("normals: points contain NaN or infinite coordinates")
    if k < 3:
        raise InputError(f"normals: k must be at least 3, got {k}")
    k = min(k, len(pts))
    _, neighbours = cKDTree(pts).query(pts, k=k)  # (N, k), nearest first
    patches = pts[neighbours]  # (N, k, 3)
    centred = patches - patches.mean(axis=1, keepdims=True)
    covariance = np.einsum("nki,nkj->nij", centred, centred) / k
    _, vectors = np.linalg.eigh(covariance)  # eigenvalues ascending
    normals = vectors[:, :, 0]  # least variance
    if viewpoint is None:
        outward = pts - pts.mean(axis=0)
    else:
        view = np.asarray(viewpoint, dtype=np.float64).reshape(3)
        outward = view - pts
    flip = np.einsum("ni,ni->n", normals, outward) < 0
    normals[flip] *= -1.0
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return normals.astype(np.float32)
