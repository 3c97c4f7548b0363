"""Labelled part graph to kinematic tree (thesis section 4.2.3).

As Xu et al. (2020b), a pairwise matrix holds the negative log-probability of each
directed edge, cost[a, b] = -log p(edge a-b exists) - log p(a is the parent of b), and
Prim's algorithm (Prim, 1957) grows a minimum spanning tree from the predicted root
(the part with the highest root probability). Each tree edge is directed away from
the root, from the part already in the tree to the part it adds, so the cost of the
orientation actually used is the one minimised.

Joint types follow the child's predicted motion type (`JOINT_TYPE_OF_MOTION`):
static -> fixed, rotating -> revolute, translating -> prismatic, both -> revolute.

Disconnected candidate graphs: pairs that are not candidate edges cost
`fallback_cost` plus their centroid distance in metres (when centroids are given), so
Prim uses them only when no candidate edge reaches the remaining parts, and then joins
the nearest part. A spanning tree therefore always exists.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from artic.objects.tree import JOINT_TYPE_OF_MOTION, GraphLabelling, KinematicTree

FALLBACK_COST = 1.0e3
_EPS = 1e-9


def edge_cost_matrix(
    labelling: GraphLabelling,
    centroids: NDArray[np.float64] | None = None,
    fallback_cost: float = FALLBACK_COST,
) -> NDArray[np.float64]:
    """(P, P) cost of each directed edge a -> b: -log p_exist - log p_dir.

    Pairs outside the candidate edges cost `fallback_cost` (+ the distance between the
    parts' centroids (P, 3), metres, when given). The diagonal is +inf.
    """
    p = labelling.num_parts
    cost = np.full((p, p), float(fallback_cost))
    if centroids is not None:
        c = np.asarray(centroids, dtype=np.float64)
        cost += np.linalg.norm(c[:, None, :] - c[None, :, :], axis=-1)
    if labelling.edges.size:
        a, b = labelling.edges[:, 0], labelling.edges[:, 1]
        exist = -np.log(np.clip(labelling.exists, _EPS, 1.0))
        first = np.clip(labelling.parent_first, _EPS, 1.0 - _EPS)
        cost[a, b] = exist - np.log(first)
        cost[b, a] = exist - np.log1p(-first)
    np.fill_diagonal(cost, np.inf)
    return cost


def prim_tree(cost: NDArray[np.float64], root: int) -> list[tuple[int, int]]:
    """Edges (parent, child) of Prim's minimum spanning tree of `cost` (P, P) grown from
    `root`; each step adds the cheapest edge from a part in the tree to one outside,
    directed outwards. Ties go to the lowest (parent, child) indices. Order: as added."""
    p = cost.shape[0]
    if cost.shape != (p, p) or not 0 <= root < p:
        raise ValueError(f"cost must be square and root in 0..{p - 1}")
    in_tree = np.zeros(p, dtype=bool)
    in_tree[root] = True
    best = cost[root].copy()
    best_parent: NDArray[np.int64] = np.full(p, root, dtype=np.int64)
    edges: list[tuple[int, int]] = []
    for _ in range(p - 1):
        candidates = np.where(in_tree, np.inf, best)
        child = int(np.argmin(candidates))
        if not np.isfinite(candidates[child]):
            raise ValueError("cost matrix has no finite edge to the remaining parts")
        edges.append((int(best_parent[child]), child))
        in_tree[child] = True
        better = cost[child] < best
        best = np.where(better, cost[child], best)
        best_parent = np.where(better, child, best_parent)
    return edges


def _breadth_first(root: int, edges: list[tuple[int, int]]) -> list[tuple[int, int]]:
    children: dict[int, list[int]] = {}
    for a, b in edges:
        children.setdefault(a, []).append(b)
    ordered: list[tuple[int, int]] = []
    queue = [root]
    while queue:
        node = queue.pop(0)
        for child in sorted(children.get(node, [])):
            ordered.append((node, child))
            queue.append(child)
    return ordered


def extract_tree(
    labelling: GraphLabelling,
    centroids: NDArray[np.float64] | None = None,
    root: int | None = None,
    fallback_cost: float = FALLBACK_COST,
) -> KinematicTree:
    """The kinematic tree of a labelled part graph (section 4.2.3).

    root: the root part; default the most probable one. centroids: (P, 3) metres, used
    only to choose among non-candidate pairs. Motion types are the most probable ones.
    Edges are ordered breadth-first from the root (children by index); axes are None.
    """
    chosen_root = int(np.argmax(labelling.root)) if root is None else int(root)
    cost = edge_cost_matrix(labelling, centroids, fallback_cost)
    edges = _breadth_first(chosen_root, prim_tree(cost, chosen_root))
    motion = tuple(int(m) for m in np.argmax(labelling.motion, axis=1))
    return KinematicTree(
        num_parts=labelling.num_parts,
        root=chosen_root,
        edges=tuple(edges),
        motion_types=motion,
        joint_types=tuple(JOINT_TYPE_OF_MOTION[motion[child]] for _, child in edges),
    )
