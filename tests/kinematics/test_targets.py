"""Label normalisation, preprocessing and the data splits of the MDN."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from numpy.typing import NDArray

from artic.artifacts.depth_dataset import DepthDataset
from artic.geometry.camera import CameraIntrinsics
from artic.kinematics.data import load_split, split_of
from artic.kinematics.preprocess import (
    DEPTH_SCALE_M,
    RELATIVE_DEPTH_M,
    SIDE_FEATURES,
    InputPipeline,
    NetworkInput,
    augment,
    full_image,
)
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


CAMERA = CameraIntrinsics(fx=140, fy=140, cx=63.5, cy=63.5, width=128, height=128)


def test_full_image_masks_and_scales():
    depth = np.array([[0.0, 2.0], [7.0, np.nan]], dtype=np.float32)
    x = full_image(depth)
    assert x.shape == (1, 1, 2, 2) and x.dtype == torch.float32
    assert x[0, 0].tolist() == [[0.0, 2.0 / DEPTH_SCALE_M], [0.0, 0.0]]
    mask = np.array([[True, False], [True, True]])
    assert full_image(depth, mask)[0, 0, 0, 1] == 0.0


def _plane(rows: slice, cols: slice, depth: float = 2.0) -> NDArray[np.float32]:
    image = np.zeros((128, 128), np.float32)
    image[rows, cols] = depth
    return image


def test_crop_is_object_centred_and_its_side_features_locate_it():
    small = _plane(slice(50, 60), slice(20, 30))  # 10 px square left of the centre
    large = _plane(slice(30, 90), slice(40, 100))  # 60 px square right of the centre
    x = InputPipeline(CAMERA, 32)(np.stack([small, large]))
    assert x.image.shape == (2, 1, 32, 32) and x.side.shape == (2, SIDE_FEATURES)
    for k in range(2):  # the object fills the same central part of the crop at any size
        inside = x.image[k, 0] > 0
        assert 0.5 < float(inside.float().mean()) < 0.85  # (10 / 13)^2, (60 / 68)^2
        assert bool(inside[16, 16]) and not bool(inside[0, 0])
        # a flat object at the mean depth: relative depth 1 everywhere on it
        assert torch.allclose(x.image[k, 0][inside], torch.tensor(1.0))
    s = x.side
    assert torch.allclose(s[:, 0], torch.tensor(2.0))  # mean depth = the centroid's x
    # the centroid's lateral offset: pixel column 24.5, (63.5 - 24.5) / 140 * 2 m to the left
    assert float(s[0, 1]) == pytest.approx((63.5 - 24.5) / 140 * 2.0, abs=1e-5)
    assert float(s[1, 1]) < 0 < float(s[0, 1])  # left of the optical axis is +y
    assert float(s[1, 5]) > 5 * float(s[0, 5])  # angular size
    assert s[:, 7:].sum() == 0  # neither touches the border


def test_crop_relative_depth_border_flags_mask_and_empty_images():
    step = _plane(slice(0, 40), slice(100, 128))  # touches the top and right borders
    step[:, 100:114] = np.where(step[:, 100:114] > 0, 2.5, 0)  # half of it 0.5 m farther
    x = InputPipeline(CAMERA, 32)(step)
    values = torch.unique(x.image[x.image > 0])
    # mean depth 2.25: the near half at 1 - 0.25 / 0.5, the far half at 1 + 0.25 / 0.5
    assert values.tolist() == pytest.approx(
        [1 - 0.25 / RELATIVE_DEPTH_M, 1 + 0.25 / RELATIVE_DEPTH_M]
    )
    assert x.side[0, 7:].tolist() == [1.0, 0.0, 0.0, 1.0]  # top, bottom, left, right
    mask = np.zeros((128, 128), bool)
    mask[:, 114:] = True  # only the near half is the object
    near = InputPipeline(CAMERA, 32)(step, mask)
    assert torch.allclose(near.image[near.image > 0], torch.tensor(1.0))
    assert float(near.side[0, 0]) == pytest.approx(2.0)
    empty = InputPipeline(CAMERA, 32)(np.zeros((128, 128), np.float32))
    assert float(empty.image.abs().sum()) == 0 and float(empty.side.abs().sum()) == 0
    with pytest.raises(ValueError, match="camera is 128x128"):
        InputPipeline(CAMERA, 32)(np.zeros((64, 64), np.float32))


def test_augment_drops_up_to_the_rate_and_is_seeded():
    x = NetworkInput(torch.ones((64, 1, 16, 16)), torch.ones((64, SIDE_FEATURES)))
    a = augment(x, 0.2, torch.Generator().manual_seed(1))
    b = augment(x, 0.2, torch.Generator().manual_seed(1))
    assert torch.equal(a.image, b.image) and torch.equal(a.side, x.side)
    dropped = 1 - a.image.mean(dim=(1, 2, 3))
    assert 0 < float(dropped.max()) < 0.3 and float(dropped.mean()) == pytest.approx(0.1, abs=0.03)
    assert torch.equal(augment(x, 0.0, torch.Generator()).image, x.image)


def test_splits_are_by_object_and_disjoint(tiny_depth):
    ds = DepthDataset.open(tiny_depth)
    parts = {s: load_split(ds, s, val_every=2) for s in ("train", "val", "test")}
    ids = {s: set(p.object_id.tolist()) for s, p in parts.items()}
    assert ids["train"] and ids["val"] and ids["test"]
    assert not (ids["train"] & ids["val"]) and not (ids["train"] | ids["val"]) & ids["test"]
    assert sum(len(p) for p in parts.values()) == ds.info.images
    camera = ds.info.camera
    x = InputPipeline(camera, 32)(parts["train"].depth_m(np.arange(2)))
    assert x.image.shape == (2, 1, 32, 32) and float(x.image.max()) > 0
    one = load_split(ds, "train", val_every=2, max_objects=1)
    assert len(set(one.object_id.tolist())) == 1
    labels = split_of(np.array([0, 1, 2, 3]), np.array([False, False, True, False]), 2)
    assert labels.tolist() == ["train", "val", "test", "val"]
