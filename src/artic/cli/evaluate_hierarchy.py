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
import json
import math
import shutil
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field

from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.scan_dataset import ScanDataset
from artic.cli.stage_runner import Plan, Stage, available_cpus
from artic.config.schemas import StageConfig, Strict
from artic.errors import InputError

MODEL = "model.pt"
CHUNKS = "chunks"
SEGMENTATIONS = ("gt", "pred")
COUNTS = ("type_errors", "nodes", "exist_errors", "pairs", "dir_errors", "directed", "root_error")

#: Table 4.1 (mAP @ 0.5 IoU) and Table 4.2 (ground-truth segmentation) of the thesis
THESIS_MAP: dict[str, dict[str, float]] = {
    "storage_furniture": {"clean": 0.922, "noisy": 0.907},
    "lamp": {"clean": 0.695, "noisy": 0.593},
    "office_chair": {"clean": 0.824, "noisy": 0.811},
}
THESIS_TREE: dict[str, dict[str, tuple[float, ...]]] = {  # E_type, E_exist, E_dir, E_root, Tree F1
    "storage_furniture": {"clean": (1.16, 1.2, 2.22, 0, 99.73),
                          "noisy": (0.39, 2.03, 29.04, 0, 99.02)},
    "lamp": {"clean": (0.47, 4.63, 31.11, 0.23, 98.24), "noisy": (0, 0.98, 17.24, 0.92, 97.82)},
    "office_chair": {"clean": (0.08, 0.1, 39.64, 0, 99.77),
                     "noisy": (0.24, 0.99, 41.73, 0, 98.67)},
}  # fmt: skip


class CategoryName(Strict):
    """The category config group; only its name is needed."""

    model_config = Strict.model_config | {"extra": "ignore"}
    name: str


class EvaluateOptions(Strict):
    kinds: tuple[Literal["clean", "noisy"], ...] = Field(("clean", "noisy"), min_length=1)
    max_objects: int | None = Field(None, gt=0, description="first N test objects (null: all)")
    max_poses: int | None = Field(None, gt=0, description="first N poses of each (null: all)")
    iou_threshold: float = Field(0.5, gt=0, le=1, description="mAP true-positive IoU")
    match_iou: float = Field(0.5, gt=0, le=1, description="predicted-to-true part matching")
    objects_per_chunk: int = Field(4, gt=0, description="test objects per resumable chunk")


class EvaluateHierarchyConfig(StageConfig):
    category: CategoryName
    scans: str = Field(description="a render-scan output folder (its test split is used)")
    segmenter: str = Field(description="a train-segmenter output folder")
    labeller: str = Field(description="a train-hierarchy output folder")
    evaluate: EvaluateOptions


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


def evaluate_scan(
    points: np.ndarray,
    true_part: np.ndarray,
    true_motion: np.ndarray,
    tree: Any,
    segmenter: Any,
    labeller: Any,
    cfg: Any,
    opts: EvaluateOptions,
    rng: np.random.Generator,
) -> dict[str, Any] | None:
    """One scan's Table 4.1 detections and Table 4.2 counts (None: root not visible).
    points (N, 3) metres; true_part, true_motion (N,) ints (-1: no part)."""
    from artic.evaluation.hierarchy import hierarchy_counts, match_parts
    from artic.evaluation.segmentation import motion_type_accuracy, object_detections
    from artic.hierarchy.fit_labeller import restrict_tree
    from artic.hierarchy.infer import build_hierarchy, segment_scan

    labelled = true_part >= 0
    present = np.unique(true_part[labelled])
    if tree.root not in present or present.max() >= tree.num_parts:
        return None
    truth = restrict_tree(tree, present.tolist())
    gt = np.searchsorted(present, true_part[labelled]).astype(np.int64)
    pts = points[labelled]
    seg = segment_scan(pts, segmenter, cfg, rng)
    det = object_detections(seg.part_id, seg.part_confidence, gt, opts.iou_threshold)
    record: dict[str, Any] = {
        "points": len(pts),
        "true_parts": truth.num_parts,
        "hidden_parts": tree.num_parts - truth.num_parts,
        "pred_parts": seg.num_parts,
        "confidence": det.confidence.tolist(),
        "true_positive": det.true_positive.tolist(),
        "n_ground_truth": det.n_ground_truth,
        "motion_accuracy": motion_type_accuracy(seg.motion_type, true_motion[labelled]),
    }
    for name, part_id in (("gt", gt), ("pred", seg.part_id)):
        h = build_hierarchy(pts, part_id, labeller, cfg, rng)
        mapping = None if name == "gt" else match_parts(part_id, gt, opts.match_iou)
        c = hierarchy_counts(h.labelling, h.tree, truth, mapping)
        record[name] = {k: int(getattr(c, k)) for k in COUNTS} | {
            "tree_precision": c.tree.precision,
            "tree_recall": c.tree.recall,
            "tree_f1": c.tree.f1,
        }
    return record


