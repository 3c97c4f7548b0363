"""Tables 4.1 and 4.2 on one scan: the segmenter and the graph network run as `segment`
and `build-hierarchy` do (`infer`), scored against the scan's true parts and tree
(`artic.evaluation`). Parts that no point of the scan shows are left out of its ground
truth (the tree is contracted over them, as in training: `fit_labeller.restrict_tree`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from artic.evaluation.hierarchy import hierarchy_counts, match_parts
from artic.evaluation.hierarchy_report import COUNTS
from artic.evaluation.segmentation import motion_type_accuracy, object_detections
from artic.hierarchy.config import HierarchyEvaluateConfig
from artic.hierarchy.fit_labeller import restrict_tree
from artic.hierarchy.gnn import GraphLabellingNet
from artic.hierarchy.infer import HierarchyConfig, build_hierarchy, segment_scan
from artic.hierarchy.segmentation import PartSegmentationNet
from artic.objects.tree import KinematicTree


def evaluate_scan(
    points: np.ndarray,
    true_part: np.ndarray,
    true_motion: np.ndarray,
    tree: KinematicTree,
    segmenter: PartSegmentationNet,
    labeller: GraphLabellingNet,
    cfg: HierarchyConfig,
    opts: HierarchyEvaluateConfig,
    rng: np.random.Generator,
) -> dict[str, Any] | None:
    """One scan's Table 4.1 detections and Table 4.2 counts (None: root not visible).
    points (N, 3) metres; true_part, true_motion (N,) ints (-1: no part)."""
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
    }
    for name, part_id in (("gt", gt), ("pred", seg.part_id)):
        h = build_hierarchy(pts, part_id, labeller, cfg, rng)
        mapping = None if name == "gt" else match_parts(part_id, gt, opts.match_iou)
        c = hierarchy_counts(h.labelling, h.tree, truth, mapping)
        record[name] = {k: int(getattr(c, k)) for k in COUNTS} | {
            "tree_precision": c.tree.precision,
            "tree_recall": c.tree.recall,
            "tree_f1": c.tree.f1,
        }
    return record
