"""Homogeneous transforms (4x4 float64) and rotations used across artic.

Frames follow the thesis (Appendix A): the camera sits at the origin looking down +x
with +z up, so "world" and "camera body frame" coincide unless a camera pose is given.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def rot_z(angle: float) -> Array:
    """Rotation about +z by `angle` radians: (3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def axis_angle(axis: Array, angle: float) -> Array:
    """Rotation by `angle` radians about the unit vector `axis` (Rodrigues): (3, 3)."""
    x, y, z = (np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)).tolist()
    c, s = math.cos(angle), math.sin(angle)
    v = 1.0 - c
    return np.array(
        [
            [c + x * x * v, x * y * v - z * s, x * z * v + y * s],
            [y * x * v + z * s, c + y * y * v, y * z * v - x * s],
            [z * x * v - y * s, z * y * v + x * s, c + z * z * v],
        ]
    )


def make_transform(rotation: Array | None = None, translation: Array | None = None) -> Array:
    """Compose a (4, 4) homogeneous transform from a (3, 3) rotation and a (3,) translation."""
    t = np.eye(4)
    if rotation is not None:
        t[:3, :3] = rotation
    if translation is not None:
        t[:3, 3] = translation
    return t


def transform_points(transform: Array, points: Array) -> Array:
    """Apply a (4, 4) transform to (N, 3) points; returns (N, 3) float64."""
    p = np.asarray(points, dtype=np.float64)
    return p @ transform[:3, :3].T + transform[:3, 3]


def invert(transform: Array) -> Array:
    """Inverse of a rigid (4, 4) transform."""
    r = transform[:3, :3]
    out = np.eye(4)
    out[:3, :3] = r.T
    out[:3, 3] = -r.T @ transform[:3, 3]
    return out


def yaw_of(rotation: Array) -> float:
    """Angle about +z of a rotation whose z axis is vertical (radians, in (-pi, pi])."""
    return float(np.arctan2(rotation[1, 0], rotation[0, 0]))