def evaluate_chunk(
    cfg: EvaluateHierarchyConfig, inputs: dict[str, Path], chunk: int, tmp: Path
) -> int:
    """Evaluate the scans of chunk `chunk`'s test objects into tmp/chunks/<chunk>.json."""
    import torch

    from artic.hierarchy.infer import HierarchyConfig
    from artic.hierarchy.models import load_labeller, load_segmenter

    torch.set_num_threads(cfg.runtime.threads or available_cpus())
    ds = _dataset(str(inputs["scans"]), cfg.category.name)
    size = cfg.evaluate.objects_per_chunk
    objects = _test_objects(cfg, inputs["scans"])[chunk * size : (chunk + 1) * size]
    segmenter = load_segmenter(inputs["segmenter"] / MODEL, cfg.category.name)
    labeller = load_labeller(inputs["labeller"] / MODEL, cfg.category.name)
    hcfg = HierarchyConfig(segmenter.inference, labeller.graph, estimate_axes=False)
    records, skipped = [], 0
    for row in ds.select("test", cfg.evaluate.kinds, objects):
        if cfg.evaluate.max_poses is not None and row.pose >= cfg.evaluate.max_poses:
            continue
        cloud, tree = ds.cloud(row), ds.tree(row.object_id)
        assert cloud.part_id is not None and cloud.motion_type is not None
        kind = ("clean", "noisy").index(row.kind)
        rng = np.random.default_rng([cfg.seed, row.object_id, row.pose, kind])
        record = evaluate_scan(
            cloud.points,
            cloud.part_id,
            cloud.motion_type,
            tree,
            segmenter.model,
            labeller.model,
            hcfg,
            cfg.evaluate,
            rng,
        )
        if record is None:
            skipped += 1
            continue
        records.append({"object_id": row.object_id, "pose": row.pose, "kind": row.kind, **record})
    (tmp / CHUNKS).mkdir()
    write_json(tmp / CHUNKS / f"{chunk:04d}.json", {"records": records, "skipped": skipped})
    return len(objects)


def table_rows(records: list[dict[str, Any]], kinds: tuple[str, ...]) -> list[dict[str, Any]]:
    """summary.csv rows: per kind and segmentation, mAP, motion accuracy and Table 4.2."""
    from artic.evaluation.hierarchy import HierarchyCounts, TreeScore, summarize
    from artic.evaluation.segmentation import Detections, mean_average_precision

    rows = []
    for kind in kinds:
        mine = [r for r in records if r["kind"] == kind]
        if not mine:
            continue
        dets = [
            Detections(
                np.asarray(r["confidence"], dtype=np.float64),
                np.asarray(r["true_positive"], dtype=bool),
                r["n_ground_truth"],
            )
            for r in mine
        ]
        m_ap = mean_average_precision(dets, pooled=True)
        motion = float(np.mean([r["motion_accuracy"] for r in mine]))
        for seg in SEGMENTATIONS:
            counts = [
                HierarchyCounts(
                    **{k: int(r[seg][k]) for k in COUNTS[:6]},
                    root_error=bool(r[seg]["root_error"]),
                    tree=TreeScore(
                        r[seg]["tree_precision"], r[seg]["tree_recall"], r[seg]["tree_f1"]
                    ),
                )
                for r in mine
            ]
            t = summarize(counts)
            rows.append(
                {
                    "kind": kind,
                    "segmentation": seg,
                    "scans": len(mine),
                    "map": m_ap,
                    "motion_accuracy": motion,
                    "e_type": t.e_type,
                    "e_exist": t.e_exist,
                    "e_dir": t.e_dir,
                    "e_root": t.e_root,
                    "tree_f1": t.tree_f1,
                }
            )
    return rows


