"""PointNet++ (Qi et al. 2017b) in plain PyTorch: the backbone of the section 4.3 segmenter.

No compiled extensions: farthest-point sampling, ball query, grouping and 3-NN
interpolation are written with dense tensor operations, which are fast enough on a CPU
for the few thousand points the segmenter sees (the scan is downsampled first).

Conventions: point sets are channels-last, `xyz (B, N, 3)` and `features (B, N, C)`
(None when a set has only coordinates). Indices are int64 into the N axis.

The neighbourhoods (FPS centres, ball-query balls, 3-NN interpolation maps) depend only on
the input coordinates, so a cloud seen every epoch can have them computed once
(`backbone_index`, a `BackboneIndex`) and passed to `PointNet2.forward(..., index=...)`:
the forward pass is then gathers and MLPs only, with the same outputs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal, NamedTuple

import numpy as np
import torch
from numpy.typing import NDArray
from torch import Tensor, nn

#: ball query and 3-NN work on (B, chunk, N) distance blocks of at most this many entries
_MAX_BLOCK = 1 << 22


class PointSet(NamedTuple):
    """A batch of point sets: coordinates and (optional) per-point features."""

    xyz: Tensor  # (B, N, 3)
    features: Tensor | None  # (B, N, C) or None


def square_distances(a: Tensor, b: Tensor) -> Tensor:
    """Squared Euclidean distances between two batches of points.

    a: (B, S, 3), b: (B, N, 3) -> (B, S, N).
    """
    return torch.cdist(a, b).square_()


def gather_points(values: Tensor, index: Tensor) -> Tensor:
    """Rows of `values` (B, N, C) picked by `index` (B, *shape) -> (B, *shape, C)."""
    b = values.shape[0]
    flat = index.reshape(b, -1)
    out = torch.gather(values, 1, flat.unsqueeze(-1).expand(-1, -1, values.shape[-1]))
    return out.reshape(*index.shape, values.shape[-1])


def farthest_point_sample(
    xyz: Tensor,
    n_samples: int,
    start: Tensor | int | None = None,
    generator: torch.Generator | None = None,
) -> Tensor:
    """Farthest-point sampling: greedily add the point farthest from those chosen so far.

    xyz: (B, N, 3); returns (B, n_samples) int64 indices, distinct while n_samples <= N
    (with n_samples > N, once every point is taken index 0 repeats).
    The first index is `start` (an int or a (B,) tensor), else drawn from `generator`, else
    0 as in the reference CUDA kernel; the rest is deterministic.
    """
    if n_samples < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples}")
    b, n, _ = xyz.shape
    device = xyz.device
    if start is None:
        if generator is not None:
            first = torch.randint(n, (b,), generator=generator, device=generator.device)
            first = first.to(device)
        else:
            first = torch.zeros(b, dtype=torch.long, device=device)
    elif isinstance(start, int):
        first = torch.full((b,), start, dtype=torch.long, device=device)
    else:
        first = start.to(device=device, dtype=torch.long).reshape(b)
    index = torch.empty(b, n_samples, dtype=torch.long, device=device)
    min_dist = torch.full((b, n), float("inf"), dtype=xyz.dtype, device=device)
    rows = torch.arange(b, device=device)
    with torch.no_grad():
        # one contiguous (B, N) row per coordinate: ~3x faster than (B, N, 3) arithmetic
        coords = xyz.detach().permute(2, 0, 1).contiguous()  # (3, B, N)
        dist = torch.empty_like(min_dist)
        diff = torch.empty_like(min_dist)
        farthest = first
        for i in range(n_samples):
            index[:, i] = farthest
            centre = coords[:, rows, farthest].unsqueeze(-1)  # (3, B, 1)
            torch.sub(coords[0], centre[0], out=dist).square_()
            torch.sub(coords[1], centre[1], out=diff)
            dist.addcmul_(diff, diff)
            torch.sub(coords[2], centre[2], out=diff)
            dist.addcmul_(diff, diff)
            torch.minimum(min_dist, dist, out=min_dist)
            farthest = min_dist.argmax(-1)
    return index


def farthest_point_indices(
    points: NDArray[np.floating], n_samples: int, start: int = 0
) -> NDArray[np.int64]:
    """`farthest_point_sample` for one cloud in numpy (about 2.5x faster on a CPU for one
    large cloud, e.g. 20,000 -> 2,048 points in ~60 ms); same indices as the torch version.

    points: (N, 3) -> (n_samples,) int64, the first being `start`.
    """
    if n_samples < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples}")
    pts = np.asarray(points, dtype=np.float32)
    x, y, z = (np.ascontiguousarray(pts[:, k]) for k in range(3))
    min_dist = np.full(len(pts), np.inf, dtype=np.float32)
    dist = np.empty_like(min_dist)
    diff = np.empty_like(min_dist)
    index = np.empty(n_samples, dtype=np.int64)
    farthest = start
    for i in range(n_samples):
        index[i] = farthest
        cx, cy, cz = pts[farthest]
        np.subtract(x, cx, out=dist)
        np.multiply(dist, dist, out=dist)
        np.subtract(y, cy, out=diff)
        np.multiply(diff, diff, out=diff)
        dist += diff
        np.subtract(z, cz, out=diff)
        np.multiply(diff, diff, out=diff)
        dist += diff
        np.minimum(min_dist, dist, out=min_dist)
        farthest = int(min_dist.argmax())
    return index


def ball_query(xyz: Tensor, centroids: Tensor, radius: float, n_neighbours: int) -> Tensor:
    """Up to `n_neighbours` points within `radius` of each centroid, lowest indices first.

    xyz: (B, N, 3), centroids: (B, S, 3) -> (B, S, K) int64 with K = n_neighbours. As in
    the reference implementation, a centroid with fewer than K neighbours repeats its
    first neighbour; one with none (not itself a point of xyz) takes its nearest point.
    """
    b, n, _ = xyz.shape
    s = centroids.shape[1]
    k = min(n_neighbours, n)
    chunk = max(1, _MAX_BLOCK // max(1, b * n))
    arange = torch.arange(n, device=xyz.device)
    parts = []
    with torch.no_grad():
        for lo in range(0, s, chunk):
            d2 = square_distances(centroids[:, lo : lo + chunk], xyz)
            key = torch.where(d2 <= radius * radius, arange, n)
            found = key.topk(k, dim=-1, largest=False, sorted=True).values
            first = found[..., :1]
            nearest = d2.argmin(-1, keepdim=True)
            first = torch.where(first == n, nearest, first)
            parts.append(torch.where(found == n, first, found))
    out = torch.cat(parts, dim=1)
    if k < n_neighbours:  # fewer points than K: pad with the first neighbour
        out = torch.cat([out, out[..., :1].expand(-1, -1, n_neighbours - k)], dim=-1)
    assert out.shape == (b, s, n_neighbours)
    return out


def group(points: PointSet, centroids: Tensor, index: Tensor) -> Tensor:
    """Neighbourhoods in local coordinates, concatenated with their features.

    points: xyz (B, N, 3), features (B, N, C) or None; centroids: (B, S, 3);
    index: (B, S, K) -> (B, S, K, 3 + C) with xyz relative to each centroid.
    """
    local = gather_points(points.xyz, index) - centroids.unsqueeze(2)
    if points.features is None:
        return local
    return torch.cat([local, gather_points(points.features, index)], dim=-1)


def three_nn(dense_xyz: Tensor, sparse_xyz: Tensor) -> tuple[Tensor, Tensor]:
    """The 3 nearest sparse points of every dense point and their inverse-squared-distance
    weights (Qi et al. 2017b, Eq. 2 with k = 3, p = 2), normalised to sum to 1.

    dense_xyz: (B, N, 3); sparse_xyz: (B, S, 3) -> index (B, N, k) int64 and weights
    (B, N, k), k = min(3, S). With S = 1 every point takes the single sparse point, weight 1.
    """
    b, n, _ = dense_xyz.shape
    s = sparse_xyz.shape[1]
    if s == 1:
        index = torch.zeros(b, n, 1, dtype=torch.long, device=dense_xyz.device)
        return index, dense_xyz.new_ones(b, n, 1)
    k = min(3, s)
    chunk = max(1, _MAX_BLOCK // max(1, b * s))
    indices, weights = [], []
    for lo in range(0, n, chunk):
        d2 = square_distances(dense_xyz[:, lo : lo + chunk], sparse_xyz)
        dist, idx = d2.topk(k, dim=-1, largest=False)
        weight = 1.0 / dist.clamp_min(1e-10)
        weights.append(weight / weight.sum(-1, keepdim=True))
        indices.append(idx)
    return torch.cat(indices, dim=1), torch.cat(weights, dim=1)


def interpolate(features: Tensor, index: Tensor, weights: Tensor) -> Tensor:
    """Weighted sums of sparse features: features (B, S, C), index and weights (B, N, k)
    (from `three_nn`) -> (B, N, C)."""
    if index.shape[-1] == 1 and features.shape[1] == 1:  # the single coarsest point
        return features.expand(index.shape[0], index.shape[1], -1)
    return (gather_points(features, index) * weights.unsqueeze(-1)).sum(2)


def three_nn_interpolate(dense_xyz: Tensor, sparse: PointSet) -> Tensor:
    """Features at `dense_xyz` by inverse-squared-distance weights of the 3 nearest sparse
    points (Qi et al. 2017b, Eq. 2 with k = 3, p = 2): `interpolate` after `three_nn`.

    dense_xyz: (B, N, 3); sparse: xyz (B, S, 3), features (B, S, C) -> (B, N, C).
    """
    assert sparse.features is not None
    return interpolate(sparse.features, *three_nn(dense_xyz, sparse.xyz))


Norm = Literal["batch", "layer"]


class SharedMLP(nn.Module):
    """Per-point MLP on the last axis: (Linear -> norm -> ReLU) per layer.

    (..., in_channels) -> (..., widths[-1]). `norm="batch"` (the reference) takes batch
    statistics over every leading axis, as a 1x1 convolution with BatchNorm2d; "layer"
    normalises each point's features on its own (no train/eval difference: use it when
    batches hold one cloud, e.g. overfitting a single scan).
    """

    def __init__(self, in_channels: int, widths: Sequence[int], norm: Norm = "batch") -> None:
        super().__init__()
        layers: list[nn.Module] = []
        for width in widths:
            layers.append(nn.Linear(in_channels, width, bias=False))
            layers.append(nn.BatchNorm1d(width) if norm == "batch" else nn.LayerNorm(width))
            layers.append(nn.ReLU())
            in_channels = width
        self.layers = nn.Sequential(*layers)
        self.out_channels = in_channels

    def forward(self, x: Tensor) -> Tensor:
        shape = x.shape[:-1]
        x = self.layers(x.reshape(-1, x.shape[-1]))
        return x.reshape(*shape, x.shape[-1])


@dataclass(frozen=True)
class SetAbstractionSpec:
    """One set abstraction level (single scale)."""

    n_centroids: int | None  # S, sampled by FPS; None groups all points into one set
    radius: float  # ball query radius, in the units of the (normalised) input
    n_neighbours: int  # K, points per ball
    widths: tuple[int, ...]  # shared MLP widths


class SetAbstraction(nn.Module):
    """Sample centroids (FPS), group balls around them, shared MLP, max pool (Qi et al. 2017b,
    section 3.2).

    PointSet xyz (B, N, 3), features (B, N, C) -> PointSet xyz (B, S, 3), features
    (B, S, widths[-1]); with `n_centroids=None` S = 1 and the single centroid is the origin
    (the grouped coordinates stay absolute).
    """

    def __init__(self, spec: SetAbstractionSpec, in_channels: int, norm: Norm = "batch") -> None:
        super().__init__()
        self.spec = spec
        self.mlp = SharedMLP(in_channels + 3, spec.widths, norm)
        self.out_channels = self.mlp.out_channels

    def forward(
        self, points: PointSet, centres: Tensor | None = None, neighbours: Tensor | None = None
    ) -> PointSet:
        """`centres` (B, S) and `neighbours` (B, S, K), int64 (from `backbone_index`): the
        FPS and ball-query indices, computed here when not given."""
        spec = self.spec
        xyz = points.xyz
        if spec.n_centroids is None:
            centroids = xyz.new_zeros(xyz.shape[0], 1, 3)
            grouped = xyz if points.features is None else torch.cat([xyz, points.features], -1)
            grouped = grouped.unsqueeze(1)
        else:
            if centres is None:
                centres = farthest_point_sample(xyz, spec.n_centroids)
            centroids = gather_points(xyz, centres)
            if neighbours is None:
                neighbours = ball_query(xyz, centroids, spec.radius, spec.n_neighbours)
            grouped = group(points, centroids, neighbours)
        return PointSet(centroids, self.mlp(grouped).amax(dim=2))


class FeaturePropagation(nn.Module):
    """3-NN interpolation of the sparse level's features onto the dense level, concatenated
    with the dense level's own features and passed through a unit PointNet (Qi et al. 2017b,
    section 3.4).

    dense: xyz (B, N, 3), features (B, N, C1) or None; sparse: xyz (B, S, 3), features
    (B, S, C2) -> (B, N, widths[-1]); in_channels = C1 + C2.
    """

    def __init__(self, in_channels: int, widths: Sequence[int], norm: Norm = "batch") -> None:
        super().__init__()
        self.mlp = SharedMLP(in_channels, widths, norm)
        self.out_channels = self.mlp.out_channels

    def forward(
        self, dense: PointSet, sparse: PointSet, maps: tuple[Tensor, Tensor] | None = None
    ) -> Tensor:
        """`maps`: the 3-NN index and weights (B, N, k) of `three_nn(dense.xyz, sparse.xyz)`,
        computed here when not given."""
        assert sparse.features is not None
        if maps is None:
            maps = three_nn(dense.xyz, sparse.xyz)
        x = interpolate(sparse.features, *maps)
        if dense.features is not None:
            x = torch.cat([dense.features, x], dim=-1)
        return self.mlp(x)


@dataclass(frozen=True)
class PointNet2Config:
    """The segmentation backbone: PointNet++ SSG as used by PartNet's instance segmenter
    (inputs normalised to the unit sphere)."""

    set_abstractions: tuple[SetAbstractionSpec, ...] = (
        SetAbstractionSpec(512, 0.2, 32, (64, 64, 128)),
        SetAbstractionSpec(128, 0.4, 64, (128, 128, 256)),
        SetAbstractionSpec(None, 0.0, 0, (256, 512, 1024)),
    )
    #: one per set abstraction, from the coarsest level back to the input points
    propagations: tuple[tuple[int, ...], ...] = ((256, 256), (256, 128), (128, 128, 128))
    in_channels: int = 0  # extra per-point input features besides xyz
    norm: Norm = "batch"  # normalisation in every shared MLP (see SharedMLP)

    def scaled(self, factor: float) -> PointNet2Config:
        """The same architecture with every width multiplied by `factor` (at least 4)."""

        def widths(w: tuple[int, ...]) -> tuple[int, ...]:
            return tuple(max(4, round(c * factor)) for c in w)

        return replace(
            self,
            set_abstractions=tuple(
                replace(s, widths=widths(s.widths)) for s in self.set_abstractions
            ),
            propagations=tuple(widths(w) for w in self.propagations),
        )


class BackboneOutput(NamedTuple):
    point_features: Tensor  # (B, N, C) per input point
    global_features: Tensor  # (B, G) max over the coarsest level


class PointNet2(nn.Module):
    """PointNet++ segmentation backbone: xyz (B, N, 3) [+ features (B, N, C_in)] ->
    BackboneOutput(point_features (B, N, propagations[-1][-1]), global_features
    (B, set_abstractions[-1].widths[-1]))."""

    def __init__(self, config: PointNet2Config | None = None) -> None:
        super().__init__()
        config = config or PointNet2Config()
        if len(config.propagations) != len(config.set_abstractions):
            raise ValueError("PointNet2Config needs one propagation per set abstraction")
        self.config = config
        channels = [config.in_channels]
        self.set_abstractions = nn.ModuleList()
        for spec in config.set_abstractions:
            sa = SetAbstraction(spec, channels[-1], config.norm)
            self.set_abstractions.append(sa)
            channels.append(sa.out_channels)
        self.propagations = nn.ModuleList()
        sparse_channels = channels[-1]
        for level, widths in zip(
            range(len(channels) - 2, -1, -1), config.propagations, strict=True
        ):
            fp = FeaturePropagation(channels[level] + sparse_channels, widths, config.norm)
            self.propagations.append(fp)
            sparse_channels = fp.out_channels
        self.out_channels = sparse_channels
        self.global_channels = channels[-1]

    def forward(
        self, xyz: Tensor, features: Tensor | None = None, index: BackboneIndex | None = None
    ) -> BackboneOutput:
        """xyz (B, N, 3), features (B, N, C_in) or None; `index`: the neighbourhoods of
        these clouds (`backbone_index(xyz, self.config)`, or `stack_indices` of the clouds'
        own), computed on the fly when None (same outputs either way)."""
        if index is not None:
            _check_index(index, self.config, xyz.shape[0], xyz.shape[1])
            index = _long(index)
        levels = [PointSet(xyz, features)]
        sampled = 0
        for sa, spec in zip(self.set_abstractions, self.config.set_abstractions, strict=True):
            if index is None or spec.n_centroids is None:
                levels.append(sa(levels[-1]))
            else:
                centres, neighbours = index.centres[sampled], index.neighbours[sampled]
                levels.append(sa(levels[-1], centres, neighbours))
                sampled += 1
        global_features = levels[-1].features
        assert global_features is not None
        sparse = levels[-1]
        for j, (fp, dense) in enumerate(zip(self.propagations, reversed(levels[:-1]), strict=True)):
            maps = None if index is None else (index.interpolation_index[j], index.weights[j])
            sparse = PointSet(dense.xyz, fp(dense, sparse, maps))
        assert sparse.features is not None
        return BackboneOutput(sparse.features, global_features.amax(dim=1))


class BackboneIndex(NamedTuple):
    """Every neighbourhood a `PointNet2` forward pass looks up, for B clouds (one cloud:
    B = 1). Computed once per cloud by `backbone_index`, joined into a batch by
    `stack_indices`, passed as `PointNet2.forward(xyz, index=...)`.

    One entry per set-abstraction level that samples centroids (`n_centroids` not None),
    in order, and one per feature propagation, coarsest first (the order of
    `PointNet2Config.propagations`). Indices may be stored narrower (int16 / int32) than
    the int64 the gathers take; `stack_indices` and `forward` widen them.
    """

    centres: tuple[Tensor, ...]  # (B, S_l) FPS indices into level l's input points
    neighbours: tuple[Tensor, ...]  # (B, S_l, K_l) ball-query indices, same points
    interpolation_index: tuple[Tensor, ...]  # (B, N_dense, k) 3-NN into the sparse level
    weights: tuple[Tensor, ...]  # (B, N_dense, k) float, inverse squared distance, sum 1

    def to(self, device: torch.device | str) -> BackboneIndex:
        """The same index on `device` (e.g. the model's, when training on a GPU)."""
        return BackboneIndex(*(tuple(t.to(device) for t in field) for field in self))


def backbone_index(xyz: Tensor, config: PointNet2Config) -> BackboneIndex:
    """The neighbourhoods `PointNet2(config)` computes in its forward pass on `xyz`
    (B, N, 3) -- the backbone's input, i.e. the *normalised* cloud when the segmenter
    normalises -- with the same functions (`farthest_point_sample` from point 0,
    `ball_query`, `three_nn`), without gradients.

    Distances are all they depend on: a rotation or translation of the cloud (hence the
    segmenter's augmentation by rotation about z, before normalisation) leaves them
    unchanged; per-point jitter does not.
    """
    centres: list[Tensor] = []
    neighbours: list[Tensor] = []
    index: list[Tensor] = []
    weights: list[Tensor] = []
    with torch.no_grad():
        xyz = xyz.detach()
        levels = [xyz]
        for spec in config.set_abstractions:
            points = levels[-1]
            if spec.n_centroids is None:
                levels.append(points.new_zeros(points.shape[0], 1, 3))
                continue
            centre = farthest_point_sample(points, spec.n_centroids)
            centroids = gather_points(points, centre)
            centres.append(centre)
            neighbours.append(ball_query(points, centroids, spec.radius, spec.n_neighbours))
            levels.append(centroids)
        for dense, sparse in zip(reversed(levels[:-1]), reversed(levels[1:]), strict=True):
            idx, weight = three_nn(dense, sparse)
            index.append(idx)
            weights.append(weight)
    return BackboneIndex(tuple(centres), tuple(neighbours), tuple(index), tuple(weights))


def stack_indices(indices: Sequence[BackboneIndex]) -> BackboneIndex:
    """The index of a batch: `indices` (of one cloud each, or of batches) joined along the
    batch axis, indices widened to int64. All must come from the same config and point
    count."""
    if not indices:
        raise ValueError("stack_indices needs at least one BackboneIndex")

    def cat(field: int, dtype: torch.dtype | None) -> tuple[Tensor, ...]:
        levels = [ix[field] for ix in indices]
        if len({len(level) for level in levels}) != 1:
            raise ValueError("stack_indices: the indices come from different configs")
        return tuple(
            torch.cat([t if dtype is None else t.to(dtype) for t in ts], dim=0)
            for ts in zip(*levels, strict=True)
        )

    return BackboneIndex(cat(0, torch.long), cat(1, torch.long), cat(2, torch.long), cat(3, None))


def _long(index: BackboneIndex) -> BackboneIndex:
    def widen(ts: tuple[Tensor, ...]) -> tuple[Tensor, ...]:
        return tuple(t.long() for t in ts)  # no copy when already int64

    return BackboneIndex(
        widen(index.centres),
        widen(index.neighbours),
        widen(index.interpolation_index),
        index.weights,
    )


def _check_index(index: BackboneIndex, config: PointNet2Config, b: int, n: int) -> None:
    """ValueError unless `index` has the shapes `backbone_index` gives for B x N clouds."""
    sizes = [n]  # points per level, the input first
    centres: list[tuple[int, ...]] = []
    balls: list[tuple[int, ...]] = []
    for spec in config.set_abstractions:
        sizes.append(1 if spec.n_centroids is None else spec.n_centroids)
        if spec.n_centroids is not None:
            centres.append((b, spec.n_centroids))
            balls.append((b, spec.n_centroids, spec.n_neighbours))
    maps = [(b, nd, min(3, ns)) for nd, ns in zip(sizes[-2::-1], sizes[:0:-1], strict=True)]
    expected = (centres, balls, maps, maps)
    got = tuple([tuple(t.shape) for t in field] for field in index)
    if got != expected:
        raise ValueError(
            f"BackboneIndex does not fit {b} clouds of {n} points and this backbone "
            f"(shapes {got}, expected {expected})"
        )
