"""A kinematic model for planning from one rendered depth view (Chapter 3 -> Chapter 5).

Algorithm 2 plans on an *estimated* model of the object. `perceive` estimates it the way
a robot would, with the Chapter 3 network (`artic predict`'s `Predictor`): the TRUE
object (the simulator's model) is rendered by ray casting at its start configuration
from a camera placed in the task's world, with the Kinect noise model of the training
data, and the MDN's estimate (section 3.3.1, most likely component; or 3.3.2, max-point)
is turned back into an `ArticulatedObject` in the world frame.

Frames: the MDN's camera frame is x forward (optical axis), y left, z up (Appendix A), so
the camera in the world is *level*: a position and a yaw about world +z, no roll or
pitch. `camera_to_world` (4, 4) maps camera-frame points to world points.

Label -> model (`labels_to_model`): the planner needs the handle link's forward
kinematics, so the predicted model is `artic.objects.categories.build` of an
`ObjectSpec` rebuilt from the predicted geometry (depth, width, height, chirality, base
pose), which gives the same links (handle included) as the true model; then every
movable joint's axis origin and direction are set to the predicted ones (the part and its
handle hang on the joint frame, so they move with it, as in `models.perturb_model`);
finally the predicted configuration is folded into the joint origin, so that the task's
start configuration q_O(0) puts the part where the network sees it:
f_pred(q) = f(q + q_pred - q_O(0)). The part-origin labels (`j*_part_*`) are not used:
the builder places the part from the predicted geometry. Joint limits, part constants
and dynamics are the task's (the network does not predict them).

Pure library code: no file access, no PyBullet; Open3D (ray casting) and torch (through
the predictor) are imported lazily.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from artic.geometry.transforms import invert, make_transform, rot_z, yaw_of
from artic.objects.labels import joint_column, joint_vector
from artic.objects.model import ArticulatedObject
from artic.objects.spec import GeometryRanges, ObjectSpec, Pose, PoseRanges

if TYPE_CHECKING:
    from artic.geometry.camera import CameraIntrinsics
    from artic.kinematics import Estimator
    from artic.kinematics.predict import Predictor
    from artic.render.noise import SensorNoiseConfig

Array = NDArray[np.float64]


def level_camera(position: Sequence[float], yaw: float) -> Array:
    """(4, 4) camera-to-world transform of a level camera at `position` (3,) m, looking
    along world (cos yaw, sin yaw, 0), z up."""
    return make_transform(rot_z(float(yaw)), np.asarray(position, dtype=np.float64))


def centred_camera(base_pose_world: Array, ranges: PoseRanges) -> Array:
    """The level camera that sees the object's base at the middle of `ranges` (Table A.2:
    mid x, y, z and yaw in the camera frame). base_pose_world: (4, 4), z axis vertical."""
    mid = [0.5 * (lo + hi) for lo, hi in (ranges.x, ranges.y, ranges.z, ranges.yaw)]
    base_in_camera = make_transform(rot_z(mid[3]), np.array(mid[:3]))
    return np.asarray(base_pose_world @ invert(base_in_camera))


def in_frame(model: ArticulatedObject, frame_to_world: Array) -> ArticulatedObject:
    """`model` (base pose in the world) expressed in the frame `frame_to_world` (4, 4)."""
    return dataclasses.replace(model, base_pose=invert(frame_to_world) @ model.base_pose)


def to_world(model: ArticulatedObject, frame_to_world: Array) -> ArticulatedObject:
    """`model` (base pose in the frame) expressed in the world."""
    return dataclasses.replace(model, base_pose=frame_to_world @ model.base_pose)


def pose_in_camera(base_pose_world: Array, camera_to_world: Array) -> Pose:
    """The object's base pose in the camera frame as Table A.2's (x, y, z, yaw).
    ValueError if the object is not upright in the camera frame (its z not vertical)."""
    local = invert(camera_to_world) @ base_pose_world
    if abs(local[2, 2] - 1.0) > 1e-6:
        raise ValueError("the object's z axis is not vertical in the camera frame")
    x, y, z = (float(v) for v in local[:3, 3])
    return Pose(x=x, y=y, z=z, yaw=yaw_of(local[:3, :3]))


def view_problems(
    pose: Pose, ranges: PoseRanges, spec: ObjectSpec, camera: CameraIntrinsics
) -> list[str]:
    """Why the MDN was not trained on this view (empty if it was): each of the base pose's
    x, y, z, yaw (camera frame) outside its Table A.2 range, and, as the dataset's
    sampler requires, the body's centre behind the camera or projecting outside the image."""
    problems = []
    for name in ("x", "y", "z", "yaw"):
        value, (lo, hi) = getattr(pose, name), getattr(ranges, name)
        if not lo - 1e-9 <= value <= hi + 1e-9:
            problems.append(f"object {name} in the camera frame {value:.3f} not in [{lo}, {hi}]")
    centre = pose.matrix() @ np.array([0.0, 0.0, spec.height / 2, 1.0])
    if centre[0] <= 0:
        problems.append("the object is behind the camera")
    else:
        u, v = camera.project(centre[None, :3])[0]
        if not (0 <= u <= camera.width - 1 and 0 <= v <= camera.height - 1):
            problems.append(
                f"the object's centre projects to pixel ({u:.0f}, {v:.0f}), outside the image"
            )
    return problems


