"""PartNet-Mobility folders -> ArticulatedObject + tree ground truth, on a fixture the
test writes in the dataset's layout (mobility.urdf, textured_objs/*.obj, semantics.txt)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pybullet
import pytest
import trimesh
import yourdfpy
from scipy.spatial.transform import Rotation

from artic.artifacts.partnet import load_partnet
from artic.errors import InputError
from artic.objects.partnet import SPIN_RANGE, parse_obj, parse_semantics
from artic.objects.tree import KinematicTree, sample_configurations
from artic.objects.urdf import write_urdf

# PartNet-Mobility's objects are y-up; the fixed joint from `base` turns them z-up.
BASE_RPY = (1.5707963267948966, 0.0, -1.5707963267948966)
PANEL = (0.6, 0.8, 0.02)  # box extents of each link's first mesh, m


def _obj_text(extents: tuple[float, float, float], centre: tuple[float, float, float]) -> str:
    box = trimesh.creation.box(extents=extents)
    lines = ["mtllib original.mtl", "o piece", "usemtl material_0"]
    lines += [f"v {x + centre[0]} {y + centre[1]} {z + centre[2]}" for x, y, z in box.vertices]
    lines += ["vt 0.0 0.0"]
    lines += [f"f {a + 1}/1 {b + 1}/1 {c + 1}/1" for a, b, c in box.faces]
    return "\n".join(lines) + "\n"


def _link(name: str, meshes: list[tuple[str, str]]) -> str:
    visuals = "".join(
        f'<visual name="{name}-{k}"><origin xyz="{xyz}"/><geometry>'
        f'<mesh filename="textured_objs/{file}"/></geometry></visual>'
        for k, (file, xyz) in enumerate(meshes)
    )
    return f'<link name="{name}">{visuals}</link>\n'


def _urdf(extra_links: str = "", extra_joints: str = "", door_type: str = "revolute") -> str:
    limit = '<limit lower="0" upper="1.5"/>' if door_type == "revolute" else ""
    return (
        '<?xml version="1.0"?>\n<robot name="partnet_fixture">\n<link name="base"/>\n'
        + _link("link_0", [("original-3.obj", "0 0 0"), ("original-4.obj", "0.1 0 0")])
        + f'<joint name="joint_0" type="{door_type}"><origin xyz="-0.3 0 0.25"/>'
        f'<axis xyz="0 1 0"/><child link="link_0"/><parent link="link_2"/>{limit}</joint>\n'
        + _link("link_1", [("original-5.obj", "0 0 0"), ("original-6.obj", "0 0 0")])
        + '<joint name="joint_1" type="prismatic"><origin xyz="0 -0.2 0.25"/>'
        '<axis xyz="0 0 1"/><child link="link_1"/><parent link="link_2"/>'
        '<limit lower="0" upper="0.35"/></joint>\n'
        + _link("link_2", [("original-1.obj", "0 0 0"), ("original-2.obj", "0 0.45 0")])
        + '<joint name="joint_2" type="fixed"><origin rpy="'
        + " ".join(map(str, BASE_RPY))
        + '" xyz="0 0 0"/><child link="link_2"/><parent link="base"/></joint>\n'
        + extra_links
        + extra_joints
        + "</robot>\n"
    )


def _write_folder(folder: Path, urdf: str | None = None, semantics: bool = True) -> Path:
    textured = folder / "textured_objs"
    textured.mkdir(parents=True)
    pieces = {
        "original-1.obj": ((0.6, 0.9, 0.5), (0.0, 0.0, 0.0)),  # body
        "original-2.obj": ((0.6, 0.02, 0.5), (0.0, 0.0, 0.0)),  # body top board
        "original-3.obj": (PANEL, (0.0, 0.0, 0.0)),  # door panel
        "original-4.obj": ((0.05, 0.1, 0.05), (0.0, 0.0, 0.05)),  # door knob
        "original-5.obj": ((0.3, 0.02, 0.5), (0.0, 0.0, 0.0)),  # drawer front
        "original-6.obj": ((0.3, 0.3, 0.02), (0.0, 0.15, 0.0)),  # drawer bottom
        "original-7.obj": ((0.02, 0.02, 0.1), (0.0, 0.0, 0.0)),  # a handle
    }
    for name, (extents, centre) in pieces.items():
        (textured / name).write_text(_obj_text(extents, centre))
    (folder / "mobility.urdf").write_text(urdf if urdf is not None else _urdf())
    if semantics:
        (folder / "semantics.txt").write_text(
            "link_0 hinge door\nlink_1 slider drawer\nlink_2 static cabinet_frame\n"
        )
    return folder


HANDLE_LINK = _link("link_3", [("original-7.obj", "0 0 0"), ("original-4.obj", "0 0 0")])
HANDLE_JOINT = (
    '<joint name="joint_3" type="fixed"><origin xyz="0.2 0.0 0.05"/>'
    '<child link="link_3"/><parent link="link_0"/></joint>\n'
)


def test_loads_links_joints_and_meshes(tmp_path: Path) -> None:
    result = load_partnet(_write_folder(tmp_path / "m"))
    obj = result.object
    # the geometry-less base is dropped; depth-first from link_2, children in file order
    assert [link.name for link in obj.links] == ["link_2", "link_0", "link_1"]
    assert [link.role for link in obj.links] == ["cabinet_frame", "door", "drawer"]
    assert [(j.name, j.type, j.parent, j.child) for j in obj.joints] == [
        ("joint_0", "revolute", "link_2", "link_0"),
        ("joint_1", "prismatic", "link_2", "link_1"),
    ]
    assert obj.dof == 2 and obj.joints[0].limits == (0.0, 1.5)
    np.testing.assert_allclose(
        obj.base_pose[:3, :3], Rotation.from_euler("xyz", BASE_RPY).as_matrix(), atol=1e-12
    )
    door = obj.links[1].mesh
    assert door.vertices.shape == (16, 3) and door.triangles.shape == (24, 3)  # two boxes
    # the knob's visual origin (0.1, 0, 0) is applied in the link frame
    np.testing.assert_allclose(door.vertices.max(axis=0), [0.3, 0.4, 0.075], atol=1e-12)
    assert all(link.inertial.mass > 0 for link in obj.links)


def test_tree_ground_truth(tmp_path: Path) -> None:
    result = load_partnet(_write_folder(tmp_path / "m"))
    tree, obj = result.tree, result.object
    assert tree.num_parts == 3 and tree.root == 0
    assert tree.edges == ((0, 1), (0, 2))
    assert tree.motion_types == ("static", "rotating", "translating")
    assert [p.semantic for p in tree.parts] == ["cabinet_frame", "door", "drawer"]
    rotation = obj.base_pose[:3, :3]
    assert tree.axes[0] is not None and tree.axes[1] is not None
    np.testing.assert_allclose(tree.axes[0].direction, rotation @ [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(tree.axes[0].origin, rotation @ [-0.3, 0, 0.25], atol=1e-12)
    np.testing.assert_allclose(tree.axes[1].direction, rotation @ [0, 0, 1], atol=1e-12)
    graph = KinematicTree.from_dict(json.loads(tree.model_dump_json()))
    assert graph.root == 0 and graph.joint_types == ("revolute", "prismatic")
    q = sample_configurations(obj, 18, np.random.default_rng(0)).array()
    assert q.shape == (18, 2) and q[:, 0].max() <= 1.5 and q[:, 1].max() <= 0.35


def test_written_urdf_loads_in_pybullet_yourdfpy_and_urdfdom(tmp_path: Path) -> None:
    obj = load_partnet(_write_folder(tmp_path / "m")).object
    files = write_urdf(obj)
    out = tmp_path / "out"
    (out / "meshes").mkdir(parents=True)
    (out / "object.urdf").write_text(files.urdf)
    for rel, text in files.meshes.items():
        (out / rel).write_text(text)
    cid = pybullet.connect(pybullet.DIRECT)
    try:
        body = pybullet.loadURDF(str(out / "object.urdf"), useFixedBase=True, physicsClientId=cid)
        assert pybullet.getNumJoints(body, physicsClientId=cid) == 2
        names = [pybullet.getJointInfo(body, j, physicsClientId=cid)[1].decode() for j in (0, 1)]
        assert names == ["joint_0", "joint_1"]
        pybullet.resetJointState(body, 1, 0.2, physicsClientId=cid)
        state = pybullet.getLinkState(body, 1, computeForwardKinematics=True, physicsClientId=cid)
        base = np.eye(4)  # loaded at the origin: compare in the root link's frame
        expected = obj.link_poses(np.array([0.0, 0.2]))
        relative = np.linalg.inv(obj.base_pose) @ expected[2]
        np.testing.assert_allclose(state[4], (base @ relative)[:3, 3], atol=1e-6)
    finally:
        pybullet.disconnect(physicsClientId=cid)
    assert yourdfpy.URDF.load(str(out / "object.urdf")).validate()
    if shutil.which("check_urdf"):
        check = subprocess.run(["check_urdf", str(out / "object.urdf")], capture_output=True)
        assert check.returncode == 0


def test_fixed_links_stay_parts_unless_merged(tmp_path: Path) -> None:
    folder = _write_folder(tmp_path / "m", _urdf(HANDLE_LINK, HANDLE_JOINT))
    kept = load_partnet(folder)
    assert [link.name for link in kept.object.links] == ["link_2", "link_0", "link_3", "link_1"]
    assert kept.tree.motion_types == ("static", "rotating", "static", "translating")
    assert kept.tree.joint_types == ("revolute", "fixed", "prismatic")
    merged = load_partnet(folder, merge_fixed=True)
    assert [link.name for link in merged.object.links] == ["link_2", "link_0", "link_1"]
    door = merged.object.links[1].mesh
    assert door.vertices.shape[0] == 16 + 16  # the handle's two boxes joined the door
    # the handle's meshes moved by its fixed joint's origin into the door frame
    handle = kept.object.links[2].mesh.vertices
    np.testing.assert_allclose(door.vertices[16:], handle + np.array([0.2, 0.0, 0.05]), atol=1e-12)
    np.testing.assert_allclose(
        merged.object.link_poses(np.zeros(2))[2], kept.object.link_poses(np.zeros(2))[3]
    )


def test_continuous_joint_and_no_semantics(tmp_path: Path) -> None:
    folder = _write_folder(tmp_path / "m", _urdf(door_type="continuous"), semantics=False)
    result = load_partnet(folder)
    assert result.object.joints[0].type == "continuous"
    assert result.object.joints[0].limits == SPIN_RANGE
    assert result.tree.joint_types[0] == "revolute"
    assert result.tree.urdf_joint_types[0] == "continuous"
    assert [link.role for link in result.object.links] == ["body", "part", "part"]
    assert "<limit effort" in write_urdf(result.object).urdf


def test_missing_files_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not a folder"):
        load_partnet(tmp_path / "nowhere")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match=r"empty/mobility\.urdf: missing"):
        load_partnet(empty)
    folder = _write_folder(tmp_path / "m")
    (folder / "textured_objs" / "original-5.obj").unlink()
    with pytest.raises(InputError, match=r"textured_objs/original-5\.obj: mesh file .* missing"):
        load_partnet(folder)


@pytest.mark.parametrize(
    ("urdf", "message"),
    [
        (_urdf().replace('<parent link="link_2"/><limit lower="0" upper="0.35"/>',
                         '<parent link="link_9"/><limit lower="0" upper="0.35"/>'),
         "joint joint_1 references unknown link 'link_9'"),
        (_urdf().replace('type="prismatic"', 'type="floating"'), "type 'floating' not supported"),
        (_urdf().replace('upper="0.35"', 'upper="-1"'), "limit lower 0.0 > upper -1.0"),
        (_urdf().replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'), "axis must be a non-zero"),
        (_urdf().replace("</robot>", "<link"), "not valid XML"),
        (_urdf().replace('<parent link="base"/>', '<parent link="link_0"/>'), "cycle"),
    ],
)  # fmt: skip
def test_bad_urdf_raises_input_error_naming_it(tmp_path: Path, urdf: str, message: str) -> None:
    folder = _write_folder(tmp_path / "m", urdf)
    with pytest.raises(InputError, match=r"mobility\.urdf") as info:
        load_partnet(folder)
    assert message in str(info.value)


def test_bad_meshes_and_semantics(tmp_path: Path) -> None:
    folder = _write_folder(tmp_path / "m")
    (folder / "textured_objs" / "original-3.obj").write_text("v 0 0 0\nv 1 0 0\n")
    with pytest.raises(InputError, match=r"original-3\.obj: an OBJ mesh with no triangles"):
        load_partnet(folder)
    folder = _write_folder(tmp_path / "s")
    (folder / "semantics.txt").write_text("link_0 hinge door\nlink_7 slider drawer\n")
    with pytest.raises(InputError, match=r"semantics\.txt: link link_7 is not a link"):
        load_partnet(folder)
    with pytest.raises(InputError, match="line 2"):
        parse_semantics("link_0 hinge door\nlink_1\n")
    assert parse_obj(_obj_text((1.0, 1.0, 1.0), (0, 0, 0)).encode(), "x.obj").triangles.shape == (
        12,
        3,
    )


def test_geometry_less_inner_link_stays_virtual(tmp_path: Path) -> None:
    helper = '<link name="helper"/>\n'
    joint = (
        '<joint name="joint_9" type="prismatic"><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>'
        '<child link="helper"/><parent link="link_1"/><limit lower="0" upper="0.1"/></joint>\n'
    )
    obj = load_partnet(_write_folder(tmp_path / "m", _urdf(helper, joint))).object
    assert obj.links[-1].name == "helper" and obj.links[-1].mesh.is_empty
    files = write_urdf(obj)
    assert "meshes/helper.obj" not in files.meshes
    out = tmp_path / "out"
    (out / "meshes").mkdir(parents=True)
    (out / "o.urdf").write_text(files.urdf)
    for rel, text in files.meshes.items():
        (out / rel).write_text(text)
    cid = pybullet.connect(pybullet.DIRECT)
    try:
        body = pybullet.loadURDF(str(out / "o.urdf"), useFixedBase=True, physicsClientId=cid)
        assert pybullet.getNumJoints(body, physicsClientId=cid) == 3
    finally:
        pybullet.disconnect(physicsClientId=cid)
    assert yourdfpy.URDF.load(str(out / "o.urdf")).validate()
