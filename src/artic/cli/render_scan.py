"""`artic render-scan` (alias `artic render-depth render=scan`): labelled point clouds
of each object across its articulation, for Chapter 4 (part segmentation and kinematic
hierarchies).

The scan stage shares render-depth's config tree (`conf/render_depth/`; its `preset`
`render=scan` selects `render/scan.yaml`) but has its own schema, stage name ("render-scan") and
output folder (`artifacts/scans/<category>`). For object i and each of its poses it
writes a clean cloud (surface samples) and a noisy cloud (K fused Kinect-like views) as
PLY, in the object frame, with part ids and motion types per point, plus the object's
ground-truth kinematic tree. Poses come from the dataset's `poses.json` when it has one
(`generate-dataset dataset=hierarchy`), else from a Latin hypercube over the joint limits
drawn as render-depth draws it; everything random about object i is seeded by (seed, i),
so any sharding of the work writes the same bytes.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import TYPE_CHECKING, Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.object_dataset import POSES, TREE, ObjectDataset, object_dir
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import StageConfig, Strict
from artic.errors import InputError
from artic.geometry.camera import CameraIntrinsics
from artic.render.noise import SensorNoiseConfig
from artic.render.scan import FusionConfig, ScanViewConfig

if TYPE_CHECKING:
    from artic.objects.model import ArticulatedObject

STAGE_NAME = "render-scan"
INFO = "scans.json"
INDEX = "index.csv"
PREVIEW = "preview.png"
KINDS = ("clean", "noisy")
_PREVIEW_POINTS = 4000  # points drawn per cloud in preview.png


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


class IndexRow(NamedTuple):
    """One row of index.csv: one cloud file."""

    object_id: int
    pose: int
    kind: str  # clean | noisy
    split: str  # train | test
    points: int
    file: str  # relative to the output folder
    configuration: str  # joint values, space-separated, radians / metres


class RenderScanConfig(StageConfig):
    dataset: str = Field(description="a generate-dataset output folder")
    camera: CameraIntrinsics
    noise: SensorNoiseConfig
    render: ScanRenderConfig


def scan_file(object_id: int, pose: int, kind: str) -> str:
    """Relative path of one cloud: scans/<object>_<pose>_<clean|noisy>.ply."""
    return f"scans/{object_id:06d}_{pose:02d}_{kind}.ply"


def tree_file(object_id: int) -> str:
    """Relative path of an object's ground-truth kinematic tree."""
    return f"trees/{object_id:06d}.json"


@functools.lru_cache(maxsize=2)
def _dataset(path: str) -> ObjectDataset:
    return ObjectDataset.open(Path(path))


def _ids(ds: ObjectDataset, cfg: RenderScanConfig, chunk: int) -> list[int]:
    size = cfg.render.objects_per_shard
    return [r.object_id for r in ds.rows[chunk * size : (chunk + 1) * size]]


def _plan(cfg: RenderScanConfig, inputs: dict[str, Path]) -> Plan:
    ds = _dataset(str(inputs["dataset"]))
    check_configurations(ds, cfg)
    n = len(ds.rows)
    size = cfg.render.objects_per_shard
    return Plan([min(size, n - c * size) for c in range(math.ceil(n / size))], "objects")


def check_configurations(ds: ObjectDataset, cfg: RenderScanConfig) -> None:
    """InputError naming render.configurations when an object's poses.json has fewer
    poses than asked for (the manifest would promise more clouds than were rendered)."""
    n = cfg.render.configurations
    for row in ds.rows:
        if ds.has(row.object_id, POSES):
            available = len(ds.poses(row.object_id).array())
            if available < n:
                raise InputError(
                    f"config field render.configurations: {n} poses asked for, but "
                    f"{ds.root / object_dir(row.object_id) / POSES} has {available}; "
                    f"set render.configurations <= {available}"
                )


