"""Per-object kinematic-tree ground truth for Chapter 4, and articulated-pose augmentation.

`object_tree(obj)` turns an `ArticulatedObject` into an `ObjectTree`: the parts (link
index = part id, 0 = the root), the directed edges parent -> child (one per URDF joint,
in joint order, so parents come before their children), per edge the joint type, limits
and axis (a point and a unit direction in the world frame, i.e. with `base_pose`
applied, at configuration zero), and per part the motion type of section 4.3 (0 static,
1 rotating, 2 translating, 3 both): a part's motion type is that of the joint to its
parent, the root is static. `generate-dataset dataset=hierarchy` writes it as
`objects/<id>/tree.json`; its keys are a superset of
`artic.hierarchy.types.KinematicTree.to_dict()`, so `KinematicTree.from_dict` reads it.

`sample_configurations(obj, count, rng)` draws the articulated poses of section 4.5
("uniformly sampling articulated poses within each part's ground truth range of
motion", 18 per object), written as `objects/<id>/poses.json` (`ArticulatedPoses`).
Pure: nothing here reads or writes files.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

from artic.objects.model import ROTATING_JOINTS, ArticulatedObject, JointType

if TYPE_CHECKING:
    from artic.hierarchy.types import KinematicTree

MOTION_TYPES = ("static", "rotating", "translating", "both")
"""Motion type names (section 4.3); the index is the integer label."""

MotionType = Literal["static", "rotating", "translating", "both"]
TreeJointType = Literal["fixed", "revolute", "prismatic"]
TREE_FORMAT: Literal[1] = 1


def motion_type_of(joint_type: str) -> int:
    """Motion type label (0 static, 1 rotating, 2 translating) of a part hung on a URDF
    joint of `joint_type`; URDF has no screw joint, so 3 (both) never comes from one."""
    if joint_type in ROTATING_JOINTS:
        return 1
    return 2 if joint_type == "prismatic" else 0


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class PartInfo(_Frozen):
    """One part: its URDF link name, its role and a semantic label."""

    name: str = Field(description="URDF link name")
    role: str = Field(description="role in the object (body, door, drawer, handle, arm, ...)")
    semantic: str = Field(description="semantic label (PartNet-Mobility semantics.txt or the role)")


class AxisRecord(_Frozen):
    """A joint axis in the world frame at configuration zero: a point and a unit direction."""

    origin: tuple[float, float, float] = Field(description="a point on the axis, metres")
    direction: tuple[float, float, float] = Field(description="unit direction")


class ObjectTree(_Frozen):
    """Kinematic-tree ground truth of one object (tree.json); see the module docstring."""

    format: Literal[1] = Field(TREE_FORMAT, description="tree.json format version")
    num_parts: int = Field(ge=1, description="P: number of parts = URDF links")
    root: int = Field(0, ge=0, description="the root part (always 0 here)")
    parts: tuple[PartInfo, ...] = Field(description="per part, in link order")
    edges: tuple[tuple[int, int], ...] = Field(description="(parent, child) per joint")
    joint_names: tuple[str, ...] = Field(description="URDF joint name per edge")
    joint_types: tuple[TreeJointType, ...] = Field(description="per edge; continuous -> revolute")
    urdf_joint_types: tuple[JointType, ...] = Field(description="per edge, as in the URDF")
    limits: tuple[tuple[float, float], ...] = Field(description="per edge (lower, upper)")
    axes: tuple[AxisRecord | None, ...] = Field(description="per edge; None for fixed joints")
    motion_types: tuple[MotionType, ...] = Field(description="per part")
    motion_type_ids: tuple[int, ...] = Field(description="per part, index into MOTION_TYPES")
    movable_edges: tuple[int, ...] = Field(description="edge of each degree of freedom")
    base_pose: tuple[tuple[float, float, float, float], ...] = Field(
        description="(4, 4) world pose of the root link"
    )

    @model_validator(mode="after")
    def _valid_tree(self) -> ObjectTree:
        p, e = self.num_parts, len(self.edges)
        if len(self.parts) != p or len(self.motion_types) != p or len(self.motion_type_ids) != p:
            raise ValueError(f"parts, motion_types and motion_type_ids need {p} entries")
        if e != p - 1:
            raise ValueError(f"a tree over {p} parts has {p - 1} edges, got {e}")
        per_edge = (self.joint_names, self.joint_types, self.urdf_joint_types, self.limits)
        if any(len(x) != e for x in (*per_edge, self.axes)):
            raise ValueError(
                "joint_names, joint_types, urdf_joint_types, limits, axes: one per edge"
            )
        if self.root != 0 or len(self.base_pose) != 4:
            raise ValueError("root must be 0 and base_pose 4 x 4")
        reached = {self.root}
        for parent, child in self.edges:
            if parent not in reached or child in reached or not 0 <= child < p:
                raise ValueError(f"edge ({parent}, {child}) does not extend the tree from the root")
            reached.add(child)
        if [MOTION_TYPES[m] for m in self.motion_type_ids] != list(self.motion_types):
            raise ValueError("motion_type_ids disagree with motion_types")
        movable = [i for i, t in enumerate(self.joint_types) if t != "fixed"]
        if list(self.movable_edges) != movable:
            raise ValueError("movable_edges must list the non-fixed edges in order")
        return self

    @property
    def dof(self) -> int:
        return len(self.movable_edges)

    def parents(self) -> NDArray[np.int64]:
        """(P,) parent part of each part, -1 for the root."""
        parent = np.full(self.num_parts, -1, dtype=np.int64)
        for a, b in self.edges:
            parent[b] = a
        return parent

    def part_motion_types(self) -> NDArray[np.int64]:
        """(P,) motion type label per part; index it with per-point part ids."""
        return np.asarray(self.motion_type_ids, dtype=np.int64)

    def to_kinematic_tree(self) -> KinematicTree:
        """The same tree as the Chapter 4 library's record (axes included)."""
        from artic.hierarchy.types import JointAxis, KinematicTree

        axes = tuple(
            None if a is None else JointAxis(np.array(a.origin), np.array(a.direction))
            for a in self.axes
        )
        return KinematicTree(
            self.num_parts, self.root, self.edges, self.motion_type_ids, self.joint_types, axes
        )


