"""Records of Chapter 4's graph network: part graphs (its input) and graph labels (its
training targets). The kinematic tree and the network's labelling of one
(`KinematicTree`, `GraphLabelling`, `MOTION_TYPES`, `JointType`) are records every
package reads: they live in `artic.objects.tree`. Frozen dataclasses, pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class PartGraph:
    """The overcomplete part graph of a segmented point cloud (section 4.4.1).

    node_points: (P, K, 3) float32, each part's points resampled to K and normalised
    (object centre subtracted, divided by `scale`). node_features: (P, 7) float32,
    normalised centroid (3), normalised bounding-box extent (3), fraction of the points.
    edges: (E, 2) int64 candidate undirected edges, first < second, sorted.
    edge_features: (E, 10) float32, oriented from edges[:, 0] to edges[:, 1] (see
    `graph.EDGE_FEATURES`). min_distance: (E,) float64 metres. centroids: (P, 3)
    float64 metres. point_counts: (P,) int64. center: (3,) metres; scale: metres.
    """

    node_points: NDArray[np.float32]
    node_features: NDArray[np.float32]
    edges: NDArray[np.int64]
    edge_features: NDArray[np.float32]
    min_distance: NDArray[np.float64]
    centroids: NDArray[np.float64]
    point_counts: NDArray[np.int64]
    center: NDArray[np.float64]
    scale: float

    @property
    def num_parts(self) -> int:
        return int(self.node_points.shape[0])

    @property
    def num_edges(self) -> int:
        return int(self.edges.shape[0])


@dataclass(frozen=True)
class GraphLabels:
    """Training targets of a part graph from its ground-truth tree (section 4.4.2).

    motion_type: (P,) int64. exists: (E,) bool, candidate edge is a tree edge.
    parent_first: (E,) bool, edges[e, 0] is the parent (meaningful where exists).
    root: the root part. uncovered: tree edges missing from the candidate graph (the
    threshold was too small for them); the network cannot predict those.
    """

    motion_type: NDArray[np.int64]
    exists: NDArray[np.bool_]
    parent_first: NDArray[np.bool_]
    root: int
    uncovered: tuple[tuple[int, int], ...]
