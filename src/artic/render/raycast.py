"""Depth by ray casting the object's link meshes with Open3D's RaycastingScene.

A scene cannot move its geometry, and building one (Embree's BVH) costs more than
casting an image's rays. So the links are split into rigid groups (links joined by fixed
joints move together) and each group gets one scene, built once per object in the
group's own frame; an image casts the camera rays, moved into each group's frame at the
configuration, against each group's scene and keeps the nearest hit. A rigid motion
keeps ray parameters, and the rays have unit forward (x) component, so the hit
distance is the depth along the optical axis. Only the choice of triangle comes from
Embree: each hit's depth is computed again in float64 from that triangle's plane, moved
into the camera frame, and the pixel's ray (elementwise NumPy arithmetic, the same bits
on every CPU), then rounded to float32, because Embree's own float32 distance carries
the rounding of whichever SIMD kernel it picked for the CPU (one unit in the last place
off the correctly rounded distance on about a third of a cabinet's pixels here), and the
sensor model's disparity quantisation turns such an ulp into a whole depth step now and
then, so images rendered on two CPUs differed (docs/architecture.md). Within a group,
the geometry id of a hit names the link, i.e. the part id. Only the rays inside the
image rectangle bounding a group's projected vertices are cast against it (a ray outside
cannot hit); when a vertex is at or behind the camera plane, every ray is. `render_many`
casts the rays of all of an object's configurations against a group in one call, and a
group that keeps its pose (the body) is cast once. `render_posed(..., stretches=...)` draws
the object with its body frame scaled along its axes (each group's mesh scaled in its own
frame, its joint's origin moved with the body): another depth, width or height from the
same scenes, approximately (walls, gaps and a door's thickness scale with the body), for
searches over an object's size that would otherwise build an object per size.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from artic.geometry.camera import CameraIntrinsics
from artic.geometry.transforms import invert, transform_points
from artic.objects.model import ArticulatedObject
from artic.render.backend import BackendBase, RenderedImage, register_backend
from artic.render.open3d_core import open3d_core

o3d = open3d_core()

RAYS_PER_CALL = 1 << 14  # rays batched into one cast_rays call (larger ones lose cache)
#: a cast_rays call of fewer rays runs on one thread whatever the backend's `threads`
#: (measured with the refinement on 2 cores: the drawer's line searches, 16k rays a call,
#: 10-21% faster on two; doors, mostly one window of 2-5k rays a call, no faster when
#: every call used both)
PARALLEL_RAYS = 1 << 12

#: one image's hits on a group: window rows, cols, distance (inf: none), part id + 1 (0: none)
_Hits = tuple[slice, slice, NDArray[np.float32], NDArray[np.uint8]]
#: a group's scale in its own frame (3, 3), applied to its mesh before its pose; None: none
_Stretch = NDArray[np.float64] | None


@dataclass
class _Group:
    """Links rigidly attached to `root`; meshes in the root link's frame."""

    root: int
    part_ids: NDArray[np.uint8]  # geometry id -> part id + 1 (the mask value); last: 0
    vertices: NDArray[np.float64]  # all vertices, root frame (for the window)
    scene: Any  # Open3D's t.geometry.RaycastingScene
    #: each triangle's plane n . x = c in the root frame, (n, c) rows, float64 from the
    #: float32 vertices Embree holds; geometry g's triangles start at row first[g]
    planes: NDArray[np.float64]
    first: NDArray[np.int64]
    norms: NDArray[np.float64]  # each plane's |n|
    #: the last single-pose cast, its pose and stretch, reused while the group does not move
    last: tuple[NDArray[np.float64], NDArray[np.float64] | None, _Hits] | None = None


def rigid_groups(obj: ArticulatedObject) -> list[list[int]]:
    """Link indices grouped by rigid attachment (fixed joints); each group's first
    index is the link whose pose stands for the group's."""
    parent_of = {j.child: j for j in obj.joints}
    root_of: dict[int, int] = {}
    for i, link in enumerate(obj.links):
        name = link.name
        while name in parent_of and parent_of[name].type == "fixed":
            name = parent_of[name].parent
        root_of[i] = obj.link_index(name)
    groups: dict[int, list[int]] = {}
    for i in range(len(obj.links)):
        groups.setdefault(root_of[i], [root_of[i]])
        if i != root_of[i]:
            groups[root_of[i]].append(i)
    return list(groups.values())


