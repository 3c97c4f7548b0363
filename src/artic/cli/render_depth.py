"""`artic render-depth`: labelled depth images across each object's articulation
(section 3.2.3). The config is `render.config.RenderDepthConfig`, the images and labels
come from `render.depth`, the files are written through `artifacts/`; any sharding of the
work writes the same bytes.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

from artic.artifacts.depth_dataset import INFO, LABELS, PREVIEW, shard_name, write_shard
from artic.artifacts.formats import read_npz, write_csv, write_json, write_png
from artic.artifacts.object_dataset import ObjectDataset
from artic.cli.stage_runner import Plan, Stage
from artic.render.config import RenderDepthConfig


@functools.lru_cache(maxsize=2)
def _dataset(path: str) -> ObjectDataset:
    return ObjectDataset.open(Path(path))


def _ids(ds: ObjectDataset, cfg: RenderDepthConfig, chunk: int) -> list[int]:
    size = cfg.render.objects_per_shard
    return [r.object_id for r in ds.rows[chunk * size : (chunk + 1) * size]]


def _plan(cfg: RenderDepthConfig, inputs: dict[str, Path]) -> Plan:
    n = len(_dataset(str(inputs["dataset"])).rows)
    size = cfg.render.objects_per_shard
    per = cfg.render.configurations
    return Plan([per * min(size, n - c * size) for c in range(math.ceil(n / size))], "images")


def render_chunk(cfg: RenderDepthConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Render the objects of shard `chunk` and write `shards/shard-<chunk>.npz` into tmp."""
    from artic.render.depth import render_objects

    ds = _dataset(str(inputs["dataset"]))
    arrays = render_objects(cfg, ds, _ids(ds, cfg, chunk))
    write_shard(tmp / shard_name(chunk), arrays)
    return len(arrays["object_id"])


def _finalize(
    cfg: RenderDepthConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    from artic.render.depth import index_shards

    ds = _dataset(str(inputs["dataset"]))
    n_chunks = math.ceil(len(ds.rows) / cfg.render.objects_per_shard)
    index = index_shards(cfg, ds, (read_npz(work / shard_name(c)) for c in range(n_chunks)))
    write_csv(work / LABELS, index.columns, index.rows)
    write_json(work / INFO, index.info)
    if index.preview is not None:
        write_png(work / PREVIEW, index.preview)
    return index.stats


STAGE: Stage[RenderDepthConfig] = Stage(
    name="render-depth",
    help=(
        "Labelled depth images across each object's articulation (section 3.2.3); with\n"
        "render=scan, fused multi-view point clouds with part labels (Chapter 4).\n\n"
        "Example: artic render-depth dataset=artifacts/objects/refrigerator"
    ),
    conf="render_depth",
    schema=RenderDepthConfig,
    plan=_plan,
    chunk=render_chunk,
    finalize=_finalize,
    inputs={"dataset": "generate-dataset"},
    input_paths=lambda cfg: {"dataset": Path(cfg.dataset)},
)
