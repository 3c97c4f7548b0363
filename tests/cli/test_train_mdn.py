"""train-mdn and predict end to end on the tiny dataset."""

from __future__ import annotations

import csv
import io
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from artic.artifacts.depth_dataset import DepthDataset
from artic.artifacts.manifest import read_manifest
from artic.artifacts.model_file import load_model_file, save_model_file
from artic.errors import InputError
from artic.kinematics.config import MDN_KIND as KIND
from cli_runner import run_cli


def test_train_mdn_writes_model_metrics_and_card(tiny_model):
    for name in ("model.pt", "metrics.csv", "model.json", "model_card.md", "manifest.json"):
        assert (tiny_model / name).is_file(), name
    rows = (tiny_model / "metrics.csv").read_text().splitlines()
    assert rows[0] == "epoch,train_nll,val_nll,lr" and len(rows) == 3
    lr = [float(row.split(",")[-1]) for row in rows[1:]]
    assert lr[0] > lr[1] > 0, "cosine schedule (conf/train_mdn: train.schedule)"
    payload = load_model_file(tiny_model / "model.pt", KIND, "microwave")
    assert payload["hparams"]["width"] == 8 and payload["meta"]["dof"] == 1
    assert np.isfinite(payload["meta"]["best_val_nll"])


def _same_weights(a: Path, b: Path) -> bool:
    x = load_model_file(a / "model.pt", KIND)["state_dict"]
    y = load_model_file(b / "model.pt", KIND)["state_dict"]
    return x.keys() == y.keys() and all(torch.equal(x[k], y[k]) for k in x)


def test_train_mdn_is_reproducible(tiny_depth, tiny_model, tmp_path):
    args = ["train-mdn", "debug=tiny", "category=microwave", f"depth={tiny_depth}"]
    code, _, err = run_cli(*args, f"out={tmp_path / 'again'}")
    assert code == 0, err
    assert _same_weights(tiny_model, tmp_path / "again"), "same seed, same weights"


def test_interrupted_training_resumes_from_the_last_epoch(
    tiny_depth, tiny_model, tmp_path, monkeypatch
):
    from artic.kinematics import train

    epochs: list[int] = []
    original = train._train_epoch

    def interrupt_second(*args, **kwargs):
        epochs.append(args[5])
        if len(epochs) == 2:
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(train, "_train_epoch", interrupt_second)
    args = ["train-mdn", "debug=tiny", "category=microwave", f"depth={tiny_depth}"]
    out = tmp_path / "resumed"
    code, _, err = run_cli(*args, f"out={out}")
    assert code == 130 and "resume" in err and not out.exists()
    epochs.clear()
    monkeypatch.setattr(train, "_train_epoch", original)
    code, _, err = run_cli(*args, f"out={out}")
    assert code == 0, err
    assert _same_weights(tiny_model, out), "resumed = uninterrupted"
    assert len((out / "metrics.csv").read_text().splitlines()) == 3


def test_train_mdn_refuses_a_dataset_of_another_category(tiny_depth, tmp_path):
    code, _, err = run_cli(
        "train-mdn", "debug=tiny", "category=drawer", f"depth={tiny_depth}", f"out={tmp_path / 'x'}"
    )
    assert code == 2 and "holds microwave images, not drawer" in err


