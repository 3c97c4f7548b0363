"""Training of the section 4.3 part segmenter: Adam (learning rate 1e-4 in the thesis) on
the Hungarian-matched instance loss + motion-type loss (masks head) or on the offset and
motion-type losses (votes head, `artic.hierarchy.votes`), validation on withheld training
objects after every epoch, early stopping on the validation loss. The votes head's
clustering radius is then chosen on the validation clouds (`choose_cluster_radius`) and,
with `train.select_*`, passes and minimum part size on whole validation scans
(`choose_inference`).

Clouds are prepared as `segment` sees them at inference: downsampled to `n_points` by
farthest-point sampling from point 0 (`prepare_cloud`). Optional augmentation: a random
rotation about z and Gaussian jitter per point.

Resumable and reproducible: epoch e's batch order and augmentation come from generators
seeded by (seed, e), so a run resumed from the checkpoint after epoch e continues exactly
as the uninterrupted run. Checkpoints are the caller's (`on_epoch`); no file access here.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np
import torch
from numpy.typing import NDArray

from artic.errors import InputError
from artic.evaluation.segmentation import (
    mean_average_precision,
    motion_type_accuracy,
    object_detections,
)
from artic.hierarchy.config import (
    AugmentConfig,
    CloudDataConfig,
    SegmenterModelConfig,
    SegmenterTrainConfig,
)
from artic.hierarchy.pointnet2 import BackboneIndex, farthest_point_indices, stack_indices
from artic.hierarchy.segmentation import (
    QUALITY,
    InferenceConfig,
    LossWeights,
    PartSegmentationNet,
    SegmentationBatch,
    SegmentationConfig,
    SegmentationOutput,
    forward,
    run_batch,
    segment,
    train_step,
)
from artic.hierarchy.votes import STATIC, VoteOutput, axis_targets, part_weights, sought
from artic.learning import trainer
from artic.learning.fit_state import FitState

if TYPE_CHECKING:
    from artic.artifacts.scan_dataset import ObjectSplit, ScanDataset
    from artic.objects.tree import KinematicTree

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


def static_part_of(
    part_id: NDArray[np.int64], motion_type: NDArray[np.int64]
) -> Literal["votes", "one"]:
    """`model.static_part=auto`: "one" when no cloud (C, S) has two parts of the static
    motion type (their static points are one rigid body), else "votes"."""
    static = (motion_type == STATIC) & (part_id >= 0)
    cloud = np.nonzero(static)[0]
    pairs = np.unique(np.stack([cloud, part_id[static]]), axis=1)
    return "votes" if (np.bincount(pairs[0]) > 1).any() else "one"


@dataclass(frozen=True)
class SegmentationData:
    """Prepared clouds: points (C, S, 3) float32, part_id (C, S) int64, motion_type (C, S)
    int64, object_id (C,) int64, noisy (C,) bool (a fused noisy scan, else clean), and
    after `with_features`: normals (C, S, 3) float32 and every cloud's backbone
    neighbourhoods (computed once, `cloud_cache`), which batches then carry."""

    points: NDArray[np.float32]
    part_id: NDArray[np.int64]
    motion_type: NDArray[np.int64]
    object_id: NDArray[np.int64]
    noisy: NDArray[np.bool_]
    normals: NDArray[np.float32] | None = None
    neighbourhoods: list[BackboneIndex] | None = None
    # (C, S) int64 `votes.axis_targets` (the axis head's), -1 to ignore; None: not loaded
    axis_vertical: NDArray[np.int64] | None = None

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @staticmethod
    def stack(
        clouds: list[PreparedCloud],
        object_id: list[int],
        noisy: list[bool],
        axis_vertical: list[NDArray[np.int64]] | None = None,
    ) -> SegmentationData:
        if not clouds:
            raise ValueError("no clouds")
        return SegmentationData(
            np.stack([c.points for c in clouds]),
            np.stack([c.part_id for c in clouds]),
            np.stack([c.motion_type for c in clouds]),
            np.asarray(object_id, dtype=np.int64),
            np.asarray(noisy, dtype=bool),
            axis_vertical=None if axis_vertical is None else np.stack(axis_vertical),
        )

    def batch(self, index: NDArray[np.int64]) -> SegmentationBatch:
        return SegmentationBatch(
            torch.from_numpy(self.points[index]),
            torch.from_numpy(self.part_id[index]),
            torch.from_numpy(self.motion_type[index]),
            None if self.normals is None else torch.from_numpy(self.normals[index]),
            None
            if self.neighbourhoods is None
            else stack_indices([self.neighbourhoods[i] for i in index]),
            None if self.axis_vertical is None else torch.from_numpy(self.axis_vertical[index]),
        )

    def with_features(self, config: SegmentationConfig, cache: Path | None) -> SegmentationData:
        """The same clouds with their normals and neighbourhoods under `config`, read from
        or written to the content-keyed `cache` folder (`cloud_cache.cloud_features`)."""
        from artic.hierarchy.cloud_cache import cloud_features

        features = [cloud_features(p, config, cache) for p in self.points]
        normals = np.stack([f.normals for f in features]).astype(np.float32)
        return dataclasses.replace(
            self, normals=normals, neighbourhoods=[f.neighbourhoods for f in features]
        )


def augment(
    batch: SegmentationBatch, cfg: AugmentConfig, generator: torch.Generator
) -> SegmentationBatch:
    """Randomly mirror each cloud of the batch in y, rotate it about z (its normals too)
    and jitter its points (CPU generator). Mirroring and rotating keep every distance, so
    the clouds' cached neighbourhoods stay valid; jitter is applied after them and the
    neighbourhoods stay those of the unjittered cloud."""
    points, normals = batch.points, batch.normals
    if cfg.mirror_y:
        flip = torch.rand(points.shape[0], generator=generator) < 0.5
        sign = torch.ones(points.shape[0], 1, 3)
        sign[flip, 0, 1] = -1.0
        points = points * sign
        normals = None if normals is None else normals * sign
    if cfg.rotate_z_deg > 0:
        b = points.shape[0]
        angle = (torch.rand(b, generator=generator) * 2 - 1) * math.radians(cfg.rotate_z_deg)
        c, s = torch.cos(angle), torch.sin(angle)
        rot = torch.zeros(b, 3, 3)
        rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1] = c, -s, s, c
        rot[:, 2, 2] = 1.0
        points = points @ rot.transpose(1, 2)
        normals = None if normals is None else normals @ rot.transpose(1, 2)
    if cfg.jitter_m > 0:
        points = points + torch.randn(points.shape, generator=generator) * cfg.jitter_m
    return batch._replace(points=points, normals=normals)


class ValidationRecord(NamedTuple):
    loss: float  # mean total loss per cloud
    quality: float  # the head's QUALITY term: matched IoU (masks) or offset error (votes)
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
    inference: InferenceConfig | None = None,
) -> FitState:
    """Train from `state` until `cfg.epochs` or early stopping (`learning.trainer.fit`);
    `on_epoch(state)` after each epoch (state.epoch = epochs done). With `inference`,
    every epoch also scores the validation clouds' mAP@0.5 through `segment` (the one
    measure both heads share, for comparing them)."""
    model.to(device)
    weights = loss or LossWeights()
    quality = QUALITY[model.config.head]

    def run_epoch(epoch: int) -> trainer.EpochResult:
        train_loss, train_quality = train_epoch(
            model, optimizer, train, cfg, augmentation, seed, epoch, device, weights
        )
        v = validate(model, val, cfg.batch_size, device, weights)
        metrics = {
            "train_loss": train_loss, f"train_{quality}": train_quality, "val_loss": v.loss,
            f"val_{quality}": v.quality, "val_motion_accuracy": v.motion_accuracy,
        }  # fmt: skip
        if inference is not None:
            scores = score_segmenter(model, val, inference)
            metrics |= {"val_map50_clean": scores.map_clean, "val_map50_noisy": scores.map_noisy}
        return trainer.EpochResult(v.loss, metrics)

    def summary(r: trainer.EpochResult) -> str:
        m = r.metrics
        q = m[f"val_{quality}"]
        return f"train loss {m['train_loss']:.3f}, val loss {r.val_loss:.3f}, val {quality} {q:.3f}"

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
    QUALITY term) per cloud."""
    order = np.random.default_rng([seed, epoch]).permutation(len(data))
    generator = torch.Generator().manual_seed(seed * 100_003 + epoch)
    quality = QUALITY[model.config.head]
    total, measure, seen, last_log = 0.0, 0.0, 0, time.perf_counter()
    for start in range(0, len(order), cfg.batch_size):
        index = np.sort(order[start : start + cfg.batch_size])
        if len(index) < 2:
            continue  # BatchNorm needs two clouds per batch in training mode
        batch = augment(data.batch(index), augmentation, generator)
        trainer.set_learning_rate(optimizer, cfg, epoch + start / len(order))
        terms = train_step(model, optimizer, batch, weights)
        total += terms["total"] * len(index)
        measure += terms[quality] * len(index)
        seen += len(index)
        if time.perf_counter() - last_log > trainer.LOG_EVERY_S:
            log.info(
                "  epoch %d: %d/%d clouds, loss %.3f", epoch + 1, seen, len(data), total / seen
            )
            last_log = time.perf_counter()
    return total / max(seen, 1), measure / max(seen, 1)


