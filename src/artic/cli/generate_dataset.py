"""`artic generate-dataset`: procedural articulated objects of one category.

`dataset=appendix_a` (default): the six template categories of Appendix A (Chapter 3).
`dataset=hierarchy`: Chapter 4 data (section 4.5); besides each object's spec and URDF it
writes its kinematic-tree ground truth (`tree.json`) and 18 articulated poses drawn
within the joint limits (`poses.json`); the varying-structure categories
(`storage_furniture`, `lamp`, `office_chair`) need it.

Object i is sampled from a generator seeded by (seed, i) and its poses from one seeded
by (seed, i, 1), so any chunking or sharding of the work writes the same bytes.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, PlainValidator, ValidationInfo, field_validator

from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.object_dataset import INDEX, INDEX_COLUMNS, object_dir, split_of
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import StageConfig, Strict
from artic.geometry.camera import CameraIntrinsics
from artic.objects.families import parse_spec
from artic.objects.spec import CategoryConfig, ObjectSpec
from artic.objects.structures import STRUCTURES, StructureConfig, StructureSpec

DatasetKind = Literal["appendix_a", "hierarchy"]
POSE_STREAM = 1  # poses of object i come from default_rng([seed, i, POSE_STREAM])


TREE = "tree.json"
POSES = "poses.json"


class DatasetConfig(Strict):
    """What to write for each object, how many objects and how they split."""

    kind: DatasetKind = Field(
        "appendix_a",
        description="appendix_a: spec + URDF (Chapter 3); hierarchy: also tree.json and poses.json",
    )

    objects: int = Field(gt=0, description="number of objects (train + test)")
    train_per_test: int = Field(
        10, ge=0, description="training objects per withheld test object (0: no test split)"
    )
    chunk_size: int = Field(
        64, gt=0, description="objects per chunk: the unit of resume and of shard files"
    )
    poses: int = Field(
        18, ge=1, description="hierarchy: articulated poses per object (section 4.5: 18)"
    )


def _category(value: Any) -> CategoryConfig | StructureConfig:
    """An Appendix A `CategoryConfig`, or the config model of a registered
    varying-structure category (chosen by `name`)."""
    if isinstance(value, CategoryConfig | StructureConfig):
        return value
    name = value.get("name") if isinstance(value, dict) else None
    if isinstance(name, str) and name in STRUCTURES:
        return STRUCTURES[name].config.model_validate(value)
    return CategoryConfig.model_validate(value)


class GenerateDatasetConfig(StageConfig):
    category: Annotated[CategoryConfig | StructureConfig, PlainValidator(_category)]
    camera: CameraIntrinsics = Field(description="the view frustum positions are sampled from")
    dataset: DatasetConfig

    @field_validator("dataset")
    @classmethod
    def _kind_fits_category(cls, dataset: DatasetConfig, info: ValidationInfo) -> DatasetConfig:
        category = info.data.get("category")
        if isinstance(category, StructureConfig) and dataset.kind != "hierarchy":
            raise ValueError(
                f"category {category.name} has a varying kinematic tree (Chapter 4); "
                "use dataset=hierarchy"
            )
        return dataset


def object_rng(seed: int, object_id: int) -> np.random.Generator:
    """The generator for object `object_id`: independent of how work is split."""
    return np.random.default_rng([seed, object_id])


def sample_object(cfg: GenerateDatasetConfig, object_id: int) -> ObjectSpec | StructureSpec:
    from artic.objects.spec import sample_spec
    from artic.objects.structures import sample_structure

    rng = object_rng(cfg.seed, object_id)
    if isinstance(cfg.category, StructureConfig):
        return sample_structure(cfg.category, object_id, rng)
    return sample_spec(cfg.category, cfg.camera, object_id, rng)


def _plan(cfg: GenerateDatasetConfig, inputs: dict[str, Path]) -> Plan:
    n, size = cfg.dataset.objects, cfg.dataset.chunk_size
    return Plan([min(size, n - c * size) for c in range(math.ceil(n / size))], "objects")


def chunk_ids(cfg: GenerateDatasetConfig, chunk: int) -> range:
    size = cfg.dataset.chunk_size
    return range(chunk * size, min((chunk + 1) * size, cfg.dataset.objects))


def generate_chunk(
    cfg: GenerateDatasetConfig, inputs: dict[str, Path], chunk: int, tmp: Path
) -> int:
    """Sample, build and write the objects of one chunk into `tmp`."""
    from artic.objects.categories import build
    from artic.objects.structures import build_structure
    from artic.objects.tree import object_tree, sample_configurations
    from artic.objects.urdf import write_urdf

    ids = chunk_ids(cfg, chunk)
    for object_id in ids:
        spec = sample_object(cfg, object_id)
        obj = build(spec) if isinstance(spec, ObjectSpec) else build_structure(spec)
        files = write_urdf(obj)
        folder = tmp / object_dir(object_id)
        (folder / "meshes").mkdir(parents=True)
        (folder / "spec.json").write_text(spec.model_dump_json(indent=2) + "\n")
        (folder / "object.urdf").write_text(files.urdf)
        for rel, text in files.meshes.items():
            (folder / rel).write_text(text)
        if cfg.dataset.kind == "hierarchy":
            poses = sample_configurations(
                obj, cfg.dataset.poses, np.random.default_rng([cfg.seed, object_id, POSE_STREAM])
            )
            (folder / TREE).write_text(object_tree(obj).model_dump_json(indent=2) + "\n")
            (folder / POSES).write_text(poses.model_dump_json(indent=2) + "\n")
    return len(ids)


def _finalize(
    cfg: GenerateDatasetConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    from artic.objects.tree import ObjectTree

    rows = []
    shapes = set()
    for object_id in range(cfg.dataset.objects):
        folder = work / object_dir(object_id)
        spec = parse_spec((folder / "spec.json").read_text())
        split = split_of(object_id, cfg.dataset.train_per_test)
        # chirality 0: not applicable (a varying-structure object's doors each have a side)
        chirality = int(spec.chirality) if isinstance(spec, ObjectSpec) else 0
        if cfg.dataset.kind == "hierarchy":
            tree = ObjectTree.model_validate_json((folder / TREE).read_text())
            dof = tree.dof
            shapes.add((tree.edges, tree.joint_types))
        else:
            assert isinstance(spec, ObjectSpec)  # the config validator ensures it
            dof = spec.dof
        rows.append((object_id, split, spec.category, dof, chirality))
    write_csv(work / INDEX, INDEX_COLUMNS, rows)
    write_json(work / "category.json", cfg.category.model_dump(mode="json"))
    n_test = sum(r[1] == "test" for r in rows)
    stats: dict[str, float | int | str] = {
        "category": cfg.category.name,
        "objects": len(rows),
        "train objects": len(rows) - n_test,
        "test objects": n_test,
    }
    if cfg.dataset.kind == "hierarchy":
        stats["distinct trees"] = len(shapes)
        stats["dof min"] = min(r[3] for r in rows)
        stats["dof max"] = max(r[3] for r in rows)
        stats["poses per object"] = cfg.dataset.poses
    return stats


STAGE: Stage[GenerateDatasetConfig] = Stage(
    name="generate-dataset",
    help=(
        "Procedural articulated objects (Appendix A): URDF + OBJ meshes + ObjectSpec JSON.\n\n"
        "Example: artic generate-dataset category=refrigerator dataset.objects=200"
    ),
    conf="generate_dataset",
    schema=GenerateDatasetConfig,
    plan=_plan,
    chunk=generate_chunk,
    finalize=_finalize,
)
