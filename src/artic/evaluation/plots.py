"""Plots of the evaluation reports (matplotlib, Agg backend, PNG)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

_TITLES = {
    "position_cm": "axis position error (cm)",
    "rotation_deg": "axis rotation error about z (deg)",
    "configuration": "configuration error",
}


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def error_histograms(
    path: Path, errors: dict[str, dict[str, NDArray[np.float64]]], config_unit: str
) -> None:
    """One panel per metric, one histogram per method."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for ax, (metric, title) in zip(axes, _TITLES.items(), strict=True):
        top = max(float(np.percentile(e[metric], 99)) for e in errors.values()) or 1.0
        bins = np.linspace(0, top, 40)
        for name, e in errors.items():
            ax.hist(np.clip(e[metric], 0, top), bins=bins, histtype="step", label=name, lw=1.5)
        ax.set_title(title if metric != "configuration" else f"{title} ({config_unit})")
        ax.set_ylabel("images")
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)


def calibration_plot(
    path: Path, coverage: dict[float, NDArray[np.float64]], groups: dict[str, list[int]]
) -> None:
    """Empirical coverage of central intervals against the nominal level."""
    plt = _pyplot()
    levels = sorted(coverage)
    fig, ax = plt.subplots(figsize=(4.6, 4.2))
    ax.plot([0, 1], [0, 1], "k--", lw=1, label="calibrated")
    for name, idx in groups.items():
        ax.plot(levels, [float(np.nanmean(coverage[lv][idx])) for lv in levels], "o-", ms=3,
                label=name)  # fmt: skip
    ax.set_xlabel("nominal coverage")
    ax.set_ylabel("fraction of true values inside")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)