@torch.no_grad()
def validate(
    model: PartSegmentationNet,
    data: SegmentationData,
    batch_size: int,
    device: torch.device,
    weights: LossWeights | None = None,
) -> ValidationRecord:
    """Mean loss, QUALITY term and motion-type accuracy of `data` in evaluation mode."""
    model.eval()
    quality = QUALITY[model.config.head]
    loss, measure, correct, seen = 0.0, 0.0, 0.0, 0
    for start in range(0, len(data), batch_size):
        index = np.arange(start, min(start + batch_size, len(data)))
        losses = run_batch(model, data.batch(index), weights)
        loss += losses.terms["total"] * len(index)
        measure += losses.terms[quality] * len(index)
        correct += losses.terms["motion_accuracy"] * len(index)
        seen += len(index)
    return ValidationRecord(loss / max(seen, 1), measure / max(seen, 1), correct / max(seen, 1))


class SegmentationScores(NamedTuple):
    """Table 4.1 metrics on prepared clouds: mAP at IoU 0.5 (pooled) and per-point
    motion-type accuracy; NaN when there are no clouds of that kind."""

    map_clean: float
    map_noisy: float
    motion_accuracy: float
    clouds: int


def network_outputs(
    model: PartSegmentationNet, data: SegmentationData, mirror_y: bool = False
) -> list[SegmentationOutput | VoteOutput]:
    """The network's output on every prepared cloud (with its cached features; averaged
    with the mirror image's for `mirror_y`, as `segment` does), to score several inference
    settings without running it again."""
    device = next(model.parameters()).device
    outputs = []
    for i in range(len(data)):
        normals = (
            None if data.normals is None else torch.from_numpy(data.normals[i]).to(device)[None]
        )
        index = None if data.neighbourhoods is None else data.neighbourhoods[i].to(device)
        outputs.append(forward(model, data.points[i], normals, index, mirror_y))
    return outputs


