"""The segmenter's votes head: offsets to part centres, clustering, training, inference."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from test_segmentation import _batch, three_boxes, tiny_config

from artic.errors import InputError
from artic.evaluation.segmentation import (
    average_precision,
    instance_iou,
    motion_type_accuracy,
    object_detections,
)
from artic.hierarchy.cloud_cache import cloud_features
from artic.hierarchy.fit_segmenter import (
    InferenceSearch,
    ValidationScan,
    choose_inference,
    static_part_of,
)
from artic.hierarchy.models import load_segmenter, save_segmenter
from artic.hierarchy.pointnet2 import farthest_point_indices
from artic.hierarchy.segmentation import (
    MIRROR_Y,
    InferenceConfig,
    PartSegmentationNet,
    forward,
    make_optimizer,
    normalization_frame,
    normalize_points,
    sample_passes,
    segment,
    train_step,
)
from artic.hierarchy.votes import (
    MODE_ITERATIONS,
    MODE_ROWS,
    MODE_SETTLED,
    VoteOutput,
    cluster_votes,
    merge_passes,
    part_offsets,
    part_weights,
    radius_components,
    seek_modes,
    sought,
    vote_loss,
)


def _one_hot_prob(motion: np.ndarray) -> np.ndarray:
    return np.eye(4, dtype=np.float32)[motion]


def test_part_offsets_point_at_each_part_mean_in_its_own_cloud() -> None:
    points, part, _ = three_boxes(300, 0)
    xyz = torch.from_numpy(np.stack([points, points[::-1].copy()]))
    ids = torch.from_numpy(np.stack([part, part[::-1].copy()]))
    ids[1, :10] = -1  # points of no part: no offset
    offsets, labelled = part_offsets(xyz, ids)
    assert not labelled[1, :10].any() and labelled[0].all()
    assert torch.equal(offsets[1, :10], torch.zeros(10, 3))
    for b in range(2):
        for p in range(3):
            members = ids[b] == p
            centre = xyz[b][members].mean(0)
            torch.testing.assert_close(
                xyz[b][members] + offsets[b][members], centre.expand(int(members.sum()), 3)
            )


def test_vote_loss_is_zero_for_true_offsets_and_confident_motion() -> None:
    points, part, motion = three_boxes(200, 1)
    xyz = torch.from_numpy(points)[None]
    ids, types = torch.from_numpy(part)[None], torch.from_numpy(motion)[None]
    offsets, _ = part_offsets(xyz, ids)
    logits = torch.from_numpy(_one_hot_prob(motion))[None] * 100.0
    exact = vote_loss(VoteOutput(logits, offsets, xyz), ids, types)
    assert float(exact.total) < 1e-5 and float(exact.offset_error) < 1e-6
    wrong = vote_loss(VoteOutput(logits, offsets + 0.1, xyz), ids, types)
    assert float(wrong.offset) == pytest.approx(0.3, abs=1e-5)
    assert float(wrong.total) > float(exact.total)


def test_true_offsets_cluster_into_exactly_the_parts() -> None:
    """Shifted by their true offsets, the points of each part collapse onto its centre."""
    points, part, motion = three_boxes(600, 2)
    offsets, _ = part_offsets(torch.from_numpy(points)[None], torch.from_numpy(part)[None])
    shifted = points + offsets[0].numpy()
    clusters = cluster_votes(shifted, _one_hot_prob(motion), radius=0.02, min_size=5)
    assert len(clusters.confidence) == 3
    iou = instance_iou(clusters.label, part)
    np.testing.assert_allclose(iou.max(axis=0), 1.0)
    np.testing.assert_allclose(clusters.confidence, 1.0)
    counts = np.bincount(clusters.label)
    assert (np.diff(counts) <= 0).all()  # parts ordered by decreasing size


def test_two_parts_of_one_motion_type_are_split_by_their_centres() -> None:
    rng = np.random.default_rng(0)
    a, b = (
        rng.normal(0.0, 0.004, (40, 3)),
        rng.normal(0.0, 0.004, (30, 3)) + np.array([0.3, 0.0, 0.0]),
    )
    shifted = np.concatenate([a, b])
    prob = _one_hot_prob(np.full(70, 2))
    clusters = cluster_votes(shifted, prob, radius=0.05, min_size=5)
    np.testing.assert_array_equal(clusters.label, [0] * 40 + [1] * 30)
    # with a radius above the gap they are one part
    assert len(cluster_votes(shifted, prob, radius=0.5, min_size=5).confidence) == 1
    # the radius of their motion type (translating) is the one that counts
    per_type = cluster_votes(shifted, prob, radius=(0.01, 0.01, 0.05, 0.01), min_size=5)
    np.testing.assert_array_equal(per_type.label, clusters.label)
    assert (
        len(cluster_votes(shifted, prob, radius=(0.5, 0.5, 0.01, 0.5), min_size=5).confidence) == 2
    )


def test_moving_together_keeps_a_part_read_as_two_moving_types_whole() -> None:
    """A drawer whose votes agree but whose points the network reads half as a door: per
    type it is two parts of half its points each; with the moving types clustered
    together it is one, next to a door whose centre is elsewhere and the static body. A
    point goes with its most probable set: one that is 0.4 static and 0.6 moving
    is moving. The part's confidence reads the probability of moving."""
    rng = np.random.default_rng(5)
    body = rng.normal(0.0, 0.004, (60, 3))
    drawer = rng.normal(0.0, 0.004, (40, 3)) + np.array([0.3, 0.0, 0.0])
    door = rng.normal(0.0, 0.004, (30, 3)) + np.array([0.0, 0.3, 0.0])
    shifted = np.concatenate([body, drawer, door])
    truth = np.array([0] * 60 + [1] * 40 + [2] * 30)
    motion = np.array([0] * 60 + [2, 1] * 20 + [1] * 30)
    prob = _one_hot_prob(motion) * 0.9 + 0.025
    prob[60] = [0.4, 0.3, 0.29, 0.01]  # more probably moving than static
    apart = cluster_votes(shifted, prob, radius=0.05, min_size=5)
    together = cluster_votes(shifted, prob, radius=0.05, min_size=5, moving_together=True)
    assert instance_iou(apart.label, truth).max(axis=0)[1] <= 0.55
    assert len(together.confidence) == 3
    np.testing.assert_allclose(instance_iou(together.label, truth).max(axis=0), 1.0)
    drawer_part = together.label[61]
    moving = prob[60:100, 1:].sum(1).mean()
    assert together.confidence[drawer_part] == pytest.approx(moving, rel=1e-6)
    # the moving set's radius is the largest of the moving types' (here translating's)
    radii = (0.5, 0.01, 0.05, 0.01)
    wide = cluster_votes(shifted, prob, radius=radii, min_size=5, moving_together=True)
    np.testing.assert_array_equal(wide.label, together.label)
    # mode seeking goes by the same sets: `sought` and the bandwidth agree
    xyz = torch.zeros(1, len(shifted), 3)
    logits = torch.from_numpy(np.log(prob))[None]
    output = VoteOutput(logits, torch.from_numpy(shifted).float()[None], xyz)
    moved = sought(output, 0.02, moving_together=True).offsets[0].numpy()
    sought_parts = cluster_votes(moved, prob, radius=0.05, min_size=5, moving_together=True)
    direct = cluster_votes(
        shifted, prob, radius=0.05, min_size=5, bandwidth=0.02, moving_together=True
    )
    np.testing.assert_array_equal(sought_parts.label, direct.label)
    np.testing.assert_array_equal(direct.label, together.label)


