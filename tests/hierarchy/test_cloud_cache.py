"""The segmenter's per-cloud cache: a cached load equals a fresh compute, damaged files
are recomputed, concurrent writers leave a valid file, keys follow content and config."""

from __future__ import annotations

import dataclasses
import multiprocessing
from pathlib import Path

import numpy as np
import pytest
import torch
from numpy.typing import NDArray

from artic.artifacts.formats import read_npz
from artic.hierarchy.cloud_cache import (
    CloudFeatures,
    cache_key,
    cloud_features,
    compute_cloud_features,
    feature_arrays,
    segmenter_cache_dir,
)
from artic.hierarchy.config import SegmenterModelConfig
from artic.hierarchy.pointnet2 import PointNet2, stack_indices
from artic.hierarchy.segmentation import SegmentationConfig, normalize_points


def _config() -> SegmentationConfig:
    return SegmenterModelConfig(width=0.25, centroids=(256, 64)).network()


def _cloud(seed: int, n: int = 1024) -> NDArray[np.float32]:
    rng = np.random.default_rng(seed)
    return (rng.uniform(0, 1, (n, 3)) * [0.8, 0.5, 1.2]).astype(np.float32)


def _assert_same(a: CloudFeatures, b: CloudFeatures) -> None:
    """Same arrays, dtypes and bytes."""
    arrays_a, arrays_b = feature_arrays(a), feature_arrays(b)
    assert list(arrays_a) == list(arrays_b)
    for key in arrays_a:
        assert arrays_a[key].dtype == arrays_b[key].dtype, key
        assert arrays_a[key].tobytes() == arrays_b[key].tobytes(), key


def test_cached_load_equals_a_fresh_compute(tmp_path: Path) -> None:
    cache = segmenter_cache_dir(tmp_path / "scans")
    assert cache == tmp_path / "scans" / ".cache" / "segmenter"
    points, config = _cloud(0), _config()
    first = cloud_features(points, config, cache)
    files = list(cache.glob("*.npz"))
    assert [f.name for f in files] == [f"{cache_key(points, config, 16)}.npz"]
    assert not list(cache.glob(".*"))  # no temporary file left behind
    again = cloud_features(points, config, cache)
    uncached = cloud_features(points, config, None)
    _assert_same(first, again)
    _assert_same(first, uncached)
    # and it is what the backbone computes on the fly: indices narrowed, values equal
    fresh = compute_cloud_features(points, config)
    np.testing.assert_array_equal(again.normals, fresh.normals)
    for got, want in zip(again.neighbourhoods, fresh.neighbourhoods, strict=True):
        for g, w in zip(got, want, strict=True):
            assert g.dtype in (torch.int16, torch.float32)
            assert torch.equal(g.to(w.dtype), w)


def test_cached_index_runs_the_network_like_the_on_the_fly_one(tmp_path: Path) -> None:
    config = _config()
    clouds = [_cloud(seed) for seed in (1, 2)]
    index = stack_indices([cloud_features(c, config, tmp_path).neighbourhoods for c in clouds])
    torch.manual_seed(0)
    net = PointNet2(config.backbone).eval()
    xyz = normalize_points(torch.from_numpy(np.stack(clouds)))
    with torch.no_grad():
        torch.testing.assert_close(
            net(xyz, index=index).point_features, net(xyz).point_features, rtol=1e-4, atol=1e-5
        )


def test_key_follows_the_points_and_the_neighbourhood_settings_only() -> None:
    points, config = _cloud(3), _config()
    key = cache_key(points, config, 16)
    moved = points.copy()
    moved[5, 0] += 1e-3
    assert cache_key(moved, config, 16) != key
    assert cache_key(points, config, 8) != key
    wider = SegmenterModelConfig(width=0.5, centroids=(256, 64)).network()
    assert cache_key(points, wider, 16) == key  # widths do not change neighbourhoods
    other = SegmenterModelConfig(width=0.25, centroids=(128, 64)).network()
    assert cache_key(points, other, 16) != key
    assert cache_key(points, dataclasses.replace(config, normalize=False), 16) != key


@pytest.mark.parametrize("damage", ["truncate", "garbage", "empty", "wrong_shape", "bad_index"])
def test_a_damaged_cache_file_is_recomputed(tmp_path: Path, damage: str) -> None:
    points, config = _cloud(4), _config()
    good = cloud_features(points, config, tmp_path)
    (path,) = tmp_path.glob("*.npz")
    data = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "garbage":
        path.write_bytes(b"not a zip file at all")
    elif damage == "empty":
        path.write_bytes(b"")
    else:
        arrays = read_npz(path)
        if damage == "wrong_shape":
            arrays["normals"] = arrays["normals"][:-1]
        else:
            arrays["neighbours_0"] = arrays["neighbours_0"].copy()
            arrays["neighbours_0"][0, 0, 0] = 5000  # beyond the cloud's 1,024 points
        np.savez(path, **arrays)  # type: ignore[arg-type]
    recomputed = cloud_features(points, config, tmp_path)
    _assert_same(recomputed, good)
    _assert_same(cloud_features(points, config, tmp_path), good)  # the file was rewritten
    assert path.read_bytes() == data


def test_an_unwritable_cache_folder_only_costs_the_caching(tmp_path: Path) -> None:
    blocker = tmp_path / "scans"
    blocker.write_text("a file where the folder should be")
    points, config = _cloud(5), _config()
    _assert_same(
        cloud_features(points, config, blocker / ".cache"), cloud_features(points, config, None)
    )


def _write_same_key(cache: str, barrier: multiprocessing.synchronize.Barrier) -> None:
    torch.set_num_threads(1)
    barrier.wait()
    for _ in range(3):
        for path in Path(cache).glob("*.npz"):  # make every round a race to write
            path.unlink(missing_ok=True)
        cloud_features(_cloud(6), _config(), Path(cache))


def test_two_processes_writing_the_same_key_leave_a_valid_file(tmp_path: Path) -> None:
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(2)
    workers = [ctx.Process(target=_write_same_key, args=(str(tmp_path), barrier)) for _ in range(2)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(timeout=120)
        assert w.exitcode == 0
    (path,) = tmp_path.glob("*.npz")
    assert not list(tmp_path.glob(".*"))
    expected = cloud_features(_cloud(6), _config(), None)
    arrays = read_npz(path)
    for key, array in feature_arrays(expected).items():
        assert arrays[key].tobytes() == array.tobytes()
