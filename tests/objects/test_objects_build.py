"""build(spec): link/joint structure, watertight parts, mass properties, kinematics."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import trimesh

from artic.errors import InputError
from artic.geometry.transforms import invert, transform_points
from artic.objects.categories import CATEGORIES, build, get_builder, register_category
from artic.objects.model import ArticulatedObject
from artic.objects.parts import Box, lazy_mass_properties, mass_properties, union_mesh
from artic.objects.spec import ObjectSpec
from fresh_python import in_fresh_python

CATEGORY_NAMES = ("cabinet", "drawer", "microwave", "toaster", "cabinet2", "refrigerator")
SEEDS = (0, 1, 2)
CASES = [(name, seed) for name in CATEGORY_NAMES for seed in SEEDS]
SpecFactory = Callable[[str, int], ObjectSpec]


def _object_frame_vertices(obj: ArticulatedObject, q: np.ndarray, link: int) -> np.ndarray:
    """(V, 3) vertices of link `link` at configuration q, in the object (body) frame."""
    poses = obj.link_poses(q)
    relative = invert(obj.base_pose) @ poses[link]
    return transform_points(relative, obj.links[link].mesh.vertices)


def test_registry_has_the_six_categories_and_chapter_7s_two() -> None:
    assert set(CATEGORIES) == set(CATEGORY_NAMES) | {"slide", "lever"}
    with pytest.raises(InputError, match="known categories: cabinet"):
        get_builder("wardrobe")
    with pytest.raises(ValueError, match="already registered"):
        register_category("cabinet")(CATEGORIES["cabinet"])


@pytest.mark.parametrize(("name", "seed"), CASES)
def test_links_and_joints_in_part_order(make_spec: SpecFactory, name: str, seed: int) -> None:
    spec = make_spec(name, seed)
    obj = build(spec)
    dof = 2 if name in ("cabinet2", "refrigerator") else 1
    assert obj.dof == spec.dof == dof
    moving = "drawer" if name == "drawer" else "door"
    expected = ["body"]
    for k in range(dof):
        expected += [f"{moving}_{k}", f"handle_{k}"]
    assert [link.name for link in obj.links] == expected
    assert [link.role for link in obj.links] == ["body"] + [moving, "handle"] * dof
    assert len(obj.joints) == len(obj.links) - 1
    for j, joint in enumerate(obj.joints):
        assert joint.child == obj.links[j + 1].name
        if j % 2 == 0:
            assert (joint.name, joint.parent, joint.type) == (
                f"joint_{j // 2}",
                "body",
                spec.joint_type,
            )
            assert joint.limits == spec.joint_limits[j // 2]
            assert np.linalg.norm(joint.axis) == pytest.approx(1.0)
        else:
            assert (joint.name, joint.type) == (f"handle_{j // 2}_fixed", "fixed")
            assert joint.parent == obj.links[j].name
    np.testing.assert_allclose(obj.base_pose, spec.pose.matrix())


@pytest.mark.parametrize(("name", "seed"), CASES)
def test_parts_are_watertight_solids_with_valid_inertia(
    make_spec: SpecFactory, name: str, seed: int
) -> None:
    spec = make_spec(name, seed)
    for link in build(spec).links:
        mesh = trimesh.Trimesh(link.mesh.vertices, link.mesh.triangles)  # default processing
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
        inertial = link.inertial
        assert inertial.mass > 0
        lo, hi = link.mesh.vertices.min(axis=0), link.mesh.vertices.max(axis=0)
        assert np.all(inertial.center_of_mass >= lo) and np.all(inertial.center_of_mass <= hi)
        np.testing.assert_allclose(inertial.inertia, inertial.inertia.T)
        principal = np.sort(np.linalg.eigvalsh(inertial.inertia))
        assert principal[0] > 0
        assert principal[0] + principal[1] >= principal[2] * (1 - 1e-9)
    obj = build(spec)
    densities = {"body": spec.parts.body_density, "handle": spec.parts.handle_density}
    densities["door"] = spec.parts.door_density
    densities["drawer"] = spec.parts.drawer_density
    for link in obj.links:
        volume = trimesh.Trimesh(link.mesh.vertices, link.mesh.triangles).volume
        assert link.inertial.mass == pytest.approx(densities[link.role] * volume)


def test_union_mesh_merges_touching_boxes_and_box_inertia_is_analytic() -> None:
    boxes = [Box((0.0, 1.0), (0.0, 2.0), (0.0, 3.0)), Box((1.0, 1.5), (0.5, 1.0), (1.0, 2.0))]
    mesh = union_mesh(boxes)
    solid = trimesh.Trimesh(mesh.vertices, mesh.triangles)
    assert solid.is_watertight and solid.body_count == 1
    assert solid.volume == pytest.approx(6.0 + 0.25)
    single = mass_properties(union_mesh(boxes[:1]), density=2.0)
    mass = 12.0
    assert single.mass == pytest.approx(mass)
    np.testing.assert_allclose(single.center_of_mass, [0.5, 1.0, 1.5])
    expected = mass / 12 * np.diag([2**2 + 3**2, 1 + 3**2, 1 + 2**2])
    np.testing.assert_allclose(single.inertia, expected, atol=1e-12)


def test_union_mesh_of_the_same_boxes_again_is_an_equal_independent_copy() -> None:
    """`union_mesh` keeps the meshes of recent boxes (the refinement builds the same parts
    many times): a repeat gives equal arrays that are the caller's own."""
    boxes = [Box((0.0, 0.4), (-0.3, 0.3), (0.0, 0.02)), Box((0.38, 0.4), (-0.3, 0.3), (0.0, 0.5))]
    first = union_mesh(boxes)
    first.vertices[:] = 9.0  # the caller's to change
    again = union_mesh(tuple(boxes))
    assert not np.any(again.vertices == 9.0)
    np.testing.assert_array_equal(again.vertices, union_mesh(list(boxes)).vertices)
    np.testing.assert_array_equal(again.triangles, union_mesh(boxes).triangles)
    assert again.vertices.flags.writeable and again.triangles.flags.writeable
    solid = trimesh.Trimesh(again.vertices, again.triangles)
    assert solid.is_watertight
    assert solid.volume == pytest.approx(0.4 * 0.6 * 0.02 + 0.02 * 0.6 * 0.48)


