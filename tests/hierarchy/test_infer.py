"""artic.hierarchy.infer: scan -> segmentation -> part graph -> labelling -> tree -> axes."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from artic.errors import InputError
from artic.hierarchy.gnn import GraphLabellingNet, GraphNetConfig
from artic.hierarchy.infer import (
    HierarchyConfig,
    build_hierarchy,
    infer_hierarchy,
    part_motion,
    required_points,
    subsample,
)
from artic.hierarchy.segmentation import InferenceConfig, PartSegmentationNet, SegmentationConfig
from box_clouds import box_cloud


@pytest.fixture(scope="module")
def nets() -> tuple[PartSegmentationNet, GraphLabellingNet]:
    torch.set_num_threads(1)
    torch.manual_seed(0)
    segmenter = PartSegmentationNet(SegmentationConfig().scaled(0.125)).eval()
    cfg = GraphNetConfig(encoder_widths=(8, 16), decoder_points=16, hidden=8, head_hidden=8)
    return segmenter, GraphLabellingNet(cfg).eval()


CFG = HierarchyConfig(segmentation=InferenceConfig(n_points=256))


def test_build_hierarchy_tree_axes_and_edge_probabilities(nets):
    points, part = box_cloud(1500)
    h = build_hierarchy(points, part, nets[1], CFG, np.random.default_rng(0))
    tree = h.tree
    assert tree.num_parts == 3 and len(tree.edges) == 2
    assert tree.axes is not None
    for axis, joint_type in zip(tree.axes, tree.joint_types, strict=True):
        assert (axis is None) == (joint_type == "fixed")
    assert h.edge_exists.shape == h.edge_direction.shape == (2,)
    assert h.root_probability.shape == (3,) and abs(h.root_probability.sum() - 1) < 1e-9
    assert tree.root == int(np.argmax(h.root_probability))
    assert tree.motion_types == tuple(int(m) for m in h.motion_probability.argmax(1))
    edges = h.labelling.edges.tolist()
    for k, (a, b) in enumerate(tree.edges):  # the boxes touch: every tree edge is a candidate
        assert h.candidate_tree_edges[k]
        e = edges.index([min(a, b), max(a, b)])
        assert h.edge_exists[k] == h.labelling.exists[e]
        first = h.labelling.parent_first[e]
        assert h.edge_direction[k] == pytest.approx(first if a < b else 1 - first)
    assert set(h.timings) == {"graph", "labelling", "tree", "joints"}


def test_infer_hierarchy_labels_every_input_point_in_order(nets):
    points, _ = box_cloud(1000)
    result = infer_hierarchy(points, *nets, CFG, np.random.default_rng(0))
    seg = result.segmentation
    p = result.num_parts
    assert seg.part_id.shape == seg.motion_type.shape == (1000,)
    assert seg.motion_prob.shape == (1000, 4) and seg.part_confidence.shape == (p,)
    assert set(np.unique(seg.part_id)) == set(range(p))
    assert np.array_equal(seg.sampled, np.arange(1000))
    assert result.tree.num_parts == p
    assert {"segment", "graph", "labelling", "tree", "joints", "total"} <= set(result.timings)


def test_large_clouds_work_on_a_subset_and_label_all_points(nets):
    points, _ = box_cloud(3000, seed=2)
    cfg = HierarchyConfig(segmentation=InferenceConfig(n_points=256), max_points=800)
    result = infer_hierarchy(points, *nets, cfg, np.random.default_rng(0))
    seg = result.segmentation
    assert seg.sampled.shape == (800,) and np.all(np.diff(seg.sampled) > 0)
    assert seg.part_id.shape == (3000,)
    assert int(result.hierarchy.graph.point_counts.sum()) == 800


def test_same_seed_same_result(nets):
    points, _ = box_cloud(1200, seed=4)
    a = infer_hierarchy(points, *nets, CFG, np.random.default_rng(7))
    b = infer_hierarchy(points, *nets, CFG, np.random.default_rng(7))
    assert np.array_equal(a.part_id, b.part_id)
    assert a.tree.to_json() == b.tree.to_json()
    assert np.array_equal(a.hierarchy.labelling.motion, b.hierarchy.labelling.motion)


def test_bad_input_raises_input_error(nets):
    points, part = box_cloud(600)
    bad = points.copy()
    bad[5, 0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        infer_hierarchy(bad, *nets, CFG)
    with pytest.raises(InputError, match=r"\(N, 3\)"):
        infer_hierarchy(points[:, :2], *nets, CFG)
    with pytest.raises(InputError, match="parts"):
        build_hierarchy(points, np.where(part == 1, 2, part), nets[1], CFG)  # part 1 empty
    with pytest.raises(InputError, match="max_points"):
        subsample(10, 0, np.random.default_rng(0))


def test_required_points_and_subsample():
    assert required_points(PartSegmentationNet()) == 512
    idx = subsample(1000, 100, np.random.default_rng(0))
    assert idx.shape == (100,) and len(np.unique(idx)) == 100 and np.all(np.diff(idx) > 0)
    assert np.array_equal(subsample(50, 100, np.random.default_rng(0)), np.arange(50))


def test_part_motion_multiplies_the_two_views_of_each_part():
    """A part the labeller is unsure of takes the type its points agree on; a part whose
    points are split follows the labeller; rows are distributions."""
    labelled = np.array([[0.9, 0.05, 0.05, 0.0], [0.1, 0.45, 0.4, 0.05], [0.1, 0.6, 0.3, 0.0]])
    part_id = np.array([0, 0, 1, 1, 1, 2, 2])
    points = np.array([
        [1, 0, 0, 0], [1, 0, 0, 0],  # part 0: static
        [0, 0, 1, 0], [0, 0, 1, 0], [0, 0.2, 0.8, 0],  # part 1: translating
        [0, 0.5, 0.5, 0], [0, 0.5, 0.5, 0],  # part 2: undecided
    ], dtype=float)  # fmt: skip
    motion = part_motion(labelled, part_id, points)
    np.testing.assert_allclose(motion.sum(1), 1.0)
    assert motion.argmax(1).tolist() == [0, 2, 1]
    assert labelled.argmax(1).tolist() == [0, 1, 1]
    # no common type: the labeller's own probabilities
    disjoint = part_motion(labelled[:1] * [0, 1, 1, 1] / 0.1, np.zeros(2, int), points[:2])
    np.testing.assert_allclose(disjoint, labelled[:1] * [0, 1, 1, 1] / 0.1)
