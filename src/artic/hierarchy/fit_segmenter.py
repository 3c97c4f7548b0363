"""Training of the section 4.3 part segmenter: Adam (learning rate 1e-4 in the thesis) on
the Hungarian-matched instance loss + motion-type loss, validation on withheld training
objects after every epoch, early stopping on the validation loss.

Clouds are prepared as `segment` sees them at inference: downsampled to `n_points` by
farthest-point sampling from point 0 (`prepare_cloud`). Optional augmentation: a random
rotation about z and Gaussian jitter per point.

Resumable and reproducible: epoch e's batch order and augmentation come from generators
seeded by (seed, e), so a run resumed from the checkpoint after epoch e continues exactly
as the uninterrupted run. Checkpoints are the caller's (`on_epoch`); no file access here.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import torch
from numpy.typing import NDArray

from artic.errors import InputError
from artic.evaluation.segmentation import (
    mean_average_precision,
    motion_type_accuracy,
    object_detections,
)
from artic.hierarchy.config import AugmentConfig, CloudDataConfig, SegmenterTrainConfig
from artic.hierarchy.pointnet2 import farthest_point_indices
from artic.hierarchy.segmentation import (
    InferenceConfig,
    LossWeights,
    PartSegmentationNet,
    SegmentationBatch,
    segment,
    segmentation_loss,
    train_step,
)
from artic.learning import trainer
from artic.learning.fit_state import FitState

if TYPE_CHECKING:
    from artic.artifacts.scan_dataset import ObjectSplit, ScanDataset

log = logging.getLogger("artic")

#: seconds between progress lines within an epoch
LOG_EVERY_S = 30.0


class PreparedCloud(NamedTuple):
    """One cloud at the network's input size S: points (S, 3) float32 metres, part_id
    (S,) int64, motion_type (S,) int64."""

    points: NDArray[np.float32]
    part_id: NDArray[np.int64]
    motion_type: NDArray[np.int64]


def prepare_cloud(
    points: NDArray[np.floating],
    part_id: NDArray[np.integer],
    motion_type: NDArray[np.integer],
    n_points: int,
    rng: np.random.Generator,
) -> PreparedCloud:
    """Downsample a labelled cloud (N, 3) to exactly `n_points` as `segment` does:
    farthest-point sampling from point 0; a cloud with fewer points keeps all of them
    plus duplicates drawn from `rng` (duplicates do not change the soft IoU much)."""
    n = len(points)
    if n >= n_points:
        index = farthest_point_indices(np.asarray(points, dtype=np.float32), n_points)
    else:
        index = np.concatenate([np.arange(n), rng.choice(n, n_points - n)])
    return PreparedCloud(
        np.asarray(points, dtype=np.float32)[index],
        np.asarray(part_id, dtype=np.int64)[index],
        np.asarray(motion_type, dtype=np.int64)[index],
    )


@dataclass(frozen=True)
class SegmentationData:
    """Prepared clouds: points (C, S, 3) float32, part_id (C, S) int64, motion_type (C, S)
    int64, object_id (C,) int64, noisy (C,) bool (a fused noisy scan, else clean)."""

    points: NDArray[np.float32]
    part_id: NDArray[np.int64]
    motion_type: NDArray[np.int64]
    object_id: NDArray[np.int64]
    noisy: NDArray[np.bool_]

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @staticmethod
    def stack(
        clouds: list[PreparedCloud], object_id: list[int], noisy: list[bool]
    ) -> SegmentationData:
        if not clouds:
            raise ValueError("no clouds")
        return SegmentationData(
            np.stack([c.points for c in clouds]),
            np.stack([c.part_id for c in clouds]),
            np.stack([c.motion_type for c in clouds]),
            np.asarray(object_id, dtype=np.int64),
            np.asarray(noisy, dtype=bool),
        )

    def batch(self, index: NDArray[np.int64]) -> SegmentationBatch:
        return SegmentationBatch(
            torch.from_numpy(self.points[index]),
            torch.from_numpy(self.part_id[index]),
            torch.from_numpy(self.motion_type[index]),
        )


def augment(points: torch.Tensor, cfg: AugmentConfig, generator: torch.Generator) -> torch.Tensor:
    """Randomly rotate each cloud of (B, S, 3) about z and jitter its points (CPU generator)."""
    out = points
    if cfg.rotate_z_deg > 0:
        b = points.shape[0]
        angle = (torch.rand(b, generator=generator) * 2 - 1) * math.radians(cfg.rotate_z_deg)
        c, s = torch.cos(angle), torch.sin(angle)
        rot = torch.zeros(b, 3, 3)
        rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1] = c, -s, s, c
        rot[:, 2, 2] = 1.0
        out = out @ rot.transpose(1, 2)
    if cfg.jitter_m > 0:
        out = out + torch.randn(out.shape, generator=generator) * cfg.jitter_m
    return out


class ValidationRecord(NamedTuple):
    loss: float  # mean total loss per cloud
    matched_iou: float  # mean soft IoU of the Hungarian-matched masks
    motion_accuracy: float  # fraction of points with the right motion type (argmax)


def fit_segmenter(
    model: PartSegmentationNet,
    optimizer: torch.optim.Optimizer,
    train: SegmentationData,
    val: SegmentationData,
    cfg: SegmenterTrainConfig,
    augmentation: AugmentConfig,
    seed: int,
    state: FitState,
    device: torch.device,
    on_epoch: Callable[[FitState], None],
    loss: LossWeights | None = None,
) -> FitState:
    """Train from `state` until `cfg.epochs` or early stopping (`learning.trainer.fit`);
    `on_epoch(state)` after each epoch (state.epoch = epochs done)."""
    model.to(device)
    weights = loss or LossWeights()

    def run_epoch(epoch: int) -> trainer.EpochResult:
        train_loss, train_iou = train_epoch(
            model, optimizer, train, cfg, augmentation, seed, epoch, device, weights
        )
        v = validate(model, val, cfg.batch_size, device, weights)
        return trainer.EpochResult(v.loss, {
            "train_loss": train_loss, "train_matched_iou": train_iou, "val_loss": v.loss,
            "val_matched_iou": v.matched_iou, "val_motion_accuracy": v.motion_accuracy,
        })  # fmt: skip

    def summary(r: trainer.EpochResult) -> str:
        m = r.metrics
        iou = m["val_matched_iou"]
        return f"train loss {m['train_loss']:.3f}, val loss {r.val_loss:.3f}, val IoU {iou:.3f}"

    return trainer.fit(model, state, cfg.epochs, cfg.patience, run_epoch, on_epoch, summary)


def train_epoch(
    model: PartSegmentationNet,
    optimizer: torch.optim.Optimizer,
    data: SegmentationData,
    cfg: SegmenterTrainConfig,
    augmentation: AugmentConfig,
    seed: int,
    epoch: int,
    device: torch.device,
    weights: LossWeights,
) -> tuple[float, float]:
    """One pass over `data` in the order drawn from (seed, epoch); (mean loss, mean
    matched IoU) per cloud."""
    order = np.random.default_rng([seed, epoch]).permutation(len(data))
    generator = torch.Generator().manual_seed(seed * 100_003 + epoch)
    total, iou, seen, last_log = 0.0, 0.0, 0, time.perf_counter()
    for start in range(0, len(order), cfg.batch_size):
        index = np.sort(order[start : start + cfg.batch_size])
        if len(index) < 2:
            continue  # BatchNorm needs two clouds per batch in training mode
        batch = data.batch(index)
        batch = batch._replace(points=augment(batch.points, augmentation, generator))
        record = train_step(model, optimizer, batch, weights)
        total += record.total * len(index)
        iou += record.matched_iou * len(index)
        seen += len(index)
        if time.perf_counter() - last_log > LOG_EVERY_S:
            log.info(
                "  epoch %d: %d/%d clouds, loss %.3f", epoch + 1, seen, len(data), total / seen
            )
            last_log = time.perf_counter()
    return total / max(seen, 1), iou / max(seen, 1)


@torch.no_grad()
def validate(
    model: PartSegmentationNet,
    data: SegmentationData,
    batch_size: int,
    device: torch.device,
    weights: LossWeights | None = None,
) -> ValidationRecord:
    """Mean loss, matched IoU and motion-type accuracy of `data` in evaluation mode."""
    model.eval()
    loss, iou, correct, seen = 0.0, 0.0, 0.0, 0
    for start in range(0, len(data), batch_size):
        index = np.arange(start, min(start + batch_size, len(data)))
        batch = data.batch(index)
        out = model(batch.points.to(device))
        part_id, motion = batch.part_id.to(device), batch.motion_type.to(device)
        losses = segmentation_loss(out, part_id, motion, weights)
        loss += float(losses.total) * len(index)
        iou += float(losses.matched_iou) * len(index)
        correct += float((out.motion_logits.argmax(-1) == motion).float().mean()) * len(index)
        seen += len(index)
    return ValidationRecord(loss / max(seen, 1), iou / max(seen, 1), correct / max(seen, 1))


class SegmentationScores(NamedTuple):
    """Table 4.1 metrics on prepared clouds: mAP at IoU 0.5 (pooled) and per-point
    motion-type accuracy; NaN when there are no clouds of that kind."""

    map_clean: float
    map_noisy: float
    motion_accuracy: float
    clouds: int


def score_segmenter(
    model: PartSegmentationNet, data: SegmentationData, inference: InferenceConfig
) -> SegmentationScores:
    """Run `segment` on every prepared cloud (already at the network's input size, so no
    further downsampling) and score it against the ground truth (PartNet protocol)."""
    detections: dict[bool, list[Any]] = {False: [], True: []}
    accuracy = []
    for i in range(len(data)):
        result = segment(model, data.points[i], inference)
        detections[bool(data.noisy[i])].append(
            object_detections(result.part_id, result.part_confidence, data.part_id[i])
        )
        accuracy.append(motion_type_accuracy(result.motion_type, data.motion_type[i]))

    def m_ap(kind: bool) -> float:
        return mean_average_precision(detections[kind]) if detections[kind] else math.nan

    mean_accuracy = float(np.mean(accuracy)) if accuracy else math.nan
    return SegmentationScores(m_ap(False), m_ap(True), mean_accuracy, len(data))


def training_objects(ds: ScanDataset, data: CloudDataConfig) -> ObjectSplit:
    """The scan folder's training objects (the first `data.max_train_objects`) split by
    object into training and validation; InputError when either side is empty."""
    from artic.artifacts.scan_dataset import split_train_objects

    train_ids = ds.object_ids("train")[: data.max_train_objects]
    split = split_train_objects(train_ids, data.val_every)
    if not split.train or not split.val:
        raise InputError(
            f"scans: {ds.root} has {len(train_ids)} training objects; with "
            f"data.val_every={data.val_every} that leaves {len(split.train)} to train "
            f"on and {len(split.val)} to validate on; scan more objects"
        )
    return split


def load_clouds(
    ds: ScanDataset,
    objects: list[int],
    data: CloudDataConfig,
    n_points: int,
    n_masks: int,
    seed: int,
) -> tuple[SegmentationData, int]:
    """The prepared training clouds of `objects` (kinds and poses per `data`, each
    downsampled to `n_points`, seeded from (seed, object, pose, noisy)) and the number of
    clouds skipped for having more parts than `n_masks`."""
    rows = ds.select("train", data.kinds, objects)
    if data.max_poses is not None:
        rows = [r for r in rows if r.pose < data.max_poses]
    clouds, ids, noisy, skipped = [], [], [], 0
    for row in rows:
        cloud = ds.cloud(row)
        assert cloud.part_id is not None and cloud.motion_type is not None
        if len(np.unique(cloud.part_id[cloud.part_id >= 0])) > n_masks:
            skipped += 1
            continue
        rng = np.random.default_rng([seed, row.object_id, row.pose, row.kind == "noisy"])
        clouds.append(prepare_cloud(cloud.points, cloud.part_id, cloud.motion_type, n_points, rng))
        ids.append(row.object_id)
        noisy.append(row.kind == "noisy")
    if not clouds:
        raise InputError(f"scans: {ds.root} has no usable clouds of objects {objects[:5]}...")
    return SegmentationData.stack(clouds, ids, noisy), skipped
