"""hierarchy.png (`artic.evaluation.hierarchy_plot`): the view, the nearest point on top,
the picture's size, colours and bytes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from artic.evaluation.hierarchy_plot import (
    HEIGHT,
    TAB10,
    WIDTH,
    cloud_pixels,
    draw_hierarchy,
    view_axes,
)
from artic.objects.tree import JointAxis, KinematicTree


def test_the_view_is_a_right_handed_rotation_with_z_up_on_screen() -> None:
    axes = view_axes()
    np.testing.assert_allclose(axes @ axes.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(axes) > 0
    assert axes[1, 2] > 0.9  # z points up on the screen (elevation 20 deg)
    assert axes[0, 2] == 0.0  # and never sideways


def test_the_nearest_point_keeps_the_pixel() -> None:
    """Two points on one line of sight: the one nearer the viewer is drawn, whichever
    comes first in the cloud."""
    toward = view_axes()[2]
    near, far = 0.5 * toward, -0.5 * toward
    for points, parts, nearer in (([near, far], [3, 7], 3), ([far, near], [7, 3], 3)):
        rows, cols, part = cloud_pixels(
            np.array(points), np.array(parts), 10.0, np.array([100.0, 100.0])
        )
        assert len(rows) == 4  # one 2 x 2 dot, every pixel once
        assert set(part.tolist()) == {nearer}
        assert len(set(zip(rows.tolist(), cols.tolist(), strict=True))) == 4


def _tree() -> KinematicTree:
    axis = JointAxis(origin=np.array([0.2, 0.0, 0.5]), direction=np.array([0.0, 0.0, 1.0]))
    slide = JointAxis(origin=np.array([0.0, 0.0, 0.2]), direction=np.array([1.0, 0.0, 0.0]))
    return KinematicTree(
        num_parts=3,
        root=0,
        edges=((0, 1), (0, 2)),
        motion_types=(0, 1, 2),
        joint_types=("revolute", "prismatic"),
        axes=(axis, slide),
    )


def test_hierarchy_png_shows_every_part_in_its_colour_and_repeats_its_bytes(
    tmp_path: Path,
) -> None:
    rng = np.random.default_rng(0)
    points = rng.uniform(-0.3, 0.3, (3000, 3)) + np.repeat(
        [[0, 0, 0], [0, 0.8, 0], [0, 0, 0.8]], 1000, 0
    )
    part_id = np.repeat([0, 1, 2], 1000)
    for name in ("a.png", "b.png"):
        draw_hierarchy(tmp_path / name, points, part_id, _tree(), "three boxes")
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()
    picture = np.asarray(Image.open(tmp_path / "a.png").convert("RGB"))
    assert picture.shape == (HEIGHT, WIDTH, 3)
    cloud = picture[:, : WIDTH // 2].reshape(-1, 3)
    for part in range(3):  # each part's colour covers pixels of the cloud's half
        assert (cloud == TAB10[part]).all(axis=1).sum() > 500
    assert (cloud == 0).all(axis=1).any()  # the joint axes, in black
    tree_half = picture[:, WIDTH // 2 :]
    assert (tree_half != 255).any(axis=2).mean() > 0.005  # the tree's boxes and text


def test_a_tree_of_one_part_without_axes_is_drawn(tmp_path: Path) -> None:
    points = np.random.default_rng(1).normal(size=(200, 3))
    tree = KinematicTree(num_parts=1, root=0, edges=(), motion_types=(0,), joint_types=())
    draw_hierarchy(tmp_path / "one.png", points, np.zeros(200, dtype=np.int64), tree, "one")
    assert Image.open(tmp_path / "one.png").size == (WIDTH, HEIGHT)
