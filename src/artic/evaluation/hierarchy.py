"""Kinematic structure errors of Table 4.2 (thesis section 4.5.2), as pure functions.

Per model, from the network's labelling of the candidate graph, the tree extracted
from it and the ground-truth tree:

- E_type: % of ground-truth parts whose motion type is mis-predicted (argmax).
- E_exist: % of part pairs whose edge existence is mis-predicted (p > 0.5). The pairs
  are the candidate edges plus the ground-truth tree edges (a tree edge missing from
  the candidate graph counts as predicted absent).
- E_dir: % of ground-truth tree edges whose direction is mis-predicted (p > 0.5 that the
  candidate edge's first part is the parent); tree edges with no candidate edge are
  counted in E_exist only.
- E_root: % of models whose root (argmax) is mis-predicted.
- Tree F1: precision = fraction of the predicted tree's nodes and directed edges that
  match their counterpart in the ground-truth tree (a node: same part with the same
  motion type; an edge: the same parent -> child), recall the same with the trees'
  roles swapped; F1 = 2PR / (P + R), in %.

With ground-truth segmentation parts are the same. With a predicted segmentation,
predicted parts are first matched one-to-one to true parts by the Hungarian algorithm
on point IoU (`match_parts`; pairs below `min_iou` stay unmatched), and every
prediction is read through that matching: an unmatched true part counts as a type
error, an unmatched predicted part or edge never matches. Over a test set, E_type,
E_exist and E_dir pool the counts of all models (micro average), E_root is over models
and Tree F1 is the mean of the per-model scores.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from artic.objects.tree import GraphLabelling, KinematicTree


def match_parts(
    pred_part_id: NDArray[np.integer], true_part_id: NDArray[np.integer], min_iou: float = 0.5
) -> NDArray[np.int64]:
    """(P_pred,) true part matched to each predicted part (Hungarian on point IoU), -1
    where unmatched or IoU < min_iou. Both inputs: (N,) ints over the same points."""
    from scipy.optimize import linear_sum_assignment

    pred = np.asarray(pred_part_id, dtype=np.int64)
    true = np.asarray(true_part_id, dtype=np.int64)
    if pred.shape != true.shape or pred.ndim != 1:
        raise ValueError(
            f"part ids must be (N,) over the same points: {pred.shape} vs {true.shape}"
        )
    p_pred, p_true = int(pred.max()) + 1, int(true.max()) + 1
    intersection = np.zeros((p_pred, p_true))
    np.add.at(intersection, (pred, true), 1.0)
    union = np.bincount(pred, minlength=p_pred)[:, None] + np.bincount(true, minlength=p_true)
    iou = intersection / np.maximum(union - intersection, 1.0)
    rows, cols = linear_sum_assignment(-iou)
    mapping = np.full(p_pred, -1, dtype=np.int64)
    keep = iou[rows, cols] >= min_iou
    mapping[rows[keep]] = cols[keep]
    return mapping


@dataclass(frozen=True)
class TreeScore:
    """Tree precision, recall and F1, in % (section 4.5.2)."""

    precision: float
    recall: float
    f1: float


def tree_score(
    pred: KinematicTree, true: KinematicTree, pred_to_true: NDArray[np.int64] | None = None
) -> TreeScore:
    """Tree F1 of `pred` against `true`; pred_to_true: (P_pred,) (identity by default)."""
    mapping = _mapping(pred, true, pred_to_true)
    true_edges = set(true.edges)
    matched_nodes = sum(
        1
        for n in range(pred.num_parts)
        if mapping[n] >= 0 and pred.motion_types[n] == true.motion_types[mapping[n]]
    )
    matched_edges = sum(
        1 for a, b in pred.edges if mapping[a] >= 0 and (mapping[a], mapping[b]) in true_edges
    )
    matched = matched_nodes + matched_edges  # one-to-one: the same count seen from both trees
    precision = 100.0 * matched / (pred.num_parts + len(pred.edges))
    recall = 100.0 * matched / (true.num_parts + len(true.edges))
    f1 = 0.0 if matched == 0 else 2.0 * precision * recall / (precision + recall)
    return TreeScore(precision, recall, f1)


def _mapping(
    pred: KinematicTree, true: KinematicTree, pred_to_true: NDArray[np.int64] | None
) -> list[int]:
    if pred_to_true is None:
        if pred.num_parts != true.num_parts:
            raise ValueError("without a part matching both trees need the same parts")
        return list(range(pred.num_parts))
    mapping = [int(m) for m in pred_to_true]
    if len(mapping) != pred.num_parts:
        raise ValueError(f"pred_to_true has {len(mapping)} entries, expected {pred.num_parts}")
    matched = [m for m in mapping if m >= 0]
    if len(set(matched)) != len(matched) or any(m >= true.num_parts for m in matched):
        raise ValueError("pred_to_true must map to distinct true parts")
    return mapping


@dataclass(frozen=True)
class HierarchyCounts:
    """Error counts of one model (denominators alongside), and its tree score."""

    type_errors: int
    nodes: int
    exist_errors: int
    pairs: int
    dir_errors: int
    directed: int
    root_error: bool
    tree: TreeScore


def hierarchy_counts(
    labelling: GraphLabelling,
    pred_tree: KinematicTree,
    true_tree: KinematicTree,
    pred_to_true: NDArray[np.int64] | None = None,
) -> HierarchyCounts:
    """Section 4.5.2's error counts for one model. labelling and pred_tree are over the
    predicted parts; pred_to_true (P_pred,) maps them to true parts (-1: unmatched),
    identity for ground-truth segmentation."""
    if labelling.num_parts != pred_tree.num_parts:
        raise ValueError("labelling and predicted tree must have the same parts")
    mapping = _mapping(pred_tree, true_tree, pred_to_true)
    true_of = {t: p for p, t in enumerate(mapping) if t >= 0}

    pred_types = np.argmax(labelling.motion, axis=1)
    type_errors = sum(
        1
        for t in range(true_tree.num_parts)
        if t not in true_of or int(pred_types[true_of[t]]) != true_tree.motion_types[t]
    )

    true_directed = set(true_tree.edges)
    true_pairs = {frozenset(e) for e in true_directed}
    predicted_exist: dict[frozenset[int], bool] = {}
    predicted_parent: dict[frozenset[int], int] = {}
    for e, (a, b) in enumerate(labelling.edges.tolist()):
        ta, tb = mapping[a], mapping[b]
        if ta < 0 or tb < 0:
            continue
        pair = frozenset((ta, tb))
        predicted_exist[pair] = bool(labelling.exists[e] > 0.5)
        predicted_parent[pair] = ta if labelling.parent_first[e] > 0.5 else tb
    pairs = set(predicted_exist) | true_pairs
    exist_errors = sum(1 for q in pairs if predicted_exist.get(q, False) != (q in true_pairs))
    judged = [(a, b) for a, b in true_directed if frozenset((a, b)) in predicted_parent]
    dir_errors = sum(1 for a, b in judged if predicted_parent[frozenset((a, b))] != a)

    pred_root = mapping[int(np.argmax(labelling.root))]
    return HierarchyCounts(
        type_errors=type_errors,
        nodes=true_tree.num_parts,
        exist_errors=exist_errors,
        pairs=len(pairs),
        dir_errors=dir_errors,
        directed=len(judged),
        root_error=pred_root != true_tree.root,
        tree=tree_score(pred_tree, true_tree, np.asarray(mapping, dtype=np.int64)),
    )


@dataclass(frozen=True)
class HierarchyMetrics:
    """Table 4.2 row: errors and Tree F1 in %, over `models` models."""

    e_type: float
    e_exist: float
    e_dir: float
    e_root: float
    tree_f1: float
    models: int


def _percent(errors: int, total: int) -> float:
    return 100.0 * errors / total if total else 0.0


def summarize(counts: Sequence[HierarchyCounts]) -> HierarchyMetrics:
    """Pool per-model counts into Table 4.2's numbers."""
    if not counts:
        raise ValueError("summarize needs at least one model")
    return HierarchyMetrics(
        e_type=_percent(sum(c.type_errors for c in counts), sum(c.nodes for c in counts)),
        e_exist=_percent(sum(c.exist_errors for c in counts), sum(c.pairs for c in counts)),
        e_dir=_percent(sum(c.dir_errors for c in counts), sum(c.directed for c in counts)),
        e_root=_percent(sum(c.root_error for c in counts), len(counts)),
        tree_f1=float(np.mean([c.tree.f1 for c in counts])),
        models=len(counts),
    )
