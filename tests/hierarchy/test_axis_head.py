"""The segmenter's axis head: per point, whether its part moves about a vertical axis, and
the cut of a part whose points read two axes (`model.axis_head`, `inference.axis_split`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from test_segmentation import three_boxes, tiny_config

from artic.hierarchy.fit_segmenter import (
    PreparedCloud,
    SegmentationData,
    fit_axis_head,
    with_axis_head,
)
from artic.hierarchy.models import load_segmenter, save_segmenter
from artic.hierarchy.segmentation import (
    MIRROR_Y,
    InferenceConfig,
    PartSegmentationNet,
    forward,
    make_optimizer,
    segment,
    train_step,
)
from artic.hierarchy.votes import (
    Clusters,
    VoteOutput,
    axis_targets,
    smooth_within_parts,
    split_by_axis,
    vote_loss,
)
from artic.objects.tree import JointAxis, KinematicTree


def _axis(direction: tuple[float, float, float]) -> JointAxis:
    return JointAxis(np.zeros(3), np.asarray(direction, dtype=np.float64))


def test_axis_targets_read_each_parts_joint_axis():
    """A caster (vertical) carrying a wheel (horizontal), a fixed part and the root: only
    the parts on a moving joint's axis have a target."""
    tree = KinematicTree(
        num_parts=4, root=0, edges=((0, 1), (1, 2), (0, 3)), motion_types=(0, 1, 1, 0),
        joint_types=("revolute", "revolute", "fixed"),
        axes=(_axis((0.0, 0.0, -1.0)), _axis((0.0, 1.0, 0.0)), None),
    )  # fmt: skip
    part_id = np.array([0, 1, 1, 2, 3, -1, 2])
    np.testing.assert_array_equal(axis_targets(part_id, tree), [-1, 1, 1, 0, -1, -1, 0])


def test_a_part_whose_points_read_two_axes_is_cut_in_two():
    """Part 0 (moving): 12 points read vertical, 8 horizontal -> two parts; part 1: one
    stray vertical point of 10, under the minimum size -> whole; part 2 (static) -> whole
    whatever its points read. Each half's confidence: the part's x its axis' probability."""
    label = np.array([0] * 20 + [1] * 10 + [2] * 6)
    vertical = np.array([0.9] * 12 + [0.2] * 8 + [0.9] + [0.1] * 9 + [0.9] * 3 + [0.1] * 3)
    static = np.array([False] * 30 + [True] * 6)
    split = split_by_axis(Clusters(label, np.array([0.8, 0.6, 0.5], dtype=np.float32)),
                          vertical.astype(np.float32), static, min_size=5)  # fmt: skip
    sizes = np.bincount(split.label)
    np.testing.assert_array_equal(sizes, [12, 10, 8, 6])  # by decreasing size
    np.testing.assert_array_equal(split.label[:12], 0)
    np.testing.assert_array_equal(split.label[12:20], 2)
    np.testing.assert_allclose(split.confidence, [0.8 * 0.9, 0.6, 0.8 * 0.8, 0.5], rtol=1e-6)
    # no cut when each side is smaller than the minimum
    whole = split_by_axis(Clusters(label, np.ones(3, dtype=np.float32)),
                          vertical.astype(np.float32), static, min_size=9)  # fmt: skip
    np.testing.assert_array_equal(whole.label, label)
    # ... or than the share of the part: 8 of 20 points is 40%
    for share, parts in ((0.4, 4), (0.45, 3)):
        cut = split_by_axis(Clusters(label, np.ones(3, dtype=np.float32)),
                            vertical.astype(np.float32), static, 5, share)  # fmt: skip
        assert cut.label.max() + 1 == parts


