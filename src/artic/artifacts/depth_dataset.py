"""The folder `render-depth` writes, and its reader.

Layout (see docs/formats.md)::

    manifest.json
    dataset.json              camera, category, DoF, label columns, depth encoding, counts
    labels.csv                one row per image: shard, row, object_id, split, image, labels...
    preview.png               contact sheet with the true axes drawn
    shards/shard-00000.npz    depth (N, H, W), part_mask (N, H, W), labels (N, L), ids

Shards are written whole by one chunk of work; a reader streams them one at a time.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, ValidationError

from artic.artifacts.formats import read_npz
from artic.artifacts.manifest import MANIFEST, Manifest, read_manifest, verify_file
from artic.errors import InputError
from artic.geometry.camera import CameraIntrinsics

STAGE = "render-depth"
INFO = "dataset.json"
LABELS = "labels.csv"
PREVIEW = "preview.png"
SHARD_ARRAYS = ("depth", "part_mask", "labels", "object_id", "image_index", "test")


def shard_name(chunk: int) -> str:
    return f"shards/shard-{chunk:05d}.npz"


def write_shard(path: Path, arrays: dict[str, NDArray[Any]]) -> None:
    """One shard, written whole (its folder created)."""
    from artic.artifacts.formats import write_npz

    path.parent.mkdir(parents=True)
    write_npz(path, arrays)


@dataclass(frozen=True)
class Shard:
    """One shard: depth in float32 metres (0 = no return), or as stored."""

    depth: NDArray[Any]
    part_mask: NDArray[np.uint8]
    labels: NDArray[np.float64]
    object_id: NDArray[np.int32]
    image_index: NDArray[np.int16]
    test: NDArray[np.bool_]


def decode_depth(stored: NDArray[Any]) -> NDArray[np.float32]:
    """uint16 millimetres or float16 metres -> float32 metres."""
    if stored.dtype == np.uint16:
        return stored.astype(np.float32) * np.float32(0.001)
    if stored.dtype == np.float16:
        return stored.astype(np.float32)
    raise InputError(f"depth stored as {stored.dtype}; expected uint16 (mm) or float16 (m)")


class DepthDatasetInfo(BaseModel):
    """`dataset.json`: what the images are of and how they were made (docs/formats.md).
    The camera, DoF and joint type travel on with a model trained on them."""

    model_config = ConfigDict(frozen=True, extra="ignore")
    category: str
    dof: int
    joint_type: str
    camera: CameraIntrinsics
    label_columns: list[str]
    depth_encoding: str | None = None
    noise: bool | None = None
    backend: str | None = None
    images: int | None = None
    objects: int | None = None
    configurations_per_object: int | None = None
    #: [min, max] of the objects' door thickness, metres (None: written before it was)
    door_thickness: tuple[float, float] | None = None


@dataclass(frozen=True)
class DepthDataset:
    """A finished `render-depth` output folder."""

    root: Path
    manifest: Manifest
    info: DepthDatasetInfo

    @classmethod
    def open(cls, root: Path) -> DepthDataset:
        manifest = read_manifest(root, expected_stage=STAGE)
        path = verify_file(root, manifest, INFO)
        try:
            info = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as err:
            raise InputError(f"{path}: not valid JSON ({err})") from None
        needed = ("category", "label_columns", "camera", "dof", "joint_type")
        if not isinstance(info, dict) or any(k not in info for k in needed):
            raise InputError(f"{path}: expected a JSON object with {', '.join(needed)}")
        try:
            return cls(root, manifest, DepthDatasetInfo.model_validate(info))
        except ValidationError as err:
            first = err.errors()[0]
            where = ".".join(str(p) for p in first["loc"])
            raise InputError(f"{path}: {where}: {first['msg']}") from None

    @classmethod
    def open_category(cls, root: Path, category: str, field: str = "depth") -> DepthDataset:
        """`open`, and InputError naming `field` unless the images are of `category`."""
        ds = cls.open(root)
        if ds.info.category != category:
            raise InputError(f"{field}: {root} holds {ds.info.category} images, not {category}")
        return ds

    @property
    def label_columns(self) -> list[str]:
        return list(self.info.label_columns)

    def shard_files(self) -> list[str]:
        return sorted(k for k in self.manifest.outputs if k.startswith("shards/"))

    def shards(self, decode: bool = True) -> Iterator[Shard]:
        """Shards in order, each verified against the manifest as it is read; depth
        decoded to float32 metres, or as stored (uint16 mm / float16 m) if not `decode`."""
        for rel in self.shard_files():
            path = verify_file(self.root, self.manifest, rel)
            data = read_npz(path, SHARD_ARRAYS)
            n = len(data["labels"])
            if any(len(data[k]) != n for k in SHARD_ARRAYS):
                raise InputError(f"{path}: shard arrays have different lengths")
            yield Shard(
                depth=decode_depth(data["depth"]) if decode else data["depth"],
                part_mask=data["part_mask"],
                labels=data["labels"],
                object_id=data["object_id"],
                image_index=data["image_index"],
                test=data["test"],
            )


def recorded_objects(depth: Path) -> tuple[list[Path], str]:
    """Where the object dataset `depth` was rendered from may lie, most likely first,
    and its content hash, from depth's manifest. A relative recorded path is relative
    to the directory render-depth ran in: found from the depth folder's own recorded
    `out` (when the folder has not moved since), else tried beside the current
    directory."""
    manifest = read_manifest(depth, expected_stage="render-depth")
    record = manifest.inputs.get("dataset")
    if record is None:
        raise InputError(f"depth: {depth / MANIFEST} records no dataset input; pass objects=PATH")
    recorded = Path(record.path)
    if recorded.is_absolute():
        return [recorded], record.content_hash
    candidates: list[Path] = []
    out = Path(str(manifest.config.get("out", "")))
    here = depth.resolve()
    if str(out) not in ("", ".") and not out.is_absolute():
        n = len(out.parts)
        if len(here.parts) > n and here.parts[-n:] == out.parts:
            candidates.append(here.parents[n - 1] / recorded)
    candidates.append(recorded)
    return candidates, record.content_hash


def source_objects(depth: Path, given: Path | None) -> Path:
    """The object dataset (a generate-dataset folder) `depth` was rendered from: `given`,
    else where depth's manifest records it (`recorded_objects`); InputError naming the
    `depth` or `objects` field unless its content hash is the one depth records."""
    try:
        candidates, expected = recorded_objects(depth)
    except InputError as err:
        message = str(err)
        raise InputError(message if message.startswith("depth:") else f"depth: {message}") from None
    if given is not None:
        objects = given
    else:
        found = [p for p in candidates if (p / MANIFEST).is_file()]
        if not found:
            raise InputError(
                f"objects: the dataset {depth} was rendered from is not at "
                f"{candidates[0]}; pass objects=PATH (its generate-dataset folder)"
            )
        objects = found[0]
    try:
        actual = read_manifest(objects, expected_stage="generate-dataset").content_hash
    except InputError as err:
        raise InputError(f"objects: {err}") from None
    if actual != expected:
        raise InputError(
            f"objects: {objects} is not the dataset {depth} was rendered from (content hash "
            f"{actual[:12]}, depth records {expected[:12]}); pass objects=PATH"
        )
    return objects
