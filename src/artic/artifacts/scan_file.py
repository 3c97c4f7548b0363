"""The scan `artic segment`, `build-hierarchy` and `infer-hierarchy` are given (a PLY,
docs/hierarchy.md), read and checked.

Bad input is an `InputError` naming the file or option: a missing, empty or non-PLY file,
NaN or infinite coordinates, fewer points than the segmenter needs, all points in one
spot, or millimetre units (bounding-box diagonal > 20; `--scale auto` divides by 1000 and
logs it instead). A cloud above `--max-points` is accepted and the adaptation logged.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from artic.artifacts.ply import MILLIMETRE_DIAGONAL, PlyCloud, read_ply
from artic.errors import InputError

log = logging.getLogger("artic")

MIN_DIAGONAL = 1e-3  # m: a smaller cloud is a point, not an object


@dataclass(frozen=True)
class Scan:
    """A scan read and checked: points (N, 3) float32 metres (scaled), part_id (N,) or
    None, the factor applied to the file's coordinates."""

    path: Path
    points: NDArray[np.float32]
    part_id: NDArray[np.int64] | None
    factor: float


def parse_scale(text: str) -> float | None:
    """`--scale`: "auto" -> None, else a positive float (InputError otherwise)."""
    if text.strip().lower() == "auto":
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"--scale: expected 'auto' or a positive number, got '{text}'")
    return value


def read_scan(path: Path, scale_text: str, max_points: int, seed: int) -> Scan:
    """Read and check a PLY scan (module doc) given the options `--scale`, `--max-points`
    and `--seed`; InputError naming the file or option on bad input. Read it before
    loading any model, so a bad scan is the error the user sees first."""
    if max_points < 1:
        raise InputError(f"--max-points: expected >= 1, got {max_points}")
    scale = parse_scale(scale_text)
    if path.is_file() and path.stat().st_size == 0:
        raise InputError(f"{path}: empty file, expected a PLY point cloud")
    cloud: PlyCloud = read_ply(path, min_points=1, max_points=max_points)
    factor = scale if scale is not None else (1e-3 if cloud.likely_millimetres else 1.0)
    if scale is None and cloud.likely_millimetres:
        log.info(
            "%s: units look like millimetres (bounding-box diagonal %.1f); --scale auto: "
            "coordinates divided by 1000",
            path,
            cloud.diagonal,
        )
    diagonal = cloud.diagonal * factor
    if diagonal > MILLIMETRE_DIAGONAL:
        raise InputError(
            f"{path}: units look like millimetres (bounding-box diagonal {diagonal:.1f}); "
            "divide by 1000 (or pass --scale auto)"
        )
    if diagonal < MIN_DIAGONAL:
        raise InputError(
            f"{path}: all points lie within {diagonal:.2g} m of each other; "
            "expected an object in metres"
        )
    n = len(cloud.points)
    if cloud.too_many_points:
        log.info(
            "%s: %d points; working on a random subset of %d (seed %d); every point gets "
            "the labels of its nearest kept point",
            path,
            n,
            max_points,
            seed,
        )
    points = (cloud.points.astype(np.float64) * factor).astype(np.float32)
    return Scan(path, points, cloud.part_id, factor)


def require_points(scan: Scan, min_points: int) -> None:
    """InputError naming the file when the scan has fewer points than the segmenter needs."""
    n = len(scan.points)
    if n < min_points:
        raise InputError(f"{scan.path}: {n} points; the segmenter needs at least {min_points}")
