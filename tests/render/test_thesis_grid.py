"""`render.sampling=thesis_grid`: the 16 door openings of the thesis generator's images
(issue 19, item 3), instead of a Latin hypercube over the joint range."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from artic.render.depth import THESIS_GRID, configurations
from cli_runner import run_cli

LIMITS = [(0.0, math.pi / 2)]


def test_sixteen_images_take_exactly_the_sixteen_values_in_order():
    qs = configurations("thesis_grid", np.random.default_rng(0), 16, LIMITS)
    assert qs.shape == (16, 1)
    assert qs[:, 0].tolist() == list(THESIS_GRID)
    assert len(set(THESIS_GRID)) == 16 and all(0 <= q <= math.pi / 2 for q in THESIS_GRID)


def test_fewer_images_take_distinct_grid_values_every_joint_alike_and_seeded():
    a = configurations("thesis_grid", np.random.default_rng(3), 5, LIMITS * 2)
    b = configurations("thesis_grid", np.random.default_rng(3), 5, LIMITS * 2)
    np.testing.assert_array_equal(a, b)
    assert np.all(a[:, 0] == a[:, 1]), "both doors open together, as the generator's"
    assert len(set(a[:, 0])) == 5 and set(a[:, 0]) <= set(THESIS_GRID)
    assert np.all(np.diff(a[:, 0]) > 0)
    continuous = configurations("continuous", np.random.default_rng(3), 5, LIMITS)
    assert not set(continuous[:, 0]) & set(THESIS_GRID)


def test_render_depth_labels_take_the_grid(tiny_objects: Path, tmp_path: Path):
    out = tmp_path / "depth"
    code, _, err = run_cli("render-depth", "debug=tiny", f"dataset={tiny_objects}",
                           "render.sampling=thesis_grid", "render.configurations=16",
                           f"out={out}")  # fmt: skip
    assert code == 0, err
    with (out / "labels.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert rows and {round(float(r["j0_q"]), 9) for r in rows} == {round(q, 9) for q in THESIS_GRID}


@pytest.mark.parametrize(
    ("overrides", "field"),
    [(["render.configurations=17"], "render.configurations"), ([], "render.sampling")],
)
def test_what_the_grid_cannot_do_exits_2_naming_the_field(
    tmp_path: Path, overrides: list[str], field: str
):
    category = "microwave" if overrides else "drawer"  # a drawer slides: no door openings
    objects = tmp_path / "objects"
    code, _, err = run_cli("generate-dataset", "debug=tiny", f"category={category}",
                           "dataset.objects=2", f"out={objects}")  # fmt: skip
    assert code == 0, err
    code, _, err = run_cli("render-depth", "debug=tiny", f"dataset={objects}",
                           "render.sampling=thesis_grid", *overrides,
                           f"out={tmp_path / 'depth'}")  # fmt: skip
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and field in lines[0], err