@pytest.fixture(scope="module")
def image(tiny_depth: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    ds = DepthDataset.open(tiny_depth)
    shard = next(ds.shards(decode=False))
    folder = tmp_path_factory.mktemp("predict")
    png = folder / "depth.png"
    Image.fromarray(shard.depth[0]).save(png)
    np.save(folder / "depth.npy", shard.depth[0].astype(np.float32) / 1000)
    camera = folder / "camera.json"
    camera.write_text(ds.info.camera.model_dump_json())
    return png, folder / "depth.npy", camera


def test_predict_prints_json(tiny_model, image):
    png, npy, camera = image
    for path in (png, npy):
        code, out, err = run_cli(
            "predict", str(path), "--category", "microwave", "--camera", str(camera),
            "--model", str(tiny_model / "model.pt"), "--samples", "5",
        )  # fmt: skip
        assert code == 0, err
        result = json.loads(out)
        (joint,) = result["joints"]
        assert joint["type"] == "revolute" and len(joint["origin"]) == 3
        assert np.linalg.norm(joint["direction"]) == pytest.approx(1.0)
        assert len(result["samples"]) == 5 and len(result["mixture"]["weights"]) == 3
        assert sum(result["mixture"]["weights"]) == pytest.approx(1.0, abs=1e-5)
        assert result["input"]["reprojected_to_training_camera"] is False


def test_predict_reprojects_another_camera_and_max_point(tiny_model, image, tmp_path):
    _, npy, camera = image
    cam = json.loads(camera.read_text())
    depth = np.load(npy)
    big = np.kron(depth, np.ones((2, 2), np.float32))  # the same view at twice the size
    np.save(tmp_path / "big.npy", big)
    cam2 = {k: 2 * cam[k] for k in ("fx", "fy", "width", "height")}
    cam2 |= {"cx": 2 * cam["cx"] + 0.5, "cy": 2 * cam["cy"] + 0.5}
    (tmp_path / "cam2.json").write_text(json.dumps(cam2))
    code, out, err = run_cli(
        "predict", str(tmp_path / "big.npy"), "--category", "microwave", "--camera",
        str(tmp_path / "cam2.json"), "--model", str(tiny_model / "model.pt"),
        "--estimator", "max-point", "--no-refine",
    )  # fmt: skip
    assert code == 0, err
    result = json.loads(out)
    assert result["input"]["reprojected_to_training_camera"] is True
    origin = np.array(result["joints"][0]["origin"])
    assert origin[0] > 0.3, "max-point picks a point of the observed cloud"


def test_predict_estimators_are_the_mixture_points_they_name(tiny_model, image):
    _, npy, camera = image
    base = [  # the network's estimators themselves: without the geometric refinement
        "predict", str(npy), "--category", "microwave", "--camera", str(camera),
        "--model", str(tiny_model / "model.pt"), "--no-refine",
    ]  # fmt: skip
    results = {}
    for estimator in ("most-likely", "densest"):
        code, out, err = run_cli(*base, "--estimator", estimator)
        assert code == 0, err
        results[estimator] = json.loads(out)
    mixture = results["densest"]["mixture"]
    assert mixture == results["most-likely"]["mixture"]
    means = np.array(mixture["means"])  # (m, L) in mixture["columns"] order
    heaviest = means[int(np.argmax(mixture["weights"]))]
    estimate = results["most-likely"]["estimate"]
    assert [estimate[c] for c in mixture["columns"]] == pytest.approx(heaviest.tolist(), abs=1e-5)
    densest = [results["densest"]["estimate"][c] for c in mixture["columns"]]
    assert np.abs(means - np.array(densest)).max(axis=1).min() < 1e-5, "a component mean"
    code, _, err = run_cli(*base, "--estimator", "mode")
    assert code == 2 and "--estimator: 'mode' (available: most-likely, densest, max-point)" in err


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda d: np.save(d / "x.npy", np.zeros((64, 64), np.float32)), "all zeros"),
        (lambda d: np.save(d / "x.npy", np.full((64, 64), np.nan, np.float32)), "NaN"),
        (lambda d: np.save(d / "x.npy", np.ones((64, 64), np.int32)), "float metres"),
        (lambda d: np.save(d / "x.npy", np.ones((32, 64), np.float32)), "intrinsics are for"),
    ],
)
def test_predict_bad_images_exit_2(tiny_model, image, tmp_path, make, message):
    make(tmp_path)
    code, _, err = run_cli(
        "predict", str(tmp_path / "x.npy"), "--category", "microwave", "--camera", str(image[2]),
        "--model", str(tiny_model / "model.pt"),
    )  # fmt: skip
    assert code == 2 and message in err, err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("mask", "message"),
    [
        (lambda depth: np.zeros(depth.shape, np.uint8), "the mask covers no pixel"),
        (lambda depth: np.ones(depth.shape, np.uint8), "the mask covers every pixel"),
        (lambda depth: (depth == 0).astype(np.uint8), "no valid depth pixel of"),
    ],
)
def test_predict_bad_masks_exit_2(tiny_model, image, tmp_path, mask, message):
    """A mask over nothing, over everything, or over the background only: one line naming
    the mask, exit 2 (issue 19, "Bad input")."""
    _, npy, camera = image
    np.save(tmp_path / "mask.npy", mask(np.load(npy)))
    code, _, err = run_cli(
        "predict", str(npy), "--category", "microwave", "--camera", str(camera),
        "--mask", str(tmp_path / "mask.npy"), "--model", str(tiny_model / "model.pt"),
    )  # fmt: skip
    assert code == 2 and message in err and "mask.npy" in err, err
    assert len(err.strip().splitlines()) == 1