class RenderedView(NamedTuple):
    """One view of the object: depth (H, W) float32 metres (0 = no return) with the
    sensor model, the clean depth, and the part mask (H, W) uint8 (link index + 1)."""

    depth: NDArray[np.float32]
    clean: NDArray[np.float32]
    mask: NDArray[np.uint8]


def render_view(
    model_in_camera: ArticulatedObject,
    configuration: Array,
    camera: CameraIntrinsics,
    noise: SensorNoiseConfig,
    rng: np.random.Generator,
) -> RenderedView:
    """Ray-cast `model_in_camera` (base pose in the camera frame) at `configuration`
    (dof,) with the `camera` intrinsics, then apply the sensor model (docs/rendering.md)
    drawing from `rng`."""
    from artic.render.backend import make_backend
    from artic.render.noise import apply_sensor_noise

    with make_backend("raycast", camera, threads=1) as backend:
        image = backend.render(model_in_camera, np.asarray(configuration, dtype=np.float64))
    depth = apply_sensor_noise(image.depth, noise, rng, camera.fx)
    return RenderedView(depth, image.depth, image.part_mask)


def _clip(value: float, bounds: tuple[float, float] | None, floor: float) -> float:
    lo, hi = bounds if bounds is not None else (floor, np.inf)
    return float(np.clip(value, max(lo, floor), hi))


def spec_from_labels(
    labels: Mapping[str, float],
    template: ObjectSpec,
    geometry: GeometryRanges | None = None,
    chiralities: Sequence[int] = (-1, 1),
) -> ObjectSpec:
    """`template` (category, part constants, joint limits) with the labels' geometry:
    depth, width, height (clipped to `geometry`, and large enough for the walls),
    chirality (the label's sign, if in `chiralities`, else the template's) and base pose
    (camera frame)."""
    p = template.parts
    walls = 2.0 * (p.panel_thickness + p.gap) + p.door_thickness + 0.01
    sizes = {
        name: _clip(labels[name], getattr(geometry, name) if geometry else None, walls)
        for name in ("depth", "width", "height")
    }
    side = 1 if labels["chirality"] >= 0 else -1
    pose = Pose(**{k: float(labels[f"pose_{k}"]) for k in ("x", "y", "z", "yaw")})
    return template.model_copy(
        update={
            **sizes,
            "chirality": side if side in chiralities else template.chirality,
            "pose": pose,
        }
    )


def labels_to_model(
    labels: Mapping[str, float],
    template: ObjectSpec,
    start: Array,
    geometry: GeometryRanges | None = None,
    chiralities: Sequence[int] = (-1, 1),
) -> ArticulatedObject:
    """The model (camera frame) a label vector describes (module docstring): build of
    `spec_from_labels`, each movable joint's origin and direction set to `j*_origin_*`
    and `j*_direction_*`, and its configuration offset so that q = `start` (dof,) is the
    labelled `j*_q`. Same links and joints as `build(template)`."""
    from artic.objects.categories import build

    obj = build(spec_from_labels(labels, template, geometry, chiralities))
    start = np.asarray(start, dtype=np.float64).reshape(-1)
    rest = obj.link_poses(start)
    joints = list(obj.joints)
    movable = [k for k, joint in enumerate(obj.joints) if joint.type != "fixed"]
    for j, k in enumerate(movable):
        joint = joints[k]
        parent = rest[obj.link_index(joint.parent)]
        origin = joint.origin.copy()
        point = np.array([labels[c] for c in joint_vector(j, "origin")], dtype=np.float64)
        origin[:3, 3] = (invert(parent) @ np.append(point, 1.0))[:3]
        direction = np.array([labels[c] for c in joint_vector(j, "direction")], dtype=np.float64)
        norm = float(np.linalg.norm(direction))
        axis = joint.axis
        if norm > 1e-9:  # a degenerate prediction keeps the built axis
            axis = (parent @ origin)[:3, :3].T @ (direction / norm)
        moved = dataclasses.replace(joint, axis=axis, origin=origin)
        shift = float(labels[joint_column(j, "q")]) - float(start[j])
        joints[k] = dataclasses.replace(moved, origin=origin @ moved.motion(shift))
    return dataclasses.replace(obj, joints=tuple(joints))


