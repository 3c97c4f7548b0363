"""Building blocks of the procedural objects: boxes, watertight meshes, mass properties,
doors, drawers, the slide's carriage and the lever's arm (Chapter 7), handles and knobs,
and the assembly of a body plus its moving parts.

Every part is a union of axis-aligned boxes. `union_mesh` turns such a union into one
closed, outward-oriented triangle mesh (faces between occupied and empty cells of the
grid the box faces span), so each link mesh is watertight and its mass properties are
exact. Frames follow `docs/objects.md`: the body frame has its origin at the centre of
the body's bottom face, x from the front into the object, z up; the front face of the
body is the plane x = -depth / 2.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any, Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from artic.geometry.transforms import make_transform
from artic.objects.model import ArticulatedObject, Inertial, Joint, Link, TriangleMesh
from artic.objects.spec import Chirality, JointKind, ObjectSpec, PartsConfig

Interval = tuple[float, float]
BarDirection = Literal["y", "z"]
HandleShape = Literal["bar", "knob"]
MovingRole = Literal["door", "drawer", "slider", "lever"]

_DECIMALS = 9  # box coordinates are snapped to 1 nm so touching faces coincide exactly


class Box(NamedTuple):
    """An axis-aligned box given by its extent along x, y and z: (min, max) metres each."""

    x: Interval
    y: Interval
    z: Interval


class HandleMount(NamedTuple):
    """Where a handle sits on its moving part: `position` (3,) on the part's front face,
    in the part's link frame, metres; the bar runs along `direction`, `length` metres.
    `shape`: "bar" (a bar on two end posts) or "knob" (one block; `handle_boxes`)."""

    position: NDArray[np.float64]
    direction: BarDirection
    length: float
    shape: HandleShape = "bar"


class MovingPart(NamedTuple):
    """A door, drawer, slider or lever: its joint in the body frame and its boxes in the
    joint frame.

    origin: (3,) joint-frame origin in the body frame (a point on the axis), metres.
    axis: (3,) unit joint axis (joint frame = body orientation). boxes: in the joint
    frame, which is also the part's link frame.
    """

    name: str
    role: MovingRole
    joint_type: JointKind
    origin: NDArray[np.float64]
    axis: NDArray[np.float64]
    boxes: tuple[Box, ...]
    handle: HandleMount


def union_mesh(boxes: Sequence[Box]) -> TriangleMesh:
    """One closed triangle mesh of the union of `boxes` (metres), outward normals.

    The box faces span a rectilinear grid; a grid face between an occupied and an
    empty cell becomes two triangles. Vertices are shared grid points, so boxes that
    touch merge into one solid and the result is watertight (given no two boxes touch
    along an edge only).
    """
    if not boxes:
        raise ValueError("union_mesh needs at least one box")
    bounds = np.round(np.array(boxes, dtype=np.float64), _DECIMALS)  # (B, 3, 2)
    if np.any(bounds[:, :, 0] >= bounds[:, :, 1]):
        raise ValueError("every box needs min < max along each axis")
    vertices, triangles = _union_arrays(bounds.tobytes(), len(bounds))
    return TriangleMesh(vertices=vertices.copy(), triangles=triangles.copy())


@functools.lru_cache(maxsize=512)
def _union_arrays(bounds_bytes: bytes, count: int) -> tuple[NDArray[np.float64], NDArray[np.int32]]:
    """`union_mesh`'s vertices and triangles of `count` boxes' rounded bounds (B, 3, 2),
    given as bytes: kept for the last 512 sets of boxes (the refinement builds objects of
    the same few parts, each handle and door many times over), never handed out (copies)."""
    bounds = np.frombuffer(bounds_bytes, dtype=np.float64).reshape(count, 3, 2)
    grids = [np.unique(bounds[:, axis, :]) for axis in range(3)]
    centres = [0.5 * (g[:-1] + g[1:]) for g in grids]
    occupied = np.zeros(tuple(len(c) for c in centres), dtype=bool)
    for box in bounds:
        inside = [(c > box[a, 0]) & (c < box[a, 1]) for a, c in enumerate(centres)]
        occupied |= inside[0][:, None, None] & inside[1][None, :, None] & inside[2][None, None, :]
    quads = _boundary_quads(np.pad(occupied, 1), tuple(len(g) for g in grids))
    used, faces = np.unique(quads, return_inverse=True)
    faces = faces.reshape(-1, 4)
    corner = np.stack(np.unravel_index(used, tuple(len(g) for g in grids)), axis=1)
    vertices = np.stack([grids[a][corner[:, a]] for a in range(3)], axis=1).astype(np.float64)
    triangles = np.concatenate([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]]).astype(np.int32)
    vertices.setflags(write=False)
    triangles.setflags(write=False)
    return vertices, triangles


def _boundary_quads(padded: NDArray[np.bool_], grid_shape: tuple[int, ...]) -> NDArray[np.int64]:
    """(F, 4) flat grid-point ids of every occupied/empty cell interface, counter-clockwise
    seen from the empty side. padded: occupancy with a one-cell empty border."""
    quads = []
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3  # (b, c) counter-clockwise about +a
        before = [slice(1, -1)] * 3
        after = [slice(1, -1)] * 3
        before[a], after[a] = slice(0, -1), slice(1, None)
        lower, upper = padded[tuple(before)], padded[tuple(after)]
        for mask, flip in ((lower & ~upper, False), (upper & ~lower, True)):
            cells = np.argwhere(mask)  # column a: plane index; b, c: lower grid corner
            corners = []
            for db, dc in ((0, 0), (1, 0), (1, 1), (0, 1)):
                point = cells.copy()
                point[:, b] += db
                point[:, c] += dc
                corners.append(np.ravel_multi_index(tuple(point.T), grid_shape))
            quad = np.stack(corners, axis=1)
            quads.append(quad[:, ::-1] if flip else quad)
    return np.concatenate(quads)


def mass_properties(mesh: TriangleMesh, density: float) -> Inertial:
    """Mass (kg), centre of mass (3,) and inertia (3, 3) about it, kg m^2, of a closed mesh
    of uniform `density` (kg/m^3), computed by trimesh in the mesh's frame."""
    import trimesh  # lazy: heavy import, only needed when building

    solid = trimesh.Trimesh(mesh.vertices, mesh.triangles, process=False)
    if not solid.is_watertight:
        raise ValueError("mass properties need a watertight mesh")
    solid.density = density
    inertia = np.asarray(solid.moment_inertia, dtype=np.float64)
    return Inertial(
        mass=float(solid.mass),
        center_of_mass=np.asarray(solid.center_mass, dtype=np.float64) + 0.0,
        inertia=0.5 * (inertia + inertia.T) + 0.0,
    )


