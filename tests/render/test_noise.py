"""The Kinect-like sensor model, the depth encodings and the preview sheet."""

from __future__ import annotations

import numpy as np
import pytest

from artic.evaluation.preview import contact_sheet
from artic.geometry.camera import CameraIntrinsics
from artic.render.noise import (
    SensorNoiseConfig,
    apply_sensor_noise,
    axial_sigma,
    depth_edges,
    depth_to_uint16_mm,
    quantize_disparity,
    uint16_mm_to_depth,
)

ONLY_AXIAL = dict(lateral_sigma_px=0.0, quantize=False, edge_dropout=0.0, dropout=0.0)


def step_image() -> np.ndarray:
    """A 64x64 scene: background wall at 3 m, a box face at 1.5 m, no return at the top."""
    depth = np.full((64, 64), 3.0, dtype=np.float32)
    depth[20:44, 20:44] = 1.5
    depth[:8] = 0.0
    return depth


def test_disabled_model_returns_a_copy():
    depth = step_image()
    out = apply_sensor_noise(depth, SensorNoiseConfig(enabled=False), np.random.default_rng(0))
    np.testing.assert_array_equal(out, depth)
    assert out is not depth


def test_same_generator_state_same_noise():
    depth, cfg = step_image(), SensorNoiseConfig()
    a = apply_sensor_noise(depth, cfg, np.random.default_rng(7))
    b = apply_sensor_noise(depth, cfg, np.random.default_rng(7))
    c = apply_sensor_noise(depth, cfg, np.random.default_rng(8))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert a.dtype == np.float32 and a.shape == depth.shape


def test_no_depth_appears_far_from_any_surface():
    depth = step_image()
    out = apply_sensor_noise(depth, SensorNoiseConfig(), np.random.default_rng(0))
    assert (out[:4] == 0).all(), "rows 4+ px from any return stay empty"
    assert (out >= 0).all() and np.isfinite(out).all()


def test_axial_noise_has_the_range_dependent_sigma():
    depth = np.full((200, 200), 2.5, dtype=np.float32)
    cfg = SensorNoiseConfig(**ONLY_AXIAL)
    err = apply_sensor_noise(depth, cfg, np.random.default_rng(0)) - 2.5
    expected = float(axial_sigma(np.array(2.5), cfg))
    assert expected == pytest.approx(0.0012 + 0.0019 * 2.1**2)
    assert abs(err.mean()) < 3 * expected / 200
    assert err.std() == pytest.approx(expected, rel=0.03)


def test_disparity_quantisation_steps():
    cfg = SensorNoiseConfig()
    z = np.linspace(0.5, 5.0, 1000)
    q = quantize_disparity(z, cfg)
    bf = cfg.baseline_m * cfg.focal_px
    steps = bf / q * cfg.subpixel
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    # the depth step grows as z^2 / (b f subpixel): about 4.9 cm at 4 m
    levels = np.unique(np.round(q, 9))
    gaps = np.diff(levels)
    near4 = gaps[np.argmin(np.abs(levels[:-1] - 4.0))]
    assert near4 == pytest.approx(4.0**2 / (bf * cfg.subpixel), rel=0.05)
    assert quantize_disparity(np.zeros(3), cfg).tolist() == [0.0, 0.0, 0.0]


def test_edges_are_where_depth_jumps():
    depth = step_image()
    edges = depth_edges(depth, 0.05)
    assert edges[20, 30] and edges[19, 30] and edges[43, 30] and edges[44, 30]
    assert not edges[30, 30] and not edges[30, 5]
    assert edges[8, 30], "next to a no-return pixel is an edge"
    assert not edges[:8].any(), "no-return pixels are not edges"


def test_edge_pixels_are_dropped_at_the_configured_rate():
    depth = step_image()
    cfg = SensorNoiseConfig(lateral_sigma_px=0.0, axial=False, quantize=False, dropout=0.0)
    edges = depth_edges(depth, cfg.edge_threshold_m)
    lost = np.zeros_like(edges, dtype=float)
    for seed in range(40):
        lost += apply_sensor_noise(depth, cfg, np.random.default_rng(seed)) == 0
    rate = lost[edges].mean() / 40
    assert rate == pytest.approx(cfg.edge_dropout, abs=0.05)
    assert lost[~edges & (depth > 0)].sum() == 0


