"""Per-cloud inputs of the segmenter computed once and kept on disk, keyed by content.

A training cloud is the same every epoch (rotation about z changes no distance), so its
normals and the PointNet++ neighbourhoods (`pointnet2.BackboneIndex`) are computed once:
`cloud_features(points, config, cache_dir)` returns them from
`<cache_dir>/<key>.npz` when that file is there and sound, else computes and stores them.

- key: SHA-256 of `CACHE_VERSION`, the points' float32 bytes and shape, and the config
  fields the result depends on (normalisation, each set-abstraction level's centroids,
  radius and ball size, the normals' k) -- not the layer widths, so one cache serves
  every width.
- beside the scans: `segmenter_cache_dir(scans)` is `<scans>/.cache/segmenter/` (a
  hidden folder: manifests skip it, so the scans' manifest stays valid).
- written atomically (a unique temporary file in the same folder, then `os.replace`), so
  processes computing the same key concurrently each leave a whole file; a file that
  cannot be read, lacks an array, or has the wrong shapes or out-of-range indices is
  recomputed and replaced, never trusted. A folder that cannot be written (read-only
  scans) only costs the caching.
- indices stored as int16 (clouds of up to 32,768 points; int32 above), the weights and
  normals as float32: about 50 KB per 1,024-point cloud of `experiment=ch4_cpu`.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray

from artic.artifacts.formats import read_npz, replace_file, write_npz
from artic.errors import InputError
from artic.hierarchy.normals import estimate_normals
from artic.hierarchy.pointnet2 import BackboneIndex, PointNet2Config, backbone_index

if TYPE_CHECKING:  # segmentation.py may import this module: no cycle at import time
    from artic.hierarchy.segmentation import SegmentationConfig

log = logging.getLogger("artic")

#: bump when backbone_index or estimate_normals change what they compute
CACHE_VERSION = 1
NORMALS_K = 16
_FIELDS = ("centres", "neighbours", "interpolation_index", "weights")


class CloudFeatures(NamedTuple):
    """What the segmenter needs of one cloud besides its points."""

    normals: NDArray[np.float32]  # (N, 3) unit, oriented away from the centroid
    neighbourhoods: BackboneIndex  # batch axis of 1; `pointnet2.stack_indices` joins clouds


def segmenter_cache_dir(scans: Path) -> Path:
    """Where the segmenter's per-cloud cache of a scans folder lives."""
    return scans / ".cache" / "segmenter"


def cache_key(points: NDArray[np.float32], config: SegmentationConfig, normals_k: int) -> str:
    """Hex SHA-256 naming the cache file of `points` (N, 3) float32 under `config`."""
    levels = [[s.n_centroids, s.radius, s.n_neighbours] for s in config.backbone.set_abstractions]
    settings = {
        "version": CACHE_VERSION,
        "normalize": config.normalize,
        "levels": levels,
        "normals_k": normals_k,
        "shape": list(points.shape),
    }
    digest = hashlib.sha256(json.dumps(settings, sort_keys=True).encode())
    digest.update(np.ascontiguousarray(points, dtype="<f4").tobytes())
    return digest.hexdigest()


def compute_cloud_features(
    points: ArrayLike, config: SegmentationConfig, normals_k: int = NORMALS_K
) -> CloudFeatures:
    """Normals (of the cloud as given, metres) and the backbone's neighbourhoods (of the
    cloud as the backbone sees it: normalised when `config.normalize`) of one cloud
    `points` (N, 3) -- the network's input, i.e. after downsampling."""
    from artic.hierarchy.segmentation import normalize_points

    pts = np.asarray(points, dtype=np.float32)
    xyz = torch.from_numpy(pts).unsqueeze(0)
    if config.normalize:
        xyz = normalize_points(xyz)
    return CloudFeatures(estimate_normals(pts, k=normals_k), backbone_index(xyz, config.backbone))


def cloud_features(
    points: ArrayLike,
    config: SegmentationConfig,
    cache_dir: Path | None,
    normals_k: int = NORMALS_K,
) -> CloudFeatures:
    """`compute_cloud_features`, read from `cache_dir` when cached there (module
    docstring); `cache_dir=None` computes without caching. The result is the same either
    way, to the byte."""
    pts = np.ascontiguousarray(points, dtype=np.float32)
    if cache_dir is None:
        return _narrow(compute_cloud_features(pts, config, normals_k))
    path = cache_dir / f"{cache_key(pts, config, normals_k)}.npz"
    if path.is_file():
        cached = _load(path, len(pts), config.backbone)
        if cached is not None:
            return cached
        log.warning("recomputing the unreadable or inconsistent cache file %s", path)
    features = _narrow(compute_cloud_features(pts, config, normals_k))
    _store(path, features)
    return features