def test_predict_refuses_unknown_category_missing_and_foreign_models(tiny_model, image, tmp_path):
    png, _, camera = image
    base = ["predict", str(png), "--camera", str(camera)]
    code, _, err = run_cli(*base, "--category", "sofa")
    assert code == 2 and "unknown category 'sofa'" in err
    code, _, err = run_cli(*base, "--category", "drawer", "--model", str(tmp_path / "none.pt"))
    assert code == 2 and f"--model {tmp_path / 'none.pt'}: no such file" in err
    code, _, err = run_cli(*base, "--category", "drawer")
    assert code == 2 and "no mdn model for drawer" in err and "artic pipeline ch3" in err
    code, _, err = run_cli(*base, "--category", "drawer", "--model", str(tiny_model / "model.pt"))
    assert code == 2 and "a model of category microwave, not drawer" in err
    save_model_file(tmp_path / "other.pt", "point-segmenter", "microwave", {}, {}, {})
    with pytest.raises(InputError, match="a point-segmenter model, not a kinematics-mdn model"):
        load_model_file(tmp_path / "other.pt", KIND, "microwave")
    # an MDN from before the object crop (its hparams have no input_size)
    payload = load_model_file(tiny_model / "model.pt", KIND, "microwave")
    old = {k: v for k, v in payload["hparams"].items() if k not in ("input_size", "side_features")}
    save_model_file(tmp_path / "old.pt", KIND, "microwave", old, {}, payload["meta"])
    code, _, err = run_cli(*base, "--category", "microwave", "--model", str(tmp_path / "old.pt"))
    assert code == 2 and "reads the whole image" in err and "retrain it" in err


def test_evaluate_mdn_writes_table_3_1_and_calibration(tiny_model, tiny_depth, tmp_path):
    out = tmp_path / "report"
    code, _, err = run_cli(
        "evaluate", "mdn", "debug=tiny", "category=microwave", f"model={tiny_model}",
        f"depth={tiny_depth}", f"out={out}",
    )  # fmt: skip
    assert code == 0, err
    report = (out / "report.md").read_text()
    for method in ("Mean", "NN", "ICP", "Ours", "Ours (densest)", "Ours + refinement"):
        assert f"| {method} |" in report
    assert "| 90% |" in report
    assert "kept the network's estimate (fallback) on" in report
    summary = (out / "summary.csv").read_text().splitlines()
    assert summary[0].startswith("method,images,position_cm_mean")
    assert "rotation_thesis_deg_mean,rotation_thesis_deg_std" in summary[0]
    assert summary[0].endswith("hinge_side_wrong_pct_mean,hinge_side_wrong_pct_std")
    assert "Rot. (thesis' metric, deg)" in report
    assert len(summary) == 7
    mean_row = dict(zip(summary[0].split(","), summary[1].split(","), strict=True))
    assert float(mean_row["position_cm_mean"]) > 0
    calibration = (out / "calibration.csv").read_text().splitlines()
    assert calibration[0].startswith("nominal,") and len(calibration) == 20
    for name in ("errors.png", "calibration.png", "examples.png", "errors.csv"):
        assert (out / name).stat().st_size > 0
    # the refined row: every test image (refine_images 500 > the tiny test set), each
    # with a status and a returned residual never above the network's
    refined = (out / "refinement.csv").read_text()
    assert refined.startswith("image,object_id,status,residual_network_m,residual_refined_m\n")
    rows = list(csv.DictReader(io.StringIO(refined)))
    last = next(csv.DictReader(io.StringIO("\n".join([summary[0], summary[-1]]))))
    assert last["method"] == "Ours + refinement" and len(rows) == int(last["images"])
    for row in rows:
        assert row["status"].startswith(("refined", "fallback", "not refined"))
        if row["residual_network_m"] != "nan":
            assert float(row["residual_refined_m"]) <= float(row["residual_network_m"])
    # the refined estimate's intervals are fitted on validation images: the tiny data
    # has none (tests/kinematics/test_refined_intervals.py fits them)
    assert "No validation images to fit its intervals on" in report
    assert not (out / "refined_intervals.csv").exists()


