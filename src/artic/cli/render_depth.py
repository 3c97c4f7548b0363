"""`artic render-depth`: labelled depth images across each object's articulation.

For object i, the configurations (a Latin hypercube over its joint ranges, so 2-DoF
objects cover their 2-D configuration space) and the sensor noise are drawn from a
generator seeded by (seed, i); shards hold a fixed number of objects. Any sharding of
the work therefore writes the same bytes.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from artic.artifacts.depth_dataset import INFO, LABELS, PREVIEW, decode_depth, shard_name
from artic.artifacts.formats import read_npz, write_csv, write_json, write_npz
from artic.artifacts.object_dataset import ObjectDataset
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import StageConfig, Strict
from artic.geometry.camera import CameraIntrinsics
from artic.render.noise import SensorNoiseConfig

PREVIEW_TILE_PX = 256  # small images are enlarged (whole multiples) to about this width


class RenderConfig(Strict):
    """What to render and how to store it."""

    backend: Literal["raycast", "pybullet"] = Field(
        "raycast", description="raycast: Open3D RaycastingScene; pybullet: TinyRenderer"
    )
    configurations: int = Field(16, gt=0, description="depth images per object")
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


@functools.lru_cache(maxsize=2)
def _dataset(path: str) -> ObjectDataset:
    return ObjectDataset.open(Path(path))


def camera_of(cfg: RenderDepthConfig, ds: ObjectDataset) -> CameraIntrinsics:
    """The camera to render with: `camera=<name>` if given, else the dataset's."""
    return cfg.camera if cfg.camera is not None else ds.camera


def _ids(ds: ObjectDataset, cfg: RenderDepthConfig, chunk: int) -> list[int]:
    size = cfg.render.objects_per_shard
    return [r.object_id for r in ds.rows[chunk * size : (chunk + 1) * size]]


def _plan(cfg: RenderDepthConfig, inputs: dict[str, Path]) -> Plan:
    n = len(_dataset(str(inputs["dataset"])).rows)
    size = cfg.render.objects_per_shard
    per = cfg.render.configurations
    return Plan([per * min(size, n - c * size) for c in range(math.ceil(n / size))], "images")


def encode_depth(depth: NDArray[np.float32], encoding: str) -> NDArray[np.generic]:
    from artic.render.noise import depth_to_uint16_mm

    return depth_to_uint16_mm(depth) if encoding == "uint16_mm" else depth.astype(np.float16)


