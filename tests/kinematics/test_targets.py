"""Label normalisation, preprocessing and the data splits of the MDN."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from artic.artifacts.depth_dataset import DepthDataset
from artic.kinematics.data import load_split, split_of
from artic.kinematics.preprocess import DEPTH_SCALE_M, augment, network_input
from artic.kinematics.targets import TargetCodec


def test_codec_round_trip_and_constant_columns():
    rng = np.random.default_rng(0)
    labels = rng.normal([1.0, -2.0, 0.0], [0.5, 3.0, 1.0], (500, 3))
    labels[:, 2] = 1.0  # a column that never varies
    codec = TargetCodec.fit(["a", "b", "c"], labels)
    z = codec.encode(labels)
    assert z.shape == (500, 2) and z.dtype == np.float32 and codec.learned_columns == ["a", "b"]
    np.testing.assert_allclose(z.mean(axis=0), 0, atol=1e-6)
    np.testing.assert_allclose(z.std(axis=0), 1, atol=1e-5)
    np.testing.assert_allclose(codec.decode(z), labels, atol=1e-5)
    scale = codec.decode_scale(np.ones((4, 2)))
    np.testing.assert_allclose(scale[0], [labels[:, 0].std(), labels[:, 1].std(), 0.0])
    again = TargetCodec.from_dict(codec.to_dict())
    np.testing.assert_array_equal(again.encode(labels), z)
    with pytest.raises(ValueError):
        TargetCodec.fit(["a"], labels)


def test_network_input_masks_and_scales():
    depth = np.array([[0.0, 2.0], [7.0, np.nan]], dtype=np.float32)
    x = network_input(depth)
    assert x.shape == (1, 1, 2, 2) and x.dtype == torch.float32
    assert x[0, 0].tolist() == [[0.0, 2.0 / DEPTH_SCALE_M], [0.0, 0.0]]
    mask = np.array([[True, False], [True, True]])
    assert network_input(depth, mask)[0, 0, 0, 1] == 0.0


def test_augment_drops_up_to_the_rate_and_is_seeded():
    x = torch.ones((64, 1, 16, 16))
    a = augment(x, 0.2, torch.Generator().manual_seed(1))
    b = augment(x, 0.2, torch.Generator().manual_seed(1))
    assert torch.equal(a, b)
    dropped = 1 - a.mean(dim=(1, 2, 3))
    assert 0 < float(dropped.max()) < 0.3 and float(dropped.mean()) == pytest.approx(0.1, abs=0.03)
    assert torch.equal(augment(x, 0.0, torch.Generator()), x)


def test_splits_are_by_object_and_disjoint(tiny_depth):
    ds = DepthDataset.open(tiny_depth)
    parts = {s: load_split(ds, s, val_every=2) for s in ("train", "val", "test")}
    ids = {s: set(p.object_id.tolist()) for s, p in parts.items()}
    assert ids["train"] and ids["val"] and ids["test"]
    assert not (ids["train"] & ids["val"]) and not (ids["train"] | ids["val"]) & ids["test"]
    assert sum(len(p) for p in parts.values()) == ds.info["images"]
    x = parts["train"].inputs(np.arange(2))
    assert x.shape[:2] == (2, 1) and float(x.max()) > 0
    one = load_split(ds, "train", val_every=2, max_objects=1)
    assert len(set(one.object_id.tolist())) == 1
    labels = split_of(np.array([0, 1, 2, 3]), np.array([False, False, True, False]), 2)
    assert labels.tolist() == ["train", "val", "test", "val"]