@pytest.mark.parametrize(("refine_images", "rows"), [("null", 4), ("2", 2), ("0", 0)])
def test_evaluate_mdn_refines_the_first_n_test_images_or_all(
    tiny_model, tiny_depth, tmp_path, refine_images, rows
):
    """`evaluate.refine_images`: the refined row's images are the first N test images, all
    of them with null (Table 3.1's rows), none with 0 (no refined row)."""
    out = tmp_path / "report"
    code, _, err = run_cli(
        "evaluate", "mdn", "debug=tiny", "category=microwave", f"model={tiny_model}",
        f"depth={tiny_depth}", "evaluate.icp_images=0", "evaluate.examples=0",
        "evaluate.max_test_images=4", f"evaluate.refine_images={refine_images}", f"out={out}",
    )  # fmt: skip
    assert code == 0, err
    summary = {r["method"]: r for r in csv.DictReader((out / "summary.csv").open())}
    assert summary["Ours"]["images"] == "4"
    if rows:
        assert summary["Ours + refinement"]["images"] == str(rows)
        assert len(list(csv.DictReader((out / "refinement.csv").open()))) == rows
    else:
        assert "Ours + refinement" not in summary


def test_evaluate_mdn_reads_the_objects_as_a_hashed_input(
    tiny_model, tiny_objects, tmp_path, monkeypatch
):
    """The object dataset behind the depth folder (the ICP template) is a declared input:
    found from the depth manifest relative to where render-depth ran, hashed, and a
    different dataset at that path is refused by name instead of used."""
    work, elsewhere = tmp_path / "work dir", tmp_path / "elsewhere"
    shutil.copytree(tiny_objects, work / "objs")
    elsewhere.mkdir()
    monkeypatch.chdir(work)
    code, _, err = run_cli("render-depth", "debug=tiny", "dataset=objs", "out=depth")
    assert code == 0, err
    monkeypatch.chdir(elsewhere)  # the recorded "objs" is relative to work/, not here
    args = [
        "evaluate", "mdn", "debug=tiny", "category=microwave", f"model={tiny_model}",
        f"depth={work / 'depth'}", "evaluate.icp_images=1", "evaluate.examples=0",
        "evaluate.max_test_images=4",
    ]  # fmt: skip
    code, _, err = run_cli(*args, "out=report")
    assert code == 0, err
    manifest = read_manifest(elsewhere / "report")
    assert manifest.inputs["objects"].path == str(work / "objs")
    assert manifest.inputs["objects"].content_hash == read_manifest(tiny_objects).content_hash
    # the same dataset elsewhere, named explicitly, is the same input: up to date
    code, out, err = run_cli(*args, "out=report", f"objects={tiny_objects}")
    assert code == 0 and "up to date" in out + err, err
    # another dataset at the recorded path: exit 2 naming it, nothing written
    shutil.rmtree(work / "objs")
    code, _, err = run_cli(
        "generate-dataset", "debug=tiny", "category=microwave", "seed=7", f"out={work / 'objs'}"
    )
    assert code == 0, err
    code, _, err = run_cli(*args, "out=report2")
    assert code == 2
    assert err.startswith("error: objects: ") and str(work / "objs") in err
    assert "is not the dataset" in err and len(err.strip().splitlines()) == 1
    assert not (elsewhere / "report2").exists()
    shutil.rmtree(work / "objs")
    code, _, err = run_cli(*args, "out=report2")
    assert code == 2 and "objects=PATH" in err and "objs" in err