def _stretch(rotation: NDArray[np.float64], scale: NDArray[np.float64]) -> _Stretch:
    """A link's scale in its own frame (3, 3) when the body frame is scaled by `scale`
    (3,): R^T diag(scale) R for the link's rest `rotation` R in the body frame; None for
    a scale of ones."""
    if np.all(scale == 1.0):
        return None
    return np.asarray(rotation.T @ np.diag(scale) @ rotation)


def _same(
    pose: NDArray[np.float64], stretch: _Stretch,
    other: NDArray[np.float64], other_stretch: _Stretch,
) -> bool:  # fmt: skip
    """Whether two placements (pose and stretch) of a group are the same."""
    if stretch is None or other_stretch is None:
        same_stretch = stretch is None and other_stretch is None
    else:
        same_stretch = np.array_equal(stretch, other_stretch)
    return bool(same_stretch and np.array_equal(pose, other))


def stretched_link_poses(
    obj: ArticulatedObject,
    base_pose: NDArray[np.float64],
    configuration: NDArray[np.float64],
    stretches: Sequence[_Stretch],
) -> list[NDArray[np.float64]]:
    """Forward kinematics (`ArticulatedObject.link_poses`) of `obj` at `base_pose` with
    each link's frame scaled by `stretches` (one per link, `_stretch`): a joint's origin
    moves with its parent's scale (a door's hinge with the body's width), its rotation
    and motion do not."""
    index = {link.name: i for i, link in enumerate(obj.links)}
    joints = []
    for joint in obj.joints:
        scale = stretches[index[joint.parent]]
        origin = joint.origin.copy()
        if scale is not None:
            origin[:3, 3] = scale @ origin[:3, 3]
        joints.append(dataclasses.replace(joint, origin=origin))
    moved = dataclasses.replace(obj, joints=tuple(joints), base_pose=base_pose)
    return moved.link_poses(configuration)


