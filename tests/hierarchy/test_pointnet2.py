"""PointNet++ operations: sampling, ball query, grouping, set abstraction, propagation."""

from __future__ import annotations

import numpy as np
import torch

from artic.hierarchy.pointnet2 import (
    FeaturePropagation,
    PointNet2,
    PointNet2Config,
    PointSet,
    SetAbstraction,
    SetAbstractionSpec,
    ball_query,
    farthest_point_indices,
    farthest_point_sample,
    gather_points,
    group,
    three_nn_interpolate,
)


def _cloud(b: int, n: int, seed: int) -> torch.Tensor:
    return torch.rand(b, n, 3, generator=torch.Generator().manual_seed(seed)) * 2 - 1


def _coverage(points: torch.Tensor, index: torch.Tensor) -> float:
    """Largest distance from a point to its nearest sample (smaller covers better)."""
    return float(torch.cdist(points, points[index]).amin(dim=1).amax())


def test_fps_distinct_and_covers_better_than_random() -> None:
    x = _cloud(2, 1000, 0)
    idx = farthest_point_sample(x, 64)
    assert idx.shape == (2, 64) and idx.dtype == torch.int64
    for b in range(2):
        assert len(set(idx[b].tolist())) == 64
        fps_cover = _coverage(x[b], idx[b])
        g = torch.Generator().manual_seed(b)
        random_cover = min(
            _coverage(x[b], torch.randperm(1000, generator=g)[:64]) for _ in range(10)
        )
        assert fps_cover < 0.8 * random_cover


def test_fps_starts_where_told_and_is_deterministic() -> None:
    x = _cloud(3, 200, 1)
    assert (farthest_point_sample(x, 10)[:, 0] == 0).all()
    assert (farthest_point_sample(x, 10, start=7)[:, 0] == 7).all()
    start = torch.tensor([3, 4, 5])
    assert farthest_point_sample(x, 10, start=start)[:, 0].tolist() == [3, 4, 5]
    a = farthest_point_sample(x, 10, generator=torch.Generator().manual_seed(5))
    b = farthest_point_sample(x, 10, generator=torch.Generator().manual_seed(5))
    assert torch.equal(a, b)
    # the second sample is the point farthest from the first
    d = (x[0] - x[0, 0]).norm(dim=-1)
    assert int(farthest_point_sample(x, 2)[0, 1]) == int(d.argmax())


def test_fps_numpy_matches_torch() -> None:
    x = _cloud(1, 500, 2)
    expected = farthest_point_sample(x, 50, start=3)[0].numpy()
    np.testing.assert_array_equal(farthest_point_indices(x[0].numpy(), 50, start=3), expected)


def test_ball_query_respects_radius_and_pads_with_first() -> None:
    x = _cloud(2, 300, 3)
    centroids = gather_points(x, farthest_point_sample(x, 16))
    radius = 0.3
    idx = ball_query(x, centroids, radius, 8)
    assert idx.shape == (2, 16, 8)
    neighbours = gather_points(x, idx)
    assert ((neighbours - centroids.unsqueeze(2)).norm(dim=-1) <= radius + 1e-5).all()
    d = torch.cdist(centroids, x)
    for b in range(2):
        for s in range(16):
            inside = torch.nonzero(d[b, s] <= radius).flatten()
            expected = inside[:8].tolist()
            expected += [expected[0]] * (8 - len(expected))
            assert idx[b, s].tolist() == expected


def test_ball_query_without_neighbours_takes_nearest_and_pads_small_sets() -> None:
    x = torch.tensor([[[0.0, 0, 0], [1.0, 0, 0]]])
    idx = ball_query(x, torch.tensor([[[0.9, 0.0, 0.0]]]), 0.01, 4)
    assert idx.tolist() == [[[1, 1, 1, 1]]]


def test_group_is_relative_and_keeps_features() -> None:
    x = _cloud(2, 50, 4)
    feats = torch.arange(2 * 50 * 2, dtype=torch.float32).reshape(2, 50, 2)
    centre_idx = farthest_point_sample(x, 5)
    centroids = gather_points(x, centre_idx)
    idx = ball_query(x, centroids, 0.5, 6)
    grouped = group(PointSet(x, feats), centroids, idx)
    assert grouped.shape == (2, 5, 6, 5)
    torch.testing.assert_close(grouped[..., :3] + centroids.unsqueeze(2), gather_points(x, idx))
    torch.testing.assert_close(grouped[..., 3:], gather_points(feats, idx))


def test_three_nn_interpolation_is_exact_at_sparse_points_and_convex() -> None:
    dense = _cloud(1, 40, 5)
    sparse_xyz = dense[:, :10]
    feats = torch.rand(1, 10, 3, generator=torch.Generator().manual_seed(6))
    out = three_nn_interpolate(dense, PointSet(sparse_xyz, feats))
    assert out.shape == (1, 40, 3)
    torch.testing.assert_close(out[:, :10], feats, atol=1e-5, rtol=1e-5)
    assert (out >= feats.amin(1, keepdim=True) - 1e-6).all()
    assert (out <= feats.amax(1, keepdim=True) + 1e-6).all()


def test_set_abstraction_and_propagation_shapes() -> None:
    torch.manual_seed(0)
    x = _cloud(2, 128, 7)
    feats = torch.rand(2, 128, 4)
    sa = SetAbstraction(SetAbstractionSpec(32, 0.4, 8, (16, 24)), in_channels=4)
    level = sa(PointSet(x, feats))
    assert level.xyz.shape == (2, 32, 3) and level.features is not None
    assert level.features.shape == (2, 32, 24)
    top = SetAbstraction(SetAbstractionSpec(None, 0.0, 0, (32,)), in_channels=24)(level)
    assert top.xyz.shape == (2, 1, 3) and top.features is not None
    assert top.features.shape == (2, 1, 32)
    fp = FeaturePropagation(4 + 24, (20,))
    assert fp(PointSet(x, feats), level).shape == (2, 128, 20)
    fp_top = FeaturePropagation(24 + 32, (8,))
    assert fp_top(level, top).shape == (2, 32, 8)


def test_backbone_shapes_and_gradients() -> None:
    torch.manual_seed(0)
    config = PointNet2Config().scaled(0.125)
    net = PointNet2(config)
    x = _cloud(2, 512, 8)
    out = net(x)
    assert out.point_features.shape == (2, 512, net.out_channels)
    assert out.global_features.shape == (2, net.global_channels)
    assert net.out_channels == config.propagations[-1][-1]
    out.point_features.sum().backward()
    assert all(p.grad is not None for p in net.parameters())


def test_backbone_handles_fewer_points_than_centroids() -> None:
    torch.manual_seed(0)
    net = PointNet2(PointNet2Config().scaled(0.125)).eval()
    with torch.no_grad():
        out = net(_cloud(1, 20, 9))
    assert out.point_features.shape[:2] == (1, 20)
    assert torch.isfinite(out.point_features).all()
