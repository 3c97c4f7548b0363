"""image_labels (thesis section 3.2.1): columns, axis geometry, behaviour under yaw."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from artic.geometry.transforms import invert, transform_points
from artic.objects.categories import build
from artic.objects.labels import image_labels, label_columns
from artic.objects.spec import ObjectSpec, Pose

CATEGORY_NAMES = ("cabinet", "drawer", "microwave", "toaster", "cabinet2", "refrigerator")
SpecFactory = Callable[[str, int], ObjectSpec]


def _vec(labels: dict[str, float], j: int, field: str) -> np.ndarray:
    return np.array([labels[f"j{j}_{field}_{a}"] for a in "xyz"])


def _in_object_frame(spec: ObjectSpec, labels: dict[str, float], j: int) -> tuple[np.ndarray, ...]:
    """(origin, direction) of joint j in the object frame."""
    to_object = invert(spec.pose.matrix())
    origin = transform_points(to_object, _vec(labels, j, "origin")[None])[0]
    return origin, to_object[:3, :3] @ _vec(labels, j, "direction")


def _random_q(spec: ObjectSpec, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.array([rng.uniform(*limits) for limits in spec.joint_limits])


def test_label_columns() -> None:
    assert label_columns(0)[:8] == [
        "pose_x", "pose_y", "pose_z", "pose_yaw", "depth", "width", "height", "chirality"
    ]  # fmt: skip
    assert len(label_columns(1)) == 18 and len(label_columns(2)) == 28
    assert label_columns(2)[8] == "j0_q" and label_columns(2)[18] == "j1_q"
    assert len(set(label_columns(2))) == 28


@pytest.mark.parametrize("name", CATEGORY_NAMES)
def test_labels_keys_values_and_unit_direction(make_spec: SpecFactory, name: str) -> None:
    spec = make_spec(name, 0)
    obj = build(spec)
    q = _random_q(spec, 1)
    labels = image_labels(spec, obj, q)
    assert list(labels) == label_columns(spec.dof)
    assert all(isinstance(v, float) and np.isfinite(v) for v in labels.values())
    assert (labels["pose_x"], labels["pose_yaw"], labels["chirality"]) == (
        spec.pose.x,
        spec.pose.yaw,
        float(spec.chirality),
    )
    for j in range(spec.dof):
        assert labels[f"j{j}_q"] == q[j]
        assert np.linalg.norm(_vec(labels, j, "direction")) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="configuration"):
        image_labels(spec, obj, np.zeros(spec.dof + 1))


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("name", CATEGORY_NAMES)
def test_axis_lies_on_the_hinge_edge_or_drawer_front(
    make_spec: SpecFactory, name: str, seed: int
) -> None:
    spec = make_spec(name, seed)
    labels = image_labels(spec, build(spec), _random_q(spec, seed))
    front, half_w = -spec.depth / 2, spec.width / 2
    for j in range(spec.dof):
        origin, direction = _in_object_frame(spec, labels, j)
        assert origin[0] == pytest.approx(front)
        if name == "drawer":
            np.testing.assert_allclose(origin, [front, 0.0, spec.height / 2], atol=1e-9)
            np.testing.assert_allclose(direction, [-1.0, 0.0, 0.0], atol=1e-9)
        elif name == "toaster":
            assert origin[2] == pytest.approx(0.0, abs=1e-9)
            np.testing.assert_allclose(direction, [0.0, -1.0, 0.0], atol=1e-9)
        else:
            hinge = (1, -1)[j] if name == "cabinet2" else spec.chirality
            np.testing.assert_allclose(direction, [0.0, 0.0, hinge], atol=1e-9)
            assert origin[1] == pytest.approx(-hinge * half_w)  # +1: hinge on the -y edge
            assert 0.0 <= origin[2] < spec.height


@pytest.mark.parametrize("name", CATEGORY_NAMES)
def test_part_origin_is_the_closed_part_centre(make_spec: SpecFactory, name: str) -> None:
    spec = make_spec(name, 3)
    obj = build(spec)
    labels = image_labels(spec, obj, np.zeros(spec.dof))
    for j, joint in enumerate(obj.movable_joints):
        part = obj.link_index(joint.child)
        world = transform_points(
            obj.link_poses(np.zeros(spec.dof))[part], obj.links[part].mesh.vertices
        )
        local = transform_points(invert(obj.joint_frames(np.zeros(spec.dof))[j]), world)
        centre = 0.5 * (local.min(axis=0) + local.max(axis=0))
        np.testing.assert_allclose(_vec(labels, j, "part"), centre, atol=1e-9)
    if name == "cabinet":
        offset = _vec(labels, 0, "part")
        assert offset[1] == pytest.approx(spec.chirality * spec.width / 2)
        assert offset[2] == pytest.approx(spec.height / 2)


@pytest.mark.parametrize("name", CATEGORY_NAMES)
def test_labels_rotate_with_yaw(make_spec: SpecFactory, name: str) -> None:
    spec = make_spec(name, 6)
    q = _random_q(spec, 6)
    reference = None
    for yaw in (-0.7, 0.0, 0.4):
        pose = Pose(x=spec.pose.x, y=spec.pose.y, z=spec.pose.z, yaw=yaw)
        turned = ObjectSpec.model_validate({**spec.model_dump(), "pose": pose.model_dump()})
        labels = image_labels(turned, build(turned), q)
        local = [np.concatenate(_in_object_frame(turned, labels, j)) for j in range(spec.dof)]
        parts = [_vec(labels, j, "part") for j in range(spec.dof)]
        if reference is None:
            reference = (local, parts)
        np.testing.assert_allclose(np.array(local), np.array(reference[0]), atol=1e-9)
        np.testing.assert_allclose(np.array(parts), np.array(reference[1]), atol=1e-12)
        offset = _vec(labels, 0, "origin") - np.array([pose.x, pose.y, pose.z])
        expected_angle = np.arctan2(reference[0][0][1], reference[0][0][0]) + yaw
        assert np.arctan2(offset[1], offset[0]) == pytest.approx(
            np.angle(np.exp(1j * expected_angle))
        )
