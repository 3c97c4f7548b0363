"""What `artic segment`, `build-hierarchy` and `infer-hierarchy` write (docs/formats.md,
"Hierarchies (Chapter 4)"): the JSON documents, the picture, and the output folder.

An output folder is written atomically, by the stages' own writer: everything goes into
the sibling `DIR.partial/` (`artifacts.workdir.WorkDir`), which replaces `DIR` only when
complete, with a `manifest.json` naming the command, its options, the input file and
models with their sha256, and every output file. An existing `DIR` is replaced only when
it is an earlier output of the same command; any other non-empty folder is refused.
"""

from __future__ import annotations

import json
import logging
import math
import shutil
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from artic.artifacts.hashing import sha256_file, sha256_json
from artic.artifacts.manifest import LOG, MANIFEST, InputRecord, Manifest, now_iso, read_manifest
from artic.artifacts.workdir import WorkDir
from artic.cli.stage_runner import ManifestHead, config_hash_of, log_to, publish, stop_log
from artic.errors import InputError
from artic.objects.tree import MOTION_TYPES

if TYPE_CHECKING:
    from artic.hierarchy.infer import LabelledHierarchy

log = logging.getLogger("artic")

FORMAT = 1
_PICTURE_POINTS = 6000  # points drawn in hierarchy.png


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


def dumps(document: dict[str, Any]) -> str:
    """JSON text: indented, except that arrays (per-point labels) sit on one line."""
    arrays = {k: v for k, v in document.items() if isinstance(v, np.ndarray)}
    plain = {k: (f"@@{k}@@" if k in arrays else v) for k, v in document.items()}
    text = json.dumps(plain, indent=2, allow_nan=False)
    for k, v in arrays.items():
        text = text.replace(f'"@@{k}@@"', json.dumps(v.tolist(), separators=(",", ":")))
    return text + "\n"


def _tree_layout(
    num_parts: int, root: int, edges: Sequence[tuple[int, int]]
) -> dict[int, tuple[float, float]]:
    """(x, y) of each part: leaves spaced evenly left to right, parents centred above."""
    children: dict[int, list[int]] = {}
    for a, b in edges:
        children.setdefault(a, []).append(b)
    pos: dict[int, tuple[float, float]] = {}
    next_leaf = [0.0]

    def place(node: int, depth: int) -> float:
        kids = children.get(node, [])
        if not kids:
            x = next_leaf[0]
            next_leaf[0] += 1.0
        else:
            x = float(np.mean([place(k, depth + 1) for k in kids]))
        pos[node] = (x, -float(depth))
        return x

    place(root, 0)
    return pos


