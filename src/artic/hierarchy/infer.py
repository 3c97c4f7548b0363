"""Scan to kinematic hierarchy, end to end (thesis section 4.2, Fig. 4.2), as pure functions.

`infer_hierarchy(points, segmenter, labeller, cfg, rng)`:
0. (cfg.yaw "canonical", the default) the scan's yaw is estimated from its dominant
   vertical planes and front (`canonical.canonical_yaw`) and the scan turned into the
   object frame (front towards -x), where the networks work; the tree's axes and the
   part centroids are turned back into the scan's frame at the end;
1. (large clouds) a seeded random subset of `cfg.max_points` points is what the networks
   and the geometry see; every input point gets the labels of its nearest kept point;
2. part segmentation with motion types (section 4.3, `segmentation.segment`);
3. `build_hierarchy` on the segmented cloud:
   a. the overcomplete part graph (section 4.4.1, `graph.build_part_graph`);
   b. graph labelling (section 4.4.2, `gnn.predict`): motion type per part, existence
      and direction per candidate edge, root probability per part;
   c. the tree: Prim's minimum spanning tree over the negative log-probabilities, grown
      from the most probable root (section 4.2.3, `tree.extract_tree`);
   d. joint axes from the parts' points (`joints.estimate_axes`; section 4.5.3's
      heuristic or the default geometric one).

Results are records with the time each step took (seconds, `time.perf_counter`). Part
labels are returned for every input point, in input order. No file access here: the
commands in `artic.hierarchy.commands` read the scan (`artifacts.scan_file`) and write
the outputs (`hierarchy.report`, `artifacts.scan_outputs`).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from artic.errors import InputError
from artic.hierarchy.canonical import (
    YawConfig,
    YawEstimate,
    canonical_yaw,
    rotate_tree_z,
    rotate_z,
)
from artic.hierarchy.gnn import Labeller
from artic.hierarchy.gnn import predict as label_graph
from artic.hierarchy.graph import PartGraphConfig, build_part_graph, check_segmented_cloud
from artic.hierarchy.joints import JointHeuristicConfig, estimate_axes
from artic.hierarchy.segmentation import (
    InferenceConfig,
    PartSegmentationNet,
    nearest_sample,
    segment,
)
from artic.hierarchy.tree import extract_tree
from artic.hierarchy.types import PartGraph
from artic.objects.tree import GraphLabelling, KinematicTree

#: clouds above this many points are subsampled before segmentation (see the module doc)
MAX_POINTS = 200_000


@dataclass(frozen=True)
class HierarchyConfig:
    """How a scan becomes a hierarchy.

    segmentation: the segmenter's inference settings (points it sees, mask merging); use
    the ones it was trained with (`models.load_segmenter(...).inference`). graph: the
    part-graph settings the labeller was trained with (`load_labeller(...).graph`).
    joints: the joint-axis heuristic. max_points: clouds with more points are subsampled
    (seeded, without replacement) before segmentation; labels go back to every point.
    estimate_axes: False leaves the tree's axes None (the metrics of Table 4.2 do not
    use them). yaw: "canonical" (default): the scan's front may face any direction;
    `segment_scan` and `infer_hierarchy` estimate its yaw (`canonical.canonical_yaw`),
    work in the object frame (front towards -x) and return axes and centroids in the
    scan's frame; "none": the scan is already in the object frame. yaw_settings: the yaw
    step's (`canonical.yaw_config(category)` for the models' category). motion_evidence:
    "both" (default): where the segmenter's per-point motion types are at hand, a part's
    motion type is the most probable under the product of the labeller's probabilities and
    the mean of its points' (`part_motion`); "labeller": the labeller's alone (the thesis).
    """

    segmentation: InferenceConfig = field(default_factory=InferenceConfig)
    graph: PartGraphConfig = field(default_factory=PartGraphConfig)
    joints: JointHeuristicConfig = field(default_factory=JointHeuristicConfig)
    max_points: int = MAX_POINTS
    estimate_axes: bool = True
    yaw: Literal["canonical", "none"] = "canonical"
    motion_evidence: Literal["labeller", "both"] = "both"
    yaw_settings: YawConfig = field(default_factory=YawConfig)


@dataclass(frozen=True)
class LabelledHierarchy:
    """A kinematic tree inferred from a segmented cloud (sections 4.4 and 4.2.3).

    tree: the KinematicTree over parts 0..P-1, with joint types and axes (None for fixed
    joints; `axes` is None when cfg.estimate_axes is False). graph: the candidate part
    graph. labelling: the network's probabilities on it (per part: motion (P, 4), root
    (P,); per candidate edge: exists (E,), parent_first (E,)). edge_exists: (P-1,)
    p(edge exists) of each tree edge, in `tree.edges` order. edge_direction: (P-1,)
    p(parent -> child) of each tree edge. Both are NaN for an edge Prim had to add
    outside the candidate graph (parts farther apart than the contact threshold).
    timings: seconds per step (graph, labelling, tree, joints).
    """

    tree: KinematicTree
    graph: PartGraph
    labelling: GraphLabelling
    edge_exists: NDArray[np.float64]
    edge_direction: NDArray[np.float64]
    timings: dict[str, float]

    @property
    def root_probability(self) -> NDArray[np.float64]:
        """(P,) p(part is the root), sums to one."""
        return self.labelling.root

    @property
    def motion_probability(self) -> NDArray[np.float64]:
        """(P, 4) motion-type probabilities of each part (MOTION_TYPES order)."""
        return self.labelling.motion

    @property
    def candidate_tree_edges(self) -> NDArray[np.bool_]:
        """(P-1,) whether each tree edge is a candidate edge of the part graph."""
        return np.isfinite(self.edge_exists)


@dataclass(frozen=True)
class ScanSegmentation:
    """Parts and motion types of every point of a scan of N points (section 4.3).

    part_id: (N,) int64 in 0..P-1, one per input point, input order (parts ordered by
    decreasing size in the segmented subset). motion_type: (N,) int64, the segmenter's
    per-point motion type (index into MOTION_TYPES); motion_prob: (N, 4) float32.
    part_confidence: (P,) float32, the segmenter's predicted IoU of each part.
    sampled: (M,) int64 sorted indices of the input points the networks worked on (all N
    when N <= cfg.max_points). timings: seconds (yaw, subsample, segment, upsample). yaw:
    the estimated yaw of the scan (None when cfg.yaw is "none").
    """

    part_id: NDArray[np.int64]
    motion_type: NDArray[np.int64]
    motion_prob: NDArray[np.float32]
    part_confidence: NDArray[np.float32]
    sampled: NDArray[np.int64]
    timings: dict[str, float]
    yaw: YawEstimate | None = None

    @property
    def num_parts(self) -> int:
        return int(self.part_confidence.shape[0])


@dataclass(frozen=True)
class HierarchyResult:
    """Everything `infer_hierarchy` found in one scan of N points.

    segmentation: per-point parts (N,) and motion types, per-part confidences.
    hierarchy: the KinematicTree (joint types and axes) over the same parts, with the
    graph network's probabilities (part-level motion types come from the graph network;
    it saw the points `segmentation.sampled`), its axes and part centroids in the scan's
    frame (the graph's normalised node and edge features are the networks' input, in the
    object frame). timings: seconds per step (yaw, subsample, segment, upsample, graph,
    labelling, tree, joints, total). yaw: the scan's estimated yaw (None for cfg.yaw
    "none"); `canonical.rotate_z(points, -yaw.yaw)` is what the networks saw.
    """

    segmentation: ScanSegmentation
    hierarchy: LabelledHierarchy
    timings: dict[str, float]

    @property
    def yaw(self) -> YawEstimate | None:
        return self.segmentation.yaw

    @property
    def part_id(self) -> NDArray[np.int64]:
        """(N,) part of every input point, input order."""
        return self.segmentation.part_id

    @property
    def tree(self) -> KinematicTree:
        return self.hierarchy.tree

    @property
    def num_parts(self) -> int:
        return self.hierarchy.tree.num_parts


def required_points(segmenter: PartSegmentationNet) -> int:
    """The fewest points a scan needs for `segmenter`: the centroids its first set
    abstraction samples (512 for the default PointNet++); fewer would repeat points."""
    counts = [s.n_centroids for s in segmenter.config.backbone.set_abstractions]
    return max([c for c in counts if c is not None] or [1])


def _check_points(points: NDArray[np.floating]) -> NDArray[np.float32]:
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise InputError(f"points: expected a non-empty (N, 3) array, got shape {pts.shape}")
    if not np.isfinite(pts).all():
        raise InputError("points: NaN or infinite coordinates")
    return pts.astype(np.float32)


def _object_frame(points: NDArray[np.float32], yaw: YawEstimate | None) -> NDArray[np.float32]:
    """(N, 3) float32: the scan turned into the object frame (unchanged for yaw None)."""
    return points if yaw is None else rotate_z(points, -yaw.yaw).astype(np.float32)


def _scan_frame(hierarchy: LabelledHierarchy, yaw: YawEstimate | None) -> LabelledHierarchy:
    """A hierarchy found in the object frame with its axes, part centroids and centre
    turned back into the scan's frame (unchanged for yaw None)."""
    if yaw is None:
        return hierarchy
    graph = dataclasses.replace(
        hierarchy.graph,
        centroids=rotate_z(hierarchy.graph.centroids, yaw.yaw),
        center=rotate_z(hierarchy.graph.center, yaw.yaw),
    )
    tree = rotate_tree_z(hierarchy.tree, yaw.yaw)
    return dataclasses.replace(hierarchy, tree=tree, graph=graph)


