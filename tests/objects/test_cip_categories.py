"""The Chapter 7 mechanisms `slide` and `lever` (thesis section 7.4): registry, spec and
config, watertight parts, knob motion, URDF in PyBullet, labels and grasp geometry."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pybullet
import pytest
import trimesh
import yaml
from scipy.spatial.transform import Rotation

from artic.geometry.camera import CameraIntrinsics
from artic.geometry.transforms import invert, transform_points
from artic.objects.categories import CATEGORIES, build
from artic.objects.families import parse_spec
from artic.objects.labels import image_labels, label_columns
from artic.objects.model import ArticulatedObject
from artic.objects.spec import CategoryConfig, ObjectSpec, PartsConfig, Pose, sample_spec
from artic.objects.urdf import write_urdf
from artic.sim.bullet import connect_direct
from urdf_folder import write_urdf_folder

CATEGORY_DIR = Path(__file__).resolve().parents[2] / "conf" / "common" / "category"
NAMES = ("slide", "lever")
MOVING = {"slide": ("slider_0", "slider"), "lever": ("lever_0", "lever")}
SEEDS = (0, 1, 2, 3)
CASES = [(name, seed) for name in NAMES for seed in SEEDS]
LEVER_SUCCESS = 1.57  # rad, beta_c of the released code's lever task (docs/cip.md)
PYBULLET_TYPES = {
    "revolute": pybullet.JOINT_REVOLUTE,
    "prismatic": pybullet.JOINT_PRISMATIC,
    "fixed": pybullet.JOINT_FIXED,
}


@pytest.fixture(scope="module")
def cip_configs() -> dict[str, CategoryConfig]:
    """conf/common/category/{slide,lever}.yaml, validated."""
    return {
        name: CategoryConfig.model_validate(
            yaml.safe_load((CATEGORY_DIR / f"{name}.yaml").read_text())
        )
        for name in NAMES
    }


def _spec(cfg: CategoryConfig, camera: CameraIntrinsics, seed: int) -> ObjectSpec:
    return sample_spec(cfg, camera, seed, np.random.default_rng(seed))


@pytest.fixture(scope="module")
def sim() -> Iterator[Any]:
    """A PyBullet client in DIRECT mode (`pybullet_utils.bullet_client.BulletClient`)."""
    client = connect_direct()
    yield client
    client.disconnect()


def _object_frame(obj: ArticulatedObject, q: float, link: int) -> np.ndarray:
    """(4, 4) pose of link `link` at configuration q in the object (body) frame."""
    return invert(obj.base_pose) @ obj.link_poses(np.array([q]))[link]


def _knob_centre(obj: ArticulatedObject, q: float) -> np.ndarray:
    """(3,) centre of the knob's (`handle_0`) bounding box at q, object frame."""
    link = obj.link_index("handle_0")
    vertices = obj.links[link].mesh.vertices
    centre = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    return transform_points(_object_frame(obj, q, link), centre[None])[0]


def _axis(obj: ArticulatedObject) -> tuple[np.ndarray, np.ndarray]:
    """(origin, unit direction) of the movable joint in the object frame."""
    frame = invert(obj.base_pose) @ obj.joint_frames(np.zeros(1))[0]
    direction = frame[:3, :3] @ obj.movable_joints[0].axis
    return frame[:3, 3], direction / np.linalg.norm(direction)


def _load(sim: Any, path: Path, obj: ArticulatedObject) -> int:
    """Load the URDF at `path` into `sim` at the object's base pose, base fixed."""
    pose = obj.base_pose
    return int(
        sim.loadURDF(
            str(path),
            basePosition=pose[:3, 3].tolist(),
            baseOrientation=Rotation.from_matrix(pose[:3, :3]).as_quat().tolist(),
            useFixedBase=True,
        )
    )


def test_both_are_registered_beside_the_appendix_a_categories() -> None:
    assert {"slide", "lever", "cabinet", "drawer"} <= set(CATEGORIES)


@pytest.mark.parametrize("name", NAMES)
def test_configs_declare_the_mechanisms(cip_configs: dict[str, CategoryConfig], name: str) -> None:
    cfg = cip_configs[name]
    assert (cfg.name, cfg.dof) == (name, 1)
    assert sorted(cfg.chirality) == [-1, 1]
    if name == "slide":
        assert cfg.joint_type == "prismatic" and cfg.configuration == (0.0, 0.2)
    else:
        assert cfg.joint_type == "revolute" and cfg.configuration[0] == 0.0
        # beta_c (1.57 rad) lies inside the range, short of the stop
        assert LEVER_SUCCESS < cfg.configuration[1] < 2.0