class ArticulatedPoses(_Frozen):
    """Articulated-pose augmentation of one object (poses.json): `configurations[i]`
    holds the values of `joint_names` (the movable joints, in order), rad or m."""

    joint_names: tuple[str, ...] = Field(description="movable joints, configuration order")
    configurations: tuple[tuple[float, ...], ...] = Field(min_length=1)

    @model_validator(mode="after")
    def _widths(self) -> ArticulatedPoses:
        if any(len(q) != len(self.joint_names) for q in self.configurations):
            raise ValueError(f"every configuration needs {len(self.joint_names)} values")
        return self

    def array(self) -> NDArray[np.float64]:
        """(count, dof) float64."""
        return np.array(self.configurations, dtype=np.float64).reshape(
            len(self.configurations), len(self.joint_names)
        )


def _clean(values: NDArray[np.float64]) -> tuple[float, ...]:
    return tuple(float(v) + 0.0 for v in values)


def object_tree(obj: ArticulatedObject, semantics: dict[str, str] | None = None) -> ObjectTree:
    """The kinematic-tree ground truth of `obj` (module docstring).

    semantics: optional link name -> label (PartNet-Mobility); else `link.semantic`,
    else the role. Raises ValueError unless `obj`'s joints form a tree from links[0].
    """
    obj.parent_indices()
    index = {link.name: i for i, link in enumerate(obj.links)}
    labels = semantics or {}
    poses = obj.link_poses(np.zeros(obj.dof))
    motion = [0] * len(obj.links)
    edges: list[tuple[int, int]] = []
    axes: list[AxisRecord | None] = []
    types: list[str] = []
    for joint in obj.joints:
        child = index[joint.child]
        edges.append((index[joint.parent], child))
        motion[child] = motion_type_of(joint.type)
        types.append("revolute" if joint.type == "continuous" else joint.type)
        if joint.type == "fixed":
            axes.append(None)
            continue
        frame = poses[index[joint.parent]] @ joint.origin
        direction = frame[:3, :3] @ joint.axis
        direction = direction / np.linalg.norm(direction)
        axes.append(AxisRecord(origin=_clean(frame[:3, 3]), direction=_clean(direction)))
    return ObjectTree.model_validate(
        {
            "num_parts": len(obj.links),
            "parts": [
                {
                    "name": link.name,
                    "role": link.role,
                    "semantic": labels.get(link.name) or link.semantic or link.role,
                }
                for link in obj.links
            ],
            "edges": edges,
            "joint_names": [j.name for j in obj.joints],
            "joint_types": types,
            "urdf_joint_types": [j.type for j in obj.joints],
            "limits": [tuple(float(v) for v in j.limits) for j in obj.joints],
            "axes": axes,
            "motion_types": [MOTION_TYPES[m] for m in motion],
            "motion_type_ids": motion,
            "movable_edges": [i for i, j in enumerate(obj.joints) if j.type != "fixed"],
            "base_pose": [_clean(row) for row in obj.base_pose],
        }
    )


def sample_configurations(
    obj: ArticulatedObject, count: int, rng: np.random.Generator
) -> ArticulatedPoses:
    """`count` configurations, each joint uniform within its limits (section 4.5).

    Returns ArticulatedPoses whose array() is (count, dof); a 0-DoF object gets `count`
    empty configurations. Raises ValueError on count < 1 or non-finite limits.
    """
    if count < 1:
        raise ValueError(f"count must be >= 1, got {count}")
    joints = obj.movable_joints
    lower = np.array([j.limits[0] for j in joints], dtype=np.float64)
    upper = np.array([j.limits[1] for j in joints], dtype=np.float64)
    if not all(math.isfinite(v) for v in (*lower, *upper)) or np.any(lower > upper):
        raise ValueError(f"{obj.name}: joint limits must be finite with lower <= upper")
    values = rng.uniform(lower, upper, size=(count, len(joints)))
    return ArticulatedPoses(
        joint_names=tuple(j.name for j in joints),
        configurations=tuple(_clean(row) for row in values),
    )
