"""The config of `generate-dataset` (validated straight from conf/generate_dataset: the
YAML holds each value, these models its type, range and meaning) and the files of one
generated object.

`dataset=appendix_a` (default): the six template categories of Appendix A (Chapter 3).
`dataset=hierarchy`: Chapter 4 data (section 4.5); besides each object's spec and URDF it
gives its kinematic-tree ground truth (`tree.json`) and 18 articulated poses drawn
within the joint limits (`poses.json`); the varying-structure categories
(`storage_furniture`, `lamp`, `office_chair`) need it.

Object i is sampled from a generator seeded by (seed, i) and its poses from one seeded
by (seed, i, 1), so any chunking or sharding of the work gives the same files. No file
access: the stage writes them through `artifacts/`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, PlainValidator, ValidationInfo, field_validator

from artic.config.schemas import StageConfig, Strict
from artic.geometry.camera import CameraIntrinsics
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


def chunk_ids(cfg: GenerateDatasetConfig, chunk: int) -> range:
    size = cfg.dataset.chunk_size
    return range(chunk * size, min((chunk + 1) * size, cfg.dataset.objects))


def object_files(cfg: GenerateDatasetConfig, object_id: int) -> dict[str, str]:
    """The files of object `object_id`, relative to its folder -> text: spec.json,
    object.urdf, meshes/*.obj and, for dataset=hierarchy, tree.json and poses.json."""
    from artic.objects.families import build_object
    from artic.objects.tree import object_tree, sample_configurations
    from artic.objects.urdf import write_urdf

    spec = sample_object(cfg, object_id)
    obj = build_object(spec)
    urdf = write_urdf(obj)
    files = {"spec.json": spec.model_dump_json(indent=2) + "\n", "object.urdf": urdf.urdf}
    files.update(urdf.meshes)
    if cfg.dataset.kind == "hierarchy":
        rng = np.random.default_rng([cfg.seed, object_id, POSE_STREAM])
        poses = sample_configurations(obj, cfg.dataset.poses, rng)
        files[TREE] = object_tree(obj).model_dump_json(indent=2) + "\n"
        files[POSES] = poses.model_dump_json(indent=2) + "\n"
    return files
