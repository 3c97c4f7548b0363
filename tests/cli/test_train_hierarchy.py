"""`artic train-hierarchy` end to end on tiny scans made by the real stages."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from artic.artifacts.scan_dataset import ScanDataset
from artic.hierarchy import fit_labeller
from artic.hierarchy.fit_labeller import make_example
from artic.hierarchy.gnn import predict
from artic.hierarchy.models import load_labeller
from artic.hierarchy.tree import extract_tree
from cli_runner import run_cli
from tiny_scans import TinyScans, tiny_hierarchy_scans

ARGS = ("train-hierarchy", "debug=tiny", "category=storage_furniture")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> TinyScans:
    return tiny_hierarchy_scans(tmp_path_factory)


@pytest.fixture(scope="module")
def trained(tiny: TinyScans, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("hierarchy") / "storage_furniture"
    code, _, err = run_cli(*ARGS, f"scans={tiny.scans}", f"out={out}")
    assert code == 0, err
    return out


def _same(a: Path, b: Path) -> bool:
    x = load_labeller(a / "model.pt", compiled=False).model.state_dict()
    y = load_labeller(b / "model.pt", compiled=False).model.state_dict()
    return x.keys() == y.keys() and all(torch.equal(x[k], y[k]) for k in x)


def test_writes_model_metrics_and_card(trained: Path, tiny: TinyScans) -> None:
    for name in ("model.pt", "metrics.csv", "pretrain.csv", "model.json", "model_card.md"):
        assert (trained / name).is_file(), name
    rows = (trained / "metrics.csv").read_text().splitlines()
    assert rows[0].startswith("epoch,train_loss,") and len(rows) == 3
    assert len((trained / "pretrain.csv").read_text().splitlines()) == 3
    loaded = load_labeller(trained / "model.pt", "storage_furniture")
    assert loaded.graph.points_per_node == 16 and loaded.graph.contact_threshold == 0.05
    used = set(loaded.meta["train_objects"]) | set(loaded.meta["val_objects"])
    assert used == {0, 1, 3, 4}, "the test split (2, 5) is never used"
    info = json.loads((trained / "model.json").read_text())
    assert info["train_graphs"] + info["skipped_clouds"] <= 8 and info["val_graphs"] > 0
    scores = info["val_metrics_gt_segmentation"]
    assert 0.0 <= scores["tree_f1"] <= 100.0 and scores["models"] == info["val_graphs"]
    assert "Tree F1" in (trained / "model_card.md").read_text()
    # the saved network labels a test object's graph built with the saved graph settings
    ds = ScanDataset.open(tiny.scans)
    row = ds.select("test", ("clean",))[0]
    cloud = ds.cloud(row)
    assert cloud.part_id is not None
    rng = np.random.default_rng(0)
    example = make_example(cloud.points, cloud.part_id, ds.tree(row.object_id), rng, loaded.graph)
    assert example is not None
    tree = extract_tree(predict(loaded.model, example.graph), example.graph.centroids)
    assert tree.num_parts == example.tree.num_parts


def test_same_seed_same_weights(trained: Path, tiny: TinyScans, tmp_path: Path) -> None:
    code, _, err = run_cli(*ARGS, f"scans={tiny.scans}", f"out={tmp_path / 'again'}")
    assert code == 0, err
    assert _same(trained, tmp_path / "again")


@pytest.mark.parametrize("phase", ["pretrain", "train"])
def test_interrupted_training_resumes_to_the_same_weights(
    phase: str, trained: Path, tiny: TinyScans, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    name = "pretrain_step" if phase == "pretrain" else "train_step"
    original = getattr(fit_labeller, name)
    calls: list[int] = []

    def interrupt(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        if len(calls) == 3:  # in the second epoch (tiny: 1 pretrain / 2 train steps per epoch)
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(fit_labeller, name, interrupt)
    out = tmp_path / "resumed"
    code, _, err = run_cli(*ARGS, f"scans={tiny.scans}", f"out={out}")
    assert code == 130 and "resume" in err and not out.exists()
    monkeypatch.setattr(fit_labeller, name, original)
    code, _, err = run_cli(*ARGS, f"scans={tiny.scans}", f"out={out}")
    assert code == 0, err
    assert _same(trained, out), "resumed = uninterrupted"
    assert (out / "metrics.csv").read_text().splitlines()[0] == (
        trained / "metrics.csv"
    ).read_text().splitlines()[0]


def _assert_identical(a: Any, b: Any) -> None:
    """Equal values of the same types; arrays of the same dtype and bytes."""
    assert type(a) is type(b), (type(a), type(b))
    if isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    elif dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            _assert_identical(getattr(a, f.name), getattr(b, f.name))
    elif isinstance(a, tuple | list):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _assert_identical(x, y)
    else:
        assert a == b or (a != a and b != b), (a, b)


def test_prepared_graph_cache_is_safe_and_exact(tmp_path: Path) -> None:
    """The resume folder's prepared graphs: tensors and plain data (weights_only), read
    back as the same objects (dtypes, numpy scalars); a corrupt cache exits 2 by name."""
    from artic.artifacts.model_file import load_torch_file, save_torch_file
    from artic.errors import InputError
    from artic.hierarchy.fit_labeller import decode as _decode
    from artic.hierarchy.fit_labeller import encode as _encode
    from artic.hierarchy.graph import PartGraphConfig
    from artic.objects.tree import KinematicTree
    from box_clouds import box_cloud

    tree = KinematicTree(3, 0, ((0, 1), (0, 2)), (0, 1, 2), ("revolute", "prismatic"))
    points, part = box_cloud(900)
    graph_cfg = PartGraphConfig(points_per_node=16)
    example = make_example(points, part, tree, np.random.default_rng(0), graph_cfg)
    assert example is not None
    cache = tmp_path / "train.pt"
    save_torch_file(cache, {"examples": [[_encode(v) for v in example]], "skipped": 2})
    stored = load_torch_file(cache, "checkpoint")
    back = type(example)(*(_decode(v) for v in stored["examples"][0]))
    _assert_identical(back, example)
    cache.write_bytes(cache.read_bytes()[:100])
    with pytest.raises(InputError, match=f"{cache}: not a readable checkpoint"):
        load_torch_file(cache, "checkpoint")


def test_bad_inputs_exit_2(tiny: TinyScans, tmp_path: Path) -> None:
    depth_like = tmp_path / "depth"
    shutil.copytree(tiny.scans, depth_like)
    manifest = json.loads((depth_like / "manifest.json").read_text())
    (depth_like / "manifest.json").write_text(json.dumps(manifest | {"stage": "render-depth"}))
    cases = [
        ((f"scans={depth_like}",), "expected a 'render-scan' output"),
        ((f"scans={tmp_path / 'missing'}",), "no such folder"),
        ((f"scans={tiny.scans}", "category=office_chair"), "not office_chair"),
        ((f"scans={tiny.scans}", "category=no_such_category"), "no_such_category"),
        ((f"scans={tiny.scans}", "graph.contact_threshold=0"), "graph.contact_threshold"),
    ]
    for extra, message in cases:
        code, _, err = run_cli(*ARGS, *extra, f"out={tmp_path / 'x'}")
        assert code == 2, (extra, err)
        assert message in err, (extra, err)
        assert len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("pipeline", ["ch4", "ch4_paper"])
def test_chapter_4_pipelines_compose(pipeline: str) -> None:
    """The training stages of stages/ch4*.yaml resolve to valid configs (no run)."""
    from artic.cli.pipeline import load_pipeline
    from artic.cli.registry import load_stage, resolve
    from artic.cli.stage_runner import resolved_config
    from artic.config.compose import validate

    root = Path(__file__).resolve().parents[2]
    spec = load_pipeline(root / "stages" / f"{pipeline}.yaml")
    commands = [s.cmd for s in spec.stages.values()]
    assert commands.count("train-segmenter") == commands.count("train-hierarchy") == 3
    for stage in (s for s in spec.stages.values() if s.cmd.startswith("train-")):
        runner = load_stage(resolve(stage.cmd, list(stage.overrides)).name)
        cfg = validate(runner.schema, resolved_config(runner, list(stage.overrides)))
        assert Path(cfg.out).as_posix() == stage.outs[0]


def test_a_segmenters_parts_add_training_graphs(
    trained: Path, tiny: TinyScans, tmp_path: Path
) -> None:
    """`segmenter=`: every cloud also gives the graph of that segmenter's parts; the
    segmenter is an input of the run (in its manifest)."""
    seg = tmp_path / "segmenter"
    code, _, err = run_cli(
        "train-segmenter", "debug=tiny", "category=storage_furniture", "model.head=votes",
        f"scans={tiny.scans}", f"out={seg}",
    )  # fmt: skip
    assert code == 0, err
    out = tmp_path / "with_predicted"
    code, _, err = run_cli(*ARGS, f"scans={tiny.scans}", f"segmenter={seg}", f"out={out}")
    assert code == 0, err
    base, more = (json.loads((d / "model.json").read_text()) for d in (trained, out))

    def graphs(info: dict[str, int]) -> int:  # made or skipped
        return info["train_graphs"] + info["val_graphs"] + info["skipped_clouds"]

    assert graphs(more) == 2 * graphs(base)
    manifest = json.loads((out / "manifest.json").read_text())
    assert "segmenter" in json.dumps(manifest["inputs"])
    code, _, err = run_cli(
        *ARGS, f"scans={tiny.scans}", f"segmenter={tmp_path}/none", f"out={tmp_path}/x"
    )
    assert code == 2 and "segmenter" in err.strip().splitlines()[-1]
