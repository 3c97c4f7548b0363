"""hierarchy.png of `artic build-hierarchy` and `infer-hierarchy` (docs/formats.md,
"Hierarchies (Chapter 4)"): the cloud coloured by part beside the kinematic tree
(matplotlib, Agg backend, PNG)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from artic.objects.tree import MOTION_TYPES, KinematicTree

_PICTURE_POINTS = 6000  # points drawn in hierarchy.png


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
    tree: KinematicTree,
    title: str,
) -> None:
    """hierarchy.png: left, the cloud coloured by part with the joint axes (revolute
    solid, prismatic dashed); right, the tree with motion and joint types. points (M, 3),
    part_id (M,): the parts of `tree`."""
    # a Figure on the Agg canvas, not pyplot: pyplot's import alone is ~0.25 s of an
    # infer-hierarchy run (issue 18's 3 s), and no window or global state is wanted
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    palette = colormaps["tab10"]
    step = max(1, len(points) // _PICTURE_POINTS)
    p, ids = np.asarray(points)[::step], np.asarray(part_id)[::step]
    fig = Figure(figsize=(11.0, 5.0), dpi=100)
    FigureCanvasAgg(fig)
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