@pytest.mark.parametrize(("name", "seed"), CASES)
def test_links_joints_and_the_handle_in_part_order(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, name: str, seed: int
) -> None:
    spec = _spec(cip_configs[name], camera, seed)
    obj = build(spec)
    part, role = MOVING[name]
    assert [link.name for link in obj.links] == ["body", part, "handle_0"]
    assert [link.role for link in obj.links] == ["body", role, "handle"]
    assert obj.parent_indices() == [-1, 0, 1]
    assert obj.link_index("handle_0") == 2
    joint, fixed = obj.joints
    assert (joint.name, joint.type, joint.parent, joint.child) == ("joint_0", spec.joint_type,
                                                                   "body", part)  # fmt: skip
    assert joint.limits == spec.joint_limits[0]
    assert (fixed.name, fixed.type, fixed.parent, fixed.child) == ("handle_0_fixed", "fixed",
                                                                   part, "handle_0")  # fmt: skip
    expected_axis = [0.0, spec.chirality, 0.0] if name == "slide" else [-spec.chirality, 0, 0]
    np.testing.assert_array_equal(joint.axis, expected_axis)
    np.testing.assert_allclose(obj.base_pose, spec.pose.matrix())


@pytest.mark.parametrize(("name", "seed"), CASES)
def test_spec_round_trips_through_json_and_builds_the_same_bytes(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, name: str, seed: int
) -> None:
    spec = _spec(cip_configs[name], camera, seed)
    text = spec.model_dump_json()
    again = ObjectSpec.model_validate_json(text)
    assert again == spec and again.model_dump_json() == text
    assert parse_spec(text) == spec
    assert write_urdf(build(spec)) == write_urdf(build(again))


@pytest.mark.parametrize(("name", "seed"), CASES)
def test_parts_are_watertight_solids_with_their_densities(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, name: str, seed: int
) -> None:
    spec = _spec(cip_configs[name], camera, seed)
    p = spec.parts
    density = {"body": p.body_density, "handle": p.handle_density}
    density[MOVING[name][1]] = p.door_density
    for link in build(spec).links:
        mesh = trimesh.Trimesh(link.mesh.vertices, link.mesh.triangles)
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.body_count == 1
        assert mesh.volume > 0
        assert link.inertial.mass == pytest.approx(density[link.role] * mesh.volume)
        assert np.all(np.linalg.eigvalsh(link.inertial.inertia) > 0)


@pytest.mark.parametrize("name", NAMES)
def test_samples_lie_inside_the_declared_ranges_and_build(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, name: str
) -> None:
    cfg = cip_configs[name]
    chiralities = set()
    for seed in range(40):
        spec = _spec(cfg, camera, seed)
        assert (spec.category, spec.index, spec.dof, spec.joint_type) == (
            name, seed, 1, cfg.joint_type)  # fmt: skip
        for value, (lo, hi) in (
            (spec.depth, cfg.geometry.depth),
            (spec.width, cfg.geometry.width),
            (spec.height, cfg.geometry.height),
            *((getattr(spec.pose, a), getattr(cfg.pose, a)) for a in ("x", "y", "z", "yaw")),
        ):
            assert lo <= value <= hi
        assert spec.joint_limits == (cfg.configuration,)
        assert spec.parts == cfg.parts
        chiralities.add(spec.chirality)
        assert build(spec).dof == 1  # every sample has room for its travel
    assert chiralities == {-1, 1}


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_spec(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, name: str
) -> None:
    cfg = cip_configs[name]
    assert _spec(cfg, camera, 7) == _spec(cfg, camera, 7)
    assert _spec(cfg, camera, 7) != _spec(cfg, camera, 8)


@pytest.mark.parametrize("name", NAMES)
def test_the_knob_is_graspable_by_a_parallel_jaw(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, name: str
) -> None:
    obj = build(_spec(cip_configs[name], camera, 0))
    vertices = obj.links[obj.link_index("handle_0")].mesh.vertices
    reach, across, along = vertices.max(axis=0) - vertices.min(axis=0)
    assert 0.02 <= across <= 0.03  # between the fingers
    assert across < along <= 0.05
    assert 0.03 <= reach <= 0.05  # stands off its part, towards the camera
    assert vertices[:, 0].max() == 0.0 and vertices[:, 0].min() < 0.0


