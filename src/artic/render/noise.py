"""A Kinect-v1-like depth sensor model, vectorised (no per-pixel Python loops).

Applied in this order to a clean depth image (metres, 0 = no return); pixel-level
parameters are at the sensor's resolution and scaled to the image's (`image_fx`):
1. lateral noise: each pixel takes the value of a neighbour offset by N(0, sigma) pixels
   (nearest), which frays depth edges as structured-light sensors do;
2. axial noise: N(0, sigma_z) with sigma_z = 0.0012 + 0.0019 (z - 0.4)^2 m
   (Nguyen, Izadi and Lovell 2012, for surfaces facing the sensor);
3. disparity quantisation: d = b f / z rounded to 1/subpixel of a pixel, with the
   sensor's own baseline and focal length (not the rendered image's);
4. missing pixels at depth edges: pixels whose 3x3 neighbourhood spans more than a
   threshold are dropped with a probability;
5. random dropout, then the sensor's valid range.
Only the lateral shift can move depth onto a pixel without a return, and only from a
neighbour; no depth appears farther than a few sigma from a surface.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field

_FAR = 1.0e6  # metres: stands for "no return" when looking for edges


class SensorNoiseConfig(BaseModel):
    """Sensor model parameters; `conf/common/noise/*.yaml`."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    enabled: bool = Field(True, description="apply the model at all")
    lateral_sigma_px: float = Field(
        0.5, ge=0, description="std of the lateral pixel shift, sensor px"
    )
    axial: bool = Field(True, description="range-dependent Gaussian noise along the ray")
    axial_a: float = Field(0.0012, ge=0, description="sigma_z = a + b (z - c)^2: a, metres")
    axial_b: float = Field(0.0019, ge=0, description="sigma_z = a + b (z - c)^2: b, 1/metres")
    axial_c: float = Field(0.4, ge=0, description="sigma_z = a + b (z - c)^2: c, metres")
    quantize: bool = Field(True, description="quantise disparity like the Kinect")
    baseline_m: float = Field(0.075, gt=0, description="projector-camera baseline, metres")
    focal_px: float = Field(580.0, gt=0, description="the sensor's IR focal length, pixels")
    subpixel: int = Field(8, gt=0, description="disparity steps per pixel (Kinect v1: 1/8 px)")
    edge_threshold_m: float = Field(
        0.05, gt=0, description="depth span over 3x3 sensor pixels that makes an edge, metres"
    )
    edge_dropout: float = Field(0.5, ge=0, le=1, description="probability an edge pixel is lost")
    dropout: float = Field(0.005, ge=0, le=1, description="probability any pixel is lost")
    min_range_m: float = Field(0.4, ge=0, description="nearest valid depth, metres")
    max_range_m: float = Field(6.0, gt=0, description="farthest valid depth, metres")


def axial_sigma(z: NDArray[np.floating], cfg: SensorNoiseConfig) -> NDArray[np.float64]:
    """Std of the axial noise at depth z (metres), Nguyen et al. 2012."""
    return cfg.axial_a + cfg.axial_b * (np.asarray(z, dtype=np.float64) - cfg.axial_c) ** 2


def quantize_disparity(z: NDArray[np.float64], cfg: SensorNoiseConfig) -> NDArray[np.float64]:
    """Depth after rounding the disparity b f / z to 1/subpixel px; 0 stays 0."""
    bf = cfg.baseline_m * cfg.focal_px
    valid = z > 0
    disparity = np.where(valid, bf / np.where(valid, z, 1.0), 0.0)
    steps = np.round(disparity * cfg.subpixel) / cfg.subpixel
    return np.where(valid & (steps > 0), bf / np.where(steps > 0, steps, 1.0), 0.0)


def depth_edges(depth: NDArray[np.floating], threshold: float) -> NDArray[np.bool_]:
    """Pixels with a return whose 3x3 neighbourhood spans > threshold (no-return pixels
    count as very far, so an object's silhouette is an edge)."""
    z = np.where(depth > 0, depth, _FAR).astype(np.float64)
    padded = np.pad(z, 1, mode="edge")
    h, w = z.shape
    windows = [padded[i : i + h, j : j + w] for i in range(3) for j in range(3)]
    hi = np.maximum.reduce(windows)
    lo = np.minimum.reduce(windows)
    return (hi - lo > threshold) & (depth > 0)


def apply_sensor_noise(
    depth: NDArray[np.float32],
    cfg: SensorNoiseConfig,
    rng: np.random.Generator,
    image_fx: float | None = None,
) -> NDArray[np.float32]:
    """The sensor's view of a clean depth image: (H, W) float32 metres -> same shape.

    image_fx: focal length of the rendered image, px (default: the sensor's own). The
    pixel-level parameters hold at the sensor's resolution, so for an image with k =
    focal_px / image_fx sensor pixels per image pixel the lateral shift is divided by k
    and the edge threshold, a depth span over 3x3 pixels, multiplied by k (a slanted
    surface spans k times more depth per image pixel).
    """
    if not cfg.enabled:
        return depth.copy()
    k = cfg.focal_px / image_fx if image_fx else 1.0
    z = depth.astype(np.float64)
    h, w = z.shape
    sigma = cfg.lateral_sigma_px / k
    if sigma > 0:
        rows = np.arange(h)[:, None] + rng.normal(0.0, sigma, (h, w))
        cols = np.arange(w)[None, :] + rng.normal(0.0, sigma, (h, w))
        z = z[
            np.clip(np.rint(rows), 0, h - 1).astype(int),
            np.clip(np.rint(cols), 0, w - 1).astype(int),
        ]
    valid = z > 0
    if cfg.axial:
        z = np.where(valid, z + rng.normal(0.0, 1.0, (h, w)) * axial_sigma(z, cfg), 0.0)
    if cfg.quantize:
        z = quantize_disparity(z, cfg)
    lost = depth_edges(depth, cfg.edge_threshold_m * k) & (rng.random((h, w)) < cfg.edge_dropout)
    lost |= rng.random((h, w)) < cfg.dropout
    z = np.where(lost | (z < cfg.min_range_m) | (z > cfg.max_range_m), 0.0, z)
    return z.astype(np.float32)


def depth_to_uint16_mm(depth: NDArray[np.floating]) -> NDArray[np.uint16]:
    """Metres -> millimetres, rounded, clipped to uint16; 0 stays 0."""
    mm = np.rint(np.asarray(depth, dtype=np.float64) * 1000.0)
    return np.clip(mm, 0, np.iinfo(np.uint16).max).astype(np.uint16)


def uint16_mm_to_depth(mm: NDArray[np.uint16]) -> NDArray[np.float32]:
    """Millimetres -> float32 metres."""
    return mm.astype(np.float32) * np.float32(0.001)
