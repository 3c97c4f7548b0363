"""Kinematic trees (the one record of them), per-object tree ground truth, articulated poses.

A kinematic hierarchy (section 4.4.1) is a directed tree over the parts of an object:
edge A -> B means part B moves with part A; every part carries a motion type
(`MOTION_TYPES`: static, rotating, translating, both) and every edge a `JointType` and,
once estimated, an axis (a point and a unit direction, metres, object frame).
`KinematicTree` is that record (a frozen dataclass, round-trips through JSON) and
`GraphLabelling` the Chapter 4 network's probabilities over one; every package reads
trees from here (the ground floor of the records: this module imports only
`artic.errors` and `artic.objects.model`).

`object_tree(obj)` turns an `ArticulatedObject` into an `ObjectTree`: the parts (link
index = part id, 0 = the root), the directed edges parent -> child (one per URDF joint,
in joint order, so parents come before their children), per edge the joint type, limits
and axis (a point and a unit direction in the world frame, i.e. with `base_pose`
applied, at configuration zero), and per part the motion type of section 4.3 (0 static,
1 rotating, 2 translating, 3 both): a part's motion type is that of the joint to its
parent, the root is static. `generate-dataset dataset=hierarchy` writes it as
`objects/<id>/tree.json`; its keys are a superset of `KinematicTree.to_dict()`, so
`KinematicTree.from_dict` reads it, and `ObjectTree.to_kinematic_tree()` gives it.

`sample_configurations(obj, count, rng)` draws the articulated poses of section 4.5
("uniformly sampling articulated poses within each part's ground truth range of
motion", 18 per object), written as `objects/<id>/poses.json` (`ArticulatedPoses`);
`latin_hypercube(rng, n, limits)` those render-depth draws (one per stratum of each
joint's range). Pure: nothing here reads or writes files.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Literal, cast, get_args

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

from artic.errors import InputError
from artic.objects.model import ROTATING_JOINTS, ArticulatedObject, UrdfJointType

MotionType = Literal["static", "rotating", "translating", "both"]
MOTION_TYPES: tuple[MotionType, ...] = get_args(MotionType)
"""Motion type names of a part (section 4.3); the index is the integer label."""

JointType = Literal["fixed", "revolute", "prismatic"]
"""Joint type of a tree edge (a URDF joint's `continuous` is `revolute` here)."""
JOINT_TYPES: tuple[JointType, ...] = get_args(JointType)

JOINT_TYPE_OF_MOTION: dict[int, JointType] = {
    0: "fixed",
    1: "revolute",
    2: "prismatic",
    3: "revolute",
}
"""Joint type of the edge into a part of each motion type. URDF has no screw joint, so
a part that both rotates and translates (3) gets a revolute joint; its motion type
stays 3 on the node, so nothing is lost for a consumer that models it otherwise."""

TREE_FORMAT: Literal[1] = 1


@dataclass(frozen=True)
class JointAxis:
    """A joint axis: origin (3,) a point on the axis and direction (3,) a unit vector,
    float64, metres, object frame."""

    origin: NDArray[np.float64]
    direction: NDArray[np.float64]

    def to_dict(self) -> dict[str, list[float]]:
        return {
            "origin": [float(v) for v in self.origin],
            "direction": [float(v) for v in self.direction],
        }

    @staticmethod
    def from_dict(data: dict[str, Any]) -> JointAxis:
        origin = np.asarray(data["origin"], dtype=np.float64)
        direction = np.asarray(data["direction"], dtype=np.float64)
        if origin.shape != (3,) or direction.shape != (3,):
            raise ValueError("axis origin and direction must have 3 values each")
        norm = float(np.linalg.norm(direction))
        if not np.isfinite(norm) or norm < 1e-9 or not np.all(np.isfinite(origin)):
            raise ValueError("axis direction must be a finite non-zero vector")
        return JointAxis(origin=origin, direction=direction / norm)


@dataclass(frozen=True)
class KinematicTree:
    """A kinematic hierarchy over parts 0..num_parts-1 (section 4.4.1).

    root: the part every other part hangs from. edges: (parent, child) pairs, ordered so
    that a parent is reached before its children (breadth-first from the root).
    motion_types: (num_parts,) ints indexing MOTION_TYPES. joint_types: one per edge.
    axes: one per edge (None while not estimated, e.g. before `joints.estimate_axes`).
    Constructing an invalid tree raises ValueError.
    """

    num_parts: int
    root: int
    edges: tuple[tuple[int, int], ...]
    motion_types: tuple[int, ...]
    joint_types: tuple[JointType, ...]
    axes: tuple[JointAxis | None, ...] | None = None

    def __post_init__(self) -> None:
        p = self.num_parts
        if p < 1:
            raise ValueError(f"num_parts must be >= 1, got {p}")
        if not 0 <= self.root < p:
            raise ValueError(f"root {self.root} is not a part of 0..{p - 1}")
        if len(self.motion_types) != p:
            raise ValueError(f"motion_types has {len(self.motion_types)} entries, expected {p}")
        if any(not 0 <= m < len(MOTION_TYPES) for m in self.motion_types):
            raise ValueError(f"motion_types must be in 0..{len(MOTION_TYPES) - 1}")
        if len(self.edges) != p - 1:
            raise ValueError(f"a tree over {p} parts has {p - 1} edges, got {len(self.edges)}")
        if len(self.joint_types) != len(self.edges):
            raise ValueError("joint_types must have one entry per edge")
        if any(t not in JOINT_TYPES for t in self.joint_types):
            raise ValueError(f"joint_types must be in {JOINT_TYPES}")
        if self.axes is not None and len(self.axes) != len(self.edges):
            raise ValueError("axes must have one entry per edge")
        reached = {self.root}
        for parent, child in self.edges:
            if not (0 <= parent < p and 0 <= child < p):
                raise ValueError(f"edge ({parent}, {child}) names a part outside 0..{p - 1}")
            if parent not in reached:
                raise ValueError(f"edge ({parent}, {child}): parent not reached from the root yet")
            if child in reached:
                raise ValueError(
                    f"edge ({parent}, {child}): part {child} has two parents or is the root"
                )
            reached.add(child)

    @property
    def parents(self) -> NDArray[np.int64]:
        """(num_parts,) parent of each part, -1 for the root."""
        parent = np.full(self.num_parts, -1, dtype=np.int64)
        for a, b in self.edges:
            parent[b] = a
        return parent

    def children(self, part: int) -> list[int]:
        return [b for a, b in self.edges if a == part]

    def depth_first_edges(self) -> list[tuple[int, int]]:
        """The edges in depth-first pre-order from the root, children in `edges` order:
        the order in which PyBullet numbers the joints of a URDF."""
        ordered: list[tuple[int, int]] = []
        stack = [(self.root, k) for k in reversed(self.children(self.root))]
        while stack:
            parent, child = stack.pop()
            ordered.append((parent, child))
            stack.extend((child, k) for k in reversed(self.children(child)))
        return ordered

    def edge_index(self, parent: int, child: int) -> int:
        """Position of the edge (parent, child) in `edges`; KeyError when absent."""
        for i, edge in enumerate(self.edges):
            if edge == (parent, child):
                return i
        raise KeyError((parent, child))

    def with_axes(self, axes: tuple[JointAxis | None, ...]) -> KinematicTree:
        return KinematicTree(
            self.num_parts, self.root, self.edges, self.motion_types, self.joint_types, axes
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "num_parts": self.num_parts,
            "root": self.root,
            "edges": [list(e) for e in self.edges],
            "motion_types": [MOTION_TYPES[m] for m in self.motion_types],
            "joint_types": list(self.joint_types),
            "axes": None
            if self.axes is None
            else [None if a is None else a.to_dict() for a in self.axes],
        }

    @staticmethod
    def from_dict(data: dict[str, Any]) -> KinematicTree:
        """Inverse of `to_dict`; raises InputError naming the field on malformed data."""
        try:
            axes_data = data.get("axes")
            axes = (
                None
                if axes_data is None
                else tuple(None if a is None else JointAxis.from_dict(a) for a in axes_data)
            )
            motion = tuple(
                MOTION_TYPES.index(m) if isinstance(m, str) else int(m)
                for m in data["motion_types"]
            )
            return KinematicTree(
                num_parts=int(data["num_parts"]),
                root=int(data["root"]),
                edges=tuple((int(a), int(b)) for a, b in data["edges"]),
                motion_types=motion,
                joint_types=tuple(cast(JointType, str(t)) for t in data["joint_types"]),
                axes=axes,
            )
        except KeyError as error:
            raise InputError(f"kinematic tree: missing field {error}") from None
        except (ValueError, TypeError) as error:
            raise InputError(f"kinematic tree: {error}") from None

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @staticmethod
    def from_json(text: str) -> KinematicTree:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as error:
            raise InputError(f"kinematic tree: not valid JSON ({error.msg})") from None
        if not isinstance(data, dict):
            raise InputError("kinematic tree: expected a JSON object")
        return KinematicTree.from_dict(data)


@dataclass(frozen=True)
class GraphLabelling:
    """The network's probabilities on one part graph (section 4.4.2).

    edges: (E, 2) int64, the candidate edges. motion: (P, 4) float64, motion-type
    probabilities. exists: (E,) p(edge exists). parent_first: (E,) p(edges[e, 0] is the
    parent | edge exists). root: (P,) p(part is the root), sums to one.
    """

    edges: NDArray[np.int64]
    motion: NDArray[np.float64]
    exists: NDArray[np.float64]
    parent_first: NDArray[np.float64]
    root: NDArray[np.float64]

    @property
    def num_parts(self) -> int:
        return int(self.motion.shape[0])


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
    joint_types: tuple[JointType, ...] = Field(description="per edge; continuous -> revolute")
    urdf_joint_types: tuple[UrdfJointType, ...] = Field(description="per edge, as in the URDF")
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
        """The same tree as a `KinematicTree` (axes included)."""
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


def latin_hypercube(
    rng: np.random.Generator, n: int, limits: list[tuple[float, float]]
) -> NDArray[np.float64]:
    """(n, dof) configurations, one per stratum of each joint's range, strata paired at
    random across joints (Latin hypercube)."""
    lo = np.array([a for a, _ in limits])
    hi = np.array([b for _, b in limits])
    u = np.stack([(rng.permutation(n) + rng.random(n)) / n for _ in limits], axis=1)
    return lo + u * (hi - lo)
