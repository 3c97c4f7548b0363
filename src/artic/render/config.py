"""The configs of `render-depth` and `render-scan`, validated straight from their Hydra
config (conf/render_depth: `render=depth`, `render=scan`; the YAML holds each value, these
models its type, range and meaning)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from artic.config.schemas import StageConfig, Strict
from artic.geometry.camera import CameraIntrinsics
from artic.render.noise import SensorNoiseConfig
from artic.render.scan import FusionConfig, ScanViewConfig


class RenderConfig(Strict):
    """What to render and how to store it."""

    backend: Literal["raycast", "pybullet"] = Field(
        "raycast", description="raycast: Open3D RaycastingScene; pybullet: TinyRenderer"
    )
    configurations: int = Field(16, gt=0, description="depth images per object")
    sampling: Literal["continuous", "thesis_grid"] = Field(
        "continuous",
        description="continuous: a Latin hypercube over each joint's range; thesis_grid: "
        "the 16 openings the thesis generator's images take (revolute joints, at most 16 "
        "images per object; docs/objects.md)",
    )
    objects_per_shard: int = Field(64, gt=0, description="objects per shard file (resume unit)")
    depth_encoding: Literal["uint16_mm", "float16_m"] = Field(
        "uint16_mm", description="how depth is stored in shards"
    )
    store_clean_depth: bool = Field(
        False, description="also store the noise-free depth as depth_clean"
    )
    preview_images: int = Field(16, ge=0, description="images in preview.png (0: none)")
    preview_columns: int = Field(4, gt=0, description="columns of the preview contact sheet")


class RenderDepthConfig(StageConfig):
    dataset: str = Field(description="a generate-dataset output folder")
    camera: CameraIntrinsics | None = Field(
        None, description="None: the dataset's camera, the one its positions were sampled for"
    )
    noise: SensorNoiseConfig
    render: RenderConfig


class ScanRenderConfig(Strict):
    """What to scan and how (`conf/render_depth/render/scan.yaml`)."""

    backend: Literal["raycast"] = Field("raycast", description="Open3D RaycastingScene")
    configurations: int = Field(
        18, gt=0, description="poses per object: the first N of poses.json, else a Latin hypercube"
    )
    objects_per_shard: int = Field(16, gt=0, description="objects per resumable chunk")
    clean_points: int = Field(10000, gt=0, description="surface samples per clean cloud")
    views: ScanViewConfig = Field(default_factory=ScanViewConfig)
    fusion: FusionConfig = Field(default_factory=FusionConfig)
    preview_images: int = Field(6, ge=0, description="clouds shown in preview.png (0: none)")
    preview_columns: int = Field(3, gt=0, description="clean/noisy pairs per preview row")


class RenderScanConfig(StageConfig):
    dataset: str = Field(description="a generate-dataset output folder")
    camera: CameraIntrinsics
    noise: SensorNoiseConfig
    render: ScanRenderConfig
