"""`artic generate-dataset`: procedural articulated objects of one category.

The config is `objects.dataset.GenerateDatasetConfig` (`dataset=appendix_a`: Chapter 3's
templates; `dataset=hierarchy`: Chapter 4 data with tree.json and poses.json); each
object's files come from `objects.dataset.object_files` and are written through
`artifacts.object_dataset`. Any chunking or sharding of the work writes the same bytes.
"""

from __future__ import annotations

import math
from pathlib import Path

from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.object_dataset import INDEX, INDEX_COLUMNS, object_dir
from artic.cli.stage_runner import Plan, Stage
from artic.objects.dataset import GenerateDatasetConfig, chunk_ids


def _plan(cfg: GenerateDatasetConfig, inputs: dict[str, Path]) -> Plan:
    n, size = cfg.dataset.objects, cfg.dataset.chunk_size
    return Plan([min(size, n - c * size) for c in range(math.ceil(n / size))], "objects")


def generate_chunk(
    cfg: GenerateDatasetConfig, inputs: dict[str, Path], chunk: int, tmp: Path
) -> int:
    """Sample, build and write the objects of one chunk into `tmp`."""
    from artic.artifacts.object_dataset import write_object
    from artic.objects.dataset import object_files

    ids = chunk_ids(cfg, chunk)
    for object_id in ids:
        write_object(tmp / object_dir(object_id), object_files(cfg, object_id))
    return len(ids)


def _finalize(
    cfg: GenerateDatasetConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    from artic.artifacts.object_dataset import index_objects

    hierarchy = cfg.dataset.kind == "hierarchy"
    rows, trees = index_objects(work, cfg.dataset.objects, cfg.dataset.train_per_test, hierarchy)
    write_csv(work / INDEX, INDEX_COLUMNS, rows)
    write_json(work / "category.json", cfg.category.model_dump(mode="json"))
    n_test = sum(r[1] == "test" for r in rows)
    stats: dict[str, float | int | str] = {
        "category": cfg.category.name,
        "objects": len(rows),
        "train objects": len(rows) - n_test,
        "test objects": n_test,
    }
    if hierarchy:
        stats["distinct trees"] = trees
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
