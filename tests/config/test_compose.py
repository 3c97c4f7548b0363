import pytest

from artic.config.compose import compose, validate
from artic.config.schemas import ShardConfig
from artic.errors import InputError


def test_overrides_and_interpolated_output_paths():
    cfg = compose("render_depth", ["dataset=artifacts/objects/toaster/", "seed=3"])
    assert cfg["out"] == "artifacts/depth/toaster"
    assert cfg["seed"] == 3
    # render-depth renders with the dataset's camera unless one is named
    assert cfg.get("camera") is None
    named = compose("render_depth", ["dataset=x", "camera=kinect_v1_128"])
    assert named["camera"]["width"] == 128


def test_debug_and_experiment_presets_override_defaults():
    tiny = compose("generate_dataset", ["debug=tiny"])
    full = compose("generate_dataset", ["experiment=appendix_a"])
    assert tiny["dataset"]["objects"] < 10
    assert full["dataset"]["objects"] == 11000
    # Chapter 3's experiments sample positions for the thesis generator's camera
    for experiment in ("ch3_cpu", "appendix_a"):
        camera = compose("generate_dataset", [f"experiment={experiment}"])["camera"]
        assert (camera["width"], camera["height"]) == (192, 108), experiment
    assert tiny["camera"]["width"] == 128


def test_hydra_errors_become_one_line_input_errors():
    with pytest.raises(InputError, match="camera"):
        compose("render_depth", ["camera=nosuchcam", "dataset=x"])


def test_validation_error_names_the_field():
    with pytest.raises(InputError, match=r"config field count: .*greater than or equal to 1"):
        validate(ShardConfig, {"index": 0, "count": 0})