def object_poses(
    ds: ObjectDataset, object_id: int, obj: ArticulatedObject, cfg: RenderScanConfig
) -> tuple[NDArray[np.float64], str]:
    """(n, dof) poses of one object and where they came from ("poses.json" or
    "latin_hypercube"): the first `configurations` rows of the dataset's poses.json,
    else the Latin hypercube render-depth draws from (seed, object_id)."""
    from artic.objects.tree import latin_hypercube

    n = cfg.render.configurations
    if not ds.has(object_id, POSES):
        rng = np.random.default_rng([cfg.seed, object_id])
        limits = [(float(j.limits[0]), float(j.limits[1])) for j in obj.movable_joints]
        return latin_hypercube(rng, n, limits), "latin_hypercube"
    poses = ds.poses(object_id)
    names, expected = list(poses.joint_names), [j.name for j in obj.movable_joints]
    if sorted(names) != sorted(expected):
        where = ds.root / object_dir(object_id) / POSES
        raise InputError(f"{where}: joint_names {names} are not the URDF's movable {expected}")
    order = [names.index(name) for name in expected]
    available = poses.array()
    if len(available) < n:
        where = ds.root / object_dir(object_id) / POSES
        raise InputError(
            f"config field render.configurations: {n} poses asked for, but {where} has "
            f"{len(available)}; set render.configurations <= {len(available)}"
        )
    return available[:n, order], "poses.json"


def object_motion_types(
    ds: ObjectDataset, object_id: int, obj: ArticulatedObject
) -> NDArray[np.int64]:
    """(P,) motion types: `motion_type_ids` of the dataset's tree.json when it has one,
    else from the joints (`part_motion_types`)."""
    from artic.render.scan import part_motion_types

    if not ds.has(object_id, TREE):
        return part_motion_types(obj)
    motion = ds.tree(object_id).part_motion_types()
    if motion.shape != (len(obj.links),):
        where = ds.root / object_dir(object_id) / TREE
        raise InputError(f"{where}: {len(motion)} parts, the URDF has {len(obj.links)} links")
    return motion


