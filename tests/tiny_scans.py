"""Tiny Chapter 4 data made by the real stages, once per test session and category.

A module (not a conftest fixture) so that tests in several folders share one copy:
`tiny_hierarchy_scans(tmp_path_factory)` runs `generate-dataset dataset=hierarchy
debug=tiny` (6 objects, 2 withheld) and `render-depth render=scan debug=tiny` with a
small camera, 2 poses and 3 views per noisy cloud.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import pytest

from cli_runner import run_cli


class TinyScans(NamedTuple):
    objects: Path  # generate-dataset output
    scans: Path  # render-scan output


_MADE: dict[str, TinyScans] = {}

SCAN_OPTIONS = (
    "render=scan",
    "debug=tiny",
    "camera=kinect_v1_128",
    "render.configurations=2",
    "render.views.views=3",
    "render.clean_points=2000",
    "render.fusion.max_points=1500",
    "render.preview_images=0",
)


def tiny_hierarchy_scans(
    factory: pytest.TempPathFactory, category: str = "storage_furniture"
) -> TinyScans:
    if category not in _MADE:
        root = factory.mktemp("ch4_" + category)
        objects, scans = root / "objects", root / "scans"
        code, _, err = run_cli(
            "generate-dataset", "debug=tiny", "dataset=hierarchy", f"category={category}",
            f"out={objects}",
        )  # fmt: skip
        assert code == 0, err
        code, _, err = run_cli("render-depth", *SCAN_OPTIONS, f"dataset={objects}", f"out={scans}")
        assert code == 0, err
        _MADE[category] = TinyScans(objects, scans)
    return _MADE[category]