def examples_sheet(
    path: Path,
    depths: NDArray[np.float32],
    true_labels: NDArray[np.float64],
    pred_labels: NDArray[np.float64],
    columns: list[str],
    predictor: Any,
) -> None:
    """Depth images with the true (green) and predicted (red) axes."""
    from PIL import Image

    from artic.evaluation.preview import colourise, draw_axes, scaled
    from artic.objects.labels import joint_vector

    col = {c: i for i, c in enumerate(columns)}
    scale = max(1, 256 // predictor.camera.width)
    big = scaled(predictor.camera, scale)

    def axes(label: NDArray[np.float64]) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
        return [
            (
                np.array([label[col[c]] for c in joint_vector(j, "origin")]),
                np.array([label[col[c]] for c in joint_vector(j, "direction")]),
            )
            for j in range(predictor.dof)
        ]

    tiles = []
    kinds = [predictor.joint_type] * predictor.dof
    for depth, truth, pred in zip(depths, true_labels, pred_labels, strict=True):
        tile = colourise(depth).repeat(scale, axis=0).repeat(scale, axis=1)
        tile = draw_axes(tile, axes(truth), kinds, big, colour=(60, 220, 60))
        tiles.append(draw_axes(tile, axes(pred), kinds, big, colour=(255, 60, 60)))
    columns_n = min(4, len(tiles))
    rows = -(-len(tiles) // columns_n)
    h, w = tiles[0].shape[:2]
    sheet = np.zeros((rows * h, columns_n * w, 3), np.uint8)
    for i, tile in enumerate(tiles):
        r, c = divmod(i, columns_n)
        sheet[r * h : (r + 1) * h, c * w : (c + 1) * w] = tile
    Image.fromarray(sheet).save(path, format="PNG")


def bootstrap_curves(path: Path, stats: dict[str, NDArray[np.float64]], title: str) -> None:
    """Figure 5.2: per init (bootstrap, random), the mean normalised return over seeds
    with a standard-error band (`curve_stats` rows [update, rollouts, mean, sem])."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.0, 3.6))
    names = {"bootstrap": "ours (motion-planner bootstrap)", "random": "random init"}
    for init, colour in zip(names, ("C0", "C3"), strict=True):
        s = stats[init]
        ax.plot(s[:, 0], s[:, 2], color=colour, lw=1.8, label=names[init])
        ax.fill_between(s[:, 0], s[:, 2] - s[:, 3], s[:, 2] + s[:, 3], color=colour, alpha=0.25)
    ax.set_xlabel("policy update")
    ax.set_ylabel("normalised return")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=100, metadata={"Software": None})
    plt.close(fig)


def frame_strips(
    path: Path, rows: Sequence[tuple[str, Sequence[NDArray[np.uint8]], str]], title: str
) -> None:
    """Figure 5.3's layout: one row of frames per episode, its label on the left and a
    caption (what the episode achieved) under the row's last frame."""
    plt = _pyplot()
    cols = max(len(frames) for _, frames, _ in rows)
    height, width = rows[0][1][0].shape[:2]
    size = 2.2
    figsize = (size * cols, size * height / width * len(rows) + 0.6)
    fig, axes = plt.subplots(len(rows), cols, squeeze=False, figsize=figsize)
    for r, (label, frames, caption) in enumerate(rows):
        for c in range(cols):
            ax = axes[r, c]
            ax.set_xticks([])
            ax.set_yticks([])
            if c < len(frames):
                ax.imshow(frames[c])
            else:
                ax.axis("off")
        axes[r, 0].set_ylabel(label, fontsize=8)
        axes[r, len(frames) - 1].set_xlabel(caption, fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=100, metadata={"Software": None})
    plt.close(fig)


def dmp_fit_plot(
    path: Path,
    demos: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
    rollout: tuple[NDArray[np.float64], NDArray[np.float64]],
    title: str,
) -> None:
    """fit-dmp's fit.png: one panel per joint, the demos' (t, q) in grey and the DMP
    rollout's (t, y) in blue."""
    plt = _pyplot()
    n_joints = demos[0][1].shape[1]
    cols = min(4, n_joints)
    rows = -(-n_joints // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.4 * rows), squeeze=False)
    for j, ax in enumerate(axes.ravel()):
        if j >= n_joints:
            ax.axis("off")
            continue
        for k, (t, q) in enumerate(demos):
            ax.plot(t, q[:, j], color="0.6", lw=1, label="demos" if k == 0 else None)
        ax.plot(rollout[0], rollout[1][:, j], color="C0", lw=1.5, label="DMP")
        ax.set_title(f"joint {j}", fontsize=9)
        ax.set_xlabel("t (s)", fontsize=8)
        ax.set_ylabel("q (rad)", fontsize=8)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)


def scan_preview(
    path: Path,
    clouds: Sequence[tuple[str, NDArray[np.float32], NDArray[np.int64] | None]],
    columns: int,
    max_points: int,
) -> None:
    """Point clouds in pairs (clean, noisy) side by side, `columns` pairs per row, each a
    3-D scatter of at most about `max_points` points coloured by part id."""
    plt = _pyplot()
    pairs = len(clouds) // 2
    columns = min(columns, pairs)
    n_rows = math.ceil(pairs / columns)
    fig = plt.figure(figsize=(5.0 * columns, 2.6 * n_rows), dpi=100)
    palette = plt.get_cmap("tab10")
    for i, (title, points, part_id) in enumerate(clouds):
        step = max(1, len(points) // max_points)
        p = points[::step]
        part = (part_id if part_id is not None else np.zeros(len(p)))[::step]
        ax = fig.add_subplot(n_rows, 2 * columns, i + 1, projection="3d")
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], c=palette(part % 10), s=1.5, linewidths=0)
        ax.view_init(elev=20, azim=200)
        ax.set_box_aspect(tuple(np.ptp(p, axis=0) + 1e-3))
        ax.set_axis_off()
        ax.set_title(title, fontsize=7)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.95, wspace=0, hspace=0.1)
    fig.savefig(path, format="png", metadata={"Software": None})
    plt.close(fig)