def test_the_lever_arm_spans_its_declared_lengths(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics
) -> None:
    """The knob's distance from the axis (the lever's length) over the sampled objects."""
    cfg = cip_configs["lever"]
    lengths = []
    for seed in range(40):
        obj = build(_spec(cfg, camera, seed))
        origin, direction = _axis(obj)
        offset = _knob_centre(obj, 0.0) - origin
        lengths.append(np.linalg.norm(offset - offset.dot(direction) * direction))
    assert min(lengths) >= 0.15 and max(lengths) <= 0.30


@pytest.mark.parametrize("seed", SEEDS)
def test_slide_knob_moves_q_along_the_rail(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, seed: int
) -> None:
    spec = _spec(cip_configs["slide"], camera, seed)
    obj = build(spec)
    knob = obj.link_index("handle_0")
    lower, upper = spec.joint_limits[0]
    closed = _object_frame(obj, lower, knob)
    rail = np.array([0.0, spec.chirality, 0.0])
    for q in np.linspace(lower, upper, 5):
        moved = _object_frame(obj, q, knob)
        np.testing.assert_allclose(moved[:3, 3] - closed[:3, 3], (q - lower) * rail, atol=1e-12)
        np.testing.assert_allclose(moved[:3, :3], closed[:3, :3], atol=1e-12)
        # in the camera frame the same translation, rotated by the yaw
        world = obj.link_poses(np.array([q]))[knob][:3, 3]
        start = obj.link_poses(np.array([lower]))[knob][:3, 3]
        np.testing.assert_allclose(world - start, (q - lower) * (obj.base_pose[:3, :3] @ rail))
    # the travel is centred on the front
    ends = [_knob_centre(obj, q)[1] for q in (lower, upper)]
    assert ends[0] == pytest.approx(-ends[1]) and abs(ends[1] - ends[0]) == pytest.approx(upper)


@pytest.mark.parametrize("seed", SEEDS)
def test_lever_knob_turns_q_about_the_axis_at_a_constant_radius(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, seed: int
) -> None:
    spec = _spec(cip_configs["lever"], camera, seed)
    obj = build(spec)
    origin, direction = _axis(obj)
    np.testing.assert_allclose(direction, [-spec.chirality, 0.0, 0.0], atol=1e-12)

    def radial(q: float) -> np.ndarray:
        offset = _knob_centre(obj, q) - origin
        return offset - offset.dot(direction) * direction

    start = radial(0.0)
    radius = np.linalg.norm(start)
    assert start[2] == pytest.approx(radius)  # up at q = 0
    for q in np.linspace(*spec.joint_limits[0], 7):
        now = radial(q)
        assert np.linalg.norm(now) == pytest.approx(radius, abs=1e-12)
        angle = math.atan2(direction @ np.cross(start, now), start @ now)
        assert angle == pytest.approx(q, abs=1e-12)
    # a quarter turn brings the knob level with the axis, on the chirality side
    quarter = radial(math.pi / 2)
    np.testing.assert_allclose(quarter, np.array([0.0, spec.chirality * radius, 0.0]), atol=1e-12)


@pytest.mark.parametrize(("name", "seed"), CASES)
def test_moving_parts_stay_in_front_of_the_body_face(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, name: str, seed: int
) -> None:
    """Across the joint range the carriage or arm and the knob stay clear of the body
    (in front of its front face) and inside the front face's outline."""
    spec = _spec(cip_configs[name], camera, seed)
    obj = build(spec)
    front = -spec.depth / 2
    for q in np.linspace(*spec.joint_limits[0], 9):
        for link in (1, 2):
            points = transform_points(_object_frame(obj, q, link), obj.links[link].mesh.vertices)
            assert np.all(points[:, 0] <= front + 1e-12), obj.links[link].name
            assert np.all(np.abs(points[:, 1]) <= spec.width / 2 + 1e-12)
            assert np.all((points[:, 2] >= -1e-12) & (points[:, 2] <= spec.height + 1e-12))
        body = obj.links[0].mesh.vertices
        carriage = transform_points(_object_frame(obj, q, 1), obj.links[1].mesh.vertices)
        assert carriage[:, 0].max() < body[:, 0].min()  # a gap from the rail / block


