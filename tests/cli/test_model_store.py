"""The model store: `artic models`, the default model of a command (local, else shipped,
never a debug model), shipping a model with its card, and `--camera` presets."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from artic.artifacts.depth_dataset import DepthDataset
from artic.artifacts.manifest import MANIFEST
from artic.artifacts.model_store import (
    CARD_JSON,
    choose_model,
    halve_shipped,
    list_models,
    read_card,
    recard_shipped,
    set_inference_shipped,
    ship_model,
)
from artic.errors import InputError
from cli_runner import run_cli


@pytest.fixture(scope="module")
def trained(tiny_depth: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A tiny microwave MDN (debug=tiny) and its evaluation."""
    root = tmp_path_factory.mktemp("store")
    model, report = root / "model", root / "report"
    code, _, err = run_cli(
        "train-mdn", "debug=tiny", "category=microwave", f"depth={tiny_depth}", f"out={model}"
    )
    assert code == 0, err
    code, _, err = run_cli(
        "evaluate", "mdn", "debug=tiny", "category=microwave", f"model={model}",
        f"depth={tiny_depth}", f"out={report}",
    )  # fmt: skip
    assert code == 0, err
    return model, report


@pytest.fixture(scope="module")
def depth_png(tiny_depth: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A depth image of the tiny dataset, in its camera (kinect_v1_128 by default)."""
    shard = next(DepthDataset.open(tiny_depth).shards(decode=False))
    png = tmp_path_factory.mktemp("image") / "depth.png"
    Image.fromarray(shard.depth[0]).save(png)
    return png


@pytest.fixture
def workspace(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty working folder (artifacts/ relative to it) and an empty shipped store."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("ARTIC_MODELS", str(tmp_path / "shipped"))
    return tmp_path


def _as_release(model: Path, target: Path) -> Path:
    """A copy of a training output that says it was trained without a debug preset."""
    shutil.copytree(model, target)
    manifest = json.loads((target / MANIFEST).read_text())
    manifest["choices"] = {"category": "microwave", "experiment": "unit_test"}
    (target / MANIFEST).write_text(json.dumps(manifest))
    return target


def _predict(png: Path, *extra: str) -> tuple[int, dict, str]:
    code, out, err = run_cli(
        "predict", str(png), "--category", "microwave", "--camera", "kinect_v1_128", *extra
    )
    return code, (json.loads(out) if code == 0 else {}), err


def test_no_model_names_the_pipeline_that_makes_one(workspace, depth_png):
    code, out, _ = run_cli("models")
    assert code == 0 and "no models" in out
    code, _, err = _predict(depth_png)
    assert code == 2
    (line,) = err.strip().splitlines()
    assert "artic pipeline ch3" in line and "minutes" in line and "--model" in line


def test_a_debug_model_is_never_the_default_and_is_flagged_when_given(
    workspace, trained, depth_png
):
    model, _ = trained
    local = workspace / "artifacts/models/mdn/microwave"
    shutil.copytree(model, local)
    (listed,) = list_models()
    assert listed.source == "local" and listed.debug and listed.preset == "debug=tiny"
    with pytest.raises(InputError, match="no mdn model for microwave"):
        choose_model("mdn", "microwave", None, "--model")
    code, result, err = _predict(depth_png, "--model", str(local / "model.pt"))
    assert code == 0, err
    assert result["input"]["model_source"] == "given"
    assert "debug=tiny" in result["warnings"][0] and "debug=tiny" in err


def test_ship_refuses_debug_models_and_foreign_evaluations(workspace, trained):
    model, report = trained
    with pytest.raises(InputError, match="debug model is never shipped"):
        ship_model(model, report, workspace / "shipped", "abc123")
    other = _as_release(model, workspace / "other")
    manifest = json.loads((other / MANIFEST).read_text())
    manifest["content_hash"] = "0" * 64  # another model's outputs
    (other / MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(InputError, match="did not evaluate the model"):
        ship_model(other, report, workspace / "shipped", "abc123")
    assert not (workspace / "shipped").exists()


def test_ship_then_predict_and_list(workspace, trained, depth_png):
    model, report = trained
    release = _as_release(model, workspace / "release")
    folder = ship_model(release, report, workspace / "shipped", "abc123")
    card = read_card(folder)
    assert (card.kind, card.category, card.preset, card.commit) == (
        "mdn", "microwave", "experiment=unit_test", "abc123",
    )  # fmt: skip
    assert card.figures and all(k.endswith("pos/rot/config") for k in card.figures)
    assert "## Shipped with artic" in (folder / "model_card.md").read_text()

    code, result, err = _predict(depth_png)
    assert code == 0, err
    assert result["input"]["model_source"] == "shipped"
    assert result["input"]["model"] == str(folder / "model.pt")

    code, out, err = run_cli("models", "--json")
    assert code == 0, err
    (row,) = json.loads(out)
    assert row["source"] == "shipped" and row["default"] and row["figures"] == card.figures

    # a local model trained without a debug preset wins over the shipped one
    _as_release(model, workspace / "artifacts/models/mdn/microwave")
    assert choose_model("mdn", "microwave", None, "--model").source == "local"
    rows = json.loads(run_cli("models", "--json")[1])
    assert [(r["source"], r["default"]) for r in rows] == [("local", True), ("shipped", False)]
    shutil.rmtree(workspace / "artifacts/models")

    # a shipped model.pt that no longer matches its card is refused
    with (folder / "model.pt").open("ab") as f:
        f.write(b"\0")
    code, _, err = _predict(depth_png)
    assert code == 2 and "does not match its card.json" in err
    (folder / CARD_JSON).write_text("{}")
    code, _, err = run_cli("models")
    assert code == 2 and "card.json: field" in err


def test_ship_carries_the_refined_intervals_of_the_evaluation(workspace, trained):
    """An evaluation with the refined estimate's interval scales ships them beside the
    model, where `artic predict` reads them (`Predictor.load`)."""
    from artic.kinematics.intervals import REFINED_INTERVALS, write_refined_intervals
    from artic.kinematics.predict import Predictor

    model, report = trained
    evaluation = workspace / "evaluation"
    shutil.copytree(report, evaluation)
    columns = list(Predictor.load(model / "model.pt").codec.columns)
    scales = {0.5: np.full(len(columns), 0.7), 0.9: np.full(len(columns), 1.3)}
    write_refined_intervals(evaluation / REFINED_INTERVALS, columns, scales)
    folder = ship_model(_as_release(model, workspace / "release"), evaluation,
                        workspace / "shipped", "abc123")  # fmt: skip
    assert (folder / REFINED_INTERVALS).read_bytes() == (
        evaluation / REFINED_INTERVALS
    ).read_bytes()
    loaded = Predictor.load(folder / "model.pt", "microwave").refined_scales
    assert loaded is not None and sorted(loaded) == [0.5, 0.9]
    np.testing.assert_array_equal(loaded[0.9], scales[0.9])
    plain = ship_model(_as_release(model, workspace / "release2"), report,
                       workspace / "shipped2", "abc123")  # fmt: skip
    assert not (plain / REFINED_INTERVALS).exists()
    assert Predictor.load(plain / "model.pt").refined_scales is None


def test_a_shipped_model_is_recarded_with_a_new_evaluation(workspace, trained, tiny_depth):
    """`recard_shipped`: the figures and hash of a new `evaluate mdn` of the shipped
    folder, its refined_intervals.csv beside the model; the model file stays, and an
    evaluation of another model is refused."""
    from artic.kinematics.intervals import REFINED_INTERVALS, write_refined_intervals
    from artic.kinematics.predict import Predictor

    model, report = trained
    folder = ship_model(_as_release(model, workspace / "release"), report,
                        workspace / "shipped", "abc123")  # fmt: skip
    before = read_card(folder)
    out = workspace / "evaluation"
    code, _, err = run_cli(
        "evaluate", "mdn", "debug=tiny", "category=microwave", f"model={folder}",
        f"depth={tiny_depth}", f"out={out}", "evaluate.icp_images=1",
    )  # fmt: skip
    assert code == 0, err
    columns = list(Predictor.load(folder / "model.pt").codec.columns)
    write_refined_intervals(out / REFINED_INTERVALS, columns, {0.9: np.full(len(columns), 1.5)})
    with pytest.raises(InputError, match="did not evaluate the model"):
        recard_shipped(folder, report)  # the training output's evaluation, not the shipped file's
    assert recard_shipped(folder, out) == folder
    after = read_card(folder)
    assert after.evaluation_hash == json.loads((out / MANIFEST).read_text())["content_hash"]
    assert after.model_sha256 == before.model_sha256 and after.commit == before.commit
    card_md = (folder / "model_card.md").read_text()
    assert card_md.count("## Shipped with artic") == 1
    scales = Predictor.load(folder / "model.pt", "microwave").refined_scales
    assert scales is not None and list(scales) == [0.9]
    assert not list(folder.glob(".*.partial"))


def test_a_shipped_model_halved_predicts_as_its_rounded_weights(workspace, trained, depth_png):
    """`halve_shipped`: float16 weights (about half the file), loaded into float32 to
    exactly the rounded values; the card gets the new bytes' hash and size and drops the
    figures and intervals measured on the old ones; `artic predict` still works and
    agrees with the float32 model to float16's rounding; halving again changes nothing."""
    import torch

    from artic.kinematics.intervals import REFINED_INTERVALS, write_refined_intervals
    from artic.kinematics.predict import Predictor

    model, report = trained
    folder = ship_model(_as_release(model, workspace / "release"), report,
                        workspace / "shipped", "abc123")  # fmt: skip
    columns = list(Predictor.load(folder / "model.pt").codec.columns)
    write_refined_intervals(folder / REFINED_INTERVALS, columns, {0.9: np.ones(len(columns))})
    before, full = read_card(folder), Predictor.load(folder / "model.pt").model.state_dict()
    code, first, err = _predict(depth_png, "--no-refine")
    assert code == 0, err
    assert halve_shipped(folder) == folder
    card = read_card(folder)
    assert card.weights == "float16" and card.figures == {} and card.evaluation_hash is None
    assert card.size == (folder / "model.pt").stat().st_size < 0.6 * before.size
    assert card.model_sha256 != before.model_sha256 and card.commit == before.commit
    assert not (folder / REFINED_INTERVALS).exists() and not list(folder.glob(".*.partial"))
    assert "weights stored as float16" in (folder / "model_card.md").read_text()
    loaded = Predictor.load(folder / "model.pt").model.state_dict()
    for name, value in full.items():
        expected = value.half().float() if value.is_floating_point() else value
        assert loaded[name].dtype == value.dtype and torch.equal(loaded[name], expected), name
    code, second, err = _predict(depth_png, "--no-refine")
    assert code == 0, err
    assert second["input"]["model_source"] == "shipped"
    for key, value in first["estimate"].items():
        assert second["estimate"][key] == pytest.approx(value, rel=0.02, abs=0.02), key
    sha = card.model_sha256
    assert read_card(halve_shipped(folder)).model_sha256 == sha


def test_a_shipped_segmenters_inference_settings_change_and_its_weights_stay(
    tmp_path: Path,
) -> None:
    """`set_inference_shipped`: the shipped storage-furniture segmenter with one pass more:
    the weights and other settings stay, the card records the change with the new
    bytes' hash and drops the figures measured before; a setting InferenceConfig refuses
    and a model of another kind are refused, leaving the files as they were."""
    import torch

    from artic.artifacts.model_store import shipped_input
    from artic.hierarchy.config import InferenceConfig
    from artic.hierarchy.models import load_segmenter

    store = Path(__file__).resolve().parents[2] / "models"
    folder = tmp_path / "segmenter"
    shutil.copytree(store / "segmenter" / "storage_furniture", folder)

    def validate(settings: dict[str, object]) -> dict[str, object]:
        return InferenceConfig(**settings).model_dump()

    before, old = read_card(folder), load_segmenter(folder / "model.pt")
    passes = old.inference.passes + 1
    assert before.figures
    assert set_inference_shipped(folder, {"passes": passes}, validate) == folder
    card, new = read_card(folder), load_segmenter(folder / "model.pt")
    assert new.inference == old.inference.model_copy(update={"passes": passes})
    for name, value in old.model.state_dict().items():
        assert torch.equal(new.model.state_dict()[name], value), name
    assert card.inference == before.inference | {"passes": passes}
    assert card.figures == {} and card.evaluation_hash is None
    assert card.model_sha256 != before.model_sha256 and card.commit == before.commit
    assert shipped_input(folder, card.stage) is not None  # the card matches the new bytes
    changed = next(
        line
        for line in (folder / "model_card.md").read_text().splitlines()
        if "inference settings changed after training:" in line
    )
    assert f"passes={passes}" in changed.split(": ", 1)[1].split(", ")
    with pytest.raises(InputError, match=r"inference\.passes"):
        set_inference_shipped(folder, {"passes": 0}, validate)
    assert read_card(folder) == card and not list(folder.glob(".*"))
    labeller = tmp_path / "labeller"
    shutil.copytree(store / "hierarchy" / "storage_furniture", labeller)
    with pytest.raises(InputError, match="no inference settings"):
        set_inference_shipped(labeller, {"passes": 2}, validate)


def test_half_precision_refuses_what_float16_cannot_hold():
    import torch

    from artic.artifacts.model_file import half_precision

    state = {"w": torch.tensor([1.0, 1e-3]), "steps": torch.tensor(7)}
    half = half_precision(state)
    assert half["w"].dtype == torch.float16 and half["steps"].dtype == torch.int64
    with pytest.raises(ValueError, match="big: values beyond float16"):
        half_precision({"big": torch.tensor([7e4])})


def test_evaluate_mdn_reads_a_shipped_model(workspace, trained, tiny_depth):
    """`evaluate mdn model=models/mdn/C` (a shipped model's folder, its manifest input the
    model's sha256) or `model=null` (the store's choice) evaluates the shipped model; one
    that no longer matches its card exits 2."""
    model, report = trained
    folder = ship_model(_as_release(model, workspace / "release"), report,
                        workspace / "shipped", "abc123")  # fmt: skip
    card = read_card(folder)
    for given in (str(folder), "null"):
        out = workspace / f"eval-{given == 'null'}"
        code, _, err = run_cli(
            "evaluate", "mdn", "debug=tiny", "category=microwave", f"model={given}",
            f"depth={tiny_depth}", f"out={out}", "evaluate.refine=false",
        )  # fmt: skip
        assert code == 0, err
        record = json.loads((out / MANIFEST).read_text())["inputs"]["model"]
        assert record["path"] == str(folder) and record["stage"] == "train-mdn"
        assert record["content_hash"] == card.model_sha256[:16]
        # the same bytes as the training output it was shipped from: the same figures
        ours = [line for line in (out / "summary.csv").read_text().splitlines()
                if line.startswith("Ours,")]  # fmt: skip
        assert ours and ours[0] in (report / "summary.csv").read_text().splitlines()
    with (folder / "model.pt").open("ab") as f:
        f.write(b"\0")
    code, _, err = run_cli(
        "evaluate", "mdn", "debug=tiny", "category=microwave", f"model={folder}",
        f"depth={tiny_depth}", f"out={workspace / 'eval-broken'}",
    )  # fmt: skip
    assert code == 2 and "does not match its card.json" in err
    assert not (workspace / "eval-broken").exists()


def test_camera_presets(workspace, trained, depth_png):
    model, _ = trained
    code, result, err = _predict(depth_png, "--model", str(model / "model.pt"))
    assert code == 0, err
    assert result["input"]["camera"] == "preset kinect_v1_128"
    assert result["input"]["reprojected_to_training_camera"] is False
    code, _, err = run_cli(
        "predict", str(depth_png), "--category", "microwave", "--camera", "kinect_v2",
        "--model", str(model / "model.pt"),
    )  # fmt: skip
    assert code == 2 and "kinect_v1" in err and "neither a JSON file nor a camera preset" in err
    # the presets are the config group's files, and the example camera file is one of them
    example = Path(__file__).parents[2] / "examples" / "camera_kinect_v1.json"
    preset = json.loads(example.read_text())
    assert preset["fx"] == 525.0 and preset["width"] == 640
    big = np.zeros((480, 640), np.uint16)
    big[200:280, 300:340] = 1500
    Image.fromarray(big).save(workspace / "kinect.png")
    for camera in ("kinect_v1", str(example)):
        code, out, err = run_cli(
            "predict", str(workspace / "kinect.png"), "--category", "microwave",
            "--camera", camera, "--model", str(model / "model.pt"),
        )  # fmt: skip
        assert code == 0, err
        assert json.loads(out)["input"]["reprojected_to_training_camera"] is True
