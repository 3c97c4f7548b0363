"""A kinematic tree + a segmented point cloud -> URDF text and OBJ meshes (pure).

Each part becomes a link whose mesh is the convex hull of its points (trimesh; a flat
or degenerate part is thickened by `min_thickness` along its thinnest direction first)
and whose inertial comes from that hull at `density`. Link frames keep the object
frame's orientation: the root link's frame is the object frame; a movable part's frame
sits on its joint axis origin, a fixed part's at its centroid. Joint axes are written in
that frame (= object-frame directions). Limits: revolute (0, revolute_upper) radians,
prismatic (0, prismatic_fraction x the child's extent along the axis) metres; the axis
heuristics of `joints.py` orient axes so that positive values open the part.

The document is written by `artic.objects.urdf.write_urdf`, so it has the same
conventions (names, deterministic numbers) as the procedural objects' URDFs. Links are
named `part_<id>`; joints `joint_<child id>`, written in depth-first order from the
root (`KinematicTree.depth_first_edges`), which is how PyBullet numbers them: PyBullet's
joint j is `tree.depth_first_edges()[j]`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from artic.geometry.transforms import make_transform
from artic.hierarchy.graph import check_segmented_cloud
from artic.objects.model import ArticulatedObject, Inertial, Joint, Link, TriangleMesh
from artic.objects.tree import KinematicTree
from artic.objects.urdf import UrdfFiles, write_urdf

Array = NDArray[np.float64]


@dataclass(frozen=True)
class TreeUrdfConfig:
    """name: robot name. density: kg/m^3 for the inertials. min_thickness: metres, the
    hull's smallest allowed extent. revolute_upper: radians. prismatic_fraction: of the
    child's length along the axis. effort, velocity, damping, friction: every movable
    joint's."""

    name: str = "inferred_object"
    density: float = 500.0
    min_thickness: float = 0.004
    revolute_upper: float = float(np.pi / 2)
    prismatic_fraction: float = 0.9
    effort: float = 10.0
    velocity: float = 1.0
    damping: float = 0.1
    friction: float = 0.0


def convex_hull_mesh(points: Array, min_thickness: float) -> TriangleMesh:
    """Convex hull (outward-wound) of (N, 3) points, in their own coordinates."""
    import trimesh

    pts = np.asarray(points, dtype=np.float64)
    center = pts.mean(axis=0)
    centred = pts - center
    _, vectors = np.linalg.eigh(centred.T @ centred)  # principal axes, (3, 3) for any N
    vt = vectors.T
    extents = np.ptp(centred @ vectors, axis=0)
    for k in np.flatnonzero(extents < min_thickness):  # flat, linear or single points
        offset = 0.5 * min_thickness * vt[k]
        pts = np.concatenate([pts + offset, pts - offset])
    hull = trimesh.convex.convex_hull(pts)
    return TriangleMesh(
        vertices=np.asarray(hull.vertices, dtype=np.float64),
        triangles=np.asarray(hull.faces, dtype=np.int32),
    )


def _inertial(mesh: TriangleMesh, density: float) -> Inertial:
    import trimesh

    body = trimesh.Trimesh(mesh.vertices, mesh.triangles, process=False)
    volume = max(float(abs(body.volume)), 1e-9)
    body.density = density
    mass = max(density * volume, 1e-3)
    inertia = np.asarray(body.moment_inertia, dtype=np.float64) * (mass / max(body.mass, 1e-12))
    return Inertial(
        mass=mass,
        center_of_mass=np.asarray(body.center_mass, dtype=np.float64),
        inertia=inertia + np.eye(3) * 1e-9,
    )


def tree_to_urdf(
    tree: KinematicTree,
    points: NDArray[np.floating],
    part_id: NDArray[np.integer],
    cfg: TreeUrdfConfig | None = None,
) -> UrdfFiles:
    """URDF + OBJ meshes of `tree` over the parts of a segmented cloud.

    points: (N, 3) metres, object frame. part_id: (N,) ints 0..P-1. Every revolute and
    prismatic edge needs an axis (`joints.estimate_axes`); raises ValueError otherwise.
    """
    cfg = cfg or TreeUrdfConfig()
    num_parts = check_segmented_cloud(points, part_id)
    if num_parts != tree.num_parts:
        raise ValueError(f"part_id has {num_parts} parts, the tree {tree.num_parts}")
    pts = np.asarray(points, dtype=np.float64)
    ids = np.asarray(part_id)
    part_points = [pts[ids == p] for p in range(num_parts)]

    frame_origin: dict[int, Array] = {tree.root: np.zeros(3)}
    joints: list[Joint] = []
    for e, ((parent, child), joint_type) in enumerate(
        zip(tree.edges, tree.joint_types, strict=True)
    ):
        axis = None if tree.axes is None else tree.axes[e]
        if joint_type != "fixed" and axis is None:
            raise ValueError(f"edge ({parent}, {child}) is {joint_type} but has no axis")
        origin = part_points[child].mean(axis=0) if axis is None else axis.origin
        frame_origin[child] = np.asarray(origin, dtype=np.float64)
        direction = np.array([0.0, 0.0, 1.0]) if axis is None else axis.direction
        if joint_type == "revolute":
            limits = (0.0, cfg.revolute_upper)
        elif joint_type == "prismatic":
            along = part_points[child] @ direction
            limits = (0.0, cfg.prismatic_fraction * float(np.ptp(along)))
        else:
            limits = (0.0, 0.0)
        movable = joint_type != "fixed"
        joints.append(
            Joint(
                name=f"joint_{child}",
                type=joint_type,
                parent=f"part_{parent}",
                child=f"part_{child}",
                origin=make_transform(translation=frame_origin[child] - frame_origin[parent]),
                axis=np.asarray(direction, dtype=np.float64),
                limits=limits,
                effort=cfg.effort if movable else 0.0,
                velocity=cfg.velocity if movable else 0.0,
                damping=cfg.damping if movable else 0.0,
                friction=cfg.friction if movable else 0.0,
            )
        )

    order = [tree.root] + [child for _, child in tree.depth_first_edges()]
    links = []
    for part in order:
        mesh = convex_hull_mesh(part_points[part] - frame_origin[part], cfg.min_thickness)
        role = "body" if part == tree.root else "part"
        links.append(Link(f"part_{part}", role, mesh, _inertial(mesh, cfg.density)))
    obj = ArticulatedObject(cfg.name, tuple(links), tuple(joints), base_pose=np.eye(4))
    return write_urdf(obj)
