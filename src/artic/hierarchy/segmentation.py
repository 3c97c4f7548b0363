"""Part segmentation network of section 4.3 (after PartNet's instance segmenter, Mo et al. 2019).

A PointNet++ backbone gives per-point features. Two per-point branches follow:
- the instance branch predicts N = 24 part masks plus one "other" mask as a softmax over
  N + 1 slots per point (PartNet's choice: every point belongs to exactly one slot, so
  masks are disjoint; "other" takes points of no part, part_id -1 in the ground truth),
  with one confidence per mask regressed from the global feature;
- the motion branch replaces PartNet's semantic branch with the thesis' four motion types
  (static, rotating, translating, both).

Loss (`segmentation_loss`): Hungarian matching of predicted to ground-truth masks on the
relaxed (soft) IoU, 1 - IoU of matched pairs, confidence regressed to the matched IoU (0 for
unmatched masks), 1 - IoU of the "other" mask where the cloud has unlabelled points, and
cross-entropy on motion types. Trained with Adam, learning rate 1e-4 (section 4.3).

Inference (`segment`): one cloud (N, 3) -> one part label per input point. The network
sees at most `n_points` points chosen by farthest-point sampling; labels go back to every
input point from its nearest sampled point.

`head="votes"` replaces the instance branch and its confidences by a per-point offset to
the part's centre; parts are then clusters of the shifted points (`artic.hierarchy.votes`,
the design of PointGroup and GAMMA), which trains to a useful segmenter on a CPU.
`normals=True` feeds per-point normals (`artic.hierarchy.normals`) to the backbone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Literal, NamedTuple, cast

import numpy as np
import torch
import torch.nn.functional as F
from numpy.typing import NDArray
from scipy.spatial import cKDTree
from torch import Tensor, nn

from artic.errors import InputError
from artic.hierarchy.config import InferenceConfig
from artic.hierarchy.pointnet2 import (
    BackboneIndex,
    PointNet2,
    PointNet2Config,
    SharedMLP,
    farthest_point_indices,
)
from artic.hierarchy.votes import (
    STATIC,
    VoteLosses,
    VoteOutput,
    merge_passes,
    sought,
    vote_loss,
    vote_parts,
)
from artic.objects.tree import MOTION_TYPES

N_MASKS = 24
#: the mirror image y -> -y (`forward`'s mirror_y)
MIRROR_Y = (1.0, -1.0, 1.0)
Head = Literal["masks", "votes"]
StaticPart = Literal["votes", "one"]
OffsetWeight = Literal["points", "parts"]


@dataclass(frozen=True)
class SegmentationConfig:
    """Architecture of the section 4.3 segmenter."""

    n_masks: int = N_MASKS  # N, instance masks (besides "other")
    backbone: PointNet2Config = field(default_factory=PointNet2Config)
    head_width: int = 256  # hidden width of the instance branch (motion branch: half)
    confidence_width: int = 256  # hidden width of the confidence MLP
    normalize: bool = True  # centre each cloud on its mean and scale it into the unit sphere
    head: Head = "masks"  # masks: section 4.3's N masks + confidences; votes: offsets
    normals: bool = False  # per-point normals as input features (backbone.in_channels 3)
    static_part: StaticPart = "votes"  # votes head: "one": every static point is one part
    # votes head's offset loss: every labelled point weighs the same ("points", PointGroup)
    # or every part of a cloud does ("parts": a part's points share its weight)
    offset_weight: OffsetWeight = "points"
    # votes head: per point, whether its part moves about a vertical axis (`votes.axis_targets`)
    axis_head: bool = False

    @property
    def one_part(self) -> tuple[int, ...]:
        """The motion types whose points are all one part at inference (votes head):
        the static type with `static_part` "one", else none."""
        return (STATIC,) if self.static_part == "one" else ()

    def scaled(self, factor: float) -> SegmentationConfig:
        """Every width times `factor` (for tests and small machines)."""
        return replace(
            self,
            backbone=self.backbone.scaled(factor),
            head_width=max(4, round(self.head_width * factor)),
            confidence_width=max(4, round(self.confidence_width * factor)),
        )


class SegmentationOutput(NamedTuple):
    mask_logits: Tensor  # (B, N, M + 1): M part masks, then "other"; softmax over the last axis
    confidence: Tensor  # (B, M) in (0, 1), predicted IoU of each mask with its part
    motion_logits: Tensor  # (B, N, 4) over MOTION_TYPES


def normalize_points(xyz: Tensor) -> Tensor:
    """Centre each cloud on its mean and scale its farthest point to radius 1.

    xyz: (B, N, 3) -> (B, N, 3), unitless.
    """
    centred = xyz - xyz.mean(dim=1, keepdim=True)
    radius = centred.norm(dim=-1).amax(dim=1).clamp_min(1e-9)
    return centred / radius[:, None, None]


class PartSegmentationNet(nn.Module):
    """points (B, N, 3), metres [+ normals (B, N, 3)] -> SegmentationOutput (section 4.3's
    masks head) or VoteOutput (the votes head)."""

    def __init__(self, config: SegmentationConfig | None = None) -> None:
        super().__init__()
        config = config or SegmentationConfig()
        if config.normals != (config.backbone.in_channels == 3):
            raise ValueError("SegmentationConfig: normals needs backbone.in_channels == 3")
        self.config = config
        self.backbone = PointNet2(config.backbone)
        c, g, h = self.backbone.out_channels, self.backbone.global_channels, config.head_width
        norm = config.backbone.norm
        if config.head == "masks":
            self.instance = nn.Sequential(
                SharedMLP(c, (h, h), norm), nn.Linear(h, config.n_masks + 1)
            )
        self.motion = nn.Sequential(
            SharedMLP(c, (h // 2,), norm), nn.Linear(h // 2, len(MOTION_TYPES))
        )
        if config.head == "votes":
            self.offset = nn.Sequential(SharedMLP(c, (h // 2,), norm), nn.Linear(h // 2, 3))
            if config.axis_head:
                self.axis = nn.Sequential(SharedMLP(c, (h // 2,), norm), nn.Linear(h // 2, 1))
            return
        # no BatchNorm here: the global feature has one row per cloud (batches of one train)
        w = config.confidence_width
        self.confidence = nn.Sequential(
            nn.Linear(g, w), nn.ReLU(), nn.Linear(w, w), nn.ReLU(), nn.Linear(w, config.n_masks)
        )

    def forward(
        self, points: Tensor, normals: Tensor | None = None, index: BackboneIndex | None = None
    ) -> SegmentationOutput | VoteOutput:
        """`index`: the backbone's neighbourhoods of these clouds (`pointnet2.backbone_index`
        of the normalised clouds), computed here when None."""
        xyz = normalize_points(points) if self.config.normalize else points
        if self.config.normals and normals is None:
            raise ValueError("this segmenter reads normals: pass normals (B, N, 3)")
        features = self.backbone(xyz, normals if self.config.normals else None, index=index)
        motion = self.motion(features.point_features)
        if self.config.head == "votes":
            axis = self.axis(features.point_features)[..., 0] if self.config.axis_head else None
            return VoteOutput(motion, self.offset(features.point_features), xyz, axis)
        return SegmentationOutput(
            self.instance(features.point_features),
            torch.sigmoid(self.confidence(features.global_features)),
            motion,
        )


def relaxed_iou(mask_prob: Tensor, part_mask: Tensor) -> Tensor:
    """Soft IoU of every predicted mask with every ground-truth part (PartNet's relaxed IoU).

    mask_prob: (N, M) in [0, 1]; part_mask: (N, P) in {0, 1} -> (M, P):
    sum(p g) / (sum(p) + sum(g) - sum(p g)).
    """
    inter = mask_prob.transpose(0, 1) @ part_mask
    union = mask_prob.sum(0)[:, None] + part_mask.sum(0)[None, :] - inter
    return inter / union.clamp_min(1e-8)


class SegmentationLosses(NamedTuple):
    total: Tensor  # weighted sum, differentiable
    mask: Tensor  # mean over parts of 1 - IoU of the matched mask
    other: Tensor  # 1 - IoU of the "other" mask with the unlabelled points (0 if none)
    confidence: Tensor  # squared error to the matched IoU (0 for unmatched masks), mean over
    # matched plus mean over unmatched masks (PartNet's balancing)
    motion: Tensor  # cross-entropy of the motion types
    matched_iou: Tensor  # mean soft IoU of matched pairs (no gradient)


@dataclass(frozen=True)
class LossWeights:
    mask: float = 1.0
    other: float = 1.0
    confidence: float = 1.0
    motion: float = 1.0


def segmentation_loss(
    output: SegmentationOutput,
    part_id: Tensor,
    motion_type: Tensor,
    weights: LossWeights | None = None,
) -> SegmentationLosses:
    """Hungarian-matched instance loss + confidence + motion-type loss, mean over the batch.

    part_id: (B, N) int64, any non-negative ids (at most M distinct per cloud), -1 for
    points of no part; motion_type: (B, N) int64 in 0..3, -1 to ignore.
    """
    from scipy.optimize import linear_sum_assignment  # training only: inference never loads it

    weights = weights or LossWeights()
    m = output.confidence.shape[1]
    probs = output.mask_logits.softmax(dim=-1)
    zero = probs.new_zeros(())
    mask_l, other_l, conf_l, ious = [], [], [], []
    for b in range(probs.shape[0]):
        labels = part_id[b]
        valid = labels >= 0
        ids, inverse = torch.unique(labels[valid], return_inverse=True)
        if len(ids) > m:
            raise InputError(f"part_id: at most {m} parts per cloud, got {len(ids)}")
        gt = probs.new_zeros(labels.shape[0], len(ids))
        gt[valid] = F.one_hot(inverse, len(ids)).to(probs.dtype)
        iou = relaxed_iou(probs[b, :, :m], gt)  # (M, P)
        rows, cols = linear_sum_assignment(iou.detach().cpu().numpy(), maximize=True)
        rows_t = torch.as_tensor(rows, device=iou.device)
        matched = iou[rows_t, torch.as_tensor(cols, device=iou.device)]
        mask_l.append((1.0 - matched).mean() if len(ids) else zero)
        ious.append(matched.detach().mean() if len(ids) else zero + 1.0)
        target = torch.zeros_like(output.confidence[b])
        target[rows_t] = matched.detach()
        is_matched = torch.zeros(m, dtype=torch.bool, device=iou.device)
        is_matched[rows_t] = True
        err = (output.confidence[b] - target).square()
        conf = err[is_matched].mean() if is_matched.any() else zero
        conf_l.append(conf + (err[~is_matched].mean() if (~is_matched).any() else zero))
        if (~valid).any():
            other = relaxed_iou(probs[b, :, m:], (~valid).to(probs.dtype)[:, None])[0, 0]
            other_l.append(1.0 - other)
        else:
            other_l.append(zero)
    motion = (
        F.cross_entropy(
            output.motion_logits.reshape(-1, len(MOTION_TYPES)),
            motion_type.reshape(-1),
            ignore_index=-1,
        )
        if (motion_type >= 0).any()
        else zero
    )
    mask_loss, other_loss = torch.stack(mask_l).mean(), torch.stack(other_l).mean()
    conf_loss = torch.stack(conf_l).mean()
    total = (
        weights.mask * mask_loss
        + weights.other * other_loss
        + weights.confidence * conf_loss
        + weights.motion * motion
    )
    return SegmentationLosses(
        total, mask_loss, other_loss, conf_loss, motion, torch.stack(ious).mean()
    )


class SegmentationBatch(NamedTuple):
    points: Tensor  # (B, N, 3) float32, metres
    part_id: Tensor  # (B, N) int64, -1 for points of no part
    motion_type: Tensor  # (B, N) int64 in 0..3, -1 to ignore
    normals: Tensor | None = None  # (B, N, 3) float32 unit normals, for `normals=True` nets
    neighbourhoods: BackboneIndex | None = None  # precomputed, `cloud_cache`
    axis_vertical: Tensor | None = None  # (B, N) int64 `votes.axis_targets`, -1 to ignore


class StepLosses(NamedTuple):
    """The loss of one batch under either head, and its terms as floats."""

    total: Tensor  # differentiable
    terms: dict[str, float]  # the head's loss terms and its quality measure (QUALITY)


#: per head, the loss term that measures its quality during training (metrics.csv)
QUALITY: dict[str, str] = {"masks": "matched_iou", "votes": "offset_error"}


def head_loss(
    output: SegmentationOutput | VoteOutput,
    part_id: Tensor,
    motion_type: Tensor,
    weights: LossWeights | None = None,
    vote_static: bool = True,
    per_part: bool = False,
    axis_vertical: Tensor | None = None,
) -> StepLosses:
    """`segmentation_loss` (masks head; `weights`) or `votes.vote_loss` (votes head;
    `vote_static` False: no offset loss on static points, `static_part` "one"; `per_part`:
    every part weighs the same in the offset loss, `offset_weight` "parts"; `axis_vertical`:
    the axis head's targets)."""
    losses: SegmentationLosses | VoteLosses
    if isinstance(output, VoteOutput):
        losses = vote_loss(output, part_id, motion_type, vote_static, per_part, axis_vertical)
    else:
        losses = segmentation_loss(output, part_id, motion_type, weights)
    terms = {k: float(v.detach()) for k, v in losses._asdict().items()}
    valid = motion_type >= 0
    right = output.motion_logits.detach().argmax(-1) == motion_type
    terms["motion_accuracy"] = float(right[valid].float().mean()) if valid.any() else 1.0
    return StepLosses(losses.total, terms)


def make_optimizer(model: nn.Module, lr: float = 1e-4) -> torch.optim.Adam:
    """Adam with the thesis' learning rate 1e-4 (section 4.3)."""
    return torch.optim.Adam(model.parameters(), lr=lr)


def run_batch(
    model: PartSegmentationNet, batch: SegmentationBatch, weights: LossWeights | None = None
) -> StepLosses:
    """The model's loss on `batch` (moved to the model's device), in its current mode."""
    device = next(model.parameters()).device
    normals = None if batch.normals is None else batch.normals.to(device)
    index = None if batch.neighbourhoods is None else batch.neighbourhoods.to(device)
    output = model(batch.points.to(device), normals, index)
    vote_static = model.config.static_part == "votes"
    per_part = model.config.offset_weight == "parts"
    axis = None if batch.axis_vertical is None else batch.axis_vertical.to(device)
    return head_loss(
        output, batch.part_id.to(device), batch.motion_type.to(device), weights, vote_static,
        per_part, axis,
    )  # fmt: skip


def train_step(
    model: PartSegmentationNet,
    optimizer: torch.optim.Optimizer,
    batch: SegmentationBatch,
    weights: LossWeights | None = None,
) -> dict[str, float]:
    """One optimisation step on `batch` -> its loss terms ("total" and the head's)."""
    model.train()
    optimizer.zero_grad(set_to_none=True)
    losses = run_batch(model, batch, weights)
    losses.total.backward()
    optimizer.step()
    return losses.terms


class SegmentationResult(NamedTuple):
    part_id: NDArray[np.int64]  # (N,) in 0..P-1, parts ordered by decreasing size
    motion_type: NDArray[np.int64]  # (N,) index into MOTION_TYPES
    motion_prob: NDArray[np.float32]  # (N, 4) softmax over MOTION_TYPES
    part_confidence: NDArray[np.float32]  # (P,) the mAP ranking score of each part


def segment(
    model: PartSegmentationNet,
    points: NDArray[np.floating],
    config: InferenceConfig | None = None,
    normals: NDArray[np.float32] | None = None,
    neighbourhoods: BackboneIndex | None = None,
    output: SegmentationOutput | VoteOutput | None = None,
) -> SegmentationResult:
    """Segment one cloud into parts with motion types: points (N, 3), metres.

    normals (N, 3) and neighbourhoods (`cloud_cache.cloud_features`): a cloud already at
    the network's input size (a prepared training cloud) whose features were computed
    once; without them they are computed here. ValueError for a cloud larger than
    `n_points` (its samples would not be the points those features belong to). output: the
    network's output on such a cloud, computed before (`forward`), to try other settings.

    1. Downsample to `n_points` by farthest-point sampling (deterministic, from point 0);
       with `passes` > 1 (votes head), up to that many disjoint such samples, each from the
       points the ones before left (`sample_passes`).
    2. Run the network on each sample (with the sample's normals if it reads them).
    3. Masks head: every sampled point takes its most probable slot; masks that are
       "other", smaller than max(min_points, min_fraction * S) or less confident than
       `min_confidence` are dropped; their points move to their most probable kept mask
       (the largest mask is always kept). Votes head: clusters of the shifted points of all
       samples together, in the first one's frame (`votes.merge_passes`), within
       `cluster_radius`, the same minimum size per sample (`votes.cluster_votes`); with
       `static_part` "one" the static points are one part; with `moving_together` the
       votes of every moving type are clustered as one set.
    4. Every input point takes the labels of its nearest sampled point (cKDTree).

    Train on clouds prepared the same way (`farthest_point_indices(scan, n_points)`).
    Step 4 cannot separate parts closer than the sample spacing: on the three-box test
    object (gaps of 2.5-3 cm, 2.15 m^2 of surface) nearest-sample upsampling of the TRUE
    labels of 512 FPS samples reaches part IoU 0.74-0.87, of 2,048 samples 1.0; on
    storage furniture's clean clouds (10,000 surface points) 1,024 samples give a median
    moving-part IoU of 0.86, 2,048 0.90 (docs/hierarchy.md, "Passes"). Several passes
    put more of the network's own predictions on the parts' boundaries.
    """
    config = config or InferenceConfig()
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise InputError(f"points: expected a non-empty (N, 3) array, got shape {pts.shape}")
    if not np.isfinite(pts).all():
        raise InputError("points: NaN or infinite coordinates")
    pts = pts.astype(np.float32)
    samples, outputs = network_passes(model, pts, config, normals, neighbourhoods, output)
    return parts_of_passes(model.config, pts, samples, outputs, config)


def network_passes(
    model: PartSegmentationNet,
    points: NDArray[np.float32],
    config: InferenceConfig,
    normals: NDArray[np.float32] | None = None,
    neighbourhoods: BackboneIndex | None = None,
    output: SegmentationOutput | VoteOutput | None = None,
) -> tuple[list[NDArray[np.int64]], list[SegmentationOutput | VoteOutput]]:
    """Steps 1-2 of `segment` on a checked cloud (N, 3) float32: its samples
    (`sample_passes`) and the network's output on each. The first K of a run with
    `passes` = P > K are those of a run with K (`choose_inference` relies on it)."""
    samples = sample_passes(points, config.n_points, config.passes)
    precomputed = (normals, neighbourhoods, output)
    if len(samples[0]) < len(points) and any(x is not None for x in precomputed):
        raise ValueError("precomputed features need a cloud of at most n_points points")
    if len(samples) > 1 and model.config.head != "votes":
        raise InputError("inference.passes: only the votes head (model.head=votes) has it")
    device = next(model.parameters()).device
    index = None if neighbourhoods is None else neighbourhoods.to(device)
    outputs = [output] if output is not None else []
    for sample in samples[len(outputs) :]:
        sample_normals: NDArray[np.float32] | None
        if model.config.normals and normals is None:
            from artic.hierarchy.normals import estimate_normals

            sample_normals = estimate_normals(points[sample])
        else:
            sample_normals = normals
        normals_t = (
            None if sample_normals is None else torch.from_numpy(sample_normals).to(device)[None]
        )
        outputs.append(forward(model, points[sample], normals_t, index, config.mirror_y))
    return samples, outputs


def parts_of_passes(
    network: SegmentationConfig,
    points: NDArray[np.float32],
    samples: Sequence[NDArray[np.int64]],
    outputs: Sequence[SegmentationOutput | VoteOutput],
    config: InferenceConfig,
) -> SegmentationResult:
    """Steps 3-4 of `segment`: the parts of every point of `points` from the network's
    outputs on its `samples` (`network_passes`), with `config`'s clustering settings (its
    `passes` is not read: every sample given is used). outputs: one per sample, or one
    for all of them, already merged (`votes.merge_passes`). With `modes_per_pass`, each
    sample's votes are moved to their modes among that sample's own (`votes.sought`) before
    the merge, and not again after it."""
    outputs, bandwidth = modes_of_passes(network, outputs, config)
    out = outputs[0] if len(outputs) == 1 else merged_passes(network, points, samples, outputs)
    sample = np.concatenate(samples)
    min_size = len(samples) * max(
        config.min_points, int(np.ceil(config.min_fraction * len(samples[0])))
    )
    if isinstance(out, VoteOutput):
        clusters, motion_prob = vote_parts(
            out,
            config.cluster_radius,
            min_size,
            network.one_part,
            bandwidth,
            config.moving_together,
            len(samples) * config.min_points if config.axis_split else None,
            config.axis_share,
            config.axis_smooth,
        )
        label, confidence = clusters.label, clusters.confidence
    else:
        mask_prob = out.mask_logits[0].softmax(-1).cpu().numpy()  # (S, M + 1)
        motion_prob = out.motion_logits[0].softmax(-1).cpu().numpy().astype(np.float32)
        merged = merge_masks(mask_prob, out.confidence[0].cpu().numpy(), config)
        label, confidence = merged.label, out.confidence[0].cpu().numpy()[merged.mask]
    nearest = nearest_sample(points[sample], points)
    used, part_id = np.unique(label[nearest], return_inverse=True)  # drop emptied parts
    return SegmentationResult(
        part_id.astype(np.int64),
        motion_prob.argmax(-1)[nearest].astype(np.int64),
        motion_prob[nearest],
        confidence[used].astype(np.float32),
    )


def merged_passes(
    network: SegmentationConfig,
    points: NDArray[np.float32],
    samples: Sequence[NDArray[np.int64]],
    outputs: Sequence[SegmentationOutput | VoteOutput],
) -> VoteOutput:
    """The votes head's outputs on `samples` of `points` as one, in the first sample's
    frame (`votes.merge_passes`); `network_passes` refuses passes to the masks head."""
    frames = [normalization_frame(points[sample], network.normalize) for sample in samples]
    return merge_passes(cast(list[VoteOutput], list(outputs)), frames)


def modes_of_passes(
    network: SegmentationConfig,
    outputs: Sequence[SegmentationOutput | VoteOutput],
    config: InferenceConfig,
) -> tuple[Sequence[SegmentationOutput | VoteOutput], float]:
    """The outputs of several passes with each one's votes moved to their modes among its
    own (`votes.sought`) and 0, the bandwidth left for clustering them together, when
    `config.modes_per_pass` (votes head, more than one output); else `outputs` and
    `config.mode_bandwidth`."""
    if not (config.modes_per_pass and len(outputs) > 1):
        return outputs, config.mode_bandwidth
    moved = [sought(cast(VoteOutput, o), config.mode_bandwidth, network.one_part,
                    config.moving_together) for o in outputs]  # fmt: skip
    return moved, 0.0


def sample_passes(
    points: NDArray[np.float32], n_points: int, passes: int
) -> list[NDArray[np.int64]]:
    """The samples `segment` runs the network on: farthest-point samples of `n_points`, each
    from the points the ones before left (the first from point 0: the one-pass sample), as
    many of `passes` as the cloud has `n_points` points for; a cloud of at most `n_points`
    is its own one sample. points (N, 3) -> index arrays into points, disjoint."""
    if len(points) <= n_points:
        return [np.arange(len(points))]
    left = np.arange(len(points))
    samples: list[NDArray[np.int64]] = []
    while len(samples) < passes and len(left) >= n_points:
        sample = left[farthest_point_indices(points[left], n_points)]
        samples.append(sample)
        left = np.setdiff1d(left, sample, assume_unique=True)
    return samples


def normalization_frame(
    points: NDArray[np.floating], normalize: bool = True
) -> tuple[NDArray[np.float64], float]:
    """(centre, radius) with which `normalize_points` maps one cloud (N, 3): x -> (x -
    centre) / radius; the identity for a network that does not normalise."""
    if not normalize:
        return np.zeros(3), 1.0
    pts = np.asarray(points, dtype=np.float64)
    centre = pts.mean(axis=0)
    return centre, max(float(np.linalg.norm(pts - centre, axis=1).max()), 1e-9)


def forward(
    model: PartSegmentationNet,
    points: NDArray[np.floating],
    normals: Tensor | None = None,
    index: BackboneIndex | None = None,
    mirror_y: bool = False,
) -> SegmentationOutput | VoteOutput:
    """The network on one cloud (S, 3) at its input size, evaluation mode, no gradient;
    normals (1, S, 3) on the model's device when it reads them. mirror_y (votes head): the
    mean of its outputs on the cloud and on its mirror image y -> -y, the mirror's offsets
    mirrored back (test-time augmentation for a model trained with augment.mirror_y; the
    neighbourhoods `index` serve both, as mirroring keeps every distance)."""
    device = next(model.parameters()).device
    model.eval()
    with torch.no_grad():
        xyz = torch.from_numpy(np.asarray(points)).to(device)[None]
        out = model(xyz, normals, index)
        if not mirror_y:
            return out
        if not isinstance(out, VoteOutput):
            raise InputError("inference.mirror_y: only the votes head (model.head=votes) has it")
        flip = torch.tensor(MIRROR_Y, dtype=xyz.dtype, device=device)
        mirrored = model(xyz * flip, None if normals is None else normals * flip, index)
        assert isinstance(mirrored, VoteOutput)
        prob = (out.motion_logits.softmax(-1) + mirrored.motion_logits.softmax(-1)) / 2
        axis = None
        if out.axis_logits is not None and mirrored.axis_logits is not None:
            # a mirror image keeps an axis's vertical component: the probabilities averaged
            up = (torch.sigmoid(out.axis_logits) + torch.sigmoid(mirrored.axis_logits)) / 2
            axis = torch.logit(up)
        offsets = (out.offsets + mirrored.offsets * flip) / 2
        return VoteOutput(prob.log(), offsets, out.xyz, axis)


class MergedMasks(NamedTuple):
    label: NDArray[np.int64]  # (S,) part of each sampled point, 0..P-1
    mask: NDArray[np.int64]  # (P,) the network mask each part comes from


def merge_masks(
    mask_prob: NDArray[np.floating],
    confidence: NDArray[np.floating],
    config: InferenceConfig | None = None,
) -> MergedMasks:
    """Hard part labels from soft masks, small or unconfident masks merged away.

    mask_prob: (S, M + 1) softmax over M masks and "other"; confidence: (M,).
    Parts are the kept masks ordered by decreasing size (ties: mask order).
    """
    config = config or InferenceConfig()
    s, m = mask_prob.shape[0], mask_prob.shape[1] - 1
    count = np.bincount(mask_prob.argmax(-1), minlength=m + 1)[:m]
    keep = (count >= max(config.min_points, config.min_fraction * s)) & (
        confidence >= config.min_confidence
    )
    if not keep.any():
        keep[count.argmax()] = True
    candidates = np.flatnonzero(keep)
    best = candidates[mask_prob[:, candidates].argmax(-1)]  # (S,) mask index
    size = np.bincount(best, minlength=m)
    kept = candidates[np.argsort(-size[candidates], kind="stable")]
    kept = kept[size[kept] > 0]
    rank = np.full(m, -1, dtype=np.int64)
    rank[kept] = np.arange(len(kept))
    return MergedMasks(rank[best], kept.astype(np.int64))


def nearest_sample(
    sampled: NDArray[np.floating], points: NDArray[np.floating]
) -> NDArray[np.int64]:
    """Index of the nearest sampled point for every point: sampled (S, 3), points (N, 3)
    -> (N,) in 0..S-1; labels of the samples go to the points by `labels[index]`."""
    return np.asarray(cKDTree(sampled).query(points, k=1)[1], dtype=np.int64)