class AxisHeadFit(NamedTuple):
    """What `fit_axis_head` did: the mean loss of each epoch and, on the validation
    clouds, the fraction of labelled points whose axis it reads right, over points and
    with every (cloud, part) pair weighing the same."""

    losses: list[float]
    val_accuracy: float
    val_part_accuracy: float


def with_axis_head(model: PartSegmentationNet) -> PartSegmentationNet:
    """A copy of a votes-head `model` with an axis head (`model.axis_head`) added, every
    other weight the model's own; the head's initial weights from torch's default
    initialisation under the current seed."""
    if model.config.head != "votes":
        raise InputError("axis head: only the votes head (model.head=votes) has one")
    grown = PartSegmentationNet(dataclasses.replace(model.config, axis_head=True))
    missing, unexpected = grown.load_state_dict(model.state_dict(), strict=False)
    assert not unexpected and all(k.startswith("axis.") for k in missing), (missing, unexpected)
    return grown


def _point_features(
    model: PartSegmentationNet, data: SegmentationData
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The backbone's features (P, C) of every point with an axis target in `data` (with
    its cached features), evaluation mode, those targets (P,) float32 and each point's
    weight (P,): every (cloud, part) pair weighs the same, its points share it (a caster
    of 6 points says as much as a seat of 400), the weights summing to 1 (`part_weights`,
    as `vote_loss` weighs the axis loss)."""
    from artic.hierarchy.segmentation import normalize_points

    assert data.axis_vertical is not None and data.normals is not None
    assert data.neighbourhoods is not None
    model.eval()
    features, targets = [], []
    with torch.no_grad():
        for i in range(len(data)):
            known = data.axis_vertical[i] >= 0
            if not known.any():
                continue
            xyz = torch.from_numpy(data.points[i])[None]
            xyz = normalize_points(xyz) if model.config.normalize else xyz
            normals = torch.from_numpy(data.normals[i])[None] if model.config.normals else None
            out = model.backbone(xyz, normals, index=data.neighbourhoods[i])
            features.append(out.point_features[0][torch.from_numpy(known)])
            targets.append(torch.from_numpy(data.axis_vertical[i][known]).float())
    known_all = torch.from_numpy(data.axis_vertical >= 0)  # the points above, in their order
    weight = part_weights(torch.from_numpy(data.part_id), known_all).float()
    return torch.cat(features), torch.cat(targets), weight


def fit_axis_head(
    model: PartSegmentationNet,
    train: SegmentationData,
    val: SegmentationData,
    epochs: int,
    seed: int,
    lr: float = 1e-3,
    batch_points: int = 4096,
) -> AxisHeadFit:
    """Train `model.axis` alone (a model from `with_axis_head`) on the axis targets of the
    `train` clouds (with their cached features and `axis_vertical`): the rest of the
    network frozen, its features computed once (evaluation mode, no augmentation), the
    head trained on them with Adam in batches of `batch_points` points (binary
    cross-entropy, every (cloud, part) pair weighing the same: `_point_features`), `epochs`
    passes in an order seeded by (seed, epoch). The backbone, motion and offset weights stay the
    bytes they were, so everything else the segmenter does stays as it was."""
    if not model.config.axis_head:
        raise ValueError("fit_axis_head: the model has no axis head (with_axis_head)")
    x, y, w = _point_features(model, train)
    head = model.axis
    optimizer = torch.optim.Adam(head.parameters(), lr=lr)
    losses = []
    for epoch in range(epochs):
        generator = torch.Generator().manual_seed(seed * 1_000_003 + epoch)
        order = torch.randperm(len(y), generator=generator)
        head.train()
        total, count = 0.0, 0
        for start in range(0, len(y), batch_points):
            batch = order[start : start + batch_points]
            if len(batch) < 2:  # batch norm needs two
                continue
            logits = head(x[batch][None])[0, :, 0]
            weight = w[batch] / w[batch].sum()
            loss = torch.nn.functional.binary_cross_entropy_with_logits(
                logits, y[batch], weight=weight, reduction="sum"
            )
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            total, count = total + float(loss.detach()), count + 1
        losses.append(total / max(count, 1))
        log.info("axis head epoch %d: loss %.4f", epoch + 1, losses[-1])
    model.eval()
    xv, yv, wv = _point_features(model, val)
    with torch.no_grad():
        right = ((head(xv[None])[0, :, 0] > 0).float() == yv).float()
    return AxisHeadFit(losses, float(right.mean()), float((right * wv).sum()))


def axis_head_payload(
    payload: dict[str, Any], scans: Path, data: CloudDataConfig, epochs: int, seed: int
) -> tuple[dict[str, Any], AxisHeadFit]:
    """A saved votes segmenter (`models.save_segmenter`'s dict) with an axis head fitted
    onto it (`with_axis_head`, its initial weights drawn after `torch.manual_seed(seed)`;
    `fit_axis_head` on the clouds `data` selects of the training objects of the scan folder
    `scans`, split into training and validation as `train-segmenter` splits them), saved
    with `inference.axis_split` on; every other weight and setting as it was. InputError
    for a masks-head model or scans of another category."""
    from artic.artifacts.scan_dataset import ScanDataset
    from artic.hierarchy.cloud_cache import segmenter_cache_dir
    from artic.hierarchy.models import segmentation_config_from_dict, segmentation_config_to_dict

    config = segmentation_config_from_dict(payload["hparams"]["segmentation"])
    if config.head != "votes":
        raise InputError("axis head: only the votes head (model.head=votes) has one")
    state = payload["state_dict"]
    model = PartSegmentationNet(config)
    model.load_state_dict({k: v.float() for k, v in state.items()})
    ds = ScanDataset.open_category(scans, str(payload["category"]))
    split = training_objects(ds, data)
    n_points = int(payload["hparams"]["inference"]["n_points"])
    clouds = [
        load_clouds(ds, objects, data, n_points, config.n_masks, seed)[0].with_features(
            config, segmenter_cache_dir(scans)
        )
        for objects in (split.train, split.val)
    ]
    torch.manual_seed(seed)
    grown = with_axis_head(model)
    fit = fit_axis_head(grown, clouds[0], clouds[1], epochs, seed)
    dtype = next(iter(state.values())).dtype
    hparams = {
        **payload["hparams"],
        "segmentation": segmentation_config_to_dict(grown.config),
        "inference": {**payload["hparams"]["inference"], "axis_split": True},
    }
    new_state = {  # the head's weights stored as the model's, its step counters as ints
        k: state[k] if k in state else v.detach().cpu().to(dtype) if v.is_floating_point() else v
        for k, v in grown.state_dict().items()
    }
    return {**payload, "hparams": hparams, "state_dict": new_state}, fit


def score_segmenter(
    model: PartSegmentationNet,
    data: SegmentationData,
    inference: InferenceConfig,
    outputs: Sequence[SegmentationOutput | VoteOutput] | None = None,
) -> SegmentationScores:
    """Run `segment` on every prepared cloud (already at the network's input size, so no
    further downsampling; with its cached normals and neighbourhoods when `data` has them,
    or from the network's `outputs` on them) and score it against the ground truth
    (PartNet protocol)."""
    detections: dict[bool, list[Any]] = {False: [], True: []}
    accuracy = []
    for i in range(len(data)):
        normals = None if data.normals is None else data.normals[i]
        index = None if data.neighbourhoods is None else data.neighbourhoods[i]
        output = None if outputs is None else outputs[i]
        result = segment(model, data.points[i], inference, normals, index, output)
        detections[bool(data.noisy[i])].append(
            object_detections(result.part_id, result.part_confidence, data.part_id[i])
        )
        accuracy.append(motion_type_accuracy(result.motion_type, data.motion_type[i]))

    def m_ap(kind: bool) -> float:
        return mean_average_precision(detections[kind]) if detections[kind] else math.nan

    mean_accuracy = float(np.mean(accuracy)) if accuracy else math.nan
    return SegmentationScores(m_ap(False), m_ap(True), mean_accuracy, len(data))


def choose_cluster_radius(
    model: PartSegmentationNet,
    data: SegmentationData,
    inference: InferenceConfig,
    radii: tuple[float, ...],
    bandwidths: tuple[float, ...] = (),
) -> tuple[InferenceConfig, dict[str, float]]:
    """Votes head: the `inference` whose per-motion-type cluster_radius (and mode_bandwidth)
    scores the best mean of clean and noisy mAP@0.5 on `data`. For each bandwidth of
    `bandwidths` (none given: inference.mode_bandwidth): first one radius of `radii` for
    every type, then each type's radius in turn with the others kept (coordinate search;
    ties: the smaller radius); the best bandwidth's (ties: the first). Returns it and every
    tried setting's score, keyed by its radii (and "h=<bandwidth>" where bandwidths were
    given). Masks head or no radii: `inference` unchanged, no scores. The network runs once
    per cloud."""
    if model.config.head != "votes" or not radii:
        return inference, {}
    from artic.progress import progress

    outputs = network_outputs(model, data, inference.mirror_y)
    one_part = model.config.one_part
    types = [t for t in range(4) if t not in one_part]
    scores: dict[str, float] = {}
    moved: list[SegmentationOutput | VoteOutput] = []
    # the candidates the search looks at (each once per bandwidth, scored ones included)
    looks = len(bandwidths or (0,)) * (len(radii) + len(types) * (1 + len(radii)) + 1)
    chosen: list[tuple[float, tuple[float, ...], float]] = []
    with progress("train-segmenter: cluster radius", looks, "settings") as advance:

        def score(setting: tuple[float, ...], h: float) -> float:
            advance(1)
            key = ",".join(f"{r:g}" for r in setting) + (f";h={h:g}" if bandwidths else "")
            if key not in scores:
                # the points were moved to their modes once for all radii (`votes.sought`)
                update = {"cluster_radius": setting, "mode_bandwidth": 0.0}
                s = score_segmenter(model, data, inference.model_copy(update=update), moved)
                scores[key] = float(np.nanmean([s.map_clean, s.map_noisy]))
            return scores[key]

        for h in bandwidths or (inference.mode_bandwidth,):
            moved[:] = [
                sought(o, h, one_part, inference.moving_together)
                if isinstance(o, VoteOutput)
                else o
                for o in outputs
            ]
            best: tuple[float, ...] = max(((r,) * 4 for r in radii), key=lambda s: score(s, h))
            for t in types:
                candidates = [best, *((*best[:t], r, *best[t + 1 :]) for r in radii)]
                best = max(candidates, key=lambda s, t=t: (score(s, h), -s[t]))  # type: ignore[misc]
            chosen.append((score(best, h), best, h))
    value, radius, bandwidth = max(chosen, key=lambda c: c[0])
    log.info("train-segmenter: cluster radius %s, bandwidth %g (validation mAP %.4f)",
             ",".join(f"{r:g}" for r in radius), bandwidth, value)  # fmt: skip
    update = {"cluster_radius": radius, "mode_bandwidth": bandwidth}
    return inference.model_copy(update=update), scores


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
    clouds, ids, noisy, axes, skipped = [], [], [], [], 0
    trees: dict[int, KinematicTree] = {}
    for row in rows:
        cloud = ds.cloud(row)
        assert cloud.part_id is not None and cloud.motion_type is not None
        if len(np.unique(cloud.part_id[cloud.part_id >= 0])) > n_masks:
            skipped += 1
            continue
        rng = np.random.default_rng([seed, row.object_id, row.pose, row.kind == "noisy"])
        prepared = prepare_cloud(cloud.points, cloud.part_id, cloud.motion_type, n_points, rng)
        clouds.append(prepared)
        if row.object_id not in trees:
            trees[row.object_id] = ds.tree(row.object_id)
        axes.append(axis_targets(prepared.part_id, trees[row.object_id]))
        ids.append(row.object_id)
        noisy.append(row.kind == "noisy")
    if not clouds:
        raise InputError(f"scans: {ds.root} has no usable clouds of objects {objects[:5]}...")
    return SegmentationData.stack(clouds, ids, noisy, axes), skipped


class ValidationScan(NamedTuple):
    """A whole scan as `artic evaluate hierarchy` scores it: its labelled points (N, 3)
    float32 metres, their true parts (N,) 0..P-1 and whether it is a noisy scan."""

    points: NDArray[np.float32]
    part_id: NDArray[np.int64]
    noisy: bool


def validation_scans(
    ds: ScanDataset, objects: Sequence[int], kinds: Sequence[str], max_poses: int | None
) -> list[ValidationScan]:
    """The training split's scans of `objects` (the `kinds`, poses below `max_poses`) at full
    resolution, for `choose_inference`; InputError when there are none."""
    rows = ds.select("train", tuple(kinds), list(objects))
    scans = []
    for row in rows:
        if max_poses is not None and row.pose >= max_poses:
            continue
        cloud = ds.cloud(row)
        assert cloud.part_id is not None
        labelled = cloud.part_id >= 0
        if not labelled.any():
            continue
        part = cloud.part_id[labelled]
        part_id = np.searchsorted(np.unique(part), part).astype(np.int64)
        points = np.asarray(cloud.points[labelled], dtype=np.float32)
        scans.append(ValidationScan(points, part_id, row.kind == "noisy"))
    if not scans:
        raise InputError(f"scans: {ds.root} has no scans of objects {list(objects)[:5]}...")
    return scans


@dataclass(frozen=True)
class InferenceSearch:
    """Candidates `choose_inference` tries for each setting (empty: the setting is kept)."""

    passes: tuple[int, ...] = ()
    min_points: tuple[int, ...] = ()
    cluster_radii: tuple[float, ...] = ()
    mode_bandwidths: tuple[float, ...] = ()
    moving_together: tuple[bool, ...] = ()
    modes_per_pass: tuple[bool, ...] = ()


def choose_inference(
    model: PartSegmentationNet,
    scans: Sequence[ValidationScan],
    inference: InferenceConfig,
    search: InferenceSearch,
) -> tuple[InferenceConfig, dict[str, float]]:
    """Votes head: `inference` with the passes, minimum part size, per-motion-type radii and
    mode-seeking bandwidth (and where the votes seek their modes, `modes_per_pass`) that
    score the best mean of clean and noisy mAP@0.5 on whole
    `scans`, every point labelled as `segment` labels it (the figure `evaluate hierarchy`
    reports; `choose_cluster_radius` scores the network's samples instead, where a part of
    a few points still counts whole). A coordinate search from `inference`: whether the
    moving types' votes are clustered together, passes, whether each pass's votes seek
    their modes among their own, then min_points, then each type's
    radius (not for a type that is one part), then the bandwidth, each candidate with the
    others kept; ties keep the current value. The network runs once per scan, on as many
    samples as the most passes tried. Returns the chosen settings and every tried
    setting's score, keyed by its values."""
    from artic.hierarchy.segmentation import (
        merged_passes,
        modes_of_passes,
        network_passes,
        parts_of_passes,
    )
    from artic.progress import progress

    if model.config.head != "votes":
        return inference, {}
    most = max((*search.passes, inference.passes))
    runs = []
    with progress("choose inference: network", len(scans), "scans") as advance:
        for scan in scans:
            settings = inference.model_copy(update={"passes": most})
            runs.append(network_passes(model, scan.points, settings))
            advance(1)
    scores: dict[str, float] = {}

    def key(s: InferenceConfig) -> str:
        radius = ",".join(f"{r:g}" for r in s.cluster_radius)
        together = ";moving_together" if s.moving_together else ""
        per_pass = ";modes_per_pass" if s.modes_per_pass else ""
        return (
            f"passes={s.passes};min_points={s.min_points};radius={radius};"
            f"h={s.mode_bandwidth:g}{together}{per_pass}"
        )

    one_part = model.config.one_part
    moved: dict[tuple[int, float, bool, bool], list[VoteOutput]] = {}

    def votes(s: InferenceConfig) -> list[VoteOutput]:
        """Every scan's first `passes` outputs merged and moved to their modes (each pass's
        among its own with `modes_per_pass`, as `parts_of_passes`), once for all the
        settings that share them (`votes.sought`)."""
        shared = (s.passes, s.mode_bandwidth, s.moving_together, s.modes_per_pass)
        if shared not in moved:
            merged = []
            for scan, (samples, outputs) in zip(scans, runs, strict=True):
                n = len(samples[: s.passes])
                moved_passes, h = modes_of_passes(model.config, outputs[:n], s)
                out = merged_passes(model.config, scan.points, samples[:n], moved_passes)
                merged.append(sought(out, h, one_part, s.moving_together))
            moved.clear()  # one of these at a time: the search changes one setting
            moved[shared] = merged
        return moved[shared]

    def score(s: InferenceConfig) -> float:
        k = key(s)
        if k not in scores:
            detections: dict[bool, list[Any]] = {False: [], True: []}
            flat = s.model_copy(update={"mode_bandwidth": 0.0})
            shifted = votes(s)
            for scan, (samples, _), out in zip(scans, runs, shifted, strict=True):
                n = len(samples[: s.passes])
                result = parts_of_passes(model.config, scan.points, samples[:n], [out], flat)
                detections[scan.noisy].append(
                    object_detections(result.part_id, result.part_confidence, scan.part_id)
                )
            maps = [mean_average_precision(d) for d in detections.values() if d]
            scores[k] = float(np.mean(maps))
        return scores[k]

    steps: list[tuple[str, Sequence[Any]]] = [
        ("moving_together", search.moving_together),
        ("passes", search.passes),
        ("modes_per_pass", search.modes_per_pass),
        ("min_points", search.min_points),
        *((f"radius{t}", search.cluster_radii) for t in range(4) if t not in one_part),
        ("mode_bandwidth", search.mode_bandwidths),
    ]
    best = inference
    for name, candidates in steps:
        log.info("choose inference: %s (best so far %s)", name, key(best))
        tried = [best]
        for value in candidates:
            if name.startswith("radius"):
                t = int(name[len("radius") :])
                radius = (*best.cluster_radius[:t], value, *best.cluster_radius[t + 1 :])
                tried.append(best.model_copy(update={"cluster_radius": radius}))
            else:
                tried.append(best.model_copy(update={name: value}))
        best = max(tried, key=score)  # the first of equals: the current one
    log.info("choose inference: %s (mAP %.4f)", key(best), score(best))
    return best, scores


