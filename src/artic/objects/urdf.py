"""URDF and OBJ text of an `ArticulatedObject` (pure: returns strings, writes nothing).

The URDF is in the object frame: the root link is the body and its `base_pose` is not
written (it lives in the `ObjectSpec`); whoever loads the file places the base. Every
link has a visual and a collision element with the same OBJ mesh and an inertial; a
virtual link (empty mesh) has only its inertial and no mesh file. A continuous joint's
`<limit>` carries effort and velocity only (URDF ignores position limits there).
Numbers are written with `repr(float)`, the shortest text that reads back to the same
double, so the output is deterministic and exact.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from artic.objects.model import ArticulatedObject, Inertial, Joint, Link, TriangleMesh


class UrdfFiles(NamedTuple):
    """`urdf`: the URDF document. `meshes`: relative path (as referenced by the URDF,
    e.g. "meshes/door_0.obj") -> OBJ text. Write them side by side to load the URDF."""

    urdf: str
    meshes: dict[str, str]


def _num(value: float) -> str:
    """Exact, deterministic text of a float (no negative zero)."""
    return repr(float(value) + 0.0)


def _nums(values: Iterable[float]) -> str:
    return " ".join(_num(v) for v in values)


def rpy_from_matrix(rotation: NDArray[np.float64]) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw (fixed axes X, Y, Z; R = Rz(yaw) Ry(pitch) Rx(roll)) of a
    (3, 3) rotation, radians."""
    r = np.asarray(rotation, dtype=np.float64)
    roll = math.atan2(r[2, 1], r[2, 2])
    pitch = math.atan2(-r[2, 0], math.hypot(r[2, 1], r[2, 2]))
    yaw = math.atan2(r[1, 0], r[0, 0])
    return roll, pitch, yaw


def mesh_to_obj(mesh: TriangleMesh, name: str) -> str:
    """Wavefront OBJ text of a triangle mesh: one object, 1-based faces, metres."""
    lines = [f"o {name}"]
    lines += [f"v {_nums(v)}" for v in mesh.vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.triangles.tolist()]
    return "\n".join(lines) + "\n"


def _origin(parent: ET.Element, transform: NDArray[np.float64]) -> None:
    ET.SubElement(
        parent,
        "origin",
        xyz=_nums(transform[:3, 3]),
        rpy=_nums(rpy_from_matrix(transform[:3, :3])),
    )


def _inertial(parent: ET.Element, inertial: Inertial) -> None:
    element = ET.SubElement(parent, "inertial")
    ET.SubElement(element, "origin", xyz=_nums(inertial.center_of_mass), rpy="0.0 0.0 0.0")
    ET.SubElement(element, "mass", value=_num(inertial.mass))
    i = inertial.inertia
    ET.SubElement(
        element,
        "inertia",
        ixx=_num(i[0, 0]),
        ixy=_num(i[0, 1]),
        ixz=_num(i[0, 2]),
        iyy=_num(i[1, 1]),
        iyz=_num(i[1, 2]),
        izz=_num(i[2, 2]),
    )


def _link(robot: ET.Element, link: Link, filename: str, is_root: bool) -> None:
    element = ET.SubElement(robot, "link", name=link.name)
    _inertial(element, link.inertial)
    if link.mesh.is_empty:
        return
    for tag in ("visual", "collision"):
        shape = ET.SubElement(element, tag)
        if tag == "collision" and is_root:
            # PyBullet extension: exact (concave) collision for the static body shell
            # instead of its convex hull; other parsers ignore the attribute.
            shape.set("concave", "yes")
        ET.SubElement(shape, "origin", xyz="0.0 0.0 0.0", rpy="0.0 0.0 0.0")
        geometry = ET.SubElement(shape, "geometry")
        ET.SubElement(geometry, "mesh", filename=filename)


def _joint(robot: ET.Element, joint: Joint) -> None:
    element = ET.SubElement(robot, "joint", name=joint.name, type=joint.type)
    ET.SubElement(element, "parent", link=joint.parent)
    ET.SubElement(element, "child", link=joint.child)
    _origin(element, joint.origin)
    if joint.type == "fixed":
        return
    ET.SubElement(element, "axis", xyz=_nums(joint.axis))
    if joint.type == "continuous":
        ET.SubElement(element, "limit", effort=_num(joint.effort), velocity=_num(joint.velocity))
    else:
        ET.SubElement(
            element,
            "limit",
            lower=_num(joint.limits[0]),
            upper=_num(joint.limits[1]),
            effort=_num(joint.effort),
            velocity=_num(joint.velocity),
        )
    ET.SubElement(element, "dynamics", damping=_num(joint.damping), friction=_num(joint.friction))


def write_urdf(obj: ArticulatedObject, mesh_dir: str = "meshes") -> UrdfFiles:
    """URDF text and OBJ meshes of `obj`, in the object frame (base_pose not included).

    mesh_dir: folder of the meshes relative to the URDF file. Links and joints keep
    `obj`'s order, so PyBullet's joint/link index j is `obj.joints[j]` / `obj.links[j+1]`.
    """
    robot = ET.Element("robot", name=obj.name)
    meshes: dict[str, str] = {}
    for index, link in enumerate(obj.links):
        filename = f"{mesh_dir}/{link.name}.obj" if mesh_dir else f"{link.name}.obj"
        if not link.mesh.is_empty:
            meshes[filename] = mesh_to_obj(link.mesh, link.name)
        _link(robot, link, filename, is_root=index == 0)
    for joint in obj.joints:
        _joint(robot, joint)
    ET.indent(robot, space="  ")
    text = '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
    return UrdfFiles(urdf=text, meshes=meshes)
