"""artic.hierarchy.canonical: a scan's yaw (its dominant vertical planes, then its front),
the rotations about z, and infer_hierarchy's `yaw` option (issue 18, item 4)."""

from __future__ import annotations

import dataclasses
import json
import math
import sys
import typing
from pathlib import Path

import numpy as np
import pytest
import torch

from artic.artifacts.manifest import read_manifest
from artic.artifacts.ply import read_ply, write_ply
from artic.artifacts.scan_dataset import ScanDataset
from artic.errors import InputError
from artic.hierarchy.canonical import (
    FRONT_WEIGHTS,
    MIN_POINTS,
    PROFILE_WEIGHTS,
    YawConfig,
    canonical_yaw,
    fit_front_weights,
    front_example,
    front_probabilities,
    rotate_tree_z,
    rotate_z,
    yaw_config,
)
from artic.hierarchy.gnn import GraphLabellingNet
from artic.hierarchy.infer import HierarchyConfig, infer_hierarchy, segment_scan
from artic.hierarchy.segmentation import InferenceConfig, PartSegmentationNet
from artic.objects.tree import JointAxis, KinematicTree
from box_clouds import box_surface
from cli_runner import run_cli
from tiny_scans import tiny_hierarchy_scans

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "cli"))
from test_infer_hierarchy import save_models, tiny_labeller, tiny_segmenter

#: yaws (degrees) the fixtures are turned by: all four quadrants, near the 45-degree
#: ambiguity of the planes and on both sides of +-180
YAWS = (0.0, 7.5, 30.0, 44.0, 46.0, 89.0, 135.0, 179.5, -179.5, -120.0, -60.0, -3.0)


def angle_gap(a: float, b: float, period: float) -> float:
    """|a - b| modulo `period` (degrees), in [0, period / 2]."""
    return abs((a - b + period / 2) % period - period / 2)


def closed_box(n: int = 4000, seed: int = 0) -> np.ndarray:
    """A closed 0.5 x 1.0 x 0.8 m box surface: its planes fix the yaw only modulo 90."""
    return box_surface([-0.25, -0.5, 0.0], [0.25, 0.5, 0.8], n, np.random.default_rng(seed))


def cabinet(n: int = 6000, seed: int = 0, door_deg: float = 40.0) -> np.ndarray:
    """A cabinet in artic's object frame (docs/objects.md): a shell of 2 cm panels open at
    the front (x = -0.2), a shelf, and a door hinged on the front's -y edge, ajar by
    `door_deg` towards -x, with a bar handle near its free edge. Points on every
    surface, as many per box as its area gives."""
    rng = np.random.default_rng(seed)
    panels = [
        ([0.18, -0.3, 0.0], [0.2, 0.3, 0.8]),  # back
        ([-0.2, -0.3, 0.0], [0.2, -0.28, 0.8]),  # sides
        ([-0.2, 0.28, 0.0], [0.2, 0.3, 0.8]),
        ([-0.2, -0.3, 0.78], [0.2, 0.3, 0.8]),  # top, bottom
        ([-0.2, -0.3, 0.0], [0.2, 0.3, 0.02]),
        ([-0.2, -0.28, 0.39], [0.18, 0.28, 0.41]),  # shelf
    ]
    door = [([-0.02, 0.0, 0.02], [0.0, 0.58, 0.78]), ([-0.05, 0.5, 0.3], [-0.03, 0.52, 0.5])]
    boxes = panels + door
    sizes = np.array([np.subtract(hi, lo) for lo, hi in boxes])
    areas = 2 * (sizes[:, 0] * sizes[:, 1] + sizes[:, 1] * sizes[:, 2] + sizes[:, 0] * sizes[:, 2])
    counts = np.maximum((n * areas / areas.sum()).astype(int), 20)
    clouds = [box_surface(lo, hi, c, rng) for (lo, hi), c in zip(boxes, counts, strict=True)]
    hinge = np.array([-0.2, -0.29, 0.0])
    moving = rotate_z(np.concatenate(clouds[len(panels) :]), math.radians(door_deg)) + hinge
    return np.concatenate([*clouds[: len(panels)], moving]).astype(np.float32)


