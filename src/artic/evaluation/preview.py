"""Contact sheets: depth images side by side, with the true joint axes drawn on them."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw

from artic.geometry.camera import CameraIntrinsics

Axis = tuple[NDArray[np.float64], NDArray[np.float64]]  # (origin (3,), unit direction (3,))
_COLOURS = {"revolute": (255, 60, 60), "prismatic": (60, 220, 60)}
_AXIS_LENGTH = 0.3  # metres of axis drawn from its origin


def colourise(depth: NDArray[np.floating]) -> NDArray[np.uint8]:
    """(H, W) depth -> (H, W, 3) grey: near bright, far dark, no return black."""
    valid = depth > 0
    out = np.zeros((*depth.shape, 3), dtype=np.uint8)
    if valid.any():
        lo, hi = float(depth[valid].min()), float(depth[valid].max())
        scale = (hi - depth) / max(hi - lo, 1e-6)
        grey = (60 + 195 * np.clip(scale, 0, 1)).astype(np.uint8)
        out[valid] = grey[valid][:, None]
    return out


def draw_axes(
    image: NDArray[np.uint8],
    axes: Sequence[Axis],
    joint_types: Sequence[str],
    camera: CameraIntrinsics,
    colour: tuple[int, int, int] | None = None,
) -> NDArray[np.uint8]:
    """Draw each axis as a segment from its origin along its direction, with a dot at
    the origin: red revolute, green prismatic, or all in `colour`."""
    pil = Image.fromarray(image)
    draw = ImageDraw.Draw(pil)
    r = max(1, camera.width // 100)
    for (origin, direction), kind in zip(axes, joint_types, strict=True):
        ends = np.stack([origin, origin + _AXIS_LENGTH * direction])
        if (ends[:, 0] <= 1e-3).any():
            continue  # behind the camera
        (u0, v0), (u1, v1) = camera.project(ends)
        fill = colour or _COLOURS.get(kind, (255, 255, 0))
        draw.line([(u0, v0), (u1, v1)], fill=fill, width=max(1, camera.width // 128))
        draw.ellipse([u0 - r, v0 - r, u0 + r, v0 + r], fill=fill)
    return np.asarray(pil)


def contact_sheet(
    depths: Sequence[NDArray[np.floating]],
    axes: Sequence[Sequence[Axis]],
    joint_types: Sequence[Sequence[str]],
    camera: CameraIntrinsics,
    columns: int = 4,
    scale: int = 1,
) -> NDArray[np.uint8]:
    """Tile depth images (with their axes) into a grid of tiles enlarged `scale` times
    (nearest pixel): (rows * scale * H, columns * scale * W, 3) uint8."""
    if not depths:
        raise ValueError("contact_sheet needs at least one image")
    big = scaled(camera, scale)
    h, w = big.height, big.width
    columns = max(1, min(columns, len(depths)))
    rows = -(-len(depths) // columns)
    sheet = np.zeros((rows * h, columns * w, 3), dtype=np.uint8)
    for i, (depth, ax, kinds) in enumerate(zip(depths, axes, joint_types, strict=True)):
        grey = colourise(depth).repeat(scale, axis=0).repeat(scale, axis=1)
        tile = draw_axes(grey, ax, kinds, big)
        r, c = divmod(i, columns)
        sheet[r * h : (r + 1) * h, c * w : (c + 1) * w] = tile
    return sheet


def scaled(camera: CameraIntrinsics, scale: int) -> CameraIntrinsics:
    """The camera whose pixels are `scale` x `scale` blocks of `camera`'s."""
    offset = (scale - 1) / 2  # pixel centre of a block, in enlarged pixels
    return CameraIntrinsics(
        fx=camera.fx * scale,
        fy=camera.fy * scale,
        cx=camera.cx * scale + offset,
        cy=camera.cy * scale + offset,
        width=camera.width * scale,
        height=camera.height * scale,
    )


def labelled_sheet(
    depths: Sequence[NDArray[np.floating]],
    labels: Sequence[NDArray[np.float64]],
    label_columns: Sequence[str],
    dof: int,
    joint_type: str,
    camera: CameraIntrinsics,
    columns: int,
    tile_px: int,
) -> NDArray[np.uint8]:
    """`contact_sheet` of depth images with the axes their label vectors
    (`objects.labels.label_columns` order) give, small images enlarged (whole multiples)
    to about `tile_px` wide."""
    from artic.objects.labels import joint_vector

    col = {c: i for i, c in enumerate(label_columns)}
    axes = [
        [
            (
                np.array([lab[col[c]] for c in joint_vector(j, "origin")]),
                np.array([lab[col[c]] for c in joint_vector(j, "direction")]),
            )
            for j in range(dof)
        ]
        for lab in labels
    ]
    kinds = [[joint_type] * dof for _ in depths]
    scale = max(1, tile_px // camera.width)
    return contact_sheet(depths, axes, kinds, camera, columns, scale)
