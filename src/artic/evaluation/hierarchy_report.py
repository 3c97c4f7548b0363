"""Chapter 4's tables as `evaluate hierarchy` writes them: summary.csv rows (per kind of
scan and segmentation: Table 4.1's mAP and motion accuracy, Table 4.2's errors and Tree
F1) from the per-scan records (`hierarchy.evaluate.evaluate_scan`), and report.md beside
the thesis' numbers. Pure functions of plain data.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from artic.evaluation.hierarchy import HierarchyCounts, TreeScore, summarize
from artic.evaluation.segmentation import Detections, mean_average_precision

SEGMENTATIONS = ("gt", "pred")
#: a scan record's Table 4.2 counts, per segmentation (`HierarchyCounts` fields)
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


def table_rows(records: list[dict[str, Any]], kinds: tuple[str, ...]) -> list[dict[str, Any]]:
    """summary.csv rows: per kind and segmentation, mAP, motion accuracy and Table 4.2."""
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


_HEAD = ["object_id", "pose", "kind", "points", "true_parts", "hidden_parts", "pred_parts",
         "n_ground_truth", "motion_accuracy"]  # fmt: skip
_TAIL = [*COUNTS, "tree_precision", "tree_recall", "tree_f1"]
PER_OBJECT_COLUMNS = [*_HEAD, "segmentation", *_TAIL]


def per_object_rows(records: list[dict[str, Any]]) -> list[list[Any]]:
    """per_object.csv rows (`PER_OBJECT_COLUMNS`): one per scan record and segmentation."""
    return [
        [r[c] for c in _HEAD] + [seg] + [r[seg][c] for c in _TAIL]
        for r in records
        for seg in SEGMENTATIONS
    ]


def chapter4_report(
    category: str,
    sources: tuple[str, str, str],
    rows: list[dict[str, Any]],
    skipped: int,
    objects: int,
) -> str:
    """report.md of `evaluate hierarchy`: Tables 4.1 and 4.2 in the thesis' layout beside
    its numbers. sources: the scans, segmenter and labeller folders, as given."""
    name = category
    scans, segmenter, labeller = sources
    tmap, ttree = THESIS_MAP.get(name, {}), THESIS_TREE.get(name, {})
    lines = [
        f"# Chapter 4 on withheld {name} objects",
        "",
        f"Test-split scans of `{scans}`; segmenter `{segmenter}`, labeller "
        f"`{labeller}`. Thesis: PartNet-Mobility models (Tables 4.1, 4.2); ours: the "
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