def axis_errors(
    predicted: Mapping[str, float], true: Mapping[str, float], dof: int, joint_type: str
) -> dict[str, list[float]]:
    """Per joint: axis position error (distance between the axis origins, cm), direction
    error (angle between the unit directions, deg) and configuration error (|q_pred -
    q_true|, deg for revolute or cm for prismatic joints, as Table 3.1)."""
    position, direction, configuration = [], [], []
    scale = np.degrees(1.0) if joint_type == "revolute" else 100.0
    for j in range(dof):
        o, d, q = joint_vector(j, "origin"), joint_vector(j, "direction"), joint_column(j, "q")
        a = np.array([predicted[c] for c in d])
        b = np.array([true[c] for c in d])
        cos = a @ b / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-12)
        position.append(100.0 * float(np.linalg.norm([predicted[c] - true[c] for c in o])))
        direction.append(float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))))
        configuration.append(scale * abs(predicted[q] - true[q]))
    return {
        "axis_position_error_cm": position,
        "axis_direction_error_deg": direction,
        "configuration_error": configuration,
    }


class Perception(NamedTuple):
    """What `perceive` saw and estimated.

    model: the predicted model, world frame. view: the rendered image. predicted, true:
    label vectors (camera frame) by column name. errors: `axis_errors`. refinement: what
    the geometric refinement did (`artic predict`'s "refinement" record).
    """

    model: ArticulatedObject
    view: RenderedView
    predicted: dict[str, float]
    true: dict[str, float]
    errors: dict[str, list[float]]
    refinement: dict[str, Any]


def perceive(
    true_model: ArticulatedObject,
    spec: ObjectSpec,
    start: Array,
    camera_to_world: Array,
    predictor: Predictor,
    noise: SensorNoiseConfig,
    rng: np.random.Generator,
    estimator: Estimator = "most-likely",
    geometry: GeometryRanges | None = None,
    chiralities: Sequence[int] = (-1, 1),
    refine: bool = True,
) -> Perception:
    """Render `true_model` (world frame; built from `spec`, whose pose is ignored) at
    `start` (dof,) from the level camera `camera_to_world` in the predictor's training
    camera, estimate its labels (geometrically refined when `refine`, as `artic predict`
    does), and rebuild the model in the world frame."""
    from artic.objects.labels import image_labels

    start = np.asarray(start, dtype=np.float64).reshape(-1)
    pose = pose_in_camera(true_model.base_pose, camera_to_world)
    true_spec = spec.model_copy(update={"pose": pose})
    seen = in_frame(true_model, camera_to_world)
    view = render_view(seen, start, predictor.camera, noise, rng)
    if not (view.depth > 0).any():
        raise ValueError("the rendered view has no depth returns")
    estimate, refinement = predictor.estimate_refined(view.depth, None, estimator, refine)
    predicted = {c: float(v) for c, v in zip(predictor.codec.columns, estimate, strict=True)}
    true = image_labels(true_spec, seen, start)
    model = labels_to_model(predicted, spec, start, geometry, chiralities)
    errors = axis_errors(predicted, true, spec.dof, spec.joint_type)
    return Perception(to_world(model, camera_to_world), view, predicted, true, errors, refinement)


def summary(perception: Perception, digits: int = 6) -> dict[str, Any]:
    """The JSON-ready record of a perception: errors and the predicted geometry."""
    p = perception.predicted

    def r(values: Sequence[float]) -> list[float]:
        return [round(float(v), digits) for v in values]

    return {
        **{k: r(v) for k, v in perception.errors.items()},
        "valid_pixels": int((perception.view.depth > 0).sum()),
        "refinement": perception.refinement,
        "predicted": {k: round(v, digits) for k, v in p.items()},
        "true": {k: round(v, digits) for k, v in perception.true.items()},
    }
