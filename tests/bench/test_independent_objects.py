"""bench/independent_objects.py: the independent storage-furniture generator (issue 18,
item 5) writes a folder artic's readers take as a generate-dataset dataset=hierarchy
output, with valid trees, scannable by render-scan, the same bytes for the same seed."""

from __future__ import annotations

import importlib.util
import sys
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from artic.artifacts.manifest import MANIFEST, read_manifest
from artic.artifacts.object_dataset import ObjectDataset, object_dir
from artic.artifacts.output import check_integrity
from artic.artifacts.scan_dataset import ScanDataset
from artic.objects.families import build_object
from artic.objects.structures import STRUCTURES
from artic.objects.tree import MOTION_TYPES, object_tree
from cli_runner import run_cli

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "independent_objects.py"


@pytest.fixture(scope="module")
def generator() -> Iterator[ModuleType]:
    """The script as a module; it registers its category in artic's structure registry,
    which is restored afterwards (other tests check the registry's contents)."""
    spec = importlib.util.spec_from_file_location("independent_objects", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["independent_objects"] = module
    before = set(STRUCTURES)
    spec.loader.exec_module(module)
    yield module
    for name in set(STRUCTURES) - before:
        STRUCTURES.pop(name)
    sys.modules.pop("independent_objects", None)


@pytest.fixture(scope="module", params=["storage_furniture", "lamp", "office_chair"])
def dataset(
    generator: ModuleType, tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest
) -> Path:
    """2 objects of a category, seed 3."""
    out = tmp_path_factory.mktemp("independent") / request.param
    argv = ["--category", request.param, "--objects", "2", "--seed", "3", "--out", str(out)]
    assert generator._generate(argv) == 0
    return out


def _files(root: Path) -> dict[str, bytes]:
    return {
        p.relative_to(root).as_posix(): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name != MANIFEST
    }


def test_artics_reader_takes_it_as_a_hierarchy_dataset(
    generator: ModuleType, dataset: Path
) -> None:
    ds = ObjectDataset.open(dataset)
    assert ds.manifest.stage == "generate-dataset"
    check_integrity(dataset, ds.manifest, ())  # render-scan's hand-edit check passes
    assert ds.category == dataset.name
    assert [(r.object_id, r.split) for r in ds.rows] == [(0, "test"), (1, "test")]
    assert ds.camera.width == 128  # the camera generate-dataset records
    for row in ds.rows:
        spec = ds.spec(row.object_id)
        assert spec.category == generator.GENERATORS[dataset.name].spec_category
        assert type(spec).model_validate_json(spec.model_dump_json()) == spec  # round trip
        ET.parse(ds.urdf(row.object_id))  # URDF and meshes verified against the manifest
        assert ds.tree(row.object_id).dof == row.dof


def test_trees_hold_every_part_with_motion_types_of_their_joints(dataset: Path) -> None:
    ds = ObjectDataset.open(dataset)
    for row in ds.rows:
        obj = build_object(ds.spec(row.object_id))
        tree = ds.tree(row.object_id)
        urdf = ET.parse(ds.urdf(row.object_id)).getroot()
        links = [link.get("name") for link in urdf.iter("link")]
        assert [p.name for p in tree.parts] == links == [link.name for link in obj.links]
        assert tree == object_tree(obj)  # the file is the built object's tree
        kinematic = tree.to_kinematic_tree()  # a valid tree: every part reached once
        assert sorted({0} | {child for _, child in kinematic.edges}) == list(range(len(links)))
        assert tree.motion_types[0] == "static"
        expected = {
            "revolute": "rotating",
            "continuous": "rotating",
            "prismatic": "translating",
            "fixed": "static",
        }
        for (_, child), joint in zip(tree.edges, tree.urdf_joint_types, strict=True):
            assert tree.motion_types[child] == expected[joint]
        roles = [p.role for p in tree.parts]
        if dataset.name == "lamp":  # a chain base -> arm_0 -> ... -> head
            assert list(tree.edges) == [(k, k + 1) for k in range(len(links) - 1)]
            assert roles == ["base"] + ["arm"] * (len(links) - 2) + ["head"]
        elif dataset.name == "office_chair":  # base -> caster -> wheel, base -> column -> seat
            parent_role = {roles[c]: roles[a] for a, c in tree.edges}
            assert all(roles[a] == "caster" for a, c in tree.edges if roles[c] == "wheel")
            assert parent_role.get("seat") in ("base", "column")
            assert parent_role.get("back", "seat") == parent_role.get("armrest", "seat") == "seat"
        else:  # doors and drawers hang on the body
            assert all(parent == 0 for parent, _ in tree.edges) and roles[0] == "body"
            for (_, child), joint in zip(tree.edges, tree.urdf_joint_types, strict=True):
                assert roles[child] == {"revolute": "door", "prismatic": "drawer"}[joint]
        assert [MOTION_TYPES[i] for i in tree.motion_type_ids] == list(tree.motion_types)
        poses = ds.poses(row.object_id).array()
        assert poses.shape == (18, tree.dof)
        limits = np.array([tree.limits[e] for e in tree.movable_edges])
        assert np.all(poses >= limits[:, 0]) and np.all(poses <= limits[:, 1])


def test_fronts_are_panelled_or_flat_and_carry_knobs(generator: ModuleType) -> None:
    """A panelled front is four frame boxes and a recessed panel in one watertight
    solid; every door and drawer has a knob in front of its face (x < 0, link frame)."""
    import trimesh

    from artic.objects.parts import union_mesh

    rng = np.random.default_rng(0)
    spec = generator.sample_independent(generator.IndependentStorageConfig(), 0, rng)
    cell = generator.Cell(height=0.5, content="door", panelled=True)
    boxes, panel = generator._front_boxes((0.0, 0.4), (0.0, 0.6), 0.02, cell, spec.build)
    assert len(boxes) == 5 and panel is not None and panel.x[0] == spec.build.recess
    mesh = union_mesh(boxes)
    assert trimesh.Trimesh(mesh.vertices, mesh.triangles).is_watertight
    for index in range(6):
        rng = np.random.default_rng([7, index])
        cfg = generator.IndependentStorageConfig()
        obj = build_object(generator.sample_independent(cfg, index, rng))
        for link in obj.links[1:]:
            assert link.role in ("door", "drawer") and link.mesh.vertices[:, 0].min() < -0.01
        assert obj.links[0].mesh.vertices[:, 2].min() == 0.0  # plinth or legs on the floor


def test_render_scan_scans_it(generator: ModuleType, dataset: Path, tmp_path: Path) -> None:
    """artic render-scan (in this process, where the category is registered) scans the
    objects; every point's label is a part of the tree with that part's motion type."""
    scans = tmp_path / "scans"
    code, _, err = run_cli(
        "render-scan", "debug=tiny", "camera=kinect_v1_128", "render.configurations=1",
        "render.views.views=2", "render.clean_points=2000", "render.fusion.max_points=1500",
        "render.preview_images=0", "noise.dropout=0.02", f"dataset={dataset}", f"out={scans}",
    )  # fmt: skip
    assert code == 0, err
    ds = ScanDataset.open_category(scans, dataset.name)
    assert ds.object_ids("test") == [0, 1]
    for row in ds.select("test"):
        cloud = ds.cloud(row)
        tree = ds.tree(row.object_id)
        assert cloud.part_id is not None and cloud.motion_type is not None
        assert len(cloud.points) > 100 and cloud.part_id.max() < tree.num_parts
        motion = np.asarray(tree.motion_types)
        assert np.array_equal(cloud.motion_type, motion[cloud.part_id])


def test_same_seed_same_bytes(generator: ModuleType, dataset: Path, tmp_path: Path) -> None:
    again, other = tmp_path / "again", tmp_path / "other"
    argv = ["--category", dataset.name, "--objects", "2", "--out"]
    assert generator._generate([*argv, str(again), "--seed", "3"]) == 0
    assert _files(again) == _files(dataset)
    assert read_manifest(again).content_hash == read_manifest(dataset).content_hash
    assert generator._generate([*argv, str(other), "--seed", "4"]) == 0
    spec = f"{object_dir(0)}/spec.json"
    assert _files(other)[spec] != _files(dataset)[spec]


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (["--category", "microwave"], "--category"),
        (["--objects", "0"], "--objects"),
        (["--seed", "-1"], "--seed"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    generator: ModuleType,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    args: list[str],
    field: str,
) -> None:
    out = tmp_path / "objects"
    argv = ["--objects", "1", "--seed", "0", "--out", str(out), *args]  # the last one wins
    assert generator._generate(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and field in err
    assert not out.exists() and not list(tmp_path.glob(".objects.partial-*"))


def test_a_non_empty_out_is_refused(
    generator: ModuleType, dataset: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    before = _files(dataset)
    argv = ["--objects", "1", "--out", str(dataset)]
    assert generator._generate(argv) == 2
    assert "--out" in capsys.readouterr().err and _files(dataset) == before


def test_lamps_stand_on_the_floor_with_the_shade_facing_forwards(generator: ModuleType) -> None:
    for index in range(6):
        rng = np.random.default_rng([7, index])
        cfg = generator.IndependentLampConfig()
        obj = build_object(generator.sample_independent_lamp(cfg, index, rng))
        poses = obj.link_poses(np.zeros(obj.dof))
        assert obj.links[0].mesh.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-9)
        head = obj.links[-1].mesh.vertices @ poses[-1][:3, :3].T + poses[-1][:3, 3]
        assert head[:, 0].min() < poses[-1][0, 3] - 0.05  # the mouth is in front of its joint
        assert 1 + len(obj.joints) == len(obj.links) and obj.dof == len(obj.joints)


def test_chairs_stand_on_their_feet(generator: ModuleType) -> None:
    """At rest no part goes below the floor and a glide, leg or wheel touches it; a
    caster (and its wheel) per leg, or none."""
    for index in range(6):
        rng = np.random.default_rng([7, index])
        cfg = generator.IndependentChairConfig()
        spec = generator.sample_independent_chair(cfg, index, rng)
        obj = build_object(spec)
        poses = obj.link_poses(np.zeros(obj.dof))
        lowest = min(
            float((link.mesh.vertices @ pose[:3, :3].T + pose[:3, 3])[:, 2].min())
            for link, pose in zip(obj.links, poses, strict=True)
        )
        assert lowest == pytest.approx(0.0, abs=1e-6)
        roles = [link.role for link in obj.links]
        casters = spec.legs if spec.feet == "casters" else 0
        assert roles.count("caster") == roles.count("wheel") == casters
        assert roles.count("seat") == 1 and roles.count("armrest") in (0, 2)


def test_a_malformed_argument_exits_2_with_one_line(
    generator: ModuleType, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as done:
        generator._generate(["--objects", "x", "--out", str(tmp_path / "objects")])
    err = capsys.readouterr().err.strip()
    assert done.value.code == 2 and len(err.splitlines()) == 1 and "--objects" in err


def test_render_scan_through_the_script_passes_artics_exit_code(
    generator: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(sys, "argv", list(sys.argv))  # the wrapper sets sys.argv
    args = [f"dataset={tmp_path / 'missing'}", f"out={tmp_path / 'scans'}"]
    assert generator._render_scan(args) == 2
    assert not (tmp_path / "scans").exists()
