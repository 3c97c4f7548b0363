"""Kinematic model sources for planning: the object's C_O and forward kinematics f_O.

Algorithm 2 plans with an *estimated* object model. Sources:
- "true": the simulated object's own model (what a perfect estimator would return);
- "noisy": the true model with each movable joint's axis direction rotated and its axis
  origin moved by Gaussian errors (`perturb_model`), a stand-in for the errors of a
  single-view estimate (Chapter 3, Table 3.1);
- "predicted": the model the Chapter 3 network (`artic predict`) estimates from a
  rendered depth view of the task's object (`artic.planning.perception.perceive`).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np
from pydantic import Field

from artic.config.schemas import Strict
from artic.errors import InputError
from artic.geometry.transforms import axis_angle
from artic.kinematics import Estimator
from artic.objects.model import ArticulatedObject
from artic.render.noise import SensorNoiseConfig

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from artic.kinematics.predict import Predictor
    from artic.objects.spec import CategoryConfig, ObjectSpec, PoseRanges

ModelSource = Literal["true", "noisy", "predicted"]
MODEL_STREAM = 1_000_003  # generator stream of the noisy model: (seed, MODEL_STREAM)
PERCEPTION_STREAM = 1_000_033  # generator stream of the predicted model's sensor noise


class CameraConfig(Strict):
    """The camera of the `predicted` model's view: level (z up, as the MDN's camera frame)."""

    position: list[float] | None = Field(
        None,
        min_length=3,
        max_length=3,
        description="camera position in the world, m; null: placed so that the object's base "
        "is at the middle of its category's Table A.2 pose ranges (camera frame)",
    )
    yaw: float = Field(
        0.0, description="with a position: heading about world +z, rad (0: along world +x)"
    )


class ModelConfig(Strict):
    """Which kinematic model of the object the demos are planned with."""

    source: ModelSource = Field(
        "true",
        description="true: the world's model; noisy: it with Gaussian axis errors; "
        "predicted: the MDN's estimate from a rendered depth view (drawer, microwave)",
    )
    direction_std_rad: float = Field(0.05, ge=0, description="noisy: axis direction std, rad")
    origin_std_m: float = Field(0.01, ge=0, description="noisy: axis origin std per axis, m")
    mdn: str | None = Field(
        None,
        description="predicted: the MDN of the task's object category, a model.pt or a "
        "train-mdn output folder; null: the model store's choice, as `artic predict` makes "
        "it (<artifacts_root>/models/mdn/<category> if trained there, else the shipped one)",
    )
    refine: bool = Field(
        True,
        description="predicted: the geometric refinement of `artic predict` (on by default "
        "there too; kinematics/refine.py)",
    )
    estimator: Estimator = Field(
        "most-likely",
        description="predicted: the MDN's estimator (section 3.3.1 / 3.3.2; kinematics/predict.py)",
    )
    camera: CameraConfig = Field(default_factory=CameraConfig, description="predicted: view")
    noise: SensorNoiseConfig = Field(
        default_factory=SensorNoiseConfig,
        description="predicted: the depth sensor model of the view (the training data's)",
    )


class PerturbedModel(NamedTuple):
    """A noisy kinematic model and the errors actually drawn, one per movable joint.

    direction_error_rad: angle between the true and the noisy axis direction, radians.
    origin_error_m: distance the joint frame (axis origin) moved, metres.
    """

    model: ArticulatedObject
    direction_error_rad: list[float]
    origin_error_m: list[float]


def perturb_model(
    model: ArticulatedObject,
    direction_std_rad: float,
    origin_std_m: float,
    rng: np.random.Generator,
) -> PerturbedModel:
    """The model with every movable joint's axis rotated and origin moved at random.

    The axis direction is rotated by the rotation vector w, the part of a N(0,
    direction_std_rad^2 I_3) draw perpendicular to the axis, so the angular error |w|
    is Rayleigh-distributed with scale `direction_std_rad` (RMS sqrt(2) * std). The
    joint frame is translated by a N(0, origin_std_m^2 I_3) offset (RMS sqrt(3) * std):
    the axis origin moves and the part that hangs on the joint (its handle included)
    moves with it, as when the part's pose is mis-estimated. Joint limits, links and
    dynamics are unchanged. Pure: draws from `rng` only.
    """
    if direction_std_rad < 0 or origin_std_m < 0:
        raise ValueError("direction_std_rad and origin_std_m must be >= 0")
    joints = list(model.joints)
    angles: list[float] = []
    offsets: list[float] = []
    for k, joint in enumerate(model.joints):
        if joint.type == "fixed":
            continue
        axis = joint.axis / np.linalg.norm(joint.axis)
        w = rng.normal(0.0, direction_std_rad, 3)
        w -= w.dot(axis) * axis
        angle = float(np.linalg.norm(w))
        new_axis = axis_angle(w / angle, angle) @ axis if angle > 0 else axis.copy()
        delta = rng.normal(0.0, origin_std_m, 3)
        origin = joint.origin.copy()
        origin[:3, 3] += delta
        joints[k] = dataclasses.replace(joint, axis=new_axis, origin=origin)
        angles.append(angle)
        offsets.append(float(np.linalg.norm(delta)))
    noisy = dataclasses.replace(model, joints=tuple(joints))
    return PerturbedModel(noisy, angles, offsets)


def axis_in_world(
    model: ArticulatedObject, configuration: np.ndarray, joint: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """World (origin (3,), unit direction (3,)) of movable joint `joint`'s axis at
    `configuration` (dof,)."""
    frame = model.joint_frames(configuration)[joint]
    axis = model.movable_joints[joint].axis
    direction = frame[:3, :3] @ (axis / np.linalg.norm(axis))
    return frame[:3, 3].copy(), direction


def noisy_model(
    cfg: ModelConfig, seed: int, true: ArticulatedObject
) -> tuple[ArticulatedObject, dict[str, Any]]:
    """The `noisy` model, drawn from (seed, MODEL_STREAM), and its demos.json record."""
    rng = np.random.default_rng([seed, MODEL_STREAM])
    noisy = perturb_model(true, cfg.direction_std_rad, cfg.origin_std_m, rng)
    record = {
        "source": cfg.source,
        "direction_std_rad": cfg.direction_std_rad,
        "origin_std_m": cfg.origin_std_m,
        "direction_error_rad": noisy.direction_error_rad,
        "origin_error_m": noisy.origin_error_m,
    }
    return noisy.model, record


def category_config(category: str) -> CategoryConfig:
    """`conf/common/category/<category>.yaml`: the ranges the category's MDN was trained on."""
    from omegaconf import OmegaConf

    from artic.config.compose import conf_dir
    from artic.objects.spec import CategoryConfig

    path = conf_dir() / "common" / "category" / f"{category}.yaml"
    if not path.is_file():
        raise InputError(f"{path}: no such category config")
    return CategoryConfig.model_validate(OmegaConf.to_container(OmegaConf.load(path)))


