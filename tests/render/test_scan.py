"""Clean surface samples and fused multi-view scans (src/artic/render/scan.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
import yaml

from artic.geometry.camera import CameraIntrinsics
from artic.objects.categories import build
from artic.objects.model import ArticulatedObject
from artic.objects.spec import CategoryConfig, sample_spec
from artic.render.backend import make_backend
from artic.render.noise import SensorNoiseConfig
from artic.render.scan import (
    FusionConfig,
    ScanViewConfig,
    fuse_views,
    fuse_views_many,
    object_frame_meshes,
    object_tree,
    part_motion_types,
    sample_surface,
    view_poses,
    voxel_downsample,
)

CONF = Path(__file__).resolve().parents[2] / "conf" / "common" / "category"
SPEC_CAMERA = CameraIntrinsics(fx=140, fy=140, cx=63.5, cy=63.5, width=128, height=128)
# a small camera keeps the fused scans fast; the pixel footprint is ~1 cm at 2 m
CAMERA = CameraIntrinsics(fx=200, fy=200, cx=99.5, cy=74.5, width=200, height=150)
CLEAN = SensorNoiseConfig(enabled=False)


def make_object(category: str, index: int = 0) -> ArticulatedObject:
    cfg = CategoryConfig.model_validate(yaml.safe_load((CONF / f"{category}.yaml").read_text()))
    return build(sample_spec(cfg, SPEC_CAMERA, index, np.random.default_rng([0, index])))


def open_configuration(obj: ArticulatedObject, fraction: float = 0.6) -> np.ndarray:
    return np.array(
        [lo + fraction * (hi - lo) for lo, hi in (j.limits for j in obj.movable_joints)]
    )


def link_distances(obj: ArticulatedObject, q: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N, P) distance of each point to each link's posed surface, metres."""
    out = []
    for vertices, triangles in object_frame_meshes(obj, q):
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(
            o3d.core.Tensor(vertices.astype(np.float32)),
            o3d.core.Tensor(triangles.astype(np.uint32)),
        )
        out.append(scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy())
    return np.stack(out, axis=1)


@pytest.fixture(scope="module")
def cabinet2() -> ArticulatedObject:
    return make_object("cabinet2")


@pytest.fixture(scope="module")
def drawer() -> ArticulatedObject:
    return make_object("drawer")


def test_motion_types_and_tree_follow_the_joints(cabinet2, drawer):
    # body, door_0, handle_0, door_1, handle_1: handles are parts of their own, static
    assert part_motion_types(cabinet2).tolist() == [0, 1, 0, 1, 0]
    assert part_motion_types(drawer).tolist() == [0, 2, 0]
    tree = object_tree(cabinet2)
    assert tree.root == 0 and tree.edges == ((0, 1), (1, 2), (0, 3), (3, 4))
    assert tree.joint_types == ("revolute", "fixed", "revolute", "fixed")
    assert tree.axes is not None and tree.axes[1] is None
    assert abs(abs(tree.axes[0].direction[2]) - 1) < 1e-12  # vertical hinges
    drawer_axis = object_tree(drawer).axes[0]  # type: ignore[index]
    assert np.allclose(drawer_axis.direction, [-1, 0, 0])  # pulled out towards the front
    # the hinge of door_0 lies on the body's front (x = -depth / 2) in the object frame
    front = min(v[:, 0].min() for v, _ in object_frame_meshes(cabinet2, np.zeros(2))[:1])
    assert abs(tree.axes[0].origin[0] - front) < 0.05


@pytest.mark.parametrize("category", ["cabinet2", "drawer"])
def test_surface_samples_lie_on_their_own_link(category):
    obj = make_object(category, 1)
    q = open_configuration(obj)
    cloud = sample_surface(obj, q, 4000, np.random.default_rng(0))
    assert cloud.points.shape == (4000, 3) and cloud.points.dtype == np.float32
    assert cloud.part_id.dtype == np.int64 and cloud.motion_type.dtype == np.int64
    assert np.array_equal(cloud.motion_type, part_motion_types(obj)[cloud.part_id])
    d = link_distances(obj, q, cloud.points)
    own = d[np.arange(len(d)), cloud.part_id]
    assert own.max() < 1e-4  # on the mesh (Open3D's distance query is float32)
    # the nearest link is the labelled one (ties only where parts touch)
    assert (np.argmin(d, axis=1) == cloud.part_id).mean() > 0.97


def test_surface_sampling_is_area_weighted_and_deterministic(cabinet2):
    q = open_configuration(cabinet2)
    n = 20000
    cloud = sample_surface(cabinet2, q, n, np.random.default_rng(3))
    areas = []
    for vertices, triangles in object_frame_meshes(cabinet2, q):
        c = vertices[triangles]
        areas.append(
            0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1).sum()
        )
    expected = np.array(areas) / sum(areas)
    observed = np.bincount(cloud.part_id, minlength=len(expected)) / n
    assert np.abs(observed - expected).max() < 4 * np.sqrt(expected.max() / n)
    again = sample_surface(cabinet2, q, n, np.random.default_rng(3))
    assert all(np.array_equal(a, b) for a, b in zip(cloud, again, strict=True))
    other = sample_surface(cabinet2, q, n, np.random.default_rng(4))
    assert not np.array_equal(cloud.points, other.points)


