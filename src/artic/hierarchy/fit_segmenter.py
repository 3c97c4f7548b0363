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
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import torch
from numpy.typing import NDArray

from artic.evaluation.segmentation import (
    mean_average_precision,
    motion_type_accuracy,
    object_detections,
)
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
from artic.learning.fit_state import FitState

log = logging.getLogger("artic")


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


@dataclass(frozen=True)
class AugmentConfig:
    """rotate_z_deg: rotation about z drawn uniformly in +-this, degrees (0: none).
    jitter_m: standard deviation of per-point Gaussian noise, metres (0: none)."""

    rotate_z_deg: float = 0.0
    jitter_m: float = 0.0


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


@dataclass(frozen=True)
class SegmenterFitConfig:
    epochs: int
    batch_size: int
    lr: float
    weight_decay: float
    patience: int
    seed: int
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    loss: LossWeights = field(default_factory=LossWeights)
    log_every_s: float = 30.0


class ValidationRecord(NamedTuple):
    loss: float  # mean total loss per cloud
    matched_iou: float  # mean soft IoU of the Hungarian-matched masks
    motion_accuracy: float  # fraction of points with the right motion type (argmax)


def fit_segmenter(
    model: PartSegmentationNet,
    optimizer: torch.optim.Optimizer,
    train: SegmentationData,
    val: SegmentationData,
    cfg: SegmenterFitConfig,
    state: FitState,
    device: torch.device,
    on_epoch: Callable[[FitState], None],
) -> FitState:
    """Train from `state` until `cfg.epochs` or early stopping; `on_epoch(state)` after
    each epoch (state.epoch = epochs done)."""
    model.to(device)
    while state.epoch < cfg.epochs and not state.stopped_early:
        t0 = time.perf_counter()
        train_loss, train_iou = train_epoch(model, optimizer, train, cfg, state.epoch, device)
        v = validate(model, val, cfg.batch_size, device, cfg.loss)
        state.end_epoch(v.loss, model, cfg.patience)
        seconds = time.perf_counter() - t0
        state.history.append(
            {"epoch": state.epoch, "train_loss": train_loss, "train_matched_iou": train_iou,
             "val_loss": v.loss, "val_matched_iou": v.matched_iou,
             "val_motion_accuracy": v.motion_accuracy, "seconds": seconds}
        )  # fmt: skip
        log.info(
            "epoch %d/%d: train loss %.3f, val loss %.3f (best %.3f at %d), val IoU %.3f, "
            "%.0f s",
            state.epoch, cfg.epochs, train_loss, v.loss, state.best_val, state.best_epoch,
            v.matched_iou, seconds,
        )  # fmt: skip
        on_epoch(state)
    return state


def train_epoch(
    model: PartSegmentationNet,
    optimizer: torch.optim.Optimizer,
    data: SegmentationData,
    cfg: SegmenterFitConfig,
    epoch: int,
    device: torch.device,
) -> tuple[float, float]:
    """One pass over `data` in the order drawn from (seed, epoch); (mean loss, mean
    matched IoU) per cloud."""
    order = np.random.default_rng([cfg.seed, epoch]).permutation(len(data))
    generator = torch.Generator().manual_seed(cfg.seed * 100_003 + epoch)
    total, iou, seen, last_log = 0.0, 0.0, 0, time.perf_counter()
    for start in range(0, len(order), cfg.batch_size):
        index = np.sort(order[start : start + cfg.batch_size])
        if len(index) < 2:
            continue  # BatchNorm needs two clouds per batch in training mode
        batch = data.batch(index)
        batch = batch._replace(points=augment(batch.points, cfg.augment, generator))
        record = train_step(model, optimizer, batch, cfg.loss)
        total += record.total * len(index)
        iou += record.matched_iou * len(index)
        seen += len(index)
        if time.perf_counter() - last_log > cfg.log_every_s:
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
