"""PartNet-Mobility objects (the data of thesis section 4.5) as `ArticulatedObject`s: pure.

A PartNet-Mobility folder holds `mobility.urdf`, its meshes `textured_objs/*.obj` and an
optional `semantics.txt` (lines `link_0 slider drawer`: link, joint kind, label).
`artic.artifacts.partnet.load_partnet(folder)` reads those files and calls
`partnet_object` here, which converts their content without touching the file system.

Conversion rules (docs/objects.md):
- Joints: revolute, continuous, prismatic and fixed; floating and planar raise InputError.
  A continuous joint's poses are drawn from [-pi, pi]. URDF's default axis is (1, 0, 0).
- A link's visuals (often several meshes) become one mesh in the link frame (each
  visual's origin and mesh scale applied). Box, cylinder and sphere visuals are meshed.
- A geometry-less root (PartNet-Mobility's `base`) on a fixed joint to a single child
  is dropped: the child becomes the root and the joint's origin the object's base_pose.
  Any other geometry-less link stays as a virtual link (empty mesh).
- merge_fixed=False (default) keeps every link as a part, as in the URDF; True merges
  each link hung on a fixed joint into its parent (one rigid part, as segmentation sees
  it), re-attaching its children to the parent.
- Links are ordered depth-first from the root (children in joint order in the file), so
  link index = part id and PyBullet's joint j is joints[j] of the written URDF.
- Inertials: the URDF's if given, else a uniform-density solid of the link's convex hull.
"""

from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import NamedTuple, cast

import numpy as np
from numpy.typing import NDArray

from artic.errors import InputError
from artic.geometry.transforms import make_transform
from artic.objects.model import (
    ArticulatedObject,
    Inertial,
    Joint,
    Link,
    TriangleMesh,
    UrdfJointType,
)
from artic.objects.tree import ObjectTree, object_tree

SPIN_RANGE = (-math.pi, math.pi)
"""Range continuous joints' articulated poses are drawn from, radians."""
_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed")
_EMPTY = TriangleMesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))


class PartNetObject(NamedTuple):
    """A converted PartNet-Mobility model: the object and its tree ground truth."""

    object: ArticulatedObject
    tree: ObjectTree


class _Visual(NamedTuple):
    origin: NDArray[np.float64]
    mesh: str | None  # filename, or None for a primitive
    scale: NDArray[np.float64]
    primitive: TriangleMesh | None


@dataclass
class _Link:
    name: str
    visuals: list[_Visual] = field(default_factory=list)
    inertial: Inertial | None = None


def _floats(text: str | None, count: int, default: float, where: str) -> NDArray[np.float64]:
    if text is None:
        return np.full(count, default)
    try:
        values = np.array([float(v) for v in text.split()], dtype=np.float64)
    except ValueError:
        raise InputError(f"{where}: expected {count} numbers, got {text!r}") from None
    if values.shape != (count,) or not np.all(np.isfinite(values)):
        raise InputError(f"{where}: expected {count} finite numbers, got {text!r}")
    return values


def _pose(element: ET.Element | None, where: str) -> NDArray[np.float64]:
    """(4, 4) transform of a URDF <origin> (xyz, rpy: R = Rz(yaw) Ry(pitch) Rx(roll))."""
    from scipy.spatial.transform import Rotation

    if element is None:
        return np.eye(4)
    xyz = _floats(element.get("xyz"), 3, 0.0, where)
    rpy = _floats(element.get("rpy"), 3, 0.0, where)
    return make_transform(Rotation.from_euler("xyz", rpy).as_matrix(), xyz)


def _primitive(geometry: ET.Element, where: str) -> TriangleMesh | None:
    import trimesh

    shape: trimesh.Trimesh | None = None
    if (box := geometry.find("box")) is not None:
        shape = trimesh.creation.box(extents=_floats(box.get("size"), 3, 0.0, where))
    elif (cyl := geometry.find("cylinder")) is not None:
        r, h = (float(_floats(cyl.get(k), 1, 0.0, where)[0]) for k in ("radius", "length"))
        shape = trimesh.creation.cylinder(radius=r, height=h)
    elif (sphere := geometry.find("sphere")) is not None:
        r = float(_floats(sphere.get("radius"), 1, 0.0, where)[0])
        shape = trimesh.creation.icosphere(subdivisions=2, radius=r)
    if shape is None:
        return None
    return TriangleMesh(
        np.asarray(shape.vertices, dtype=np.float64), np.asarray(shape.faces, dtype=np.int32)
    )


