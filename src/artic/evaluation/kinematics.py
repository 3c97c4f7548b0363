"""Table 3.1 metrics: axis position, axis orientation about z, configuration errors,
and the calibration of predicted intervals.

Errors are per image. For two-DoF objects the position and configuration errors are the
mean over the two joints. The axis orientation about z is the yaw of the axis frame,
which for every category is the object's yaw (`pose_yaw`): the joint frames are the
body's frame rotated about z (docs/formats.md).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

METRICS = ("position_cm", "rotation_deg", "configuration")


def wrap_angle(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles to (-pi, pi]."""
    return np.asarray(np.pi - np.mod(np.pi - a, 2 * np.pi))


def kinematic_errors(
    pred: NDArray[np.float64],
    true: NDArray[np.float64],
    columns: list[str],
    dof: int,
    joint_type: str,
) -> dict[str, NDArray[np.float64]]:
    """Per-image errors of label vectors (N, L): position in cm, rotation about z in
    degrees, configuration in degrees (revolute) or cm (prismatic)."""
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
    }


def configuration_unit(joint_type: str) -> str:
    return "deg" if joint_type == "revolute" else "cm"


def coverage(
    lower: NDArray[np.float64], upper: NDArray[np.float64], true: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Per column: the fraction of rows whose true value lies in [lower, upper]."""
    inside = (true >= lower) & (true <= upper)
    return np.asarray(inside.mean(axis=0), dtype=np.float64)
