"""Chapter 4 categories with varying kinematic trees: structure, trees, poses, URDF, CLI."""

from __future__ import annotations

import json
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pybullet
import pytest
import trimesh
import yaml
import yourdfpy
from pydantic import ValidationError
from typer.testing import CliRunner

from artic.cli.main import app
from artic.objects.categories import CATEGORIES
from artic.objects.structures import (
    STRUCTURES,
    StructureConfig,
    StructureSpec,
    build_structure,
    get_structure,
    parse_structure_spec,
    register_structure,
    sample_structure,
)
from artic.objects.tree import (
    MOTION_TYPES,
    ArticulatedPoses,
    KinematicTree,
    ObjectTree,
    object_tree,
    sample_configurations,
)
from artic.objects.urdf import write_urdf
from urdf_folder import write_urdf_folder

CATEGORY_DIR = Path(__file__).resolve().parents[2] / "conf" / "common" / "category"
NAMES = ("storage_furniture", "lamp", "office_chair")
SEEDS = range(12)


@pytest.fixture(scope="module")
def configs() -> dict[str, StructureConfig]:
    return {
        name: get_structure(name).config.model_validate(
            yaml.safe_load((CATEGORY_DIR / f"{name}.yaml").read_text())
        )
        for name in NAMES
    }


def _spec(configs: dict[str, StructureConfig], name: str, seed: int) -> StructureSpec:
    return sample_structure(configs[name], seed, np.random.default_rng(seed))


@pytest.fixture(scope="module")
def client() -> Iterator[int]:
    cid = pybullet.connect(pybullet.DIRECT)
    yield cid
    pybullet.disconnect(physicsClientId=cid)


def test_registry_is_separate_from_the_appendix_a_categories() -> None:
    assert set(STRUCTURES) == set(NAMES)
    assert not set(STRUCTURES) & set(CATEGORIES)
    with pytest.raises(KeyError, match="known varying-structure categories: lamp"):
        get_structure("sofa")
    with pytest.raises(ValueError, match="already registered"):
        entry = STRUCTURES["lamp"]
        register_structure("lamp", entry.config, entry.spec, entry.sample)(entry.build)


@pytest.mark.parametrize("name", NAMES)
def test_structures_vary_across_seeds(configs: dict[str, StructureConfig], name: str) -> None:
    shapes = set()
    for seed in SEEDS:
        tree = object_tree(build_structure(_spec(configs, name, seed)))
        axes = tuple(None if a is None else a.direction for a in tree.axes)
        shapes.add((tree.edges, tree.joint_types, tuple(p.role for p in tree.parts), axes))
    assert len(shapes) >= 4, f"{name}: only {len(shapes)} distinct trees in {len(SEEDS)} objects"


def test_storage_furniture_counts_of_drawers_and_doors_vary(
    configs: dict[str, StructureConfig],
) -> None:
    counts = set()
    for seed in SEEDS:
        spec = _spec(configs, "storage_furniture", seed)
        links = build_structure(spec).links
        roles = [link.role for link in links]
        moving = roles.count("drawer") + roles.count("door")
        assert moving >= 1 and len(roles) == moving + 1  # body + doors/drawers, no handle links
        counts.add((roles.count("drawer"), roles.count("door")))
        # each door/drawer link carries its handle: its mesh stands out of the front panel
        p = spec.parts
        for link in links[1:]:
            depth = np.ptp(link.mesh.vertices[:, 0])
            if link.role == "door":
                assert depth == pytest.approx(
                    p.door_thickness + p.handle_standoff + p.handle_thickness
                )
            else:
                assert depth > p.handle_standoff + p.handle_thickness
    assert len(counts) >= 4


