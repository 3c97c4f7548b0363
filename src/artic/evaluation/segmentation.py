"""Table 4.1 metrics: part instance mAP at IoU 0.5 (PartNet protocol, Mo et al. 2019) and
per-point motion-type accuracy.

Protocol: in each object, predicted parts are taken in decreasing confidence; a prediction
is a true positive if its IoU with a ground-truth part not yet matched is >= the threshold
(the best such part is matched), else a false positive. The average precision is the area
under the precision-recall curve with precision made monotone (the all-point VOC
interpolation PartNet uses). Table 4.1 pools the detections of all test objects of a
category into one curve (`mean_average_precision(..., pooled=True)`); the mean of
per-object APs is available too. Points whose ground-truth part is -1 are ignored.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from artic.errors import InputError


class Detections(NamedTuple):
    """The predicted parts of one (or several pooled) objects, classified against the truth."""

    confidence: NDArray[np.float64]  # (K,) score of each predicted part
    true_positive: NDArray[np.bool_]  # (K,) matched a ground-truth part at the IoU threshold
    n_ground_truth: int  # ground-truth parts


def instance_iou(
    pred_part_id: NDArray[np.integer], gt_part_id: NDArray[np.integer]
) -> NDArray[np.float64]:
    """IoU of every predicted part with every ground-truth part of one cloud.

    pred_part_id: (N,) in 0..K-1; gt_part_id: (N,) in 0..P-1, or -1 (ignored) ->
    (K, P) with K = max(pred) + 1 and P = max(gt) + 1 (empty parts have IoU 0).
    """
    pred = np.asarray(pred_part_id, dtype=np.int64)
    gt = np.asarray(gt_part_id, dtype=np.int64)
    if pred.shape != gt.shape or pred.ndim != 1:
        raise InputError(f"part ids: expected two (N,) arrays, got {pred.shape} and {gt.shape}")
    if (pred < 0).any():
        raise InputError("pred_part_id: expected ids >= 0")
    valid = gt >= 0
    k = int(pred.max()) + 1 if len(pred) else 0
    p = int(gt.max()) + 1 if valid.any() else 0
    inter = np.zeros((k, p))
    np.add.at(inter, (pred[valid], gt[valid]), 1.0)
    pred_size = np.bincount(pred[valid], minlength=k).astype(np.float64)
    gt_size = np.bincount(gt[valid], minlength=p).astype(np.float64)
    union = pred_size[:, None] + gt_size[None, :] - inter
    return np.divide(inter, union, out=np.zeros_like(inter), where=union > 0)


def match_detections(
    iou: NDArray[np.float64], confidence: NDArray[np.floating], threshold: float = 0.5
) -> Detections:
    """Greedy matching in decreasing confidence: iou (K, P), confidence (K,) -> Detections
    (in the order of `confidence`)."""
    iou = np.asarray(iou, dtype=np.float64)
    conf = np.asarray(confidence, dtype=np.float64)
    if iou.ndim != 2 or conf.shape != (iou.shape[0],):
        raise InputError(f"confidence: expected ({iou.shape[0]},) scores, got {conf.shape}")
    free = np.ones(iou.shape[1], dtype=bool)
    tp = np.zeros(len(conf), dtype=bool)
    for i in np.argsort(-conf, kind="stable"):
        candidates = np.where(free & (iou[i] >= threshold), iou[i], -1.0)
        if len(candidates) and candidates.max() >= 0.0:
            j = int(candidates.argmax())
            free[j] = False
            tp[i] = True
    return Detections(conf, tp, iou.shape[1])


def object_detections(
    pred_part_id: NDArray[np.integer],
    confidence: NDArray[np.floating],
    gt_part_id: NDArray[np.integer],
    threshold: float = 0.5,
) -> Detections:
    """One object: per-point predicted and true part ids (N,), confidence (K,) per
    predicted part -> Detections. Only ground-truth parts with points count."""
    iou = instance_iou(pred_part_id, gt_part_id)
    gt = np.asarray(gt_part_id)
    present = np.bincount(gt[gt >= 0], minlength=iou.shape[1]) > 0
    conf = np.asarray(confidence, dtype=np.float64)
    if len(conf) < iou.shape[0]:
        raise InputError(f"confidence: expected {iou.shape[0]} part scores, got {len(conf)}")
    return match_detections(
        np.pad(iou[:, present], ((0, len(conf) - iou.shape[0]), (0, 0))), conf, threshold
    )


def average_precision(detections: Detections) -> float:
    """Area under the monotone precision-recall curve; 0.0 with no predictions, NaN when
    there is no ground-truth part."""
    if detections.n_ground_truth == 0:
        return float("nan")
    order = np.argsort(-detections.confidence, kind="stable")
    tp = detections.true_positive[order].astype(np.float64)
    if len(tp) == 0:
        return 0.0
    hits = np.cumsum(tp)
    recall = np.concatenate([[0.0], hits / detections.n_ground_truth, [1.0]])
    precision = np.concatenate([[0.0], hits / np.arange(1, len(tp) + 1), [0.0]])
    precision = np.maximum.accumulate(precision[::-1])[::-1]
    step = np.flatnonzero(recall[1:] != recall[:-1])
    return float(np.sum((recall[step + 1] - recall[step]) * precision[step + 1]))


def pool(detections: Sequence[Detections]) -> Detections:
    """Several objects' detections as one set (one precision-recall curve)."""
    if not detections:
        return Detections(np.zeros(0), np.zeros(0, dtype=bool), 0)
    return Detections(
        np.concatenate([d.confidence for d in detections]),
        np.concatenate([d.true_positive for d in detections]),
        sum(d.n_ground_truth for d in detections),
    )


def mean_average_precision(detections: Sequence[Detections], pooled: bool = True) -> float:
    """AP of the pooled detections of a category (Table 4.1), or with `pooled=False` the
    mean AP over objects (objects without ground-truth parts are skipped)."""
    if pooled:
        return average_precision(pool(detections))
    aps = [average_precision(d) for d in detections if d.n_ground_truth > 0]
    return float(np.mean(aps)) if aps else float("nan")


def category_map(
    detections: Mapping[str, Sequence[Detections]], pooled: bool = True
) -> dict[str, float]:
    """mAP per category (a Table 4.1 column), keyed like `detections`, plus "mean"."""
    table = {name: mean_average_precision(d, pooled) for name, d in detections.items()}
    values = [v for v in table.values() if not np.isnan(v)]
    table["mean"] = float(np.mean(values)) if values else float("nan")
    return table


def motion_type_accuracy(
    pred_motion_type: NDArray[np.integer], gt_motion_type: NDArray[np.integer]
) -> float:
    """Fraction of points with the right motion type; (N,) each, ground truth -1 ignored."""
    pred = np.asarray(pred_motion_type)
    gt = np.asarray(gt_motion_type)
    if pred.shape != gt.shape:
        raise InputError(f"motion types: shapes differ, {pred.shape} and {gt.shape}")
    valid = gt >= 0
    return float(np.mean(pred[valid] == gt[valid])) if valid.any() else float("nan")


def motion_type_confusion(
    pred_motion_type: NDArray[np.integer], gt_motion_type: NDArray[np.integer], n_types: int = 4
) -> NDArray[np.int64]:
    """Confusion counts (n_types, n_types): rows ground truth, columns prediction."""
    pred = np.asarray(pred_motion_type, dtype=np.int64)
    gt = np.asarray(gt_motion_type, dtype=np.int64)
    valid = gt >= 0
    out = np.zeros((n_types, n_types), dtype=np.int64)
    np.add.at(out, (gt[valid], pred[valid]), 1)
    return out
