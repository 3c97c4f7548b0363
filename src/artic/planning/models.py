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
from typing import Literal, NamedTuple

import numpy as np

from artic.geometry.transforms import axis_angle
from artic.objects.model import ArticulatedObject

ModelSource = Literal["true", "noisy", "predicted"]


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
