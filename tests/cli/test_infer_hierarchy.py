"""`artic segment`, `build-hierarchy` and `infer-hierarchy` through the CLI runner:
output contracts, determinism, and every bad-input path (exit 2, one line)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from artic.artifacts.manifest import read_manifest
from artic.artifacts.ply import read_ply, write_ply
from artic.hierarchy.gnn import GraphLabellingNet, GraphNetConfig
from artic.hierarchy.graph import PartGraphConfig
from artic.hierarchy.models import save_labeller, save_segmenter
from artic.hierarchy.pointnet2 import farthest_point_indices
from artic.hierarchy.segmentation import (
    InferenceConfig,
    PartSegmentationNet,
    SegmentationBatch,
    SegmentationConfig,
    make_optimizer,
    train_step,
)
from artic.objects.tree import KinematicTree
from box_clouds import box_cloud
from cli_runner import run_cli

CATEGORY = "storage_furniture"


def tiny_labeller() -> GraphLabellingNet:
    torch.manual_seed(1)
    cfg = GraphNetConfig(encoder_widths=(8, 16), decoder_points=16, hidden=8, head_hidden=8)
    return GraphLabellingNet(cfg)


def tiny_segmenter(steps: int = 50) -> PartSegmentationNet:
    """A 1/8-width segmenter trained a few steps on box_cloud (so it finds several parts)."""
    torch.manual_seed(0)
    model = PartSegmentationNet(SegmentationConfig().scaled(0.125))
    points, part = box_cloud(2000, seed=1)
    idx = farthest_point_indices(points, 512)
    motion = np.minimum(part, 1)
    batch = SegmentationBatch(
        torch.from_numpy(points[idx])[None],
        torch.from_numpy(part[idx])[None],
        torch.from_numpy(motion[idx])[None],
    )
    optimizer = make_optimizer(model, 1e-2)
    for _ in range(steps):
        train_step(model, optimizer, batch)
    # batch-norm statistics of the final weights (a few steps leave the running ones stale)
    for module in model.modules():
        if isinstance(module, torch.nn.BatchNorm1d):
            module.momentum = 1.0
    with torch.no_grad():
        model.train()(batch.points)
    return model.eval()


def save_models(folder: Path) -> tuple[Path, Path]:
    """seg.pt and lab.pt (kinds part-segmenter and hierarchy-gnn) in `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)
    seg, lab = folder / "seg.pt", folder / "lab.pt"
    inference = InferenceConfig(n_points=512, min_confidence=0.0)  # confidences barely trained
    save_segmenter(seg, CATEGORY, tiny_segmenter(), inference, {})
    save_labeller(lab, CATEGORY, tiny_labeller(), PartGraphConfig(), {})
    return seg, lab


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return save_models(tmp_path_factory.mktemp("models"))


@pytest.fixture(scope="module")
def scan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3,000-point labelled scan (more points than the segmenter's 512)."""
    path = tmp_path_factory.mktemp("scan") / "cabinet.ply"
    points, part = box_cloud(3000)
    write_ply(path, points, part_id=part)
    return path


def infer(scan: Path, models: tuple[Path, Path], out: Path, *extra: str) -> tuple[int, str, str]:
    seg, lab = models
    args = ["infer-hierarchy", str(scan), "--out", str(out)]
    return run_cli(*args, "--segmenter", str(seg), "--labeller", str(lab), *extra)


def without_timings(path: Path) -> dict[str, object]:
    doc = json.loads(path.read_text())
    doc.pop("timings_s")
    return doc


def load_urdf_joints(urdf: Path) -> int:
    import pybullet as p

    client = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(urdf), physicsClientId=client)
        return int(p.getNumJoints(body, physicsClientId=client))
    finally:
        p.disconnect(client)


def test_infer_hierarchy_writes_the_contracted_outputs(scan, models, tmp_path):
    out = tmp_path / "out"
    code, stdout, err = infer(scan, models, out)
    assert code == 0, err
    assert str(out) in stdout and "parts" in stdout
    points = read_ply(scan).points
    doc = json.loads((out / "hierarchy.json").read_text())
    tree = KinematicTree.from_json((out / "hierarchy.json").read_text())
    labels = np.asarray(doc["point_part_id"])
    assert labels.shape == (len(points),)  # one label per input point
    assert set(np.unique(labels)) == set(range(tree.num_parts))
    assert tree.num_parts >= 2 and len(doc["parts"]) == tree.num_parts
    assert len(doc["joints"]) == len(tree.edges)
    for joint, joint_type in zip(doc["joints"], tree.joint_types, strict=True):
        assert joint["type"] == joint_type
        assert (joint["axis"] is None) == (joint_type == "fixed")
    assert abs(sum(p["root_probability"] for p in doc["parts"]) - 1.0) < 1e-4
    ply = read_ply(out / "parts.ply")
    assert np.array_equal(ply.points, points)  # input order, metres
    assert np.array_equal(ply.part_id, labels)
    assert np.array_equal(ply.motion_type, np.asarray(tree.motion_types)[labels])
    assert (out / "hierarchy.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert load_urdf_joints(out / "object.urdf") == tree.num_parts - 1
    manifest = read_manifest(out, expected_stage="infer-hierarchy")
    assert {"hierarchy.json", "object.urdf", "parts.ply", "hierarchy.png"} <= set(manifest.outputs)
    assert set(manifest.inputs) == {"scan", "segmenter", "labeller"}
    assert not out.with_name("out.partial").exists()


def test_infer_hierarchy_is_deterministic_and_replaces_its_own_output(scan, models, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert infer(scan, models, a)[0] == 0
    assert infer(scan, models, b)[0] == 0
    assert without_timings(a / "hierarchy.json") == without_timings(b / "hierarchy.json")
    for name in ("parts.ply", "object.urdf"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    code, _, err = infer(scan, models, a)  # an earlier infer-hierarchy output: replaced
    assert code == 0 and "replacing" in err


def test_segment_then_build_hierarchy_default_folders(scan, models, tmp_path):
    seg, lab = models
    local = tmp_path / "cabinet.ply"
    local.write_bytes(scan.read_bytes())
    code, _, err = run_cli("segment", str(local), "--model", str(seg))
    assert code == 0, err
    segmented = tmp_path / "cabinet_segmented"
    ply = read_ply(segmented / "parts.ply")
    info = json.loads((segmented / "segmentation.json").read_text())
    assert ply.part_id is not None and ply.confidence is not None
    assert ply.part_id.shape == (3000,) and info["num_parts"] == int(ply.part_id.max()) + 1
    assert read_manifest(segmented).stage == "segment"
    code, _, err = run_cli("build-hierarchy", str(segmented / "parts.ply"), "--model", str(lab))
    assert code == 0, err
    built = tmp_path / "cabinet_hierarchy"  # beside the segment folder
    tree = KinematicTree.from_json((built / "hierarchy.json").read_text())
    assert tree.num_parts == info["num_parts"]
    assert load_urdf_joints(built / "object.urdf") == tree.num_parts - 1


def test_build_hierarchy_renumbers_part_ids_and_keeps_input_order(models, tmp_path):
    points, part = box_cloud(1500, seed=3)
    ids = np.array([4, 9, 2])[part]  # non-contiguous ids
    path = tmp_path / "parts.ply"
    write_ply(path, points, part_id=ids)
    code, _, err = run_cli("build-hierarchy", str(path), "--model", str(models[1]))
    assert code == 0, err
    doc = json.loads((tmp_path / "parts_hierarchy" / "hierarchy.json").read_text())
    assert [p["input_part_id"] for p in doc["parts"]] == [2, 4, 9]
    mapped = np.array([p["input_part_id"] for p in doc["parts"]])[doc["point_part_id"]]
    assert np.array_equal(mapped, ids)


def test_large_cloud_is_subsampled_and_every_point_labelled(models, tmp_path):
    points, part = box_cloud(4000, seed=5)
    path = tmp_path / "big.ply"
    write_ply(path, points, part_id=part)
    code, _, err = infer(path, models, tmp_path / "out", "--max-points", "1000")
    assert code == 0, err
    assert "4000 points; working on a random subset of 1000" in err
    doc = json.loads((tmp_path / "out" / "hierarchy.json").read_text())
    assert len(doc["point_part_id"]) == 4000 and doc["input"]["worked_on_points"] == 1000


def test_scale_auto_rescales_millimetres(scan, models, tmp_path):
    cloud = read_ply(scan)
    path = tmp_path / "mm.ply"
    write_ply(path, cloud.points * 1000.0)
    code, _, err = infer(path, models, tmp_path / "out", "--scale", "auto")
    assert code == 0, err
    assert "millimetres" in err and "divided by 1000" in err
    ply = read_ply(tmp_path / "out" / "parts.ply")
    assert np.allclose(ply.points, cloud.points, atol=1e-6)  # written in metres


def _bad_files(tmp: Path) -> dict[str, tuple[Path, str]]:
    """name -> (file, expected fragment of the one-line message)."""
    points, _ = box_cloud(3000)
    cases: dict[str, tuple[Path, str]] = {}
    empty = tmp / "empty.ply"
    empty.write_bytes(b"")
    cases["empty"] = (empty, "empty file")
    text = tmp / "notes.ply"
    text.write_text("hello\n")
    cases["not a ply"] = (text, "not a PLY file")
    no_vertices = tmp / "none.ply"
    write_ply(no_vertices, np.zeros((0, 3), np.float32))
    cases["no vertices"] = (no_vertices, "no vertices")
    nan = tmp / "nan.ply"
    bad = points.copy()
    bad[10] = np.nan
    write_ply(nan, bad)
    cases["nan"] = (nan, "NaN or infinite")
    inf = tmp / "inf.ply"
    bad = points.copy()
    bad[3, 1] = np.inf
    write_ply(inf, bad)
    cases["inf"] = (inf, "NaN or infinite")
    few = tmp / "few.ply"
    write_ply(few, points[:100])
    cases["too few points"] = (few, "100 points; the segmenter needs at least 512")
    mm = tmp / "mm.ply"
    write_ply(mm, points * 1000.0)
    cases["millimetres"] = (mm, "units look like millimetres")
    point = tmp / "point.ply"
    write_ply(point, np.zeros((600, 3), np.float32))
    cases["all points coincide"] = (point, "all points lie within")
    cases["missing"] = (tmp / "absent.ply", "no such file")
    return cases


def test_bad_scans_exit_2_with_one_line_and_no_output(models, tmp_path):
    for name, (path, fragment) in _bad_files(tmp_path).items():
        for command in ("infer-hierarchy", "segment"):
            out = tmp_path / f"out-{command}"
            if command == "segment":
                code, _, err = run_cli(
                    command, str(path), "--model", str(models[0]), "--out", str(out)
                )
            else:
                code, _, err = infer(path, models, out)
            lines = err.strip().splitlines()
            assert code == 2, (name, command, err)
            assert len(lines) == 1 and lines[0].startswith("error: "), (name, err)
            assert fragment in lines[0], (name, lines[0])
            assert "Traceback" not in err
            assert not out.exists() and not out.with_name(out.name + ".partial").exists()


def test_bad_options_and_models_exit_2(scan, models, tmp_path):
    lab = models[1]
    cases = [
        (["--scale", "-3"], "--scale: expected 'auto' or a positive number"),
        (["--scale", "mm"], "--scale"),
        (["--max-points", "0"], "--max-points"),
    ]
    for extra, fragment in cases:
        code, _, err = infer(scan, models, tmp_path / "o", *extra)
        assert code == 2 and fragment in err, err
    code, _, err = infer(scan, (lab, lab), tmp_path / "o")  # a labeller as segmenter
    assert code == 2 and "not a part-segmenter model" in err, err
    code, _, err = infer(scan, models, tmp_path / "o", "--category", "lamp")
    assert code == 2 and "not lamp" in err, err
    code, _, err = run_cli("segment", str(scan), "--category", "lamp", "--out", str(tmp_path / "o"))
    assert code == 2 and "artic pipeline ch4" in err and "--model PATH" in err, err
    # two models of two categories, no --category: refused, whichever is given
    lamp_lab = tmp_path / "lamp_lab.pt"
    save_labeller(lamp_lab, "lamp", tiny_labeller(), PartGraphConfig(), {})
    code, _, err = infer(scan, (models[0], lamp_lab), tmp_path / "o")
    assert code == 2 and "a model of category lamp, not storage_furniture" in err, err
    assert not (tmp_path / "o").exists()
    stranger = tmp_path / "mine"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("keep me")
    code, _, err = infer(scan, models, stranger)
    assert code == 2 and "not an artic output folder" in err, err
    assert (stranger / "notes.txt").read_text() == "keep me"


def test_build_hierarchy_bad_part_ids_exit_2(models, tmp_path):
    points, part = box_cloud(800)
    unlabelled = tmp_path / "plain.ply"
    write_ply(unlabelled, points)
    negative = tmp_path / "negative.ply"
    write_ply(negative, points, part_id=part - 1)
    for path, fragment in [(unlabelled, "no part_id"), (negative, "part_id must be >= 0")]:
        code, _, err = run_cli(
            "build-hierarchy", str(path), "--model", str(models[1]), "--out", str(tmp_path / "o")
        )
        assert code == 2 and fragment in err and len(err.strip().splitlines()) == 1, err
