"""Training helpers of Chapter 4: cloud preparation, augmentation, tree restriction."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from artic.hierarchy.fit_labeller import (
    make_example,
    make_predicted_example,
    predicted_parts_tree,
    restrict_tree,
)
from artic.hierarchy.fit_segmenter import AugmentConfig, augment, prepare_cloud
from artic.hierarchy.graph import PartGraphConfig
from artic.hierarchy.pointnet2 import farthest_point_indices
from artic.hierarchy.segmentation import SegmentationBatch
from artic.objects.tree import KinematicTree

#: body 0 -> door 1 -> handle 2; body 0 -> drawer 3 -> handle 4
TREE = KinematicTree(
    num_parts=5,
    root=0,
    edges=((0, 1), (0, 3), (1, 2), (3, 4)),
    motion_types=(0, 1, 0, 2, 0),
    joint_types=("revolute", "prismatic", "fixed", "fixed"),
)


def test_prepare_cloud_matches_segment_downsampling() -> None:
    rng = np.random.default_rng(0)
    points = rng.normal(size=(500, 3))
    part = rng.integers(0, 3, 500)
    motion = part % 2
    out = prepare_cloud(points, part, motion, 64, np.random.default_rng(1))
    index = farthest_point_indices(points.astype(np.float32), 64)
    assert np.array_equal(out.points, points[index].astype(np.float32))
    assert np.array_equal(out.part_id, part[index]) and np.array_equal(
        out.motion_type, motion[index]
    )
    small = prepare_cloud(points[:10], part[:10], motion[:10], 64, np.random.default_rng(1))
    assert small.points.shape == (64, 3)
    assert np.array_equal(small.points[:10], points[:10].astype(np.float32))


def test_augment_rotates_about_z_and_is_seeded() -> None:
    points = torch.randn(3, 50, 3)
    normals = torch.nn.functional.normalize(torch.randn(3, 50, 3), dim=-1)
    batch = SegmentationBatch(
        points, torch.zeros(3, 50, dtype=torch.long), torch.zeros(3, 50), normals
    )

    def run(cfg: AugmentConfig, seed: int = 0) -> SegmentationBatch:
        return augment(batch, cfg, torch.Generator().manual_seed(seed))

    cfg = AugmentConfig(rotate_z_deg=90.0)
    a, b = run(cfg).points, run(cfg).points
    assert torch.equal(a, b)
    assert torch.allclose(a[..., 2], points[..., 2])
    assert torch.allclose(a[..., :2].norm(dim=-1), points[..., :2].norm(dim=-1), atol=1e-5)
    assert not torch.allclose(a, points)
    rotated = run(cfg)
    assert rotated.normals is not None  # rotated with the points: dot products are kept
    torch.testing.assert_close(
        (rotated.points * rotated.normals).sum(-1), (points * normals).sum(-1), atol=1e-5, rtol=0
    )
    flips = []
    for seed in range(8):
        y = run(AugmentConfig(mirror_y=True), seed).points[..., 1]
        same, negated = (y == points[..., 1]).all(1), (y == -points[..., 1]).all(1)
        assert (same | negated).all()  # each cloud as a whole
        flips += negated.tolist()
    assert 0.25 < np.mean(flips) < 0.75  # about half of them
    mirrored = run(AugmentConfig(mirror_y=True), 0)
    torch.testing.assert_close(mirrored.points[..., 1].abs(), points[..., 1].abs())
    assert mirrored.normals is not None
    torch.testing.assert_close(
        (mirrored.points * mirrored.normals).sum(-1), (points * normals).sum(-1), atol=1e-6, rtol=0
    )
    jitter = run(AugmentConfig(jitter_m=0.01)).points
    assert 0.005 < float((jitter - points).std()) < 0.02
    assert all(x is y for x, y in zip(run(AugmentConfig()), batch, strict=True))
    assert math.isclose(cfg.rotate_z_deg, 90.0)


def test_restrict_tree_contracts_hidden_parts() -> None:
    assert restrict_tree(TREE, range(5)) == TREE
    sub = restrict_tree(TREE, [0, 2, 3])  # door 1 and drawer handle 4 hidden
    assert sub.num_parts == 3 and sub.root == 0
    assert set(sub.edges) == {(0, 1), (0, 2)}  # the door handle hangs from the body now
    assert sub.motion_types == (0, 0, 2)
    assert sub.joint_types[sub.edge_index(0, 1)] == "fixed"
    with pytest.raises(ValueError, match="root"):
        restrict_tree(TREE, [1, 2])


def test_make_example_compacts_part_ids() -> None:
    rng = np.random.default_rng(0)
    offsets = np.array([[0, 0, 0], [0.5, 0, 0], [0.5, 0.3, 0], [0, 0, 0.5], [0, 0, 0.8]])
    part = np.repeat(np.arange(5), 40)
    points = offsets[part] + rng.uniform(-0.2, 0.2, (200, 3))
    keep = part != 1
    example = make_example(
        points[keep],
        part[keep],
        TREE,
        rng,
        PartGraphConfig(contact_threshold=0.1, points_per_node=8),
    )
    assert example is not None
    assert example.graph.num_parts == 4 and example.tree.num_parts == 4
    assert example.labels.motion_type.tolist() == [0, 0, 2, 0]
    only_root = make_example(points[part == 0], part[part == 0], TREE, rng, PartGraphConfig())
    assert only_root is None
    no_root = part != 0
    assert make_example(points[no_root], part[no_root], TREE, rng, PartGraphConfig()) is None


def test_predicted_parts_tree_of_a_perfect_segmentation_is_the_true_tree() -> None:
    part = np.repeat(np.arange(5), 10)
    relabelled = np.array([7, 3, 9, 1, 4])[part]  # any ids, any order
    found = predicted_parts_tree(relabelled, part, TREE)
    assert found is not None
    kept, tree = found
    assert kept.tolist() == [1, 3, 4, 7, 9]
    # node i is predicted part kept[i], i.e. true part [3, 1, 4, 0, 2][i]
    true_of = {1: 3, 3: 1, 4: 4, 7: 0, 9: 2}
    assert tree.root == 3
    mapped = {(true_of[int(kept[p])], true_of[int(kept[c])]) for p, c in tree.edges}
    assert mapped == set(TREE.edges)
    assert [tree.motion_types[i] for i in range(5)] == [
        TREE.motion_types[true_of[int(q)]] for q in kept
    ]


def test_predicted_parts_tree_hangs_fragments_and_contracts_merged_parts() -> None:
    part = np.repeat(np.arange(5), 10)
    predicted = part.copy()
    predicted[:4] = 5  # a small fragment of the body: a fixed, static child of the body
    predicted[part == 2] = 1  # the door's handle merged into the door: handle left out
    predicted[part == 4] = 8
    predicted[40:42] = -9  # two points of the drawer's handle: another fragment of it
    found = predicted_parts_tree(predicted, part, TREE)
    assert found is not None
    kept, tree = found
    node = {int(q): i for i, q in enumerate(kept)}
    assert tree.root == node[0]
    assert (node[0], node[5]) in tree.edges
    assert tree.joint_types[tree.edges.index((node[0], node[5]))] == "fixed"
    assert tree.motion_types[node[5]] == 0
    assert (node[0], node[1]) in tree.edges and (node[3], node[8]) in tree.edges
    assert (node[8], node[-9]) in tree.edges  # the larger piece stands for the handle
    assert kept.tolist() == [-9, 0, 1, 3, 5, 8] and tree.num_parts == 6  # no door handle
    assert predicted_parts_tree(np.zeros(50, dtype=np.int64), part, TREE) is None  # one part


def test_make_predicted_example_labels_the_segmenters_parts() -> None:
    rng = np.random.default_rng(0)
    offsets = np.array([[0, 0, 0], [0.5, 0, 0], [0.5, 0.3, 0], [0, 0, 0.5], [0, 0, 0.8]])
    part = np.repeat(np.arange(5), 40)
    points = offsets[part] + rng.uniform(-0.2, 0.2, (200, 3))
    predicted = part.copy()
    predicted[part == 2] = 1
    cfg = PartGraphConfig(contact_threshold=0.1, points_per_node=8)
    example = make_predicted_example(points, predicted, part, TREE, rng, cfg)
    assert example is not None and example.graph.num_parts == 4 == example.tree.num_parts
    assert example.labels.motion_type.tolist() == [0, 1, 2, 0]
