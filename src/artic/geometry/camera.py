"""Pinhole camera in the thesis convention (Appendix A).

The camera body frame has +x forward (the optical axis), +y left and +z up. A point
(x, y, z) in that frame with x > 0 projects to pixel column u = cx - fx * y / x and row
v = cy - fy * z / x; its depth is x, the distance along the optical axis. Pixel centres
are at integer (u, v) (OpenCV convention: cx = (width - 1) / 2 for a centred camera).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator


class CameraIntrinsics(BaseModel):
    """Pinhole intrinsics; the same fields as the `--camera` JSON file."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    fx: float = Field(gt=0, description="focal length along image columns, pixels")
    fy: float = Field(gt=0, description="focal length along image rows, pixels")
    cx: float = Field(description="principal point column, pixels (0 = centre of first pixel)")
    cy: float = Field(description="principal point row, pixels")
    width: int = Field(gt=0, le=8192, description="image width, pixels")
    height: int = Field(gt=0, le=8192, description="image height, pixels")

    @model_validator(mode="after")
    def _principal_point_inside(self) -> CameraIntrinsics:
        if not (0 <= self.cx <= self.width - 1 and 0 <= self.cy <= self.height - 1):
            raise ValueError(
                f"principal point ({self.cx}, {self.cy}) outside a {self.width}x{self.height} image"
            )
        return self

    @classmethod
    def from_json(cls, text: str) -> CameraIntrinsics:
        data: dict[str, Any] = json.loads(text)
        return cls.model_validate(data)

    def ray_directions(self) -> NDArray[np.float32]:
        """Un-normalised ray directions with unit x component: (height, width, 3) float32.

        Ray t * d hits depth t, so a ray caster's hit distance along these rays is the
        depth along the optical axis directly.
        """
        u = np.arange(self.width, dtype=np.float64)
        v = np.arange(self.height, dtype=np.float64)
        uu, vv = np.meshgrid(u, v)
        d = np.empty((self.height, self.width, 3), dtype=np.float64)
        d[..., 0] = 1.0
        d[..., 1] = -(uu - self.cx) / self.fx
        d[..., 2] = -(vv - self.cy) / self.fy
        return d.astype(np.float32)

    def project(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Project (N, 3) camera-frame points (x > 0) to (N, 2) pixel coordinates (u, v)."""
        p = np.asarray(points, dtype=np.float64)
        u = self.cx - self.fx * p[:, 1] / p[:, 0]
        v = self.cy - self.fy * p[:, 2] / p[:, 0]
        return np.stack([u, v], axis=1)

    def back_project(self, depth: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
        """Depth image (height, width) metres -> (N, 3) points of the valid (> 0) pixels."""
        if depth.shape != (self.height, self.width):
            raise ValueError(
                f"depth image is {depth.shape[1]}x{depth.shape[0]}, "
                f"camera is {self.width}x{self.height}"
            )
        vv, uu = np.nonzero(depth > 0)
        z = depth[vv, uu].astype(np.float64)
        return np.stack([z, -(uu - self.cx) * z / self.fx, -(vv - self.cy) * z / self.fy], axis=1)


def reproject(
    depth: NDArray[np.floating[Any]], source: CameraIntrinsics, target: CameraIntrinsics
) -> NDArray[np.float32]:
    """Depth seen by `source` -> the depth image `target` sees from the same pose.

    Every valid pixel is back-projected to a point and projected into `target`; where
    several points land on one pixel the nearest wins (a z-buffer), and target pixels no
    point lands on stay 0. Both cameras share the body frame (x forward, z up).
    """
    points = source.back_project(np.asarray(depth))
    out = np.zeros((target.height, target.width), dtype=np.float32)
    if len(points) == 0:
        return out
    uv = np.rint(target.project(points)).astype(np.int64)
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < target.width) & (uv[:, 1] >= 0)
    inside &= uv[:, 1] < target.height
    u, v, z = uv[inside, 0], uv[inside, 1], points[inside, 0]
    order = np.argsort(-z)  # far first, so the nearest point is written last
    out[v[order], u[order]] = z[order]
    return out