def test_aligned_layouts_stack_compartments_in_columns(
    configs: dict[str, StructureConfig],
) -> None:
    """`layout.aligned`: every row takes the bottom row's column widths; with
    `uniform_row` = 1 each column holds one kind (a stack of drawers, say); at 0 the rows
    split on their own (so, over seeds, some object has rows of different splits)."""
    base = configs["storage_furniture"]

    def variant(aligned: float, uniform: float) -> StructureConfig:
        layout = base.layout.model_copy(update={"aligned": aligned, "uniform_row": uniform})
        return base.model_copy(update={"layout": layout})

    stacked, free = variant(1.0, 1.0), variant(0.0, 0.0)
    stacks = 0
    for seed in SEEDS:
        spec = sample_structure(stacked, seed, np.random.default_rng(seed))
        widths = [tuple(c.width for c in row.compartments) for row in spec.rows]
        assert all(w == widths[0] for w in widths)
        for j in range(len(widths[0])):
            assert len({row.compartments[j].content for row in spec.rows}) == 1
        stacks += len(spec.rows) > 1
        build_structure(spec)  # geometry and joints still valid
    assert stacks >= 3
    splits = [
        len({len(r.compartments) for r in sample_structure(free, s, np.random.default_rng(s)).rows})
        for s in SEEDS
    ]
    assert max(splits) > 1


@pytest.mark.parametrize("name", NAMES)
def test_every_tree_is_valid_with_a_single_root(
    configs: dict[str, StructureConfig], name: str
) -> None:
    for seed in SEEDS:
        obj = build_structure(_spec(configs, name, seed))
        tree = object_tree(obj)
        parents = tree.parents()
        assert tree.num_parts == len(obj.links) and tree.root == 0
        assert list(parents).count(-1) == 1 and parents[0] == -1
        assert len(tree.edges) == tree.num_parts - 1
        assert all(parents[c] == p and p < c for p, c in tree.edges)  # depth-first order
        assert tree.dof == obj.dof >= 1
        for (_, child), kind, axis in zip(
            tree.edges, tree.urdf_joint_types, tree.axes, strict=True
        ):
            expected = {"fixed": 0, "revolute": 1, "continuous": 1, "prismatic": 2}[kind]
            assert tree.motion_type_ids[child] == expected
            assert (axis is None) == (kind == "fixed")
            if axis is not None:
                assert np.linalg.norm(axis.direction) == pytest.approx(1.0)
        # the Chapter 4 library reads tree.json as its KinematicTree
        graph = KinematicTree.from_dict(json.loads(tree.model_dump_json()))
        assert graph.edges == tree.edges and graph.motion_types == tree.motion_type_ids
        assert tree.to_kinematic_tree().joint_types == tree.joint_types
        assert ObjectTree.model_validate_json(tree.model_dump_json()) == tree
    assert MOTION_TYPES == ("static", "rotating", "translating", "both")


def test_motion_types_of_storage_parts(configs: dict[str, StructureConfig]) -> None:
    obj = build_structure(_spec(configs, "storage_furniture", 1))
    tree = object_tree(obj)
    expected = {"body": "static", "door": "rotating", "drawer": "translating"}
    assert [expected[p.role] for p in tree.parts] == list(tree.motion_types)


@pytest.mark.parametrize("name", NAMES)
def test_parts_are_watertight_and_moving_parts_do_not_overlap(
    configs: dict[str, StructureConfig], name: str
) -> None:
    for seed in range(4):
        obj = build_structure(_spec(configs, name, seed))
        boxes = []
        for link, pose in zip(obj.links, obj.link_poses(np.zeros(obj.dof)), strict=True):
            mesh = trimesh.Trimesh(link.mesh.vertices, link.mesh.triangles)
            assert mesh.is_watertight and mesh.volume > 0 and link.inertial.mass > 0
            world = link.mesh.vertices @ pose[:3, :3].T + pose[:3, 3]
            boxes.append((world.min(axis=0), world.max(axis=0)))
        if name != "storage_furniture":
            continue
        for i in range(1, len(boxes)):  # doors and drawers (handles included): disjoint
            for j in range(i + 1, len(boxes)):
                overlap = np.minimum(boxes[i][1], boxes[j][1]) - np.maximum(
                    boxes[i][0], boxes[j][0]
                )
                assert np.any(overlap <= 1e-9), (seed, obj.links[i].name, obj.links[j].name)


