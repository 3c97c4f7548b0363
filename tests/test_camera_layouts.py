"""Camera files written by other tools (issue 24, item 5): artic's six fields, ROS
CameraInfo (`K` / `k`), ROS camera_info YAML (`camera_matrix`) and Open3D
(`intrinsic_matrix`, column-major) all read to the same intrinsics; fields a layout does
not use give one warning naming them; missing or invalid intrinsics exit 2 naming the
file and the field, through `artic predict` too."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pytest

from artic.artifacts.depth_image import read_camera, read_camera_arg
from artic.errors import InputError
from artic.geometry.camera import CameraFieldError, CameraIntrinsics, camera_from_mapping
from cli_runner import run_cli

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

#: not square pixels and not centred, so that a swapped fx/fy or cx/cy shows
CAM = CameraIntrinsics(fx=531.5, fy=527.25, cx=318.0, cy=241.5, width=640, height=480)
K = [[531.5, 0.0, 318.0], [0.0, 527.25, 241.5], [0.0, 0.0, 1.0]]
FLAT = [x for row in K for x in row]
COLUMN_MAJOR = [K[r][c] for c in range(3) for r in range(3)]

LAYOUTS = {
    "artic": ({"fx": 531.5, "fy": 527.25, "cx": 318.0, "cy": 241.5, "width": 640, "height": 480},
              "artic"),
    "ros1 flat K": ({"width": 640, "height": 480, "K": FLAT}, "ros"),
    "ros2 flat k": ({"width": 640, "height": 480, "k": FLAT}, "ros"),
    "ros nested K": ({"width": 640, "height": 480, "K": K}, "ros"),
    "ros yaml": ({"image_width": 640, "image_height": 480,
                  "camera_matrix": {"rows": 3, "cols": 3, "data": FLAT}}, "ros_yaml"),
    "open3d column-major": ({"width": 640, "height": 480,
                             "intrinsic_matrix": COLUMN_MAJOR}, "open3d"),
    "opencv nested rows": ({"width": 640, "height": 480, "intrinsic_matrix": K}, "open3d"),
}  # fmt: skip


@pytest.mark.parametrize("name", list(LAYOUTS))
def test_each_layout_reads_to_the_same_intrinsics(name, tmp_path):
    data, layout = LAYOUTS[name]
    read = camera_from_mapping(data)
    assert read.intrinsics == CAM and read.layout == layout and read.ignored == ()
    path = tmp_path / "cam.json"
    path.write_text(json.dumps(data))
    assert read_camera(path) == CAM
    assert read_camera_arg(str(path)) == CAM


def test_a_file_open3d_writes_reads_back_column_major(tmp_path):
    """Open3D's own writer: its JSON stores the Eigen matrix in storage (column) order."""
    o3d = pytest.importorskip("open3d")
    path = tmp_path / "o3d.json"
    intrinsic = o3d.camera.PinholeCameraIntrinsic(640, 480, 531.5, 527.25, 318.0, 241.5)
    assert o3d.io.write_pinhole_camera_intrinsic(str(path), intrinsic)
    stored = json.loads(path.read_text())["intrinsic_matrix"]
    assert stored[2] == 0.0 and stored[6] == 318.0, "column-major: cx is the 7th number"
    assert read_camera(path) == CAM
    np.testing.assert_array_equal(np.asarray(intrinsic.intrinsic_matrix), K)


def test_the_ros_example_file_is_kinect_v1(caplog):
    kinect = json.loads((EXAMPLES / "camera_kinect_v1.json").read_text())
    with caplog.at_level(logging.WARNING):
        cam = read_camera(EXAMPLES / "camera_ros_camera_info.json")
    assert cam == CameraIntrinsics(**kinect)
    (record,) = caplog.records
    assert "camera_ros_camera_info.json" in record.getMessage()
    for field in ("D", "P", "R", "header", "distortion_model"):
        assert field in record.getMessage()


def test_extra_fields_give_exactly_one_warning_naming_them(tmp_path, caplog):
    data = dict(LAYOUTS["artic"][0]) | {"frame": "camera_link", "model": "kinect", "D": [0.1]}
    path = tmp_path / "extra.json"
    path.write_text(json.dumps(data))
    with caplog.at_level(logging.WARNING):
        assert read_camera(path) == CAM
    (record,) = caplog.records
    message = record.getMessage()
    assert "\n" not in message and str(path) in message
    assert "ignored fields D, frame, model" in message
    caplog.clear()
    path.write_text(json.dumps(LAYOUTS["artic"][0]))
    with caplog.at_level(logging.WARNING):
        read_camera(path)
    assert caplog.records == [], "no extra field, no warning"


