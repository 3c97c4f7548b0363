"""Precomputed PointNet++ neighbourhoods (`BackboneIndex`): the same network outputs and
gradients as neighbourhoods computed inside the forward pass, for a batch's own index and
for single clouds' indices stacked; unchanged by the segmenter's rotation about z."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from artic.hierarchy.config import SegmenterModelConfig
from artic.hierarchy.pointnet2 import (
    BackboneIndex,
    PointNet2,
    PointNet2Config,
    backbone_index,
    stack_indices,
)
from artic.hierarchy.segmentation import normalize_points


def _config(in_channels: int = 0) -> PointNet2Config:
    """A quarter-width backbone with `experiment=ch4_cpu`'s centroids (256/64)."""
    model = SegmenterModelConfig(width=0.25, centroids=(256, 64))
    return dataclasses.replace(model.network().backbone, in_channels=in_channels)


def _clouds(b: int, n: int, seed: int) -> torch.Tensor:
    """B boxes' worth of points in metres (the segmenter's input), normalised as it does."""
    g = torch.Generator().manual_seed(seed)
    points = torch.rand(b, n, 3, generator=g) * torch.tensor([0.8, 0.5, 1.2]) + 0.3
    return normalize_points(points)


def _run(
    net: PointNet2,
    xyz: torch.Tensor,
    features: torch.Tensor | None,
    index: BackboneIndex | None,
) -> tuple[torch.Tensor, torch.Tensor, list[torch.Tensor]]:
    """Point and global features and the gradients of a scalar loss on them."""
    net.zero_grad()
    out = net(xyz, features, index=index)
    loss = out.point_features.square().mean() + out.global_features.sin().sum()
    loss.backward()
    grads = [p.grad.clone() for p in net.parameters() if p.grad is not None]
    return out.point_features.detach(), out.global_features.detach(), grads


@pytest.mark.parametrize("mode", ["train", "eval"])
@pytest.mark.parametrize("in_channels", [0, 3])
def test_cached_index_gives_the_same_outputs_and_gradients(mode: str, in_channels: int) -> None:
    config = _config(in_channels)
    torch.manual_seed(0)
    net = PointNet2(config).train(mode == "train")
    xyz = _clouds(3, 1024, 1)
    features = torch.randn(3, 1024, 3) if in_channels else None
    on_the_fly = _run(net, xyz, features, None)
    cached = _run(net, xyz, features, backbone_index(xyz, config))
    # the same functions on the same batch: bit for bit
    assert torch.equal(on_the_fly[0], cached[0])
    assert torch.equal(on_the_fly[1], cached[1])
    assert len(on_the_fly[2]) == len(cached[2]) == len(list(net.parameters()))
    for a, b in zip(on_the_fly[2], cached[2], strict=True):
        assert torch.equal(a, b)


def test_single_cloud_indices_stack_into_the_batch_index() -> None:
    config = _config()
    torch.manual_seed(1)
    net = PointNet2(config).train()
    xyz = _clouds(4, 1024, 2)
    singles = [backbone_index(xyz[i : i + 1], config) for i in range(4)]
    stacked = stack_indices(singles)
    batch = backbone_index(xyz, config)
    for got, want in zip(stacked[:3], batch[:3], strict=True):
        for g, w in zip(got, want, strict=True):
            assert g.dtype == torch.int64
            assert torch.equal(g, w)
    for g, w in zip(stacked.weights, batch.weights, strict=True):
        torch.testing.assert_close(g, w)
    on_the_fly = _run(net, xyz, None, None)
    cached = _run(net, xyz, None, stacked)
    expected = [on_the_fly[0], on_the_fly[1], *on_the_fly[2]]
    for a, b in zip(expected, [cached[0], cached[1], *cached[2]], strict=True):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-5)