@pytest.mark.parametrize("name", NAMES)
def test_eighteen_poses_within_limits_and_seeded(
    configs: dict[str, StructureConfig], name: str
) -> None:
    obj = build_structure(_spec(configs, name, 3))
    poses = sample_configurations(obj, 18, np.random.default_rng([0, 3, 1]))
    q = poses.array()
    assert q.shape == (18, obj.dof)
    assert poses.joint_names == tuple(j.name for j in obj.movable_joints)
    lower = np.array([j.limits[0] for j in obj.movable_joints])
    upper = np.array([j.limits[1] for j in obj.movable_joints])
    assert np.all(q >= lower) and np.all(q <= upper)
    assert len({tuple(row) for row in q.tolist()}) == 18
    again = sample_configurations(obj, 18, np.random.default_rng([0, 3, 1]))
    assert again == poses and ArticulatedPoses.model_validate_json(poses.model_dump_json()) == poses
    for row in q:
        assert all(np.all(np.isfinite(p)) for p in obj.link_poses(row))
    with pytest.raises(ValueError, match="count"):
        sample_configurations(obj, 0, np.random.default_rng(0))


@pytest.mark.parametrize("name", NAMES)
def test_urdf_loads_in_pybullet_with_the_expected_joints(
    configs: dict[str, StructureConfig], client: int, tmp_path: Path, name: str
) -> None:
    from scipy.spatial.transform import Rotation

    obj = build_structure(_spec(configs, name, 0))
    urdf = str(write_urdf_folder(obj, tmp_path))
    body = pybullet.loadURDF(urdf, useFixedBase=True, physicsClientId=client)
    assert pybullet.getNumJoints(body, physicsClientId=client) == len(obj.joints)
    infos = [pybullet.getJointInfo(body, j, physicsClientId=client) for j in range(len(obj.joints))]
    assert [i[1].decode() for i in infos] == [j.name for j in obj.joints]
    assert [i[12].decode() for i in infos] == [link.name for link in obj.links[1:]]
    q = sample_configurations(obj, 1, np.random.default_rng(0)).array()[0]
    movable = [j for j, joint in enumerate(obj.joints) if joint.type != "fixed"]
    for index, value in zip(movable, q, strict=True):
        pybullet.resetJointState(body, index, value, physicsClientId=client)
    expected = obj.link_poses(q)
    for j in range(len(obj.joints)):
        state = pybullet.getLinkState(
            body, j, computeForwardKinematics=True, physicsClientId=client
        )
        np.testing.assert_allclose(state[4], expected[j + 1][:3, 3], atol=1e-6)
        rotation = Rotation.from_quat(state[5]).as_matrix()
        np.testing.assert_allclose(rotation, expected[j + 1][:3, :3], atol=1e-6)


@pytest.mark.parametrize("name", NAMES)
def test_urdf_validates_in_yourdfpy_and_urdfdom(
    configs: dict[str, StructureConfig], tmp_path: Path, name: str
) -> None:
    obj = build_structure(_spec(configs, name, 5))
    path = write_urdf_folder(obj, tmp_path)
    urdf = yourdfpy.URDF.load(str(path))
    assert urdf.validate()
    assert urdf.actuated_joint_names == [j.name for j in obj.movable_joints]
    if shutil.which("check_urdf"):
        result = subprocess.run(["check_urdf", str(path)], capture_output=True, text=True)
        assert result.returncode == 0, result.stderr


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_bytes(configs: dict[str, StructureConfig], name: str) -> None:
    spec = _spec(configs, name, 7)
    assert _spec(configs, name, 7) == spec
    again = parse_structure_spec(spec.model_dump_json())
    assert again == spec
    assert write_urdf(build_structure(again)) == write_urdf(build_structure(spec))
    assert object_tree(build_structure(again)) == object_tree(build_structure(spec))
    assert _spec(configs, name, 8) != spec


def test_bad_specs_and_configs_are_rejected(configs: dict[str, StructureConfig]) -> None:
    spec = _spec(configs, "storage_furniture", 0)
    data = json.loads(spec.model_dump_json())
    data["height"] += 0.1
    with pytest.raises(ValidationError, match="add up"):
        parse_structure_spec(json.dumps(data))
    raw = yaml.safe_load((CATEGORY_DIR / "lamp.yaml").read_text())
    with pytest.raises(ValidationError, match="chain"):
        get_structure("lamp").config.model_validate({**raw, "chain": [1, 3]})
    raw = yaml.safe_load((CATEGORY_DIR / "storage_furniture.yaml").read_text())
    with pytest.raises(ValidationError, match="min_compartment"):
        get_structure("storage_furniture").config.model_validate(
            {**raw, "layout": {**raw["layout"], "min_compartment": 5.0}}
        )


