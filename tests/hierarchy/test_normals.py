"""Normals by local PCA: face normals of a box, rotation equivariance, the sign rules,
determinism and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from artic.errors import InputError
from artic.hierarchy.normals import estimate_normals

SIZE = np.array([0.8, 0.5, 1.2])  # box extents, metres


def _box_surface(n: int, seed: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """`n` points uniform on the surface of a box centred at the origin and each point's
    outward face normal."""
    rng = np.random.default_rng(seed)
    half = SIZE / 2
    areas = np.array([SIZE[1] * SIZE[2], SIZE[0] * SIZE[2], SIZE[0] * SIZE[1]]).repeat(2)
    face = rng.choice(6, size=n, p=areas / areas.sum())
    points = rng.uniform(-half, half, size=(n, 3))
    axis, sign = face // 2, np.where(face % 2 == 0, -1.0, 1.0)
    points[np.arange(n), axis] = sign * half[axis]
    normals = np.zeros((n, 3))
    normals[np.arange(n), axis] = sign
    return points, normals


def _away_from_edges(points: NDArray[np.float64], margin: float) -> NDArray[np.bool_]:
    """Points at least `margin` inside their face (farther from every edge)."""
    inside = np.abs(points) <= SIZE / 2 - margin
    return inside.sum(axis=1) == 2  # the face's two free coordinates


def test_normals_of_a_box_are_its_outward_face_normals() -> None:
    points, faces = _box_surface(6000, 0)
    normals = estimate_normals(points, k=16)
    assert normals.shape == points.shape and normals.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)
    interior = _away_from_edges(points, 0.1)
    assert interior.sum() > 3000
    # a flat patch: exactly the face normal; away from the centroid = outward on a box
    np.testing.assert_allclose(normals[interior], faces[interior], atol=1e-5)


def test_rotating_and_moving_the_cloud_rotates_the_normals() -> None:
    points, _ = _box_surface(3000, 1)
    points = points + np.random.default_rng(2).normal(scale=0.003, size=points.shape)  # noisy
    rotation = Rotation.from_rotvec([0.3, -0.8, 1.1]).as_matrix()
    moved = points @ rotation.T + np.array([1.5, -0.2, 0.7])
    np.testing.assert_allclose(
        estimate_normals(moved), estimate_normals(points) @ rotation.T.astype(np.float32), atol=1e-4
    )


def test_viewpoint_rule_points_toward_the_sensor() -> None:
    points, faces = _box_surface(6000, 3)
    sensor = np.array([3.0, 0.0, 0.0])
    normals = estimate_normals(points, viewpoint=sensor)
    assert (np.einsum("ni,ni->n", normals.astype(np.float64), sensor - points) >= 0).all()
    # the face toward the sensor (+x) keeps its outward normal, the far one (-x) flips
    interior = _away_from_edges(points, 0.1)
    near = interior & (faces[:, 0] == 1)
    far = interior & (faces[:, 0] == -1)
    np.testing.assert_allclose(normals[near], faces[near], atol=1e-5)
    np.testing.assert_allclose(normals[far], -faces[far], atol=1e-5)


def test_same_points_same_bytes() -> None:
    points, _ = _box_surface(2000, 4)
    assert estimate_normals(points).tobytes() == estimate_normals(points.copy()).tobytes()


def test_tiny_clouds_and_bad_input() -> None:
    tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    normals = estimate_normals(tri, k=16)  # k capped at N
    np.testing.assert_allclose(np.abs(normals[:, 2]), 1.0, atol=1e-6)
    with pytest.raises(InputError, match="at least 3 points"):
        estimate_normals(tri[:2])
    with pytest.raises(InputError, match=r"\(N, 3\)"):
        estimate_normals(np.zeros((5, 2)))
    with pytest.raises(InputError, match="NaN"):
        estimate_normals(np.vstack([tri, [np.nan, 0.0, 0.0]]))
    with pytest.raises(InputError, match="k must be"):
        estimate_normals(tri, k=2)