def scan_chunk(cfg: RenderScanConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Scan the objects of chunk `chunk` into tmp: their clouds and trees."""
    from artic.artifacts.ply import write_ply
    from artic.objects.families import build_object
    from artic.render.backend import make_backend
    from artic.render.scan import fuse_views_many, object_tree, sample_surface, view_poses

    ds = _dataset(str(inputs["dataset"]))
    rows = {r.object_id: r for r in ds.rows}
    ids = _ids(ds, cfg, chunk)
    (tmp / "scans").mkdir(parents=True)
    (tmp / "trees").mkdir()
    with make_backend(cfg.render.backend, cfg.camera, threads=1) as backend:
        for object_id in ids:
            obj = build_object(ds.spec(object_id))
            qs, source = object_poses(ds, object_id, obj, cfg)
            motion = object_motion_types(ds, object_id, obj)
            tree = object_tree(obj, motion)
            (tmp / tree_file(object_id)).write_text(tree.to_json() + "\n")
            cameras = view_poses(obj, qs, cfg.camera, cfg.render.views)
            noise_rng = np.random.default_rng([cfg.seed, object_id, 3])
            noisy = fuse_views_many(
                obj, qs, cameras, backend, cfg.noise, noise_rng, cfg.render.fusion, motion
            )
            clean_rng = np.random.default_rng([cfg.seed, object_id, 2])
            for pose, (q, fused) in enumerate(zip(qs, noisy, strict=True)):
                clean = sample_surface(obj, q, cfg.render.clean_points, clean_rng, motion)
                for kind, cloud in zip(KINDS, (clean, fused), strict=True):
                    comments = [
                        "artic render-depth render=scan",
                        f"category {rows[object_id].category}",
                        f"object_id {object_id}",
                        f"split {rows[object_id].split}",
                        f"pose {pose}",
                        f"kind {kind}",
                        "configuration " + " ".join(repr(float(v)) for v in q),
                        f"poses {source}",
                        "frame object (root link), metres",
                    ]
                    write_ply(
                        tmp / scan_file(object_id, pose, kind),
                        cloud.points,
                        part_id=cloud.part_id,
                        motion_type=cloud.motion_type,
                        comments=comments,
                    )
    return len(ids)


def _finalize(
    cfg: RenderScanConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    from artic.artifacts.ply import read_ply_header

    ds = _dataset(str(inputs["dataset"]))
    rows: list[IndexRow] = []
    sources: set[str] = set()
    for path in sorted((work / "scans").glob("*.ply")):
        header = read_ply_header(path)
        meta = dict(c.partition(" ")[::2] for c in header.comments)
        vertex = header.element("vertex")
        assert vertex is not None
        sources.add(meta["poses"])
        rows.append(
            IndexRow(
                object_id=int(meta["object_id"]),
                pose=int(meta["pose"]),
                kind=meta["kind"],
                split=meta["split"],
                points=vertex.count,
                file=path.relative_to(work).as_posix(),
                configuration=meta["configuration"],
            )
        )
    write_csv(work / INDEX, IndexRow._fields, rows)
    counts = {k: [r.points for r in rows if r.kind == k] for k in KINDS}
    info = {
        "category": ds.category,
        "objects": len(ds.rows),
        "clouds_per_kind": len(counts["noisy"]),
        "poses": sorted(sources),
        "camera": cfg.camera.model_dump(),
        "noise": cfg.noise.model_dump(),
        "render": cfg.render.model_dump(mode="json"),
        "frame": "object (root link): base at the centre of the body's bottom face, z up, "
        "front towards -x; metres",
        "ply_properties": ["x", "y", "z", "part_id", "motion_type"],
        "motion_types": ["static", "rotating", "translating", "both"],
    }
    write_json(work / INFO, info)
    if cfg.render.preview_images:
        _write_preview(work, rows, cfg)
    n_test = sum(1 for r in rows if r.kind == "noisy" and r.split == "test")
    noisy = counts["noisy"]
    return {
        "category": ds.category,
        "objects": len(ds.rows),
        "clouds (clean + noisy)": len(rows),
        "test poses": n_test,
        "mean noisy points": round(float(np.mean(noisy)), 1) if noisy else 0.0,
        "poses from": ", ".join(sorted(sources)),
    }


def _write_preview(work: Path, rows: list[IndexRow], cfg: RenderScanConfig) -> None:
    """preview.png: the first pose of the first objects, clean and noisy side by side,
    points coloured by part id."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from artic.artifacts.ply import read_ply

    firsts = [r for r in rows if r.pose == 0 and r.kind == "clean"][: cfg.render.preview_images]
    columns = min(cfg.render.preview_columns, len(firsts))
    n_rows = math.ceil(len(firsts) / columns)
    fig = plt.figure(figsize=(5.0 * columns, 2.6 * n_rows), dpi=100)
    palette = plt.get_cmap("tab10")
    for i, row in enumerate(firsts):
        for j, kind in enumerate(KINDS):
            rel = scan_file(row.object_id, row.pose, kind)
            cloud = read_ply(work / rel)
            step = max(1, len(cloud.points) // _PREVIEW_POINTS)
            p = cloud.points[::step]
            part = (cloud.part_id if cloud.part_id is not None else np.zeros(len(p)))[::step]
            ax = fig.add_subplot(n_rows, 2 * columns, 2 * i + j + 1, projection="3d")
            ax.scatter(p[:, 0], p[:, 1], p[:, 2], c=palette(part % 10), s=1.5, linewidths=0)
            ax.view_init(elev=20, azim=200)
            ax.set_box_aspect(tuple(np.ptp(p, axis=0) + 1e-3))
            ax.set_axis_off()
            ax.set_title(f"{row.object_id:06d} pose 0 {kind}", fontsize=7)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.95, wspace=0, hspace=0.1)
    fig.savefig(work / PREVIEW, format="png", metadata={"Software": None})
    plt.close(fig)


STAGE: Stage[RenderScanConfig] = Stage(
    name=STAGE_NAME,
    help=(
        "Fused multi-view point clouds with part labels and motion types across each\n"
        "object's articulation (Chapter 4); also run as render-depth render=scan.\n\n"
        "Example: artic render-scan dataset=artifacts/objects/storage_furniture"
    ),
    preset=("render=scan",),
    alias="render-depth render=scan",
    conf="render_depth",
    schema=RenderScanConfig,
    plan=_plan,
    chunk=scan_chunk,
    finalize=_finalize,
    inputs={"dataset": "generate-dataset"},
    input_paths=lambda cfg: {"dataset": Path(cfg.dataset)},
)
