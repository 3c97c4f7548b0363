"""Labelled point clouds of articulated objects, the input of Chapter 4's networks.

Two kinds, both in the object frame (the root link's frame: base at the centre of the
body's bottom face, z up, front facing -x) with a part id and a motion type per point:

- clean clouds: points drawn uniformly over the surface of the posed link meshes
  (area-weighted), as PartNet samples its shapes (Mo et al. 2019; section 4.3);
- fused scans: K depth views from around the object's front hemisphere, each passed
  through the Kinect sensor model (`render.noise`), back-projected with the camera,
  moved into the object frame and merged on a voxel grid, a synthetic stand-in for the
  RTAB-Map scans of section 4.5.3.

Part ids are link indices (0 = the root body); a handle is its own part, as in PartNet
and PartNet-Mobility. A part's motion type is the type of the joint to its parent
(`MOTION_TYPES` of `artic.objects.tree`: 0 static, 1 rotating, 2 translating,
3 both), so a handle on its fixed joint is static (it moves only through its parent,
which the tree edge records). Pure functions: no file access; randomness from the
`np.random.Generator` passed in.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field

from artic.geometry.camera import CameraIntrinsics
from artic.geometry.transforms import invert, transform_points
from artic.objects.model import ArticulatedObject
from artic.objects.tree import JOINT_TYPE_OF_MOTION, JointAxis, JointType, KinematicTree
from artic.render.backend import DepthBackend
from artic.render.noise import SensorNoiseConfig, apply_sensor_noise

#: motion type of a part from the type of the joint to its parent (root: static)
MOTION_OF_JOINT = {"fixed": 0, "revolute": 1, "continuous": 1, "prismatic": 2}
_KEY_BITS = 21  # bits per voxel coordinate in a packed voxel key (+-2^20 voxels)
_CROP_MARGIN_PX = 3  # background kept around the object when applying sensor noise


class LabelledCloud(NamedTuple):
    """points: (N, 3) float32, metres, object frame. part_id: (N,) int64, link index.
    motion_type: (N,) int64, 0 static, 1 rotating, 2 translating, 3 both."""

    points: NDArray[np.float32]
    part_id: NDArray[np.int64]
    motion_type: NDArray[np.int64]


class ScanViewConfig(BaseModel):
    """Where the K scan cameras stand (object frame, around the -x front)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    views: int = Field(6, gt=0, description="depth views fused into one scan")
    azimuth_deg: tuple[float, float] = Field(
        (-70.0, 70.0), description="azimuth range of the views about +z, 0 = straight in front"
    )
    elevations_deg: tuple[float, ...] = Field(
        (15.0, 40.0), min_length=1, description="view elevations, cycled over the views"
    )
    distance_m: float = Field(1.5, gt=0, description="least camera distance to the centre, m")
    fit_margin: float = Field(
        1.1, ge=1.0, description="the object's bounding sphere times this fits in the image"
    )


