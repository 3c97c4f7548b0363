"""Both depth backends against analytic depth, against each other, and their plumbing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from artic.artifacts.object_dataset import ObjectDataset
from artic.geometry.camera import CameraIntrinsics
from artic.geometry.transforms import make_transform, rot_z
from artic.objects.categories import build
from artic.objects.model import ArticulatedObject, Link
from artic.objects.parts import Box, mass_properties, union_mesh
from artic.objects.tree import latin_hypercube
from artic.objects.urdf import write_urdf
from artic.render.backend import make_backend
from artic.render.open3d_core import open3d_core
from artic.render.raycast import rigid_groups

o3c = open3d_core().core
BACKENDS = ["raycast", "pybullet"]
CAMERA = CameraIntrinsics(fx=100.0, fy=100.0, cx=47.5, cy=35.5, width=96, height=72)
HALF = np.array([0.25, 0.3, 0.2])  # box half extents, metres


def box_object(centre: np.ndarray, yaw: float) -> ArticulatedObject:
    """One rigid box (a body without joints) centred at `centre`, turned `yaw` about z."""
    mesh = union_mesh([Box(x=(-HALF[0], HALF[0]), y=(-HALF[1], HALF[1]), z=(-HALF[2], HALF[2]))])
    link = Link("body", "body", mesh, mass_properties(mesh, 500.0))
    pose = make_transform(rotation=rot_z(yaw), translation=centre)
    return ArticulatedObject("box", (link,), (), pose)


def write_object(obj: ArticulatedObject, folder: Path) -> Path:
    files = write_urdf(obj)
    for name, text in files.meshes.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text)
    path = folder / "object.urdf"
    path.write_text(files.urdf)
    return path


def analytic_depth(obj: ArticulatedObject, camera: CameraIntrinsics) -> np.ndarray:
    """Depth of the box by the slab method, per pixel ray (unit forward component)."""
    pose = obj.base_pose
    d = camera.ray_directions().reshape(-1, 3).astype(np.float64) @ pose[:3, :3]  # box frame
    o = -pose[:3, :3].T @ pose[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-HALF - o) / d, (HALF - o) / d
    near = np.nanmax(np.minimum(t1, t2), axis=1)
    far = np.nanmin(np.maximum(t1, t2), axis=1)
    hit = (near <= far) & (near > 0)
    return np.where(hit, near, 0.0).reshape(camera.height, camera.width)


def silhouette_band(depth: np.ndarray) -> np.ndarray:
    """Pixels within one pixel of where the analytic image changes from hit to miss."""
    hit = np.pad(depth > 0, 1, mode="edge")
    h, w = depth.shape
    windows = [hit[i : i + h, j : j + w] for i in range(3) for j in range(3)]
    return np.logical_or.reduce(windows) & ~np.logical_and.reduce(windows)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("yaw", [0.0, np.deg2rad(30.0), np.deg2rad(-55.0)])
def test_box_depth_matches_analytic_depth(backend, yaw, tmp_path):
    obj = box_object(np.array([2.2, 0.1, -0.05]), yaw)
    urdf = write_object(obj, tmp_path)
    with make_backend(backend, CAMERA) as renderer:
        image = renderer.render(obj, np.zeros(0), urdf)
    truth = analytic_depth(obj, CAMERA)
    inner = ~silhouette_band(truth)
    assert (truth > 0).sum() > 500, "the box fills a good part of the image"
    np.testing.assert_array_equal(image.depth[inner] > 0, truth[inner] > 0)
    both = inner & (truth > 0)
    assert np.abs(image.depth[both] - truth[both]).max() < 1e-3
    np.testing.assert_array_equal(image.part_mask > 0, image.depth > 0)
    assert set(np.unique(image.part_mask)) <= {0, 1}


@pytest.fixture(scope="module")
def scenes(tiny_objects: Path) -> list[tuple[ArticulatedObject, np.ndarray, Path]]:
    ds = ObjectDataset.open(tiny_objects)
    items = []
    for row in ds.rows:
        spec = ds.spec(row.object_id)
        obj = build(spec)
        for q in latin_hypercube(np.random.default_rng(row.object_id), 3, list(spec.joint_limits)):
            items.append((obj, q, ds.urdf(row.object_id)))
    return items


def test_backends_agree_on_generated_objects(scenes):
    with make_backend("raycast", CAMERA) as ray, make_backend("pybullet", CAMERA) as bullet:
        pairs = [(ray.render(o, q, u), bullet.render(o, q, u)) for o, q, u in scenes]
    hits = close = same_part = one_only = 0
    for a, b in pairs:
        both = (a.depth > 0) & (b.depth > 0)
        hits += int(both.sum())
        close += int((np.abs(a.depth - b.depth)[both] <= 1e-3).sum())
        same_part += int((a.part_mask == b.part_mask)[both].sum())
        one_only += int(((a.depth > 0) != (b.depth > 0)).sum())
    assert hits > 1000
    assert close / hits >= 0.99
    assert same_part / hits >= 0.99
    assert one_only / hits < 0.01


def test_every_part_of_an_open_object_is_seen(scenes):
    # half open (wide open, a door's handle can face away from the camera), over the
    # tiny dataset's objects (one near the image's edge can have its handle outside)
    objects = list({id(o): o for o, _, _ in scenes}.values())
    seen: set[int] = set()
    with make_backend("raycast", CAMERA) as ray:
        for obj in objects:
            q = np.array([hi / 2 for _, hi in (j.limits for j in obj.movable_joints)])
            parts = set(np.unique(ray.render(obj, q).part_mask).tolist())
            assert parts <= {0, *range(1, len(obj.links) + 1)}
            seen |= parts
    assert seen == {0, *range(1, len(objects[0].links) + 1)}


def test_raycast_rerenders_the_same_image_after_other_objects(scenes):
    (a, qa, _), (b, qb, _) = scenes[0], scenes[-1]
    with make_backend("raycast", CAMERA) as ray:
        first = ray.render(a, qa)
        ray.render(b, qb)
        again = ray.render(a, qa)
    np.testing.assert_array_equal(first.depth, again.depth)
    np.testing.assert_array_equal(first.part_mask, again.part_mask)


@pytest.mark.parametrize("backend", BACKENDS)
def test_render_many_equals_one_at_a_time(backend, scenes):
    obj, _, urdf = scenes[0]
    qs = np.array([q for o, q, _ in scenes if o is obj] + [scenes[0][1]])  # a repeat too
    with make_backend(backend, CAMERA) as renderer:
        many = renderer.render_many(obj, qs, urdf)
    with make_backend(backend, CAMERA) as renderer:
        single = [renderer.render(obj, q, urdf) for q in qs]
    assert len(many) == len(qs)
    for a, b in zip(many, single, strict=True):
        np.testing.assert_array_equal(a.depth, b.depth)
        np.testing.assert_array_equal(a.part_mask, b.part_mask)
    np.testing.assert_array_equal(many[0].depth, many[-1].depth)


def test_rigid_groups_follow_fixed_joints(scenes):
    obj, _, _ = scenes[0]  # microwave: body, door, handle on the door
    assert rigid_groups(obj) == [[0], [1, 2]]


def test_unknown_backend_is_refused_by_name():
    with pytest.raises(KeyError, match="unknown render backend 'mitsuba'"):
        make_backend("mitsuba", CAMERA)


def test_pybullet_needs_the_urdf(scenes):
    obj, q, _ = scenes[0]
    with make_backend("pybullet", CAMERA) as bullet, pytest.raises(ValueError, match="urdf"):
        bullet.render(obj, q)


class _OffByUlps:
    """A RaycastingScene whose hit distances are rounded otherwise, as another CPU's
    SIMD kernel may round them: each one moved a few float32 ulps up or down."""

    def __init__(self, scene, rng: np.random.Generator) -> None:
        self.scene, self.rng = scene, rng

    def cast_rays(self, rays, nthreads=0):
        hits = dict(self.scene.cast_rays(rays, nthreads=nthreads))
        t = hits["t_hit"].numpy()
        ulps = self.rng.integers(-3, 4, t.shape)
        moved = np.where(np.isfinite(t), t + ulps * np.spacing(t), t).astype(np.float32)
        hits["t_hit"] = o3c.Tensor.from_numpy(moved)
        return hits


def test_raycast_depth_does_not_carry_the_ray_casters_rounding(scenes):
    """Only the choice of triangle comes from Embree: its distances off by a few ulps
    give the same bytes (the cross-CPU difference that the float64 distance removes)."""
    with make_backend("raycast", CAMERA) as ray:
        clean = [ray.render(o, q) for o, q, _ in scenes]
    rng = np.random.default_rng(0)
    with make_backend("raycast", CAMERA) as ray:
        again = []
        for obj, q, _ in scenes:
            for group in ray._scenes(obj):
                if not isinstance(group.scene, _OffByUlps):
                    group.scene = _OffByUlps(group.scene, rng)
            again.append(ray.render(obj, q))
    for a, b in zip(clean, again, strict=True):
        assert a.depth.tobytes() == b.depth.tobytes()
        np.testing.assert_array_equal(a.part_mask, b.part_mask)


def test_raycast_depth_is_the_rounded_plane_distance():
    """A face square to the camera at a float32 distance renders at exactly that distance
    on every pixel it covers."""
    obj = box_object(np.array([2.2 + HALF[0], 0.1, -0.05]), 0.0)
    near = np.float32(2.2)
    with make_backend("raycast", CAMERA) as ray:
        image = ray.render(obj, np.zeros(0))
    hit = image.depth > 0
    assert hit.sum() > 400
    assert set(np.unique(image.depth[hit]).tolist()) == {float(near)}
