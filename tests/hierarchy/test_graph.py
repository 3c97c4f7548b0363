"""Part graph (section 4.4.1): candidate edges by contact distance, features, labels."""

from __future__ import annotations

import numpy as np
import pytest

from artic.errors import InputError
from artic.hierarchy.graph import (
    EDGE_FEATURES,
    PartGraphConfig,
    build_part_graph,
    graph_labels,
    reverse_edge_features,
)
from artic.objects.tree import KinematicTree
from box_clouds import box_surface


def three_boxes(rng: np.random.Generator, n: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """Boxes 0 | 1 | 2 in a row along x, 5 mm gaps: 0-1 and 1-2 touch, 0-2 are 0.5 m apart."""
    boxes = [
        ([0.0, 0.0, 0.0], [0.5, 0.5, 0.5]),
        ([0.505, 0.1, 0.1], [1.0, 0.4, 0.4]),
        ([1.005, 0.0, 0.0], [1.3, 0.5, 0.5]),
    ]
    points = np.concatenate([box_surface(lo, hi, n, rng) for lo, hi in boxes])
    part_id = np.repeat(np.arange(3), n)
    return points.astype(np.float32), part_id


def test_touching_boxes_give_expected_edges() -> None:
    points, part_id = three_boxes(np.random.default_rng(0))
    graph = build_part_graph(points, part_id, np.random.default_rng(1))
    assert graph.edges.tolist() == [[0, 1], [1, 2]]
    assert graph.num_parts == 3
    assert np.all(graph.min_distance >= 0.005 - 1e-6)
    assert np.all(graph.min_distance < 0.02)
    assert graph.edge_features.shape == (2, len(EDGE_FEATURES))
    # centroid offset points from the first to the second endpoint (+x here)
    assert np.all(graph.edge_features[:, 1] > 0)
    assert graph.node_points.shape == (3, 128, 3) and graph.node_points.dtype == np.float32
    assert np.abs(graph.node_points).max() <= 1.0 + 1e-5  # normalised by the object radius


def test_threshold_controls_edges() -> None:
    points, part_id = three_boxes(np.random.default_rng(0))
    rng = np.random.default_rng(1)
    none = build_part_graph(points, part_id, rng, PartGraphConfig(contact_threshold=0.004))
    assert none.num_edges == 0 and none.edge_features.shape == (0, len(EDGE_FEATURES))
    far = build_part_graph(points, part_id, rng, PartGraphConfig(contact_threshold=0.6))
    assert far.edges.tolist() == [[0, 1], [0, 2], [1, 2]]


def test_same_seed_same_graph_and_resampling() -> None:
    points, part_id = three_boxes(np.random.default_rng(0), n=50)
    cfg = PartGraphConfig(points_per_node=64)  # more than a part has: drawn with replacement
    a = build_part_graph(points, part_id, np.random.default_rng(5), cfg)
    b = build_part_graph(points, part_id, np.random.default_rng(5), cfg)
    c = build_part_graph(points, part_id, np.random.default_rng(6), cfg)
    assert np.array_equal(a.node_points, b.node_points)
    assert not np.array_equal(a.node_points, c.node_points)
    assert a.node_points.shape == (3, 64, 3)


def test_reverse_edge_features_is_an_involution() -> None:
    points, part_id = three_boxes(np.random.default_rng(0))
    graph = build_part_graph(points, part_id, np.random.default_rng(1))
    reversed_ = reverse_edge_features(graph.edge_features)
    assert np.allclose(reversed_[:, 1:4], -graph.edge_features[:, 1:4])
    assert np.array_equal(reverse_edge_features(reversed_), graph.edge_features)


def test_labels_from_tree() -> None:
    points, part_id = three_boxes(np.random.default_rng(0))
    graph = build_part_graph(points, part_id, np.random.default_rng(1))
    tree = KinematicTree(3, 1, ((1, 0), (1, 2)), (2, 0, 1), ("prismatic", "revolute"))
    labels = graph_labels(graph, tree)
    assert labels.exists.tolist() == [True, True]
    assert labels.parent_first.tolist() == [False, True]  # (0, 1): 1 is parent; (1, 2): 1
    assert labels.root == 1 and labels.motion_type.tolist() == [2, 0, 1]
    assert labels.uncovered == ()
    chain = KinematicTree(3, 0, ((0, 2), (2, 1)), (0, 1, 1), ("revolute", "revolute"))
    labels = graph_labels(graph, chain)
    assert labels.exists.tolist() == [False, True]
    assert labels.uncovered == ((0, 2),)


@pytest.mark.parametrize(
    ("points", "part_id", "field"),
    [
        (np.full((4, 3), np.nan), np.zeros(4, int), "points"),
        (np.zeros((4, 2)), np.zeros(4, int), "points"),
        (np.zeros((4, 3)), np.array([0, 0, 2, 2]), "part_id"),
        (np.zeros((4, 3)), np.zeros(3, int), "part_id"),
        (np.zeros((4, 3)), np.array([0, -1, 0, 0]), "part_id"),
    ],
)
def test_bad_input_raises(points: np.ndarray, part_id: np.ndarray, field: str) -> None:
    with pytest.raises(InputError, match=field):
        build_part_graph(points, part_id, np.random.default_rng(0))
