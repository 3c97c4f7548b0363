"""Kinematic structure errors of Table 4.2 (section 4.5.2): hand-computed cases."""

from __future__ import annotations

import numpy as np
import pytest

from artic.evaluation.hierarchy import (
    hierarchy_counts,
    match_parts,
    summarize,
    tree_score,
)
from artic.hierarchy.tree import extract_tree
from artic.objects.tree import GraphLabelling, KinematicTree

TRUE = KinematicTree(
    4, 0, ((0, 1), (0, 2), (2, 3)), (0, 1, 2, 1), ("revolute", "prismatic", "revolute")
)
CANDIDATES = [(0, 1), (0, 2), (1, 2), (2, 3)]


def labelling(
    motion: list[int],
    exists: list[float],
    parent_first: list[float],
    root: int,
    edges: list[tuple[int, int]] = CANDIDATES,
) -> GraphLabelling:
    parts = len(motion)
    return GraphLabelling(
        edges=np.array(edges, dtype=np.int64),
        motion=np.eye(4)[motion] * 0.9 + 0.025,
        exists=np.array(exists),
        parent_first=np.array(parent_first),
        root=np.eye(parts)[root] * 0.9 + 0.1 / parts,
    )


def test_perfect_prediction_has_no_errors() -> None:
    lab = labelling([0, 1, 2, 1], [0.9, 0.9, 0.1, 0.9], [0.9, 0.9, 0.5, 0.9], root=0)
    predicted = extract_tree(lab)
    assert set(predicted.edges) == set(TRUE.edges)
    counts = hierarchy_counts(lab, predicted, TRUE)
    assert (counts.type_errors, counts.exist_errors, counts.dir_errors) == (0, 0, 0)
    assert (counts.nodes, counts.pairs, counts.directed) == (4, 4, 3)
    assert not counts.root_error
    assert counts.tree.f1 == pytest.approx(100.0)
    metrics = summarize([counts, counts])
    assert (metrics.e_type, metrics.e_exist, metrics.e_dir, metrics.e_root) == (0, 0, 0, 0)
    assert metrics.tree_f1 == pytest.approx(100.0) and metrics.models == 2


def test_hand_computed_errors_with_ground_truth_segmentation() -> None:
    # part 3 typed translating (wrong), edge 1-2 said to exist (wrong), 2->3 reversed (wrong)
    lab = labelling([0, 1, 2, 2], [0.9, 0.9, 0.8, 0.9], [0.9, 0.9, 0.5, 0.2], root=0)
    predicted = KinematicTree(
        4, 0, ((0, 1), (1, 2), (2, 3)), (0, 1, 2, 2), ("revolute", "prismatic", "prismatic")
    )
    counts = hierarchy_counts(lab, predicted, TRUE)
    assert counts.type_errors == 1 and counts.nodes == 4
    assert counts.exist_errors == 1 and counts.pairs == 4
    assert counts.dir_errors == 1 and counts.directed == 3
    # nodes 0, 1, 2 and edges 0->1, 2->3 match: 5 of 7 on both sides
    assert counts.tree.precision == pytest.approx(500 / 7)
    assert counts.tree.f1 == pytest.approx(500 / 7)
    wrong_root = labelling([0, 1, 2, 1], [0.9, 0.9, 0.1, 0.9], [0.9, 0.9, 0.5, 0.9], root=2)
    counts_root = hierarchy_counts(wrong_root, extract_tree(wrong_root), TRUE)
    assert counts_root.root_error
    metrics = summarize([counts, counts_root])
    assert metrics.e_type == pytest.approx(100 * 1 / 8)
    assert metrics.e_exist == pytest.approx(100 * 1 / 8)
    assert metrics.e_dir == pytest.approx(100 * 1 / 6)
    assert metrics.e_root == pytest.approx(50.0)


def test_tree_edge_missing_from_candidates_counts_as_existence_error() -> None:
    edges = [(0, 1), (0, 2), (1, 2)]  # no candidate 2-3
    lab = labelling([0, 1, 2, 1], [0.9, 0.9, 0.1], [0.9, 0.9, 0.5], root=0, edges=edges)
    counts = hierarchy_counts(lab, extract_tree(lab), TRUE)
    assert counts.exist_errors == 1 and counts.pairs == 4
    assert counts.directed == 2 and counts.dir_errors == 0


def test_match_parts_hungarian_on_iou() -> None:
    true = np.repeat([0, 1, 2], 10)
    pred = np.concatenate([np.full(10, 1), np.full(10, 0), np.full(8, 2), np.full(2, 3)])
    assert match_parts(pred, true).tolist() == [1, 0, 2, -1]
    assert match_parts(pred, true, min_iou=0.9).tolist() == [1, 0, -1, -1]
    assert match_parts(true, true).tolist() == [0, 1, 2]


def test_hand_computed_errors_with_predicted_segmentation() -> None:
    true_tree = KinematicTree(3, 0, ((0, 1), (0, 2)), (0, 1, 2), ("revolute", "prismatic"))
    mapping = np.array([1, 0, 2, -1])  # predicted parts -> true parts; part 3 is spurious
    lab = GraphLabelling(
        edges=np.array([(0, 1), (1, 2), (2, 3), (0, 2)]),
        motion=np.eye(4)[[1, 0, 1, 0]],
        exists=np.array([0.9, 0.9, 0.9, 0.1]),
        parent_first=np.array([0.1, 0.9, 0.9, 0.5]),
        root=np.array([0.1, 0.7, 0.1, 0.1]),
    )
    predicted = KinematicTree(4, 1, ((1, 0), (1, 2), (2, 3)), (1, 0, 1, 0), ("revolute",) * 3)
    counts = hierarchy_counts(lab, predicted, true_tree, mapping)
    assert (counts.type_errors, counts.nodes) == (1, 3)
    assert (counts.exist_errors, counts.pairs) == (0, 3)
    assert (counts.dir_errors, counts.directed) == (0, 2)
    assert not counts.root_error
    # matched: nodes pred 0, 1; edges 1->0, 1->2 = 4; predicted 4 + 3, true 3 + 2
    assert counts.tree.precision == pytest.approx(400 / 7)
    assert counts.tree.recall == pytest.approx(80.0)
    assert counts.tree.f1 == pytest.approx(2 * (4 / 7) * 0.8 / (4 / 7 + 0.8) * 100)


def test_invalid_inputs_raise() -> None:
    with pytest.raises(ValueError, match="distinct"):
        tree_score(TRUE, TRUE, np.array([0, 0, 1, 2]))
    with pytest.raises(ValueError, match="same points"):
        match_parts(np.zeros(3, int), np.zeros(4, int))
    with pytest.raises(ValueError, match="at least one"):
        summarize([])
