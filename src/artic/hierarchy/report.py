"""The documents `artic segment`, `build-hierarchy` and `infer-hierarchy` write
(docs/formats.md, "Hierarchies (Chapter 4)"): segmentation.json and hierarchy.json as
dicts, built from the records of `hierarchy.infer`. Pure functions of plain data; the
files are written by `artifacts.scan_outputs`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from artic.hierarchy.infer import LabelledHierarchy, ScanSegmentation, subsample
from artic.objects.tree import MOTION_TYPES

FORMAT = 1


def _round(value: float, digits: int = 6) -> float | None:
    """A JSON number (None for NaN)."""
    return None if not math.isfinite(float(value)) else round(float(value), digits)


def _vector(v: NDArray[np.floating]) -> list[float]:
    return [round(float(x), 6) for x in v]


def motion_dict(prob: NDArray[np.floating]) -> dict[str, float]:
    """(4,) probabilities -> {"static": p, "rotating": p, ...}."""
    return {name: round(float(p), 6) for name, p in zip(MOTION_TYPES, prob, strict=True)}


def hierarchy_document(
    hierarchy: LabelledHierarchy,
    part_id: NDArray[np.int64],
    part_confidence: NDArray[np.float32] | None,
    input_part_ids: Sequence[int] | None,
    extra: dict[str, Any],
) -> dict[str, Any]:
    """hierarchy.json as a dict. Its keys num_parts, root, edges, motion_types,
    joint_types and axes are `KinematicTree.to_dict()`, so `KinematicTree.from_json`
    reads the file; the rest: per part, per joint and per candidate edge probabilities,
    and `point_part_id`, one part per input point in input order (N,)."""
    tree, graph, labelling = hierarchy.tree, hierarchy.graph, hierarchy.labelling
    parts = []
    for p in range(tree.num_parts):
        parts.append(
            {
                "id": p,
                "points": int(graph.point_counts[p]),
                "centroid": _vector(graph.centroids[p]),
                "motion_type": MOTION_TYPES[tree.motion_types[p]],
                "motion_probabilities": motion_dict(labelling.motion[p]),
                "root_probability": round(float(labelling.root[p]), 6),
                "confidence": None if part_confidence is None else _round(part_confidence[p]),
                "input_part_id": None if input_part_ids is None else int(input_part_ids[p]),
            }
        )
    joints = []
    for k, ((parent, child), joint_type) in enumerate(
        zip(tree.edges, tree.joint_types, strict=True)
    ):
        axis = None if tree.axes is None else tree.axes[k]
        joints.append(
            {
                "name": f"joint_{child}",
                "parent": parent,
                "child": child,
                "type": joint_type,
                "axis": None if axis is None else axis.to_dict(),
                "exists_probability": _round(hierarchy.edge_exists[k]),
                "direction_probability": _round(hierarchy.edge_direction[k]),
                "candidate": bool(np.isfinite(hierarchy.edge_exists[k])),
            }
        )
    candidates = [
        {
            "parts": [int(a), int(b)],
            "exists_probability": round(float(labelling.exists[e]), 6),
            "first_is_parent_probability": round(float(labelling.parent_first[e]), 6),
            "min_distance_m": round(float(graph.min_distance[e]), 6),
        }
        for e, (a, b) in enumerate(labelling.edges.tolist())
    ]
    return {
        "format": FORMAT,
        "kind": "artic-hierarchy",
        **tree.to_dict(),
        "parts": parts,
        "joints": joints,
        "candidate_edges": candidates,
        **extra,
        "point_part_id": np.asarray(part_id, dtype=np.int64),
    }


def segmentation_document(
    seg: ScanSegmentation, input_info: dict[str, Any], models: dict[str, Any]
) -> dict[str, Any]:
    """segmentation.json as a dict: per part its points, confidence and motion type (the
    majority vote of its points) with the mean motion probabilities."""
    parts = []
    for p in range(seg.num_parts):
        mask = seg.part_id == p
        votes = np.bincount(seg.motion_type[mask], minlength=len(MOTION_TYPES))
        parts.append(
            {
                "id": p,
                "points": int(mask.sum()),
                "confidence": round(float(seg.part_confidence[p]), 6),
                "motion_type": MOTION_TYPES[int(votes.argmax())],
                "motion_probabilities": motion_dict(seg.motion_prob[mask].mean(axis=0)),
            }
        )
    return {
        "format": FORMAT,
        "kind": "artic-segmentation",
        "num_parts": seg.num_parts,
        "parts": parts,
        "ply": "parts.ply",
        "input": input_info,
        "models": models,
        "timings_s": rounded_timings(seg.timings),
    }


def input_info(path: Path, points: int, factor: float, worked_on: int) -> dict[str, Any]:
    """The "input" entry of both documents: the file, its points, the scale applied."""
    return {
        "file": str(path),
        "points": points,
        "scale": factor,
        "worked_on_points": int(worked_on),
        "frame": "the input's, scaled to metres",
    }


def rounded_timings(timings: dict[str, float]) -> dict[str, float]:
    return {k: round(v, 4) for k, v in timings.items()}


def part_subset(part_id: NDArray[np.int64], max_points: int, seed: int) -> NDArray[np.int64]:
    """Indices of at most ~max_points points keeping every part (build-hierarchy)."""
    idx = subsample(len(part_id), max_points, np.random.default_rng(seed))
    missing = np.setdiff1d(np.unique(part_id), np.unique(part_id[idx]))
    extra = [np.flatnonzero(part_id == p)[:32] for p in missing]
    return np.unique(np.concatenate([idx, *extra])) if extra else idx


def robot_name(name: str) -> str:
    """The URDF robot name of a file stem: anything but [A-Za-z0-9_] becomes '_'."""
    return re.sub(r"[^A-Za-z0-9_]", "_", name) or "inferred_object"
