"""Intervals of the refined estimate (issue 19: calibration "for the refined estimate
too"; docs/kinematics.md, "The refined estimate's intervals").

The refinement (kinematics/refine.py) moves the point estimate; its central interval at
level p is the refined estimate +- k_p x the half-width of the network's central p
interval of the same image and column (normalised split conformal prediction): the
network's width says how sure it is of this image, k_p (one per column, fitted on images
withheld from training by `artic evaluate mdn`, `refined_scales`) how far the refined
estimate lies from the truth against that width. `evaluate mdn` writes the scales as
`refined_intervals.csv` (a row per level: `nominal` and one column per label column);
beside a model's `model.pt`, `artic predict` prints the refined estimate's intervals
with them (`read_refined_intervals`).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from artic.artifacts.model_store import REFINED_INTERVALS
from artic.errors import InputError

__all__ = [
    "MIN_HALF_WIDTH",
    "REFINED_INTERVALS",
    "Scales",
    "read_refined_intervals",
    "refined_interval",
    "refined_scales",
    "write_refined_intervals",
]

#: the network's half-widths are taken as at least this (label units) in the refined
#: estimate's intervals (a column the network is sure of to the last digit)
MIN_HALF_WIDTH = 1e-12

Scales = dict[float, NDArray[np.float64]]


def refined_scales(
    refined: NDArray[np.float64],
    truth: NDArray[np.float64],
    half: NDArray[np.float64],
    level: float,
) -> NDArray[np.float64]:
    """Per column (L,): the scale k of the refined estimate's central `level` interval,
    estimate +- k x the half-width of the network's interval at that level, from images
    withheld from training (N, L each): normalised split conformal prediction. Each
    image's score is |refined - truth| / half-width; k is the ceil((N + 1) level)-th
    smallest score (inf when that exceeds N), so that a new image from the same data lies
    inside with probability at least `level`. The network's width carries how sure it is
    of this image; k, how far the refinement moves the estimate against that."""
    scores = np.abs(refined - truth) / np.maximum(half, MIN_HALF_WIDTH)
    rank = math.ceil((len(scores) + 1) * level)
    if rank > len(scores):
        return np.full(scores.shape[1], np.inf)
    # a hair wider: the image that sets k stays inside after rounding
    return np.asarray(np.sort(scores, axis=0)[rank - 1] * (1 + 1e-9), dtype=np.float64)


def refined_interval(
    refined: NDArray[np.float64], half: NDArray[np.float64], k: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The refined estimate's interval (lower, upper), each (N, L): the estimate (N, L)
    +- k (L,) x the network's half-width (N, L) (`refined_scales`)."""
    reach = np.where(np.isinf(k), np.inf, k * np.maximum(half, MIN_HALF_WIDTH))
    return refined - reach, refined + reach


def write_refined_intervals(path: Path, columns: list[str], scales: Scales) -> None:
    """`scales` (level -> (L,) k, NaN for a column the network does not learn) as csv."""
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["nominal", *columns])
        for level, k in sorted(scales.items()):
            w.writerow([level, *k.tolist()])


def read_refined_intervals(path: Path, columns: list[str]) -> Scales:
    """The scales of `path` (`write_refined_intervals`) for a model with label `columns`;
    InputError naming the file when its columns are not the model's or a value is not a
    number >= 0 (or NaN) at a level in (0, 1)."""
    try:
        with path.open(newline="") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"{path}: cannot read it ({err})") from None
    if not rows or rows[0] != ["nominal", *columns]:
        raise InputError(f"{path}: its columns are not the model's label columns")
    scales: Scales = {}
    for n, row in enumerate(rows[1:], start=2):
        try:
            values = [float(v) for v in row]
        except ValueError:
            raise InputError(f"{path}: line {n}: not a number") from None
        level, k = values[0], np.array(values[1:], dtype=np.float64)
        if len(k) != len(columns) or not 0 < level < 1 or np.any(k < 0):
            raise InputError(f"{path}: line {n}: a level in (0, 1) and a scale >= 0 per column")
        scales[level] = k
    return scales