def test_pixel_parameters_scale_with_the_image_resolution():
    # a surface slanted so that depth grows 2 cm per sensor pixel (4 cm over a 3x3
    # window): not an edge (5 cm) at the sensor's resolution, nor at a quarter of it
    # (8 cm per image pixel, 16 cm over the window) once the threshold is scaled
    cfg = SensorNoiseConfig(
        lateral_sigma_px=0.0, axial=False, quantize=False, dropout=0.0, edge_dropout=1.0
    )

    def ramp(step: float) -> np.ndarray:
        return (1.5 + step * np.arange(40))[None, :].repeat(40, axis=0).astype(np.float32)

    native = apply_sensor_noise(ramp(0.02), cfg, np.random.default_rng(0), cfg.focal_px)
    assert (native[:, 1:-1] > 0).all()
    unscaled = apply_sensor_noise(ramp(0.08), cfg, np.random.default_rng(0))
    scaled = apply_sensor_noise(ramp(0.08), cfg, np.random.default_rng(0), cfg.focal_px / 4)
    assert (unscaled == 0).all(), "without scaling the whole ramp reads as edges"
    assert (scaled[:, 1:-1] > 0).all()
    # and the lateral shift shrinks: at k = 4 a 0.5 px sigma rounds to no shift
    step = np.zeros((40, 40), np.float32)
    step[:, 20:] = 2.0
    cfg = SensorNoiseConfig(axial=False, quantize=False, dropout=0.0, edge_dropout=0.0)
    shifted = apply_sensor_noise(step, cfg, np.random.default_rng(0))
    kept = apply_sensor_noise(step, cfg, np.random.default_rng(0), cfg.focal_px / 8)
    assert not np.array_equal(shifted, step) and np.array_equal(kept, step)


def test_out_of_range_depth_is_lost():
    depth = np.array([[0.2, 1.0, 7.0]], dtype=np.float32)
    cfg = SensorNoiseConfig(**ONLY_AXIAL, axial=False)
    assert apply_sensor_noise(depth, cfg, np.random.default_rng(0)).tolist() == [[0.0, 1.0, 0.0]]


def test_uint16_millimetres_round_trip():
    depth = np.array([[0.0, 0.0004, 0.0006, 1.23449, 65.535, 70.0]], dtype=np.float32)
    mm = depth_to_uint16_mm(depth)
    assert mm.dtype == np.uint16
    assert mm.tolist() == [[0, 0, 1, 1234, 65535, 65535]]
    back = uint16_mm_to_depth(mm)
    assert back.dtype == np.float32
    assert np.abs(back[0, :5] - depth[0, :5]).max() <= 0.0005 + 1e-7


def test_contact_sheet_tiles_images_and_draws_axes():
    cam = CameraIntrinsics(fx=50, fy=50, cx=31.5, cy=23.5, width=64, height=48)
    depths = [np.full((48, 64), 2.0, np.float32) for _ in range(5)]
    axis = (np.array([2.0, 0.0, -0.2]), np.array([0.0, 0.0, 1.0]))
    sheet = contact_sheet(depths, [[axis]] * 5, [["revolute"]] * 5, cam, columns=2)
    assert sheet.shape == (3 * 48, 2 * 64, 3) and sheet.dtype == np.uint8
    red = (sheet[..., 0] > 200) & (sheet[..., 1] < 100)
    assert red[:48, :64].any(), "the revolute axis is drawn in red"
    assert not sheet[2 * 48 :, 64:].any(), "the unused last tile stays black"
    big = contact_sheet(depths[:1], [[axis]], [["prismatic"]], cam, scale=3)
    assert big.shape == (3 * 48, 3 * 64, 3)
    green = (big[..., 1] > 200) & (big[..., 0] < 100)
    rows, cols = np.nonzero(green)
    # the axis rises from its origin, projected at (31.5, 28.5) px, i.e. (95.5, 86.5) x3
    assert abs(cols.mean() - 95.5) < 1.5
    assert rows.max() == pytest.approx(86.5, abs=2)
    with pytest.raises(ValueError):
        contact_sheet([], [], [], cam)