@pytest.mark.parametrize(("name", "seed"), CASES)
def test_closed_parts_lie_in_the_body_box(make_spec: SpecFactory, name: str, seed: int) -> None:
    spec = make_spec(name, seed)
    obj = build(spec)
    p = spec.parts
    front_reach = p.door_thickness + p.handle_standoff + p.handle_thickness
    lo = np.array([-spec.depth / 2 - front_reach, -spec.width / 2, 0.0]) - 1e-9
    hi = np.array([spec.depth / 2, spec.width / 2, spec.height]) + 1e-9
    q = np.zeros(obj.dof)
    for index in range(len(obj.links)):
        points = _object_frame_vertices(obj, q, index)
        assert np.all(points >= lo) and np.all(points <= hi), obj.links[index].name


@pytest.mark.parametrize(("name", "seed"), CASES)
def test_opening_moves_parts_towards_the_camera(
    make_spec: SpecFactory, name: str, seed: int
) -> None:
    spec = make_spec(name, seed)
    obj = build(spec)
    front = -spec.depth / 2
    for j, joint in enumerate(obj.movable_joints):
        part = obj.link_index(joint.child)
        closed = _object_frame_vertices(obj, np.zeros(obj.dof), part)
        for fraction in (0.25, 0.5, 1.0):
            q = np.zeros(obj.dof)
            q[j] = fraction * joint.limits[1]
            opened = _object_frame_vertices(obj, q, part)
            if joint.type == "prismatic":
                np.testing.assert_allclose(opened[:, 0], closed[:, 0] - q[j])
                np.testing.assert_allclose(opened[:, 1:], closed[:, 1:])
                continue
            # the free edge (farthest from the axis) moves out by about radius * sin(q)
            # (less by the door's thickness, a tenth of a 15 cm cabinet2 door's radius)
            origin = transform_points(obj.joints[2 * j].origin, np.zeros((1, 3)))[0]
            radius = np.linalg.norm(np.cross(closed - origin, joint.axis), axis=1)
            free = np.argmax(radius)
            drop = closed[free, 0] - opened[free, 0]
            assert drop > 0.85 * radius[free] * np.sin(q[j])
            # a door never swings into the body
            assert np.all(opened[:, 0] <= front + 1e-9)


@pytest.mark.parametrize(("name", "seed"), CASES)
def test_handles_move_rigidly_with_their_part(make_spec: SpecFactory, name: str, seed: int) -> None:
    spec = make_spec(name, seed)
    obj = build(spec)
    rng = np.random.default_rng(seed)
    reference = None
    for _ in range(4):
        q = np.array([rng.uniform(*limits) for limits in spec.joint_limits])
        poses = obj.link_poses(q)
        relative = [invert(poses[2 * k + 1]) @ poses[2 * k + 2] for k in range(obj.dof)]
        if reference is None:
            reference = relative
        for got, want in zip(relative, reference, strict=True):
            np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.parametrize("name", CATEGORY_NAMES)