def test_view_poses_face_the_object_and_fit_it_in_the_image(cabinet2):
    qs = np.stack([np.zeros(2), open_configuration(cabinet2, 1.0)])
    cfg = ScanViewConfig(views=5, distance_m=1.0)
    poses = view_poses(cabinet2, qs, CAMERA, cfg)
    assert poses.shape == (5, 4, 4)
    vertices = np.concatenate([v for q in qs for v, _ in object_frame_meshes(cabinet2, q)])
    centre = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    for pose in poses:
        r = pose[:3, :3]
        assert np.allclose(r.T @ r, np.eye(3)) and np.isclose(np.linalg.det(r), 1.0)
        to_centre = centre - pose[:3, 3]
        assert np.allclose(r[:, 0], to_centre / np.linalg.norm(to_centre))  # looks at it
        assert pose[0, 3] < centre[0] and pose[2, 3] > centre[2]  # in front, above
        assert np.linalg.norm(to_centre) >= cfg.distance_m
        in_camera = (vertices - pose[:3, 3]) @ r  # object-frame points in the camera frame
        uv = CAMERA.project(in_camera)
        assert (uv >= 0).all() and (uv[:, 0] <= CAMERA.width - 1).all()
        assert (uv[:, 1] <= CAMERA.height - 1).all()


def test_voxel_downsample_merges_points_into_centroids_with_majority_labels():
    points = np.array(
        [[0.001, 0.001, 0.001], [0.003, 0.002, 0.001], [0.004, 0.004, 0.004], [0.5, 0.5, 0.5]]
    )
    part = np.array([1, 2, 2, 0])
    merged, labels = voxel_downsample(points, part, n_parts=3, spacing=0.01)
    assert merged.shape == (2, 3) and merged.dtype == np.float32
    assert np.allclose(merged[0], points[:3].mean(axis=0)) and np.allclose(merged[1], points[3])
    assert labels.tolist() == [2, 0]


def test_noise_free_fused_scan_lies_on_the_surface_with_correct_labels(cabinet2):
    q = open_configuration(cabinet2)
    poses = view_poses(cabinet2, q[None], CAMERA, ScanViewConfig(views=4))
    fusion = FusionConfig(voxel_m=0.01, max_points=0)
    with make_backend("raycast", CAMERA) as backend:
        cloud = fuse_views(cabinet2, q, poses, backend, CLEAN, np.random.default_rng(0), fusion)
    assert len(cloud.points) > 2000 and cloud.points.dtype == np.float32
    d = link_distances(cabinet2, q, cloud.points)
    nearest = d.min(axis=1)
    # centroids of points on one face stay on it; at edges they cut the corner (< voxel)
    assert np.median(nearest) < 1e-4 and nearest.max() < fusion.voxel_m
    assert (np.argmin(d, axis=1) == cloud.part_id).mean() > 0.95
    assert set(np.unique(cloud.part_id)) == {0, 1, 2, 3, 4}  # both doors and handles seen
    assert np.array_equal(cloud.motion_type, part_motion_types(cabinet2)[cloud.part_id])


def test_noisy_scans_stay_near_the_surface_and_are_reproducible(drawer):
    qs = np.stack([open_configuration(drawer, 0.3), open_configuration(drawer, 0.9)])
    poses = view_poses(drawer, qs, CAMERA, ScanViewConfig(views=3))
    fusion = FusionConfig(voxel_m=0.01, max_points=1500)
    noise = SensorNoiseConfig()

    def scan(seed: int) -> list:
        with make_backend("raycast", CAMERA) as backend:
            rng = np.random.default_rng(seed)
            return fuse_views_many(drawer, qs, poses, backend, noise, rng, fusion)

    clouds = scan(7)
    assert len(clouds) == 2
    for q, cloud in zip(qs, clouds, strict=True):
        assert len(cloud.points) == 1500  # capped
        d = link_distances(drawer, q, cloud.points)
        nearest = d.min(axis=1)
        # Kinect noise at ~1.5-2 m: sigma_z ~ 5 mm plus disparity steps of ~1 cm
        assert np.median(nearest) < 0.01 and np.percentile(nearest, 90) < 0.03
        assert (np.argmin(d, axis=1) == cloud.part_id).mean() > 0.8
    again = scan(7)
    for a, b in zip(clouds, again, strict=True):
        assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(clouds[0].points, scan(8)[0].points)


def test_views_that_miss_the_object_give_an_empty_cloud(drawer):
    q = np.zeros(1)
    away = view_poses(drawer, q[None], CAMERA, ScanViewConfig(views=1))
    away[0, :3, :2] *= -1  # turn the camera around (x and y flipped: still a rotation)
    with make_backend("raycast", CAMERA) as backend:
        cloud = fuse_views(
            drawer, q, away, backend, CLEAN, np.random.default_rng(0), FusionConfig()
        )
    assert cloud.points.shape == (0, 3) and cloud.part_id.shape == (0,)
