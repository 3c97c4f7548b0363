"""The voting head of the part segmenter: per-point motion type + offset to the part centre,
parts found by clustering the shifted points (`model.head=votes`, docs/hierarchy.md).

The design of the closest peers on PartNet-Mobility (PointGroup, Jiang et al. 2020;
GAMMA, Yu et al. 2023; GAPartNet): dense per-point supervision instead of the 24 ordered
masks of the thesis' PartNet head (section 4.3), which on two CPU cores flattens at a matched
IoU of about 0.5.

- Training (`vote_loss`): cross-entropy on the motion types, and for every labelled point
  the L1 distance of its predicted offset to the centre (mean) of its part's points in the
  same cloud plus one minus the cosine between the two (PointGroup's regression and
  direction losses). Coordinates are those the network sees (`normalize_points`: unit
  sphere), so offsets are in cloud radii. With `model.static_part=one` the static points
  get no offset loss: they are one part at inference (below). With
  `model.offset_weight=parts` the offset and direction losses are means over the batch's
  (cloud, part) pairs of each part's mean, not over points: a part of 8 points (an office
  chair's caster) weighs as much as one of 400 (its seat), where a mean over points
  leaves it 2% of the seat's say.
- Inference (`cluster_votes`): points of one predicted motion type are shifted by their
  offsets and grouped by flood fill over pairs closer than that type's `cluster_radius`
  (the connected components of the radius graph, DBSCAN with min_samples 1; a radius per
  motion type because the offsets of large parts, e.g. a cabinet's static body, scatter
  more than those of small ones). Groups smaller than
  max(min_points, min_fraction * S) are not parts: their points join the part of the
  nearest kept shifted point, whatever its motion type. A part's confidence, for the mAP
  ranking, is the mean probability of its motion type over its points times the fraction
  of its points whose shifted position lies within its type's radius of the part's median
  shifted position (a compact vote is a confident one).
- Mode seeking (`inference.mode_bandwidth` h > 0, chosen on validation clouds with the
  radii): before the flood fill, the shifted points of each motion type climb to the modes
  of their own density (Gaussian mean shift, bandwidth h, at most `MODE_ITERATIONS`
  steps, a point stopping once its step is under `MODE_SETTLED` h; the
  kernel's support is the type's shifted points, which stay put). The votes of one part
  scatter about its centre; two neighbouring parts' scatters touch, and the flood fill
  chains through the contact. Contracted onto their modes, they come apart. The confidence's
  compactness is measured on the moved points.
- Moving votes together (`inference.moving_together`, structure, not learning): the
  points of every moving type (rotating, translating, both) are one set for the mode
  seeking and the flood fill, with the largest of those types' radii. The network's
  motion type is a per-point guess; where it reads a closed drawer's points half as a
  door, clustering each type apart cuts the drawer in two however well its votes agree,
  while two moving parts never share a centre. The part's confidence reads the
  probability of moving (one minus static) over its points; the points keep their own
  motion probabilities (the graph network's motion evidence reads them per part).
- `model.static_part=one` (structure, not learning): in a category whose static points are
  one rigid body (storage furniture: the carcass of every object, from which the doors and
  drawers hang), all points of the static motion type form one part, whatever their
  offsets; its confidence is their mean static probability. The offset branch then spends
  its capacity on the moving parts, where the votes head loses (docs/hierarchy.md).
"""

from __future__ import annotations

import functools
from collections.abc import Collection, Sequence
from typing import Any, NamedTuple

import numpy as np
import torch
import torch.nn.functional as F
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from torch import Tensor

from artic.objects.tree import MOTION_TYPES, KinematicTree

#: the static motion type's index
STATIC = MOTION_TYPES.index("static")
#: the first moving type's index: the set every moving vote joins with moving_together
ROTATING = MOTION_TYPES.index("rotating")
#: mean-shift steps of `seek_modes`: at the bandwidths chosen (0.05-0.1 cloud radii) the
#: points have settled by then
MODE_ITERATIONS = 10
#: rows of the mean-shift kernel formed at once (`seek_modes`): 256 x 3,000 float64 is 6 MB
MODE_ROWS = 256
#: a mean-shift step shorter than this many bandwidths ends the point's climb (`seek_modes`)
MODE_SETTLED = 1e-6