def chair(swivel_deg: float, n: int = 6000, seed: int = 0) -> np.ndarray:
    """An office chair in artic's object frame (objects/structures/office_chair.py): four
    legs along +-x and +-y, a tube, and a seat with its back (behind it, at +x when the seat
    is not turned) swivelled by `swivel_deg` about z."""
    rng = np.random.default_rng(seed)
    legs = [([0.0, -0.02, 0.05], [0.3, 0.02, 0.09])]
    legs = [(rotate_z(np.array(lo), k * math.pi / 2), rotate_z(np.array(hi), k * math.pi / 2))
            for k in range(4) for lo, hi in legs]  # fmt: skip
    base = [(np.minimum(lo, hi), np.maximum(lo, hi)) for lo, hi in legs]
    base.append((np.array([-0.03, -0.03, 0.09]), np.array([0.03, 0.03, 0.45])))  # tube
    seat = [([-0.23, -0.24, 0.45], [0.23, 0.24, 0.52]), ([0.2, -0.21, 0.52], [0.23, 0.21, 1.0])]
    counts = [400] * len(base) + [n // 2, n // 2]
    clouds = [box_surface(list(lo), list(hi), c, rng)
              for (lo, hi), c in zip([*base, *seat], counts, strict=True)]  # fmt: skip
    turned = rotate_z(np.concatenate(clouds[len(base) :]), math.radians(swivel_deg))
    return np.concatenate([*clouds[: len(base)], turned]).astype(np.float32)


@pytest.mark.parametrize("swivel_deg", (0.0, 27.0, -100.0))
def test_the_yaw_settings_and_an_office_chair_aligned_by_its_legs(swivel_deg: float) -> None:
    """Each category's yaw settings (`yaw_config`) and the weights they name; the office
    chair's yaw step reads the planes of its legs, the default settings the seat's, which
    swivels."""
    settings = yaw_config("office_chair")
    assert settings.profile == "office_chair" and yaw_config("storage_furniture") == YawConfig()
    assert yaw_config("lamp") == YawConfig(profile="lamp")
    assert set(PROFILE_WEIGHTS) == set(typing.get_args(typing.get_type_hints(YawConfig)["profile"]))
    assert all(w.shape == FRONT_WEIGHTS.shape for w in PROFILE_WEIGHTS.values())
    points = chair(swivel_deg)
    for yaw_deg in (12.0, -75.0, 160.0):
        turned = rotate_z(points, math.radians(yaw_deg))
        estimate = canonical_yaw(turned, settings)
        assert angle_gap(math.degrees(estimate.plane_yaw), yaw_deg, 90.0) < 0.5
        if swivel_deg == 27.0:  # the seat's own planes are 27 degrees off the legs'
            default = canonical_yaw(turned)
            assert angle_gap(math.degrees(default.plane_yaw), yaw_deg, 90.0) > 5.0


@pytest.mark.parametrize("camera", ("kinect_v1", "kinect_v1_128"))
def test_an_office_chair_scan_comes_back_to_the_side_it_was_taken_from(
    tmp_path: Path, tmp_path_factory: pytest.TempPathFactory, camera: str
) -> None:
    """A swivelling chair's legs do not say which side is its front, its scan does: the
    chair's weights turn a noisy scan (views within 70 degrees of the object frame's -x,
    by the real stages) back to that frame, with the full Kinect or its 128-pixel camera;
    storage furniture's weights do not."""
    objects = tiny_hierarchy_scans(tmp_path_factory, "office_chair").objects
    scans = tmp_path / "scans"
    code, _, err = run_cli("render-depth", "render=scan", "debug=tiny", f"camera={camera}",
                           "render.configurations=2", "render.preview_images=0",
                           f"dataset={objects}", f"out={scans}")  # fmt: skip
    assert code == 0, err
    ds = ScanDataset.open_category(scans, "office_chair")
    rows = [r for s in ("train", "test") for r in ds.select(s, ["noisy"], ds.object_ids(s))]
    chair_settings = yaw_config("office_chair")
    sf_settings = dataclasses.replace(chair_settings, profile="storage_furniture")
    right = {"chair": 0, "storage furniture": 0}
    for row in rows:
        points = ds.cloud(row).points
        for yaw_deg in (12.0, -75.0, 160.0):
            turned = rotate_z(points, math.radians(yaw_deg))
            for name, settings in (("chair", chair_settings), ("storage furniture", sf_settings)):
                estimate = canonical_yaw(turned, settings)
                right[name] += angle_gap(estimate.yaw_deg, yaw_deg, 360.0) < 5
    n = 3 * len(rows)
    assert n == 36 and right["chair"] >= 0.8 * n > right["storage furniture"], right


@pytest.mark.parametrize("yaw_deg", YAWS)
def test_a_box_turned_by_any_yaw_is_aligned_modulo_90(yaw_deg: float) -> None:
    points = closed_box()
    estimate = canonical_yaw(rotate_z(points, math.radians(yaw_deg)))
    assert angle_gap(math.degrees(estimate.plane_yaw), yaw_deg, 90.0) < 0.1
    assert angle_gap(estimate.yaw_deg, yaw_deg, 90.0) < 0.1
    assert -45.0 <= math.degrees(estimate.plane_yaw) < 45.0
    assert 0.5 < estimate.plane_confidence <= 1.0
    probabilities = estimate.side_probabilities
    assert probabilities.shape == (4,) and math.isclose(probabilities.sum(), 1.0)
    assert estimate.front_confidence == probabilities.max()


@pytest.mark.parametrize("door_deg", [20.0, 40.0, 80.0])
def test_a_cabinet_turned_by_any_yaw_comes_back_to_its_object_frame(door_deg: float) -> None:
    points = cabinet(door_deg=door_deg)
    for yaw_deg in YAWS:
        turned = rotate_z(points, math.radians(yaw_deg))
        estimate = canonical_yaw(turned)
        assert angle_gap(estimate.yaw_deg, yaw_deg, 360.0) < 0.5, (door_deg, yaw_deg)
        assert estimate.front_confidence > 0.9
        back = rotate_z(turned, -estimate.yaw)
        assert np.abs(back - points).max() < 0.01  # metres, at 0.5 deg and 0.8 m away


def test_the_estimate_is_deterministic_and_does_not_change_its_input() -> None:
    points = rotate_z(cabinet(), 1.0)
    copy = points.copy()
    a, b = canonical_yaw(points), canonical_yaw(points)
    assert np.array_equal(points, copy)
    assert a.yaw == b.yaw and a.plane_yaw == b.plane_yaw
    assert np.array_equal(a.side_probabilities, b.side_probabilities)
    assert set(a.to_dict()) == {
        "yaw_deg",
        "plane_yaw_deg",
        "plane_confidence",
        "front_confidence",
        "side_probabilities",
    }


def test_rotate_z_round_trips_and_turns_trees_axes() -> None:
    points = np.random.default_rng(3).normal(size=(50, 3))
    for angle in (0.3, -2.0, math.pi):
        turned = rotate_z(points, angle)
        assert np.allclose(turned[:, 2], points[:, 2])  # about z: heights kept
        assert np.allclose(
            np.linalg.norm(turned[:, :2], axis=1), np.linalg.norm(points[:, :2], axis=1)
        )
        assert np.allclose(rotate_z(turned, -angle), points, atol=1e-12)
    assert np.allclose(rotate_z(np.array([1.0, 0.0, 0.5]), math.pi / 2), [0.0, 1.0, 0.5])
    axis = JointAxis(origin=np.array([-0.2, -0.3, 0.0]), direction=np.array([0.0, 0.6, 0.8]))
    tree = KinematicTree(3, 0, ((0, 1), (0, 2)), (0, 1, 0), ("revolute", "fixed"), (axis, None))
    turned_tree = rotate_tree_z(tree, 0.7)
    assert turned_tree.edges == tree.edges and turned_tree.axes is not None
    turned_axis = turned_tree.axes[0]
    assert turned_axis is not None and turned_tree.axes[1] is None
    assert np.allclose(turned_axis.origin, rotate_z(axis.origin, 0.7))
    assert np.allclose(turned_axis.direction, rotate_z(axis.direction, 0.7))
    back = rotate_tree_z(turned_tree, -0.7).axes
    assert back is not None and back[0] is not None
    assert np.allclose(back[0].origin, axis.origin) and np.allclose(
        back[0].direction, axis.direction
    )
    no_axes = KinematicTree(2, 0, ((0, 1),), (0, 2), ("prismatic",))
    assert rotate_tree_z(no_axes, 1.0) == no_axes


def test_bad_input_raises_input_error() -> None:
    points = cabinet(200)
    nan = points.copy()
    nan[5, 1] = np.nan
    with pytest.raises(InputError, match="NaN"):
        canonical_yaw(nan)
    with pytest.raises(InputError, match="too few"):
        canonical_yaw(points[: MIN_POINTS - 1])
    with pytest.raises(InputError, match=r"\(N, 3\)"):
        canonical_yaw(points[:, :2])
    inf = points.copy()
    inf[0, 0] = np.inf
    with pytest.raises(InputError):
        canonical_yaw(inf)


Nets = tuple[PartSegmentationNet, GraphLabellingNet]


@pytest.fixture(scope="module")
def nets() -> Nets:
    torch.set_num_threads(1)
    return tiny_segmenter(), tiny_labeller().eval()


CFG = HierarchyConfig(segmentation=InferenceConfig(n_points=512, min_confidence=0.0))


def test_infer_hierarchy_gives_the_same_tree_for_a_scan_and_its_turned_copy(nets: Nets) -> None:
    points = cabinet(3000)
    base = infer_hierarchy(points, *nets, CFG, np.random.default_rng(0))
    assert base.yaw is not None and angle_gap(base.yaw.yaw_deg, 0.0, 360.0) < 0.5
    for yaw_deg in (63.0, -150.0):
        angle = math.radians(yaw_deg)
        turned = infer_hierarchy(rotate_z(points, angle), *nets, CFG, np.random.default_rng(0))
        assert turned.yaw is not None
        assert angle_gap(turned.yaw.yaw_deg, yaw_deg, 360.0) < 0.5
        a, b = base.tree, turned.tree
        assert (a.num_parts, a.root, a.edges, a.motion_types, a.joint_types) == (
            b.num_parts,
            b.root,
            b.edges,
            b.motion_types,
            b.joint_types,
        )
        assert np.mean(base.part_id == turned.part_id) > 0.99
        # axes and centroids come back in the turned scan's frame
        assert np.allclose(
            turned.hierarchy.graph.centroids,
            rotate_z(base.hierarchy.graph.centroids, angle),
            atol=0.01,
        )
        for axis_a, axis_b in zip(a.axes or (), b.axes or (), strict=True):
            if axis_a is None or axis_b is None:
                assert axis_a is axis_b
                continue
            assert abs(np.dot(rotate_z(axis_a.direction, angle), axis_b.direction)) > 0.99


def test_yaw_none_leaves_the_scan_in_its_frame(nets: Nets) -> None:
    points = cabinet(3000)
    cfg = HierarchyConfig(CFG.segmentation, yaw="none")
    result = infer_hierarchy(points, *nets, cfg, np.random.default_rng(0))
    assert result.yaw is None and result.segmentation.yaw is None
    seg = segment_scan(points, nets[0], cfg, np.random.default_rng(0))
    assert np.array_equal(seg.part_id, result.part_id)
    canonical = segment_scan(points, nets[0], CFG, np.random.default_rng(0))
    assert canonical.yaw is not None and "yaw" in canonical.timings


def test_infer_hierarchy_cli_yaw_option_and_its_record(tmp_path: Path) -> None:
    seg, lab = save_models(tmp_path / "models")
    scan = tmp_path / "turned cabinet.ply"
    write_ply(scan, rotate_z(cabinet(3000), math.radians(120.0)).astype(np.float32))
    models = ["--segmenter", str(seg), "--labeller", str(lab)]
    outputs, outputs_err = {}, {}
    for mode in ("canonical", "none"):
        out = tmp_path / mode
        code, _, err = run_cli(
            "infer-hierarchy", str(scan), "--out", str(out), *models, "--yaw", mode
        )
        assert code == 0, err
        document = json.loads((out / "hierarchy.json").read_text())
        record = document["input"]["yaw"]
        assert record["mode"] == mode
        assert read_manifest(out, expected_stage="infer-hierarchy").config["yaw"] == mode
        outputs[mode] = document, read_ply(out / "parts.ply")
        outputs_err[mode] = err
    record = outputs["canonical"][0]["input"]["yaw"]
    assert angle_gap(record["yaw_deg"], 120.0, 360.0) < 0.5
    assert 0.0 <= record["front_confidence"] <= 1.0 and len(record["side_probabilities"]) == 4
    assert set(outputs["none"][0]["input"]["yaw"]) == {"mode"}
    for _, cloud in outputs.values():  # parts.ply keeps the input points, in the input frame
        assert np.allclose(cloud.points, read_ply(scan).points)
    code, _, err = run_cli(
        "infer-hierarchy", str(scan), "--out", str(tmp_path / "x"), "--yaw", "up"
    )
    assert code == 2 and "--yaw" in err
    assert "front is uncertain" not in outputs_err["canonical"]
    box = tmp_path / "box.ply"  # nothing tells a closed box's front: a warning, still a tree
    write_ply(box, closed_box(3000).astype(np.float32))
    code, _, err = run_cli("infer-hierarchy", str(box), "--out", str(tmp_path / "b"), *models)
    assert code == 0 and "front is uncertain" in err and "--yaw none" in err
    code, _, err = run_cli("segment", str(box), "--out", str(tmp_path / "s"), "--model", str(seg))
    assert code == 0 and "front is uncertain" in err


def test_front_examples_and_fitted_weights_tell_the_front() -> None:
    rng = np.random.default_rng(5)
    examples = []
    for door_deg in (15.0, 35.0, 60.0, 85.0):
        points = cabinet(2500, seed=int(door_deg), door_deg=door_deg)
        for yaw in rng.uniform(-math.pi, math.pi, 3):
            example = front_example(points, float(yaw))
            estimate = canonical_yaw(rotate_z(points, float(yaw)))
            assert example.features.shape == (4, 4, 8)
            assert np.allclose(example.features[:, 0].sum(axis=1), 1.0)  # every point binned
            assert (example.features[:, 1:].sum(axis=(1, 2)) <= 1.0 + 1e-12).all()
            turn = math.degrees(estimate.plane_yaw) + 90.0 * example.front
            assert angle_gap(turn, math.degrees(yaw), 360.0) < 0.5
            examples.append(example)
    features = np.stack([e.features for e in examples])
    fronts = np.array([e.front for e in examples])
    weights = fit_front_weights(features, fronts)
    assert weights.shape == FRONT_WEIGHTS.shape
    assert np.array_equal(weights, fit_front_weights(features, fronts))  # deterministic
    chosen = [int(np.argmax(front_probabilities(f, weights))) for f in features]
    assert chosen == fronts.tolist()


def test_clouds_without_vertical_planes_get_no_plane_confidence() -> None:
    rng = np.random.default_rng(0)
    line = np.c_[np.linspace(0.0, 1.0, 100), np.zeros(100), np.zeros(100)]
    floor = np.c_[rng.uniform(size=(500, 2)), np.zeros(500)]
    for points in (np.ones((100, 3)), line, floor):
        estimate = canonical_yaw(points)
        assert estimate.plane_confidence == 0.0
        assert -math.pi <= estimate.yaw < math.pi
