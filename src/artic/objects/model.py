"""In-memory articulated objects: links with triangle meshes, joints, forward kinematics.

This is what `build(spec)` returns and what the URDF writer and the depth renderers
consume. Everything is pure numpy; nothing here reads or writes files.

An object is a kinematic tree of any depth (thesis section 4.4.1): a link's parent is any
earlier link. `links[0]` is the root; joint i's child is `links[i + 1]` for the objects
`artic.objects` builds (depth-first order, which is PyBullet's joint numbering), so a
link's index is its part id. Joints may be revolute, continuous (an unlimited revolute;
`limits` is then only the range poses are drawn from), prismatic or fixed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from artic.geometry.transforms import axis_angle, make_transform

UrdfJointType = Literal["revolute", "prismatic", "fixed", "continuous"]
"""A URDF joint's type; a kinematic tree's edges have `artic.objects.tree.JointType`."""

ROTATING_JOINTS = ("revolute", "continuous")
"""Joint types whose value is an angle (radians)."""


class TriangleMesh(NamedTuple):
    """A triangle mesh in its link's frame.

    vertices: (V, 3) float64, metres. triangles: (F, 3) int32, counter-clockwise seen
    from outside (outward normals). V = F = 0 for a virtual link (no geometry).
    """

    @property
    def is_empty(self) -> bool:
        """True for a mesh without triangles (a virtual link)."""
        return int(self.triangles.shape[0]) == 0

    vertices: NDArray[np.float64]
    triangles: NDArray[np.int32]


@dataclass(frozen=True)
class Inertial:
    """Mass properties of a link, in the link frame: mass (kg), centre of mass (3,),
    inertia tensor (3, 3) about the centre of mass, kg m^2."""

    mass: float
    center_of_mass: NDArray[np.float64]
    inertia: NDArray[np.float64]


@dataclass(frozen=True)
class Link:
    """A rigid part. `role` is its part in the kinematic graph (section 2.3): "body",
    "door", "drawer", "handle" (Appendix A), "slider", "lever" (Chapter 7), or a Chapter 4
    role such as "base", "arm", "head", "column", "seat", "back", "armrest", "caster",
    "wheel" (docs/objects.md).
    `semantic` is a free-text label (PartNet-Mobility's semantics.txt), "" when unset."""

    name: str
    role: str
    mesh: TriangleMesh
    inertial: Inertial
    semantic: str = ""


@dataclass(frozen=True)
class Joint:
    """A joint between `parent` and `child` links (URDF semantics).

    origin: (4, 4) pose of the joint frame (= the child link frame at q = 0) in the
    parent link frame. axis: (3,) unit vector in the joint frame. limits: (lower, upper)
    in radians (revolute, continuous) or metres (prismatic); (0, 0) for fixed joints;
    for a continuous joint only the range configurations are drawn from (not in URDF).
    effort (N m or N) and velocity (rad/s or m/s) limits; damping and friction for the
    simulator.
    """

    name: str
    type: UrdfJointType
    parent: str
    child: str
    origin: NDArray[np.float64]
    axis: NDArray[np.float64] = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    limits: tuple[float, float] = (0.0, 0.0)
    effort: float = 0.0
    velocity: float = 0.0
    damping: float = 0.0
    friction: float = 0.0

    def motion(self, q: float) -> NDArray[np.float64]:
        """(4, 4) transform of the child frame in the joint frame at configuration q."""
        if self.type in ROTATING_JOINTS:
            return make_transform(rotation=axis_angle(self.axis, q))
        if self.type == "prismatic":
            return make_transform(translation=self.axis * q)
        return np.eye(4)

    def child_pose(self, parent_pose: NDArray[np.float64], q: float) -> NDArray[np.float64]:
        """World pose of the child link given its parent's world pose and q."""
        frame = parent_pose @ self.origin
        return frame if self.type == "fixed" else frame @ self.motion(q)


@dataclass(frozen=True)
class ArticulatedObject:
    """A kinematic tree of links. `base_pose` (4, 4) places the root link in the world
    (= camera body) frame. Links are ordered: the root first, then in the order their
    joints appear; a link's position in `links` is its part id (0 = body)."""

    name: str
    links: tuple[Link, ...]
    joints: tuple[Joint, ...]
    base_pose: NDArray[np.float64]

    @property
    def movable_joints(self) -> tuple[Joint, ...]:
        """Revolute and prismatic joints, in order: the object's degrees of freedom."""
        return tuple(j for j in self.joints if j.type != "fixed")

    @property
    def dof(self) -> int:
        return len(self.movable_joints)

    def parent_indices(self) -> list[int]:
        """Parent link index of every link, in `links` order; -1 for the root.

        Raises ValueError unless the joints form a tree over `links` rooted at
        `links[0]` with every parent listed before its child's joint.
        """
        index = {link.name: i for i, link in enumerate(self.links)}
        if len(index) != len(self.links):
            raise ValueError(f"{self.name}: link names are not unique")
        if len(self.joints) != len(self.links) - 1:
            raise ValueError(
                f"{self.name}: {len(self.joints)} joints for {len(self.links)} links; a tree "
                "has one joint fewer than links"
            )
        parents = [-1] * len(self.links)
        reached = {0}
        for joint in self.joints:
            if joint.parent not in index or joint.child not in index:
                raise ValueError(f"{self.name}: joint {joint.name} names an unknown link")
            parent, child = index[joint.parent], index[joint.child]
            if parent not in reached or child in reached:
                raise ValueError(
                    f"{self.name}: joint {joint.name} ({joint.parent} -> {joint.child}) "
                    "does not extend the tree from the root"
                )
            parents[child] = parent
            reached.add(child)
        return parents

    def link_index(self, name: str) -> int:
        for i, link in enumerate(self.links):
            if link.name == name:
                return i
        raise KeyError(name)

    def link_poses(self, configuration: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Forward kinematics: world pose (4, 4) of every link, in `links` order.

        configuration: (dof,) values for `movable_joints`, radians or metres.
        """
        q = np.asarray(configuration, dtype=np.float64).reshape(-1)
        if q.shape[0] != self.dof:
            raise ValueError(f"configuration has {q.shape[0]} values, object has {self.dof} DoF")
        values = iter(q.tolist())
        poses: dict[str, NDArray[np.float64]] = {self.links[0].name: self.base_pose}
        for joint in self.joints:  # parents precede children; movable ones in dof order
            value = 0.0 if joint.type == "fixed" else next(values)
            poses[joint.child] = joint.child_pose(poses[joint.parent], value)
        return [poses[link.name] for link in self.links]

    def joint_frames(self, configuration: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """World pose (4, 4) of each movable joint's frame at `configuration`.

        The joint frame is fixed to the parent link: it depends on the values of the
        joints above it in the tree, never on the joint's own value.
        """
        poses = self.link_poses(configuration)
        by_name = {link.name: pose for link, pose in zip(self.links, poses, strict=True)}
        return [by_name[j.parent] @ j.origin for j in self.movable_joints]
