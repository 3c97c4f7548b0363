"""Per-image labels of the kinematic model (thesis section 3.2.1 and section 2.3).

For one rendered configuration the label vector holds the geometry theta (base pose,
depth, width, height, chirality), and per degree of freedom j its configuration q_j
and kinematic parameters phi_j: a point on the joint axis, the axis' unit direction,
and the moving part's origin in the axis frame. Everything is in the camera (= world)
frame: metres, radians. Column definitions are in `docs/objects.md`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from artic.objects.model import ArticulatedObject
from artic.objects.spec import ObjectSpec

GEOMETRY_COLUMNS = (
    "pose_x",
    "pose_y",
    "pose_z",
    "pose_yaw",
    "depth",
    "width",
    "height",
    "chirality",
)
_JOINT_FIELDS = (
    "q",
    "origin_x",
    "origin_y",
    "origin_z",
    "direction_x",
    "direction_y",
    "direction_z",
    "part_x",
    "part_y",
    "part_z",
)


def label_columns(dof: int) -> list[str]:
    """Names of the label vector of an object with `dof` movable joints, in order:
    the 8 geometry columns, then `j<j>_<field>` (10 fields) for each joint j."""
    if dof < 0:
        raise ValueError(f"dof must be >= 0, got {dof}")
    return [*GEOMETRY_COLUMNS] + [f"j{j}_{f}" for j in range(dof) for f in _JOINT_FIELDS]


def part_origin(obj: ArticulatedObject, joint_index: int) -> NDArray[np.float64]:
    """(3,) centre of the moving part's bounding box at q = 0, in its joint frame (metres).

    The child link frame equals the joint frame at q = 0, so this is the centre of the
    link mesh's axis-aligned bounding box; the handle (a separate link) is not included.
    """
    joint = obj.movable_joints[joint_index]
    vertices = obj.links[obj.link_index(joint.child)].mesh.vertices
    return 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))


def image_labels(
    spec: ObjectSpec, obj: ArticulatedObject, configuration: NDArray[np.float64]
) -> dict[str, float]:
    """Labels (theta, q, phi) of `obj` at `configuration`, keys in `label_columns` order.

    configuration: (dof,) radians or metres. `j<j>_origin_*`: the joint frame's origin,
    a point on the axis, camera frame. `j<j>_direction_*`: unit axis direction, camera
    frame. `j<j>_part_*`: `part_origin` (joint frame, so independent of pose and q).
    """
    if spec.dof != obj.dof:
        raise ValueError(f"dof: spec has {spec.dof}, object has {obj.dof}")
    q = np.asarray(configuration, dtype=np.float64).reshape(-1)
    if q.shape[0] != obj.dof or not np.all(np.isfinite(q)):
        raise ValueError(f"configuration: expected {obj.dof} finite values, got {q.tolist()}")
    values = [spec.pose.x, spec.pose.y, spec.pose.z, spec.pose.yaw]
    values += [spec.depth, spec.width, spec.height, float(spec.chirality)]
    frames = obj.joint_frames(q)
    for j, (joint, frame) in enumerate(zip(obj.movable_joints, frames, strict=True)):
        direction = frame[:3, :3] @ joint.axis
        values += [q[j], *frame[:3, 3], *(direction / np.linalg.norm(direction))]
        values += list(part_origin(obj, j))
    columns = label_columns(obj.dof)
    return {name: float(v) for name, v in zip(columns, values, strict=True)}


def joint_column(j: int, field: str) -> str:
    """The label column of joint j's `field` (one of the joint fields: "q", "origin_x",
    ...): `j<j>_<field>`."""
    return f"j{j}_{field}"


def joint_vector(j: int, name: str) -> list[str]:
    """The three label columns of joint j's vector `name` ("origin", "direction",
    "part"): `j<j>_<name>_x`, `_y`, `_z`."""
    return [f"j{j}_{name}_{a}" for a in "xyz"]
