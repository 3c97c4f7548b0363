"""URDF of an inferred kinematic tree: loads in PyBullet with the tree's joints."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from artic.hierarchy.joints import estimate_axes
from artic.hierarchy.urdf import convex_hull_mesh, tree_to_urdf
from artic.objects.tree import KinematicTree
from artic.sim.bullet import connect_direct
from box_clouds import box_surface


def cabinet(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, KinematicTree]:
    """Body (open front), a door with a handle on top, a drawer below (5 cm out)."""
    shell = box_surface([0.0, -0.3, 0.0], [0.4, 0.3, 0.8], 3000, rng)
    shell = shell[shell[:, 0] > 1e-9]
    door = box_surface([-0.023, -0.28, 0.42], [-0.003, 0.28, 0.78], 800, rng)
    handle = box_surface([-0.05, 0.18, 0.55], [-0.024, 0.22, 0.65], 100, rng)
    drawer = box_surface([-0.07, -0.27, 0.05], [0.31, 0.27, 0.38], 800, rng)
    parts = [shell, door, handle, drawer]
    points = np.concatenate(parts).astype(np.float32)
    part_id = np.repeat(np.arange(4), [len(p) for p in parts])
    tree = KinematicTree(
        4, 0, ((0, 1), (0, 3), (1, 2)), (0, 1, 0, 2), ("revolute", "prismatic", "fixed")
    )
    return points, part_id, estimate_axes(tree, points, part_id)


def write(files_urdf: str, meshes: dict[str, str], folder: Path) -> Path:
    path = folder / "object.urdf"
    path.write_text(files_urdf)
    for relative, text in meshes.items():
        (folder / relative).parent.mkdir(parents=True, exist_ok=True)
        (folder / relative).write_text(text)
    return path


def test_urdf_loads_in_pybullet_with_the_trees_joints(tmp_path: Path) -> None:
    points, part_id, tree = cabinet(np.random.default_rng(0))
    files = tree_to_urdf(tree, points, part_id)
    assert set(files.meshes) == {f"meshes/part_{p}.obj" for p in range(4)}
    path = write(files.urdf, files.meshes, tmp_path)
    client = connect_direct()
    try:
        body = client.loadURDF(str(path), useFixedBase=True)
        assert client.getNumJoints(body) == len(tree.edges)
        types = {"revolute": client.JOINT_REVOLUTE, "prismatic": client.JOINT_PRISMATIC}
        types["fixed"] = client.JOINT_FIXED
        order = tree.depth_first_edges()
        assert order == [(0, 1), (1, 2), (0, 3)]
        for j, (parent, child) in enumerate(order):
            e = tree.edge_index(parent, child)
            joint_type = tree.joint_types[e]
            info = client.getJointInfo(body, j)
            assert info[1].decode() == f"joint_{child}"
            assert info[12].decode() == f"part_{child}"
            assert info[2] == types[joint_type]
            if joint_type != "fixed":
                axis = tree.axes[e]  # type: ignore[index]
                assert np.allclose(info[13], axis.direction, atol=1e-6)  # type: ignore[union-attr]
                assert info[8] == 0.0 and info[9] > 0.0
        # positive joint values open the parts towards the camera (-x)
        closed = [np.array(client.getLinkState(body, j)[0]) for j in range(3)]
        client.resetJointState(body, 0, 0.8)  # door
        client.resetJointState(body, 2, 0.1)  # drawer
        opened = [np.array(client.getLinkState(body, j)[0]) for j in range(3)]
        assert opened[0][0] < closed[0][0] - 0.05  # door centre of mass swings out
        assert opened[1][0] < closed[1][0] - 0.1  # the handle follows the door
        assert opened[2][0] == pytest.approx(closed[2][0] - 0.1, abs=0.01)  # drawer slides
    finally:
        client.disconnect()


def test_urdf_is_deterministic_and_needs_axes() -> None:
    points, part_id, tree = cabinet(np.random.default_rng(1))
    assert tree_to_urdf(tree, points, part_id) == tree_to_urdf(tree, points, part_id)
    bare = tree.with_axes((None, None, None))
    with pytest.raises(ValueError, match="no axis"):
        tree_to_urdf(bare, points, part_id)


def test_hull_of_a_flat_part_is_thickened() -> None:
    rng = np.random.default_rng(2)
    flat = np.concatenate([rng.random((200, 2)), np.zeros((200, 1))], axis=1)
    mesh = convex_hull_mesh(flat, min_thickness=0.004)
    assert np.ptp(mesh.vertices[:, 2]) == pytest.approx(0.004)
    assert len(mesh.triangles) >= 4


def test_yourdfpy_and_urdfdom_accept(tmp_path: Path) -> None:
    import yourdfpy

    points, part_id, tree = cabinet(np.random.default_rng(3))
    files = tree_to_urdf(tree, points, part_id)
    path = write(files.urdf, files.meshes, tmp_path)
    assert yourdfpy.URDF.load(str(path)).validate()
    if shutil.which("check_urdf") is None:
        pytest.skip("liburdfdom-tools not installed")
    result = subprocess.run(["check_urdf", str(path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