def _number(element: ET.Element | None, key: str, default: float, where: str) -> float:
    """Attribute `key` of `element` as a float; `default` when the element or key is absent."""
    text = None if element is None else element.get(key)
    return float(_floats(text, 1, default, where)[0])


def _inertial(element: ET.Element | None, where: str) -> Inertial | None:
    """A URDF <inertial> (mass, origin, inertia), or None when absent or massless."""
    if element is None or element.find("mass") is None:
        return None
    i = element.find("inertia")
    v = {k: _number(i, k, 0.0, where) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    tensor = np.array(
        [
            [v["ixx"], v["ixy"], v["ixz"]],
            [v["ixy"], v["iyy"], v["iyz"]],
            [v["ixz"], v["iyz"], v["izz"]],
        ]
    )
    mass = _number(element.find("mass"), "value", 0.0, where)
    return Inertial(mass, _pose(element.find("origin"), where)[:3, 3], tensor)


def _parse_link(element: ET.Element, source: str) -> _Link:
    name = element.get("name") or ""
    where = f"{source}: link {name}"
    link = _Link(name, inertial=_inertial(element.find("inertial"), where))
    for visual in element.findall("visual"):
        geometry = visual.find("geometry")
        if geometry is None:
            raise InputError(f"{where}: a <visual> without <geometry>")
        origin = _pose(visual.find("origin"), where)
        mesh = geometry.find("mesh")
        if mesh is not None:
            filename = mesh.get("filename")
            if not filename:
                raise InputError(f"{where}: <mesh> without a filename")
            scale = _floats(mesh.get("scale"), 3, 1.0, where)
            link.visuals.append(_Visual(origin, filename, scale, None))
            continue
        primitive = _primitive(geometry, where)
        if primitive is None:
            raise InputError(f"{where}: unsupported visual geometry (mesh, box, cylinder, sphere)")
        link.visuals.append(_Visual(origin, None, np.ones(3), primitive))
    return link


def _parse_joint(element: ET.Element, source: str) -> Joint:
    name = element.get("name") or ""
    where = f"{source}: joint {name}"
    kind = element.get("type")
    if kind not in _JOINT_TYPES:
        raise InputError(
            f"{where}: type {kind!r} not supported; expected one of {', '.join(_JOINT_TYPES)}"
        )
    parent, child = element.find("parent"), element.find("child")
    if parent is None or child is None or not parent.get("link") or not child.get("link"):
        raise InputError(f"{where}: needs <parent link=...> and <child link=...>")
    axis_element = element.find("axis")
    axis = np.array([1.0, 0.0, 0.0])  # the URDF default
    if axis_element is not None:
        axis = _floats(axis_element.get("xyz"), 3, 0.0, where)
    norm = float(np.linalg.norm(axis))
    if kind != "fixed" and norm < 1e-9:
        raise InputError(f"{where}: axis must be a non-zero vector")
    limit = element.find("limit")
    limits: tuple[float, float] = (0.0, 0.0)
    if kind in ("revolute", "prismatic"):
        if limit is None:
            raise InputError(f"{where}: a {kind} joint needs <limit lower upper>")
        limits = (_number(limit, "lower", 0.0, where), _number(limit, "upper", 0.0, where))
        if limits[0] > limits[1]:
            raise InputError(f"{where}: limit lower {limits[0]} > upper {limits[1]}")
    elif kind == "continuous":
        limits = SPIN_RANGE
    dynamics = element.find("dynamics")
    return Joint(
        name=name,
        type=cast(UrdfJointType, kind),
        parent=str(parent.get("link")),
        child=str(child.get("link")),
        origin=_pose(element.find("origin"), where),
        axis=axis / norm if norm > 0 else np.array([1.0, 0.0, 0.0]),
        limits=limits,
        effort=_number(limit, "effort", 0.0, where),
        velocity=_number(limit, "velocity", 0.0, where),
        damping=_number(dynamics, "damping", 0.0, where),
        friction=_number(dynamics, "friction", 0.0, where),
    )


def _parse(urdf_text: str, source: str) -> tuple[str, dict[str, _Link], list[Joint]]:
    try:
        robot = ET.fromstring(urdf_text)
    except ET.ParseError as err:
        raise InputError(f"{source}: not valid XML ({err})") from None
    if robot.tag != "robot":
        raise InputError(f"{source}: expected a <robot> document, got <{robot.tag}>")
    links: dict[str, _Link] = {}
    for element in robot.findall("link"):
        link = _parse_link(element, source)
        if not link.name or link.name in links:
            raise InputError(f"{source}: link name {link.name!r} is empty or repeated")
        links[link.name] = link
    joints = [_parse_joint(element, source) for element in robot.findall("joint")]
    for joint in joints:
        for end in (joint.parent, joint.child):
            if end not in links:
                raise InputError(f"{source}: joint {joint.name} references unknown link {end!r}")
    if not links:
        raise InputError(f"{source}: no links")
    return robot.get("name") or "partnet_object", links, joints


def mesh_filenames(urdf_text: str, source: str = "mobility.urdf") -> list[str]:
    """The distinct mesh filenames the URDF's visuals reference, in document order,
    relative to the URDF's folder (what the file-reading side must load)."""
    _, links, _ = _parse(urdf_text, source)
    names: list[str] = []
    for link in links.values():
        names += [v.mesh for v in link.visuals if v.mesh is not None and v.mesh not in names]
    return names


def parse_obj(data: bytes, source: str) -> TriangleMesh:
    """A triangle mesh from Wavefront OBJ bytes (all objects and groups merged);
    InputError naming `source` if it holds no triangles."""
    import trimesh

    try:
        mesh = trimesh.load(io.BytesIO(data), file_type="obj", force="mesh", process=False)
    except Exception as err:  # trimesh raises many kinds on malformed input
        raise InputError(f"{source}: not a readable OBJ mesh ({type(err).__name__})") from None
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int32).reshape(-1, 3)
    vertices = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=np.float64).reshape(
        -1, 3
    )
    if faces.shape[0] == 0 or not np.all(np.isfinite(vertices)):
        raise InputError(f"{source}: an OBJ mesh with no triangles or non-finite vertices")
    return TriangleMesh(vertices, faces)


