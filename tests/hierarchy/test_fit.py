"""Training helpers of Chapter 4: cloud preparation, augmentation, tree restriction."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from artic.hierarchy.fit_labeller import make_example, restrict_tree
from artic.hierarchy.fit_segmenter import AugmentConfig, augment, prepare_cloud
from artic.hierarchy.graph import PartGraphConfig
from artic.hierarchy.pointnet2 import farthest_point_indices
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
    cfg = AugmentConfig(rotate_z_deg=90.0)
    a = augment(points, cfg, torch.Generator().manual_seed(0))
    b = augment(points, cfg, torch.Generator().manual_seed(0))
    assert torch.equal(a, b)
    assert torch.allclose(a[..., 2], points[..., 2])
    assert torch.allclose(a[..., :2].norm(dim=-1), points[..., :2].norm(dim=-1), atol=1e-5)
    assert not torch.allclose(a, points)
    jitter = augment(points, AugmentConfig(jitter_m=0.01), torch.Generator().manual_seed(0))
    assert 0.005 < float((jitter - points).std()) < 0.02
    assert torch.equal(augment(points, AugmentConfig(), torch.Generator()), points)
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
