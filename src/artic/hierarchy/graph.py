"""Point cloud to part graph (thesis section 4.4.1).

"Our system constructs the initial graph by adding an undirected edge between any two
parts whose Euclidean distance is below a small threshold." The distance between two
parts is the minimum point-to-point distance (scipy's cKDTree, after a bounding-box
test that skips far pairs). Each node keeps its part's points resampled to a fixed
count for the PointNet encoder (seeded), and simple geometric features; each edge gets
features oriented from its first to its second endpoint. Coordinates given to the
network are normalised: the object's bounding-box centre is subtracted and the result
divided by the object's radius, so the features do not depend on the object's size.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from artic.errors import InputError
from artic.hierarchy.config import PartGraphConfig
from artic.hierarchy.types import GraphLabels, PartGraph
from artic.objects.tree import KinematicTree

EDGE_FEATURES = (
    "min_distance",
    "centroid_offset_x",
    "centroid_offset_y",
    "centroid_offset_z",
    "contact_from_first_x",
    "contact_from_first_y",
    "contact_from_first_z",
    "contact_from_second_x",
    "contact_from_second_y",
    "contact_from_second_z",
)
"""Columns of `PartGraph.edge_features` (normalised lengths): minimum distance, second
centroid minus first centroid, contact point minus first / second centroid. The contact
point is the mean midpoint of the point pairs closer than the threshold."""

NODE_FEATURES = (
    "centroid_x",
    "centroid_y",
    "centroid_z",
    "extent_x",
    "extent_y",
    "extent_z",
    "fraction",
)


def reverse_edge_features(features: NDArray[np.float32]) -> NDArray[np.float32]:
    """(E, 10) edge features of the reversed edges (second -> first endpoint)."""
    out = features.copy()
    out[:, 1:4] = -features[:, 1:4]
    out[:, 4:7] = features[:, 7:10]
    out[:, 7:10] = features[:, 4:7]
    return out


def check_segmented_cloud(points: NDArray[np.floating], part_id: NDArray[np.integer]) -> int:
    """Validate a segmented cloud; returns the number of parts P.

    points: (N, 3) finite. part_id: (N,) integers covering 0..P-1, every part non-empty.
    Raises InputError naming the field.
    """
    pts = np.asarray(points)
    ids = np.asarray(part_id)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] == 0:
        raise InputError(f"points: expected a non-empty (N, 3) array, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise InputError("points: contains NaN or infinite values")
    if ids.shape != (pts.shape[0],) or not np.issubdtype(ids.dtype, np.integer):
        raise InputError(
            f"part_id: expected ({pts.shape[0]},) integers, got {ids.dtype} {ids.shape}"
        )
    if ids.min() < 0:
        raise InputError("part_id: expected ids >= 0")
    num_parts = int(ids.max()) + 1
    counts = np.bincount(ids, minlength=num_parts)
    if np.any(counts == 0):
        missing = np.flatnonzero(counts == 0).tolist()
        raise InputError(
            f"part_id: ids must cover 0..{num_parts - 1}; parts {missing} have no points"
        )
    return num_parts


def _pair_contact(
    small: NDArray[np.float64], tree: cKDTree, threshold: float
) -> tuple[float, NDArray[np.float64]] | None:
    """Minimum distance and contact point between `small` and the points of `tree`,
    or None when no point pair is closer than `threshold`."""
    distance, index = tree.query(small, k=1, distance_upper_bound=threshold)
    close = np.isfinite(distance)
    if not np.any(close):
        return None
    midpoints = 0.5 * (small[close] + tree.data[index[close]])
    return float(distance[close].min()), midpoints.mean(axis=0)


def _resample(
    points: NDArray[np.float64], count: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """`count` points drawn from `points` without replacement when possible."""
    n = points.shape[0]
    index = rng.choice(n, size=count, replace=n < count)
    return points[index]


def build_part_graph(
    points: NDArray[np.floating],
    part_id: NDArray[np.integer],
    rng: np.random.Generator,
    cfg: PartGraphConfig | None = None,
) -> PartGraph:
    """The overcomplete part graph of a segmented point cloud (section 4.4.1).

    points: (N, 3) metres. part_id: (N,) ints 0..P-1. rng draws the node resampling.
    """
    cfg = cfg or PartGraphConfig()
    if cfg.contact_threshold <= 0 or cfg.points_per_node < 1:
        raise InputError("graph config: contact_threshold and points_per_node must be positive")
    num_parts = check_segmented_cloud(points, part_id)
    pts = np.asarray(points, dtype=np.float64)
    ids = np.asarray(part_id, dtype=np.int64)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    center = 0.5 * (lo + hi)
    scale = max(float(np.linalg.norm(pts - center, axis=1).max()), 1e-6)

    order = np.argsort(ids, kind="stable")
    bounds = np.searchsorted(ids[order], np.arange(num_parts + 1))
    parts = [pts[order[bounds[p] : bounds[p + 1]]] for p in range(num_parts)]
    counts = np.array([len(p) for p in parts], dtype=np.int64)
    centroids = np.stack([p.mean(axis=0) for p in parts])
    box_lo = np.stack([p.min(axis=0) for p in parts])
    box_hi = np.stack([p.max(axis=0) for p in parts])
    trees: dict[int, cKDTree] = {}

    edges: list[tuple[int, int]] = []
    distances: list[float] = []
    contacts: list[NDArray[np.float64]] = []
    threshold = cfg.contact_threshold
    for i in range(num_parts):
        for j in range(i + 1, num_parts):
            gap = np.maximum(box_lo[i] - box_hi[j], box_lo[j] - box_hi[i]).clip(min=0.0)
            if float(np.linalg.norm(gap)) >= threshold:
                continue
            small, large = (i, j) if counts[i] <= counts[j] else (j, i)
            if large not in trees:
                trees[large] = cKDTree(parts[large])
            found = _pair_contact(parts[small], trees[large], threshold)
            if found is not None:
                edges.append((i, j))
                distances.append(found[0])
                contacts.append(found[1])

    edge_array = np.array(edges, dtype=np.int64).reshape(-1, 2)
    edge_features = np.zeros((len(edges), len(EDGE_FEATURES)), dtype=np.float32)
    if edges:
        first, second = centroids[edge_array[:, 0]], centroids[edge_array[:, 1]]
        contact = np.stack(contacts)
        edge_features[:, 0] = np.asarray(distances) / scale
        edge_features[:, 1:4] = (second - first) / scale
        edge_features[:, 4:7] = (contact - first) / scale
        edge_features[:, 7:10] = (contact - second) / scale

    node_points = np.stack(
        [(_resample(p, cfg.points_per_node, rng) - center) / scale for p in parts]
    )
    node_features = np.concatenate(
        [(centroids - center) / scale, (box_hi - box_lo) / scale, (counts / len(pts))[:, None]],
        axis=1,
    )
    return PartGraph(
        node_points=node_points.astype(np.float32),
        node_features=node_features.astype(np.float32),
        edges=edge_array,
        edge_features=edge_features,
        min_distance=np.asarray(distances, dtype=np.float64),
        centroids=centroids,
        point_counts=counts,
        center=center,
        scale=scale,
    )


def graph_labels(graph: PartGraph, tree: KinematicTree) -> GraphLabels:
    """Training targets of `graph` from the ground-truth `tree` over the same parts."""
    if tree.num_parts != graph.num_parts:
        raise ValueError(f"tree has {tree.num_parts} parts, graph has {graph.num_parts}")
    directed = set(tree.edges)
    exists = np.zeros(graph.num_edges, dtype=bool)
    parent_first = np.zeros(graph.num_edges, dtype=bool)
    for e, (a, b) in enumerate(graph.edges.tolist()):
        exists[e] = (a, b) in directed or (b, a) in directed
        parent_first[e] = (a, b) in directed
    candidates = {(int(a), int(b)) for a, b in graph.edges.tolist()}
    uncovered = tuple(e for e in tree.edges if (min(e), max(e)) not in candidates)
    return GraphLabels(
        motion_type=np.asarray(tree.motion_types, dtype=np.int64),
        exists=exists,
        parent_first=parent_first,
        root=tree.root,
        uncovered=uncovered,
    )