def camera_pose(cfg: CameraConfig, base_pose: NDArray[np.float64], ranges: PoseRanges) -> Any:
    """(4, 4) camera-to-world transform of the configured (or centred) level camera."""
    from artic.planning.perception import centred_camera, level_camera

    if cfg.position is None:
        return centred_camera(base_pose, ranges)
    return level_camera(cfg.position, cfg.yaw)


def predicted_model(
    cfg: ModelConfig,
    seed: int,
    true: ArticulatedObject,
    spec: ObjectSpec,
    start: NDArray[np.float64],
    category: str,
    predictor: Predictor,
) -> tuple[ArticulatedObject, dict[str, Any]]:
    """The model `predictor` (the category's MDN) estimates from a rendered view of the
    object `true` (built from `spec`) at configuration `start`
    (`artic.planning.perception.perceive`; sensor noise from (seed, PERCEPTION_STREAM)),
    and its demos.json record (without the MDN folder)."""
    from artic.geometry.transforms import yaw_of
    from artic.planning.perception import perceive, pose_in_camera, summary, view_problems

    classes = category_config(category)
    camera = camera_pose(cfg.camera, true.base_pose, classes.pose)
    pose = pose_in_camera(true.base_pose, camera)
    problems = view_problems(pose, classes.pose, spec, predictor.camera)
    if problems:
        raise InputError(
            f"model.camera: the {category} MDN was not trained on this view: " + "; ".join(problems)
        )
    rng = np.random.default_rng([seed, PERCEPTION_STREAM])
    seen = perceive(
        true, spec, start, camera, predictor, cfg.noise, rng, cfg.estimator,
        classes.geometry, classes.chirality, cfg.refine,
    )  # fmt: skip
    record: dict[str, Any] = {
        "source": "predicted",
        "category": category,
        "estimator": cfg.estimator,
        "camera": {
            "position": [round(float(v), 6) for v in camera[:3, 3]],
            "yaw": round(yaw_of(camera[:3, :3]), 6),
        },
        "object_pose_in_camera": {k: round(v, 6) for k, v in pose.model_dump().items()},
        "configuration_error_unit": "deg" if spec.joint_type == "revolute" else "cm",
        **summary(seen),
    }
    return seen.model, record
