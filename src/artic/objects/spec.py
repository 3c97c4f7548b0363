"""Object specifications: the data that fully determines one procedural object.

Sample, then build: `sample_spec(cfg, camera, index, rng)` draws an `ObjectSpec` from a
`CategoryConfig` (one `conf/common/category/*.yaml` file: the ranges of thesis Tables A.1
and A.2), and `artic.objects.categories.build(spec)` turns it into meshes and joints
without any further randomness. A spec is plain data and round-trips through JSON.

Units: metres and radians throughout (Table A.1 is in cm, the drawer range of Table A.2
in cm; the configs hold them converted to metres).
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    ValidationInfo,
    model_validator,
)

from artic.geometry.camera import CameraIntrinsics
from artic.geometry.transforms import make_transform, rot_z

JointKind = Literal["revolute", "prismatic"]
Chirality = Literal[-1, 1]

MAX_POSE_TRIES = 100


def _ordered(value: tuple[float, float], info: ValidationInfo) -> tuple[float, float]:
    """Field validator of `Range`: finite bounds with min <= max."""
    lo, hi = value
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"{info.field_name}: bounds must be finite, got [{lo}, {hi}]")
    if lo > hi:
        raise ValueError(f"{info.field_name}: min {lo} > max {hi}; expected [min, max]")
    return value


Range = Annotated[tuple[float, float], AfterValidator(_ordered)]
"""A closed interval [min, max] (min <= max), in the unit of its field."""


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class GeometryRanges(_Frozen):
    """Ranges of the outer body dimensions, metres (thesis Table A.1, converted from cm)."""

    depth: Range = Field(description="extent along the object's x (front to back), metres")
    width: Range = Field(description="extent along the object's y (side to side), metres")
    height: Range = Field(description="extent along the object's z (bottom to top), metres")
    door_thickness: Range | None = Field(
        default=None,
        description="the doors' (drawer fronts') thickness drawn per object, metres (ours, "
        "not Table A.1); None: `parts.door_thickness` for every object",
    )


class PoseRanges(_Frozen):
    """Ranges of the base pose in the camera frame (thesis Table A.2)."""

    x: Range = Field(description="base-centre x (distance along the optical axis), metres")
    y: Range = Field(description="base-centre y (+y = camera's left), metres")
    z: Range = Field(description="base-centre z (+z = up), metres")
    yaw: Range = Field(description="rotation about +z, radians")


class PartsConfig(_Frozen):
    """Construction constants of the parts; the thesis gives none, these are ours.

    Lengths in metres, densities in kg/m^3. Damping is N m s/rad (revolute) or N s/m
    (prismatic), friction N m or N, effort N m or N, velocity rad/s or m/s. Chapter 7's
    slide and lever size their knob with the handle fields, their carriage or arm with
    `door_thickness` and `handle_inset`, and weigh it with `door_density`
    (docs/objects.md, "Chapter 7 mechanisms").
    """

    panel_thickness: float = Field(default=0.02, gt=0, description="body shell wall thickness, m")
    door_thickness: float = Field(
        default=0.02, gt=0, description="door / drawer-front thickness, m"
    )
    gap: float = Field(default=0.002, ge=0, description="clearance between neighbouring parts, m")
    handle_length: float = Field(default=0.2, gt=0, description="longest handle bar, m")
    handle_fraction: float = Field(
        default=0.6, gt=0, le=1, description="bar length cap as a fraction of the part's extent"
    )
    handle_thickness: float = Field(
        default=0.015, gt=0, description="square bar cross-section side, m"
    )
    handle_standoff: float = Field(default=0.03, gt=0, description="clearance behind the bar, m")
    handle_inset: float = Field(default=0.05, gt=0, description="bar centreline to free edge, m")
    body_density: float = Field(default=600.0, gt=0, description="body material density, kg/m^3")
    door_density: float = Field(default=500.0, gt=0, description="door material density, kg/m^3")
    drawer_density: float = Field(
        default=700.0, gt=0, description="drawer material density, kg/m^3"
    )
    handle_density: float = Field(
        default=1000.0, gt=0, description="handle density (light), kg/m^3"
    )
    joint_damping: float = Field(default=0.1, ge=0, description="viscous joint damping")
    joint_friction: float = Field(default=0.05, ge=0, description="Coulomb joint friction")
    joint_effort: float = Field(default=50.0, gt=0, description="joint effort limit")
    joint_velocity: float = Field(default=2.0, gt=0, description="joint velocity limit")
    control_panel_fraction: float = Field(
        default=0.25,
        gt=0,
        lt=1,
        description="front width taken by a control panel (microwave, toaster)",
    )
    freezer_fraction: float = Field(
        default=1.0 / 3.0, gt=0, lt=1, description="height share of a refrigerator's upper door"
    )
    drawer_front: Literal["inset", "overlay"] = Field(
        default="inset",
        description="a drawer's front: inside the opening, flush with the body front when "
        "shut (the generator's), or an overlay front over the whole body front, its back face "
        "on the body front when shut (the refinement's second reading, docs/kinematics.md)",
    )


class CategoryConfig(_Frozen):
    """One object category: the content of `conf/common/category/<name>.yaml`."""

    name: str = Field(description="category name, a key of the category registry")
    dof: int = Field(ge=1, le=2, description="number of movable joints")
    joint_type: JointKind = Field(description="kind of every movable joint")
    geometry: GeometryRanges = Field(description="body dimension ranges (Table A.1)")
    pose: PoseRanges = Field(description="base pose ranges (Table A.2)")
    configuration: Range = Field(
        description="joint value range, radians (revolute) or metres (prismatic), Table A.2"
    )
    chirality: list[Chirality] = Field(
        min_length=1, description="hinge sides drawn uniformly; [1] where it has no meaning"
    )
    parts: PartsConfig = Field(default=PartsConfig(), description="part constants")

    def door_thickness_range(self) -> tuple[float, float]:
        """[min, max] of its objects' door thickness, metres (`sample_spec`)."""
        fixed = self.parts.door_thickness
        return self.geometry.door_thickness or (fixed, fixed)


