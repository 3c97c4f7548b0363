"""What the network predicts, and the label normalisation stored with the model.

The targets are the label columns of section 3.2.1 (docs/formats.md): geometry theta
(base pose, depth, width, height, chirality) and, per joint, the configuration q and the
kinematic parameters phi (axis origin and unit direction in the camera frame, the moving
part's origin in the axis frame). Each column is standardised with the training set's
mean and standard deviation; columns that do not vary in a category (e.g. the axis
direction's z component of a drawer) are not predicted: the codec stores their value
and puts it back when decoding.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: a column varies when its std exceeds this (labels are metres and radians)
CONSTANT_STD = 1e-9


@dataclass(frozen=True)
class TargetCodec:
    """Label columns <-> standardised network targets (the learned columns only)."""

    columns: tuple[str, ...]
    mean: NDArray[np.float64]  # (L,)
    std: NDArray[np.float64]  # (L,), 1 for constant columns
    learned: NDArray[np.bool_]  # (L,)

    @classmethod
    def fit(cls, columns: list[str], labels: NDArray[np.float64]) -> TargetCodec:
        """Statistics of `labels` (N, L), N > 0."""
        if labels.ndim != 2 or labels.shape[1] != len(columns) or len(labels) == 0:
            raise ValueError(f"labels {labels.shape} do not match {len(columns)} columns")
        mean = labels.mean(axis=0)
        std = labels.std(axis=0)
        learned = std > CONSTANT_STD
        return cls(tuple(columns), mean, np.where(learned, std, 1.0), learned)

    @property
    def dim(self) -> int:
        """Number of predicted (learned) columns: the MDN's output dimension."""
        return int(self.learned.sum())

    @property
    def learned_columns(self) -> list[str]:
        return [c for c, k in zip(self.columns, self.learned, strict=True) if k]

    def encode(self, labels: NDArray[np.float64]) -> NDArray[np.float32]:
        """(..., L) labels -> (..., D) standardised float32 targets."""
        z = (labels - self.mean) / self.std
        return z[..., self.learned].astype(np.float32)

    def decode(self, z: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
        """(..., D) standardised values -> (..., L) labels, constants filled in."""
        z = np.asarray(z, dtype=np.float64)
        out = np.broadcast_to(self.mean, (*z.shape[:-1], len(self.columns))).copy()
        out[..., self.learned] = z * self.std[self.learned] + self.mean[self.learned]
        return out

    def decode_scale(self, sigma: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
        """(..., D) standardised std devs -> (..., L) in label units (0 for constants)."""
        sigma = np.asarray(sigma, dtype=np.float64)
        out = np.zeros((*sigma.shape[:-1], len(self.columns)))
        out[..., self.learned] = sigma * self.std[self.learned]
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "columns": list(self.columns),
            "mean": self.mean.tolist(),
            "std": self.std.tolist(),
            "learned": self.learned.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TargetCodec:
        return cls(
            tuple(data["columns"]),
            np.asarray(data["mean"], dtype=np.float64),
            np.asarray(data["std"], dtype=np.float64),
            np.asarray(data["learned"], dtype=np.bool_),
        )