def seek_modes(
    points: NDArray[np.floating], bandwidth: float, iterations: int = MODE_ITERATIONS
) -> NDArray[np.float64]:
    """Gaussian mean shift: every point of `points` (n, 3) moved up to `iterations` times
    to the kernel-weighted mean of `points` around it (bandwidth in the points' units).
    The kernel's support stays put, so each point's path is its own: a point whose step
    was shorter than `MODE_SETTLED` bandwidths stops there (the steps shrink about tenfold
    per iteration near a mode, so it would have moved about a tenth of that further).
    O(n^2) per step; n is at most the network's input size times `InferenceConfig.passes`.

    The kernel is formed `MODE_ROWS` rows at a time in one reused buffer, in place: the
    whole n x n matrix and its temporaries (72 MB each at 3,000 points) left the cache at
    every operation (docs/hierarchy.md, "Speed"). The matrix products run on one BLAS
    thread whatever the process allows (`artic infer-hierarchy` runs with one already;
    an evaluation or a search in one process did not): with an inner dimension of 3 a
    second thread had nothing to share, and beside another job on two cores it made the
    mean shift of 2,000 votes twice as slow (0.69 against 0.36 s, pinned kernels)."""
    with _blas().limit(limits=1, user_api="blas"):
        return _seek_modes(np.asarray(points, dtype=np.float64), bandwidth, iterations)


@functools.cache
def _blas() -> Any:
    """threadpoolctl's controller of the loaded libraries (found once: ~4 ms each time)."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


def _seek_modes(x: NDArray[np.float64], bandwidth: float, iterations: int) -> NDArray[np.float64]:
    """`seek_modes` in the caller's thread settings."""
    y = x.copy()
    xx = (x * x).sum(1)
    xt = np.ascontiguousarray(x.T)
    scale = -0.5 / (bandwidth * bandwidth)
    block = np.empty((min(MODE_ROWS, len(x)), len(x)))
    moving = np.arange(len(x))
    for _ in range(iterations):
        if not len(moving):
            break
        here = y[moving]
        there = np.empty_like(here)
        yy = (here * here).sum(1)
        for start in range(0, len(here), MODE_ROWS):
            rows = slice(start, start + MODE_ROWS)
            w = block[: len(here[rows])]
            # |y - x|^2 as |y|^2 + |x|^2 - 2 y.x: a matrix product instead of an (n, n, 3)
            # array
            np.matmul(here[rows], xt, out=w)
            w *= -2.0
            w += yy[rows, None]
            w += xx[None, :]
            np.maximum(w, 0.0, out=w)
            w *= scale
            np.exp(w, out=w)
            there[rows] = (w @ x) / w.sum(1, keepdims=True)
        y[moving] = there
        moving = moving[np.linalg.norm(there - here, axis=1) >= MODE_SETTLED * bandwidth]
    return y


def set_probabilities(
    motion_prob: NDArray[np.floating], moving_together: bool = False
) -> NDArray[np.float64]:
    """The probability (S, K) of each set a point's vote may be clustered in
    (`cluster_votes`): its motion types' (S, T), or with `moving_together` static's and
    the moving types' sum (the set numbered as the first moving type, rotating). A point
    joins its most probable set, so with `moving_together` a point is moving when it is
    more probably moving than static, whichever moving type it is (module doc)."""
    prob = np.asarray(motion_prob, dtype=np.float64)
    if not moving_together:
        return prob
    return np.concatenate([prob[:, :ROTATING], prob[:, ROTATING:].sum(1, keepdims=True)], 1)


def set_radii(
    radius: float | Sequence[float], moving_together: bool = False
) -> NDArray[np.float64]:
    """The flood-fill radius of each vote set (`set_probabilities`, numbered by motion
    type): the type's own, or with `moving_together` the largest moving type's for the
    moving set."""
    radii = np.array(np.broadcast_to(np.asarray(radius, dtype=np.float64), (len(MOTION_TYPES),)))
    if moving_together:
        radii[ROTATING] = radii[ROTATING:].max()
    return radii


def seek_type_modes(
    shifted: NDArray[np.floating],
    motion: NDArray[np.integer],
    bandwidth: float,
    one_part: Collection[int] = (),
) -> NDArray[np.float64]:
    """`shifted` (S, 3) with the points of each vote set (S,: a motion type, or the sets of
    `set_probabilities`) not in `one_part` moved to their modes among that set's points
    (`seek_modes`); unchanged for bandwidth 0."""
    out = np.array(shifted, dtype=np.float64)
    if bandwidth > 0:
        for t in np.unique(motion):
            if t not in one_part:
                members = motion == t
                out[members] = seek_modes(out[members], bandwidth)
    return out


