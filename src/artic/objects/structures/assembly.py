"""Assemble a kinematic tree of any depth from box-built parts (section 4.4.1).

A builder lists `PartNode`s, each naming its parent node; `assemble_tree` orders them
depth-first from the root (children in the order listed: PyBullet's joint numbering),
meshes each part (`parts.union_mesh`, watertight), computes its mass properties and
writes one joint per non-root part. Link frames keep the object frame's orientation at
configuration zero (URDF rpy = 0): a node's `origin` is its joint frame's position in
its parent's link frame, and its boxes are in its own link frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from artic.geometry.transforms import make_transform
from artic.objects.model import ArticulatedObject, Joint, Link, UrdfJointType
from artic.objects.parts import Box, MovingPart, handle_boxes, lazy_mass_properties, union_mesh
from artic.objects.spec import PartsConfig


class PartNode(NamedTuple):
    """One part of a tree under construction.

    parent: index of the parent node in the builder's list (-1 for the root, which must
    come first). joint_type: the joint to the parent ("fixed" for rigidly attached parts;
    ignored for the root). origin: (3,) joint-frame position in the parent's link frame,
    metres. axis: (3,) unit joint axis. limits: (lower, upper) rad or m, (0, 0) if fixed.
    boxes: the part's solid in its link frame (metres). density: kg/m^3.
    """

    name: str
    role: str
    boxes: tuple[Box, ...]
    density: float
    parent: int = -1
    joint_type: UrdfJointType = "fixed"
    origin: NDArray[np.float64] = np.zeros(3)
    axis: NDArray[np.float64] = np.array([0.0, 0.0, 1.0])
    limits: tuple[float, float] = (0.0, 0.0)


def depth_first(nodes: Sequence[PartNode]) -> list[int]:
    """Node indices in depth-first pre-order from node 0, children in list order.

    Raises ValueError unless node 0 is the only root and every node is reached.
    """
    if not nodes or nodes[0].parent != -1:
        raise ValueError("the first node must be the root (parent -1)")
    children: dict[int, list[int]] = {i: [] for i in range(len(nodes))}
    for i, node in enumerate(nodes[1:], start=1):
        if not 0 <= node.parent < len(nodes) or node.parent == i:
            raise ValueError(f"part {node.name}: parent {node.parent} is not another node")
        children[node.parent].append(i)
    order: list[int] = []
    stack = [0]
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(children[i]))
    if len(order) != len(nodes):
        raise ValueError("the parts do not form one tree from the root")
    return order


def assemble_tree(
    name: str,
    nodes: Sequence[PartNode],
    parts: PartsConfig,
    base_pose: NDArray[np.float64] | None = None,
) -> ArticulatedObject:
    """An ArticulatedObject of `nodes` in depth-first order (links[i + 1] = joints[i].child).

    Movable joints are named `joint_<k>` in degree-of-freedom order, fixed ones
    `<child>_fixed`; damping, friction, effort and velocity come from `parts`.
    base_pose: (4, 4), identity by default (the object frame is the world frame).
    """
    order = depth_first(nodes)
    links, joints = [], []
    dof = 0
    for i in order:
        node = nodes[i]
        mesh = union_mesh(node.boxes)
        links.append(
            Link(
                name=node.name,
                role=node.role,
                mesh=mesh,
                inertial=lazy_mass_properties(mesh, node.density),
            )
        )
        if node.parent < 0:
            continue
        parent = nodes[node.parent].name
        transform = make_transform(translation=np.asarray(node.origin, dtype=np.float64))
        if node.joint_type == "fixed":
            joints.append(
                Joint(
                    name=f"{node.name}_fixed",
                    type="fixed",
                    parent=parent,
                    child=node.name,
                    origin=transform,
                )
            )
            continue
        joints.append(
            Joint(
                name=f"joint_{dof}",
                type=node.joint_type,
                parent=parent,
                child=node.name,
                origin=transform,
                axis=np.asarray(node.axis, dtype=np.float64),
                limits=node.limits,
                damping=parts.joint_damping,
                friction=parts.joint_friction,
                effort=parts.joint_effort,
                velocity=parts.joint_velocity,
            )
        )
        dof += 1
    pose = np.eye(4) if base_pose is None else np.asarray(base_pose, dtype=np.float64)
    return ArticulatedObject(name=name, links=tuple(links), joints=tuple(joints), base_pose=pose)


def moving_part_node(
    part: MovingPart, parent: int, parts: PartsConfig, limits: tuple[float, float]
) -> PartNode:
    """A door or drawer (`parts.vertical_door` / `parts.drawer`) hung on node `parent`,
    its handle part of the same link (as PartNet-Mobility's links: one rigid body per
    moving part; the handle's boxes moved to its mount, with the part's density). The
    part's origin is in the parent's link frame."""
    density = parts.drawer_density if part.role == "drawer" else parts.door_density
    mount = np.asarray(part.handle.position, dtype=np.float64)
    handle = tuple(
        Box(*((lo + m, hi + m) for (lo, hi), m in zip(box, mount, strict=True)))
        for box in handle_boxes(part.handle, parts)
    )
    return PartNode(
        name=part.name,
        role=part.role,
        boxes=(*part.boxes, *handle),
        density=density,
        parent=parent,
        joint_type=part.joint_type,
        origin=part.origin,
        axis=part.axis,
        limits=limits,
    )
