"""`artic predict`: one depth image -> kinematic model, configuration, geometry (JSON).

Reads the image (`.npy` float metres, or a 16-bit PNG in millimetres; 0 = no return),
the camera intrinsics (JSON with fx, fy, cx, cy, width, height), an optional object
mask (PNG or .npy, nonzero = object), and the category's model (`artic train-mdn`).
An image from another camera is reprojected into the training camera.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any


def predict(
    image: Path,
    category: str,
    camera: Path,
    model: Path | None,
    mask: Path | None,
    samples: int,
    estimator: str,
    seed: int,
) -> dict[str, Any]:
    """Everything `artic predict` prints, as a dict (`kinematics.predict.predict_image`;
    the inputs are read by `artifacts.depth_image`)."""
    started = time.perf_counter()
    from artic.kinematics.predict import predict_image

    return predict_image(image, category, camera, model, mask, samples, estimator, seed, started)