class FusionConfig(BaseModel):
    """How the back-projected views merge into one cloud."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    voxel_m: float = Field(0.01, gt=0, description="voxel grid spacing, metres")
    max_points: int = Field(
        10000, ge=0, description="keep at most this many points, drawn at random (0: all)"
    )


def part_motion_types(obj: ArticulatedObject) -> NDArray[np.int64]:
    """(P,) motion type of each link: that of the joint to its parent, 0 for the root."""
    out = np.zeros(len(obj.links), dtype=np.int64)
    for joint in obj.joints:
        out[obj.link_index(joint.child)] = MOTION_OF_JOINT[joint.type]
    return out


def object_tree(
    obj: ArticulatedObject, motion_types: NDArray[np.int64] | None = None
) -> KinematicTree:
    """The object's kinematic tree over its parts (links), the ground truth of section
    4.4.1: one edge per joint (parent link -> child link, in joint order), URDF joint
    types (continuous -> revolute), the axes of the movable joints at configuration 0 in
    the object frame (None on fixed edges). motion_types: (P,), default
    `part_motion_types(obj)`."""
    motion = part_motion_types(obj) if motion_types is None else motion_types
    poses = obj.link_poses(np.zeros(obj.dof))
    to_object = invert(poses[0])
    edges: list[tuple[int, int]] = []
    kinds: list[JointType] = []
    axes: list[JointAxis | None] = []
    for joint in obj.joints:
        parent, child = obj.link_index(joint.parent), obj.link_index(joint.child)
        edges.append((parent, child))
        kinds.append(JOINT_TYPE_OF_MOTION[MOTION_OF_JOINT[joint.type]])
        if joint.type == "fixed":
            axes.append(None)
            continue
        frame = to_object @ poses[parent] @ joint.origin
        direction = frame[:3, :3] @ joint.axis
        axes.append(JointAxis(frame[:3, 3].copy(), direction / np.linalg.norm(direction)))
    return KinematicTree(
        num_parts=len(obj.links),
        root=0,
        edges=tuple(edges),
        motion_types=tuple(int(m) for m in motion),
        joint_types=tuple(kinds),
        axes=tuple(axes),
    )


def object_frame_meshes(
    obj: ArticulatedObject, configuration: NDArray[np.float64]
) -> list[tuple[NDArray[np.float64], NDArray[np.int32]]]:
    """Each link's (vertices (V, 3) float64 metres, triangles (F, 3)) posed at
    `configuration` (dof,), in the object (root link) frame."""
    poses = obj.link_poses(configuration)
    to_object = invert(poses[0])
    return [
        (transform_points(to_object @ pose, link.mesh.vertices), link.mesh.triangles)
        for link, pose in zip(obj.links, poses, strict=True)
    ]


def sample_surface(
    obj: ArticulatedObject,
    configuration: NDArray[np.float64],
    n: int,
    rng: np.random.Generator,
    motion_types: NDArray[np.int64] | None = None,
) -> LabelledCloud:
    """n points uniform over the surface of the object posed at `configuration`:
    triangles drawn with probability proportional to area, then a uniform point in the
    triangle (barycentric u = 1 - sqrt(r1), v = sqrt(r1)(1 - r2), w = sqrt(r1) r2).

    motion_types: (P,) per part; default `part_motion_types(obj)`.
    """
    motion = part_motion_types(obj) if motion_types is None else motion_types
    meshes = object_frame_meshes(obj, configuration)
    corners = np.concatenate([v[t] for v, t in meshes])  # (F, 3, 3)
    owner = np.concatenate([np.full(len(t), i, dtype=np.int64) for i, (_, t) in enumerate(meshes)])
    edge1, edge2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    area = 0.5 * np.linalg.norm(np.cross(edge1, edge2), axis=1)
    face = rng.choice(len(area), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)[:, None]
    points = corners[face, 0] + s * (1.0 - r2[:, None]) * edge1[face]
    points += s * r2[:, None] * edge2[face]
    part = owner[face]
    return LabelledCloud(points.astype(np.float32), part, motion[part])


def look_at(eye: NDArray[np.float64], target: NDArray[np.float64]) -> NDArray[np.float64]:
    """(4, 4) pose of a camera at `eye` looking at `target`, in the thesis' camera body
    convention (x forward, y left, z up; the image's up is as close to +z as it can be)."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    left = np.cross([0.0, 0.0, 1.0], forward)
    if np.linalg.norm(left) < 1e-9:  # looking straight down or up
        left = np.array([0.0, 1.0, 0.0])
    left /= np.linalg.norm(left)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2] = forward, left, np.cross(forward, left)
    pose[:3, 3] = eye
    return pose


