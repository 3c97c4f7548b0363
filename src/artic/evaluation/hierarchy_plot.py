"""hierarchy.png of `artic build-hierarchy` and `infer-hierarchy` (docs/formats.md,
"Hierarchies (Chapter 4)"): the cloud coloured by part beside the kinematic tree.

Drawn with Pillow on a pixel array, not matplotlib: importing matplotlib and drawing a 3D
scatter were 0.5-0.9 s of a 3 s command (issue 18's wall target; docs/hierarchy.md,
"Speed"), for a quick-look picture. The cloud is an orthographic view from elevation 20
deg, azimuth 200 deg (matplotlib's `view_init` convention), nearer points drawn over
farther ones."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from artic.objects.tree import MOTION_TYPES, KinematicTree

_PICTURE_POINTS = 6000  # points drawn in hierarchy.png
#: the picture in pixels: the cloud on the left half, the tree on the right
WIDTH, HEIGHT = 1100, 500
#: the view of the cloud, in degrees (matplotlib's `view_init(elev, azim)`)
ELEVATION, AZIMUTH = 20.0, 200.0
#: matplotlib's tab10 colours, the parts' colours by part index modulo 10
TAB10 = np.array(
    [
        (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
        (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207),
    ],
    dtype=np.uint8,
)  # fmt: skip
_TITLE_H = 28  # pixels above each panel's drawing for its title
_MARGIN = 12
_DOT = 2  # a point is a _DOT x _DOT square


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


def view_axes() -> NDArray[np.float64]:
    """(3, 3) rows: the screen's right, its up, and the direction toward the viewer, in
    the cloud's frame (orthographic view at ELEVATION, AZIMUTH)."""
    e, a = np.radians(ELEVATION), np.radians(AZIMUTH)
    right = [-np.sin(a), np.cos(a), 0.0]
    up = [-np.sin(e) * np.cos(a), -np.sin(e) * np.sin(a), np.cos(e)]
    toward = [np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)]
    return np.array([right, up, toward])


def _fit(
    screen: NDArray[np.float64], box: tuple[int, int, int, int]
) -> tuple[float, NDArray[np.float64]]:
    """Scale and offset mapping (right, up) screen coordinates into the pixel box
    (x0, y0, x1, y1) with the aspect kept, the extent centred."""
    lo, hi = screen.min(0), screen.max(0)
    span = np.maximum(hi - lo, 1e-9)
    x0, y0, x1, y1 = box
    scale = float(min((x1 - x0) / span[0], (y1 - y0) / span[1]))
    centre = (lo + hi) / 2.0
    offset = np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0])
    return scale, offset - scale * np.array([1.0, -1.0]) * centre