@pytest.mark.parametrize("name", NAMES)
def test_labels_of_the_mechanisms(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, name: str
) -> None:
    spec = _spec(cip_configs[name], camera, 1)
    obj = build(spec)
    rotation = spec.pose.matrix()[:3, :3]
    local = [0.0, spec.chirality, 0.0] if name == "slide" else [-spec.chirality, 0.0, 0.0]
    first = image_labels(spec, obj, np.array([0.0]))
    for q in np.linspace(*spec.joint_limits[0], 3):
        labels = image_labels(spec, obj, np.array([q]))
        assert list(labels) == label_columns(1) and labels["j0_q"] == q
        direction = [labels[f"j0_direction_{a}"] for a in "xyz"]
        np.testing.assert_allclose(direction, rotation @ np.array(local), atol=1e-12)
        for key in [f"j0_{v}_{a}" for v in ("origin", "part") for a in "xyz"]:
            assert labels[key] == first[key]  # fixed to the body, independent of q


@pytest.mark.parametrize("name", NAMES)
def test_pybullet_loads_the_urdf_with_its_joint_and_limits(
    cip_configs: dict[str, CategoryConfig],
    camera: CameraIntrinsics,
    sim: Any,
    tmp_path: Path,
    name: str,
) -> None:
    spec = _spec(cip_configs[name], camera, 2)
    obj = build(spec)
    body = _load(sim, write_urdf_folder(obj, tmp_path), obj)
    assert sim.getNumJoints(body) == 2
    for j, joint in enumerate(obj.joints):
        info = sim.getJointInfo(body, j)
        assert (info[1].decode(), info[12].decode()) == (joint.name, obj.links[j + 1].name)
        assert info[2] == PYBULLET_TYPES[joint.type]
    info = sim.getJointInfo(body, 0)
    assert (info[8], info[9]) == pytest.approx(spec.joint_limits[0])
    np.testing.assert_allclose(info[13], obj.joints[0].axis)
    rng = np.random.default_rng(0)
    for q in [*spec.joint_limits[0], rng.uniform(*spec.joint_limits[0])]:
        sim.resetJointState(body, 0, q)
        expected = obj.link_poses(np.array([q]))
        for j in range(2):
            state = sim.getLinkState(body, j, computeForwardKinematics=True)
            np.testing.assert_allclose(state[4], expected[j + 1][:3, 3], atol=1e-6)
            rotation = Rotation.from_quat(state[5]).as_matrix()
            np.testing.assert_allclose(rotation, expected[j + 1][:3, :3], atol=1e-6)
    sim.removeBody(body)


def _driven_to_the_stop(sim: Any, body: int, spec: ObjectSpec) -> float:
    """The joint value after driving joint 0 past its range for 1 s (240 Hz, no gravity)
    at its effort limit; `sim` a BulletClient."""
    sim.setGravity(0.0, 0.0, 0.0)
    sim.resetJointState(body, 0, spec.joint_limits[0][0])
    sim.setJointMotorControl2(
        body,
        0,
        sim.VELOCITY_CONTROL,
        targetVelocity=5.0 * spec.parts.joint_velocity,
        force=spec.parts.joint_effort,
    )
    for _ in range(240):
        sim.stepSimulation()
    return float(sim.getJointState(body, 0)[0])


@pytest.mark.parametrize("name", NAMES)
def test_pybullet_holds_the_joint_limits(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, tmp_path: Path, name: str
) -> None:
    """Loaded from the URDF file and by `artic.sim.scene.load_articulated` (the
    environments' path, no files), the joint driven past its range stops at its upper
    limit; the in-memory body has the same joints and kinematics."""
    from artic.sim.scene import load_articulated

    spec = _spec(cip_configs[name], camera, 3)
    obj = build(spec)
    upper = spec.joint_limits[0][1]
    path = write_urdf_folder(obj, tmp_path)
    for loader in ("urdf", "memory"):
        sim = connect_direct()
        try:
            body = _load(sim, path, obj) if loader == "urdf" else load_articulated(sim, obj)
            assert sim.getNumJoints(body) == 2
            assert [sim.getJointInfo(body, j)[2] for j in range(2)] == [
                PYBULLET_TYPES[spec.joint_type], pybullet.JOINT_FIXED]  # fmt: skip
            sim.resetJointState(body, 0, upper)
            knob = sim.getLinkState(body, 1, computeForwardKinematics=True)[4]
            np.testing.assert_allclose(knob, obj.link_poses(np.array([upper]))[2][:3, 3], atol=1e-6)
            q = _driven_to_the_stop(sim, body, spec)
            assert 0.98 * upper <= q <= 1.01 * upper, loader
        finally:
            sim.disconnect()


