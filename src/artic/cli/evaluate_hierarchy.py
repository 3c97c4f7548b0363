"""`artic evaluate hierarchy`: Tables 4.1 and 4.2 for one category on its withheld objects.

For every test-split scan (clean and noisy, every pose) of a render-scan folder:
- Table 4.1: the segmenter's parts against the true ones, mAP at IoU 0.5 (PartNet's
  protocol, detections of all objects pooled; `artic.evaluation.segmentation`), and the
  per-point motion-type accuracy;
- Table 4.2: the graph network's labelling and the extracted tree against the true tree
  (E_type, E_exist, E_dir, E_root, Tree F1; `artic.evaluation.hierarchy`), once on the
  ground-truth segmentation (the thesis' setting) and once on the predicted one (parts
  matched to true parts by Hungarian IoU >= evaluate.match_iou).
Parts that no point of a scan shows are left out of its ground truth (the tree is
contracted over them, as in training: `fit_labeller.restrict_tree`); a scan whose root
part is not visible is skipped and counted.

Writes report.md (the tables in the thesis' layout beside its numbers), summary.csv
(one row per kind and segmentation), per_object.csv (one row per scan and
segmentation). Shardable by object: `shard.index/shard.count` take chunks of
`evaluate.objects_per_chunk` test objects; every scan is seeded from (seed, object,
pose, kind).
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

from pydantic import Field

from artic.artifacts.chunk_parts import take_json
from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.scan_dataset import ScanDataset
from artic.artifacts.workers import available_cpus
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import StageConfig
from artic.errors import InputError
from artic.evaluation.hierarchy_report import (
    PER_OBJECT_COLUMNS,
    chapter4_report,
    per_object_rows,
    table_rows,
)
from artic.hierarchy.config import CategoryName, HierarchyEvaluateConfig

MODEL = "model.pt"
CHUNKS = "chunks"


class EvaluateHierarchyConfig(StageConfig):
    category: CategoryName
    scans: str = Field(description="a render-scan output folder (its test split is used)")
    segmenter: str = Field(description="a train-segmenter output folder")
    labeller: str = Field(description="a train-hierarchy output folder")
    evaluate: HierarchyEvaluateConfig


@functools.lru_cache(maxsize=2)
def _dataset(path: str, category: str) -> ScanDataset:
    return ScanDataset.open_category(Path(path), category)


def _test_objects(cfg: EvaluateHierarchyConfig, scans: Path) -> list[int]:
    ids = _dataset(str(scans), cfg.category.name).object_ids("test")
    if not ids:
        raise InputError(f"scans: {scans} has no test objects")
    return ids[: cfg.evaluate.max_objects]


def _plan(cfg: EvaluateHierarchyConfig, inputs: dict[str, Path]) -> Plan:
    n, size = len(_test_objects(cfg, inputs["scans"])), cfg.evaluate.objects_per_chunk
    return Plan([min(size, n - c * size) for c in range(math.ceil(n / size))], "objects")


def evaluate_chunk(
    cfg: EvaluateHierarchyConfig, inputs: dict[str, Path], chunk: int, tmp: Path
) -> int:
    """Evaluate the scans of chunk `chunk`'s test objects into tmp/chunks/<chunk>.json."""
    import torch

    from artic.hierarchy.evaluate import evaluate_rows, evaluation_config
    from artic.hierarchy.models import load_labeller, load_segmenter

    torch.set_num_threads(cfg.runtime.threads or available_cpus())
    ds = _dataset(str(inputs["scans"]), cfg.category.name)
    size = cfg.evaluate.objects_per_chunk
    objects = _test_objects(cfg, inputs["scans"])[chunk * size : (chunk + 1) * size]
    segmenter = load_segmenter(inputs["segmenter"] / MODEL, cfg.category.name)
    labeller = load_labeller(inputs["labeller"] / MODEL, cfg.category.name)
    max_poses = cfg.evaluate.max_poses
    rows = [
        row
        for row in ds.select("test", cfg.evaluate.kinds, objects)
        if max_poses is None or row.pose < max_poses
    ]
    hcfg = evaluation_config(segmenter, labeller, cfg.evaluate)
    records, skipped = evaluate_rows(
        ds, rows, segmenter.model, labeller.model, hcfg, cfg.evaluate, cfg.seed
    )
    (tmp / CHUNKS).mkdir()
    write_json(tmp / CHUNKS / f"{chunk:04d}.json", {"records": records, "skipped": skipped})
    return len(objects)


def _finalize(
    cfg: EvaluateHierarchyConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    parts = take_json(sorted((work / CHUNKS).glob("*.json")))
    (work / CHUNKS).rmdir()
    records: list[dict[str, Any]] = [r for part in parts for r in part["records"]]
    skipped = sum(int(part["skipped"]) for part in parts)
    if not records:
        raise InputError(f"scans: no test scan of {inputs['scans']} shows its root part")
    records.sort(key=lambda r: (r["object_id"], r["pose"], r["kind"]))
    rows = table_rows(records, cfg.evaluate.kinds)
    columns = list(rows[0])
    write_csv(work / "summary.csv", columns, [[r[c] for c in columns] for r in rows])
    write_csv(work / "per_object.csv", PER_OBJECT_COLUMNS, per_object_rows(records))
    objects = len({r["object_id"] for r in records})
    sources = (cfg.scans, cfg.segmenter, cfg.labeller)
    report = chapter4_report(cfg.category.name, sources, rows, skipped, objects)
    (work / "report.md").write_text(report)
    stats: dict[str, float | int | str] = {"category": cfg.category.name, "scans": len(records)}
    for r in rows:
        if r["segmentation"] == "gt":
            stats[f"{r['kind']} mAP"] = round(float(r["map"]), 4)
        stats[f"{r['kind']} Tree F1 ({r['segmentation']} seg.)"] = round(float(r["tree_f1"]), 2)
    if cfg.evaluate.yaw == "random":
        import numpy as np

        error = np.degrees(np.abs([r["yaw_error"] for r in records]))
        stats["yaw error median (deg)"] = round(float(np.median(error)), 2)
        stats["yaw within 5 deg"] = round(float(np.mean(error <= 5.0)), 4)
        # the planes' angle alone (the yaw modulo a quarter turn): all an office chair's
        # four-fold base tells (docs/hierarchy.md, "Scan frame and yaw")
        planes = np.abs((error + 45.0) % 90.0 - 45.0)
        stats["yaw error mod 90 median (deg)"] = round(float(np.median(planes)), 3)
        stats["yaw mod 90 within 2 deg"] = round(float(np.mean(planes <= 2.0)), 4)
    return stats


STAGE: Stage[EvaluateHierarchyConfig] = Stage(
    name="evaluate-hierarchy",
    command="evaluate hierarchy",
    help=(
        "Tables 4.1 and 4.2 for one category: part mAP, E_type, E_exist, E_dir, E_root,\n"
        "Tree F1 (ground-truth and predicted segmentation, clean and noisy scans).\n\n"
        "Example: artic evaluate hierarchy category=storage_furniture"
    ),
    conf="evaluate_hierarchy",
    schema=EvaluateHierarchyConfig,
    plan=_plan,
    chunk=evaluate_chunk,
    finalize=_finalize,
    inputs={"scans": "render-scan", "segmenter": "train-segmenter", "labeller": "train-hierarchy"},
    input_paths=lambda cfg: {
        "scans": Path(cfg.scans),
        "segmenter": Path(cfg.segmenter),
        "labeller": Path(cfg.labeller),
    },
)
