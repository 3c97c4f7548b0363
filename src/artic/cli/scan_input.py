"""Reading what `artic segment`, `build-hierarchy` and `infer-hierarchy` are given: the
scan (PLY), the options shared by the three commands, the default output folder and the
models (docs/hierarchy.md).

Bad input is an `InputError` naming the file or option: a missing, empty or non-PLY file,
NaN or infinite coordinates, fewer points than the segmenter needs, all points in one
spot, or millimetre units (bounding-box diagonal > 20; `--scale auto` divides by 1000 and
logs it instead). A cloud above `--max-points` is accepted and the adaptation logged.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from artic.artifacts.manifest import MANIFEST, read_manifest
from artic.artifacts.ply import MILLIMETRE_DIAGONAL, PlyCloud, read_ply
from artic.errors import InputError
from artic.hierarchy.infer import MAX_POINTS

if TYPE_CHECKING:
    from artic.hierarchy.models import LoadedLabeller, LoadedSegmenter

log = logging.getLogger("artic")

DEFAULT_CATEGORY = "storage_furniture"
SEGMENTER_ROOT = Path("artifacts/models/segmenter")
LABELLER_ROOT = Path("artifacts/models/hierarchy")
MIN_DIAGONAL = 1e-3  # m: a smaller cloud is a point, not an object
_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


@dataclass(frozen=True)
class Options:
    """The settings shared by the three commands (recorded in the manifest)."""

    category: str | None = None  # None: storage_furniture for default model paths, unchecked
    scale: str = "1"  # "auto" or a positive factor applied to the coordinates
    max_points: int = MAX_POINTS
    seed: int = 0

    @property
    def category_name(self) -> str:
        return self.category or DEFAULT_CATEGORY


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


def read_scan(path: Path, opts: Options) -> Scan:
    """Read and check a PLY scan (module doc); InputError naming the file on bad input.
    Read it before loading any model, so a bad scan is the error the user sees first."""
    if opts.max_points < 1:
        raise InputError(f"--max-points: expected >= 1, got {opts.max_points}")
    scale = parse_scale(opts.scale)
    if path.is_file() and path.stat().st_size == 0:
        raise InputError(f"{path}: empty file, expected a PLY point cloud")
    cloud: PlyCloud = read_ply(path, min_points=1, max_points=opts.max_points)
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
            opts.max_points,
            opts.seed,
        )
    points = (cloud.points.astype(np.float64) * factor).astype(np.float32)
    return Scan(path, points, cloud.part_id, factor)


def require_points(scan: Scan, min_points: int) -> None:
    """InputError naming the file when the scan has fewer points than the segmenter needs."""
    n = len(scan.points)
    if n < min_points:
        raise InputError(f"{scan.path}: {n} points; the segmenter needs at least {min_points}")


def default_out(path: Path, command: str) -> Path:
    """The output folder when --out is not given (module doc)."""
    if command == "segment":
        return path.parent / f"{path.stem}_segmented"
    folder = path.parent
    if command == "build-hierarchy" and (folder / MANIFEST).is_file():
        try:
            stage = read_manifest(folder).stage
        except InputError:
            stage = ""
        if stage == "segment":
            return folder.parent / f"{folder.name.removesuffix('_segmented')}_hierarchy"
    return folder / f"{path.stem}_hierarchy"


def _check_category(opts: Options) -> None:
    if opts.category is not None and not _NAME.match(opts.category):
        raise InputError(f"--category: '{opts.category}' is not a category name")


def load_segmenter_for(model: Path | None, opts: Options) -> tuple[LoadedSegmenter, Path]:
    from artic.hierarchy.models import load_segmenter

    _check_category(opts)
    path = model or SEGMENTER_ROOT / opts.category_name / "model.pt"
    if model is None and not path.is_file():
        raise InputError(
            f"{path}: no segmenter for {opts.category_name}; train one with: "
            f"artic train-segmenter category={opts.category_name}"
        )
    return load_segmenter(path, opts.category), path


def load_labeller_for(model: Path | None, opts: Options) -> tuple[LoadedLabeller, Path]:
    from artic.hierarchy.models import load_labeller

    _check_category(opts)
    path = model or LABELLER_ROOT / opts.category_name / "model.pt"
    if model is None and not path.is_file():
        raise InputError(
            f"{path}: no hierarchy model for {opts.category_name}; train one with: "
            f"artic train-hierarchy category={opts.category_name}"
        )
    return load_labeller(path, opts.category), path