@pytest.mark.parametrize("name", NAMES)
def test_the_handle_grasp_finds_the_knob(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics, name: str
) -> None:
    """Chapter 5's EstimateGrasp reads the knob as it reads a handle bar: approach into
    the front (+x of the knob's frame), the tool's x along the knob's long side (z), so a
    parallel jaw closes across its narrow side; the grasp point is on the knob."""
    from artic.planning.grasp import estimate_grasp
    from artic.sim.scene import handle_grasp_point

    spec = _spec(cip_configs[name], camera, 0)
    obj = build(spec)
    link = obj.link_index("handle_0")
    for q in spec.joint_limits[0]:
        grasp = estimate_grasp(obj, link, np.array([q]), kind="handle")
        np.testing.assert_allclose(grasp.approach, [1.0, 0.0, 0.0])
        np.testing.assert_allclose(np.abs(grasp.offset[:3, 0]), [0.0, 0.0, 1.0], atol=1e-12)
    mesh = obj.links[link].mesh
    point = handle_grasp_point(mesh, spec.parts.handle_thickness)
    assert np.all(point >= mesh.vertices.min(axis=0)) and np.all(point <= mesh.vertices.max(axis=0))


def test_the_lever_friction_holds_the_arm_against_gravity(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics
) -> None:
    """lever.yaml's joint friction exceeds the largest gravity torque of arm and knob
    (arm level, the largest sampled lever), so a released lever keeps its angle."""
    cfg = cip_configs["lever"]
    worst = 0.0
    for seed in range(40):
        obj = build(_spec(cfg, camera, seed))
        origin, _ = _axis(obj)
        torque = 0.0
        for link in (1, 2):
            inertial = obj.links[link].inertial
            centre = transform_points(
                _object_frame(obj, math.pi / 2, link), inertial.center_of_mass[None]
            )[0]
            torque += inertial.mass * 9.81 * abs(centre[1] - origin[1])
        worst = max(worst, torque)
    assert 0.0 < worst < cfg.parts.joint_friction


@pytest.mark.parametrize("name", NAMES)
def test_default_parts_build_too(name: str) -> None:
    """With `PartsConfig()` (the environments' defaults) the knob is a handle-section
    block (`handle_thickness` across) on a 2 `handle_inset` carriage or arm."""
    parts = PartsConfig()
    spec = ObjectSpec(
        category=name, index=0, dof=1, joint_type="prismatic" if name == "slide" else "revolute",
        depth=0.15, width=0.5, height=0.5, chirality=1, pose=Pose(x=1.2, y=0.0, z=0.3, yaw=0.0),
        joint_limits=((0.0, 0.2 if name == "slide" else 1.75),), parts=parts,
    )  # fmt: skip
    obj = build(spec)
    knob = obj.links[2].mesh.vertices
    extent = knob.max(axis=0) - knob.min(axis=0)
    np.testing.assert_allclose(
        extent,
        [parts.handle_standoff + parts.handle_thickness, parts.handle_thickness,
         parts.handle_fraction * 2 * parts.handle_inset],
    )  # fmt: skip
    for link in obj.links:
        assert trimesh.Trimesh(link.mesh.vertices, link.mesh.triangles).is_watertight


def test_a_front_too_small_for_the_mechanism_raises(
    cip_configs: dict[str, CategoryConfig], camera: CameraIntrinsics
) -> None:
    slide = _spec(cip_configs["slide"], camera, 0)
    narrow = slide.model_copy(update={"width": 0.2})  # < 0.2 m travel + 6 cm carriage
    with pytest.raises(ValueError, match="width"):
        build(narrow)
    lever = _spec(cip_configs["lever"], camera, 0)
    small = lever.model_copy(update={"width": 0.1})  # no room for an arm
    with pytest.raises(ValueError, match="width"):
        build(small)
    thick = lever.parts.model_copy(update={"handle_thickness": 0.1})  # wider than the arm
    fat = lever.model_copy(update={"parts": thick})
    with pytest.raises(ValueError, match="handle_thickness"):
        build(fat)
