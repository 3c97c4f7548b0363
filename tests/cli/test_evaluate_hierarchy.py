"""`artic evaluate hierarchy` (Tables 4.1 and 4.2) on the tiny scans, with small untrained
networks in hand-made train-segmenter / train-hierarchy output folders."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import torch

from artic.artifacts.scan_outputs import OutputFolder
from artic.cli.registry import stage_entries
from artic.hierarchy.gnn import GraphLabellingNet, GraphNetConfig
from artic.hierarchy.graph import PartGraphConfig
from artic.hierarchy.models import save_labeller, save_segmenter
from artic.hierarchy.segmentation import InferenceConfig, PartSegmentationNet, SegmentationConfig
from cli_runner import run_cli
from tiny_scans import TinyScans, tiny_hierarchy_scans

CATEGORY = "storage_furniture"


def _publish(out: Path, stage: str, write: object) -> Path:
    folder = OutputFolder(out, stage, {"test": True}, {})
    write(folder.path / "model.pt")  # type: ignore[operator]
    folder.publish(0, {})
    return out


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> tuple[TinyScans, Path, Path]:
    torch.set_num_threads(1)
    torch.manual_seed(0)
    tiny = tiny_hierarchy_scans(tmp_path_factory, CATEGORY)
    root = tmp_path_factory.mktemp("trained")
    seg_net = PartSegmentationNet(SegmentationConfig().scaled(0.125))
    infer = InferenceConfig(n_points=256)
    lab_net = GraphLabellingNet(
        GraphNetConfig(encoder_widths=(8, 16), decoder_points=16, hidden=8, head_hidden=8)
    )
    graph = PartGraphConfig()
    seg = _publish(
        root / "seg", "train-segmenter", lambda p: save_segmenter(p, CATEGORY, seg_net, infer, {})
    )
    lab = _publish(
        root / "lab", "train-hierarchy", lambda p: save_labeller(p, CATEGORY, lab_net, graph, {})
    )
    return tiny, seg, lab


def evaluate(setup: tuple[TinyScans, Path, Path], out: Path, *extra: str) -> tuple[int, str, str]:
    tiny, seg, lab = setup
    return run_cli(
        "evaluate",
        "hierarchy",
        "debug=tiny",
        f"scans={tiny.scans}",
        f"segmenter={seg}",
        f"labeller={lab}",
        f"out={out}",
        *extra,
    )


@pytest.fixture(scope="module")
def report(setup, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("report") / CATEGORY
    code, _, err = evaluate(setup, out)
    assert code == 0, err
    return out


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


def test_tables_4_1_and_4_2_are_written(report):
    assert stage_entries()["evaluate-hierarchy"].module == "artic.cli.evaluate_hierarchy"
    summary = _rows(report / "summary.csv")
    assert [(r["kind"], r["segmentation"]) for r in summary] == [
        ("clean", "gt"),
        ("clean", "pred"),
        ("noisy", "gt"),
        ("noisy", "pred"),
    ]
    for r in summary:
        assert 0.0 <= float(r["map"]) <= 1.0 and 0.0 <= float(r["motion_accuracy"]) <= 1.0
        for key in ("e_type", "e_exist", "e_dir", "e_root", "tree_f1"):
            assert 0.0 <= float(r[key]) <= 100.0
    per = _rows(report / "per_object.csv")
    # 2 test objects x 2 poses (debug=tiny) x clean/noisy x gt/pred segmentation
    assert len(per) == 2 * 2 * 2 * 2
    assert {r["object_id"] for r in per} == {"2", "5"}
    for r in per:
        if r["segmentation"] == "gt":  # ground-truth parts: every visible true part is a node
            assert r["nodes"] == r["true_parts"] == r["n_ground_truth"]
        assert int(r["pred_parts"]) >= 1
    text = (report / "report.md").read_text()
    assert "Table 4.1" in text and "Table 4.2" in text
    assert "0.907" in text and "99.02" in text  # the thesis' storage-furniture figures
    manifest = (report / "manifest.json").read_text()
    assert '"stage": "evaluate-hierarchy"' in manifest


def test_shards_merge_into_the_same_files(setup, report, tmp_path):
    """Shards, worker processes and torch threads never change the bytes (the report was
    made by one process with one thread)."""
    out = tmp_path / "sharded"
    assert evaluate(setup, out, "shard.count=2", "shard.index=1", "runtime.threads=2")[0] == 0
    assert not out.exists()
    assert evaluate(setup, out, "shard.count=2", "shard.index=0")[0] == 0
    parallel = tmp_path / "two_workers"
    assert evaluate(setup, parallel, "runtime.workers=2", "runtime.threads=2")[0] == 0
    for name in ("summary.csv", "per_object.csv", "report.md"):
        assert (out / name).read_bytes() == (report / name).read_bytes()
        assert (parallel / name).read_bytes() == (report / name).read_bytes()


def test_bad_inputs_exit_2(setup, tmp_path):
    tiny, _, lab = setup
    code, _, err = run_cli(
        "evaluate",
        "hierarchy",
        f"scans={tiny.scans}",
        f"segmenter={lab}",
        f"labeller={lab}",
        f"out={tmp_path / 'x'}",
    )
    assert code == 2 and "expected a 'train-segmenter' output" in err, err
    code, _, err = evaluate(setup, tmp_path / "x", "evaluate.iou_threshold=0")
    assert code == 2 and "evaluate.iou_threshold" in err, err
    code, _, err = evaluate(setup, tmp_path / "x", "category=lamp")
    assert code == 2 and "not lamp" in err, err
    assert not (tmp_path / "x").exists()


def test_turned_scans_are_scored_after_the_yaw_estimate(setup, tmp_path):
    """`evaluate.yaw=random`: every scan turned by a seeded random yaw and turned back by
    the estimated one; the manifest reports how well the yaw was recovered."""
    out = tmp_path / "yaw"
    code, _, err = evaluate(setup, out, "evaluate.yaw=random")
    assert code == 0, err
    stats = json.loads((out / "manifest.json").read_text())["stats"]
    assert 0.0 <= stats["yaw within 5 deg"] <= 1.0 and stats["yaw error median (deg)"] >= 0.0
    summary = _rows(out / "summary.csv")
    assert len(summary) == 4 and all(0.0 <= float(r["tree_f1"]) <= 100.0 for r in summary)
    again = tmp_path / "again"
    assert evaluate(setup, again, "evaluate.yaw=random")[0] == 0
    assert (again / "per_object.csv").read_bytes() == (out / "per_object.csv").read_bytes()
