"""The folder `generate-dataset` writes, and its reader.

Layout (see docs/formats.md)::

    manifest.json
    index.csv                      object_id, split, category, dof, chirality
    objects/000042/spec.json       every sampled parameter (ObjectSpec)
    objects/000042/object.urdf     body, moving parts and handles; meshes relative
    objects/000042/meshes/*.obj

Every file read goes through the manifest's sha256, so a corrupted dataset is reported
by name instead of silently producing wrong labels.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from artic.artifacts.manifest import Manifest, read_manifest, verify_file
from artic.errors import InputError

if TYPE_CHECKING:
    from artic.objects.spec import ObjectSpec

STAGE = "generate-dataset"
INDEX = "index.csv"
INDEX_COLUMNS = ("object_id", "split", "category", "dof", "chirality")


def object_dir(object_id: int) -> str:
    """Relative folder of one object."""
    return f"objects/{object_id:06d}"


def split_of(object_id: int, train_per_test: int) -> str:
    """ "test" for every (train_per_test + 1)-th object, else "train" (split by object;
    10:1 as in the thesis: 10,000 training and 1,000 withheld objects). 0 = no test set."""
    if train_per_test > 0 and object_id % (train_per_test + 1) == train_per_test:
        return "test"
    return "train"


@dataclass(frozen=True)
class IndexRow:
    object_id: int
    split: str
    category: str
    dof: int
    chirality: int


@dataclass(frozen=True)
class ObjectDataset:
    """A finished `generate-dataset` output folder."""

    root: Path
    manifest: Manifest
    rows: tuple[IndexRow, ...]

    @classmethod
    def open(cls, root: Path) -> ObjectDataset:
        manifest = read_manifest(root, expected_stage=STAGE)
        text = verify_file(root, manifest, INDEX).read_text()
        reader = csv.DictReader(io.StringIO(text))
        if tuple(reader.fieldnames or ()) != INDEX_COLUMNS:
            raise InputError(f"{root / INDEX}: expected columns {', '.join(INDEX_COLUMNS)}")
        rows = tuple(
            IndexRow(
                int(r["object_id"]), r["split"], r["category"], int(r["dof"]), int(r["chirality"])
            )
            for r in reader
        )
        if not rows:
            raise InputError(f"{root / INDEX}: the dataset has no objects")
        return cls(root, manifest, rows)

    @property
    def category(self) -> str:
        return self.rows[0].category

    def spec(self, object_id: int) -> ObjectSpec:
        from artic.objects.spec import ObjectSpec

        path = verify_file(self.root, self.manifest, f"{object_dir(object_id)}/spec.json")
        return ObjectSpec.model_validate_json(path.read_text())

    def urdf(self, object_id: int) -> Path:
        """Path of the object's URDF after verifying it and its meshes."""
        folder = object_dir(object_id)
        for rel in self.manifest.outputs:
            if rel.startswith(folder + "/meshes/"):
                verify_file(self.root, self.manifest, rel)
        return verify_file(self.root, self.manifest, f"{folder}/object.urdf")
