"""`artic render-scan` (alias `artic render-depth render=scan`): labelled point clouds
of each object across its articulation, for Chapter 4 (part segmentation and kinematic
hierarchies).

The scan stage shares render-depth's config tree (`conf/render_depth/`; its `preset`
`render=scan` selects `render/scan.yaml`) but has its own schema
(`render.config.RenderScanConfig`), stage name ("render-scan") and output folder
(`artifacts/scans/<category>`, `artifacts.scan_dataset`). The clouds and trees come from
`render.scan_objects`; any sharding of the work writes the same bytes.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np

from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.object_dataset import ObjectDataset
from artic.artifacts.scan_dataset import INDEX, INDEX_COLUMNS, INFO, KINDS, scan_file, tree_file
from artic.cli.stage_runner import Plan, Stage
from artic.render.config import RenderScanConfig

STAGE_NAME = "render-scan"
PREVIEW = "preview.png"
_PREVIEW_POINTS = 4000  # points drawn per cloud in preview.png


@functools.lru_cache(maxsize=2)
def _dataset(path: str) -> ObjectDataset:
    return ObjectDataset.open(Path(path))


def _ids(ds: ObjectDataset, cfg: RenderScanConfig, chunk: int) -> list[int]:
    size = cfg.render.objects_per_shard
    return [r.object_id for r in ds.rows[chunk * size : (chunk + 1) * size]]


def _plan(cfg: RenderScanConfig, inputs: dict[str, Path]) -> Plan:
    from artic.render.scan_objects import check_configurations

    ds = _dataset(str(inputs["dataset"]))
    check_configurations(ds, cfg)
    n = len(ds.rows)
    size = cfg.render.objects_per_shard
    return Plan([min(size, n - c * size) for c in range(math.ceil(n / size))], "objects")


def scan_chunk(cfg: RenderScanConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Scan the objects of chunk `chunk` into tmp: their clouds and trees."""
    from artic.artifacts.ply import write_ply
    from artic.render.backend import make_backend
    from artic.render.scan_objects import scan_object

    ds = _dataset(str(inputs["dataset"]))
    ids = _ids(ds, cfg, chunk)
    (tmp / "scans").mkdir(parents=True)
    (tmp / "trees").mkdir()
    with make_backend(cfg.render.backend, cfg.camera, threads=1) as backend:
        for object_id in ids:
            tree, clouds = scan_object(cfg, ds, object_id, backend)
            (tmp / tree_file(object_id)).write_text(tree.to_json() + "\n")
            for pose, kind, cloud, comments in clouds:
                path = tmp / scan_file(object_id, pose, kind)
                part, motion = cloud.part_id, cloud.motion_type
                write_ply(path, cloud.points, part, motion, comments=comments)
    return len(ids)


def _finalize(
    cfg: RenderScanConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    from artic.artifacts.scan_dataset import index_clouds

    ds = _dataset(str(inputs["dataset"]))
    rows, sources = index_clouds(work)
    write_csv(work / INDEX, INDEX_COLUMNS, rows)
    counts = {k: [r.points for r in rows if r.kind == k] for k in KINDS}
    info = {
        "category": ds.category,
        "objects": len(ds.rows),
        "clouds_per_kind": len(counts["noisy"]),
        "poses": sorted(sources),
        "camera": cfg.camera.model_dump(),
        "noise": cfg.noise.model_dump(),
        "render": cfg.render.model_dump(mode="json"),
        "frame": "object (root link): base at the centre of the body's bottom face, z up, "
        "front towards -x; metres",
        "ply_properties": ["x", "y", "z", "part_id", "motion_type"],
        "motion_types": ["static", "rotating", "translating", "both"],
    }
    write_json(work / INFO, info)
    if cfg.render.preview_images:
        from artic.artifacts.ply import read_ply
        from artic.evaluation.plots import scan_preview

        firsts = [r for r in rows if r.pose == 0 and r.kind == "clean"]
        clouds = []
        for r in firsts[: cfg.render.preview_images]:
            for kind in KINDS:
                cloud = read_ply(work / scan_file(r.object_id, r.pose, kind))
                clouds.append((f"{r.object_id:06d} pose 0 {kind}", cloud.points, cloud.part_id))
        scan_preview(work / PREVIEW, clouds, cfg.render.preview_columns, _PREVIEW_POINTS)
    n_test = sum(1 for r in rows if r.kind == "noisy" and r.split == "test")
    noisy = counts["noisy"]
    return {
        "category": ds.category,
        "objects": len(ds.rows),
        "clouds (clean + noisy)": len(rows),
        "test poses": n_test,
        "mean noisy points": round(float(np.mean(noisy)), 1) if noisy else 0.0,
        "poses from": ", ".join(sorted(sources)),
    }


STAGE: Stage[RenderScanConfig] = Stage(
    name=STAGE_NAME,
    help=(
        "Fused multi-view point clouds with part labels and motion types across each\n"
        "object's articulation (Chapter 4); also run as render-depth render=scan.\n\n"
        "Example: artic render-scan dataset=artifacts/objects/storage_furniture"
    ),
    preset=("render=scan",),
    alias="render-depth render=scan",
    conf="render_depth",
    schema=RenderScanConfig,
    plan=_plan,
    chunk=scan_chunk,
    finalize=_finalize,
    inputs={"dataset": "generate-dataset"},
    input_paths=lambda cfg: {"dataset": Path(cfg.dataset)},
)