def parse_semantics(text: str, source: str = "semantics.txt") -> dict[str, str]:
    """Link name -> label from semantics.txt lines `<link> <joint kind> <label>`."""
    labels: dict[str, str] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if not words:
            continue
        if len(words) < 2:
            raise InputError(f"{source}: line {number}: expected '<link> <joint kind> <label>'")
        labels[words[0]] = words[-1]
    return labels


def _transformed(
    mesh: TriangleMesh, transform: NDArray[np.float64], scale: NDArray[np.float64]
) -> TriangleMesh:
    vertices = (mesh.vertices * scale) @ transform[:3, :3].T + transform[:3, 3]
    triangles = mesh.triangles
    if np.linalg.det(transform[:3, :3] * scale) < 0:  # a mirroring scale flips the winding
        triangles = triangles[:, ::-1]
    return TriangleMesh(vertices, np.ascontiguousarray(triangles, dtype=np.int32))


def _concatenate(pieces: list[TriangleMesh]) -> TriangleMesh:
    if not pieces:
        return _EMPTY
    offsets = np.cumsum([0] + [p.vertices.shape[0] for p in pieces[:-1]])
    return TriangleMesh(
        np.concatenate([p.vertices for p in pieces]).astype(np.float64),
        np.concatenate([p.triangles + o for p, o in zip(pieces, offsets, strict=True)]).astype(
            np.int32
        ),
    )


def hull_inertial(mesh: TriangleMesh, density: float) -> Inertial:
    """Mass properties of the solid convex hull of `mesh` at `density` (kg/m^3), in the
    mesh frame; a flat hull uses its bounding box thickened to 1 mm; an empty mesh a
    1e-4 kg point mass."""
    import trimesh

    if mesh.is_empty:
        return Inertial(1e-4, np.zeros(3), np.eye(3) * 1e-9)
    try:
        hull = trimesh.Trimesh(mesh.vertices, mesh.triangles, process=False).convex_hull
        volume = float(hull.volume)
    except Exception:  # qhull fails on flat or degenerate point sets
        volume = 0.0
    if volume > 1e-9:
        hull.density = density
        inertia = np.asarray(hull.moment_inertia, dtype=np.float64)
        return Inertial(
            float(hull.mass),
            np.asarray(hull.center_mass, dtype=np.float64),
            0.5 * (inertia + inertia.T),
        )
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    a, b, c = np.maximum(hi - lo, 1e-3)
    mass = density * a * b * c
    inertia = mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    return Inertial(float(mass), 0.5 * (lo + hi), inertia)


