"""generate-dataset and render-depth end to end through the CLI, on the tiny preset."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from artic.artifacts import workers
from artic.artifacts.depth_dataset import DepthDataset
from artic.artifacts.manifest import read_manifest
from artic.artifacts.object_dataset import ObjectDataset
from cli_runner import run_cli


def tree_bytes(folder: Path) -> dict[str, bytes]:
    """Every data file of an output folder (not the manifest or log, which hold times)."""
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name not in ("manifest.json", "artic.log")
    }


def test_generate_dataset_writes_objects_index_and_manifest(tiny_objects):
    ds = ObjectDataset.open(tiny_objects)
    assert [r.object_id for r in ds.rows] == list(range(6))
    assert [r.split for r in ds.rows] == ["train", "train", "test"] * 2
    manifest = read_manifest(tiny_objects)
    assert manifest.stage == "generate-dataset" and manifest.status == "complete"
    assert manifest.config["category"]["name"] == "microwave"
    assert manifest.seed == 0 and manifest.wall_time_s >= 0
    assert {"numpy", "open3d", "pybullet", "python"} <= set(manifest.versions)
    for object_id in range(6):
        assert ds.spec(object_id).category == "microwave"
        assert ds.urdf(object_id).is_file()
    assert all(len(rec.sha256) == 64 for rec in manifest.outputs.values())


def test_render_depth_writes_shards_labels_and_preview(tiny_depth):
    ds = DepthDataset.open(tiny_depth)
    shards = list(ds.shards())
    assert len(shards) == 3  # 6 objects, 2 per shard
    images = sum(s.depth.shape[0] for s in shards)
    assert images == 6 * 4 == ds.info.images
    s = shards[0]
    assert s.depth.shape == (8, 128, 128) and s.depth.dtype == np.float32
    assert s.part_mask.shape == (8, 128, 128) and s.part_mask.max() >= 2
    assert s.labels.shape == (8, len(ds.label_columns))
    assert np.isfinite(s.labels).all()
    # the object is seen: valid depth on the object's pixels, within the sampled range
    assert ((s.depth > 0) & (s.part_mask > 0)).sum(axis=(1, 2)).min() > 50
    assert s.depth[s.depth > 0].max() < 6.0
    labels = (tiny_depth / "labels.csv").read_text().splitlines()
    assert len(labels) == 1 + images
    assert labels[0].startswith("shard,row,object_id,split,image_index,")
    assert (tiny_depth / "preview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    info = json.loads((tiny_depth / "dataset.json").read_text())
    assert info["category"] == "microwave" and info["dof"] == 1


def test_configurations_cover_the_joint_range(tiny_depth):
    ds = DepthDataset.open(tiny_depth)
    q = np.concatenate([s.labels[:, ds.label_columns.index("j0_q")] for s in ds.shards()])
    assert q.min() >= 0.0 and q.max() <= np.pi / 2
    # Latin hypercube: each object's 4 images fall in 4 different quarters of the range
    per_object = q.reshape(-1, 4)
    bins = np.floor(per_object / (np.pi / 2) * 4).clip(0, 3)
    assert all(len(set(b)) == 4 for b in bins)


def test_up_to_date_stage_is_skipped_and_force_redoes_it(tiny_objects, tmp_path):
    code, out, _ = run_cli(
        "generate-dataset", "debug=tiny", "category=microwave", f"out={tiny_objects}"
    )
    assert code == 0 and "up to date" in " ".join(out.split())  # the line may wrap


def test_an_input_moved_elsewhere_is_the_same_input(tiny_objects, tiny_depth, tmp_path):
    # the same dataset under another path: the rendered images are up to date
    moved = tmp_path / "moved"
    shutil.copytree(tiny_objects, moved)
    args = ["render-depth", "debug=tiny", f"out={tiny_depth}"]
    code, out, err = run_cli(*args, f"dataset={moved}")
    assert code == 0 and "up to date" in " ".join(out.split()), err
    # another dataset (other content) is not: the images are made again
    other = tmp_path / "other"
    gen = ["generate-dataset", "debug=tiny", "category=microwave", "seed=1"]
    assert run_cli(*gen, f"out={other}")[0] == 0
    depth = tmp_path / "depth"
    shutil.copytree(tiny_depth, depth)
    code, out, _ = run_cli("render-depth", "debug=tiny", f"out={depth}", f"dataset={other}")
    assert code == 0 and "up to date" not in " ".join(out.split())
    assert tree_bytes(depth) != tree_bytes(tiny_depth)


def test_same_seed_same_bytes_and_shards_merge_to_one_run(tmp_path, tiny_objects, tiny_depth):
    a = tmp_path / "a"
    args = ["generate-dataset", "debug=tiny", "category=microwave"]
    assert run_cli(*args, f"out={a}")[0] == 0
    assert tree_bytes(a) == tree_bytes(tiny_objects)
    # three shard jobs into one folder: the last one finishes it
    b = tmp_path / "b"
    results = [run_cli(*args, f"out={b}", f"shard.index={i}", "shard.count=3") for i in (2, 0, 1)]
    assert [r[0] for r in results] == [0, 0, 0]
    assert "chunks done" in results[0][1]
    assert tree_bytes(b) == tree_bytes(tiny_objects)
    # render-depth sharded with 2 workers gives the same bytes as the inline run
    d = tmp_path / "d"
    code, _, err = run_cli(
        "render-depth", "debug=tiny", f"dataset={tiny_objects}", f"out={d}", "runtime.workers=2"
    )
    assert code == 0, err
    assert tree_bytes(d) == tree_bytes(tiny_depth)


def test_render_depth_uses_the_datasets_camera_unless_one_is_named(tmp_path, tiny_depth):
    # the tiny dataset was sampled for the default kinect_v1_128 (128x128): render-depth
    # without camera= renders with it, byte for byte as when it is named
    assert json.loads((tiny_depth / "dataset.json").read_text())["camera"]["width"] == 128
    objects = tmp_path / "objects"
    gen = ["generate-dataset", "debug=tiny", "category=drawer", "camera=thesis_sim"]
    assert run_cli(*gen, "dataset.objects=2", f"out={objects}")[0] == 0
    outs = {}
    for name, extra in (("default", []), ("named", ["camera=thesis_sim"])):
        outs[name] = tmp_path / name
        code, _, err = run_cli(
            "render-depth", "debug=tiny", f"dataset={objects}", f"out={outs[name]}", *extra
        )
        assert code == 0, err
    ds = DepthDataset.open(outs["default"])
    assert (ds.info.camera.width, ds.info.camera.height) == (192, 108)
    assert next(iter(ds.shards())).depth.shape[1:] == (108, 192)
    assert tree_bytes(outs["default"]) == tree_bytes(outs["named"])
    # another camera, named, is honoured
    other = tmp_path / "other"
    args = ["render-depth", "debug=tiny", f"dataset={objects}", f"out={other}"]
    assert run_cli(*args, "camera=kinect_v1_128")[0] == 0
    assert DepthDataset.open(other).info.camera.width == 128


def test_other_seed_gives_other_objects(tmp_path, tiny_objects):
    out = tmp_path / "s1"
    assert (
        run_cli("generate-dataset", "debug=tiny", "category=microwave", "seed=1", f"out={out}")[0]
        == 0
    )
    assert (
        tree_bytes(out)["objects/000000/spec.json"]
        != tree_bytes(tiny_objects)["objects/000000/spec.json"]
    )


def test_interrupted_run_resumes_without_redoing_finished_chunks(
    tmp_path, tiny_objects, tiny_depth, monkeypatch
):
    out = tmp_path / "depth"
    args = ["render-depth", "debug=tiny", f"dataset={tiny_objects}", f"out={out}"]
    calls: list[int] = []
    armed = [True]
    original = workers._run_chunk

    def interrupt_second(fn, cfg, inputs, chunk, out_dir):
        calls.append(chunk)
        if armed[0] and len(calls) == 2:
            raise KeyboardInterrupt
        return original(fn, cfg, inputs, chunk, out_dir)

    monkeypatch.setattr(workers, "_run_chunk", interrupt_second)
    code, _, err = run_cli(*args)
    assert code == 130 and "resume" in err
    assert not out.exists() and out.with_name("depth.partial").is_dir()
    calls.clear()
    armed[0] = False
    code, _, err = run_cli(*args)
    assert code == 0, err
    assert calls == [1, 2], "chunk 0 was finished before the interruption and is not redone"
    assert tree_bytes(out) == tree_bytes(tiny_depth)


def test_corrupted_output_is_reported_by_name(tmp_path, tiny_objects):
    out = tmp_path / "objs"
    args = ["generate-dataset", "debug=tiny", "category=microwave", f"out={out}"]
    assert run_cli(*args)[0] == 0
    spec = out / "objects/000001/spec.json"
    spec.write_text(spec.read_text().replace("microwave", "microwavX"))
    code, _, err = run_cli(*args)
    assert code == 2
    assert "objects/000001/spec.json: corrupted" in err and len(err.strip().splitlines()) == 1
    # a downstream stage reading the corrupted file says the same
    code, _, err = run_cli("render-depth", "debug=tiny", f"dataset={out}", f"out={tmp_path / 'd'}")
    assert code == 2 and "000001/spec.json: corrupted" in err
    assert run_cli(*args, "--force")[0] == 0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["generate-dataset", "category=sofa"], "category"),
        (["generate-dataset", "dataset.objects=-5"], "dataset.objects"),
        (["generate-dataset", "category.geometry.depth=[0.6,0.5]"], "category.geometry.depth"),
        (["generate-dataset", "shard.index=3", "shard.count=2"], "shard"),
        (["generate-dataset", "no_such_key=1"], "no_such_key"),
        (["render-depth"], "dataset"),
        (["render-depth", "dataset=/nonexistent/objects"], "dataset: /nonexistent/objects"),
        (["render-depth", "dataset=."], "not a stage output"),
        (["render-depth", "dataset=/tmp", "render.configurations=0"], "render.configurations"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path, args, message):
    code, _, err = run_cli(*args, f"out={tmp_path / 'o'}")
    assert code == 2, err
    assert message in err
    assert len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "o").exists()


def test_unwritable_output_folder(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    code, _, err = run_cli("generate-dataset", "debug=tiny", f"out={blocker / 'x'}")
    assert code == 2 and "out: cannot write" in err


def test_cfg_prints_resolved_config(tmp_path):
    code, out, _ = run_cli("generate-dataset", "--cfg", "category=drawer")
    assert code == 0
    assert "name: drawer" in out and "out: artifacts/objects/drawer" in out
    code, out, _ = run_cli("render-depth", "--cfg", "dataset=artifacts/objects/drawer")
    assert code == 0 and "out: artifacts/depth/drawer" in out


def test_clean_depth_and_float16_encoding(tmp_path, tiny_objects):
    out = tmp_path / "d"
    code, _, err = run_cli(
        "render-depth", "debug=tiny", f"dataset={tiny_objects}", f"out={out}",
        "render.store_clean_depth=true", "render.depth_encoding=float16_m",
    )  # fmt: skip
    assert code == 0, err
    shard = np.load(out / "shards/shard-00000.npz")
    depth, clean, mask = shard["depth"], shard["depth_clean"], shard["part_mask"]
    assert depth.dtype == clean.dtype == np.float16
    np.testing.assert_array_equal(clean > 0, mask > 0)  # masks come from the clean render
    assert not np.array_equal(depth, clean), "the stored depth is the noisy one"
    assert 0.5 < float(clean[clean > 0].mean()) < 6.0
