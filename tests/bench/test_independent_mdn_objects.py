"""bench/independent_mdn_objects.py: the second generator of the six categories (issue
24, "Done when") labels its objects in artic's convention exactly, hinges them on the side
it says, gives the same bytes for the same seed, and scores `artic predict`'s answers
into errors.csv and summary.csv; bad input exits 2 with one line."""

from __future__ import annotations

import importlib.util
import io
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from PIL import Image

from artic.artifacts.formats import read_csv
from artic.geometry.transforms import invert, transform_points
from artic.objects.categories import build
from artic.objects.labels import image_labels, label_columns
from artic.objects.spec import ObjectSpec, PartsConfig, Pose
from artic.render.backend import make_backend

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "bench" / "independent_mdn_objects.py"
NEW = ["cabinet2", "toaster", "drawer", "refrigerator"]  # the categories added second


@pytest.fixture(scope="module")
def bench() -> Iterator[ModuleType]:
    """The script as a module."""
    spec = importlib.util.spec_from_file_location("independent_mdn_objects", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["independent_mdn_objects"] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("independent_mdn_objects", None)


SPEC_SIZES = {
    "microwave": [(0.41, 0.62, 0.33)],
    "cabinet": [(0.3, 0.55, 0.64)],
    "cabinet2": [(0.3, 0.9, 0.64), (0.6, 1.35, 0.7), (0.29, 0.32, 1.3)],
    "toaster": [(0.31, 0.52, 0.29), (0.2, 0.4, 0.5), (0.5, 0.6, 0.2)],
    "drawer": [(0.5, 0.41, 0.18), (0.45, 0.76, 0.1), (0.6, 0.3, 0.3)],
    "refrigerator": [(0.7, 0.75, 0.85), (0.6, 0.9, 0.82), (0.8, 0.6, 0.88)],
}


def _artic_spec(
    category: str, chirality: int, yaw: float = 0.4, sizes: tuple[float, float, float] | None = None
) -> ObjectSpec:
    depth, width, height = sizes or SPEC_SIZES[category][0]
    dof = 2 if category in ("cabinet2", "refrigerator") else 1
    upper = 0.4 if category == "drawer" else math.pi / 2
    return ObjectSpec(
        category=category,
        index=5,
        dof=dof,
        joint_type="prismatic" if category == "drawer" else "revolute",
        depth=depth,
        width=width,
        height=height,
        chirality=chirality,  # type: ignore[arg-type]
        pose=Pose(x=1.42, y=-0.17, z=-0.36, yaw=yaw),
        joint_limits=((0.0, upper),) * dof,
        parts=PartsConfig(),
    )


@pytest.mark.parametrize("chirality", [1, -1])
@pytest.mark.parametrize("category", ["microwave", "cabinet"])
def test_labels_agree_with_artics_builder(bench: ModuleType, category: str, chirality: int) -> None:
    """The same numbers, no extra details: every label column (pose, sizes, chirality,
    q, joint origin, direction, part origin) equals what artic's builder gives."""
    artic_spec = _artic_spec(category, chirality)
    for q in (0.0, 0.61, math.pi / 2):
        ours = bench.from_artic_spec(artic_spec, q)
        expected = image_labels(artic_spec, build(artic_spec), np.array([q]))
        got = image_labels(ours.label_spec(), bench.build(ours), np.array([q]))
        assert list(got) == label_columns(1)
        for column in expected:
            assert got[column] == pytest.approx(expected[column], abs=1e-6), column


@pytest.mark.parametrize(
    ("category", "chirality"),
    [("cabinet2", 1), ("toaster", 1), ("drawer", 1), ("refrigerator", 1), ("refrigerator", -1)],
)
def test_new_categories_labels_agree_with_artics_builder(
    bench: ModuleType, category: str, chirality: int
) -> None:
    """Several sizes, yaws and configurations (a q per joint; metres for the drawer), no
    extra details: every label column equals artic's builder's."""
    dof = 2 if category in ("cabinet2", "refrigerator") else 1
    upper = 0.4 if category == "drawer" else math.pi / 2
    for sizes, yaw in zip(SPEC_SIZES[category], (0.4, -0.7, 0.0), strict=True):
        artic_spec = _artic_spec(category, chirality, yaw, sizes)
        for q in ([0.0, 0.0], [0.3 * upper, 0.8 * upper], [upper, 0.1]):
            ours = bench.from_artic_spec(artic_spec, q[:dof])
            expected = image_labels(artic_spec, build(artic_spec), np.array(q[:dof]))
            got = image_labels(ours.label_spec(), bench.build(ours), np.array(q[:dof]))
            assert list(got) == label_columns(dof)
            for column in expected:
                assert got[column] == pytest.approx(expected[column], abs=1e-6), (sizes, q, column)


def _door_joint_checks(spec: Any, obj: Any, category: str) -> None:
    """Each vertical-hinge door: the axis +-z, the door on its free side of the hinge,
    its bottom at the joint origin's height, its back face on the body's front plane."""
    for j, joint in enumerate(obj.movable_joints):
        door = obj.links[obj.link_index(joint.child)].mesh.vertices
        sense = joint.axis[2]  # +1: hinge on -y, the door towards +y
        hinge_side = -1 if category == "cabinet2" and j == 1 else 1
        assert abs(sense) == pytest.approx(1.0)
        assert sense == hinge_side * spec.chirality
        assert door[:, 2].min() == pytest.approx(0.0, abs=1e-9)
        assert door[:, 0].max() == pytest.approx(0.0, abs=1e-9)
        assert (sense * door[:, 1]).min() == pytest.approx(0.0, abs=1e-9)
        origin = joint.origin[:3, 3]
        assert origin[0] == pytest.approx(-spec.depth / 2)
        assert -sense * origin[1] == pytest.approx(spec.width / 2, abs=0.01)


@pytest.mark.parametrize("category", NEW)
def test_new_categories_detailed_joints(bench: ModuleType, category: str) -> None:
    """With every detail: the two-door cabinet's doors hinged at its outer edges, the
    refrigerator's both on the chirality side, the fridge below the freezer; the toaster's
    door on its bottom edge, axis -y; the drawer's front centred on y = 0, axis -x; pose z
    at what the object stands on, height the overall height; chirality 1 unless sided."""
    for index in range(6):
        spec, obj = bench.make_object(category, "table_a1", "both", 4, index)
        assert spec.dof == obj.dof == (2 if category in ("cabinet2", "refrigerator") else 1)
        assert spec.chirality == (1 if category != "refrigerator" or index % 2 == 0 else -1)
        joints = obj.movable_joints
        if category in ("cabinet2", "refrigerator"):
            _door_joint_checks(spec, obj, category)
        if category == "cabinet2":
            assert joints[0].origin[1, 3] < 0 < joints[1].origin[1, 3]
        if category == "refrigerator":
            assert joints[0].origin[2, 3] < joints[1].origin[2, 3]
            assert joints[0].origin[1, 3] == pytest.approx(joints[1].origin[1, 3])
        if category == "toaster":
            assert np.allclose(joints[0].axis, [0.0, -1.0, 0.0])
            door = obj.links[obj.link_index(joints[0].child)].mesh.vertices
            assert door[:, 2].min() == pytest.approx(0.0, abs=1e-9)
            assert door[:, 1].min() == pytest.approx(-door[:, 1].max())
            assert joints[0].origin[0, 3] == pytest.approx(-spec.depth / 2)
        if category == "drawer":
            assert joints[0].type == "prismatic" and np.allclose(joints[0].axis, [-1.0, 0, 0])
            assert joints[0].origin[0, 3] == pytest.approx(-spec.depth / 2)
            assert joints[0].origin[1, 3] == pytest.approx(0.0, abs=1e-9)
            assert 0.0 <= spec.configuration <= 0.4
        points = transform_points(invert(obj.base_pose), np.concatenate([
            transform_points(p, link.mesh.vertices)
            for link, p in zip(obj.links, obj.link_poses(np.zeros(obj.dof)), strict=True)
        ]))  # fmt: skip
        assert points[:, 2].min() == pytest.approx(0.0, abs=1e-9)
        assert points[:, 2].max() == pytest.approx(spec.height, abs=1e-9)


@pytest.mark.parametrize("category", ["microwave", "cabinet"])
def test_detailed_doors_keep_the_joint_origin_on_the_hinge_edge_bottom(
    bench: ModuleType, category: str
) -> None:
    """With every detail: the joint origin is the door's hinge-edge bottom point on its
    back face, the axis +z for chirality +1 and -z for -1, the door on the free side."""
    for index in range(6):
        spec, obj = bench.make_object(category, "table_a1", "both", 4, index)
        joint = obj.movable_joints[0]
        door = obj.links[obj.link_index(joint.child)].mesh.vertices
        c = spec.chirality
        assert np.allclose(joint.axis, [0.0, 0.0, c])
        assert door[:, 2].min() == pytest.approx(0.0, abs=1e-9)  # bottom
        assert door[:, 0].max() == pytest.approx(0.0, abs=1e-9)  # back face
        along = c * door[:, 1]  # from the hinge towards the free edge
        assert along.min() == pytest.approx(0.0, abs=1e-9)
        origin = joint.origin[:3, 3]
        assert origin[0] == pytest.approx(-spec.depth / 2)
        assert -c * origin[1] == pytest.approx(spec.width / 2, abs=0.01)  # hinge-side edge
        assert origin[2] > 0 or category == "cabinet"
        labels = image_labels(spec.label_spec(), obj, np.array([spec.configuration]))
        at_pose = transform_points(spec.pose.matrix(), origin[None])[0]
        assert [labels[f"j0_origin_{a}"] for a in "xyz"] == pytest.approx(at_pose.tolist())
        tops = transform_points(invert(obj.base_pose), np.concatenate([
            transform_points(p, link.mesh.vertices)
            for link, p in zip(obj.links, obj.link_poses(np.zeros(1)), strict=True)
        ]))  # fmt: skip
        assert tops[:, 2].min() == pytest.approx(0.0, abs=1e-9)  # pose z: what it stands on
        assert tops[:, 2].max() == pytest.approx(spec.height, abs=1e-9)  # height: overall


@pytest.mark.parametrize("category", ["microwave", "cabinet"])
def test_mirrored_object_flips_chirality_and_hinge_side(bench: ModuleType, category: str) -> None:
    """One object hinged right then left (yaw 0, straight ahead): the chirality label
    flips, the hinge origin moves to the other side of the camera's y, and the door
    opened to pi/2 sticks out towards the camera on that side of the image."""
    seen = {}
    for sides in ("right", "left"):
        spec, _ = bench.make_object(category, "generator", sides, 1, 0)
        spec = spec.model_copy(
            update={"pose": Pose(x=2.4, y=0.0, z=-0.2, yaw=0.0), "configuration": math.pi / 2}
        )
        obj = bench.build(spec)
        labels = image_labels(spec.label_spec(), obj, np.array([math.pi / 2]))
        with make_backend("raycast", bench.CAMERA) as backend:
            depth = backend.render_many(obj, np.array([[math.pi / 2]]))[0].depth
        nearest = np.where(depth > 0, depth, np.inf)
        column = float(np.unravel_index(np.argmin(nearest), depth.shape)[1])
        seen[sides] = (labels["chirality"], labels["j0_origin_y"], column)
    assert seen["right"][0] == 1 and seen["left"][0] == -1
    assert seen["right"][1] < 0 < seen["left"][1]  # +y is the camera's left
    assert seen["right"][2] > bench.CAMERA.cx > seen["left"][2]  # image right: u > cx


def _png_bytes(depth_mm: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(depth_mm).save(buffer, format="PNG")
    return buffer.getvalue()


@pytest.mark.parametrize("category", ["microwave", "cabinet", *NEW])
def test_same_seed_same_images_and_labels(bench: ModuleType, category: str) -> None:
    """Two objects generated and rendered twice: the same PNG bytes and labels; another
    seed gives other objects. The whole object stays inside the image."""
    runs = []
    for seed in (7, 7, 8):
        with make_backend("raycast", bench.CAMERA) as backend:
            out = []
            for index in range(2):
                spec, obj = bench.make_object(category, "table_a1", "both", seed, index)
                image = bench.render(spec, obj, seed, backend)
                assert image.depth_mm.dtype == np.uint16
                assert image.depth_mm.shape == (480, 640)
                rows, cols = np.nonzero(image.depth_mm)
                assert rows.size > 1000
                assert rows.min() > 0 and rows.max() < 479 and cols.min() > 0 and cols.max() < 639
                assert list(image.labels) == label_columns(spec.dof)
                out.append((spec.model_dump_json(), _png_bytes(image.depth_mm), image.labels))
        runs.append(out)
    assert runs[0] == runs[1]
    assert runs[0][0][0] != runs[2][0][0]


def test_sizes_and_distributions(bench: ModuleType) -> None:
    """Microwaves within Table A.1's ranges; cabinets of Table A.1 or of the generator's
    half sizes; configuration in [0, pi/2], yaw in [-pi/4, pi/4]; sides alternate."""
    for sizes, ranges in bench.CABINET_SIZES.items():
        for index in range(8):
            spec, _ = bench.make_object("cabinet", sizes, "both", 2, index)
            for key in ("depth", "width", "height"):
                assert ranges[key][0] <= getattr(spec, key) <= ranges[key][1]
            assert spec.chirality == (1 if index % 2 == 0 else -1)
    for index in range(8):
        spec, _ = bench.make_object("microwave", "table_a1", "left", 2, index)
        for key, (lo, hi) in bench.MICROWAVE_SIZES.items():
            assert lo <= getattr(spec, key) <= hi
        assert spec.chirality == -1
        assert 0.0 <= spec.configuration <= math.pi / 2
        assert abs(spec.pose.yaw) <= math.pi / 4
    for category in NEW:
        ranges = bench.SIZES.get(category, bench.CABINET_SIZES["table_a1"])
        for index in range(8):
            spec, _ = bench.make_object(category, "table_a1", "both", 2, index)
            for key, (lo, hi) in ranges.items():
                assert lo <= getattr(spec, key) <= hi, (category, key)
            upper = 0.4 if category == "drawer" else math.pi / 2
            assert all(0.0 <= q <= upper for q in spec.q()) and len(spec.q()) == spec.dof
            assert abs(spec.pose.yaw) <= math.pi / 4


def test_table_a2_placement_moves_the_height_only(bench: ModuleType) -> None:
    """`--placement table_a2`: the same object, distance and y as the default placement,
    its base's height inside Table A.2's range wherever the image allows one there (else
    at the allowed height nearest the range), and still inside the image."""
    for category in ("drawer", "refrigerator", "cabinet"):
        low, high = bench.table_a2_height(category)
        inside = 0
        for index in range(12):
            frame, _ = bench.make_object(category, "table_a1", "both", 0, index)
            spec, obj = bench.make_object(category, "table_a1", "both", 0, index, "bench",
                                          "table_a2")  # fmt: skip
            moved = spec.model_copy(update={"pose": frame.pose.model_copy(
                update={"z": spec.pose.z})})  # fmt: skip
            assert moved == spec  # only z differs
            corners = bench._corners(obj, spec.q())
            window = bench._window(corners, spec.pose.x, 2)
            assert window[0] - 1e-9 <= spec.pose.z <= window[1] + 1e-9
            if window[0] <= high and window[1] >= low:
                assert low - 1e-9 <= spec.pose.z <= high + 1e-9
                inside += 1
            else:  # the window's end nearest the range
                assert spec.pose.z == pytest.approx(window[1] if window[1] < low else window[0])
        assert inside > 0 or category == "refrigerator", category


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An evaluate-mdn-like folder: errors.csv with the network's ("Ours") and the refined
    ("Ours + refinement") rows."""
    folder = tmp_path_factory.mktemp("report")
    (folder / "errors.csv").write_text(
        "method,image,object_id,position_cm,rotation_deg,configuration\n"
        "Mean,0,1,50.0,1.0,1.0\nOurs,0,1,2.0,1.0,1.0\nOurs,1,1,6.0,1.0,1.0\n"
        "Ours,2,2,4.0,1.0,1.0\nOurs + refinement,0,1,1.0,1.0,1.0\n"
        "Ours + refinement,1,1,3.0,1.0,1.0\n"
    )
    return folder


def test_tiny_end_to_end_writes_both_csvs(
    bench: ModuleType, tiny_model: Path, report: Path, tmp_path: Path
) -> None:
    """Two microwaves (one per side) predicted by the tiny model through predict's code
    path: errors.csv (one row per image) and summary.csv with the exact columns, the
    withheld median read from the report; the same images and labels again."""
    outs = [tmp_path / "a", tmp_path / "b"]
    for out in outs:
        argv = ["--category", "microwave", "--objects", "2", "--seed", "0", "--no-refine",
                "--model", str(tiny_model), "--report", str(report), "--out", str(out)]  # fmt: skip
        assert bench.main(argv) == 0
    out = outs[0]
    errors = read_csv(out / "errors.csv")
    assert tuple(errors[0]) == bench.ERROR_COLUMNS
    assert [r[2] for r in errors[1:]] == ["right", "left"]
    for row in errors[1:]:
        assert float(row[5]) >= 0 and float(row[8]) >= 0
        assert row[9] in ("0", "1") and row[10] in ("0", "1")
        assert "not the training camera" in row[11]  # reprojected, as predict does
    summary = read_csv(out / "summary.csv")
    assert tuple(summary[0]) == bench.SUMMARY_COLUMNS
    assert [r[1] for r in summary[1:]] == ["right", "left", "both"]
    both = dict(zip(summary[0], summary[-1], strict=True))
    assert both["images"] == "2" and both["withheld_axis_position_cm_median"] == "4.0"
    assert both["estimator"] == "Ours"  # --no-refine: the network's, against its withheld rows
    assert float(both["ratio"]) == pytest.approx(float(both["axis_position_cm_median"]) / 4.0, 1e-3)
    labels = read_csv(out / "labels.csv")
    assert labels[0] == ["image", "object_id", "side", *label_columns(1)]
    camera = (out / "camera.json").read_text()
    assert '"frame_id"' in camera
    for name in ("labels.csv", "objects.jsonl", "camera.json", "images/000000.png",
                 "images/000001.png"):  # fmt: skip
        assert (outs[0] / name).read_bytes() == (outs[1] / name).read_bytes(), name


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"--category": "lamp"}, "--category"),
        ({"--category": "drawer", "--sides": "left"}, "no hinge side"),
        ({"--objects": "0"}, "--objects"),
        ({"--model": "no/such/model"}, "--model"),
        ({"--sides": "up"}, "--sides"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    bench: ModuleType,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    change: dict[str, str],
    message: str,
) -> None:
    """Checked in order, before anything is written (the model last: missing here)."""
    args = {"--category": "microwave", "--objects": "1", "--model": str(tmp_path / "none.pt"),
            "--out": str(tmp_path / "out")}  # fmt: skip
    args.update(change)
    argv = [x for pair in args.items() for x in pair]
    assert bench.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "out").exists()


def test_report_of_another_category_exits_2(
    bench: ModuleType, tiny_model: Path, report: Path, tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    other = tmp_path / "report"
    other.mkdir()
    (other / "errors.csv").write_bytes((report / "errors.csv").read_bytes())
    (other / "manifest.json").write_text('{"config": {"category": {"name": "cabinet"}}}')
    argv = ["--category", "microwave", "--objects", "1", "--model", str(tiny_model),
            "--report", str(other), "--out", str(tmp_path / "out")]  # fmt: skip
    assert bench.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "an evaluation of cabinet" in err[0], err
    assert bench.withheld_median(report, "microwave", refine=False) == 4.0  # "Ours" rows only
    assert bench.withheld_median(report, "microwave") == 2.0  # "Ours + refinement" rows


@pytest.mark.parametrize("category", NEW)
def test_tiny_end_to_end_new_categories(bench: ModuleType, category: str, tmp_path: Path) -> None:
    """One object of each new category predicted by the shipped model of its category
    (the network's estimate): one row per image in errors.csv, one summary row, "both",
    with the exact columns (the withheld median left empty without a report); the
    two-door categories' labels.csv has both joints' columns."""
    out = tmp_path / category
    argv = ["--category", category, "--objects", "1", "--seed", "3", "--no-refine",
            "--model", str(ROOT / "models" / "mdn" / category), "--out", str(out)]  # fmt: skip
    assert bench.main(argv) == 0
    errors = read_csv(out / "errors.csv")
    assert tuple(errors[0]) == bench.ERROR_COLUMNS
    assert [r[2] for r in errors[1:]] == ["right" if category == "refrigerator" else "none"]
    assert float(errors[1][5]) >= 0 and errors[1][9] in ("0", "1")
    summary = read_csv(out / "summary.csv")
    assert tuple(summary[0]) == bench.SUMMARY_COLUMNS
    expected_sides = ["right"] if category == "refrigerator" else ["both"]
    assert [r[1] for r in summary[1:]] == expected_sides
    row = dict(zip(summary[0], summary[1], strict=True))
    assert row["category"] == category and row["images"] == "1" and row["estimator"] == "Ours"
    assert row["withheld_axis_position_cm_median"] == "" and row["ratio"] == ""
    dof = 2 if category in ("cabinet2", "refrigerator") else 1
    assert read_csv(out / "labels.csv")[0] == ["image", "object_id", "side", *label_columns(dof)]