class _LazyInertial(Inertial):
    """An `Inertial` whose fields `mass_properties` computes on first read: building an
    object to render it (the refinement builds two per image) reads none, and trimesh's
    import alone costs ~0.8 s of an `artic predict` process on this machine."""

    def __init__(self, mesh: TriangleMesh, density: float) -> None:  # fields: on first read
        object.__setattr__(self, "_source", (mesh, density))

    def __getattr__(self, name: str) -> Any:
        # called only for attributes not set yet: the fields, until the first read
        if name not in _INERTIAL_FIELDS or "_source" not in self.__dict__:
            raise AttributeError(name)
        computed = mass_properties(*self.__dict__["_source"])
        for field in _INERTIAL_FIELDS:
            object.__setattr__(self, field, getattr(computed, field))
        return getattr(computed, name)


_INERTIAL_FIELDS = ("mass", "center_of_mass", "inertia")


def lazy_mass_properties(mesh: TriangleMesh, density: float) -> Inertial:
    """`mass_properties(mesh, density)`, computed when a field is first read (the same
    values; a mesh that is not watertight raises then)."""
    return _LazyInertial(mesh, density)


def shell_boxes(depth: float, width: float, height: float, wall: float) -> list[Box]:
    """Hollow body open at the front (x = -depth/2): back, right (-y), left (+y), bottom
    and top panels of thickness `wall`, non-overlapping. Body frame, metres."""
    x0, x1, y0, y1 = -depth / 2, depth / 2, -width / 2, width / 2
    inner_x = (x0, x1 - wall)
    inner_y = (y0 + wall, y1 - wall)
    return [
        Box((x1 - wall, x1), (y0, y1), (0.0, height)),
        Box(inner_x, (y0, y0 + wall), (0.0, height)),
        Box(inner_x, (y1 - wall, y1), (0.0, height)),
        Box(inner_x, inner_y, (0.0, wall)),
        Box(inner_x, inner_y, (height - wall, height)),
    ]


