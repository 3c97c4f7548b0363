"""The folder `generate-dataset` writes, and its reader.

Layout (see docs/formats.md)::

    manifest.json
    index.csv                      object_id, split, category, dof, chirality
    objects/000042/spec.json       every sampled parameter (ObjectSpec)
    objects/000042/object.urdf     body, moving parts and handles; meshes relative
    objects/000042/meshes/*.obj
    objects/000042/tree.json       dataset=hierarchy: kinematic-tree ground truth (ObjectTree)
    objects/000042/poses.json      dataset=hierarchy: articulated poses (ArticulatedPoses)

Every file read goes through the manifest's sha256, so a corrupted dataset is reported
by name instead of silently producing wrong labels.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from pydantic import BaseModel, ValidationError

from artic.artifacts.manifest import Manifest, read_manifest, verify_file
from artic.errors import InputError
from artic.geometry.camera import CameraIntrinsics

if TYPE_CHECKING:
    from artic.objects.spec import ObjectSpec
    from artic.objects.structures import StructureSpec
    from artic.objects.tree import ArticulatedPoses, ObjectTree

M = TypeVar("M", bound=BaseModel)

STAGE = "generate-dataset"
INDEX = "index.csv"
INDEX_COLUMNS = ("object_id", "split", "category", "dof", "chirality")
TREE = "tree.json"
POSES = "poses.json"


def object_dir(object_id: int) -> str:
    """Relative folder of one object."""
    return f"objects/{object_id:06d}"


def split_of(object_id: int, train_per_test: int) -> str:
    """ "test" for every (train_per_test + 1)-th object, else "train" (split by object;
    10:1 as in the thesis: 10,000 training and 1,000 withheld objects). 0 = no test set."""
    if train_per_test > 0 and object_id % (train_per_test + 1) == train_per_test:
        return "test"
    return "train"


def write_object(folder: Path, files: dict[str, str]) -> None:
    """One object's files (relative path -> text) into `folder` (created, with meshes/)."""
    (folder / "meshes").mkdir(parents=True)
    for rel, text in files.items():
        (folder / rel).write_text(text)


def index_objects(
    root: Path, objects: int, train_per_test: int, hierarchy: bool
) -> tuple[list[tuple[int, str, str, int, int]], int]:
    """The rows of index.csv (`INDEX_COLUMNS`) of the objects written under `root`, read
    from their spec.json (and tree.json when `hierarchy`), and the number of distinct
    kinematic trees among them (0 unless `hierarchy`)."""
    from artic.objects.families import parse_spec
    from artic.objects.spec import ObjectSpec
    from artic.objects.tree import ObjectTree

    rows = []
    shapes = set()
    for object_id in range(objects):
        folder = root / object_dir(object_id)
        spec = parse_spec((folder / "spec.json").read_text())
        split = split_of(object_id, train_per_test)
        # chirality 0: not applicable (a varying-structure object's doors each have a side)
        chirality = int(spec.chirality) if isinstance(spec, ObjectSpec) else 0
        if hierarchy:
            tree = ObjectTree.model_validate_json((folder / TREE).read_text())
            dof = tree.dof
            shapes.add((tree.edges, tree.joint_types))
        else:
            assert isinstance(spec, ObjectSpec)  # the config validator ensures it
            dof = spec.dof
        rows.append((object_id, split, spec.category, dof, chirality))
    return rows, len(shapes)


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
        try:
            rows = tuple(
                IndexRow(
                    int(r["object_id"]),
                    r["split"],
                    r["category"],
                    int(r["dof"]),
                    int(r["chirality"]),
                )
                for r in reader
            )
        except (TypeError, ValueError):
            raise InputError(f"{root / INDEX}: malformed row") from None
        if not rows:
            raise InputError(f"{root / INDEX}: the dataset has no objects")
        return cls(root, manifest, rows)

    @property
    def category(self) -> str:
        return self.rows[0].category

    @property
    def camera(self) -> CameraIntrinsics:
        """The camera the objects' positions were sampled for (the generating config's)."""
        try:
            return CameraIntrinsics.model_validate(self.manifest.config["camera"])
        except (KeyError, ValidationError):
            raise InputError(
                f"{self.root / 'manifest.json'}: config has no valid camera; pass camera=<name>"
            ) from None

    def spec(self, object_id: int) -> ObjectSpec | StructureSpec:
        """The object's spec.json (verified), of either family: an Appendix A `ObjectSpec`
        or a varying-structure `StructureSpec` (`artic.objects.families.parse_spec`)."""
        from artic.objects.families import parse_spec

        path = verify_file(self.root, self.manifest, f"{object_dir(object_id)}/spec.json")
        try:
            return parse_spec(path.read_text())
        except (ValueError, ValidationError, KeyError) as err:
            first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            raise InputError(f"{path}: not a valid object spec ({first})") from None

    def template_spec(self, object_id: int) -> ObjectSpec:
        """The spec of an Appendix A (fixed-structure) object; InputError naming the
        dataset for a varying-structure category (those have no fixed label columns)."""
        from artic.objects.spec import ObjectSpec

        spec = self.spec(object_id)
        if not isinstance(spec, ObjectSpec):
            raise InputError(
                f"{self.root}: category {spec.category} has a varying kinematic tree "
                "(Chapter 4); this stage needs an Appendix A category"
            )
        return spec

    def has(self, object_id: int, name: str) -> bool:
        """Whether the object's folder holds `name` (e.g. TREE, POSES) in the manifest."""
        return f"{object_dir(object_id)}/{name}" in self.manifest.outputs

    def tree(self, object_id: int) -> ObjectTree:
        """The object's kinematic-tree ground truth, tree.json (verified); written by
        `generate-dataset dataset=hierarchy`. `.to_kinematic_tree()` gives the Chapter 4
        library's record."""
        from artic.objects.tree import ObjectTree

        return self._model(object_id, TREE, ObjectTree)

    def poses(self, object_id: int) -> ArticulatedPoses:
        """The object's articulated poses, poses.json (verified); `dataset=hierarchy`."""
        from artic.objects.tree import ArticulatedPoses

        return self._model(object_id, POSES, ArticulatedPoses)

    def _model(self, object_id: int, name: str, model: type[M]) -> M:
        rel = f"{object_dir(object_id)}/{name}"
        if not self.has(object_id, name):
            raise InputError(
                f"{self.root / rel}: not in the dataset; generate it with dataset=hierarchy"
            )
        path = verify_file(self.root, self.manifest, rel)
        try:
            return model.model_validate_json(path.read_text())
        except ValidationError as err:
            raise InputError(f"{path}: malformed {name} ({err.errors()[0]['msg']})") from None

    def urdf(self, object_id: int) -> Path:
        """Path of the object's URDF after verifying it and its meshes."""
        import xml.etree.ElementTree as ET

        folder = object_dir(object_id)
        for rel in self.manifest.outputs:
            if rel.startswith(folder + "/meshes/"):
                verify_file(self.root, self.manifest, rel)
        path = verify_file(self.root, self.manifest, f"{folder}/object.urdf")
        try:
            root = ET.parse(path).getroot()
        except (ET.ParseError, UnicodeDecodeError) as err:
            raise InputError(f"{path}: not a valid URDF ({err})") from None
        if root.tag != "robot":
            raise InputError(f"{path}: not a valid URDF (root element <{root.tag}>, not <robot>)")
        return path
