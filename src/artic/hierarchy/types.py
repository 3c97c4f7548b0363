"""Records of Chapter 4's graph stage: kinematic trees, part graphs, graph labellings.

A kinematic hierarchy (section 4.4.1) is a directed tree over the parts of an object:
edge A -> B means part B moves with part A; every part carries a motion type (static,
rotating, translating, both) and every edge a URDF joint type and, once estimated, an
axis (a point and a unit direction, metres, object frame). Records are frozen
dataclasses; `KinematicTree` round-trips through JSON. Pure numpy, no file access.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Literal, cast

import numpy as np
from numpy.typing import NDArray

from artic.errors import InputError

MOTION_TYPES = ("static", "rotating", "translating", "both")
"""Motion type labels of a part (section 4.3): index = the integer label."""

JointType = Literal["fixed", "revolute", "prismatic"]
JOINT_TYPES: tuple[JointType, ...] = ("fixed", "revolute", "prismatic")

JOINT_TYPE_OF_MOTION: dict[int, JointType] = {
    0: "fixed",
    1: "revolute",
    2: "prismatic",
    3: "revolute",
}
"""Joint type of the edge into a part of each motion type. URDF has no screw joint, so
a part that both rotates and translates (3) gets a revolute joint; its motion type
stays 3 on the node, so nothing is lost for a consumer that models it otherwise."""


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
class PartGraph:
    """The overcomplete part graph of a segmented point cloud (section 4.4.1).

    node_points: (P, K, 3) float32, each part's points resampled to K and normalised
    (object centre subtracted, divided by `scale`). node_features: (P, 7) float32,
    normalised centroid (3), normalised bounding-box extent (3), fraction of the points.
    edges: (E, 2) int64 candidate undirected edges, first < second, sorted.
    edge_features: (E, 10) float32, oriented from edges[:, 0] to edges[:, 1] (see
    `graph.EDGE_FEATURES`). min_distance: (E,) float64 metres. centroids: (P, 3)
    float64 metres. point_counts: (P,) int64. center: (3,) metres; scale: metres.
    """

    node_points: NDArray[np.float32]
    node_features: NDArray[np.float32]
    edges: NDArray[np.int64]
    edge_features: NDArray[np.float32]
    min_distance: NDArray[np.float64]
    centroids: NDArray[np.float64]
    point_counts: NDArray[np.int64]
    center: NDArray[np.float64]
    scale: float

    @property
    def num_parts(self) -> int:
        return int(self.node_points.shape[0])

    @property
    def num_edges(self) -> int:
        return int(self.edges.shape[0])


@dataclass(frozen=True)
class GraphLabels:
    """Training targets of a part graph from its ground-truth tree (section 4.4.2).

    motion_type: (P,) int64. exists: (E,) bool, candidate edge is a tree edge.
    parent_first: (E,) bool, edges[e, 0] is the parent (meaningful where exists).
    root: the root part. uncovered: tree edges missing from the candidate graph (the
    threshold was too small for them); the network cannot predict those.
    """

    motion_type: NDArray[np.int64]
    exists: NDArray[np.bool_]
    parent_first: NDArray[np.bool_]
    root: int
    uncovered: tuple[tuple[int, int], ...]


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
