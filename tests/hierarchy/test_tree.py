"""Tree extraction (section 4.2.3) and the KinematicTree record."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.csgraph import minimum_spanning_tree

from artic.errors import InputError
from artic.hierarchy.tree import FALLBACK_COST, edge_cost_matrix, extract_tree, prim_tree
from artic.objects.tree import GraphLabelling, JointAxis, KinematicTree


def labelling(
    edges: list[tuple[int, int]],
    exists: list[float],
    parent_first: list[float],
    root: list[float],
    motion: list[int],
) -> GraphLabelling:
    one_hot = np.eye(4)[motion] * 0.9 + 0.025
    return GraphLabelling(
        edges=np.array(edges, dtype=np.int64).reshape(-1, 2),
        motion=one_hot,
        exists=np.array(exists),
        parent_first=np.array(parent_first),
        root=np.array(root) / np.sum(root),
    )


HAND_MADE = labelling(
    edges=[(0, 1), (0, 2), (1, 2), (2, 3)],
    exists=[0.9, 0.8, 0.3, 0.7],
    parent_first=[0.9, 0.95, 0.5, 0.2],
    root=[0.7, 0.1, 0.1, 0.1],
    motion=[0, 1, 2, 0],
)


def test_cost_matrix_is_negative_log_probability() -> None:
    cost = edge_cost_matrix(HAND_MADE)
    assert cost[0, 1] == pytest.approx(-np.log(0.9) - np.log(0.9))
    assert cost[1, 0] == pytest.approx(-np.log(0.9) - np.log(0.1))
    assert cost[3, 2] == pytest.approx(-np.log(0.7) - np.log(0.8))
    assert cost[0, 3] == FALLBACK_COST and np.isinf(cost[2, 2])


def test_prim_from_predicted_root() -> None:
    tree = extract_tree(HAND_MADE)
    assert tree.root == 0
    assert tree.edges == ((0, 1), (0, 2), (2, 3))
    assert tree.motion_types == (0, 1, 2, 0)
    assert tree.joint_types == ("revolute", "prismatic", "fixed")
    assert tree.axes is None


def test_prim_from_a_given_root_directs_edges_outwards() -> None:
    tree = extract_tree(HAND_MADE, root=3)
    # 3->2 (0.58), then 2->1 (1.90) beats 2->0 (3.22), then 1->0 (2.41)
    assert tree.edges == ((3, 2), (2, 1), (1, 0))
    assert tree.joint_types == ("prismatic", "revolute", "fixed")


def test_disconnected_graph_falls_back_to_nearest_part() -> None:
    lab = labelling([(0, 1)], [0.9], [0.9], [1.0, 0.0, 0.0], [0, 1, 1])
    centroids = np.array([[0.0, 0, 0], [1.0, 0, 0], [1.2, 0, 0]])
    tree = extract_tree(lab, centroids=centroids)
    assert tree.edges == ((0, 1), (1, 2))
    empty = labelling([], [], [], [0.0, 0.0, 1.0], [0, 0, 0])
    assert extract_tree(empty, centroids=centroids).edges == ((2, 1), (1, 0))


def test_prim_total_cost_matches_scipy_on_symmetric_costs() -> None:
    rng = np.random.default_rng(0)
    for _ in range(5):
        w = rng.random((8, 8)) + 0.1
        w = w + w.T
        np.fill_diagonal(w, np.inf)
        edges = prim_tree(w, root=int(rng.integers(8)))
        assert len(edges) == 7
        ours = sum(w[a, b] for a, b in edges)
        reference = minimum_spanning_tree(np.where(np.isinf(w), 0, w)).sum()
        assert ours == pytest.approx(reference)


def test_invalid_trees_raise() -> None:
    with pytest.raises(ValueError, match="two parents"):
        KinematicTree(3, 0, ((0, 1), (0, 1)), (0, 0, 0), ("fixed", "fixed"))
    with pytest.raises(ValueError, match="edges"):
        KinematicTree(3, 0, ((0, 1),), (0, 0, 0), ("fixed",))
    with pytest.raises(ValueError, match="not reached"):
        KinematicTree(3, 0, ((1, 2), (0, 1)), (0, 0, 0), ("fixed", "fixed"))


def test_json_round_trip() -> None:
    axes = (
        JointAxis(np.array([0.1, -0.2, 0.3]), np.array([0.0, 0.0, 1.0])),
        None,
    )
    tree = KinematicTree(3, 1, ((1, 0), (1, 2)), (1, 0, 0), ("revolute", "fixed"), axes)
    back = KinematicTree.from_json(tree.to_json())
    assert back.to_dict() == tree.to_dict()
    assert back.edges == tree.edges and back.motion_types == tree.motion_types
    assert back.axes is not None and back.axes[1] is None
    assert np.array_equal(back.axes[0].origin, axes[0].origin)  # type: ignore[union-attr]
    plain = KinematicTree(1, 0, (), (0,), ())
    assert KinematicTree.from_json(plain.to_json()) == plain


@pytest.mark.parametrize(
    "text",
    [
        "[1]",
        "{",
        '{"num_parts": 2}',
        '{"num_parts": 2, "root": 5, "edges": [[0, 1]], '
        '"motion_types": ["static", "rotating"], "joint_types": ["revolute"]}',
    ],
)
def test_bad_json_raises_input_error(text: str) -> None:
    with pytest.raises(InputError, match="kinematic tree"):
        KinematicTree.from_json(text)
