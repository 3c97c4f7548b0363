"""Training, validation and test images of a `render-depth` folder, held in memory.

Depth stays in its stored encoding (uint16 millimetres: 32 KiB per 128x128 image, so
the thesis' 176,000 images of one category take 5.8 GB) and is decoded batch by batch.
Splits are by object: the test objects are the ones `generate-dataset` withheld; of the
remaining objects, every `val_every`-th (object_id mod val_every = val_every - 1) is a
validation object used for early stopping, and the rest train.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from artic.artifacts.depth_dataset import DepthDataset, decode_depth

Split = Literal["train", "val", "test"]


def split_of(object_id: NDArray[np.int32], test: NDArray[np.bool_], val_every: int) -> NDArray:
    """Per image: "train", "val" or "test" (object-level, see the module docstring)."""
    val = (object_id % val_every == val_every - 1) & ~test
    return np.where(test, "test", np.where(val, "val", "train"))


@dataclass(frozen=True)
class DepthSplit:
    """Images of one split: stored depth (N, H, W), labels (N, L), object ids (N,)."""

    depth: NDArray[np.generic]
    labels: NDArray[np.float64]
    object_id: NDArray[np.int32]

    def __len__(self) -> int:
        return len(self.labels)

    def depth_m(self, index: NDArray[np.int64] | slice) -> NDArray[np.float32]:
        return decode_depth(self.depth[index])

    def head(self, n: int | None) -> DepthSplit:
        """The first `n` images (None: all)."""
        return DepthSplit(self.depth[:n], self.labels[:n], self.object_id[:n])

    @staticmethod
    def concat(parts: list[DepthSplit]) -> DepthSplit:
        """The images of `parts`, in order."""
        return DepthSplit(
            np.concatenate([p.depth for p in parts]),
            np.concatenate([p.labels for p in parts]),
            np.concatenate([p.object_id for p in parts]),
        )


def load_split(
    ds: DepthDataset, split: Split, val_every: int = 10, max_objects: int | None = None
) -> DepthSplit:
    """The images of `split`, shard by shard (each shard's sha256 is verified as read);
    `max_objects` keeps the first objects of the split (by object id)."""
    depth: list[NDArray[np.generic]] = []
    labels: list[NDArray[np.float64]] = []
    ids: list[NDArray[np.int32]] = []
    for shard in ds.shards(decode=False):
        keep = split_of(shard.object_id, shard.test, val_every) == split
        depth.append(shard.depth[keep])
        labels.append(shard.labels[keep])
        ids.append(shard.object_id[keep])
    out = DepthSplit(np.concatenate(depth), np.concatenate(labels), np.concatenate(ids))
    if max_objects is not None:
        chosen = np.unique(out.object_id)[:max_objects]
        keep = np.isin(out.object_id, chosen)
        out = DepthSplit(out.depth[keep], out.labels[keep], out.object_id[keep])
    return out