def view_poses(
    obj: ArticulatedObject,
    configurations: NDArray[np.float64],
    camera: CameraIntrinsics,
    cfg: ScanViewConfig,
) -> NDArray[np.float64]:
    """(K, 4, 4) camera poses in the object frame, looking at the centre of the box
    bounding the object over `configurations` (n, dof). View k is at azimuth
    linspace(azimuth_deg)[k] from the front (-x), elevation elevations_deg[k mod E], at
    the larger of `distance_m` and the distance at which the bounding sphere (times
    `fit_margin`) fits in the narrower half field of view."""
    vertices = np.concatenate(
        [v for q in np.atleast_2d(configurations) for v, _ in object_frame_meshes(obj, q)]
    )
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(vertices - centre, axis=1).max())
    half_fov = min(
        math.atan(min(camera.cx, camera.width - 1 - camera.cx) / camera.fx),
        math.atan(min(camera.cy, camera.height - 1 - camera.cy) / camera.fy),
    )
    distance = max(cfg.distance_m, cfg.fit_margin * radius / math.sin(half_fov))
    azimuths = np.radians(np.linspace(*cfg.azimuth_deg, cfg.views))
    poses = []
    for k, azimuth in enumerate(azimuths):
        elevation = math.radians(cfg.elevations_deg[k % len(cfg.elevations_deg)])
        direction = np.array(
            [
                -math.cos(elevation) * math.cos(azimuth),
                -math.cos(elevation) * math.sin(azimuth),
                math.sin(elevation),
            ]
        )
        poses.append(look_at(centre + distance * direction, centre))
    return np.stack(poses)


class _Voxels(NamedTuple):
    """Per occupied voxel: packed key (V,), coordinate sums (V, 3), point counts (V,),
    points per part (V, P)."""

    keys: NDArray[np.int64]
    sums: NDArray[np.float64]
    counts: NDArray[np.float64]
    parts: NDArray[np.float64]


def _voxelise(
    points: NDArray[np.float64], part_id: NDArray[np.int64], n_parts: int, spacing: float
) -> _Voxels:
    cells = np.floor(points / spacing).astype(np.int64) + (1 << (_KEY_BITS - 1))
    if cells.size and (cells.min() < 0 or cells.max() >= 1 << _KEY_BITS):
        raise ValueError(f"points span more than 2^{_KEY_BITS} voxels of {spacing} m")
    keys = (cells[:, 0] << (2 * _KEY_BITS)) | (cells[:, 1] << _KEY_BITS) | cells[:, 2]
    unique, inverse = np.unique(keys, return_inverse=True)
    v = len(unique)
    sums = np.stack(
        [np.bincount(inverse, points[:, i], minlength=v) for i in range(3)], axis=1
    ).astype(np.float64)
    parts = np.bincount(inverse * n_parts + part_id, minlength=v * n_parts)
    counts = np.bincount(inverse, minlength=v).astype(np.float64)
    return _Voxels(unique, sums, counts, parts.reshape(v, n_parts).astype(np.float64))


def _merge(grids: list[_Voxels]) -> _Voxels:
    """Sum the voxels of several grids that share a key (sorted by key)."""
    keys = np.concatenate([g.keys for g in grids])
    unique, inverse = np.unique(keys, return_inverse=True)
    v = len(unique)

    def add(values: NDArray[np.float64]) -> NDArray[np.float64]:
        cols = values.reshape(len(keys), -1)
        return np.stack(
            [np.bincount(inverse, weights=cols[:, i], minlength=v) for i in range(cols.shape[1])],
            axis=1,
        )

    return _Voxels(
        unique,
        add(np.concatenate([g.sums for g in grids])),
        add(np.concatenate([g.counts for g in grids]))[:, 0],
        add(np.concatenate([g.parts for g in grids])),
    )


def voxel_downsample(
    points: NDArray[np.floating], part_id: NDArray[np.int64], n_parts: int, spacing: float
) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
    """One point per occupied voxel of a grid of `spacing` metres: the centroid of its
    points, labelled with their most frequent part (ties: the lower id); (M, 3) float32
    and (M,) int64, ordered by voxel."""
    vox = _voxelise(np.asarray(points, dtype=np.float64), part_id, n_parts, spacing)
    return _finish(vox)


def _finish(vox: _Voxels) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
    centroids = (vox.sums / vox.counts[:, None]).astype(np.float32)
    return centroids, np.argmax(vox.parts, axis=1).astype(np.int64)