def _caster_and_wheel() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One moving part of 30 points: a caster (8 points above, z 1.0-1.07, reading
    vertical) on a wheel (22 below, z 0-0.21), with two of the wheel's points misread
    vertical and one of the caster's horizontal; and a seat (part 1) far away, 12 points
    reading horizontal but for three scattered misread ones."""
    rng = np.random.default_rng(0)
    caster = np.c_[rng.uniform(0, 0.05, (8, 2)), np.linspace(1.0, 1.07, 8)]
    wheel = np.c_[rng.uniform(0, 0.05, (22, 2)), np.linspace(0.0, 0.21, 22)]
    seat = np.c_[rng.uniform(5, 6, (12, 2)), np.zeros(12)]
    xyz = np.concatenate([caster, wheel, seat])
    label = np.array([0] * 30 + [1] * 12)
    vertical = np.array([0.9] * 7 + [0.3] + [0.1] * 22 + [0.1] * 12, dtype=np.float32)
    vertical[[12, 25]] = 0.8  # the wheel's misread points
    vertical[[31, 35, 40]] = 0.9  # the seat's
    return xyz, label, vertical


def test_smoothing_within_parts_outvotes_stray_readings_and_keeps_a_block():
    """Each point's reading becomes its part's k nearest points' mean: the wheel's and the
    seat's stray vertical readings fall under one half, the caster's misread point rises
    above it, and no reading crosses a part (the seat's points never read the caster's)."""
    xyz, label, vertical = _caster_and_wheel()
    smooth = smooth_within_parts(vertical, xyz, label, 4)
    assert (smooth[:8] > 0.5).all() and (smooth[8:] < 0.5).all()
    # a part of fewer points than k: every point takes the part's mean
    one = smooth_within_parts(vertical[:3], xyz[:3], np.zeros(3, dtype=np.int64), 5)
    np.testing.assert_allclose(one, vertical[:3].mean(), rtol=1e-6)
    # k = 1: each point its own neighbour, nothing changes
    np.testing.assert_allclose(smooth_within_parts(vertical, xyz, label, 1), vertical)


def test_the_cut_after_smoothing_separates_the_caster_exactly():
    """Unsmoothed, the cut takes the wheel's two misread points with the caster and
    leaves the caster's misread point on the wheel, and cuts the seat's three strays off
    when no share is asked; smoothed (k 4), the caster's 8 points are one part, the wheel's
    22 another, the seat whole."""
    xyz, label, vertical = _caster_and_wheel()
    static = np.zeros(len(label), dtype=bool)
    clusters = Clusters(label, np.ones(2, dtype=np.float32))
    raw = split_by_axis(clusters, vertical, static, 2)
    assert raw.label.max() + 1 == 4
    assert not (raw.label[:8] == raw.label[0]).all()
    cut = split_by_axis(clusters, smooth_within_parts(vertical, xyz, label, 4), static, 2, 0.0)
    assert cut.label.max() + 1 == 3
    for members in (np.arange(8), np.arange(8, 30), np.arange(30, 42)):
        assert len(np.unique(cut.label[members])) == 1
    assert len(np.unique(cut.label[[0, 8, 30]])) == 3


def test_the_axis_loss_joins_the_total_only_where_it_has_targets():
    xyz = torch.randn(1, 6, 3, generator=torch.Generator().manual_seed(0))
    ids = torch.tensor([[0, 0, 1, 1, 2, 2]])
    types = torch.tensor([[0, 0, 1, 1, 1, 1]])
    logits = torch.zeros(1, 6, 4)
    plain = vote_loss(VoteOutput(logits, torch.zeros(1, 6, 3), xyz), ids, types)
    assert float(plain.axis) == 0.0
    targets = torch.tensor([[-1, -1, 1, 1, 0, 0]])
    right = torch.tensor([[50.0, -50.0, 20.0, 20.0, -20.0, -20.0]])  # the first two ignored
    good = vote_loss(VoteOutput(logits, torch.zeros(1, 6, 3), xyz, right), ids, types,
                     axis_vertical=targets)  # fmt: skip
    bad = vote_loss(VoteOutput(logits, torch.zeros(1, 6, 3), xyz, -right), ids, types,
                    axis_vertical=targets)  # fmt: skip
    assert float(good.axis) < 1e-6 and float(bad.axis) > 10.0
    assert float(good.total) == pytest.approx(float(plain.total), abs=1e-6)
    assert float(bad.total) == pytest.approx(float(plain.total) + float(bad.axis), rel=1e-6)


def _boxes_data(config, seed: int) -> SegmentationData:  # type: ignore[no-untyped-def]
    """Two clouds of the three boxes, the static box with no target, box 1 vertical and
    box 2 horizontal, with their normals and neighbourhoods."""
    clouds, axes = [], []
    for k in range(2):
        points, part, motion = three_boxes(256, seed + k)
        clouds.append(PreparedCloud(points, part, motion))
        axes.append(np.where(part == 1, 1, np.where(part == 2, 0, -1)).astype(np.int64))
    data = SegmentationData.stack(clouds, [0, 1], [False, False], axes)
    return data.with_features(config, None)


def test_fitting_the_axis_head_leaves_every_other_weight_and_reads_the_axes(tmp_path):
    """`with_axis_head` + `fit_axis_head`: the head learns which box turns about a vertical
    axis; every other weight keeps its bytes, so the motion types and the offsets are the
    model's own; mirror averaging keeps the axis reading; the model file round-trips."""
    torch.manual_seed(0)
    base = PartSegmentationNet(dataclasses.replace(tiny_config(), head="votes"))
    data = _boxes_data(base.config, 0)
    optimizer = make_optimizer(base, lr=1e-3)  # features that know the boxes apart
    for step in range(150):
        train_step(base, optimizer, data.batch(np.array([step % 2])))
    base.eval()
    model = with_axis_head(base)
    before = {k: v.clone() for k, v in model.state_dict().items()}
    fit = fit_axis_head(model, data, data, epochs=60, seed=0, lr=1e-2, batch_points=128)
    assert fit.losses[-1] < 0.5 * fit.losses[0]
    assert fit.val_accuracy > 0.9
    after = model.state_dict()
    changed = {k for k in before if not torch.equal(before[k], after[k])}
    assert changed and all(k.startswith("axis.") for k in changed)
    points = data.points[0]
    out = forward(model, points)
    plain = forward(base, points)
    assert isinstance(out, VoteOutput) and isinstance(plain, VoteOutput)
    assert out.axis_logits is not None and plain.axis_logits is None
    torch.testing.assert_close(out.offsets, plain.offsets)
    mirrored = forward(model, points * np.float32(MIRROR_Y), None, None, mirror_y=True)
    both = forward(model, points, None, None, mirror_y=True)
    assert isinstance(mirrored, VoteOutput) and isinstance(both, VoteOutput)
    assert mirrored.axis_logits is not None and both.axis_logits is not None
    torch.testing.assert_close(mirrored.axis_logits, both.axis_logits, atol=1e-4, rtol=1e-4)
    inference = InferenceConfig(cluster_radius=0.1, n_points=256, axis_split=True)
    save_segmenter(tmp_path / "model.pt", "storage_furniture", model, inference, {})
    loaded = load_segmenter(tmp_path / "model.pt", "storage_furniture")
    assert loaded.model.config.axis_head and loaded.inference.axis_split
    a, b = segment(model, points, inference), segment(loaded.model, points, loaded.inference)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def test_a_votes_model_without_the_head_cannot_be_fitted():
    model = PartSegmentationNet(dataclasses.replace(tiny_config(), head="votes"))
    with pytest.raises(ValueError, match="no axis head"):
        fit_axis_head(model, _boxes_data(model.config, 0), _boxes_data(model.config, 0), 1, 0)