def subsample(n: int, max_points: int, rng: np.random.Generator) -> NDArray[np.int64]:
    """Sorted indices of at most `max_points` of `n` points (a seeded subset without
    replacement; all of them when n <= max_points)."""
    if max_points < 1:
        raise InputError(f"max_points: expected >= 1, got {max_points}")
    if n <= max_points:
        return np.arange(n, dtype=np.int64)
    return np.sort(rng.choice(n, size=max_points, replace=False)).astype(np.int64)


def _tree_edge_probabilities(
    tree: KinematicTree, labelling: GraphLabelling
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(P-1,) p(exists) and p(parent -> child) of each tree edge (NaN if not a candidate)."""
    index = {(int(a), int(b)): e for e, (a, b) in enumerate(labelling.edges.tolist())}
    exists = np.full(len(tree.edges), np.nan)
    direction = np.full(len(tree.edges), np.nan)
    for k, (parent, child) in enumerate(tree.edges):
        e = index.get((min(parent, child), max(parent, child)))
        if e is None:
            continue
        exists[k] = labelling.exists[e]
        first = labelling.parent_first[e]
        direction[k] = first if parent < child else 1.0 - first
    return exists, direction


def part_motion(
    labelled: NDArray[np.floating],
    part_id: NDArray[np.integer],
    motion_prob: NDArray[np.floating],
) -> NDArray[np.float64]:
    """Motion-type probabilities of P parts from two views: the labeller's (P, T), from the
    part's shape in its graph, and the mean of the segmenter's per-point probabilities
    (N, T) over the part's points (part_id (N,) in 0..P-1); each part's product, normalised
    (the labeller's alone where the product vanishes)."""
    lab = np.asarray(labelled, dtype=np.float64)
    ids = np.asarray(part_id, dtype=np.int64)
    sums = np.zeros_like(lab)
    np.add.at(sums, ids, np.asarray(motion_prob, dtype=np.float64))
    mean = sums / np.maximum(np.bincount(ids, minlength=len(lab)), 1)[:, None]
    product = lab * mean
    total = product.sum(1, keepdims=True)
    return np.where(total > 0, product / np.where(total > 0, total, 1.0), lab)


def build_hierarchy(
    points: NDArray[np.floating],
    part_id: NDArray[np.integer],
    labeller: Labeller,
    cfg: HierarchyConfig | None = None,
    rng: np.random.Generator | None = None,
    motion_prob: NDArray[np.floating] | None = None,
) -> LabelledHierarchy:
    """Kinematic tree of an already segmented cloud (sections 4.4, 4.2.3 and 4.5.3).

    points: (N, 3) metres, object frame, z up. part_id: (N,) ints covering 0..P-1, every
    part non-empty (InputError otherwise). labeller: the graph labelling network.
    rng: draws the per-part point resampling of the graph nodes (default: seed 0).
    motion_prob: (N, 4) the segmenter's motion-type probabilities of the points, the
    second view of each part's motion type with cfg.motion_evidence "both" (`part_motion`).
    """
    cfg = cfg or HierarchyConfig()
    rng = rng if rng is not None else np.random.default_rng(0)
    check_segmented_cloud(points, part_id)
    pts = np.asarray(points, dtype=np.float64)
    ids = np.asarray(part_id, dtype=np.int64)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    graph = build_part_graph(pts, ids, rng, cfg.graph)
    t1 = time.perf_counter()
    import torch  # loaded already: the networks are torch modules

    # TorchScript's profiling executor spends a compiled labeller's first two calls
    # profiling and optimising its graph (0.29 and 0.16 s on the office chair's, the
    # commands' only call), which then takes 8 ms, as it does unoptimised: the same outputs
    with torch.jit.optimized_execution(False):
        labelling = label_graph(labeller, graph)
    if motion_prob is not None and cfg.motion_evidence == "both":
        motion = part_motion(labelling.motion, ids, motion_prob)
        labelling = dataclasses.replace(labelling, motion=motion)
    t2 = time.perf_counter()
    tree = extract_tree(labelling, graph.centroids)
    t3 = time.perf_counter()
    if cfg.estimate_axes:
        tree = estimate_axes(tree, pts, ids, cfg.joints)
    t4 = time.perf_counter()
    timings.update(graph=t1 - t0, labelling=t2 - t1, tree=t3 - t2, joints=t4 - t3)
    exists, direction = _tree_edge_probabilities(tree, labelling)
    return LabelledHierarchy(tree, graph, labelling, exists, direction, timings)


def segment_scan(
    points: NDArray[np.floating],
    segmenter: PartSegmentationNet,
    cfg: HierarchyConfig | None = None,
    rng: np.random.Generator | None = None,
) -> ScanSegmentation:
    """Parts and motion types of every point of a scan (section 4.3; module doc, 1-2).

    points: (N, 3) float, metres, z up; finite (InputError otherwise); in the object frame
    for cfg.yaw "none", else facing any direction (its yaw is estimated first). rng: the
    subsample of clouds larger than cfg.max_points (default seed 0).
    """
    cfg = cfg or HierarchyConfig()
    rng = rng if rng is not None else np.random.default_rng(0)
    t_start = time.perf_counter()
    pts = _check_points(points)
    yaw = canonical_yaw(pts, cfg.yaw_settings) if cfg.yaw == "canonical" else None
    pts = _object_frame(pts, yaw)
    t_yaw = time.perf_counter()
    sampled = subsample(len(pts), cfg.max_points, rng)
    work = pts[sampled]
    t0 = time.perf_counter()
    seg = segment(segmenter, work, cfg.segmentation)
    t1 = time.perf_counter()
    if len(sampled) < len(pts):
        nearest = nearest_sample(work, pts)
        nearest[sampled] = np.arange(len(sampled))  # a kept point keeps its own labels
        part_id, motion_type = seg.part_id[nearest], seg.motion_type[nearest]
        motion_prob = seg.motion_prob[nearest]
    else:
        part_id, motion_type, motion_prob = seg.part_id, seg.motion_type, seg.motion_prob
    t2 = time.perf_counter()
    return ScanSegmentation(
        part_id=np.asarray(part_id, dtype=np.int64),
        motion_type=np.asarray(motion_type, dtype=np.int64),
        motion_prob=np.asarray(motion_prob, dtype=np.float32),
        part_confidence=np.asarray(seg.part_confidence, dtype=np.float32),
        sampled=sampled,
        timings={
            "yaw": t_yaw - t_start,
            "subsample": t0 - t_yaw,
            "segment": t1 - t0,
            "upsample": t2 - t1,
        },
        yaw=yaw,
    )


def infer_hierarchy(
    points: NDArray[np.floating],
    segmenter: PartSegmentationNet,
    labeller: Labeller,
    cfg: HierarchyConfig | None = None,
    rng: np.random.Generator | None = None,
) -> HierarchyResult:
    """Segment a scan and infer its kinematic hierarchy (Fig. 4.2 (a)-(c)).

    points: (N, 3) float, metres, z up; finite (InputError otherwise); in the object frame
    (front towards -x) for cfg.yaw "none", else facing any direction: the yaw is
    estimated, the networks work in the object frame and the tree's axes come back in
    the scan's frame. segmenter / labeller: the section 4.3 and 4.4 networks (evaluation
    mode is set). rng: the subsample of large clouds and the graph's node resampling
    (default seed 0); the same inputs and seed give the same result (timings aside).
    """
    cfg = cfg or HierarchyConfig()
    rng = rng if rng is not None else np.random.default_rng(0)
    t0 = time.perf_counter()
    seg = segment_scan(points, segmenter, cfg, rng)
    work = _object_frame(_check_points(points), seg.yaw)[seg.sampled]
    part_id, motion_prob = seg.part_id[seg.sampled], seg.motion_prob[seg.sampled]
    hierarchy = build_hierarchy(work, part_id, labeller, cfg, rng, motion_prob)
    hierarchy = _scan_frame(hierarchy, seg.yaw)
    timings = {**seg.timings, **hierarchy.timings, "total": time.perf_counter() - t0}
    return HierarchyResult(seg, hierarchy, timings)