def radius_components(points: NDArray[np.floating], radius: float) -> NDArray[np.int64]:
    """The connected components of the graph joining the points (n, 3) closer than
    `radius` (at most), numbered in the order of their first point: scipy's
    `connected_components` of that graph, label for label.

    The votes of a part stand on its mode after mode seeking, so that graph has up to a
    million edges for 3,000 points, and building and transposing it took most of the time.
    Points in one grid cell of side radius / sqrt(3) are closer than `radius`, so they are
    one component whatever else holds: the components are those of the cells joined by
    the pairs that cross cells, a graph of a few hundred nodes and edges."""
    x = np.asarray(points, dtype=np.float64)
    side = radius / np.sqrt(3.0) * (1.0 - 1e-9)  # a cell's diagonal safely under the radius
    keys, cell = np.unique(np.floor(x / side), axis=0, return_inverse=True)
    cell = cell.reshape(-1)
    pairs = cKDTree(x).query_pairs(radius, output_type="ndarray")
    across = pairs[cell[pairs[:, 0]] != cell[pairs[:, 1]]]
    graph = coo_matrix(
        (np.ones(len(across)), (cell[across[:, 0]], cell[across[:, 1]])), shape=(len(keys),) * 2
    )
    _, joined = connected_components(graph, directed=False)
    component = joined[cell]
    # renumbered by first point, as connected_components numbers the points' own graph
    _, first = np.unique(component, return_index=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    return rank[component]


class VoteOutput(NamedTuple):
    motion_logits: Tensor  # (B, N, 4) over MOTION_TYPES
    offsets: Tensor  # (B, N, 3), from each point to its part's centre, in cloud radii
    xyz: Tensor  # (B, N, 3) the (normalised) coordinates the network saw
    # (B, N) logit that the point's part moves about (or along) a vertical axis; with
    # `model.axis_head` only (`axis_targets`, `split_by_axis`)
    axis_logits: Tensor | None = None


class VoteLosses(NamedTuple):
    total: Tensor  # motion + offset + direction (+ axis), differentiable
    motion: Tensor  # cross-entropy of the motion types
    offset: Tensor  # mean L1 (summed over x, y, z) of the offset error, labelled points
    direction: Tensor  # mean 1 - cos(predicted, true offset), labelled points
    offset_error: Tensor  # mean Euclidean offset error, cloud radii (no gradient)
    axis: Tensor  # binary cross-entropy of the axis head, points of a moving part (or 0)


#: a joint axis whose direction's |z| exceeds this is vertical (`axis_targets`)
VERTICAL = 0.5


def axis_targets(part_id: NDArray[np.integer], tree: KinematicTree) -> NDArray[np.int64]:
    """Per point (N,), whether its part's joint axis is vertical (1) or not (0), -1 for
    points of no part, of the root or of a part on a fixed joint (no axis). The axis is
    the tree's at configuration zero in the object frame (z up): exact for a part whose
    ancestors turn only about vertical axes (a chair's wheel under its swivelling caster, a
    cabinet's doors and drawers), an approximation below a tilting one."""
    vertical = np.full(tree.num_parts + 1, -1, dtype=np.int64)  # the last: no part
    for (_, child), axis in zip(tree.edges, tree.axes or (), strict=False):
        if axis is not None:
            vertical[child] = int(abs(float(axis.direction[2])) > VERTICAL)
    ids = np.asarray(part_id, dtype=np.int64)
    return vertical[np.where((ids >= 0) & (ids < tree.num_parts), ids, tree.num_parts)]


def _part_groups(part_id: Tensor, labelled: Tensor) -> tuple[Tensor, Tensor]:
    """Each labelled point's part among the batch's (cloud, part) pairs (0..G-1, in the
    labelled points' order) and each pair's point count (G,)."""
    b = part_id.shape[0]
    key = part_id + torch.arange(b, device=part_id.device)[:, None] * (int(part_id.max()) + 1)
    _, inverse = torch.unique(key[labelled], return_inverse=True)
    return inverse, torch.bincount(inverse)


def part_offsets(xyz: Tensor, part_id: Tensor) -> tuple[Tensor, Tensor]:
    """Offset from every point to the mean of its part's points in its own cloud.

    xyz: (B, N, 3); part_id: (B, N) int64, -1 for points of no part ->
    (offsets (B, N, 3), zero where part_id < 0; labelled (B, N) bool).
    """
    b, n = part_id.shape
    labelled = part_id >= 0
    inverse, counts = _part_groups(part_id, labelled)
    points = xyz[labelled]
    sums = points.new_zeros(len(counts), 3).index_add_(0, inverse, points)
    offsets = xyz.new_zeros(b, n, 3)
    offsets[labelled] = sums[inverse] / counts.to(points.dtype)[inverse, None] - points
    return offsets, labelled


def part_weights(part_id: Tensor, labelled: Tensor) -> Tensor:
    """Per point of `labelled` (in its order), the weight under which every (cloud, part)
    pair among them weighs the same: 1 / (its points x the pairs); the weights sum to 1."""
    inverse, counts = _part_groups(torch.where(labelled, part_id, -1), labelled)
    return 1.0 / (counts[inverse].double() * len(counts))


def vote_loss(
    output: VoteOutput,
    part_id: Tensor,
    motion_type: Tensor,
    vote_static: bool = True,
    per_part: bool = False,
    axis_vertical: Tensor | None = None,
) -> VoteLosses:
    """PointGroup's losses, mean over the batch's labelled points (module doc).

    part_id: (B, N) int64, -1 for points of no part; motion_type: (B, N) int64, -1 to ignore.
    vote_static False: points whose true motion type is static (0) get no offset loss.
    per_part: the offset and direction losses weigh every (cloud, part) pair the same
    (`part_weights`) instead of every point (`model.offset_weight=parts`); the reported
    offset error stays the mean over points. axis_vertical (B, N) int64 (`axis_targets`,
    -1 to ignore): with the output's `axis_logits`, their binary cross-entropy joins the
    total, every (cloud, part) pair it labels weighing the same (`part_weights`: a caster
    of 6 points as much as a seat of 400, as `fit_axis_head` weighs them).
    """
    zero = output.offsets.new_zeros(())
    motion = (
        F.cross_entropy(
            output.motion_logits.reshape(-1, output.motion_logits.shape[-1]),
            motion_type.reshape(-1),
            ignore_index=-1,
        )
        if (motion_type >= 0).any()
        else zero
    )
    target, labelled = part_offsets(output.xyz.detach(), part_id)
    if not vote_static:
        labelled = labelled & (motion_type != STATIC)
    if labelled.any():
        predicted, true = output.offsets[labelled], target[labelled]
        weight = part_weights(part_id, labelled).to(predicted.dtype) if per_part else None

        def mean(values: Tensor) -> Tensor:
            return values.mean() if weight is None else (values * weight).sum()

        offset = mean((predicted - true).abs().sum(-1))
        cosine = F.cosine_similarity(predicted, true, dim=-1, eps=1e-8)
        direction = mean(1.0 - cosine)
        error = (predicted - true).detach().norm(dim=-1).mean()
    else:
        offset, direction, error = zero, zero, zero
    axis = zero
    if output.axis_logits is not None and axis_vertical is not None:
        known = axis_vertical >= 0
        if known.any():
            logits = output.axis_logits[known]
            bce = F.binary_cross_entropy_with_logits(
                logits, axis_vertical[known].to(logits.dtype), reduction="none"
            )
            axis = (bce * part_weights(part_id, known).to(bce.dtype)).sum()
    return VoteLosses(motion + offset + direction + axis, motion, offset, direction, error, axis)


class Clusters(NamedTuple):
    label: NDArray[np.int64]  # (S,) part of every point, 0..P-1, parts by decreasing size
    confidence: NDArray[np.float32]  # (P,) in [0, 1]


def cluster_votes(
    shifted: NDArray[np.floating],
    motion_prob: NDArray[np.floating],
    radius: float | Sequence[float],
    min_size: int,
    one_part: Collection[int] = (),
    bandwidth: float = 0.0,
    moving_together: bool = False,
) -> Clusters:
    """Parts from shifted points (module doc): shifted (S, 3) = point + offset; motion_prob
    (S, T) softmax over motion types; radius: one for all types or one per type; one_part:
    motion types whose points are all one part (no flood fill; confidence: their mean
    probability of that type); bandwidth > 0: the points of each other type seek their
    modes first (`seek_modes`); moving_together: the moving types' points are one set
    (`set_probabilities`, `set_radii`). Deterministic; every point gets a part."""
    prob = set_probabilities(motion_prob, moving_together)
    radii = set_radii(radius, moving_together)
    motion = prob.argmax(-1)
    shifted = seek_type_modes(shifted, motion, bandwidth, one_part)
    groups: list[NDArray[np.int64]] = []
    for t in np.unique(motion):
        members = np.flatnonzero(motion == t)
        if t in one_part:
            groups.append(members)
            continue
        component = radius_components(shifted[members], float(radii[t]))
        order = np.argsort(component, kind="stable")
        starts = np.flatnonzero(np.diff(component[order], prepend=-1))
        groups.extend(members[part] for part in np.split(order, starts[1:]))
    sizes = np.array([len(g) for g in groups])
    kept = [g for g in groups if len(g) >= min_size] or [groups[int(sizes.argmax())]]
    kept.sort(key=lambda g: (-len(g), int(g[0])))
    label = np.full(len(shifted), -1, dtype=np.int64)
    for i, g in enumerate(kept):
        label[g] = i
    orphans = np.flatnonzero(label < 0)
    if len(orphans):
        assigned = np.flatnonzero(label >= 0)
        nearest = cKDTree(shifted[assigned]).query(shifted[orphans], k=1)[1]
        label[orphans] = label[assigned[nearest]]
    confidence = np.empty(len(kept), dtype=np.float32)
    for i, g in enumerate(kept):
        t = motion[g[0]]
        centre = np.median(shifted[g], axis=0)
        compact = (
            1.0
            if t in one_part
            else float(np.mean(np.linalg.norm(shifted[g] - centre, axis=1) <= radii[t]))
        )
        confidence[i] = float(prob[g, t].mean()) * compact
    return Clusters(label, confidence)


def sought(
    output: VoteOutput,
    bandwidth: float,
    one_part: Collection[int] = (),
    moving_together: bool = False,
) -> VoteOutput:
    """`output` (one cloud) with the offsets that move each point where `cluster_votes`'s
    mode seeking would (the points of each vote set not in `one_part`), so that clustering
    it with bandwidth 0 clusters `output` with `bandwidth` (to within float32 rounding):
    one mean shift for many radii."""
    if bandwidth <= 0:
        return output
    shifted = (output.xyz[0] + output.offsets[0]).cpu().numpy()
    logits = output.motion_logits[0]
    if moving_together:
        motion = set_probabilities(logits.softmax(-1).cpu().numpy(), True).argmax(-1)
    else:
        motion = logits.argmax(-1).cpu().numpy()
    shifted = seek_type_modes(shifted, motion, bandwidth, one_part)
    moved = torch.from_numpy(shifted).to(output.xyz) - output.xyz[0]
    return output._replace(offsets=moved[None])


def merge_passes(
    outputs: Sequence[VoteOutput], frames: Sequence[tuple[NDArray[np.floating], float]]
) -> VoteOutput:
    """The outputs of several runs of the network on disjoint samples of one cloud (each a
    batch of one) as one output in the first run's frame, so that all their shifted points
    are clustered together (`InferenceConfig.passes`). frames[i]: (centre (3,), radius) the
    i-th run's points were normalised with (`segmentation.normalization_frame`)."""
    c0, r0 = frames[0]
    xyz, offsets = [], []
    for out, (centre, radius) in zip(outputs, frames, strict=True):
        scale = float(radius) / float(r0)
        shift = torch.as_tensor((np.asarray(centre) - c0) / r0, dtype=out.xyz.dtype)
        xyz.append(out.xyz[0] * scale + shift.to(out.xyz.device))
        offsets.append(out.offsets[0] * scale)
    logits = torch.cat([out.motion_logits[0] for out in outputs])
    axes = [out.axis_logits[0] for out in outputs if out.axis_logits is not None]
    axis = torch.cat(axes)[None] if len(axes) == len(outputs) else None
    return VoteOutput(logits[None], torch.cat(offsets)[None], torch.cat(xyz)[None], axis)


def vote_parts(
    output: VoteOutput,
    radius: float | Sequence[float],
    min_size: int,
    one_part: Collection[int] = (),
    bandwidth: float = 0.0,
    moving_together: bool = False,
    axis_split: int | None = None,
    axis_share: float = 0.25,
    axis_smooth: int = 0,
) -> tuple[Clusters, NDArray[np.float32]]:
    """`cluster_votes` on the first cloud of a batch -> (clusters, motion_prob (S, T));
    with `axis_split` (the halves' minimum size; None: no cut) and the output's
    `axis_logits`, then `split_by_axis` (`axis_share`: its `min_share`), each point's
    reading first smoothed over its part's `axis_smooth` nearest (`smooth_within_parts`;
    0: not)."""
    prob = output.motion_logits[0].softmax(-1).cpu().numpy().astype(np.float32)
    shifted = (output.xyz[0] + output.offsets[0]).cpu().numpy()
    clusters = cluster_votes(shifted, prob, radius, min_size, one_part, bandwidth, moving_together)
    if axis_split is not None and output.axis_logits is not None:
        vertical = torch.sigmoid(output.axis_logits[0]).cpu().numpy().astype(np.float32)
        static = prob.argmax(-1) == STATIC
        if axis_smooth:
            xyz = output.xyz[0].cpu().numpy()
            vertical = smooth_within_parts(vertical, xyz, clusters.label, axis_smooth)
        clusters = split_by_axis(clusters, vertical, static, axis_split, axis_share)
    return clusters, prob


def split_by_axis(
    clusters: Clusters,
    vertical: NDArray[np.floating],
    static: NDArray[np.bool_],
    min_size: int,
    min_share: float = 0.0,
) -> Clusters:
    """Each part of moving points cut in two where its points read two axes (structure: a
    rigid part moves about one axis): its points whose `vertical` probability (S,) is above
    one half against the rest, when both have `min_size` points and `min_share` of the
    part's (a few misread points of a seat are no second part) (`segment`: the minimum
    per sample, `inference.min_points`, times the samples; a half is a part of a kept
    cluster, so the cluster's floor of a fraction of the sample does not apply to it;
    `min_share` is `inference.axis_share`, chosen on the office chair's validation scans,
    docs/hierarchy.md). A swivelling caster and
    the wheel it carries vote for centres 2-3 cm apart, which the clustering joins; the
    caster turns about a vertical axis, the wheel about a horizontal one. Parts of `static`
    points (S,) stay whole. Each half's confidence is the part's times its points' mean
    probability of their axis. Parts renumbered by decreasing size, as `cluster_votes`."""
    groups: list[tuple[NDArray[np.int64], float]] = []
    up = vertical > 0.5
    for part, confidence in enumerate(clusters.confidence.tolist()):
        members = np.flatnonzero(clusters.label == part)
        halves = [members[up[members]], members[~up[members]]]
        smaller = min(len(h) for h in halves)
        if static[members].mean() > 0.5 or smaller < max(1, min_size, min_share * len(members)):
            groups.append((members, confidence))
            continue
        for half, p in zip(halves, (vertical, 1.0 - vertical), strict=True):
            groups.append((half, confidence * float(np.mean(p[half]))))
    groups.sort(key=lambda g: (-len(g[0]), int(g[0][0])))
    label = np.empty_like(clusters.label)
    for i, (members, _) in enumerate(groups):
        label[members] = i
    return Clusters(label, np.array([c for _, c in groups], dtype=np.float32))


def smooth_within_parts(
    values: NDArray[np.floating],
    xyz: NDArray[np.floating],
    label: NDArray[np.integer],
    k: int,
) -> NDArray[np.float32]:
    """`values` (S,) with each point's the mean over the `k` nearest points (S, 3 `xyz`,
    itself included) that share its `label` (S,): all of them in a part of at most k
    points. A rigid part's points read one axis, so a few misread ones among their
    neighbours are outvoted while a caster's own points, a block of them, keep theirs."""
    v = np.asarray(values, dtype=np.float64)
    out = np.empty(len(v), dtype=np.float32)
    for part in np.unique(label):
        members = np.flatnonzero(label == part)
        n = min(k, len(members))
        _, near = cKDTree(xyz[members]).query(xyz[members], k=n)
        near = np.asarray(near).reshape(len(members), n)
        out[members] = v[members][near].mean(1)
    return out