def test_the_strict_model_still_refuses_extra_fields():
    """CameraIntrinsics (also a config model) stays strict; the reader converts."""
    with pytest.raises(ValueError, match="frame"):
        CameraIntrinsics.model_validate(dict(LAYOUTS["artic"][0]) | {"frame": "x"})


BAD = {
    "no intrinsics": ({"frame": "x"}, "field fx: missing"),
    "artic without cy": ({"fx": 1.0, "fy": 1.0, "cx": 1.0, "width": 4, "height": 4}, "field cy"),
    "ros without width": ({"height": 480, "K": FLAT}, "field width: missing"),
    "yaml without image_height": (
        {"image_width": 640, "camera_matrix": {"data": FLAT}}, "field image_height"),
    "skew": ({"width": 640, "height": 480, "K": [531.5, 2.0, 318.0, 0, 527.25, 241.5, 0, 0, 1]},
             "skew"),
    "short K": ({"width": 640, "height": 480, "K": FLAT[:8]}, "field K: expected a 3x3"),
    "K with text": ({"width": 640, "height": 480, "K": ["a"] * 9}, "field K: expected a number"),
    "row-major read as open3d": (
        {"width": 640, "height": 480, "intrinsic_matrix": FLAT}, "field intrinsic_matrix"),
    "negative focal in K": (
        {"width": 640, "height": 480, "K": [-5.0, 0, 318.0, 0, 527.25, 241.5, 0, 0, 1]},
        "field K (fx)"),
    "fractional width": ({"width": 640.5, "height": 480, "K": FLAT}, "field width"),
    "NaN fx": ({"fx": float("nan"), "fy": 1.0, "cx": 1.0, "cy": 1.0, "width": 4, "height": 4},
               "field fx"),
    "principal point outside": ({"width": 64, "height": 48, "K": FLAT}, "principal point"),
    "not an object": ([1, 2, 3], "field camera"),
    "camera_matrix 3x4": (
        {"image_width": 640, "image_height": 480,
         "camera_matrix": {"rows": 3, "cols": 4, "data": FLAT}}, "field camera_matrix"),
}  # fmt: skip


@pytest.mark.parametrize("name", list(BAD))
def test_missing_or_invalid_intrinsics_name_the_field(name, tmp_path):
    data, fragment = BAD[name]
    with pytest.raises(CameraFieldError, match=r"^field "):
        camera_from_mapping(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(InputError) as err:
        read_camera(path)
    message = str(err.value)
    assert message.startswith(f"{path}: field ") and fragment in message, message
    assert "\n" not in message


@pytest.mark.parametrize("name", ["ros without width", "skew", "row-major read as open3d"])
def test_predict_with_a_bad_camera_file_exits_2_with_one_line(name, tmp_path):
    data, fragment = BAD[name]
    cam = tmp_path / "bad.json"
    cam.write_text(json.dumps(data))
    depth = tmp_path / "d.npy"
    np.save(depth, np.full((480, 640), 1.5, np.float32))
    code, out, err = run_cli(
        "predict", str(depth), "--category", "microwave", "--camera", str(cam),
        "--model", str(tmp_path / "never-read.pt"),
    )  # fmt: skip
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, err
    assert len(lines) == 1 and str(cam) in lines[0] and fragment in lines[0], err
    assert "Traceback" not in out + err


def test_a_ros_camera_info_yaml_file_reads_as_yaml(tmp_path, caplog):
    """camera_calibration_parsers' file as written (YAML), not only converted to JSON."""
    path = tmp_path / "depth_camera.yaml"
    path.write_text(
        "image_width: 640\n"
        "image_height: 480\n"
        "camera_name: depth\n"
        "camera_matrix:\n"
        "  rows: 3\n"
        "  cols: 3\n"
        f"  data: [{', '.join(str(x) for x in FLAT)}]\n"
        "distortion_model: plumb_bob\n"
        "distortion_coefficients:\n"
        "  rows: 1\n"
        "  cols: 5\n"
        "  data: [0, 0, 0, 0, 0]\n"
    )
    with caplog.at_level(logging.WARNING):
        assert read_camera_arg(str(path)) == CAM
    (record,) = caplog.records
    assert "camera_name, distortion_coefficients, distortion_model" in record.getMessage()
    path.write_text("camera_matrix: [unclosed\n")
    with pytest.raises(InputError, match=r"depth_camera\.yaml: not YAML"):
        read_camera(path)
