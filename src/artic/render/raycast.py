"""Depth by ray casting the object's link meshes with Open3D's RaycastingScene.

A scene cannot move its geometry, and building one (Embree's BVH) costs more than
casting an image's rays. So the links are split into rigid groups (links joined by fixed
joints move together) and each group gets one scene, built once per object in the
group's own frame; an image casts the camera rays, moved into each group's frame at the
configuration, against each group's scene and keeps the nearest hit. A rigid motion
keeps ray parameters, and the rays have unit forward (x) component, so the hit
distance is the depth along the optical axis. Within a group, the geometry id of a hit
names the link, i.e. the part id. Only the rays inside the image rectangle bounding a
group's projected vertices are cast against it (a ray outside cannot hit); when a
vertex is at or behind the camera plane, every ray is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

from artic.geometry.camera import CameraIntrinsics
from artic.geometry.transforms import invert, transform_points
from artic.objects.model import ArticulatedObject
from artic.render.backend import BackendBase, RenderedImage, register_backend

_Cast = tuple[NDArray[np.float64], slice, slice, NDArray[np.float32], NDArray[np.uint8]]


@dataclass
class _Group:
    """Links rigidly attached to `root`; meshes in the root link's frame."""

    root: int
    part_ids: NDArray[np.uint8]  # geometry id -> part id + 1 (the mask value); last: 0
    vertices: NDArray[np.float64]  # all vertices, root frame (for the window)
    scene: o3d.t.geometry.RaycastingScene
    #: the last cast: pose, window, hit distances and geometry ids (reused while the
    #: group has not moved, e.g. the body across an object's configurations)
    last: (
        tuple[NDArray[np.float64], slice, slice, NDArray[np.float32], NDArray[np.uint8]] | None
    ) = None


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


@register_backend("raycast")
class RaycastBackend(BackendBase):
    """Open3D ray casting; scenes cached for the most recent object."""

    def __init__(self, camera: CameraIntrinsics, threads: int = 1) -> None:
        self.camera = camera
        self.threads = threads
        self._directions = camera.ray_directions()
        self._object: ArticulatedObject | None = None
        self._groups: list[_Group] = []

    def _scenes(self, obj: ArticulatedObject) -> list[_Group]:
        if self._object is obj:
            return self._groups
        rest = obj.link_poses(np.zeros(obj.dof))
        groups = []
        for members in rigid_groups(obj):
            to_root = invert(rest[members[0]])
            scene = o3d.t.geometry.RaycastingScene(nthreads=self.threads)
            vertices = []
            for i in members:
                local = transform_points(to_root @ rest[i], obj.links[i].mesh.vertices)
                scene.add_triangles(
                    o3d.core.Tensor(local.astype(np.float32)),
                    o3d.core.Tensor(obj.links[i].mesh.triangles.astype(np.uint32)),
                )
                vertices.append(local)
            part_ids = np.array([*(i + 1 for i in members), 0], dtype=np.uint8)
            groups.append(_Group(members[0], part_ids, np.concatenate(vertices), scene))
        self._object, self._groups = obj, groups
        return groups

    def render(
        self,
        obj: ArticulatedObject,
        configuration: NDArray[np.float64],
        urdf_path: Path | None = None,
    ) -> RenderedImage:
        poses = obj.link_poses(configuration)
        shape = (self.camera.height, self.camera.width)
        depth = np.full(shape, np.inf, dtype=np.float32)
        mask = np.zeros(shape, dtype=np.uint8)
        for group in self._scenes(obj):
            pose = poses[group.root]
            if group.last is not None and np.array_equal(group.last[0], pose):
                _, rows, cols, t, parts = group.last
            else:
                rows, cols, t, parts = self._cast(group, pose)
                group.last = (pose, rows, cols, t, parts)
            if t.size == 0:
                continue
            nearer = t < depth[rows, cols]
            np.copyto(depth[rows, cols], t, where=nearer)
            np.copyto(mask[rows, cols], parts, where=nearer)
        depth[~np.isfinite(depth)] = 0.0
        return RenderedImage(depth, mask)

    def _cast(
        self, group: _Group, pose: NDArray[np.float64]
    ) -> tuple[slice, slice, NDArray[np.float32], NDArray[np.uint8]]:
        """Cast the rays of the group's window at `pose`: rows, cols, hit distance (inf:
        no hit) and part id + 1 (0: no hit) over the window."""
        rows, cols = self._window(transform_points(pose, group.vertices))
        if rows.start >= rows.stop or cols.start >= cols.stop:
            return rows, cols, np.zeros(0, np.float32), np.zeros(0, np.uint8)
        window = self._directions[rows, cols]
        # camera rays in the group frame: origin R^T (0 - t), direction R^T d
        rays = np.empty((window.shape[0] * window.shape[1], 6), dtype=np.float32)
        rays[:, :3] = -(pose[:3, 3] @ pose[:3, :3])
        np.matmul(window.reshape(-1, 3), pose[:3, :3].astype(np.float32), out=rays[:, 3:])
        hits = group.scene.cast_rays(o3d.core.Tensor.from_numpy(rays), nthreads=self.threads)
        t = hits["t_hit"].numpy().reshape(window.shape[:2])
        ids = hits["geometry_ids"].numpy().reshape(window.shape[:2])
        # misses carry Open3D's invalid id (2^32 - 1): clipped onto the trailing 0
        parts = np.take(group.part_ids, ids, mode="clip")
        return rows, cols, t, parts

    def _window(self, points: NDArray[np.float64]) -> tuple[slice, slice]:
        """Rows and columns of the pixels whose rays may hit the convex hull of `points`."""
        h, w = self.camera.height, self.camera.width
        if points[:, 0].min() <= 1e-6:
            return slice(0, h), slice(0, w)
        uv = self.camera.project(points)
        u0, v0 = uv.min(axis=0).tolist()
        u1, v1 = uv.max(axis=0).tolist()
        rows = slice(max(math.floor(v0) - 1, 0), min(math.ceil(v1) + 2, h))
        return rows, slice(max(math.floor(u0) - 1, 0), min(math.ceil(u1) + 2, w))

    def close(self) -> None:
        self._object, self._groups = None, []