def draw_hierarchy(
    path: Path,
    points: NDArray[np.floating],
    part_id: NDArray[np.integer],
    hierarchy: LabelledHierarchy,
    title: str,
) -> None:
    """hierarchy.png: left, the cloud coloured by part with the joint axes (revolute
    solid, prismatic dashed); right, the tree with motion and joint types."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tree = hierarchy.tree
    palette = plt.get_cmap("tab10")
    step = max(1, len(points) // _PICTURE_POINTS)
    p, ids = np.asarray(points)[::step], np.asarray(part_id)[::step]
    fig = plt.figure(figsize=(11.0, 5.0), dpi=100)
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.scatter(p[:, 0], p[:, 1], p[:, 2], c=palette(ids % 10), s=3.0, linewidths=0)
    extent = float(np.ptp(p, axis=0).max()) or 1.0
    for k, joint_type in enumerate(tree.joint_types):
        axis = None if tree.axes is None else tree.axes[k]
        if axis is None:
            continue
        ends = axis.origin + np.outer([-0.3, 0.3], extent * axis.direction)  # (2, 3)
        style = "-" if joint_type == "revolute" else "--"
        ax.plot(ends[:, 0], ends[:, 1], ends[:, 2], style, color="black", linewidth=1.5)
    ax.view_init(elev=20, azim=200)
    ax.set_box_aspect(tuple(np.ptp(p, axis=0) + 1e-3))
    ax.set_axis_off()
    ax.set_title(title, fontsize=9)

    ax2 = fig.add_subplot(1, 2, 2)
    pos = _tree_layout(tree.num_parts, tree.root, tree.edges)
    for (a, b), joint_type in zip(tree.edges, tree.joint_types, strict=True):
        (xa, ya), (xb, yb) = pos[a], pos[b]
        ax2.annotate(
            "",
            xy=(xb, yb + 0.12),
            xytext=(xa, ya - 0.12),
            arrowprops={"arrowstyle": "->", "color": "0.3"},
        )
        ax2.text(
            (xa + xb) / 2,
            (ya + yb) / 2,
            joint_type,
            fontsize=7,
            ha="center",
            va="center",
            bbox={"boxstyle": "round", "fc": "white", "ec": "none", "alpha": 0.8},
        )
    for node, (x, y) in pos.items():
        label = f"part {node}\n{MOTION_TYPES[tree.motion_types[node]]}"
        if node == tree.root:
            label += "\n(root)"
        ax2.text(
            x,
            y,
            label,
            fontsize=7,
            ha="center",
            va="center",
            bbox={"boxstyle": "round", "fc": palette(node % 10), "alpha": 0.6},
        )
    xs = [x for x, _ in pos.values()]
    ys = [y for _, y in pos.values()]
    ax2.set_xlim(min(xs) - 0.8, max(xs) + 0.8)
    ax2.set_ylim(min(ys) - 0.6, 0.6)
    ax2.set_axis_off()
    ax2.set_title(f"kinematic tree: {tree.num_parts} parts", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, format="png", metadata={"Software": None})
    plt.close(fig)


def check_output_folder(out: Path, command: str) -> None:
    """Refuse to write over anything but an earlier output of `command` (InputError)."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out: {out} is a file, expected a folder")
    if not out.is_dir() or not any(out.iterdir()):
        return
    if not (out / MANIFEST).is_file():
        raise InputError(
            f"--out: {out} exists and is not an artic output folder; "
            "choose another --out or remove it"
        )
    stage = read_manifest(out).stage
    if stage != command:
        raise InputError(
            f"--out: {out} holds the output of 'artic {stage}', not of 'artic {command}'; "
            "choose another --out"
        )
    log.info("replacing the previous output in %s", out)


class OutputFolder:
    """`DIR.partial/` to write into, then the manifest and the atomic rename (`publish`),
    through the stages' own writer (`cli/stage_runner`: `log_to`, `publish`, with
    `artifacts.workdir.WorkDir` and its lock): the same files and manifest fields as a
    stage's output.

    command: the manifest's stage name. options: the command's settings (its config).
    inputs: name -> file read (hashed into the manifest).
    """

    def __init__(
        self, out: Path, command: str, options: dict[str, Any], inputs: dict[str, Path]
    ) -> None:
        check_output_folder(out, command)
        self.out, self.command, self.options = out, command, options
        self.inputs = {
            name: InputRecord(path=str(path), stage="file", content_hash=sha256_file(path))
            for name, path in inputs.items()
        }
        self.started, self.t0 = now_iso(), time.perf_counter()
        self.work = WorkDir(out)
        self.work.prepare(sha256_json({"command": command, "options": options}), fresh=True)
        self.path = self.work.path
        self.handler = log_to(self.path / LOG)

    def close_log(self) -> None:
        stop_log(self.handler)

    def abandon(self) -> None:
        """After bad input: remove the work area (nothing is published)."""
        self.close_log()
        with self.work.locked():
            self.work.leave()
            shutil.rmtree(self.path, ignore_errors=True)

    def publish(self, seed: int, stats: dict[str, float | int | str]) -> Manifest:
        """Write manifest.json and move the folder into place."""
        self.close_log()
        # the options name no output folder, shard or runtime: all of them are hashed
        config_hash = config_hash_of(self.command, self.options, ())
        head = ManifestHead(self.command, self.options, config_hash, seed, self.inputs)
        return publish(self.work, head, stats, self.started, self.t0)