def _to_pixels(
    screen: NDArray[np.float64], scale: float, offset: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(n, 2) pixel (column, row) of screen (right, up) coordinates."""
    return screen * np.array([scale, -scale]) + offset


def cloud_pixels(
    points: NDArray[np.floating],
    part_id: NDArray[np.integer],
    scale: float,
    offset: NDArray[np.float64],
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """(rows, columns, part) of the pixels the cloud covers in the view (`view_axes`,
    then `_to_pixels` with scale and offset), within the picture: one entry a pixel, the
    part of the nearest point drawn there."""
    axes = view_axes()
    screen = np.asarray(points, dtype=np.float64) @ axes[:2].T
    depth = np.asarray(points, dtype=np.float64) @ axes[2]
    pix = np.floor(_to_pixels(screen, scale, offset)).astype(np.int64)
    order = np.argsort(-depth, kind="stable")  # nearest first: it keeps its pixels
    dr, dc = (d.ravel() for d in np.meshgrid(np.arange(_DOT), np.arange(_DOT), indexing="ij"))
    rows = pix[order, 1][:, None] + dr[None, :]  # (n, _DOT^2)
    cols = pix[order, 0][:, None] + dc[None, :]
    parts = np.repeat(np.asarray(part_id, dtype=np.int64)[order], _DOT * _DOT)
    rows, cols = rows.ravel(), cols.ravel()
    inside = (rows >= 0) & (rows < HEIGHT) & (cols >= 0) & (cols < WIDTH)
    rows, cols, parts = rows[inside], cols[inside], parts[inside]
    _, first = np.unique(rows * WIDTH + cols, return_index=True)
    return rows[first], cols[first], parts[first]


def _blend(colour: NDArray[np.uint8], alpha: float) -> tuple[int, int, int]:
    """`colour` at `alpha` over white."""
    c = alpha * colour.astype(np.float64) + (1.0 - alpha) * 255.0
    r, g, b = (int(v) for v in np.rint(c))
    return (r, g, b)


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
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.load_default(size=11)
    step = max(1, len(points) // _PICTURE_POINTS)
    p, ids = np.asarray(points, dtype=np.float64)[::step], np.asarray(part_id)[::step]
    canvas = np.full((HEIGHT, WIDTH, 3), 255, dtype=np.uint8)
    half = WIDTH // 2
    box = (_MARGIN, _TITLE_H + _MARGIN, half - _MARGIN, HEIGHT - _MARGIN)
    extent = float(np.ptp(p, axis=0).max()) or 1.0
    segments = [
        (joint_type, axis.origin + np.outer([-0.3, 0.3], extent * axis.direction))  # (2, 3)
        for joint_type, axis in zip(
            tree.joint_types, tree.axes or (None,) * len(tree.edges), strict=True
        )
        if axis is not None
    ]
    axes = view_axes()
    drawn = np.concatenate([p, *(ends for _, ends in segments)])  # all fit in the box
    scale, offset = _fit(drawn @ axes[:2].T, box)
    rows, cols, parts = cloud_pixels(p, ids, scale, offset)
    canvas[rows, cols] = TAB10[parts % 10]
    image = Image.fromarray(canvas, "RGB")
    draw = ImageDraw.Draw(image)
    draw.text((half / 2, _TITLE_H / 2 + 4), title, fill="black", font=font, anchor="mm")
    for joint_type, ends in segments:
        (a, b) = _to_pixels(ends @ axes[:2].T, scale, offset)
        pieces = 1 if joint_type == "revolute" else 9  # prismatic: dashed
        for i in range(0, pieces, 2):
            u, v = a + (b - a) * i / pieces, a + (b - a) * (i + 1) / pieces
            draw.line([tuple(u), tuple(v)], fill="black", width=2)

    _draw_tree(draw, font, tree, (half + _MARGIN, _TITLE_H + _MARGIN, WIDTH - _MARGIN, HEIGHT))
    draw.text(
        (half + half / 2, _TITLE_H / 2 + 4),
        f"kinematic tree: {tree.num_parts} parts",
        fill="black",
        font=font,
        anchor="mm",
    )
    image.save(path, format="PNG")


def _draw_tree(draw: Any, font: Any, tree: KinematicTree, box: tuple[int, int, int, int]) -> None:
    """The tree in the pixel box: parts as boxes in their colours (motion type, root),
    edges parent -> child as arrows labelled with the joint type."""
    pos = _tree_layout(tree.num_parts, tree.root, tree.edges)
    labels = {}
    for node in pos:
        label = f"part {node}\n{MOTION_TYPES[tree.motion_types[node]]}"
        labels[node] = label + ("\n(root)" if node == tree.root else "")
    boxes = [draw.multiline_textbbox((0, 0), t, font=font, align="center") for t in labels.values()]
    half_h = max(b[3] - b[1] for b in boxes) / 2 + 5
    x0, y0, x1, y1 = box
    xs = [x for x, _ in pos.values()]
    levels = -min(y for _, y in pos.values())
    # leaves at most 140 px apart, levels at most 120 px: a small tree is not stretched
    dx = min(140.0, (x1 - x0 - 80) / max(max(xs) - min(xs), 1e-9))
    dy = min(120.0, (y1 - y0 - 2 * half_h - 8) / max(levels, 1e-9))
    centre = (x0 + x1) / 2 - dx * (max(xs) + min(xs)) / 2

    def pixel(node: int) -> tuple[float, float]:
        x, y = pos[node]
        return centre + dx * x, y0 + half_h - dy * y

    for (a, b), joint_type in zip(tree.edges, tree.joint_types, strict=True):
        (ua, va), (ub, vb) = pixel(a), pixel(b)
        start, end = np.array([ua, va + half_h]), np.array([ub, vb - half_h])
        draw.line([tuple(start), tuple(end)], fill=(77, 77, 77), width=1)
        direction = (end - start) / max(float(np.linalg.norm(end - start)), 1e-9)
        normal = np.array([-direction[1], direction[0]])
        head = [
            tuple(end),
            tuple(end - 8 * direction + 4 * normal),
            tuple(end - 8 * direction - 4 * normal),
        ]
        draw.polygon(head, fill=(77, 77, 77))
        middle = (start + end) / 2
        text_box = draw.textbbox(tuple(middle), joint_type, font=font, anchor="mm")
        draw.rounded_rectangle(
            (text_box[0] - 3, text_box[1] - 2, text_box[2] + 3, text_box[3] + 2),
            radius=4,
            fill="white",
        )
        draw.text(tuple(middle), joint_type, fill="black", font=font, anchor="mm")
    for node, label in labels.items():
        u, v = pixel(node)
        b = draw.multiline_textbbox((u, v), label, font=font, anchor="mm", align="center")
        draw.rounded_rectangle(
            (b[0] - 5, b[1] - 4, b[2] + 5, b[3] + 4),
            radius=6,
            fill=_blend(TAB10[node % 10], 0.6),
        )
        draw.multiline_text((u, v), label, fill="black", font=font, anchor="mm", align="center")