def _report(
    cfg: EvaluateHierarchyConfig, rows: list[dict[str, Any]], skipped: int, objects: int
) -> str:
    name = cfg.category.name
    tmap, ttree = THESIS_MAP.get(name, {}), THESIS_TREE.get(name, {})
    lines = [
        f"# Chapter 4 on withheld {name} objects",
        "",
        f"Test-split scans of `{cfg.scans}`; segmenter `{cfg.segmenter}`, labeller "
        f"`{cfg.labeller}`. Thesis: PartNet-Mobility models (Tables 4.1, 4.2); ours: the "
        "procedural objects of this folder, so the numbers are comparable in kind, not equal.",
        "",
        "## Table 4.1: part segmentation (mAP @ 0.5 IoU)",
        "",
        "| Category | Clean | Noisy | Clean (thesis) | Noisy (thesis) |",
        "|---|---|---|---|---|",
    ]
    get = {(r["kind"], r["segmentation"]): r for r in rows}

    def cell(kind: str, key: str, seg: str = "gt", fmt: str = "{:.3f}") -> str:
        row = get.get((kind, seg))
        return "-" if row is None or np.isnan(row[key]) else fmt.format(row[key])

    def thesis_map(kind: str) -> str:
        return f"{tmap[kind]:.3f}" if kind in tmap else "-"

    lines.append(
        f"| {name} | {cell('clean', 'map')} | {cell('noisy', 'map')} "
        f"| {thesis_map('clean')} | {thesis_map('noisy')} |"
    )
    accuracy = ", ".join(f"{k} {cell(k, 'motion_accuracy')}" for k in ("clean", "noisy"))
    lines += ["", f"Per-point motion-type accuracy: {accuracy}", ""]
    lines += [
        "## Table 4.2: kinematic structure error (%)",
        "",
        "| Data Type | Segmentation | E_type ↓ | E_exist ↓ | E_dir ↓ | E_root ↓ | Tree F1 ↑ "
        "| scans |",
        "|---|---|---|---|---|---|---|---|",
    ]
    keys = ("e_type", "e_exist", "e_dir", "e_root", "tree_f1")
    for kind in ("clean", "noisy"):
        for seg, label in (("gt", "ground truth"), ("pred", "predicted")):
            row = get.get((kind, seg))
            if row is None:
                continue
            cells = " | ".join(f"{row[k]:.2f}" for k in keys)
            lines.append(f"| {kind.capitalize()} | {label} | {cells} | {row['scans']} |")
        if kind in ttree:
            cells = " | ".join(f"{v:g}" for v in ttree[kind])
            lines.append(f"| {kind.capitalize()} | ground truth (thesis) | {cells} | - |")
    lines += [
        "",
        "E_type, E_exist, E_dir pool the counts of all scans; E_root is over scans; Tree F1 is "
        "the mean of per-scan scores. Parts hidden in a scan are left out of its ground truth; "
        f"scans skipped because the root part is hidden: {skipped}. "
        f"Test objects: {objects}. Data: summary.csv, per_object.csv.",
        "",
    ]
    return "\n".join(lines)


def _finalize(
    cfg: EvaluateHierarchyConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    records: list[dict[str, Any]] = []
    skipped = 0
    for path in sorted((work / CHUNKS).glob("*.json")):
        data = json.loads(path.read_text())
        records += data["records"]
        skipped += int(data["skipped"])
    shutil.rmtree(work / CHUNKS)
    if not records:
        raise InputError(f"scans: no test scan of {inputs['scans']} shows its root part")
    records.sort(key=lambda r: (r["object_id"], r["pose"], r["kind"]))
    rows = table_rows(records, cfg.evaluate.kinds)
    columns = list(rows[0])
    write_csv(work / "summary.csv", columns, [[r[c] for c in columns] for r in rows])
    head = [
        "object_id",
        "pose",
        "kind",
        "points",
        "true_parts",
        "hidden_parts",
        "pred_parts",
        "n_ground_truth",
        "motion_accuracy",
    ]
    tail = [*COUNTS, "tree_precision", "tree_recall", "tree_f1"]
    per = [
        [r[c] for c in head] + [seg] + [r[seg][c] for c in tail]
        for r in records
        for seg in SEGMENTATIONS
    ]
    write_csv(work / "per_object.csv", [*head, "segmentation", *tail], per)
    objects = len({r["object_id"] for r in records})
    (work / "report.md").write_text(_report(cfg, rows, skipped, objects))
    stats: dict[str, float | int | str] = {"category": cfg.category.name, "scans": len(records)}
    for r in rows:
        if r["segmentation"] == "gt":
            stats[f"{r['kind']} mAP"] = round(float(r["map"]), 4)
        stats[f"{r['kind']} Tree F1 ({r['segmentation']} seg.)"] = round(float(r["tree_f1"]), 2)
    return stats


STAGE: Stage[EvaluateHierarchyConfig] = Stage(
    name="evaluate-hierarchy",
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