# --- generate-dataset dataset=hierarchy ------------------------------------------------


def _cli(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.stdout, result.stderr


def _data_files(folder: Path) -> dict[str, bytes]:
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name not in ("manifest.json", "artic.log")
    }


TINY = ("generate-dataset", "debug=tiny", "dataset=hierarchy", "category=storage_furniture")


@pytest.fixture(scope="module")
def hierarchy_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("hierarchy") / "storage_furniture"
    code, _, err = _cli(*TINY, f"out={out}")
    assert code == 0, err
    return out


def test_hierarchy_dataset_writes_tree_and_poses(hierarchy_dataset: Path) -> None:
    from artic.artifacts.object_dataset import ObjectDataset

    ds = ObjectDataset.open(hierarchy_dataset)
    assert [r.object_id for r in ds.rows] == list(range(6))
    manifest = json.loads((hierarchy_dataset / "manifest.json").read_text())
    assert manifest["stats"]["poses per object"] == 18
    assert manifest["stats"]["distinct trees"] >= 2
    for row in ds.rows:
        folder = hierarchy_dataset / "objects" / f"{row.object_id:06d}"
        tree = ObjectTree.model_validate_json((folder / "tree.json").read_text())
        poses = ArticulatedPoses.model_validate_json((folder / "poses.json").read_text())
        assert row.dof == tree.dof == len(poses.joint_names) and row.chirality == 0
        q = poses.array()
        assert q.shape == (18, tree.dof)
        limits = np.array([tree.limits[e] for e in tree.movable_edges])
        assert np.all(q >= limits[:, 0]) and np.all(q <= limits[:, 1])
        assert poses.joint_names == tuple(tree.joint_names[e] for e in tree.movable_edges)
        urdf = ds.urdf(row.object_id).read_text()
        assert urdf.count("<joint ") == tree.num_parts - 1
        spec = parse_structure_spec((folder / "spec.json").read_text())
        assert object_tree(build_structure(spec)) == tree


def test_hierarchy_dataset_is_deterministic_and_shards_merge(
    hierarchy_dataset: Path, tmp_path: Path
) -> None:
    a = tmp_path / "a"
    assert _cli(*TINY, f"out={a}")[0] == 0
    assert _data_files(a) == _data_files(hierarchy_dataset)
    b = tmp_path / "b"
    codes = [_cli(*TINY, f"out={b}", f"shard.index={i}", "shard.count=3")[0] for i in (1, 2, 0)]
    assert codes == [0, 0, 0]
    assert _data_files(b) == _data_files(hierarchy_dataset)
    c = tmp_path / "c"
    assert _cli(*TINY, f"out={c}", "seed=1")[0] == 0
    assert _data_files(c)["objects/000000/tree.json"] != _data_files(a)["objects/000000/tree.json"]


def test_hierarchy_dataset_of_an_appendix_a_category(tmp_path: Path) -> None:
    out = tmp_path / "mw"
    code, _, err = _cli(
        "generate-dataset", "debug=tiny", "dataset=hierarchy", "category=microwave", f"out={out}"
    )
    assert code == 0, err
    tree = ObjectTree.model_validate_json((out / "objects/000000/tree.json").read_text())
    assert [p.role for p in tree.parts] == ["body", "door", "handle"]
    assert tree.motion_types == ("static", "rotating", "static")
    spec = json.loads((out / "objects/000000/spec.json").read_text())
    np.testing.assert_allclose(tree.base_pose[0][3], spec["pose"]["x"])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["category=storage_furniture"], "use dataset=hierarchy"),
        (["dataset=hierarchy", "category=sofa"], "category"),
        (["dataset=hierarchy", "category=lamp", "dataset.poses=0"], "dataset.poses"),
        (["dataset=hierarchy", "category=lamp", "category.chain=[1,3]"], "chain"),
        (["dataset=hierarchy", "category=office_chair", "category.nope=1"], "nope"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path: Path, args: list[str], message: str) -> None:
    code, _, err = _cli("generate-dataset", "debug=tiny", *args, f"out={tmp_path / 'o'}")
    assert code == 2, err
    assert message in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "o").exists()
