"""The folder `artic render-depth render=scan` writes, and its reader (Chapter 4 data).

Layout (docs/formats.md, "Scans (Chapter 4)")::

    manifest.json                 stage "render-scan"
    scans.json                    category, camera, noise, scan settings
    index.csv                     object_id, pose, kind (clean|noisy), split, points, file,
                                  configuration
    scans/000042_03_clean.ply     x, y, z (metres, object frame), part_id, motion_type
    scans/000042_03_noisy.ply
    trees/000042.json             ground-truth KinematicTree

Every file read goes through the manifest's sha256. The test split (`split` = "test",
objects withheld by generate-dataset) is never used for training or validation; training
stages take their validation objects from the training split with `split_train_objects`.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from artic.artifacts.manifest import Manifest, read_manifest, verify_file
from artic.errors import InputError

if TYPE_CHECKING:
    from artic.artifacts.ply import PlyCloud
    from artic.objects.tree import KinematicTree

STAGE = "render-scan"
INFO = "scans.json"
INDEX = "index.csv"
INDEX_COLUMNS = ("object_id", "pose", "kind", "split", "points", "file", "configuration")
KINDS = ("clean", "noisy")
SPLITS = ("train", "test")


class ScanRow(NamedTuple):
    """One row of index.csv: one labelled cloud."""

    object_id: int
    pose: int
    kind: str  # clean | noisy
    split: str  # train | test
    points: int
    file: str  # relative to the folder
    configuration: str  # joint values, space-separated, radians / metres


def scan_file(object_id: int, pose: int, kind: str) -> str:
    """Relative path of one cloud: scans/<object>_<pose>_<clean|noisy>.ply."""
    return f"scans/{object_id:06d}_{pose:02d}_{kind}.ply"


def tree_file(object_id: int) -> str:
    """Relative path of an object's ground-truth tree."""
    return f"trees/{object_id:06d}.json"


def index_clouds(root: Path) -> tuple[list[ScanRow], set[str]]:
    """The rows of index.csv for the clouds under root/scans (read from their PLY
    headers, in file order) and where their poses came from (`poses` comments)."""
    from artic.artifacts.ply import read_ply_header

    rows: list[ScanRow] = []
    sources: set[str] = set()
    for path in sorted((root / "scans").glob("*.ply")):
        header = read_ply_header(path)
        meta = dict(c.partition(" ")[::2] for c in header.comments)
        vertex = header.element("vertex")
        assert vertex is not None
        sources.add(meta["poses"])
        rows.append(
            ScanRow(
                object_id=int(meta["object_id"]),
                pose=int(meta["pose"]),
                kind=meta["kind"],
                split=meta["split"],
                points=vertex.count,
                file=path.relative_to(root).as_posix(),
                configuration=meta["configuration"],
            )
        )
    return rows, sources


class ObjectSplit(NamedTuple):
    """Training objects divided into the ones trained on and the ones validated on."""

    train: list[int]
    val: list[int]


def split_train_objects(object_ids: Sequence[int], val_every: int) -> ObjectSplit:
    """Every `val_every`-th object (1st, (val_every+1)-th, ... in sorted order, offset so
    that the first object trains) is a validation object; the rest train. By object, so
    no pose of a validation object is trained on. val_every >= 2."""
    if val_every < 2:
        raise ValueError(f"val_every must be >= 2, got {val_every}")
    ids = sorted(set(object_ids))
    val = [o for i, o in enumerate(ids) if i % val_every == val_every - 1]
    held_out = set(val)
    return ObjectSplit([o for o in ids if o not in held_out], val)


@dataclass(frozen=True)
class ScanDataset:
    """A finished `render-scan` output folder."""

    root: Path
    manifest: Manifest
    info: dict[str, Any]
    rows: tuple[ScanRow, ...]

    @classmethod
    def open(cls, root: Path) -> ScanDataset:
        """Read the manifest (stage "render-scan"), scans.json and index.csv; InputError
        naming the file when the folder is something else or malformed."""
        manifest = read_manifest(root, expected_stage=STAGE)
        try:
            info = json.loads(verify_file(root, manifest, INFO).read_text())
        except json.JSONDecodeError as err:
            raise InputError(f"{root / INFO}: not valid JSON ({err.msg})") from None
        if not isinstance(info, dict) or not isinstance(info.get("category"), str):
            raise InputError(f"{root / INFO}: expected a JSON object with a category")
        text = verify_file(root, manifest, INDEX).read_text()
        reader = csv.DictReader(io.StringIO(text))
        if tuple(reader.fieldnames or ()) != INDEX_COLUMNS:
            raise InputError(f"{root / INDEX}: expected columns {', '.join(INDEX_COLUMNS)}")
        try:
            rows = tuple(
                ScanRow(
                    int(r["object_id"]),
                    int(r["pose"]),
                    r["kind"],
                    r["split"],
                    int(r["points"]),
                    r["file"],
                    r["configuration"],
                )
                for r in reader
            )
        except (TypeError, ValueError):
            raise InputError(f"{root / INDEX}: malformed row") from None
        if not rows:
            raise InputError(f"{root / INDEX}: the folder has no scans")
        bad = [r for r in rows if r.kind not in KINDS or r.split not in SPLITS]
        if bad:
            raise InputError(
                f"{root / INDEX}: kind must be clean|noisy and split train|test "
                f"(object {bad[0].object_id} pose {bad[0].pose})"
            )
        return cls(root, manifest, info, rows)

    @classmethod
    def open_category(cls, root: Path, category: str, field: str = "scans") -> ScanDataset:
        """`open`, and InputError naming `field` unless the scans are of `category`."""
        try:
            ds = cls.open(root)
        except InputError as err:
            raise InputError(f"{field}: {err}") from None
        if ds.category != category:
            raise InputError(f"{field}: {root} holds {ds.category} scans, not {category}")
        return ds

    @property
    def category(self) -> str:
        return str(self.info["category"])

    def select(
        self,
        split: str | None = None,
        kinds: Sequence[str] = KINDS,
        objects: Sequence[int] | None = None,
    ) -> list[ScanRow]:
        """Rows of `split` (None: both), of the given kinds, of the given objects (None:
        all), in index order (object, pose, kind)."""
        wanted = None if objects is None else set(objects)
        return [
            r
            for r in self.rows
            if (split is None or r.split == split)
            and r.kind in kinds
            and (wanted is None or r.object_id in wanted)
        ]

    def object_ids(self, split: str | None = None) -> list[int]:
        """Sorted ids of the objects of `split` (None: all)."""
        return sorted({r.object_id for r in self.rows if split is None or r.split == split})

    def cloud(self, row: ScanRow) -> PlyCloud:
        """The cloud of one row (verified; part ids and motion types required)."""
        from artic.artifacts.ply import read_ply

        path = verify_file(self.root, self.manifest, row.file)
        cloud = read_ply(path)
        if cloud.part_id is None or cloud.motion_type is None:
            raise InputError(f"{path}: expected part_id and motion_type properties")
        return cloud

    def tree(self, object_id: int) -> KinematicTree:
        """The ground-truth kinematic tree of one object (trees/<id>.json, verified)."""
        from artic.objects.tree import KinematicTree

        path = verify_file(self.root, self.manifest, tree_file(object_id))
        try:
            return KinematicTree.from_json(path.read_text())
        except InputError as err:
            raise InputError(f"{path}: {err}") from None
        except (ValueError, KeyError, TypeError) as err:
            raise InputError(f"{path}: not a valid kinematic tree ({err})") from None
