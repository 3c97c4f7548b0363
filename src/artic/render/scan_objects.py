"""Chapter 4's labelled scans of a generate-dataset folder (`artic render-scan`): the
poses and motion types of each object, and its clean and fused clouds.

For object i and each of its poses: a clean cloud (surface samples) and a noisy cloud
(K fused Kinect-like views), in the object frame, with part ids and motion types per
point, plus the object's ground-truth kinematic tree. Poses come from the dataset's
`poses.json` when it has one (`generate-dataset dataset=hierarchy`), else from a Latin
hypercube over the joint limits drawn as render-depth draws it; everything random about
object i is seeded by (seed, i), so any sharding of the work gives the same clouds. No
file access: the stage writes through `artifacts/`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray

from artic.artifacts.object_dataset import POSES, TREE, ObjectDataset, object_dir
from artic.errors import InputError
from artic.render.config import RenderScanConfig

if TYPE_CHECKING:
    from artic.objects.model import ArticulatedObject
    from artic.objects.tree import KinematicTree
    from artic.render.backend import DepthBackend
    from artic.render.scan import LabelledCloud

KINDS = ("clean", "noisy")


class ScannedCloud(NamedTuple):
    """One cloud of an object: its pose index, kind, cloud and PLY comments."""

    pose: int
    kind: str  # clean | noisy
    cloud: LabelledCloud
    comments: list[str]


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


def dataset_object(ds: ObjectDataset, object_id: int) -> ArticulatedObject:
    """Object `object_id` of `ds`: built from its spec.json when the spec's category is one
    of artic's generators (the registries of `objects.categories` and
    `objects.structures`), else from its object.urdf and meshes (both verified against the
    manifest), as `artic.objects.partnet` reads a URDF: objects written in
    generate-dataset's layout by another generator (bench/independent_objects.py) scan
    like artic's own."""
    from artic.artifacts.manifest import verify_file
    from artic.objects.categories import CATEGORIES
    from artic.objects.families import build_object, spec_category
    from artic.objects.partnet import mesh_filenames, parse_obj, partnet_object
    from artic.objects.structures import STRUCTURES

    spec = verify_file(ds.root, ds.manifest, f"{object_dir(object_id)}/spec.json")
    try:
        category = spec_category(spec.read_text())
    except ValueError:
        category = None  # ds.spec names the problem
    if category is None or category in CATEGORIES or category in STRUCTURES:
        return build_object(ds.spec(object_id))
    urdf = ds.urdf(object_id)
    text = urdf.read_text()
    meshes = {
        name: parse_obj((urdf.parent / name).read_bytes(), source=str(urdf.parent / name))
        for name in mesh_filenames(text, source=str(urdf))
    }
    return partnet_object(text, meshes, source=str(urdf)).object


def scan_object(
    cfg: RenderScanConfig, ds: ObjectDataset, object_id: int, backend: DepthBackend
) -> tuple[KinematicTree, list[ScannedCloud]]:
    """Object `object_id`'s ground-truth tree and its clouds (pose by pose, clean then
    noisy), rendered with `backend` (`render.backend.make_backend` of cfg.camera)."""
    from artic.render.scan import fuse_views_many, object_tree, sample_surface, view_poses

    row = next(r for r in ds.rows if r.object_id == object_id)
    obj = dataset_object(ds, object_id)
    qs, source = object_poses(ds, object_id, obj, cfg)
    motion = object_motion_types(ds, object_id, obj)
    tree = object_tree(obj, motion)
    cameras = view_poses(obj, qs, cfg.camera, cfg.render.views)
    noise_rng = np.random.default_rng([cfg.seed, object_id, 3])
    noisy = fuse_views_many(
        obj, qs, cameras, backend, cfg.noise, noise_rng, cfg.render.fusion, motion
    )
    clean_rng = np.random.default_rng([cfg.seed, object_id, 2])
    clouds: list[ScannedCloud] = []
    for pose, (q, fused) in enumerate(zip(qs, noisy, strict=True)):
        clean = sample_surface(obj, q, cfg.render.clean_points, clean_rng, motion)
        for kind, cloud in zip(KINDS, (clean, fused), strict=True):
            comments = [
                "artic render-depth render=scan",
                f"category {row.category}",
                f"object_id {object_id}",
                f"split {row.split}",
                f"pose {pose}",
                f"kind {kind}",
                "configuration " + " ".join(repr(float(v)) for v in q),
                f"poses {source}",
                "frame object (root link), metres",
            ]
            clouds.append(ScannedCloud(pose, kind, cloud, comments))
    return tree, clouds
