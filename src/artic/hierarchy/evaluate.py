"""Tables 4.1 and 4.2 on one scan: the segmenter and the graph network run as `segment`
and `build-hierarchy` do (`infer`), scored against the scan's true parts and tree
(`artic.evaluation`). With `evaluate.yaw=random` the scan is first turned by a random yaw
and brought back by the estimated one (`canonical`), as a user's scan would be. Parts that
no point of the scan shows are left out of its ground truth (the tree is contracted over
them, as in training: `fit_labeller.restrict_tree`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from artic.artifacts.scan_dataset import KINDS
from artic.evaluation.hierarchy import hierarchy_counts, match_parts
from artic.evaluation.hierarchy_report import COUNTS
from artic.evaluation.segmentation import motion_type_accuracy, object_detections
from artic.hierarchy.canonical import YawConfig, canonical_yaw, rotate_z
from artic.hierarchy.config import HierarchyEvaluateConfig
from artic.hierarchy.fit_labeller import restrict_tree
from artic.hierarchy.gnn import Labeller
from artic.hierarchy.infer import MAX_POINTS, HierarchyConfig, build_hierarchy, segment_scan
from artic.hierarchy.models import LoadedLabeller, LoadedSegmenter, hierarchy_config
from artic.hierarchy.segmentation import PartSegmentationNet
from artic.objects.tree import KinematicTree

if TYPE_CHECKING:
    from artic.artifacts.scan_dataset import ScanDataset, ScanRow


def _turned_and_recovered(
    points: np.ndarray, rng: np.random.Generator, settings: YawConfig
) -> tuple[np.ndarray, dict[str, float]]:
    """`points` turned about z by an angle drawn from `rng`, then turned back by the yaw
    `canonical_yaw` estimates of the turned scan with `settings` (what infer-hierarchy
    --yaw canonical works on), and the angles (radians): turned, estimated, and the error
    wrapped to [-pi, pi)."""
    turned_by = float(rng.uniform(-np.pi, np.pi))
    turned = rotate_z(points, turned_by)
    estimate = canonical_yaw(turned, settings)
    error = (estimate.yaw - turned_by + np.pi) % (2 * np.pi) - np.pi
    record = {"yaw": turned_by, "yaw_estimate": estimate.yaw, "yaw_error": float(error)}
    return rotate_z(turned, -estimate.yaw).astype(np.float32), record


def evaluate_scan(
    points: np.ndarray,
    true_part: np.ndarray,
    true_motion: np.ndarray,
    tree: KinematicTree,
    segmenter: PartSegmentationNet,
    labeller: Labeller,
    cfg: HierarchyConfig,
    opts: HierarchyEvaluateConfig,
    rng: np.random.Generator,
) -> dict[str, Any] | None:
    """One scan's Table 4.1 detections and Table 4.2 counts (None: root not visible).
    points (N, 3) metres; true_part, true_motion (N,) ints (-1: no part)."""
    yaw_record: dict[str, float] = {}
    if opts.yaw == "random":
        points, yaw_record = _turned_and_recovered(points, rng, cfg.yaw_settings)
    labelled = true_part >= 0
    present = np.unique(true_part[labelled])
    if tree.root not in present or present.max() >= tree.num_parts:
        return None
    truth = restrict_tree(tree, present.tolist())
    gt = np.searchsorted(present, true_part[labelled]).astype(np.int64)
    pts = points[labelled]
    seg = segment_scan(pts, segmenter, cfg, rng)
    det = object_detections(seg.part_id, seg.part_confidence, gt, opts.iou_threshold)
    record: dict[str, Any] = {
        "points": len(pts),
        "true_parts": truth.num_parts,
        "hidden_parts": tree.num_parts - truth.num_parts,
        "pred_parts": seg.num_parts,
        "confidence": det.confidence.tolist(),
        "true_positive": det.true_positive.tolist(),
        "n_ground_truth": det.n_ground_truth,
        "motion_accuracy": motion_type_accuracy(seg.motion_type, true_motion[labelled]),
        **yaw_record,
    }
    for name, part_id in (("gt", gt), ("pred", seg.part_id)):
        h = build_hierarchy(pts, part_id, labeller, cfg, rng, seg.motion_prob)
        mapping = None if name == "gt" else match_parts(part_id, gt, opts.match_iou)
        c = hierarchy_counts(h.labelling, h.tree, truth, mapping)
        record[name] = {k: int(getattr(c, k)) for k in COUNTS} | {
            "tree_precision": c.tree.precision,
            "tree_recall": c.tree.recall,
            "tree_f1": c.tree.f1,
        }
    return record


def evaluation_config(
    segmenter: LoadedSegmenter, labeller: LoadedLabeller, opts: HierarchyEvaluateConfig
) -> HierarchyConfig:
    """The settings `artic evaluate hierarchy` runs the models with: theirs
    (`models.hierarchy_config`), no axis estimate, the object frame (`evaluate_scan` turns
    the scan itself with opts.yaw) and opts' motion evidence."""
    cfg = hierarchy_config(segmenter, labeller, MAX_POINTS)
    return replace(cfg, estimate_axes=False, yaw="none", motion_evidence=opts.motion_evidence)


def evaluate_rows(
    ds: ScanDataset,
    rows: Iterable[ScanRow],
    segmenter: PartSegmentationNet,
    labeller: Labeller,
    cfg: HierarchyConfig,
    opts: HierarchyEvaluateConfig,
    seed: int,
) -> tuple[list[dict[str, Any]], int]:
    """`evaluate_scan` on each scan of `rows` of `ds`, each seeded from (seed, object, pose,
    kind) -> (records, each with its object, pose and kind; scans skipped: root not
    visible)."""
    records, skipped = [], 0
    for row in rows:
        cloud, tree = ds.cloud(row), ds.tree(row.object_id)
        assert cloud.part_id is not None and cloud.motion_type is not None
        kind = KINDS.index(row.kind)
        rng = np.random.default_rng([seed, row.object_id, row.pose, kind])
        record = evaluate_scan(cloud.points, cloud.part_id, cloud.motion_type, tree,
                               segmenter, labeller, cfg, opts, rng)  # fmt: skip
        if record is None:
            skipped += 1
            continue
        records.append({"object_id": row.object_id, "pose": row.pose, "kind": row.kind, **record})
    return records, skipped