def test_build_is_deterministic(make_spec: SpecFactory, name: str) -> None:
    spec = make_spec(name, 5)
    a, b = build(spec), build(ObjectSpec.model_validate_json(spec.model_dump_json()))
    for la, lb in zip(a.links, b.links, strict=True):
        np.testing.assert_array_equal(la.mesh.vertices, lb.mesh.vertices)
        np.testing.assert_array_equal(la.mesh.triangles, lb.mesh.triangles)
        assert la.inertial.mass == lb.inertial.mass


def test_mass_properties_are_computed_when_first_read(make_spec: SpecFactory):
    import pickle

    # building an object to render it reads no mass property: no trimesh import (a fresh
    # interpreter; this one has trimesh loaded)
    code = (
        "import json, sys\n"
        "from artic.objects.categories import build\n"
        "from artic.objects.spec import ObjectSpec, PartsConfig, Pose\n"
        "spec = ObjectSpec(category='microwave', index=0, dof=1, joint_type='revolute',\n"
        "    depth=0.4, width=0.6, height=0.35, chirality=1, pose=Pose(x=1.4, y=0, z=0, yaw=0),\n"
        "    joint_limits=((0.0, 1.5),), parts=PartsConfig())\n"
        "obj = build(spec)\n"
        "before = 'trimesh' in sys.modules\n"
        "mass = obj.links[0].inertial.mass\n"
        "print(json.dumps([before, 'trimesh' in sys.modules, mass > 0]))"
    )
    assert in_fresh_python(code) == [False, True, True]
    # the values read are mass_properties' own, also after a pickle round trip unread
    obj = build(make_spec("cabinet2", 0))
    unread = pickle.loads(pickle.dumps(obj))
    for link, copied in zip(obj.links, unread.links, strict=True):
        eager = mass_properties(link.mesh, 500.0)
        lazy = lazy_mass_properties(link.mesh, 500.0)
        assert (lazy.mass, lazy.center_of_mass.tolist(), lazy.inertia.tolist()) == (
            eager.mass, eager.center_of_mass.tolist(), eager.inertia.tolist())  # fmt: skip
        assert copied.inertial.mass == link.inertial.mass
        assert np.array_equal(copied.inertial.inertia, link.inertial.inertia)
        assert np.array_equal(copied.inertial.center_of_mass, link.inertial.center_of_mass)


@pytest.mark.parametrize("seed", SEEDS)
def test_an_overlay_drawer_front_covers_the_body_front_and_keeps_the_joint(
    make_spec: SpecFactory, seed: int
) -> None:
    """`parts.drawer_front = "overlay"`: a plate `door_thickness` thick stands in front of
    the body's front when shut, its back face on it, covering it but `gap` round its edge;
    the joint (origin, axis, limits) and every other box of the drawer are the inset
    drawer's, and the handle stands on the plate's face."""
    spec = make_spec("drawer", seed)
    p = spec.parts
    overlay = spec.model_copy(update={"parts": p.model_copy(update={"drawer_front": "overlay"})})
    inset_obj, overlay_obj = build(spec), build(overlay)
    (ji,), (jo,) = inset_obj.movable_joints, overlay_obj.movable_joints
    np.testing.assert_array_equal(ji.origin, jo.origin)
    np.testing.assert_array_equal(ji.axis, jo.axis)
    assert ji.limits == jo.limits
    part = overlay_obj.link_index(jo.child)
    closed = _object_frame_vertices(overlay_obj, np.zeros(1), part)
    front = -spec.depth / 2
    low = [front - p.door_thickness, -spec.width / 2 + p.gap, p.gap]
    np.testing.assert_allclose(closed.min(axis=0), low, atol=1e-8)
    high = [spec.width / 2 - p.gap, spec.height - p.gap]
    np.testing.assert_allclose(closed[:, 1:].max(axis=0), high, atol=1e-8)
    # nothing of the drawer but the plate lies in front of the body
    inset_part = _object_frame_vertices(inset_obj, np.zeros(1), part)
    assert inset_part[:, 0].min() == pytest.approx(front, abs=1e-8)
    handle = part + 1
    shift = (_object_frame_vertices(overlay_obj, np.zeros(1), handle)
             - _object_frame_vertices(inset_obj, np.zeros(1), handle))  # fmt: skip
    np.testing.assert_allclose(shift, np.tile([-p.door_thickness, 0.0, 0.0], (len(shift), 1)),
                               atol=1e-8)  # fmt: skip
