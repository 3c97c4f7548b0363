"""write_urdf: the files load in PyBullet, yourdfpy and urdfdom and match the model."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pybullet
import pytest
import yourdfpy
from scipy.spatial.transform import Rotation

from artic.objects.categories import build
from artic.objects.model import ArticulatedObject
from artic.objects.spec import ObjectSpec
from artic.objects.urdf import write_urdf
from urdf_folder import write_urdf_folder

CATEGORY_NAMES = ("cabinet", "drawer", "microwave", "toaster", "cabinet2", "refrigerator")
SpecFactory = Callable[[str, int], ObjectSpec]
PYBULLET_TYPES = {"revolute": pybullet.JOINT_REVOLUTE, "prismatic": pybullet.JOINT_PRISMATIC}
PYBULLET_TYPES["fixed"] = pybullet.JOINT_FIXED


@pytest.fixture(scope="module")
def client() -> Iterator[int]:
    cid = pybullet.connect(pybullet.DIRECT)
    yield cid
    pybullet.disconnect(physicsClientId=cid)


def _load(client: int, path: Path, obj: ArticulatedObject) -> int:
    pose = obj.base_pose
    return pybullet.loadURDF(
        str(path),
        basePosition=pose[:3, 3].tolist(),
        baseOrientation=Rotation.from_matrix(pose[:3, :3]).as_quat().tolist(),
        useFixedBase=True,
        physicsClientId=client,
    )


@pytest.mark.parametrize("name", CATEGORY_NAMES)
def test_pybullet_loads_joints_in_order(
    make_spec: SpecFactory, client: int, tmp_path: Path, name: str
) -> None:
    obj = build(make_spec(name, 1))
    body = _load(client, write_urdf_folder(obj, tmp_path), obj)
    assert pybullet.getNumJoints(body, physicsClientId=client) == len(obj.joints)
    for j, joint in enumerate(obj.joints):
        info = pybullet.getJointInfo(body, j, physicsClientId=client)
        assert info[1].decode() == joint.name
        assert info[12].decode() == obj.links[j + 1].name
        assert info[2] == PYBULLET_TYPES[joint.type]
        if joint.type != "fixed":
            assert (info[8], info[9]) == pytest.approx(joint.limits)
            assert (info[10], info[11]) == pytest.approx((joint.effort, joint.velocity))
            assert (info[6], info[7]) == pytest.approx((joint.damping, joint.friction))
        link = obj.links[j + 1]
        mass = pybullet.getDynamicsInfo(body, j, physicsClientId=client)[0]
        assert mass == pytest.approx(link.inertial.mass)


@pytest.mark.parametrize("name", CATEGORY_NAMES)
def test_pybullet_link_poses_match_forward_kinematics(
    make_spec: SpecFactory, client: int, tmp_path: Path, name: str
) -> None:
    spec = make_spec(name, 2)
    obj = build(spec)
    body = _load(client, write_urdf_folder(obj, tmp_path), obj)
    movable = [j for j, joint in enumerate(obj.joints) if joint.type != "fixed"]
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = np.array([rng.uniform(*limits) for limits in spec.joint_limits])
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


@pytest.mark.parametrize("name", CATEGORY_NAMES)
def test_yourdfpy_validates(make_spec: SpecFactory, tmp_path: Path, name: str) -> None:
    obj = build(make_spec(name, 0))
    urdf = yourdfpy.URDF.load(str(write_urdf_folder(obj, tmp_path)))
    assert urdf.validate()
    assert list(urdf.link_map) == [link.name for link in obj.links]
    assert urdf.actuated_joint_names == [j.name for j in obj.movable_joints]


@pytest.mark.skipif(shutil.which("check_urdf") is None, reason="liburdfdom-tools not installed")
@pytest.mark.parametrize("name", CATEGORY_NAMES)
def test_check_urdf_accepts(make_spec: SpecFactory, tmp_path: Path, name: str) -> None:
    path = write_urdf_folder(build(make_spec(name, 0)), tmp_path)
    result = subprocess.run(["check_urdf", str(path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize("name", CATEGORY_NAMES)
def test_urdf_text_is_deterministic(make_spec: SpecFactory, name: str) -> None:
    spec = make_spec(name, 4)
    first = write_urdf(build(spec))
    second = write_urdf(build(ObjectSpec.model_validate_json(spec.model_dump_json())))
    assert first == second
    assert sorted(first.meshes) == sorted(f"meshes/{link.name}.obj" for link in build(spec).links)
    assert "base_pose" not in first.urdf and str(spec.pose.x) not in first.urdf