def handle_length(extent: float, parts: PartsConfig) -> float:
    """Bar length, metres: `handle_length`, capped at `handle_fraction` of `extent`."""
    length = min(parts.handle_length, parts.handle_fraction * extent)
    if length < 3.0 * parts.handle_thickness:
        raise ValueError(f"handle_length: a {extent} m part leaves no room for a handle")
    return length


def handle_boxes(mount: HandleMount, parts: PartsConfig) -> list[Box]:
    """A bar of square section standing `handle_standoff` in front of the surface (-x),
    on two end posts; handle frame at the mount point on the surface. Metres.

    A "knob" mount is one block reaching as far in front of the surface as a bar does
    (`handle_standoff + handle_thickness`), `handle_thickness` wide across `direction`
    and `mount.length` long along it."""
    half, side, standoff = mount.length / 2, parts.handle_thickness, parts.handle_standoff
    across = (-side / 2, side / 2)
    pieces = [
        ((-(standoff + side), -standoff), (-half, half)),  # bar
        ((-standoff, 0.0), (-half, -half + side)),  # post
        ((-standoff, 0.0), (half - side, half)),  # post
    ]
    if mount.shape == "knob":
        pieces = [((-(standoff + side), 0.0), (-half, half))]
    if mount.direction == "y":
        return [Box(x, along, across) for x, along in pieces]
    return [Box(x, across, along) for x, along in pieces]


def vertical_door(
    name: str,
    parts: PartsConfig,
    front_x: float,
    span_y: Interval,
    span_z: Interval,
    hinge: Chirality,
) -> MovingPart:
    """A door in front of the plane x = `front_x`, covering `span_y` x `span_z` (body
    frame). hinge +1: hinge on the low-y edge, axis +z; -1: high-y edge, axis -z. Either
    way q > 0 swings the free edge towards -x (out of the body, towards the camera).
    Joint origin: hinge edge, door bottom, on the body front. Handle: vertical bar
    `handle_inset` from the free edge, at mid-height."""
    width, height = span_y[1] - span_y[0], span_z[1] - span_z[0]
    hinge_y = span_y[0] if hinge == 1 else span_y[1]
    thick = parts.door_thickness
    panel = Box((-thick, 0.0), (min(0.0, hinge * width), max(0.0, hinge * width)), (0.0, height))
    inset = min(parts.handle_inset, width / 4)
    mount = HandleMount(
        position=np.array([-thick, hinge * (width - inset), height / 2]),
        direction="z",
        length=handle_length(height, parts),
    )
    return MovingPart(
        name=name,
        role="door",
        joint_type="revolute",
        origin=np.array([front_x, hinge_y, span_z[0]]),
        axis=np.array([0.0, 0.0, float(hinge)]),
        boxes=(panel,),
        handle=mount,
    )