def test_stack_widens_narrow_indices_and_forward_accepts_them() -> None:
    config = _config()
    net = PointNet2(config).eval()
    xyz = _clouds(2, 512, 3)
    index = backbone_index(xyz, config)
    narrow = BackboneIndex(
        tuple(t.to(torch.int16) for t in index.centres),
        tuple(t.to(torch.int16) for t in index.neighbours),
        tuple(t.to(torch.int16) for t in index.interpolation_index),
        index.weights,
    )
    stacked = stack_indices([narrow]).to("cpu")
    assert all(t.dtype == torch.int64 for field in stacked[:3] for t in field)
    with torch.no_grad():
        want = net(xyz, index=index).point_features
        assert torch.equal(net(xyz, index=stacked).point_features, want)
        assert torch.equal(net(xyz, index=narrow).point_features, want)


def test_index_of_a_rotated_moved_scaled_cloud_is_the_originals() -> None:
    """Rotation about z (the training augmentation), translation and scale commute with
    the segmenter's normalisation, and the neighbourhoods depend on distances only: the
    cached index of a cloud serves every rotated copy of it."""
    config = _config()
    g = torch.Generator().manual_seed(4)
    points = torch.rand(2, 1024, 3, generator=g, dtype=torch.float64)
    angle = 0.7
    c, s = math.cos(angle), math.sin(angle)
    rotation = torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    moved = (points @ rotation.T) * 1.7 + torch.tensor([0.4, -2.0, 0.3], dtype=torch.float64)
    original = backbone_index(normalize_points(points.float()), config)
    rotated = backbone_index(normalize_points(moved.float()), config)
    for got, want in zip(rotated[:3], original[:3], strict=True):
        for g_, w in zip(got, want, strict=True):
            assert torch.equal(g_, w)
    for g_, w in zip(rotated.weights, original.weights, strict=True):
        torch.testing.assert_close(g_, w, rtol=1e-3, atol=1e-5)


def test_index_shapes_follow_the_config() -> None:
    config = _config()
    index = backbone_index(_clouds(2, 1024, 5), config)
    assert [tuple(t.shape) for t in index.centres] == [(2, 256), (2, 64)]
    assert [tuple(t.shape) for t in index.neighbours] == [(2, 256, 32), (2, 64, 64)]
    # coarsest first: the global point onto 64 centroids, 64 onto 256, 256 onto the input
    assert [tuple(t.shape) for t in index.interpolation_index] == [
        (2, 64, 1),
        (2, 256, 3),
        (2, 1024, 3),
    ]
    for w in index.weights:
        torch.testing.assert_close(w.sum(-1), torch.ones(w.shape[:2]))
        assert (w >= 0).all()
    for centre, ball, n in zip(index.centres, index.neighbours, (1024, 256), strict=True):
        assert int(centre.max()) < n and int(ball.max()) < n and int(ball.min()) >= 0


def test_index_of_another_config_or_size_is_refused() -> None:
    config = _config()
    net = PointNet2(config).eval()
    xyz = _clouds(2, 512, 6)
    index = backbone_index(xyz, config)
    with pytest.raises(ValueError, match="does not fit"):
        net(xyz[:1], index=index)  # batch of 1, index of 2
    with pytest.raises(ValueError, match="does not fit"):
        net(_clouds(2, 600, 6), index=index)
    other = dataclasses.replace(
        config,
        set_abstractions=(
            dataclasses.replace(config.set_abstractions[0], n_neighbours=16),
            *config.set_abstractions[1:],
        ),
    )
    with pytest.raises(ValueError, match="does not fit"):
        net(xyz, index=backbone_index(xyz, other))
    with pytest.raises(ValueError, match="at least one"):
        stack_indices([])


def test_fewer_points_than_centroids() -> None:
    config = _config()
    net = PointNet2(config).eval()
    xyz = _clouds(2, 100, 7)  # 100 points, 256 centroids: FPS repeats
    with torch.no_grad():
        want = net(xyz).point_features
        got = net(xyz, index=backbone_index(xyz, config)).point_features
    assert torch.equal(got, want)
