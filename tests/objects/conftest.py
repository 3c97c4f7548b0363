"""Fixtures of the objects tests: the six category configs, a camera, sampled specs."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml

from artic.geometry.camera import CameraIntrinsics
from artic.objects.spec import CategoryConfig, ObjectSpec, sample_spec

CATEGORY_DIR = Path(__file__).resolve().parents[2] / "conf" / "common" / "category"
CATEGORY_NAMES = ("cabinet", "drawer", "microwave", "toaster", "cabinet2", "refrigerator")
TWO_DOF = ("cabinet2", "refrigerator")

SpecFactory = Callable[[str, int], ObjectSpec]


@pytest.fixture(scope="session")
def camera() -> CameraIntrinsics:
    """Kinect v1 intrinsics (640x480, f = 525 px)."""
    return CameraIntrinsics(fx=525.0, fy=525.0, cx=319.5, cy=239.5, width=640, height=480)


@pytest.fixture(scope="session")
def configs() -> dict[str, CategoryConfig]:
    """Every `conf/common/category/*.yaml`, validated."""
    return {
        name: CategoryConfig.model_validate(
            yaml.safe_load((CATEGORY_DIR / f"{name}.yaml").read_text())
        )
        for name in CATEGORY_NAMES
    }


@pytest.fixture(scope="session")
def make_spec(configs: dict[str, CategoryConfig], camera: CameraIntrinsics) -> SpecFactory:
    """`make_spec(category, seed)`: the spec sampled from `default_rng(seed)`."""

    def make(category: str, seed: int) -> ObjectSpec:
        return sample_spec(configs[category], camera, seed, np.random.default_rng(seed))

    return make