def test_small_groups_join_the_nearest_part_and_every_point_gets_one() -> None:
    rng = np.random.default_rng(1)
    big = rng.normal(0.0, 0.005, (50, 3))
    stray = np.array([[0.08, 0.0, 0.0], [0.5, 0.5, 0.5]])
    other = rng.normal(0.0, 0.005, (20, 3)) + np.array([1.0, 0.0, 0.0])
    shifted = np.concatenate([big, stray, other])
    motion = np.array([0] * 50 + [1, 1] + [0] * 20)  # the strays have another motion type
    clusters = cluster_votes(shifted, _one_hot_prob(motion), radius=0.03, min_size=5)
    assert len(clusters.confidence) == 2
    assert clusters.label[50] == clusters.label[0] and (clusters.label[52:] == 1).all()
    assert (clusters.label >= 0).all()
    again = cluster_votes(shifted, _one_hot_prob(motion), radius=0.03, min_size=5)
    np.testing.assert_array_equal(again.label, clusters.label)
    # nothing big enough: the largest group is kept
    tiny = cluster_votes(shifted, _one_hot_prob(motion), radius=0.03, min_size=500)
    np.testing.assert_array_equal(tiny.label, np.zeros(72))


def test_votes_net_overfits_one_cloud_of_three_boxes_and_round_trips(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """~10 s: 500 Adam steps on one 384-point cloud; the saved model segments the same.
    Each box's best IoU plateaus at 0.92-0.98 by then, at a value that depends on the
    number of threads (the order of torch's reductions): hence 0.85, not 0.9 (400 steps
    left the third box at 0.86 on one thread)."""
    torch.manual_seed(0)
    config = dataclasses.replace(tiny_config(), head="votes")
    model = PartSegmentationNet(config)
    assert not hasattr(model, "instance") and not hasattr(model, "confidence")
    optimizer = make_optimizer(model, lr=1e-3)
    points, part, motion = three_boxes(384, 0)
    batch = _batch(points, part, motion)
    totals = [train_step(model, optimizer, batch)["total"] for _ in range(500)]
    assert totals[-1] < 0.3 * totals[0]
    inference = InferenceConfig(cluster_radius=0.1)
    result = segment(model, points, inference)
    assert isinstance(model(torch.from_numpy(points)[None]), VoteOutput)
    iou = instance_iou(result.part_id, part)
    assert (iou.max(axis=0) > 0.85).all()
    assert average_precision(object_detections(result.part_id, result.part_confidence, part)) == 1.0
    assert motion_type_accuracy(result.motion_type, motion) > 0.9
    save_segmenter(tmp_path / "model.pt", "storage_furniture", model, inference, {})
    loaded = load_segmenter(tmp_path / "model.pt", "storage_furniture")
    assert loaded.model.config.head == "votes" and loaded.inference.cluster_radius == (0.1,) * 4
    again = segment(loaded.model, points, loaded.inference)
    for a, b in zip(result, again, strict=True):
        np.testing.assert_array_equal(a, b)
    # a prepared cloud's cached features give the same parts as computing them here
    features = cloud_features(points, config, tmp_path / "cache")
    cached = segment(
        loaded.model, points, loaded.inference, features.normals, features.neighbourhoods
    )
    for a, b in zip(result, cached, strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="n_points"):
        segment(model, points, InferenceConfig(n_points=100), features.normals)


def test_per_part_offset_loss_weighs_a_small_part_as_much_as_a_large_one() -> None:
    """`model.offset_weight=parts`: in two clouds, a 90-point part with exact offsets and a
    10-point part (the other cloud's parts of 50 and 50) with every offset 0.1 off in x:
    over points the small part's error is 10% of the first cloud's loss, over parts it is
    one of the batch's four parts; static points left out (`vote_static`) do not count."""
    ids = torch.tensor([[0] * 90 + [1] * 10, [0] * 50 + [1] * 50])
    xyz = torch.randn(2, 100, 3, generator=torch.Generator().manual_seed(0))
    offsets, labelled = part_offsets(xyz, ids)
    weights = part_weights(ids, labelled)
    assert float(weights.sum()) == pytest.approx(1.0)
    for b, p in ((0, 0), (0, 1), (1, 0), (1, 1)):
        assert float(weights[(ids[labelled] == p) & (torch.arange(200) // 100 == b)].sum()) == (
            pytest.approx(0.25)
        )
    wrong = offsets.clone()
    wrong[0, 90:, 0] += 0.1
    types = torch.ones_like(ids)
    logits = torch.nn.functional.one_hot(types, 4).float() * 100.0
    output = VoteOutput(logits, wrong, xyz)
    by_point = vote_loss(output, ids, types)
    by_part = vote_loss(output, ids, types, per_part=True)
    assert float(by_point.offset) == pytest.approx(0.1 * 10 / 200, abs=1e-6)
    assert float(by_part.offset) == pytest.approx(0.1 / 4, abs=1e-6)
    assert float(by_part.offset_error) == pytest.approx(float(by_point.offset_error))
    types[1, :50] = 0  # the second cloud's first part static, its offsets not learnt
    by_part = vote_loss(output, ids, types, vote_static=False, per_part=True)
    assert float(by_part.offset) == pytest.approx(0.1 / 3, abs=1e-6)


def test_static_one_part_ignores_the_static_offsets() -> None:
    """`model.static_part=one`: static points are one part however their votes scatter,
    and their offsets cost nothing; the moving points are clustered and supervised as
    before."""
    points, part, motion = three_boxes(300, 3)
    xyz = torch.from_numpy(points)[None]
    ids, types = torch.from_numpy(part)[None], torch.from_numpy(motion)[None]
    offsets, _ = part_offsets(xyz, ids)
    static = types == 0
    assert static.any() and (~static).any()
    noise = torch.randn(offsets.shape, generator=torch.Generator().manual_seed(0))
    scattered = offsets + static[..., None] * noise
    logits = torch.from_numpy(_one_hot_prob(motion))[None] * 100.0
    output = VoteOutput(logits, scattered, xyz)
    assert float(vote_loss(output, ids, types).offset_error) > 0.1
    ignored = vote_loss(output, ids, types, vote_static=False)
    assert float(ignored.offset_error) < 1e-6 and float(ignored.total) < 1e-5
    shifted = (xyz + scattered)[0].numpy()
    prob = _one_hot_prob(motion)
    split = cluster_votes(shifted, prob, radius=0.02, min_size=1)
    one = cluster_votes(shifted, prob, radius=0.02, min_size=1, one_part=(0,))
    assert len(split.confidence) > len(one.confidence) == 3
    np.testing.assert_allclose(instance_iou(one.label, part).max(axis=0), 1.0)
    np.testing.assert_allclose(one.confidence, 1.0)


def test_static_part_auto_follows_the_training_clouds() -> None:
    """One static part in every cloud (the body of a storage-furniture object): "one";
    a cloud with two static parts (an office chair's base and fixed seat): "votes"."""
    part = np.array([[0, 0, 1, 2, -1], [0, 1, 1, 2, 2]])
    motion = np.array([[0, 0, 1, 2, -1], [1, 0, 0, 2, 2]])
    assert static_part_of(part, motion) == "one"
    motion[1] = [0, 0, 0, 2, 2]  # parts 0 and 1 of the second cloud are both static
    assert static_part_of(part, motion) == "votes"
    assert static_part_of(part, np.ones_like(motion)) == "one"  # no static part at all


def test_mode_seeking_separates_touching_scatters_that_the_flood_fill_chains() -> None:
    """Two parts' votes scattered about centres 0.2 apart touch through a few stray votes:
    the flood fill at 0.05 chains them into one part; moved to their modes first, they
    are two, and `sought` gives the same parts at bandwidth 0."""
    rng = np.random.default_rng(4)
    a = rng.normal(0.0, 0.03, (60, 3))
    b = rng.normal(0.0, 0.03, (60, 3)) + np.array([0.2, 0.0, 0.0])
    bridge = np.linspace([0.03, 0.0, 0.0], [0.17, 0.0, 0.0], 6)
    shifted = np.concatenate([a, bridge, b])
    truth = np.array([0] * 63 + [1] * 63)
    prob = _one_hot_prob(np.full(len(shifted), 1))
    chained = cluster_votes(shifted, prob, radius=0.05, min_size=5)
    assert len(chained.confidence) == 1
    moved = seek_modes(shifted, 0.05)
    assert np.abs(moved[:60].mean(0)).max() < 0.01  # a's votes at a's centre
    parts = cluster_votes(shifted, prob, radius=0.05, min_size=5, bandwidth=0.05)
    assert len(parts.confidence) == 2
    np.testing.assert_allclose(instance_iou(parts.label, truth).max(axis=0), 1.0)
    xyz = torch.zeros(1, len(shifted), 3)
    output = VoteOutput(torch.from_numpy(prob)[None], torch.from_numpy(shifted).float()[None], xyz)
    again = cluster_votes((sought(output, 0.05).offsets[0]).numpy(), prob, radius=0.05, min_size=5)
    np.testing.assert_array_equal(again.label, parts.label)
    assert sought(output, 0.0) is output


def test_mode_seeking_is_each_points_own_mean_shift_climb() -> None:
    """`seek_modes` forms its kernel MODE_ROWS rows at a time and stops each point once its
    step is under MODE_SETTLED bandwidths: over several blocks (and a short last one) it
    is, point by point, Gaussian mean shift with the whole cloud as the kernel's support,
    here written out with explicit differences, one point at a time."""
    rng = np.random.default_rng(7)
    points = rng.normal(0.0, 0.2, (2 * MODE_ROWS + 37, 3))
    points[:40] = rng.normal(0.0, 0.01, (40, 3)) + 0.5  # a tight cluster: settles early
    bandwidth = 0.08
    expected, steps = points.copy(), []
    for i in range(len(points)):
        taken = 0
        while taken < MODE_ITERATIONS:
            w = np.exp(-0.5 * ((expected[i] - points) ** 2).sum(-1) / bandwidth**2)
            moved = (w @ points) / w.sum()
            taken += 1
            settled = np.linalg.norm(moved - expected[i]) < MODE_SETTLED * bandwidth
            expected[i] = moved
            if settled:
                break
        steps.append(taken)
    np.testing.assert_allclose(seek_modes(points, bandwidth), expected, rtol=0, atol=1e-12)
    assert np.abs(expected - points).max() > 0.05  # the points did move
    assert min(steps) < MODE_ITERATIONS == max(steps)  # some stopped early, some did not


def test_mode_seeking_runs_on_one_blas_thread_and_restores_the_callers(monkeypatch) -> None:
    """`seek_modes`'s matrix products run on one BLAS thread whatever the process allows
    (a second one only waits on a shared 2-core machine), the caller's setting comes back
    afterwards, and the bytes are those of a process with one thread."""
    from threadpoolctl import threadpool_info, threadpool_limits

    import artic.hierarchy.votes as votes_module

    def blas_threads() -> set[int]:
        return {p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}

    rng = np.random.default_rng(0)
    centres = rng.uniform(-1.0, 1.0, (12, 3))
    points = centres[rng.integers(0, 12, 400)] + rng.normal(0.0, 0.03, (400, 3))
    with threadpool_limits(limits=1, user_api="blas"):
        alone = seek_modes(points, 0.08)
    seen: list[set[int]] = []
    inner = votes_module._seek_modes

    def recorded(*args: object) -> np.ndarray:
        seen.append(blas_threads())
        return inner(*args)

    monkeypatch.setattr(votes_module, "_seek_modes", recorded)
    with threadpool_limits(limits=2, user_api="blas"):
        moved = seek_modes(points, 0.08)
        assert blas_threads() == {2}
    assert seen == [{1}]
    assert moved.tobytes() == alone.tobytes()


@pytest.mark.parametrize("radius", [0.005, 0.02, 0.05, 0.2])
def test_radius_components_are_the_radius_graphs_components_label_for_label(
    radius: float,
) -> None:
    """Votes on their modes (tight clumps, exact duplicates) and scattered strays: the
    components, and their numbering, are scipy's on the whole radius graph."""
    rng = np.random.default_rng(int(radius * 1000))
    modes = rng.uniform(-1.0, 1.0, (12, 3))
    clumps = modes[rng.integers(0, 12, 900)] + rng.normal(0.0, 1e-7, (900, 3))
    strays = rng.uniform(-1.0, 1.0, (300, 3))
    points = rng.permutation(np.concatenate([clumps, strays, clumps[:50]]))
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(points),) * 2)
    count, expected = connected_components(graph, directed=False)
    labels = radius_components(points, radius)
    np.testing.assert_array_equal(labels, expected)
    assert 12 <= count < len(points)
    assert radius_components(points[:1], radius).tolist() == [0]


def test_mirror_averaging_makes_the_outputs_mirror_equivariant() -> None:
    """`inference.mirror_y`: the outputs on a cloud and on its mirror image are averaged,
    so an untrained network segments a mirrored cloud as the mirror image of the cloud
    (to float rounding), and gives the mean of its two plain outputs."""
    torch.manual_seed(0)
    model = PartSegmentationNet(dataclasses.replace(tiny_config(), head="votes")).eval()
    points, _, _ = three_boxes(256, 1)
    flip = np.array(MIRROR_Y, dtype=np.float32)
    plain, mirrored = forward(model, points), forward(model, points * flip)
    averaged, of_mirror = (
        forward(model, points, mirror_y=True),
        forward(model, points * flip, mirror_y=True),
    )
    assert isinstance(plain, VoteOutput) and isinstance(mirrored, VoteOutput)
    assert isinstance(averaged, VoteOutput) and isinstance(of_mirror, VoteOutput)
    f = torch.from_numpy(flip)
    torch.testing.assert_close(averaged.offsets, (plain.offsets + mirrored.offsets * f) / 2)
    prob = (plain.motion_logits.softmax(-1) + mirrored.motion_logits.softmax(-1)) / 2
    torch.testing.assert_close(averaged.motion_logits.softmax(-1), prob)
    torch.testing.assert_close(of_mirror.offsets, averaged.offsets * f, atol=1e-5, rtol=1e-4)
    torch.testing.assert_close(of_mirror.motion_logits.softmax(-1), prob, atol=1e-5, rtol=1e-4)
    assert not torch.allclose(plain.offsets, mirrored.offsets * f, atol=1e-3), (
        "without averaging an untrained network is not mirror-equivariant"
    )
    masks = PartSegmentationNet(tiny_config()).eval()
    with pytest.raises(InputError, match="mirror_y"):
        forward(masks, points, mirror_y=True)


def _slabs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """n points in three 1 m slabs along x with 1 cm gaps: (points (n, 3), part (n,))."""
    rng = np.random.default_rng(7)
    part = rng.integers(0, 3, n)
    points = rng.uniform(0.0, 1.0, (n, 3)).astype(np.float32)
    points[:, 0] += part * 1.01
    return points, part


class _SlabOracle(PartSegmentationNet):
    """A votes network that knows the truth: motion type = part, every offset points at
    the mean of its part's points among those it is given (no normalisation)."""

    def forward(self, points, normals=None, index=None):  # type: ignore[no-untyped-def]
        x = points[0]
        part = (x[:, 0] > 1.005).long() + (x[:, 0] > 2.015).long()
        centre = torch.stack([x[part == p].mean(0) for p in range(3)])
        logits = torch.nn.functional.one_hot(part, 4).float() * 100.0
        return VoteOutput(logits[None], (centre[part] - x)[None], x[None])


def test_passes_put_the_network_on_every_point_of_a_larger_cloud() -> None:
    """`inference.passes`: disjoint farthest-point samples (the first the one-pass sample),
    clustered together. On 1,200 points in slabs 1 cm apart, one pass of 400 labels the
    points between samples by their nearest sample, across the gaps; three passes see
    every point and recover the slabs exactly."""
    points, part = _slabs(1200)
    samples = sample_passes(points, 400, 3)
    assert [len(s) for s in samples] == [400, 400, 400]
    np.testing.assert_array_equal(samples[0], farthest_point_indices(points, 400))
    np.testing.assert_array_equal(np.sort(np.concatenate(samples)), np.arange(1200))
    assert len(sample_passes(points, 400, 10)) == 3 and len(sample_passes(points, 500, 3)) == 2
    np.testing.assert_array_equal(sample_passes(points, 2000, 3)[0], np.arange(1200))
    config = dataclasses.replace(tiny_config(), head="votes", normals=False, normalize=False)
    config = dataclasses.replace(
        config, backbone=dataclasses.replace(config.backbone, in_channels=0)
    )
    oracle = _SlabOracle(config)
    one = segment(oracle, points, InferenceConfig(n_points=400, cluster_radius=0.2))
    three = segment(oracle, points, InferenceConfig(n_points=400, cluster_radius=0.2, passes=3))
    assert instance_iou(one.part_id, part).max(axis=0).min() < 0.99
    np.testing.assert_allclose(instance_iou(three.part_id, part).max(axis=0), 1.0)
    np.testing.assert_array_equal(three.motion_type, part)
    masks = PartSegmentationNet(tiny_config()).eval()
    with pytest.raises(InputError, match="passes"):
        segment(masks, points, InferenceConfig(n_points=400, passes=2))


def _slab_oracle() -> _SlabOracle:
    config = dataclasses.replace(tiny_config(), head="votes", normals=False, normalize=False)
    return _SlabOracle(
        dataclasses.replace(config, backbone=dataclasses.replace(config.backbone, in_channels=0))
    )


def test_choose_inference_finds_the_passes_and_part_size_that_whole_scans_need() -> None:
    """`choose_inference` scores settings on whole scans as `segment` labels them: a 5 cm
    cube of 12 points beside two slabs (738 points) is a point or two of one 246-point
    sample, under the saved minimum part size (3 a sample), but all 12 of three samples
    (over 9): the search takes three passes (mAP 1, every point right), where the saved
    settings miss the cube, and keeps the minimum, since 8 does no better. Candidates no
    better than the current value keep it."""
    rng = np.random.default_rng(3)
    points, part = _slabs(1200)
    keep = np.concatenate([np.flatnonzero(part == 0)[:363], np.flatnonzero(part == 1)[:363]])
    cube = rng.uniform(0.0, 0.05, (12, 3)) + np.array([2.02, 0.0, 0.0])
    points = np.concatenate([points[keep], cube]).astype(np.float32)
    part = np.concatenate([part[keep], np.full(12, 2)]).astype(np.int64)
    scans = [ValidationScan(points, part, noisy) for noisy in (False, True)]
    saved = InferenceConfig(n_points=246, cluster_radius=0.2, min_points=3, min_fraction=0.0)
    oracle = _slab_oracle()
    assert len(np.unique(segment(oracle, points, saved).part_id)) == 2  # no cube
    search = InferenceSearch(passes=(1, 3), min_points=(3, 8))
    chosen, scores = choose_inference(oracle, scans, saved, search)
    assert (chosen.passes, chosen.min_points) == (3, 3)
    first, *_ = scores
    assert first.startswith("passes=1;min_points=3;")
    assert scores[first] < 0.9
    assert max(scores.values()) == pytest.approx(1.0)
    result = segment(oracle, points, chosen)
    np.testing.assert_allclose(instance_iou(result.part_id, part).max(axis=0), 1.0)
    same, tried = choose_inference(oracle, scans, chosen, InferenceSearch(passes=(3,)))
    assert same == chosen and len(tried) == 1


class _ThirdsReadOracle(_SlabOracle):
    """The slab oracle, but it reads the third slab (a translating part) a third each as
    translating, rotating and both: its votes still agree."""

    def forward(self, points, normals=None, index=None):  # type: ignore[no-untyped-def]
        out = super().forward(points, normals, index)
        logits = out.motion_logits.clone()
        third = torch.nonzero(logits[0, :, 2] > 0).flatten()
        logits[0, third[1::3]] = logits[0, third[1::3]].roll(-1, dims=-1)  # -> rotating
        logits[0, third[2::3]] = logits[0, third[2::3]].roll(1, dims=-1)  # -> both
        return out._replace(motion_logits=logits)


def test_choose_inference_clusters_moving_types_together_where_that_scores() -> None:
    """A part the network reads as three moving types is three parts of a third of its
    points each per type (not found at IoU 0.5: mAP under 1) and whole with
    `moving_together`, which the search takes as its first step; segment then recovers
    every slab."""
    points, part = _slabs(600)
    oracle = _ThirdsReadOracle(_slab_oracle().config)
    saved = InferenceConfig(n_points=600, cluster_radius=0.2, min_points=3, min_fraction=0.0)
    apart = segment(oracle, points, saved)
    assert instance_iou(apart.part_id, part).max(axis=0)[2] < 0.4
    scans = [ValidationScan(points, part, noisy) for noisy in (False, True)]
    search = InferenceSearch(moving_together=(True,))
    chosen, scores = choose_inference(oracle, scans, saved, search)
    assert chosen.moving_together and len(scores) == 2
    assert max(scores.values()) == pytest.approx(1.0)
    assert min(scores.values()) < 0.7
    together = segment(oracle, points, chosen)
    np.testing.assert_allclose(instance_iou(together.part_id, part).max(axis=0), 1.0)


def test_modes_per_pass_seek_each_sample_among_its_own_votes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """`inference.modes_per_pass`: each pass's votes climb to their modes among that pass's
    own votes before all are clustered together. On slabs whose oracle votes for each
    sample's own part means (which differ from pass to pass by the sampling), three passes
    give every slab exactly, as the mean shift over all votes does, with the kernel formed
    over one sample's votes at a time (a third of the points per call); with one pass the
    option changes nothing."""
    import artic.hierarchy.votes as votes_module

    sizes: list[int] = []
    seek = votes_module.seek_modes

    def recorded(points, bandwidth, iterations=votes_module.MODE_ITERATIONS):  # type: ignore[no-untyped-def]
        sizes.append(len(points))
        return seek(points, bandwidth, iterations)

    monkeypatch.setattr(votes_module, "seek_modes", recorded)
    points, part = _slabs(1200)
    oracle = _slab_oracle()
    joint = InferenceConfig(n_points=400, cluster_radius=0.1, mode_bandwidth=0.05, passes=3)
    per_pass = joint.model_copy(update={"modes_per_pass": True})
    together = segment(oracle, points, joint)
    joint_sizes, sizes[:] = list(sizes), []
    apart = segment(oracle, points, per_pass)
    np.testing.assert_allclose(instance_iou(apart.part_id, part).max(axis=0), 1.0)
    np.testing.assert_array_equal(apart.part_id, together.part_id)
    assert sum(joint_sizes) == sum(sizes) == 1200 and len(sizes) == 3 * len(joint_sizes)
    assert max(sizes) <= max(joint_sizes) // 2
    one = joint.model_copy(update={"passes": 1})
    plain = segment(oracle, points, one)
    flagged = segment(oracle, points, one.model_copy(update={"modes_per_pass": True}))
    np.testing.assert_array_equal(plain.part_id, flagged.part_id)
    np.testing.assert_array_equal(plain.part_confidence, flagged.part_confidence)
    scans = [ValidationScan(points, part, noisy) for noisy in (False, True)]
    chosen, scores = choose_inference(oracle, scans, joint, InferenceSearch(modes_per_pass=(True,)))
    assert chosen == joint  # a tie keeps the saved setting
    assert sorted(scores) == sorted(
        [
            "passes=3;min_points=8;radius=0.1,0.1,0.1,0.1;h=0.05",
            "passes=3;min_points=8;radius=0.1,0.1,0.1,0.1;h=0.05;modes_per_pass",
        ]
    )
    assert list(scores.values()) == pytest.approx([1.0, 1.0])


def test_merged_passes_are_in_the_first_passes_frame() -> None:
    """`merge_passes`: each run's normalised points and offsets mapped into the first run's
    normalisation frame, so shifted points of every run are comparable."""
    points, _ = _slabs(900)
    samples = sample_passes(points, 300, 3)
    rng = np.random.default_rng(1)
    outputs, frames = [], []
    for s in samples:
        xyz = normalize_points(torch.from_numpy(points[s])[None])
        offsets = torch.from_numpy(rng.normal(0, 0.1, (1, 300, 3)).astype(np.float32))
        outputs.append(VoteOutput(torch.zeros(1, 300, 4), offsets, xyz))
        frames.append(normalization_frame(points[s]))
    merged = merge_passes(outputs, frames)
    centre, radius = frames[0]
    allpts = points[np.concatenate(samples)].astype(np.float64)
    np.testing.assert_allclose(merged.xyz[0].numpy(), (allpts - centre) / radius, atol=1e-5)
    metres = np.concatenate(
        [
            c + r * (o.xyz[0] + o.offsets[0]).numpy()
            for o, (c, r) in zip(outputs, frames, strict=True)
        ]
    )
    shifted = (merged.xyz[0] + merged.offsets[0]).numpy()
    np.testing.assert_allclose(shifted, (metres - centre) / radius, atol=1e-5)
    assert merged.motion_logits.shape == (1, 900, 4)


def test_offset_weight_reaches_the_network_config() -> None:
    from artic.hierarchy.config import SegmenterModelConfig

    assert SegmenterModelConfig(head="votes").network().offset_weight == "points"
    parts = SegmenterModelConfig(head="votes", offset_weight="parts").network()
    assert parts.offset_weight == "parts"
