"""Chapter 3's labelled depth images (`artic render-depth`): the images of a chunk of
objects, and the label table, info and preview of the finished shards.

For object i, the configurations (a Latin hypercube over its joint ranges, so 2-DoF
objects cover their 2-D configuration space) and the sensor noise are drawn from a
generator seeded by (seed, i); shards hold a fixed number of objects. Any sharding of
the work therefore gives the same arrays. No file access: the stage reads and writes
through `artifacts/`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from artic.artifacts.depth_dataset import decode_depth
from artic.artifacts.object_dataset import ObjectDataset
from artic.errors import InputError
from artic.geometry.camera import CameraIntrinsics
from artic.objects.spec import ObjectSpec
from artic.render.config import RenderDepthConfig

PREVIEW_TILE_PX = 256  # small images are enlarged (whole multiples) to about this width
LABEL_HEADER = ("shard", "row", "object_id", "split", "image_index")


def camera_of(cfg: RenderDepthConfig, ds: ObjectDataset) -> CameraIntrinsics:
    """The camera to render with: `camera=<name>` if given, else the dataset's."""
    return cfg.camera if cfg.camera is not None else ds.camera


def _door_thickness(ds: ObjectDataset) -> list[float] | None:
    """[min, max] door thickness (m) of the generating config's category
    (`CategoryConfig.door_thickness_range`); None when its manifest does not say."""
    from pydantic import ValidationError

    from artic.objects.spec import CategoryConfig

    try:
        category = CategoryConfig.model_validate(ds.manifest.config["category"])
    except (KeyError, TypeError, ValidationError):
        return None
    return list(category.door_thickness_range())


def encode_depth(depth: NDArray[np.float32], encoding: str) -> NDArray[np.generic]:
    from artic.render.noise import depth_to_uint16_mm

    return depth_to_uint16_mm(depth) if encoding == "uint16_mm" else depth.astype(np.float16)


#: the 16 door openings (rad) at which the thesis generator's images are taken: its
#: velocity servo opens every door the same way and it renders every 250 steps (the
#: values of `q_to_idx` in its authors' evaluation code, babbatem/GeneralizingKinematics,
#: `magic/mixture/utils.py`; negative there on one hinge side, q >= 0 in artic)
THESIS_GRID: tuple[float, ...] = (
    3.7259654560926e-06, 0.0619193502438947, 0.158249459384306, 0.257895820952111,
    0.357861743606078, 0.457858459841061, 0.55785814341053, 0.657858112918615,
    0.757858109980349, 0.857858109697211, 0.957858109669927, 1.0578581096673,
    1.15785810966704, 1.25785810966702, 1.35785810966701, 1.457858109667,
)  # fmt: skip


def configurations(
    sampling: str, rng: np.random.Generator, n: int, limits: list[tuple[float, float]]
) -> NDArray[np.float64]:
    """(n, dof) configurations of one object's images: `continuous`, a Latin hypercube
    over the joint ranges (`objects.tree.latin_hypercube`); `thesis_grid`, the 16 values of
    `THESIS_GRID` in order when n = 16, else n of them drawn without replacement and
    sorted, every joint at the same value (the generator opens all doors together)."""
    from artic.objects.tree import latin_hypercube

    if sampling == "continuous":
        return latin_hypercube(rng, n, limits)
    if n > len(THESIS_GRID):
        raise ValueError(f"render.configurations: {n} > the thesis grid's {len(THESIS_GRID)}")
    pick = (
        np.arange(n)
        if n == len(THESIS_GRID)
        else np.sort(rng.choice(len(THESIS_GRID), n, replace=False))
    )
    values = np.asarray(THESIS_GRID)[pick]
    return np.repeat(values[:, None], len(limits), axis=1)


def check_thesis_grid(n: int, spec: ObjectSpec) -> None:
    """InputError unless `render.sampling=thesis_grid` fits: revolute joints, at most 16
    images per object."""
    if spec.joint_type != "revolute":
        raise InputError(
            f"render.sampling: thesis_grid is the generator's door openings; "
            f"{spec.category} has {spec.joint_type} joints"
        )
    if n > len(THESIS_GRID):
        raise InputError(f"render.configurations: {n} > the thesis grid's {len(THESIS_GRID)}")


def render_objects(
    cfg: RenderDepthConfig, ds: ObjectDataset, object_ids: Sequence[int]
) -> dict[str, NDArray[Any]]:
    """The arrays of one shard (`artifacts.depth_dataset.SHARD_ARRAYS`, plus
    `depth_clean` when stored): `render.configurations` images per object."""
    from artic.objects.categories import build
    from artic.objects.labels import image_labels, label_columns
    from artic.render.backend import make_backend
    from artic.render.noise import apply_sensor_noise

    split = {r.object_id: r.split for r in ds.rows}
    arrays: dict[str, list[NDArray[np.generic]]] = {
        k: [] for k in ("depth", "depth_clean", "part_mask", "labels")
    }
    ids: list[tuple[int, int, bool]] = []
    camera = camera_of(cfg, ds)
    with make_backend(cfg.render.backend, camera, threads=1) as backend:
        for object_id in object_ids:
            spec = ds.template_spec(object_id)
            if cfg.render.sampling == "thesis_grid":
                check_thesis_grid(cfg.render.configurations, spec)
            obj = build(spec)
            columns = label_columns(spec.dof)
            urdf = ds.urdf(object_id) if cfg.render.backend == "pybullet" else None
            rng = np.random.default_rng([cfg.seed, object_id])
            limits = [tuple(lim) for lim in spec.joint_limits]
            qs = configurations(cfg.render.sampling, rng, cfg.render.configurations, limits)  # type: ignore[arg-type]
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
    return out


@dataclass(frozen=True)
class DepthIndex:
    """What render-depth writes beside its shards: labels.csv (`columns`, `rows`),
    dataset.json (`info`), preview.png (`preview`, None: none) and the stage's stats."""

    columns: list[str]
    rows: list[list[object]]
    info: dict[str, Any]
    preview: NDArray[np.uint8] | None
    stats: dict[str, float | int | str]


def index_shards(
    cfg: RenderDepthConfig, ds: ObjectDataset, shards: Iterable[Mapping[str, NDArray[Any]]]
) -> DepthIndex:
    """The label table, info and preview of the finished shards (in chunk order)."""
    from artic.evaluation.preview import labelled_sheet
    from artic.objects.labels import label_columns

    camera = camera_of(cfg, ds)
    dof = ds.rows[0].dof
    columns = label_columns(dof)
    rows: list[list[object]] = []
    preview: list[NDArray[np.float32]] = []
    preview_labels: list[NDArray[np.float64]] = []
    for chunk, data in enumerate(shards):
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
        # the doors' thickness the objects were built with (a model's refinement builds its
        # doors at the middle of it: kinematics/predict.py)
        "door_thickness": _door_thickness(ds),
    }
    sheet = None
    if preview:
        n_columns = cfg.render.preview_columns
        sheet = labelled_sheet(
            preview,
            preview_labels,
            columns,
            dof,
            category.joint_type,
            camera,
            n_columns,
            PREVIEW_TILE_PX,
        )
    n_test = sum(r[3] == "test" for r in rows)
    stats: dict[str, float | int | str] = {
        "category": ds.category,
        "images": len(rows),
        "train images": len(rows) - n_test,
        "test images": n_test,
        "backend": cfg.render.backend,
    }
    return DepthIndex([*LABEL_HEADER, *columns], rows, info, sheet, stats)
