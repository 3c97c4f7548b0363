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


def test_thesis_category_variants_are_the_generators_data_under_the_same_name():
    for name in ("cabinet", "cabinet2", "microwave", "refrigerator"):
        default = compose("generate_dataset", [f"category={name}"])
        thesis = compose("generate_dataset", [f"category=thesis/{name}"])
        assert thesis["category"]["name"] == name
        assert thesis["out"] == default["out"] == f"artifacts/objects/{name}"
        # everything but the sizes (door thickness included), the hinge sides and the
        # distances (the cabinet's) is the default category's
        keep = {"geometry", "chirality", "pose"}
        assert thesis["category"]["geometry"].get("door_thickness") is None
        table_a2 = [1.5, 3.5] if name == "refrigerator" else [1.0, 2.0]
        assert thesis["category"]["pose"]["x"] == table_a2
        assert {k: v for k, v in thesis["category"].items() if k not in keep} == {
            k: v for k, v in default["category"].items() if k not in keep
        }
    cabinet = compose("generate_dataset", ["category=thesis/cabinet"])["category"]
    assert cabinet["geometry"] == {"depth": [0.28, 0.32], "width": [0.3, 0.7],
                                   "height": [0.3, 0.7]}  # fmt: skip
    default = compose("generate_dataset", ["category=cabinet"])["category"]["geometry"]
    for key, (lo, hi) in cabinet["geometry"].items():
        assert default[key][0] <= lo and hi <= default[key][1]  # the union holds both
    assert default["depth"][1] >= 0.64 and default["width"][1] >= 1.4  # Table A.1's
    assert compose("generate_dataset", ["category=thesis/microwave"])["category"]["chirality"] == [
        -1
    ]
    assert compose("generate_dataset", [])["category"]["chirality"] == [-1, 1]