def flap_door(
    name: str, parts: PartsConfig, front_x: float, span_y: Interval, span_z: Interval
) -> MovingPart:
    """A door hinged at its bottom edge (toaster oven), in front of x = `front_x`.

    Axis (0, -1, 0), so q > 0 drops the door outwards and down. Joint origin: centre of
    the bottom edge on the body front. Handle: horizontal bar near the top edge."""
    width, height = span_y[1] - span_y[0], span_z[1] - span_z[0]
    thick = parts.door_thickness
    panel = Box((-thick, 0.0), (-width / 2, width / 2), (0.0, height))
    inset = min(parts.handle_inset, height / 4)
    mount = HandleMount(
        position=np.array([-thick, 0.0, height - inset]),
        direction="y",
        length=handle_length(width, parts),
    )
    return MovingPart(
        name=name,
        role="door",
        joint_type="revolute",
        origin=np.array([front_x, 0.5 * (span_y[0] + span_y[1]), span_z[0]]),
        axis=np.array([0.0, -1.0, 0.0]),
        boxes=(panel,),
        handle=mount,
    )


def drawer(
    name: str, parts: PartsConfig, span_x: Interval, span_y: Interval, span_z: Interval
) -> MovingPart:
    """An open-top box occupying `span_x` x `span_y` x `span_z` (body frame) when closed;
    its front face is the plane x = span_x[0]. Front `door_thickness`, other walls
    `panel_thickness`. Axis (-1, 0, 0): q > 0 pulls it out towards the camera. Joint
    origin: centre of the front face. Handle: horizontal bar centred on the front."""
    length, width, height = (s[1] - s[0] for s in (span_x, span_y, span_z))
    front, wall = parts.door_thickness, parts.panel_thickness
    hw, hh = width / 2, height / 2
    inner_x = (front, length - wall)
    boxes = (
        Box((0.0, front), (-hw, hw), (-hh, hh)),  # front
        Box((length - wall, length), (-hw, hw), (-hh, hh)),  # back
        Box(inner_x, (-hw, -hw + wall), (-hh, hh)),  # side
        Box(inner_x, (hw - wall, hw), (-hh, hh)),  # side
        Box(inner_x, (-hw + wall, hw - wall), (-hh, -hh + wall)),  # bottom
    )
    centre = [span_x[0], 0.5 * (span_y[0] + span_y[1]), 0.5 * (span_z[0] + span_z[1])]
    return MovingPart(
        name=name,
        role="drawer",
        joint_type="prismatic",
        origin=np.array(centre),
        axis=np.array([-1.0, 0.0, 0.0]),
        boxes=boxes,
        handle=HandleMount(np.zeros(3), "y", handle_length(width, parts)),
    )


def overlay_front(part: MovingPart, parts: PartsConfig, half: tuple[float, float]) -> MovingPart:
    """`part` (a `drawer`) with an overlay front: a plate `door_thickness` thick in front of
    its front face (joint frame x in [-thickness, 0]), `half` (y, z) its half extents about
    the joint origin, the handle moved onto the plate's face. The joint origin stays where
    it was: the plate's back face when the drawer is shut (the body's front)."""
    thick = parts.door_thickness
    plate = Box((-thick, 0.0), (-half[0], half[0]), (-half[1], half[1]))
    handle = part.handle._replace(position=part.handle.position - np.array([thick, 0.0, 0.0]))
    return part._replace(boxes=(plate, *part.boxes), handle=handle)


def _knob(parts: PartsConfig, face: float) -> HandleMount:
    """A knob at its part's link origin, its long side along z: `handle_length`, capped
    at `handle_fraction` of the part's face (`face` metres square, as bars are capped);
    ValueError unless its `handle_thickness` fits on the face."""
    if parts.handle_thickness > face:
        raise ValueError(
            f"handle_thickness: a {parts.handle_thickness} m knob does not fit on a "
            f"{face} m part face (2 x handle_inset)"
        )
    length = min(parts.handle_length, parts.handle_fraction * face)
    return HandleMount(np.zeros(3), "z", length, "knob")