def feature_arrays(features: CloudFeatures) -> dict[str, NDArray[Any]]:
    """The arrays of one cloud's features, named `normals`, `centres_0`, ... (npz keys)."""
    arrays: dict[str, NDArray[Any]] = {"normals": features.normals}
    for name, tensors in zip(_FIELDS, features.neighbourhoods, strict=True):
        for level, tensor in enumerate(tensors):
            arrays[f"{name}_{level}"] = tensor.numpy()
    return arrays


def _narrow(features: CloudFeatures) -> CloudFeatures:
    """Indices as int16 when every one fits (else int32), weights float32."""
    index = features.neighbourhoods
    top = max(int(t.max()) for field in index[:3] for t in field if t.numel())
    dtype = torch.int16 if top <= torch.iinfo(torch.int16).max else torch.int32

    def to(ts: tuple[torch.Tensor, ...], dtype: torch.dtype) -> tuple[torch.Tensor, ...]:
        return tuple(t.to(dtype) for t in ts)

    narrow = BackboneIndex(
        to(index.centres, dtype),
        to(index.neighbours, dtype),
        to(index.interpolation_index, dtype),
        to(index.weights, torch.float32),
    )
    return CloudFeatures(features.normals, narrow)


def _expected(n: int, config: PointNet2Config) -> dict[str, tuple[tuple[int, ...], int]]:
    """npz key -> (shape, bound) for one cloud of n points: an index array's entries lie
    in [0, bound) (the number of points of the level it points into)."""
    expected: dict[str, tuple[tuple[int, ...], int]] = {"normals": ((n, 3), 0)}
    sizes = [n]  # points per level, the input first
    sampled = 0
    for spec in config.set_abstractions:
        if spec.n_centroids is None:
            sizes.append(1)
            continue
        s, k = spec.n_centroids, spec.n_neighbours
        expected[f"centres_{sampled}"] = ((1, s), sizes[-1])
        expected[f"neighbours_{sampled}"] = ((1, s, k), sizes[-1])
        sizes.append(s)
        sampled += 1
    for j, (dense, sparse) in enumerate(zip(sizes[-2::-1], sizes[:0:-1], strict=True)):
        expected[f"interpolation_index_{j}"] = ((1, dense, min(3, sparse)), sparse)
        expected[f"weights_{j}"] = ((1, dense, min(3, sparse)), 0)
    return expected


def _load(path: Path, n: int, config: PointNet2Config) -> CloudFeatures | None:
    """The features stored in `path`, or None if it is unreadable or does not fit."""
    expected = _expected(n, config)
    try:
        arrays = read_npz(path, tuple(expected))
    except InputError:
        return None
    if set(arrays) != set(expected):
        return None
    fields: dict[str, list[torch.Tensor]] = {name: [] for name in _FIELDS}
    for key, (shape, bound) in expected.items():
        array = arrays[key]
        if array.shape != shape:
            return None
        if key == "normals" or key.startswith("weights_"):
            if array.dtype != np.float32 or not np.isfinite(array).all():
                return None
        elif array.dtype not in (np.int16, np.int32) or (
            array.size and (array.min() < 0 or array.max() >= bound)
        ):
            return None
        if key != "normals":
            fields[key.rsplit("_", 1)[0]].append(torch.from_numpy(array))
    index = BackboneIndex(
        tuple(fields["centres"]),
        tuple(fields["neighbours"]),
        tuple(fields["interpolation_index"]),
        tuple(fields["weights"]),
    )
    return CloudFeatures(arrays["normals"], index)


def _store(path: Path, features: CloudFeatures) -> None:
    """Write `features` to `path` atomically; a folder that cannot be written is logged
    and skipped."""
    tmp: Path | None = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem[:16]}.", suffix=".tmp")
        os.close(fd)
        tmp = Path(name)
        write_npz(tmp, feature_arrays(features), compress=False)
        replace_file(tmp, path)
        tmp = None
    except OSError as err:
        log.warning("could not cache the segmenter's cloud features in %s: %s", path.parent, err)
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                tmp.unlink()
