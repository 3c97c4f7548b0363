import numpy as np
import pytest
from pydantic import ValidationError

from artic.geometry.camera import CameraIntrinsics
from artic.geometry.transforms import axis_angle, invert, make_transform, rot_z, transform_points

CAM = CameraIntrinsics(fx=140, fy=140, cx=63.5, cy=63.5, width=128, height=128)


def test_projection_convention_camera_looks_down_x_with_z_up():
    centre = CAM.project(np.array([[2.0, 0.0, 0.0]]))[0]
    np.testing.assert_allclose(centre, [63.5, 63.5])
    left, up = CAM.project(np.array([[2.0, 0.5, 0.0], [2.0, 0.0, 0.5]]))
    assert left[0] < 63.5, "+y is to the left in the image"
    assert up[1] < 63.5, "+z is up in the image (row 0 at the top)"


def test_back_project_inverts_project():
    depth = np.zeros((128, 128), dtype=np.float32)
    depth[10, 100] = 1.5
    depth[64, 3] = 2.5
    points = CAM.back_project(depth)
    uv = CAM.project(points)
    np.testing.assert_allclose(sorted(map(tuple, uv)), [(3.0, 64.0), (100.0, 10.0)], atol=1e-9)
    np.testing.assert_allclose(sorted(points[:, 0]), [1.5, 2.5], atol=1e-6)


def test_rays_have_unit_forward_component():
    rays = CAM.ray_directions()
    assert rays.shape == (128, 128, 3)
    np.testing.assert_array_equal(rays[..., 0], 1.0)


def test_bad_intrinsics_are_refused():
    with pytest.raises(ValidationError, match="principal point"):
        CameraIntrinsics(fx=1, fy=1, cx=500, cy=1, width=10, height=10)
    with pytest.raises(ValidationError, match="fx"):
        CameraIntrinsics(fx=-1, fy=1, cx=1, cy=1, width=10, height=10)


def test_transforms_compose_and_invert():
    t = make_transform(rot_z(0.3) @ axis_angle(np.array([1.0, 1.0, 0.0]), 0.2), [1, 2, 3])
    np.testing.assert_allclose(t @ invert(t), np.eye(4), atol=1e-12)
    p = np.random.default_rng(0).normal(size=(5, 3))
    np.testing.assert_allclose(transform_points(invert(t), transform_points(t, p)), p, atol=1e-12)
    np.testing.assert_allclose(axis_angle(np.array([0.0, 0.0, 1.0]), 0.7), rot_z(0.7), atol=1e-12)


def test_reproject_into_the_same_camera_is_identity_and_halves_with_focal():
    from artic.geometry.camera import reproject

    cam = CameraIntrinsics(fx=100, fy=100, cx=31.5, cy=23.5, width=64, height=48)
    depth = np.zeros((48, 64), np.float32)
    depth[10:30, 20:50] = 2.0
    depth[15:20, 25:30] = 1.5  # a nearer patch in front
    np.testing.assert_array_equal(reproject(depth, cam, cam), depth)
    half = CameraIntrinsics(fx=50, fy=50, cx=15.5, cy=11.5, width=32, height=24)
    small = reproject(depth, cam, half)
    assert small.shape == (24, 32)
    assert set(np.unique(small)) == {0.0, 1.5, 2.0}
    assert small[(15 + 20) // 4, (25 + 30) // 4] == 1.5, "the patch's ray keeps its depth"
    assert reproject(np.zeros((48, 64), np.float32), cam, half).max() == 0


def test_reproject_keeps_a_noisy_surface_in_place_and_fills_a_finer_camera():
    """Reducing a 640x480 image (f = 525) into 192x108 (f = 105.4) must not move a noisy
    surface: each target pixel is one measurement, not the nearest of ~25. Enlarging a
    coarse image leaves no hole inside its view."""
    from artic.geometry.camera import reproject

    fine = CameraIntrinsics(fx=525, fy=525, cx=319.5, cy=239.5, width=640, height=480)
    coarse = CameraIntrinsics(fx=105.4, fy=105.4, cx=95.5, cy=53.5, width=192, height=108)
    rng = np.random.default_rng(0)
    noisy = (2.0 + rng.normal(0.0, 0.005, (480, 640))).astype(np.float32)
    small = reproject(noisy, fine, coarse)
    seen = small[small > 0]
    assert seen.size > 0.4 * small.size  # the fine camera's narrower view, in the middle
    assert abs(float(np.mean(seen)) - 2.0) < 0.001  # a z-buffer put it ~1 cm nearer
    assert abs(float(np.std(seen)) - 0.005) < 0.001  # one measurement's noise per pixel
    noisy[100:110, 200:210] = np.nan  # no return: stays 0
    assert np.isfinite(reproject(noisy, fine, fine)).all()
    big = reproject(np.full((108, 192), 2.0, np.float32), coarse, fine)
    assert (big == 2.0).all()  # the coarse camera sees all of the fine one's view


def test_camera_configs_load_and_thesis_sim_has_the_generators_field_of_view():
    from pathlib import Path

    import yaml

    folder = Path(__file__).resolve().parents[2] / "conf" / "common" / "camera"
    cams = {f.stem: CameraIntrinsics(**yaml.safe_load(f.read_text())) for f in folder.iterdir()}
    assert {"kinect_v1", "kinect_v1_128", "thesis_sim"} <= set(cams)
    sim = cams["thesis_sim"]
    fov_x = np.degrees(2 * np.arctan(sim.width / 2 / sim.fx))
    fov_y = np.degrees(2 * np.arctan(sim.height / 2 / sim.fy))
    assert (sim.width, sim.height) == (192, 108)
    assert fov_x == pytest.approx(84.65, abs=0.05) and fov_y == pytest.approx(54.28, abs=0.05)