def slide_carriage(
    name: str,
    parts: PartsConfig,
    rail_front_x: float,
    centre_z: float,
    travel: Interval,
    direction: Chirality,
) -> MovingPart:
    """A square plate (side 2 `handle_inset`, `door_thickness` thick) riding `gap` in
    front of a rail whose front face is the plane x = `rail_front_x`, a knob at its centre.

    Prismatic along (0, `direction`, 0); the travel [lower, upper] (metres) is centred
    on y = 0: the plate's centre is at y = direction (q - (lower + upper) / 2), z =
    `centre_z`. Joint origin: centre of the plate's front face at q = 0."""
    inset, thick = parts.handle_inset, parts.door_thickness
    mid = 0.5 * (travel[0] + travel[1])
    return MovingPart(
        name=name,
        role="slider",
        joint_type="prismatic",
        origin=np.array([rail_front_x - parts.gap - thick, -direction * mid, centre_z]),
        axis=np.array([0.0, float(direction), 0.0]),
        boxes=(Box((0.0, thick), (-inset, inset), (-inset, inset)),),
        handle=_knob(parts, 2.0 * inset),
    )


def lever_arm(
    name: str,
    parts: PartsConfig,
    front_x: float,
    pivot_z: float,
    length: float,
    direction: Chirality,
) -> MovingPart:
    """A flat bar (`door_thickness` thick, 2 `handle_inset` wide) `gap` in front of the
    plane x = `front_x`, hinged at one end about a horizontal axis along x through
    (y = 0, z = `pivot_z`), with a knob `length` metres from the axis.

    At q = 0 the bar points up (+z); q > 0 turns the knob towards `direction` * y in the
    front plane: axis (-direction, 0, 0). The bar reaches `handle_inset` past the axis
    and past the knob's centre. Joint origin: the pivot on the bar's front face."""
    inset, thick = parts.handle_inset, parts.door_thickness
    return MovingPart(
        name=name,
        role="lever",
        joint_type="revolute",
        origin=np.array([front_x - parts.gap - thick, 0.0, pivot_z]),
        axis=np.array([-float(direction), 0.0, 0.0]),
        boxes=(Box((0.0, thick), (-inset, inset), (-inset, length + inset)),),
        handle=_knob(parts, 2.0 * inset)._replace(position=np.array([0.0, 0.0, length])),
    )


def _link(name: str, role: str, boxes: Sequence[Box], density: float) -> Link:
    mesh = union_mesh(boxes)
    return Link(name=name, role=role, mesh=mesh, inertial=lazy_mass_properties(mesh, density))


def assemble(
    spec: ObjectSpec, body: Sequence[Box], moving: Sequence[MovingPart]
) -> ArticulatedObject:
    """Links and joints in part-id order: body, then each moving part and its handle.

    Joint k of the object is `joint_<k>` (body -> part); each handle hangs on a fixed
    joint `handle_<k>_fixed` at its mount point. Densities (`drawer_density` for
    drawers, `door_density` for doors, sliders and levers), damping, friction and
    effort/velocity limits come from `spec.parts`; limits from `spec.joint_limits`.
    """
    if len(moving) != spec.dof:
        raise ValueError(f"{spec.category}: built {len(moving)} joints, spec says dof {spec.dof}")
    p = spec.parts
    links = [_link("body", "body", body, p.body_density)]
    joints: list[Joint] = []
    for k, part in enumerate(moving):
        density = p.drawer_density if part.role == "drawer" else p.door_density
        links.append(_link(part.name, part.role, part.boxes, density))
        joints.append(
            Joint(
                name=f"joint_{k}",
                type=part.joint_type,
                parent="body",
                child=part.name,
                origin=make_transform(translation=part.origin),
                axis=part.axis,
                limits=spec.joint_limits[k],
                damping=p.joint_damping,
                friction=p.joint_friction,
                effort=p.joint_effort,
                velocity=p.joint_velocity,
            )
        )
        handle = f"handle_{k}"
        links.append(_link(handle, "handle", handle_boxes(part.handle, p), p.handle_density))
        joints.append(
            Joint(
                name=f"{handle}_fixed",
                type="fixed",
                parent=part.name,
                child=handle,
                origin=make_transform(translation=part.handle.position),
            )
        )
    return ArticulatedObject(
        name=f"{spec.category}_{spec.index}",
        links=tuple(links),
        joints=tuple(joints),
        base_pose=spec.pose.matrix(),
    )
