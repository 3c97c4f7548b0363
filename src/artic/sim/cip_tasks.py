"""Task configurations of Chapter 7 (section 7.3): `door`, `drawer`, `slide`, `lever`,
with their own registry (Chapter 5 owns `task`, Chapter 6 `rmp_task`): each registers
with `@register_cip_task` (the YAML mirrors in `conf/common/cip_task/` come with the
`train-cip` stage).

World frame as in Chapters 5 and 6: the iiwa's base at the origin on the table plane
z = 0, +x ahead, +z up. Each task is one `artic.objects` object standing on the table
in front of the robot, its front facing the robot (-x), its pose jittered at every reset
(+-2 cm, +-0.1 rad about z: issue 21; the thesis: "randomized over a small range as in
the original benchmark"). beta_c: the object's joint past `success` (the released
code, babbatem/robosuite: door 0.3 rad, lever 1.57 rad; drawer and slide ours).
Constants: docs/cip.md.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from artic.control.osc import VicesConfig
from artic.control.safety import SafetyConfig
from artic.named import Registry
from artic.objects.spec import PartsConfig
from artic.sim.gripper import GripperConfig
from artic.sim.tasks import RobotConfig

CipTaskName = Literal["door", "drawer", "slide", "lever"]
_CATEGORY = {"door": "cabinet", "drawer": "drawer", "slide": "slide", "lever": "lever"}


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class CipObject(_Frozen):
    """The manipulated object: an `artic.objects` category at a nominal pose."""

    category: str = Field(description="artic.objects category")
    joint_type: Literal["revolute", "prismatic"] = Field(description="its one joint's kind")
    depth: float = Field(gt=0, description="body extent along x, m")
    width: float = Field(gt=0, description="body extent along y, m")
    height: float = Field(gt=0, description="body extent along z, m")
    chirality: Literal[-1, 1] = Field(1, description="+1: hinge on the -y edge (revolute)")
    joint_limit: float = Field(gt=0, description="the joint's range from closed, rad or m")
    x: float = Field(description="body centre x, m (front face at x - depth/2)")
    y: float = Field(0.0, description="body centre y, m")
    z: float = Field(0.0, ge=0, description="body base height above the table, m")
    jitter_xy: float = Field(0.02, ge=0, description="uniform +- jitter of x and y, m")
    jitter_yaw: float = Field(0.1, ge=0, description="uniform +- jitter of the yaw, rad")
    parts: PartsConfig = Field(
        default_factory=PartsConfig,
        description="part constants (artic.objects; joint damping and friction included)",
    )


class CipTaskConfig(_Frozen):
    """One Chapter 7 task: every number the simulation uses."""

    name: CipTaskName = Field(description="task name (registry key)")
    control_dt: float = Field(0.05, gt=0, description="action period, s (20 Hz)")
    substeps: int = Field(12, ge=1, description="physics steps per action (240 Hz physics)")
    horizon: int = Field(250, ge=1, description="actions per episode (thesis: 250)")
    gravity: float = Field(-9.81, description="gravity along z, m/s^2")
    robot: RobotConfig = Field(default_factory=RobotConfig, description="the iiwa; start_q: home")
    gripper: GripperConfig = Field(default_factory=GripperConfig, description="parallel jaw")
    vices: VicesConfig = Field(default_factory=VicesConfig, description="the action space")
    safety: SafetyConfig = Field(default_factory=SafetyConfig, description="sigma and B's limit")
    object: CipObject = Field(description="the manipulated object")
    success: float = Field(gt=0, description="beta_c: the joint past this, rad or m")
    gamma: float = Field(0.99, gt=0, le=1, description="discount of the potential shaping")
    contact_loss_steps: int = Field(
        10, ge=1, description="B: no finger contact for this many actions ends the episode"
    )
    grasp_time: float = Field(0.5, gt=0, description="Gamma closing on the grasp at reset, s")
    grasp_clearance: float = Field(
        0.01, ge=0, description="reference grasp: fingertips this far off the handle's base, m"
    )

    @property
    def physics_dt(self) -> float:
        return self.control_dt / self.substeps

    @model_validator(mode="after")
    def _consistent(self) -> CipTaskConfig:
        if self.object.category != _CATEGORY[self.name]:
            raise ValueError(
                f"object.category {self.object.category!r} is not task {self.name!r}'s "
                f"({_CATEGORY[self.name]!r})"
            )
        if self.success >= self.object.joint_limit:
            raise ValueError("success: beyond the object's joint_limit")
        return self


CipTaskFactory = Callable[[], CipTaskConfig]
CIP_TASKS: Registry[CipTaskFactory] = Registry("task", "CIP task", "CIP tasks")
"""Registered Chapter 7 task factories by name; fill it with `@register_cip_task`."""
#: decorator: register a factory returning the default `CipTaskConfig` of a name
register_cip_task = CIP_TASKS.register


def get_cip_task(name: str) -> CipTaskConfig:
    """The default config of Chapter 7 task `name`; InputError listing the known ones."""
    return CIP_TASKS.lookup(name)()


#: home (E2E's start): the tool at (0.62, 0, 0.40) m pointing down, clear of every object
HOME = [0.0, 0.6, 0.0, -1.3, 0.0, 1.2, 0.0]


@register_cip_task("door")
def door_task() -> CipTaskConfig:
    """Open a cabinet door past 0.3 rad (the released code's threshold)."""
    return CipTaskConfig(
        name="door",
        robot=RobotConfig(start_q=HOME),
        object=CipObject(
            category="cabinet",
            joint_type="revolute",
            depth=0.35,
            width=0.4,
            height=0.5,
            joint_limit=1.6,
            x=1.1,
            z=0.15,
            parts=PartsConfig(joint_damping=0.5, joint_friction=0.2),
        ),
        success=0.3,
    )


@register_cip_task("drawer")
def drawer_task() -> CipTaskConfig:
    """Pull a drawer out past 0.1 m (ours: half a 0.2 m stroke)."""
    return CipTaskConfig(
        name="drawer",
        robot=RobotConfig(start_q=HOME),
        object=CipObject(
            category="drawer",
            joint_type="prismatic",
            depth=0.35,
            width=0.4,
            height=0.2,
            joint_limit=0.2,
            x=1.1,
            z=0.15,
            parts=PartsConfig(joint_damping=0.5, joint_friction=0.2),
        ),
        success=0.1,
    )


#: the knob of the slide and the lever: the category configs' part constants
#: (conf/common/category/slide.yaml, lever.yaml; docs/objects.md)
_KNOB = {
    "handle_length": 0.04, "handle_fraction": 0.7, "handle_thickness": 0.025,
    "handle_standoff": 0.015, "handle_inset": 0.03, "gap": 0.002,
}  # fmt: skip


@register_cip_task("slide")
def slide_task() -> CipTaskConfig:
    """Slide a knob 0.1 m along its rail (ours: half the 0.2 m travel)."""
    parts = PartsConfig(**_KNOB, door_thickness=0.01, joint_damping=1.0, joint_friction=1.0,
                        joint_effort=50.0, joint_velocity=0.5)  # fmt: skip
    return CipTaskConfig(
        name="slide",
        robot=RobotConfig(start_q=HOME),
        object=CipObject(category="slide", joint_type="prismatic", depth=0.15, width=0.4,
                         height=0.25, joint_limit=0.2, x=1.0, z=0.1, parts=parts),
        success=0.1,
    )  # fmt: skip


@register_cip_task("lever")
def lever_task() -> CipTaskConfig:
    """Turn a lever past 1.57 rad (the released code's threshold)."""
    parts = PartsConfig(**_KNOB, door_thickness=0.02, joint_damping=0.2, joint_friction=1.0,
                        joint_effort=20.0, joint_velocity=2.0)  # fmt: skip
    return CipTaskConfig(
        name="lever",
        robot=RobotConfig(start_q=HOME),
        object=CipObject(category="lever", joint_type="revolute", depth=0.15, width=0.5,
                         height=0.5, joint_limit=1.75, x=1.05, z=0.1, parts=parts),
        success=1.57,
    )  # fmt: skip
