"""Pinhole camera in the thesis convention (Appendix A).

The camera body frame has +x forward (the optical axis), +y left and +z up. A point
(x, y, z) in that frame with x > 0 projects to pixel column u = cx - fx * y / x and row
v = cy - fy * z / x; its depth is x, the distance along the optical axis. Pixel centres
are at integer (u, v) (OpenCV convention: cx = (width - 1) / 2 for a centred camera).
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator


@functools.lru_cache(maxsize=8)
def _ray_directions(camera: CameraIntrinsics) -> NDArray[np.float32]:
    u = np.arange(camera.width, dtype=np.float64)
    v = np.arange(camera.height, dtype=np.float64)
    uu, vv = np.meshgrid(u, v)
    d = np.empty((camera.height, camera.width, 3), dtype=np.float64)
    d[..., 0] = 1.0
    d[..., 1] = -(uu - camera.cx) / camera.fx
    d[..., 2] = -(vv - camera.cy) / camera.fy
    rays = d.astype(np.float32)
    rays.flags.writeable = False
    return rays


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
        """artic's own six-field JSON, strictly (no other field). Files written by other
        tools (ROS, OpenCV, Open3D): `camera_from_mapping`."""
        data: dict[str, Any] = json.loads(text)
        return cls.model_validate(data)

    def ray_directions(self) -> NDArray[np.float32]:
        """Un-normalised ray directions with unit x component: (height, width, 3) float32,
        read-only (computed once per camera: the refinement asks for them dozens of times
        an image, ~1 ms each).

        Ray t * d hits depth t, so a ray caster's hit distance along these rays is the
        depth along the optical axis directly.
        """
        return _ray_directions(self)

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


INTRINSICS = ("fx", "fy", "cx", "cy", "width", "height")

#: the layouts `camera_from_mapping` reads (docs/kinematics.md, "Camera files")
CameraLayout = Literal["artic", "ros", "ros_yaml", "open3d"]


class CameraFieldError(ValueError):
    """A camera file's `field` is missing or invalid: `str(err)` is "field FIELD: why"."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"field {field}: {message}")
        self.field = field


@dataclass(frozen=True)
class CameraFile:
    """A camera file read by `camera_from_mapping`: its intrinsics, which layout held
    them and the top-level fields it ignored (sorted)."""

    intrinsics: CameraIntrinsics
    layout: CameraLayout
    ignored: tuple[str, ...]


