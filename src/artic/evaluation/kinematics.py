"""Table 3.1 metrics: axis position, axis orientation about z, configuration errors,
and the calibration of predicted intervals.

Errors are per image. For two-DoF objects the position and configuration errors are the
mean over the two joints. The axis orientation about z is the yaw of the axis frame,
which for every category is the object's yaw (`pose_yaw`): the joint frames are the
body's frame rotated about z (docs/formats.md).

`rotation_thesis_deg` is the rotation error as the thesis' evaluation code computes it,
for comparison with Table 3.1's column: the axis quaternion of an object at angle
pi + yaw about z (the thesis generator's objects face the camera at pi) becomes the
angle 2 acos(w) after w is clamped to [0, 1], so every yaw > 0 becomes 180 deg; the
error is the difference of those angles. It is about half the yaw error for a Mean
predictor (docs/reproduction.md, Chapter 3).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

METRICS = ("position_cm", "rotation_deg", "configuration", "rotation_thesis_deg")


def wrap_angle(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles to (-pi, pi]."""
    return np.asarray(np.pi - np.mod(np.pi - a, 2 * np.pi))


def thesis_axis_angle(yaw: NDArray[np.float64]) -> NDArray[np.float64]:
    """The angle the thesis' code reads off the axis quaternion of yaw (radians): pi + yaw
    for yaw <= 0 and pi for yaw > 0 (`2 acos(clamp(w, 0, 1))`, module docstring)."""
    w = np.cos((np.pi + wrap_angle(np.asarray(yaw, dtype=np.float64))) / 2)
    return np.asarray(2 * np.arccos(np.clip(w, 0.0, 1.0)))


def kinematic_errors(
    pred: NDArray[np.float64],
    true: NDArray[np.float64],
    columns: list[str],
    dof: int,
    joint_type: str,
) -> dict[str, NDArray[np.float64]]:
    """Per-image errors of label vectors (N, L): position in cm, rotation about z in
    degrees, configuration in degrees (revolute) or cm (prismatic), and the rotation
    error as the thesis' code computes it (degrees; module docstring)."""
    col = {c: i for i, c in enumerate(columns)}
    position = np.zeros(len(true))
    configuration = np.zeros(len(true))
    for j in range(dof):
        o = [col[f"j{j}_origin_{a}"] for a in "xyz"]
        position += np.linalg.norm(pred[:, o] - true[:, o], axis=1)
        q = col[f"j{j}_q"]
        configuration += np.abs(pred[:, q] - true[:, q])
    yaw = col["pose_yaw"]
    scale = np.degrees(1.0) if joint_type == "revolute" else 100.0
    return {
        "position_cm": 100.0 * position / dof,
        "rotation_deg": np.degrees(np.abs(wrap_angle(pred[:, yaw] - true[:, yaw]))),
        "configuration": scale * configuration / dof,
        "rotation_thesis_deg": np.degrees(
            np.abs(thesis_axis_angle(pred[:, yaw]) - thesis_axis_angle(true[:, yaw]))
        ),
    }


def configuration_unit(joint_type: str) -> str:
    return "deg" if joint_type == "revolute" else "cm"


def coverage(
    lower: NDArray[np.float64], upper: NDArray[np.float64], true: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Per column: the fraction of rows whose true value lies in [lower, upper]."""
    inside = (true >= lower) & (true <= upper)
    return np.asarray(inside.mean(axis=0), dtype=np.float64)
