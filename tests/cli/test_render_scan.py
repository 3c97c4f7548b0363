"""`artic render-depth render=scan` end to end on the tiny preset (src/artic/cli/render_scan.py)."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_stages import tree_bytes

from artic.artifacts.formats import write_json
from artic.artifacts.manifest import (
    MANIFEST,
    list_outputs,
    outputs_hash,
    read_manifest,
)
from artic.artifacts.object_dataset import ObjectDataset
from artic.artifacts.ply import read_ply
from artic.cli import render_scan
from artic.cli.render_scan import STAGE, scan_file
from artic.cli.stage_runner import resolved_config, run_stage
from artic.config.compose import validate
from artic.errors import InputError
from artic.objects.categories import build
from artic.objects.tree import KinematicTree, object_tree
from artic.render.scan_objects import object_motion_types, object_poses
from cli_runner import run_cli

# small and fast: the 128 px camera, 2 poses, 3 views per scan
SMALL = [
    "render=scan",
    "debug=tiny",
    "camera=kinect_v1_128",
    "render.configurations=2",
    "render.views.views=3",
    "render.clean_points=2000",
    "render.fusion.max_points=1500",
    "render.preview_images=2",
]


def scan(dataset: Path, out: Path, *extra: str) -> None:
    result = run_stage(STAGE, [*SMALL, f"dataset={dataset}", f"out={out}", *extra])
    assert result.status in ("complete", "partial"), result.message


@pytest.fixture(scope="module")
def tiny_scans(tiny_objects: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scans") / "microwave"
    scan(tiny_objects, out)
    return out


def test_scan_stage_writes_labelled_clouds_trees_index_and_preview(tiny_scans, tiny_objects):
    manifest = read_manifest(tiny_scans, expected_stage="render-scan")
    assert manifest.stats["clouds (clean + noisy)"] == 6 * 2 * 2
    assert manifest.stats["poses from"] == "latin_hypercube"
    with (tiny_scans / "index.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == [
        "object_id",
        "pose",
        "kind",
        "split",
        "points",
        "file",
        "configuration",
    ]
    assert len(rows) == 24
    assert {r["split"] for r in rows if r["object_id"] in ("2", "5")} == {"test"}
    ds = ObjectDataset.open(tiny_objects)
    for row in rows:
        object_id, pose = int(row["object_id"]), int(row["pose"])
        assert row["file"] == scan_file(object_id, pose, row["kind"])
        cloud = read_ply(tiny_scans / row["file"])
        assert len(cloud.points) == int(row["points"]) > 500
        tree = KinematicTree.from_json((tiny_scans / f"trees/{object_id:06d}.json").read_text())
        assert tree.num_parts == 3 and tree.edges == ((0, 1), (1, 2))  # body, door, handle
        assert cloud.part_id is not None and cloud.motion_type is not None
        assert set(np.unique(cloud.part_id)) <= {0, 1, 2}
        assert np.array_equal(cloud.motion_type, np.array(tree.motion_types)[cloud.part_id])
        # the object frame: base at the bottom face's centre, so z >= 0 and the body is
        # centred on x, y; the recorded configuration is inside the joint limits
        assert cloud.points[:, 2].min() > -0.05
        q = float(row["configuration"])
        lo, hi = ds.spec(object_id).joint_limits[0]
        assert lo <= q <= hi
        assert f"configuration {row['configuration']}" in cloud.comments
    info = json.loads((tiny_scans / "scans.json").read_text())
    assert info["category"] == "microwave" and info["camera"]["width"] == 128
    assert (tiny_scans / "preview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_shards_merge_into_the_same_bytes(tiny_scans, tiny_objects, tmp_path):
    out = tmp_path / "sharded"
    scan(tiny_objects, out, "shard.count=2", "shard.index=1")
    assert not out.exists()  # half the chunks: nothing published yet
    scan(tiny_objects, out, "shard.count=2", "shard.index=0")
    assert tree_bytes(out) == tree_bytes(tiny_scans)


def test_config_selects_scans_and_rejects_bad_values(tiny_objects):
    raw = resolved_config(STAGE, ["render=scan", "dataset=artifacts/objects/storage_furniture"])
    assert raw["out"] == "artifacts/scans/storage_furniture"
    assert raw["camera"]["width"] == 640  # the full Kinect camera by default
    cfg = validate(render_scan.RenderScanConfig, raw)
    assert cfg.render.configurations == 18 and cfg.render.views.views == 6
    for bad, field in [
        ("render.views.views=0", "render.views.views"),
        ("render.backend=pybullet", "render.backend"),
        ("render.fusion.voxel_m=-1", "render.fusion.voxel_m"),
    ]:
        with pytest.raises(InputError, match=field):
            run_stage(STAGE, [*SMALL, f"dataset={tiny_objects}", "out=/nonexistent/x", bad])
    with pytest.raises(InputError, match="no such folder"):
        run_stage(STAGE, [*SMALL, "dataset=/nonexistent/objects", "out=/nonexistent/x"])


def with_files(src: Path, dst: Path, files: dict[str, str]) -> ObjectDataset:
    """A copy of a generate-dataset folder with extra files, its manifest updated."""
    shutil.copytree(src, dst)
    for rel, text in files.items():
        (dst / rel).write_text(text)
    manifest = read_manifest(dst)
    outputs = list_outputs(dst)
    update = {"outputs": outputs, "content_hash": outputs_hash(outputs)}
    write_json(dst / MANIFEST, manifest.model_copy(update=update).model_dump(mode="json"))
    return ObjectDataset.open(dst)


def test_poses_and_motion_types_come_from_hierarchy_files_when_present(tiny_objects, tmp_path):
    poses = {"joint_names": ["joint_0"], "configurations": [[0.1], [0.2], [0.3]]}
    # a tree.json that says the door both rotates and translates: read, not recomputed
    tree = object_tree(build(ObjectDataset.open(tiny_objects).spec(0)))
    tree = tree.model_copy(
        update={"motion_types": ("static", "both", "static"), "motion_type_ids": (0, 3, 0)}
    )
    ds = with_files(
        tiny_objects,
        tmp_path / "objects",
        {
            "objects/000000/poses.json": json.dumps(poses),
            "objects/000000/tree.json": tree.model_dump_json(),
            "objects/000001/poses.json": json.dumps({"joint_names": ["x"], "configurations": []}),
            "objects/000002/poses.json": json.dumps(
                {"joint_names": ["x"], "configurations": [[0.0]]}
            ),
        },
    )
    cfg = validate(
        render_scan.RenderScanConfig,
        resolved_config(STAGE, [*SMALL, f"dataset={ds.root}"]),
    )
    obj = build(ds.spec(0))
    qs, source = object_poses(ds, 0, obj, cfg)
    assert source == "poses.json" and qs.tolist() == [[0.1], [0.2]]  # first N = 2
    assert object_motion_types(ds, 0, obj).tolist() == [0, 3, 0]
    with pytest.raises(InputError, match=r"000001/poses\.json: malformed"):
        object_poses(ds, 1, build(ds.spec(1)), cfg)
    with pytest.raises(InputError, match=r"000002/poses\.json: joint_names \['x'\]"):
        object_poses(ds, 2, build(ds.spec(2)), cfg)
    qs, source = object_poses(ds, 3, build(ds.spec(3)), cfg)
    assert source == "latin_hypercube" and qs.shape == (2, 1)
    assert object_motion_types(ds, 3, build(ds.spec(3))).tolist() == [0, 1, 0]


def test_command_line_render_depth_render_scan(tiny_scans, tiny_objects, tmp_path):
    out = tmp_path / "cli"
    code, _, err = run_cli("render-depth", *SMALL, f"dataset={tiny_objects}", f"out={out}")
    assert code == 0, err
    assert read_manifest(out).stage == "render-scan"
    assert tree_bytes(out) == tree_bytes(tiny_scans)
    code, _, err = run_cli("render-depth", "render=scan", "dataset=/nonexistent/objects")
    assert code == 2 and "no such folder" in err


def test_hierarchy_dataset_poses_and_trees_are_used(tmp_path):
    pytest.importorskip("artic.objects.structures")
    objects = tmp_path / "objects"
    code, _, err = run_cli(
        "generate-dataset",
        "debug=tiny",
        "dataset=hierarchy",
        "category=storage_furniture",
        "dataset.objects=2",
        f"out={objects}",
    )
    assert code == 0, err
    out = tmp_path / "scans"
    scan(objects, out, "render.preview_images=0")
    assert read_manifest(out).stats["poses from"] == "poses.json"
    for object_id in range(2):
        folder = objects / f"objects/{object_id:06d}"
        truth = json.loads((folder / "tree.json").read_text())
        tree = KinematicTree.from_json((out / f"trees/{object_id:06d}.json").read_text())
        assert [list(e) for e in tree.edges] == truth["edges"]
        assert list(tree.motion_types) == truth["motion_type_ids"]
        poses = json.loads((folder / "poses.json").read_text())["configurations"]
        for pose in range(2):
            cloud = read_ply(out / scan_file(object_id, pose, "noisy"))
            values = " ".join(repr(float(v)) for v in poses[pose])
            assert f"configuration {values}" in cloud.comments
            assert cloud.motion_type is not None and cloud.part_id is not None
            motion = np.array(truth["motion_type_ids"])
            assert np.array_equal(cloud.motion_type, motion[cloud.part_id])