def _crop(mask: NDArray[np.uint8]) -> tuple[slice, slice]:
    """The rows and columns around the seen object, with a background margin (the
    sensor model only moves depth between neighbouring pixels, so noise applied to the
    crop is noise applied to the image)."""
    rows, cols = np.nonzero(np.any(mask > 0, axis=1))[0], np.nonzero(np.any(mask > 0, axis=0))[0]
    m = _CROP_MARGIN_PX
    return (
        slice(max(int(rows[0]) - m, 0), int(rows[-1]) + m + 1),
        slice(max(int(cols[0]) - m, 0), int(cols[-1]) + m + 1),
    )


def _back_project(
    depth: NDArray[np.float32],
    mask: NDArray[np.uint8],
    window: tuple[slice, slice],
    camera: CameraIntrinsics,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Camera-frame points (M, 3) and part ids (M,) of the window's pixels that have a
    depth and an object label."""
    vv, uu = np.nonzero((depth > 0) & (mask > 0))
    z = depth[vv, uu].astype(np.float64)
    v = vv + window[0].start
    u = uu + window[1].start
    points = np.stack([z, -(u - camera.cx) * z / camera.fx, -(v - camera.cy) * z / camera.fy], 1)
    return points, mask[vv, uu].astype(np.int64) - 1


def fuse_views_many(
    obj: ArticulatedObject,
    configurations: NDArray[np.float64],
    camera_poses: NDArray[np.float64],
    backend: DepthBackend,
    noise: SensorNoiseConfig,
    rng: np.random.Generator,
    fusion: FusionConfig,
    motion_types: NDArray[np.int64] | None = None,
) -> list[LabelledCloud]:
    """One fused scan per row of `configurations` (n, dof).

    For each view k (camera_poses (K, 4, 4), object frame) the object is rendered at
    every configuration from that camera (`backend`, its `camera`), each depth image
    passes through the sensor model (noise drawn from `rng`, views outer, configurations
    inner), and the pixels with a depth and a part label in the noise-free part mask
    are back-projected, moved into the object frame and summed into a voxel grid.
    Then each scan is one centroid per voxel labelled by majority, and at most
    `fusion.max_points` of them are kept (a random subset, in voxel order).
    """
    motion = part_motion_types(obj) if motion_types is None else motion_types
    qs = np.atleast_2d(np.asarray(configurations, dtype=np.float64))
    n_parts = len(obj.links)
    camera = backend.camera
    grids: list[list[_Voxels]] = [[] for _ in qs]
    for pose in camera_poses:
        # the object placed in this camera's frame: object-to-camera = pose^-1
        view = dataclasses.replace(obj, base_pose=invert(pose))
        for k, image in enumerate(backend.render_many(view, qs)):
            if not image.part_mask.any():
                continue
            window = _crop(image.part_mask)
            depth = apply_sensor_noise(image.depth[window], noise, rng, camera.fx)
            seen, part = _back_project(depth, image.part_mask[window], window, camera)
            if len(seen):
                grids[k].append(
                    _voxelise(transform_points(pose, seen), part, n_parts, fusion.voxel_m)
                )
    clouds = []
    for grid in grids:
        if grid:
            points, part = _finish(_merge(grid))
        else:
            points, part = np.zeros((0, 3), np.float32), np.zeros(0, np.int64)
        if 0 < fusion.max_points < len(points):
            keep = np.sort(rng.choice(len(points), fusion.max_points, replace=False))
            points, part = points[keep], part[keep]
        clouds.append(LabelledCloud(points, part, motion[part]))
    return clouds


def fuse_views(
    obj: ArticulatedObject,
    configuration: NDArray[np.float64],
    camera_poses: NDArray[np.float64],
    backend: DepthBackend,
    noise: SensorNoiseConfig,
    rng: np.random.Generator,
    fusion: FusionConfig,
    motion_types: NDArray[np.int64] | None = None,
) -> LabelledCloud:
    """The fused scan of the object at one `configuration` (dof,): `fuse_views_many`."""
    q = np.asarray(configuration, dtype=np.float64).reshape(1, -1)
    return fuse_views_many(obj, q, camera_poses, backend, noise, rng, fusion, motion_types)[0]
