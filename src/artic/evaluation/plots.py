"""Plots of the evaluation reports (matplotlib, Agg backend, PNG)."""

from __future__ import annotations

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

    col = {c: i for i, c in enumerate(columns)}
    scale = max(1, 256 // predictor.camera.width)
    big = scaled(predictor.camera, scale)

    def axes(label: NDArray[np.float64]) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
        return [
            (
                np.array([label[col[f"j{j}_origin_{a}"]] for a in "xyz"]),
                np.array([label[col[f"j{j}_direction_{a}"]] for a in "xyz"]),
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