def render_chunk(cfg: RenderDepthConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Render the objects of shard `chunk` and write `shards/shard-<chunk>.npz` into tmp."""
    from artic.objects.categories import build
    from artic.objects.labels import image_labels, label_columns
    from artic.objects.tree import latin_hypercube
    from artic.render.backend import make_backend
    from artic.render.noise import apply_sensor_noise

    ds = _dataset(str(inputs["dataset"]))
    split = {r.object_id: r.split for r in ds.rows}
    arrays: dict[str, list[NDArray[np.generic]]] = {
        k: [] for k in ("depth", "depth_clean", "part_mask", "labels")
    }
    ids: list[tuple[int, int, bool]] = []
    camera = camera_of(cfg, ds)
    with make_backend(cfg.render.backend, camera, threads=1) as backend:
        for object_id in _ids(ds, cfg, chunk):
            spec = ds.template_spec(object_id)
            obj = build(spec)
            columns = label_columns(spec.dof)
            urdf = ds.urdf(object_id) if cfg.render.backend == "pybullet" else None
            rng = np.random.default_rng([cfg.seed, object_id])
            limits = [tuple(lim) for lim in spec.joint_limits]
            qs = latin_hypercube(rng, cfg.render.configurations, limits)  # type: ignore[arg-type]
            for k, (q, image) in enumerate(
                zip(qs, backend.render_many(obj, qs, urdf), strict=True)
            ):
                noisy = apply_sensor_noise(image.depth, cfg.noise, rng, camera.fx)
                labels = image_labels(spec, obj, q)
                arrays["depth"].append(encode_depth(noisy, cfg.render.depth_encoding))
                if cfg.render.store_clean_depth:
                    clean = encode_depth(image.depth, cfg.render.depth_encoding)
                    arrays["depth_clean"].append(clean)
                arrays["part_mask"].append(image.part_mask)
                arrays["labels"].append(np.array([labels[c] for c in columns]))
                ids.append((object_id, k, split[object_id] == "test"))
    out = {k: np.stack(v) for k, v in arrays.items() if v}
    out["object_id"] = np.array([i[0] for i in ids], dtype=np.int32)
    out["image_index"] = np.array([i[1] for i in ids], dtype=np.int16)
    out["test"] = np.array([i[2] for i in ids], dtype=np.bool_)
    path = tmp / shard_name(chunk)
    path.parent.mkdir(parents=True)
    write_npz(path, out)
    return len(ids)


def _finalize(
    cfg: RenderDepthConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    from artic.objects.labels import label_columns

    ds = _dataset(str(inputs["dataset"]))
    camera = camera_of(cfg, ds)
    dof = ds.rows[0].dof
    columns = label_columns(dof)
    rows: list[list[object]] = []
    n_chunks = math.ceil(len(ds.rows) / cfg.render.objects_per_shard)
    preview: list[NDArray[np.float32]] = []
    preview_labels: list[NDArray[np.float64]] = []
    for chunk in range(n_chunks):
        data = read_npz(work / shard_name(chunk))
        for row in range(data["labels"].shape[0]):
            split = "test" if data["test"][row] else "train"
            rows.append(
                [chunk, row, int(data["object_id"][row]), split, int(data["image_index"][row])]
                + [float(v) for v in data["labels"][row]]
            )
        # one image per object across the first shards, for variety
        step = cfg.render.configurations
        for row in range(0, data["labels"].shape[0], step):
            if len(preview) < cfg.render.preview_images:
                preview.append(decode_depth(data["depth"][row]))
                preview_labels.append(data["labels"][row])
    write_csv(work / LABELS, ["shard", "row", "object_id", "split", "image_index", *columns], rows)
    category = ds.template_spec(ds.rows[0].object_id)
    info = {
        "category": ds.category,
        "dof": dof,
        "joint_type": category.joint_type,
        "camera": camera.model_dump(),
        "label_columns": columns,
        "depth_encoding": cfg.render.depth_encoding,
        "noise": cfg.noise.enabled,
        "backend": cfg.render.backend,
        "images": len(rows),
        "objects": len(ds.rows),
        "configurations_per_object": cfg.render.configurations,
    }
    write_json(work / INFO, info)
    if preview:
        _write_preview(
            work / PREVIEW, preview, preview_labels, columns, dof, cfg, camera, category.joint_type
        )
    n_test = sum(r[3] == "test" for r in rows)
    return {
        "category": ds.category,
        "images": len(rows),
        "train images": len(rows) - n_test,
        "test images": n_test,
        "backend": cfg.render.backend,
    }


def _write_preview(
    path: Path,
    depths: list[NDArray[np.float32]],
    labels: list[NDArray[np.float64]],
    columns: list[str],
    dof: int,
    cfg: RenderDepthConfig,
    camera: CameraIntrinsics,
    joint_type: str,
) -> None:
    from PIL import Image

    from artic.evaluation.preview import contact_sheet

    col = {c: i for i, c in enumerate(columns)}
    axes = [
        [
            (
                np.array([lab[col[f"j{j}_origin_{a}"]] for a in "xyz"]),
                np.array([lab[col[f"j{j}_direction_{a}"]] for a in "xyz"]),
            )
            for j in range(dof)
        ]
        for lab in labels
    ]
    kinds = [[joint_type] * dof for _ in depths]
    scale = max(1, PREVIEW_TILE_PX // camera.width)
    sheet = contact_sheet(depths, axes, kinds, camera, cfg.render.preview_columns, scale)
    Image.fromarray(sheet).save(path, format="PNG")


STAGE: Stage[RenderDepthConfig] = Stage(
    name="render-depth",
    help=(
        "Labelled depth images across each object's articulation (section 3.2.3); with\n"
        "render=scan, fused multi-view point clouds with part labels (Chapter 4).\n\n"
        "Example: artic render-depth dataset=artifacts/objects/refrigerator"
    ),
    conf="render_depth",
    schema=RenderDepthConfig,
    plan=_plan,
    chunk=render_chunk,
    finalize=_finalize,
    inputs={"dataset": "generate-dataset"},
    input_paths=lambda cfg: {"dataset": Path(cfg.dataset)},
)