def _number(value: Any, field: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise CameraFieldError(field, f"expected a number, got {value!r:.40}")
    if not math.isfinite(value):
        raise CameraFieldError(field, f"expected a finite number, got {value}")
    return float(value)


def _matrix3(value: Any, field: str, order: Literal["rows", "columns"]) -> list[list[float]]:
    """A 3x3 matrix as rows from 9 numbers (row- or column-major, `order`) or 3 lists of 3
    (always rows: that is how numpy's `tolist()` and OpenCV's nested lists read)."""
    if isinstance(value, Sequence) and not isinstance(value, str):
        if len(value) == 3 and all(
            isinstance(r, Sequence) and not isinstance(r, str) and len(r) == 3 for r in value
        ):
            return [[_number(x, field) for x in row] for row in value]
        if len(value) == 9:
            flat = [_number(x, field) for x in value]
            rows = [flat[3 * i : 3 * i + 3] for i in range(3)]
            return rows if order == "rows" else [list(c) for c in zip(*rows, strict=True)]
    raise CameraFieldError(field, "expected a 3x3 matrix: 9 numbers or 3 lists of 3")


def _from_matrix(k: list[list[float]], field: str, order: str) -> dict[str, float]:
    """fx, fy, cx, cy of a pinhole K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]; `order`
    says how 9 numbers were read, for the message."""
    if k[0][1] != 0:
        raise CameraFieldError(
            field, f"skew K[0][1] = {k[0][1]} is not 0 (artic's pinhole model has no skew)"
        )
    if k[1][0] != 0 or k[2] != [0.0, 0.0, 1.0]:
        raise CameraFieldError(
            field,
            "not a pinhole matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] "
            f"(got rows {k}; 9 numbers are read {order})",
        )
    return {"fx": k[0][0], "fy": k[1][1], "cx": k[0][2], "cy": k[1][2]}


def _layout_of(data: Mapping[str, Any]) -> CameraLayout:
    if any(f in data for f in ("fx", "fy", "cx", "cy")):
        return "artic"
    if "K" in data or "k" in data:
        return "ros"
    if "camera_matrix" in data:
        return "ros_yaml"
    if "intrinsic_matrix" in data:
        return "open3d"
    raise CameraFieldError(
        "fx",
        "missing: expected fx, fy, cx, cy, width, height, or a ROS CameraInfo K / "
        "camera_matrix, or an Open3D intrinsic_matrix, with width and height",
    )


def camera_from_mapping(data: Any) -> CameraFile:
    """Pinhole intrinsics from a camera file's parsed JSON (or YAML), in any of these
    layouts:

    - artic: `fx, fy, cx, cy, width, height`;
    - ROS `sensor_msgs/CameraInfo` (as a message dumped to JSON): `width`, `height` and
      `K` (ROS 1) or `k` (ROS 2), 9 numbers row-major or 3 lists of 3;
    - ROS camera_info YAML (camera_calibration_parsers), parsed: `image_width`,
      `image_height`, `camera_matrix: {rows: 3, cols: 3, data: [9 numbers, row-major]}`;
    - Open3D `PinholeCameraIntrinsic` JSON (`o3d.io.write_pinhole_camera_intrinsic`):
      `width`, `height`, `intrinsic_matrix`, 9 numbers COLUMN-major (Eigen's storage
      order), or 3 lists of 3 as rows (OpenCV / numpy `tolist()`).

    Top-level fields the layout does not use (a frame name, distortion `D`, `P`, a model
    string, ...) are returned in `ignored`; distortion is not applied (the depth image is
    taken as rectified). A matrix must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]: nonzero
    skew is refused. Raises `CameraFieldError` naming the file's field."""
    if not isinstance(data, Mapping):
        raise CameraFieldError("camera", f"expected a JSON object, got {type(data).__name__}")
    layout = _layout_of(data)
    names = dict(zip(INTRINSICS, INTRINSICS, strict=True))  # intrinsic -> the file's field
    values: dict[str, Any]
    if layout == "artic":
        values = {f: data[f] for f in INTRINSICS if f in data}
    elif layout == "ros":
        key = "K" if "K" in data else "k"
        values = _from_matrix(_matrix3(data[key], key, "rows"), key, "row-major")
        names |= {f: f"{key} ({f})" for f in ("fx", "fy", "cx", "cy")}
        values |= {f: data[f] for f in ("width", "height") if f in data}
    elif layout == "ros_yaml":
        cm = data["camera_matrix"]
        if not isinstance(cm, Mapping) or "data" not in cm:
            raise CameraFieldError("camera_matrix", "expected {rows: 3, cols: 3, data: [...]}")
        if cm.get("rows", 3) != 3 or cm.get("cols", 3) != 3:
            raise CameraFieldError("camera_matrix", "expected rows: 3 and cols: 3")
        k = _matrix3(cm["data"], "camera_matrix.data", "rows")
        values = _from_matrix(k, "camera_matrix", "row-major")
        names |= {f: f"camera_matrix ({f})" for f in ("fx", "fy", "cx", "cy")}
        names |= {"width": "image_width", "height": "image_height"}
        values |= {f: data[names[f]] for f in ("width", "height") if names[f] in data}
    else:
        key = "intrinsic_matrix"
        values = _from_matrix(
            _matrix3(data[key], key, "columns"), key, "column-major, as Open3D writes them"
        )
        names |= {f: f"{key} ({f})" for f in ("fx", "fy", "cx", "cy")}
        values |= {f: data[f] for f in ("width", "height") if f in data}
    used = set(values) if layout == "artic" else {names[f].split(" ")[0] for f in INTRINSICS}
    for f in INTRINSICS:
        if f not in values:
            raise CameraFieldError(names[f], "missing")
        number = _number(values[f], names[f])
        if f in ("width", "height") and number != int(number):
            raise CameraFieldError(names[f], f"expected a whole number of pixels, got {number}")
    try:
        intrinsics = CameraIntrinsics.model_validate(values)
    except ValidationError as err:
        first = err.errors()[0]
        field = ".".join(str(p) for p in first["loc"])
        raise CameraFieldError(names.get(field, "camera"), first["msg"]) from None
    ignored = tuple(sorted(str(k) for k in data if k not in used))
    return CameraFile(intrinsics, layout, ignored)


def reproject(
    depth: NDArray[np.floating[Any]], source: CameraIntrinsics, target: CameraIntrinsics
) -> NDArray[np.float32]:
    """Depth seen by `source` -> the depth image `target` sees from the same pose.

    Both cameras share the body frame (x forward, z up) and the optical centre, so a ray
    keeps its depth from one image to the other: each target pixel takes the depth of the
    source pixel its centre ray falls in (nearest neighbour along rays; 0 outside the
    source's view or where the source has no return). That is what a renderer does, one
    ray per pixel, so a reduced image has the statistics of one rendered in `target`: one
    measurement per pixel, no mixing across an edge. (A z-buffer of every source point,
    the nearest winning, moved a noisy surface towards the camera when reducing: the
    least of the ~25 noisy samples of a 640x480 image that fall in one pixel of a 192x108
    one lies about two standard deviations in front of the surface.)
    """
    image = np.asarray(depth)
    if image.shape != (source.height, source.width):
        raise ValueError(
            f"depth image is {image.shape[1]}x{image.shape[0]}, "
            f"camera is {source.width}x{source.height}"
        )
    # the source pixel of each target column and row; floor(x + 1/2): no ties to even
    u = np.floor(
        source.cx + source.fx * (np.arange(target.width) - target.cx) / target.fx + 0.5
    ).astype(np.int64)
    v = np.floor(
        source.cy + source.fy * (np.arange(target.height) - target.cy) / target.fy + 0.5
    ).astype(np.int64)
    cols, rows = (u >= 0) & (u < source.width), (v >= 0) & (v < source.height)
    out = np.zeros((target.height, target.width), dtype=np.float32)
    out[np.ix_(rows, cols)] = image[np.ix_(v[rows], u[cols])]
    return np.where(np.isfinite(out) & (out > 0), out, 0).astype(np.float32)
