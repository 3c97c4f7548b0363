"""What a model was trained on, and predict's warnings about it (issue 24, item 4).

train-mdn records the training images' chiralities, size / configuration / distance /
yaw ranges and camera in model.pt's meta, model.json and the card; `artic predict`
always prints a `warnings` list (empty when there is nothing to say) and logs each
warning on one stderr line: the estimate outside those ranges, an image camera that is
not the training camera, a mixture split between hinge sides. A model from before the
record gives no range warning and does not fail.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from artic.artifacts.depth_dataset import DepthDataset
from artic.artifacts.model_file import load_model_file, save_model_file
from artic.kinematics.config import MDN_KIND as KIND
from artic.kinematics.predict import (
    RANGE_TOLERANCE,
    RANGE_TOLERANCE_ABS,
    SIDE_WEIGHT,
    Predictor,
    TrainingDomain,
)
from cli_runner import run_cli, train_tiny_mdn


@pytest.fixture(scope="module")
def tiny_depth(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Tiny microwaves of one hinge side (`category.chirality=[1]`, as the thesis
    generator's are of one side): the default microwaves have both since issue 24, and a
    tiny model trained on both splits its mixture, which these tests must control."""
    root = tmp_path_factory.mktemp("one_side")
    objects, depth = root / "objects", root / "depth"
    code, _, err = run_cli("generate-dataset", "debug=tiny", "category=microwave",
                           "category.chirality=[1]", f"out={objects}")  # fmt: skip
    assert code == 0, err
    code, _, err = run_cli("render-depth", "debug=tiny", f"dataset={objects}", f"out={depth}")
    assert code == 0, err
    return depth