def triangle_planes(corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, 3, 3) triangle corners -> (T, 4) planes (n, c) with n . x = c (n unnormalised:
    only ratios of it are used), in elementwise float64 arithmetic."""
    a, b = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    n = np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                  a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                  a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)  # fmt: skip
    return np.concatenate([n, _dot(n, corners[:, 0])[:, None]], axis=1)


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Dot products over the last axis (length 3) of broadcast arrays, summed in a fixed
    order: elementwise products and sums are correctly rounded on any CPU, unlike a BLAS
    or SIMD reduction, whose order and fused multiply-adds depend on the kernel."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _linear(pose: NDArray[np.float64], stretch: _Stretch) -> NDArray[np.float64]:
    """(3, 3) L taking a camera-frame direction d into the group's mesh frame as d @ L (and
    a mesh plane's normal n into the camera frame as L n): the pose's rotation R, or
    R M^-1 for a group scaled by the symmetric M in its own frame."""
    rotation = pose[:3, :3]
    return rotation if stretch is None else rotation @ np.linalg.inv(stretch)


def _plane_distances(
    group: _Group,
    poses: NDArray[np.float64],
    pose_of_ray: NDArray[np.int64],
    across: tuple[NDArray[np.float64], NDArray[np.float64]],
    geometry: NDArray[np.uint32],
    primitive: NDArray[np.uint32],
    t_embree: NDArray[np.float32],
) -> NDArray[np.float32]:
    """The depth of each camera ray (direction (1, dy, dz); `across`: (dy, dz), float64),
    cast at the group's pose `poses[pose_of_ray]` ((P, 4, 4) group to camera; a stretched
    group's carries `_linear`'s R M^-1 in place of its rotation, as normals move by it), on the
    plane of the triangle Embree hit, in float64 rounded to float32 (inf where Embree
    found none). The group's triangle planes are moved into the camera frame at each pose
    (n' = R n, c' = c + n' . t; elementwise, a fixed order) and the depth is c' / (n' . d),
    computed for the hits only. A ray (nearly) parallel to its triangle keeps Embree's
    distance."""
    hit = np.flatnonzero(np.isfinite(t_embree))
    t = np.full(len(t_embree), np.inf, dtype=np.float32)
    if len(hit) == 0:
        return t
    n, rotation, shift = group.planes[None, :, :3], poses[:, None, :3, :3], poses[:, None, :3, 3]
    nx, ny, nz = (_dot(n, rotation[..., i, :]) for i in range(3))  # (P, T) each
    offsets = (
        group.planes[None, :, 3] + (nx * shift[..., 0] + ny * shift[..., 1] + nz * shift[..., 2])
    ).ravel()
    normals = (nx.ravel(), ny.ravel(), nz.ravel())
    triangle = group.first.take(geometry.take(hit)) + primitive.take(hit)
    index = pose_of_ray.take(hit) * len(group.planes) + triangle  # into the (P T,) arrays
    along = (normals[0].take(index) + normals[1].take(index) * across[0].take(hit)
             + normals[2].take(index) * across[1].take(hit))  # fmt: skip
    meets = np.abs(along) > 1e-9 * group.norms.take(triangle)  # else (nearly) parallel
    exact = offsets.take(index) / np.where(meets, along, 1.0)
    t[hit] = np.where(meets, exact, t_embree.take(hit))
    return t


@register_backend("raycast")
class RaycastBackend(BackendBase):
    """Open3D ray casting; scenes cached for the most recent object's geometry (its
    links and joints, by identity: the scenes are built in each rigid group's own frame,
    so the same object at another `base_pose`, `dataclasses.replace(obj, base_pose=...)`,
    reuses them)."""

    def __init__(self, camera: CameraIntrinsics, threads: int = 1) -> None:
        self.camera = camera
        self.threads = threads
        self._directions = camera.ray_directions()
        #: each pixel's ray direction's y and z (its x is 1), float64
        self._across = (self._directions[..., 1].astype(np.float64),
                        self._directions[..., 2].astype(np.float64))  # fmt: skip
        self._object: ArticulatedObject | None = None
        self._groups: list[_Group] = []

    def _scenes(self, obj: ArticulatedObject) -> list[_Group]:
        last = self._object
        if last is not None and last.links is obj.links and last.joints is obj.joints:
            return self._groups
        rest = obj.link_poses(np.zeros(obj.dof))
        groups = []
        for members in rigid_groups(obj):
            to_root = invert(rest[members[0]])
            scene = o3d.t.geometry.RaycastingScene(nthreads=self.threads)
            vertices, planes = [], []
            for i in members:
                local = transform_points(to_root @ rest[i], obj.links[i].mesh.vertices)
                held = local.astype(np.float32)
                # C order: Open3D copies any other layout element by element (~10 ms for a
                # microwave's body, where the scene's build is ~0.1 ms)
                triangles = np.ascontiguousarray(obj.links[i].mesh.triangles, dtype=np.uint32)
                scene.add_triangles(o3d.core.Tensor(held), o3d.core.Tensor(triangles))
                vertices.append(local)
                planes.append(triangle_planes(held.astype(np.float64)[triangles]))
            part_ids = np.array([*(i + 1 for i in members), 0], dtype=np.uint8)
            first = np.cumsum([0, *(len(p) for p in planes)], dtype=np.int64)
            every = np.concatenate(planes)
            norms = np.sqrt(_dot(every[:, :3], every[:, :3]))
            groups.append(_Group(members[0], part_ids, np.concatenate(vertices), scene,
                                 every, first, norms))  # fmt: skip
        self._object, self._groups = obj, groups
        return groups

    def render(
        self,
        obj: ArticulatedObject,
        configuration: NDArray[np.float64],
        urdf_path: Path | None = None,
    ) -> RenderedImage:
        q = np.asarray(configuration, dtype=np.float64).reshape(1, -1)
        return self.render_many(obj, q, urdf_path)[0]

    def render_many(
        self,
        obj: ArticulatedObject,
        configurations: NDArray[np.float64],
        urdf_path: Path | None = None,
    ) -> list[RenderedImage]:
        qs = np.asarray(configurations, dtype=np.float64).reshape(len(configurations), -1)
        return self._render_link_poses(obj, [obj.link_poses(q) for q in qs])

    def render_posed(
        self,
        obj: ArticulatedObject,
        base_poses: Sequence[NDArray[np.float64]],
        configurations: NDArray[np.float64],
        stretches: NDArray[np.float64] | None = None,
    ) -> list[RenderedImage]:
        """The images of `obj` at each (4, 4) base pose with its configuration (one row of
        `configurations` each), cast together as `render_many`'s: the same images as
        rendering `dataclasses.replace(obj, base_pose=...)` one at a time. `stretches`
        (N, 3): each image's scale of the body frame's x, y, z (module docstring); a row
        of ones gives the unstretched image."""
        qs = np.asarray(configurations, dtype=np.float64).reshape(len(configurations), -1)
        if stretches is None:
            poses = [dataclasses.replace(obj, base_pose=base).link_poses(q)
                     for base, q in zip(base_poses, qs, strict=True)]  # fmt: skip
            return self._render_link_poses(obj, poses)
        scales = np.asarray(stretches, dtype=np.float64).reshape(len(qs), 3)
        rest = obj.link_poses(np.zeros(obj.dof))
        to_body = [invert(obj.base_pose) @ pose for pose in rest]
        frames = [[_stretch(b[:3, :3], scale) for b in to_body] for scale in scales]
        poses = [stretched_link_poses(obj, base, q, f)
                 for base, q, f in zip(base_poses, qs, frames, strict=True)]  # fmt: skip
        return self._render_link_poses(obj, poses, frames)

    def _render_link_poses(
        self,
        obj: ArticulatedObject,
        poses: list[list[NDArray[np.float64]]],
        stretches: list[list[_Stretch]] | None = None,
    ) -> list[RenderedImage]:
        """One image per entry of `poses` (each: every link's camera-frame pose), each
        link's frame scaled by `stretches` (the same shape; None: none)."""
        n, shape = len(poses), (self.camera.height, self.camera.width)
        depth = np.full((n, *shape), np.inf, dtype=np.float32)
        mask = np.zeros((n, *shape), dtype=np.uint8)
        for group in self._scenes(obj):
            group_poses = [p[group.root] for p in poses]
            scaled: list[_Stretch] = (
                [None] * n if stretches is None else [f[group.root] for f in stretches]
            )
            for k, (rows, cols, t, parts) in enumerate(self._cast(group, group_poses, scaled)):
                if t.size == 0:
                    continue
                nearer = t < depth[k, rows, cols]
                np.copyto(depth[k, rows, cols], t, where=nearer)
                np.copyto(mask[k, rows, cols], parts, where=nearer)
        depth[depth == np.inf] = 0.0
        return [RenderedImage(d, m) for d, m in zip(depth, mask, strict=True)]

    def _cast(
        self, group: _Group, poses: list[NDArray[np.float64]], stretches: list[_Stretch]
    ) -> list[_Hits]:
        """The group's hits at each pose (and stretch): one cast_rays call for all poses.
        A group that keeps one pose (the body) is cast once, or not at all if it has not
        moved since the previous call."""
        if all(_same(p, m, poses[0], stretches[0]) for p, m in zip(poses, stretches, strict=True)):
            last = group.last
            if last is None or not _same(last[0], last[1], poses[0], stretches[0]):
                hits = self._cast_poses(group, poses[:1], stretches[:1])[0]
                last = group.last = (poses[0], stretches[0], hits)
            return [last[2]] * len(poses)
        return self._cast_poses(group, poses, stretches)

    def _cast_poses(
        self, group: _Group, poses: list[NDArray[np.float64]], stretches: list[_Stretch]
    ) -> list[_Hits]:
        windows = self._windows(group.vertices, poses, stretches)
        out: list[_Hits] = []
        batch: list[tuple[slice, slice, NDArray[np.float64]]] = []
        size = 0
        for (rows, cols), pose, stretch in zip(windows, poses, stretches, strict=True):
            if stretch is not None:  # rays and normals move by R M^-1 (`_linear`)
                pose = pose.copy()
                pose[:3, :3] = _linear(pose, stretch)
            batch.append((rows, cols, pose))
            size += (rows.stop - rows.start) * (cols.stop - cols.start)
            if size >= RAYS_PER_CALL:
                out += self._cast_batch(group, batch)
                batch, size = [], 0
        return out + self._cast_batch(group, batch) if batch else out

    def _cast_batch(
        self, group: _Group, batch: list[tuple[slice, slice, NDArray[np.float64]]]
    ) -> list[_Hits]:
        """Hits for each (window, pose) of `batch`, from one cast_rays call."""
        chunks, shapes = [], []
        for rows, cols, pose in batch:
            window = self._directions[rows, cols]
            shapes.append(window.shape[:2])
            # camera rays in the group frame: origin R^T (0 - t), direction R^T d (float32:
            # they only choose the triangle, `_plane_distances` gives the distance)
            rays = np.empty((shapes[-1][0] * shapes[-1][1], 6), dtype=np.float32)
            rays[:, :3] = -(pose[:3, 3] @ pose[:3, :3])
            np.matmul(window.reshape(-1, 3), pose[:3, :3].astype(np.float32), out=rays[:, 3:])
            chunks.append(rays)
        if sum(len(c) for c in chunks) == 0:
            empty = (np.zeros((0, 0), np.float32), np.zeros((0, 0), np.uint8))
            return [(rows, cols, *empty) for rows, cols, _ in batch]
        every = np.concatenate(chunks)
        threads = self.threads if len(every) >= PARALLEL_RAYS else 1
        hits = group.scene.cast_rays(o3d.core.Tensor.from_numpy(every), nthreads=threads)
        geometry_all = hits["geometry_ids"].numpy()
        primitive_all = hits["primitive_ids"].numpy()
        t_embree = hits["t_hit"].numpy()
        # misses carry Open3D's invalid id (2^32 - 1): clipped onto part_ids' trailing 0
        parts_all = np.take(group.part_ids, geometry_all, mode="clip")
        sizes = [shape[0] * shape[1] for shape in shapes]
        dy, dz = (np.concatenate([a[rows, cols].ravel() for rows, cols, _ in batch])
                  for a in self._across)  # fmt: skip
        t_all = _plane_distances(
            group, np.stack([pose for _, _, pose in batch]),
            np.repeat(np.arange(len(batch)), sizes), (dy, dz),
            geometry_all, primitive_all, t_embree,
        )  # fmt: skip
        out: list[_Hits] = []
        start = 0
        for (rows, cols, _), shape, size in zip(batch, shapes, sizes, strict=True):
            stop = start + size
            t, parts = t_all[start:stop].reshape(shape), parts_all[start:stop].reshape(shape)
            out.append((rows, cols, t, parts))
            start = stop
        return out

    def _windows(
        self, vertices: NDArray[np.float64], poses: list[NDArray[np.float64]],
        stretches: list[_Stretch],
    ) -> list[tuple[slice, slice]]:  # fmt: skip
        """Rows and columns of the pixels whose rays may hit the convex hull of `vertices`
        (V, 3) at each pose (and stretch), a pixel's margin around its projection (so a
        last bit of rounding in the projection never drops a pixel a ray can hit): all
        poses' points at once."""
        h, w, cam = self.camera.height, self.camera.width, self.camera
        if any(m is not None for m in stretches):
            points = np.stack([transform_points(p, vertices if m is None else vertices @ m)
                               for p, m in zip(poses, stretches, strict=True)])  # fmt: skip
        else:
            stack = np.stack(poses)
            points = vertices @ stack[:, :3, :3].transpose(0, 2, 1) + stack[:, None, :3, 3]
        x = points[..., 0]
        behind = x.min(axis=1) <= 1e-6  # at or behind the camera plane
        x = np.where(behind[:, None], 1.0, x)
        u = cam.cx - cam.fx * points[..., 1] / x
        v = cam.cy - cam.fy * points[..., 2] / x
        out = []
        for k, (u0, u1, v0, v1) in enumerate(zip(u.min(axis=1).tolist(), u.max(axis=1).tolist(),
                                                 v.min(axis=1).tolist(), v.max(axis=1).tolist(),
                                                 strict=True)):  # fmt: skip
            if behind[k]:
                out.append((slice(0, h), slice(0, w)))
                continue
            rows = slice(max(math.floor(v0) - 1, 0), min(math.ceil(v1) + 2, h))
            out.append((rows, slice(max(math.floor(u0) - 1, 0), min(math.ceil(u1) + 2, w))))
        return out

    def close(self) -> None:
        self._object, self._groups = None, []