def head_description(model: SegmenterModelConfig, info: dict[str, Any]) -> str:
    """The model card's words for a trained segmenter's head (`info`: its model.json)."""
    if model.head == "masks":
        return f"{model.n_masks} masks + confidence (the thesis' head)"
    network = info["network"]
    return (
        "per-point offsets to the part centre, parts by clustering (votes head, radii "
        f"{info['inference']['cluster_radius']} per motion type, chosen on validation clouds)"
        + (", every static point one part" if network.get("static_part") == "one" else "")
        + (", offsets learnt part by part" if network.get("offset_weight") == "parts" else "")
        + (
            ", an axis head (does the point's part move about a vertical axis?), parts cut "
            "where it reads two"
            if network.get("axis_head") and info["inference"].get("axis_split")
            else ""
        )
        + (
            ", the moving types' votes clustered together"
            if info["inference"].get("moving_together")
            else ""
        )
    )


def select_on_whole_scans(
    model: PartSegmentationNet,
    ds: ScanDataset,
    objects: Sequence[int],
    kinds: Sequence[str],
    train: SegmenterTrainConfig,
    inference: InferenceConfig,
) -> tuple[InferenceConfig, dict[str, float]]:
    """train-segmenter's `choose_inference` on the whole scans (`kinds`, `train.select_poses`
    poses) of its validation `objects`, with the candidates of `train.select_passes`,
    `select_min_points`, `select_moving_together`, `cluster_radii` and `mode_bandwidths`;
    `inference` unchanged and no scores when the three select lists are empty or the head
    is the masks head."""
    selected = train.select_passes or train.select_min_points or train.select_moving_together
    if model.config.head != "votes" or not selected:
        return inference, {}
    search = InferenceSearch(
        train.select_passes,
        train.select_min_points,
        train.cluster_radii,
        train.mode_bandwidths,
        train.select_moving_together,
    )
    scans = validation_scans(ds, objects, kinds, train.select_poses)
    return choose_inference(model, scans, inference, search)
