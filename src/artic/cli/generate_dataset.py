"""`artic generate-dataset`: procedural articulated objects of one category (Appendix A).

Object i is sampled from a generator seeded by (seed, i), so any chunking or sharding
of the work writes the same bytes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from pydantic import Field

from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.object_dataset import INDEX, INDEX_COLUMNS, object_dir, split_of
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import StageConfig, Strict
from artic.geometry.camera import CameraIntrinsics
from artic.objects.spec import CategoryConfig, ObjectSpec


class DatasetConfig(Strict):
    """How many objects and how they split."""

    objects: int = Field(gt=0, description="number of objects (train + test)")
    train_per_test: int = Field(
        10, ge=0, description="training objects per withheld test object (0: no test split)"
    )
    chunk_size: int = Field(
        64, gt=0, description="objects per chunk: the unit of resume and of shard files"
    )


class GenerateDatasetConfig(StageConfig):
    category: CategoryConfig
    camera: CameraIntrinsics = Field(description="the view frustum positions are sampled from")
    dataset: DatasetConfig


def object_rng(seed: int, object_id: int) -> np.random.Generator:
    """The generator for object `object_id`: independent of how work is split."""
    return np.random.default_rng([seed, object_id])


def sample_object(cfg: GenerateDatasetConfig, object_id: int) -> ObjectSpec:
    from artic.objects.spec import sample_spec

    return sample_spec(cfg.category, cfg.camera, object_id, object_rng(cfg.seed, object_id))


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
    from artic.objects.urdf import write_urdf

    ids = chunk_ids(cfg, chunk)
    for object_id in ids:
        spec = sample_object(cfg, object_id)
        files = write_urdf(build(spec))
        folder = tmp / object_dir(object_id)
        (folder / "meshes").mkdir(parents=True)
        (folder / "spec.json").write_text(spec.model_dump_json(indent=2) + "\n")
        (folder / "object.urdf").write_text(files.urdf)
        for rel, text in files.meshes.items():
            (folder / rel).write_text(text)
    return len(ids)


def _finalize(
    cfg: GenerateDatasetConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    rows = []
    for object_id in range(cfg.dataset.objects):
        spec = ObjectSpec.model_validate_json(
            (work / object_dir(object_id) / "spec.json").read_text()
        )
        split = split_of(object_id, cfg.dataset.train_per_test)
        rows.append((object_id, split, spec.category, spec.dof, spec.chirality))
    write_csv(work / INDEX, INDEX_COLUMNS, rows)
    write_json(work / "category.json", cfg.category.model_dump(mode="json"))
    n_test = sum(r[1] == "test" for r in rows)
    return {
        "category": cfg.category.name,
        "objects": len(rows),
        "train objects": len(rows) - n_test,
        "test objects": n_test,
    }


STAGE: Stage[GenerateDatasetConfig] = Stage(
    name="generate-dataset",
    conf="generate_dataset",
    schema=GenerateDatasetConfig,
    plan=_plan,
    chunk=generate_chunk,
    finalize=_finalize,
)