@pytest.fixture(scope="module")
def tiny_model(tiny_depth: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A debug=tiny microwave MDN on the one-sided `tiny_depth`."""
    return train_tiny_mdn(tiny_depth, tmp_path_factory.mktemp("one_side_mdn") / "microwave")


@pytest.fixture(scope="module")
def model_pt(tiny_model: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny model's model.pt away from its folder: predict does not add the warning
    about a debug=tiny model (read from the folder's manifest), so only ours remain."""
    path = tmp_path_factory.mktemp("alone") / "model.pt"
    shutil.copyfile(tiny_model / "model.pt", path)
    return path


@pytest.fixture(scope="module")
def training_image(tiny_depth: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A training image (float metres .npy) and its camera file."""
    ds = DepthDataset.open(tiny_depth)
    shard = next(ds.shards())
    folder = tmp_path_factory.mktemp("image")
    np.save(folder / "depth.npy", shard.depth[0])
    (folder / "camera.json").write_text(ds.info.camera.model_dump_json())
    return folder / "depth.npy", folder / "camera.json"


def _predict(image: Path, camera: Path, model: Path) -> tuple[int, dict, list[str]]:
    code, out, err = run_cli(
        "predict", str(image), "--category", "microwave", "--camera", str(camera),
        "--model", str(model),
    )  # fmt: skip
    assert code == 0, err
    return code, json.loads(out), [ln for ln in err.splitlines() if ln.strip()]


def _with_meta(model: Path, out: Path, change) -> Path:
    """A copy of `model`'s model.pt with its meta changed by `change(meta)`."""
    payload = load_model_file(model / "model.pt", KIND, "microwave")
    meta = json.loads(json.dumps(payload["meta"]))
    change(meta)
    save_model_file(out, KIND, "microwave", payload["hparams"], payload["state_dict"], meta)
    return out


def test_train_mdn_records_what_the_model_was_trained_on(tiny_model, tiny_depth):
    ds = DepthDataset.open(tiny_depth)
    info = json.loads((tiny_model / "model.json").read_text())
    meta = load_model_file(tiny_model / "model.pt", KIND)["meta"]
    assert meta["training_domain"] == info["training_domain"]
    domain = TrainingDomain.model_validate(info["training_domain"])
    assert domain.chiralities == [1], "one hinge side (the tiny_depth fixture)"
    assert set(domain.ranges) == {"depth", "width", "height", "pose_yaw", "j0_q", "distance"}
    assert all(lo <= hi for lo, hi in domain.ranges.values())
    assert domain.cameras == [ds.info.camera] and domain.images == info["train_images"]
    lo, hi = domain.ranges["depth"]
    assert lo >= 0.25 and hi <= 0.56, "Table A.1's microwave depths (conf/common/category)"
    card = (tiny_model / "model_card.md").read_text()
    assert "- trained on (labels of the" in card and "chirality +1" in card
    assert "one hinge side only" in card and "training camera:" in card
    # the doors: drawn 2-5 cm thick (conf/common/category/microwave.yaml), built at 3.5 cm
    assert ds.info.door_thickness == domain.door_thickness == (0.02, 0.05)
    assert "- doors 2.0 to 5.0 cm thick; the refinement builds them 3.50 cm thick" in card
    assert Predictor.load(tiny_model / "model.pt").parts.door_thickness == pytest.approx(0.035)


def test_a_model_without_the_door_record_refines_with_2_cm_doors(tiny_model, tmp_path):
    """Models trained before the door thickness was recorded were trained on 2 cm doors."""

    def forget(meta):
        del meta["training_domain"]["door_thickness"]

    older = _with_meta(tiny_model, tmp_path / "model.pt", forget)
    assert Predictor.load(older).parts.door_thickness == 0.02
    assert Predictor.load(older).domain is not None


def test_an_in_range_image_gives_no_warning(model_pt, training_image):
    image, camera = training_image
    _, result, lines = _predict(image, camera, model_pt)
    assert result["warnings"] == []
    assert lines == [], "no warning line on stderr"


def test_an_estimate_outside_the_training_ranges_is_flagged(tiny_model, training_image, tmp_path):
    """The same image and weights, the recorded depth range moved away from the estimate:
    the warning names the quantity, once on stderr and once in the JSON."""

    def narrow(meta: dict) -> None:
        meta["training_domain"]["ranges"]["depth"] = [5.0, 5.5]
        meta["training_domain"]["chiralities"] = [-1]

    model = _with_meta(tiny_model, tmp_path / "narrow.pt", narrow)
    image, camera = training_image
    _, result, lines = _predict(image, camera, model)
    (warning,) = result["warnings"]
    assert warning.startswith("the estimate lies outside the training data: depth ")
    assert "(trained 5.000 to 5.500)" in warning and "chirality +1 (trained [-1])" in warning
    assert "width" not in warning, "only the quantities outside their range"
    assert lines == [f"predict: {warning}"]


def test_a_model_without_the_record_gives_no_range_warning(tiny_model, training_image, tmp_path):
    model = _with_meta(tiny_model, tmp_path / "old.pt", lambda m: m.pop("training_domain"))
    image, camera = training_image
    _, result, lines = _predict(image, camera, model)
    assert result["warnings"] == [] and lines == []
    assert Predictor.load(model).domain is None


def test_another_camera_is_flagged(tiny_model, training_image, tmp_path):
    image, camera = training_image
    cam = json.loads(camera.read_text())
    depth = np.load(image)
    np.save(tmp_path / "big.npy", np.kron(depth, np.ones((2, 2), np.float32)))
    cam2 = {k: 2 * cam[k] for k in ("fx", "fy", "width", "height")}
    cam2 |= {"cx": 2 * cam["cx"] + 0.5, "cy": 2 * cam["cy"] + 0.5}
    (tmp_path / "cam2.json").write_text(json.dumps(cam2))
    _, result, lines = _predict(
        tmp_path / "big.npy", tmp_path / "cam2.json", tiny_model / "model.pt"
    )
    camera_warnings = [w for w in result["warnings"] if "is not the training camera" in w]
    assert len(camera_warnings) == 1 and "reprojected" in camera_warnings[0]
    assert f"predict: {camera_warnings[0]}" in lines


def test_a_camera_file_with_extra_fields_is_used_and_named_once(model_pt, training_image, tmp_path):
    image, camera = training_image
    cam = json.loads(camera.read_text())
    k = [cam["fx"], 0, cam["cx"], 0, cam["fy"], cam["cy"], 0, 0, 1]
    ros = {"header": {"frame_id": "depth"}, "width": cam["width"], "height": cam["height"],
           "K": k, "D": [0, 0, 0, 0, 0], "distortion_model": "plumb_bob"}  # fmt: skip
    (tmp_path / "ros.json").write_text(json.dumps(ros))
    _, result, lines = _predict(image, tmp_path / "ros.json", model_pt)
    (warning,) = result["warnings"]
    assert "ignored fields D, distortion_model, header" in warning
    assert lines == [f"predict: {warning}"]
    assert result["input"]["reprojected_to_training_camera"] is False


def _predictor_with_domain(tiny_model: Path) -> Predictor:
    return Predictor.load(tiny_model / "model.pt")


def test_domain_warnings_tolerance_and_hinge_side_split(tiny_model):
    """The unit: a value at the range's edge plus the documented tolerance passes, one
    beyond it does not; a mixture with less than SIDE_WEIGHT on the estimate's side is
    split, one with more is not."""
    predictor = _predictor_with_domain(tiny_model)
    assert predictor.domain is not None
    codec = predictor.codec
    col = {c: i for i, c in enumerate(codec.columns)}
    label = codec.mean.copy()
    lo, hi = predictor.domain.ranges["depth"]
    tol = RANGE_TOLERANCE * (hi - lo) + RANGE_TOLERANCE_ABS
    means = np.stack([label, label])
    weights = np.array([0.5, 0.5])
    cam = predictor.camera
    assert predictor.domain_warnings(label, weights, means, cam) == []
    label[col["depth"]] = hi + 0.99 * tol
    assert predictor.domain_warnings(label, weights, means, cam) == []
    label[col["depth"]] = hi + 1.01 * tol
    (warning,) = predictor.domain_warnings(label, weights, means, cam)
    assert "depth" in warning
    label = codec.mean.copy()
    means[1, col["chirality"]] = -1.0  # the second component on the other hinge side
    for w0, split in ((SIDE_WEIGHT - 0.05, True), (SIDE_WEIGHT + 0.05, False)):
        got = predictor.domain_warnings(label, np.array([w0, 1 - w0]), means, cam)
        assert any("split between hinge sides" in w for w in got) is split, (w0, got)