def _tree_order(
    links: Mapping[str, object], joints: list[Joint], source: str
) -> tuple[str, list[Joint]]:
    """The root link and the joints in depth-first order (children in file order)."""
    children = [j.child for j in joints]
    repeated = {c for c in children if children.count(c) > 1}
    if repeated:
        raise InputError(f"{source}: link {sorted(repeated)[0]} has more than one parent joint")
    roots = [name for name in links if name not in set(children)]
    if len(roots) != 1:
        raise InputError(
            f"{source}: expected one root link, found {len(roots)} ({', '.join(roots)})"
        )
    ordered: list[Joint] = []
    stack: list[tuple[str, Joint | None]] = [(roots[0], None)]
    while stack:  # pre-order: a joint is listed when its child is visited
        name, via = stack.pop()
        if via is not None:
            ordered.append(via)
        below = [j for j in joints if j.parent == name]
        stack.extend((j.child, j) for j in reversed(below))
    if len(ordered) != len(joints):
        raise InputError(f"{source}: the joints contain a cycle; a URDF must be a tree")
    return roots[0], ordered


def _merge_fixed(
    pieces: dict[str, list[TriangleMesh]], joints: list[Joint]
) -> tuple[list[Joint], set[str]]:
    """Merge every child of a fixed joint into its parent (meshes moved into the parent
    frame, its own joints re-attached to the parent); returns the joints left and the
    links that absorbed others."""
    joints = list(joints)
    grown: set[str] = set()
    while fixed := next((j for j in joints if j.type == "fixed"), None):
        pieces[fixed.parent] += [
            _transformed(m, fixed.origin, np.ones(3)) for m in pieces.pop(fixed.child)
        ]
        grown.add(fixed.parent)
        rest = []
        for j in joints:
            if j is fixed:
                continue
            if j.parent == fixed.child:
                j = replace(j, parent=fixed.parent, origin=fixed.origin @ j.origin)
            rest.append(j)
        joints = rest
    return joints, grown


def partnet_object(
    urdf_text: str,
    meshes: Mapping[str, TriangleMesh],
    semantics: Mapping[str, str] | None = None,
    *,
    source: str = "mobility.urdf",
    semantics_source: str = "semantics.txt",
    merge_fixed: bool = False,
    density: float = 500.0,
) -> PartNetObject:
    """Convert a PartNet-Mobility URDF (module docstring) into an ArticulatedObject and
    its tree ground truth (`artic.objects.tree.object_tree`).

    meshes: every filename of `mesh_filenames(urdf_text)` -> its mesh in file units
    (metres). semantics: link name -> label (`parse_semantics`). source and
    semantics_source: the files' paths, for error messages. density: kg/m^3 for links
    without a URDF inertial. Raises InputError naming the file on malformed input.
    """
    name, links, joints = _parse(urdf_text, source)
    labels = dict(semantics or {})
    unknown = sorted(set(labels) - set(links))
    if unknown:
        raise InputError(f"{semantics_source}: link {unknown[0]} is not a link of {source}")
    pieces: dict[str, list[TriangleMesh]] = {}
    for link in links.values():
        pieces[link.name] = []
        for visual in link.visuals:
            mesh = visual.primitive if visual.mesh is None else meshes.get(visual.mesh)
            if mesh is None:
                raise InputError(f"{source}: link {link.name}: mesh {visual.mesh} was not loaded")
            pieces[link.name].append(_transformed(mesh, visual.origin, visual.scale))
    root, joints = _tree_order(links, joints, source)
    base_pose = np.eye(4)
    while not pieces[root]:  # drop a geometry-less root on a fixed joint to one child
        below = [j for j in joints if j.parent == root]
        if len(below) != 1 or below[0].type != "fixed":
            break
        base_pose, root = base_pose @ below[0].origin, below[0].child
        joints = joints[1:]  # depth-first: the root's only joint comes first
    grown: set[str] = set()
    if merge_fixed:
        joints, grown = _merge_fixed(pieces, joints)
        kept = {n: None for n in [root, *(j.child for j in joints)]}
        root, joints = _tree_order(kept, joints, source)
    out_links = []
    for link_name in [root, *(j.child for j in joints)]:
        mesh = _concatenate(pieces[link_name])
        given = links[link_name].inertial
        usable = given is not None and link_name not in grown
        inertial = given if usable and given is not None else hull_inertial(mesh, density)
        label = labels.get(link_name, "")
        role = label or ("body" if link_name == root else "part")
        out_links.append(Link(link_name, role, mesh, inertial, semantic=label))
    obj = ArticulatedObject(
        name=name, links=tuple(out_links), joints=tuple(joints), base_pose=base_pose
    )
    return PartNetObject(obj, object_tree(obj, labels))
