"""Depth image -> network input, shared by training, evaluation and prediction.

1. Pixels outside the object mask (when one is given) and pixels without a return are
   0; valid depth is metric depth along the optical axis, in metres. The image is not
   cropped or re-centred: the network reads the object's position in the camera frame
   off where and how far the object appears, so the training camera's full field of
   view is kept (`artic predict` reprojects other cameras' images into it).
2. Depth beyond `MAX_DEPTH_M` is dropped (the sensor's range).
3. The input is depth / `DEPTH_SCALE_M`, one channel, float32 (N, 1, H, W).
Training adds augmentation (`augment`): a random fraction (up to `dropout_max`) of the
valid pixels of each image is dropped, like the sensor's missing returns.
"""

from __future__ import annotations

import numpy as np
import torch
from numpy.typing import NDArray

MAX_DEPTH_M = 6.0
DEPTH_SCALE_M = 4.0  # metres that map to 1.0


def network_input(
    depth: NDArray[np.floating], mask: NDArray[np.bool_] | None = None
) -> torch.Tensor:
    """(N, H, W) or (H, W) depth in metres (0 = no return) -> (N, 1, H, W) float32."""
    d = np.asarray(depth, dtype=np.float32)
    if d.ndim == 2:
        d = d[None]
    valid = (d > 0) & (d <= MAX_DEPTH_M) & np.isfinite(d)
    if mask is not None:
        valid &= np.broadcast_to(mask, d.shape)
    x = np.where(valid, d / DEPTH_SCALE_M, 0.0).astype(np.float32)
    return torch.from_numpy(x[:, None])


def augment(x: torch.Tensor, dropout_max: float, generator: torch.Generator) -> torch.Tensor:
    """Drop a fraction U(0, dropout_max) of each image's pixels (set them to 0)."""
    if dropout_max <= 0:
        return x
    n = x.shape[0]
    rate = torch.rand((n, 1, 1, 1), generator=generator, device=x.device) * dropout_max
    keep = torch.rand(x.shape, generator=generator, device=x.device) >= rate
    return x * keep