class Pose(_Frozen):
    """Base pose: the centre of the body's bottom face in the camera frame, and its yaw."""

    x: float = Field(description="metres, along the optical axis")
    y: float = Field(description="metres, +y = camera's left")
    z: float = Field(description="metres, +z = up")
    yaw: float = Field(description="rotation about +z, radians")

    def matrix(self) -> NDArray[np.float64]:
        """(4, 4) object-to-camera transform: translation(x, y, z) @ rot_z(yaw)."""
        return make_transform(rot_z(self.yaw), np.array([self.x, self.y, self.z]))


class ObjectSpec(_Frozen):
    """Everything `build` needs: one object instance, fully determined, JSON round-trip."""

    category: str = Field(description="category name (registry key)")
    index: int = Field(ge=0, description="sample index within its dataset")
    dof: int = Field(ge=1, le=2, description="number of movable joints")
    joint_type: JointKind = Field(description="kind of every movable joint")
    depth: float = Field(gt=0, description="body extent along object x, metres")
    width: float = Field(gt=0, description="body extent along object y, metres")
    height: float = Field(gt=0, description="body extent along object z, metres")
    chirality: Chirality = Field(description="+1: hinge on the -y (camera-right) edge, axis +z")
    pose: Pose = Field(description="base pose in the camera frame")
    joint_limits: tuple[Range, ...] = Field(
        description="(lower, upper) per movable joint, radians or metres"
    )
    parts: PartsConfig = Field(description="part constants used to build it")

    @model_validator(mode="after")
    def _consistent(self) -> ObjectSpec:
        if len(self.joint_limits) != self.dof:
            raise ValueError(
                f"joint_limits: {len(self.joint_limits)} ranges for an object with dof {self.dof}"
            )
        walls = 2.0 * (self.parts.panel_thickness + self.parts.gap) + self.parts.door_thickness
        if walls >= min(self.depth, self.width, self.height):
            raise ValueError(
                f"parts.panel_thickness: walls of {walls} m leave no room inside a "
                f"{self.depth} x {self.width} x {self.height} m body"
            )
        return self


def _uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return float(rng.uniform(bounds[0], bounds[1]))


def _centre_visible(centre: NDArray[np.float64], camera: CameraIntrinsics) -> bool:
    """True if a camera-frame point (3,) lies in front of the camera and inside the image."""
    if centre[0] <= 0:
        return False
    u, v = camera.project(centre[None, :])[0]
    return bool(0.0 <= u <= camera.width - 1 and 0.0 <= v <= camera.height - 1)


def sample_pose(
    ranges: PoseRanges, height: float, camera: CameraIntrinsics, rng: np.random.Generator
) -> Pose:
    """Uniform pose in `ranges` whose bounding-box centre is in the view frustum.

    The thesis (section 3.2.3) samples positions "from the view frustum of the camera";
    we rejection-sample the Table A.2 box until the body's bounding-box centre
    (base + height/2 along z; yaw does not move it) projects inside the image.
    Raises ValueError after `MAX_POSE_TRIES` rejections.
    """
    for _ in range(MAX_POSE_TRIES):
        x, y, z = (_uniform(rng, ranges.x), _uniform(rng, ranges.y), _uniform(rng, ranges.z))
        if _centre_visible(np.array([x, y, z + 0.5 * height]), camera):
            return Pose(x=x, y=y, z=z, yaw=_uniform(rng, ranges.yaw))
    raise ValueError(
        f"pose: no position in x={ranges.x}, y={ranges.y}, z={ranges.z} put the object "
        f"inside a {camera.width}x{camera.height} image after {MAX_POSE_TRIES} tries"
    )


def sample_spec(
    cfg: CategoryConfig, camera: CameraIntrinsics, index: int, rng: np.random.Generator
) -> ObjectSpec:
    """Draw one object of category `cfg` (thesis Appendix A, Tables A.1 and A.2).

    Dimensions are independent uniforms over Table A.1; chirality is uniform over
    `cfg.chirality`; the pose comes from `sample_pose`; the door thickness, when the
    category gives a range (`GeometryRanges.door_thickness`), is uniform over it, drawn
    last (a category without one draws the numbers it always did). Only `rng` is used, so
    the same generator state gives the same spec. Joint limits are the configuration range.
    """
    depth = _uniform(rng, cfg.geometry.depth)
    width = _uniform(rng, cfg.geometry.width)
    height = _uniform(rng, cfg.geometry.height)
    chirality = cfg.chirality[int(rng.integers(len(cfg.chirality)))]
    pose = sample_pose(cfg.pose, height, camera, rng)
    parts = cfg.parts
    if cfg.geometry.door_thickness is not None:
        thickness = _uniform(rng, cfg.geometry.door_thickness)
        parts = PartsConfig.model_validate(parts.model_dump() | {"door_thickness": thickness})
    return ObjectSpec(
        category=cfg.name,
        index=index,
        dof=cfg.dof,
        joint_type=cfg.joint_type,
        depth=depth,
        width=width,
        height=height,
        chirality=chirality,
        pose=pose,
        joint_limits=(cfg.configuration,) * cfg.dof,
        parts=parts,
    )
