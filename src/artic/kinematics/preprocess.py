"""Depth image -> network input, shared by training, evaluation and prediction.

The MDN reads an object-centred crop plus a vector of where that crop is (docs/kinematics.md):

1. Valid pixels: depth > 0, at most `MAX_DEPTH_M` (the sensor's range), finite, and
   inside the object mask when one is given. Depth is metric depth along the optical axis
   of the training camera (`artic predict` reprojects other cameras' images into it).
2. **Crop**: the square window centred on the valid pixels' bounding box, `CROP_MARGIN`
   larger than its longer side (plus 2 pixels), resampled to `size` x `size` by nearest
   neighbour (no mixing of object and background depths); pixels outside the image are
   background. The object fills the network's input whatever its distance: a microwave
   1.8 m away is 60 of the 128 pixels wide, and the crop gives its hinge and handle the
   whole input instead of a fifth of it.
3. **Relative depth**: a valid pixel is 1 + (depth - mean valid depth) / `RELATIVE_DEPTH_M`,
   clipped to [0.05, 3]; background is 0. The object's shape is on the scale of its size,
   not of its distance.
4. **Where the crop is** (`side`, `SIDE_FEATURES` numbers): the centroid (x, y, z) of the
   valid pixels back-projected into the camera frame (metres), the crop centre's ray
   (-(u - cx) / fx, -(v - cy) / fy), the crop's angular and metric size (its side / fx,
   times the mean depth), and four flags for a bounding box touching the image's top,
   bottom, left and right border (the object continues outside the view). The camera-frame
   labels (axis position, yaw) are the crop's content read relative to these.

An image without valid pixels gives an all-background crop of the whole image and zeros.
Training adds augmentation (`augment`): a random fraction (up to `dropout_max`) of each
crop's pixels is dropped, like the sensor's missing returns.

`full_image` is the older whole-image input (depth / `DEPTH_SCALE_M`), kept for the NN
baseline's "depth-image space" (section 3.3.1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import torch
import torch.nn.functional as F
from numpy.typing import NDArray

from artic.geometry.camera import CameraIntrinsics

MAX_DEPTH_M = 6.0
DEPTH_SCALE_M = 4.0  # full_image: metres that map to 1.0
CROP_MARGIN = 0.1  # the crop's side is (1 + CROP_MARGIN) * the bounding box's + 2 px
RELATIVE_DEPTH_M = 0.5  # metres of depth relative to the mean that map to 1.0
RELATIVE_RANGE = (0.05, 3.0)
SIDE_FEATURES = 11


class NetworkInput(NamedTuple):
    """A batch of network inputs: crops (N, 1, S, S) and where they are (N, K)."""

    image: torch.Tensor
    side: torch.Tensor

    def to(self, device: torch.device, channels_last: bool = False) -> NetworkInput:
        memory = torch.channels_last if channels_last else torch.contiguous_format
        image = self.image.to(device=device, memory_format=memory)
        return NetworkInput(image, self.side.to(device))


def valid_pixels(depth: NDArray[np.floating], mask: NDArray[np.bool_] | None) -> NDArray:
    """(N, H, W) bool: the pixels the network reads (module docstring, step 1)."""
    valid = (depth > 0) & (depth <= MAX_DEPTH_M) & np.isfinite(depth)
    if mask is not None:
        valid &= np.broadcast_to(mask, depth.shape)
    return valid


@dataclass(frozen=True)
class InputPipeline:
    """Depth in the training camera -> `NetworkInput` with `size` x `size` crops."""

    camera: CameraIntrinsics
    size: int

    def __call__(
        self, depth: NDArray[np.floating], mask: NDArray[np.bool_] | None = None
    ) -> NetworkInput:
        """(N, H, W) or (H, W) depth in metres (0 = no return) -> NetworkInput."""
        d = np.asarray(depth, dtype=np.float32)
        if d.ndim == 2:
            d = d[None]
        cam = self.camera
        if d.shape[1:] != (cam.height, cam.width):
            raise ValueError(
                f"depth images are {d.shape[2]}x{d.shape[1]}, camera is {cam.width}x{cam.height}"
            )
        valid_np = valid_pixels(d, mask)
        z = torch.from_numpy(np.where(valid_np, d, 0.0).astype(np.float32))
        valid = torch.from_numpy(valid_np)
        n, h, w = z.shape
        count = valid.sum((1, 2)).clamp(min=1).to(torch.float32)
        rows, cols = valid.any(2), valid.any(1)
        r0, r1 = _first_last(rows)
        c0, c1 = _first_last(cols)
        empty = ~rows.any(1)
        r0, c0 = torch.where(empty, 0.0, r0), torch.where(empty, 0.0, c0)
        r1, c1 = torch.where(empty, h - 1.0, r1), torch.where(empty, w - 1.0, c1)
        cu, cv = (c0 + c1) / 2, (r0 + r1) / 2
        side_px = (1 + CROP_MARGIN) * (torch.maximum(r1 - r0, c1 - c0) + 1) + 2
        theta = torch.zeros(n, 2, 3)
        theta[:, 0, 0], theta[:, 1, 1] = side_px / w, side_px / h
        theta[:, 0, 2], theta[:, 1, 2] = (2 * cu + 1) / w - 1, (2 * cv + 1) / h - 1
        grid = F.affine_grid(theta, [n, 1, self.size, self.size], align_corners=False)
        crop = F.grid_sample(z[:, None], grid, mode="nearest", align_corners=False)
        mean = z.sum((1, 2)) / count
        relative = (1 + (crop - mean[:, None, None, None]) / RELATIVE_DEPTH_M).clamp(
            *RELATIVE_RANGE
        )
        image = torch.where(crop > 0, relative, torch.zeros_like(crop))
        rays = torch.from_numpy(cam.ray_directions().copy())  # depth * ray = the pixel's point
        y = (z * rays[..., 1]).sum((1, 2)) / count
        up = (z * rays[..., 2]).sum((1, 2)) / count
        side = torch.stack(
            [
                mean, y, up,
                -(cu - cam.cx) / cam.fx, -(cv - cam.cy) / cam.fy,
                side_px / cam.fx, side_px / cam.fx * mean,
                (r0 <= 0).float(), (r1 >= h - 1).float(),
                (c0 <= 0).float(), (c1 >= w - 1).float(),
            ],
            dim=1,
        )  # fmt: skip
        side = torch.where(empty[:, None], torch.zeros_like(side), side)
        return NetworkInput(image, side)


def _first_last(any_: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(N, K) bool -> first and last True index per row (float; garbage for none)."""
    index = torch.arange(any_.shape[1], dtype=torch.float32)
    first = torch.where(any_, index, float(any_.shape[1])).amin(1)
    last = torch.where(any_, index, -1.0).amax(1)
    return first, last


def full_image(depth: NDArray[np.floating], mask: NDArray[np.bool_] | None = None) -> torch.Tensor:
    """(N, H, W) or (H, W) depth in metres -> (N, 1, H, W) float32: valid depth /
    `DEPTH_SCALE_M`, 0 elsewhere (the NN baseline's depth-image space)."""
    d = np.asarray(depth, dtype=np.float32)
    if d.ndim == 2:
        d = d[None]
    x = np.where(valid_pixels(d, mask), d / DEPTH_SCALE_M, 0.0).astype(np.float32)
    return torch.from_numpy(x[:, None])


def augment(inputs: NetworkInput, dropout_max: float, generator: torch.Generator) -> NetworkInput:
    """Drop a fraction U(0, dropout_max) of each crop's pixels (set them to 0)."""
    if dropout_max <= 0:
        return inputs
    x = inputs.image
    rate = torch.rand((x.shape[0], 1, 1, 1), generator=generator, device=x.device) * dropout_max
    keep = torch.rand(x.shape, generator=generator, device=x.device) >= rate
    return NetworkInput(x * keep, inputs.side)
