"""Task configurations of Chapter 5 (section 5.3.1): drawer, microwave, t-ball.

A `TaskConfig` fully describes one simulated manipulation task: the control rate and
physics substeps, the horizon, the goal object configuration q_O* and the reward of
Eq. 5.1 (`r_t = -c ||q_O* - q_O||^2 - a_t^T R a_t`, c = 60, R = 0.001 I), the robot's
start configuration and its noise, the grasp model and the scene (an articulated
object from `artic.objects`, or a tee and a ball). Tasks register with
`@register_task("name")`; `get_task(name)` returns the defaults, which
`conf/common/task/<name>.yaml` mirrors (stages compose it under the key `task`).

World frame: the robot's base at the origin on the ground plane z = 0, +z up, the
objects in front of it (+x). Units: metres, radians, seconds, kilograms, newtons.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from artic.named import Registry
from artic.objects.spec import ObjectSpec, PartsConfig, Pose, Range

Vector7 = Annotated[list[float], Field(min_length=7, max_length=7)]


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


# real KUKA LBR iiwa 7 R800 axis speeds (datasheet: 98, 98, 100, 130, 140, 180, 180 deg/s);
# the pybullet_data URDF says 10 rad/s for every joint, which no real iiwa reaches
IIWA7_VELOCITY_LIMITS = [1.71, 1.71, 1.75, 2.27, 2.44, 3.14, 3.14]


class RobotConfig(_Frozen):
    """The 7-DoF KUKA LBR iiwa (`pybullet_data` `kuka_iiwa/model.urdf`, fixed base at the
    world origin), its start configuration and its tool frame."""

    urdf: str = Field(
        default="kuka_iiwa/model.urdf", description="robot URDF, relative to pybullet_data"
    )
    start_q: Vector7 = Field(
        default=[0.0, 0.5, 0.0, -1.5, 0.0, 1.0, 0.0],
        description="start joint configuration q_R(0), rad",
    )
    start_noise: float = Field(
        default=0.02, ge=0, description="std of the Gaussian added to start_q at reset, rad"
    )
    velocity_limits: Vector7 = Field(
        default=IIWA7_VELOCITY_LIMITS,
        description="joint speed limits; actions are clipped to them, rad/s",
    )
    tool_offset: float = Field(
        default=0.1,
        gt=0,
        description="tool point along the last link's z axis from its URDF frame, m "
        "(flange at about 0.045 m; the rest is a virtual gripper)",
    )


class GraspConfig(_Frozen):
    """The grasp model (see `artic.sim.robot.Grasp`): a point-to-point constraint between
    the tool point and the grasp point, made when they come within `attach_distance`,
    limited to `max_force`, released when stretched beyond `slip_distance`."""

    enabled: bool = Field(default=True, description="whether the robot can grasp at all")
    attach_distance: float = Field(
        default=0.03, gt=0, description="tool-to-grasp-point distance that closes the grasp, m"
    )
    max_force: float = Field(
        default=150.0, gt=0, description="largest force the grasp transmits, N"
    )
    slip_distance: float = Field(
        default=0.06, gt=0, description="stretch of the grasp at which the handle slips out, m"
    )

    @model_validator(mode="after")
    def _slip_beyond_attach(self) -> GraspConfig:
        if self.slip_distance <= self.attach_distance:
            raise ValueError("grasp.slip_distance must exceed grasp.attach_distance")
        return self


class ArticulatedScene(_Frozen):
    """An articulated object from `artic.objects` (fixed geometry, in Table A.1's ranges),
    fixed-base in the world. The pose places the object frame (centre of the bottom face,
    x into the object) in the robot's world; at yaw 0 its front faces the robot."""

    kind: Literal["articulated"] = Field(default="articulated", description="scene type")
    category: Literal["drawer", "microwave"] = Field(
        default="drawer", description="artic.objects category"
    )
    depth: float = Field(default=0.5, gt=0, description="body extent along object x, m")
    width: float = Field(default=0.5, gt=0, description="body extent along object y, m")
    height: float = Field(default=0.2, gt=0, description="body extent along object z, m")
    chirality: Literal[-1, 1] = Field(
        default=1, description="+1: hinge on the -y edge (microwave); 1 for a drawer"
    )
    pose: Pose = Field(
        default=Pose(x=1.0875, y=0.0, z=0.2, yaw=0.0),
        description="object base pose in the world (robot) frame",
    )
    joint_limits: Range = Field(default=(0.0, 0.3), description="joint range, m or rad")
    parts: PartsConfig = Field(default=PartsConfig(), description="part constants and dynamics")
    geometry_jitter: float = Field(
        default=0.0,
        ge=0,
        lt=0.5,
        description="scale depth/width/height by U[1 - j, 1 + j] per world (0: fixed)",
    )

    def spec(self) -> ObjectSpec:
        """The `ObjectSpec` that `artic.objects.categories.build` turns into the object."""
        return ObjectSpec(
            category=self.category,
            index=0,
            dof=1,
            joint_type="prismatic" if self.category == "drawer" else "revolute",
            depth=self.depth,
            width=self.width,
            height=self.height,
            chirality=self.chirality,
            pose=self.pose,
            joint_limits=(self.joint_limits,),
            parts=self.parts,
        )


class TBallScene(_Frozen):
    """A static tee (a cylinder standing on the ground) and a dynamic ball resting on it.
    The object configuration is the ball's y displacement from its start (dof 1)."""

    kind: Literal["tball"] = Field(default="tball", description="scene type")
    tee_x: float = Field(default=0.6, description="tee position x, m")
    tee_y: float = Field(default=0.0, description="tee position y, m")
    tee_height: float = Field(default=0.3, gt=0, description="tee height (top face), m")
    tee_radius: float = Field(default=0.015, gt=0, description="tee cylinder radius, m")
    ball_radius: float = Field(default=0.035, gt=0, description="ball radius, m")
    ball_mass: float = Field(default=0.06, gt=0, description="ball mass, kg")
    ball_restitution: float = Field(default=0.5, ge=0, le=1, description="ball bounciness")
    ball_rolling_friction: float = Field(
        default=0.002, ge=0, description="rolling friction of ball and ground (stops it)"
    )
    travel: Range = Field(
        default=(-3.0, 3.0), description="y displacement range of the kinematic model, m"
    )


class RewardConfig(_Frozen):
    """Eq. 5.1: r_t = -c ||q_O* - q_O||^2 - a_t^T R a_t with R = r I."""

    c: float = Field(default=60.0, ge=0, description="weight of the squared goal error")
    r: float = Field(default=0.001, ge=0, description="action penalty R = r I")


class TaskConfig(_Frozen):
    """One Chapter 5 task (section 5.3.1); every number the simulation uses."""

    name: str = Field(default="drawer", description="task name (registry key)")
    control_dt: float = Field(default=0.05, gt=0, description="control period, s (20 Hz)")
    substeps: int = Field(
        default=12, ge=1, description="physics steps per control period (240 Hz physics)"
    )
    horizon: int = Field(default=80, ge=1, description="control steps per episode")
    goal: list[float] = Field(default=[0.25], min_length=1, description="q_O*, m or rad")
    object_start: list[float] = Field(
        default=[0.0], min_length=1, description="object configuration at reset, m or rad"
    )
    success_threshold: float = Field(
        default=0.03, gt=0, description="success when ||q_O - q_O*|| <= this, m or rad"
    )
    reward: RewardConfig = Field(default=RewardConfig(), description="Eq. 5.1 weights")
    gravity: float = Field(default=-9.81, description="gravity along z, m/s^2")
    robot: RobotConfig = Field(default=RobotConfig(), description="the KUKA iiwa")
    grasp: GraspConfig = Field(default=GraspConfig(), description="grasp model")
    scene: ArticulatedScene | TBallScene = Field(
        default=ArticulatedScene(), discriminator="kind", description="object(s) to act on"
    )

    @property
    def physics_dt(self) -> float:
        """Physics time step, s."""
        return self.control_dt / self.substeps

    @model_validator(mode="after")
    def _consistent(self) -> TaskConfig:
        if len(self.goal) != len(self.object_start):
            raise ValueError("goal and object_start must have the object's dof entries")
        if any(not math.isfinite(v) for v in [*self.goal, *self.object_start]):
            raise ValueError("goal and object_start must be finite")
        return self


TaskFactory = Callable[[], TaskConfig]
TASKS: Registry[TaskFactory] = Registry("task", "task", "tasks")
"""Registered task factories by name; fill it with `@register_task`."""
#: decorator: register a factory returning the default `TaskConfig` of a name
register_task = TASKS.register


def get_task(name: str) -> TaskConfig:
    """The default `TaskConfig` of task `name`; InputError listing the known tasks."""
    return TASKS.lookup(name)()


#: Runner dynamics of the heavy `drawer` (issue 23; docs/bootstrap.md, "Heavy drawer and
#: exploring baseline"): Coulomb friction = the breakaway force, N (a loaded kitchen drawer,
#: 14 kg box and contents on wooden runners, mu about 0.5-0.7), and viscous damping, N s/m
#: (stiff runners: 75 N more at the planned 0.25 m/s). Together they need 175 N at the
#: planned speed, more than the grasp's 150 N: the planned demo slips off the handle.
HEAVY_DRAWER_FRICTION = 100.0
HEAVY_DRAWER_DAMPING = 300.0


def _drawer(name: str, joint_damping: float, joint_friction: float) -> TaskConfig:
    """The drawer task with the given runner damping (N s/m) and friction (N)."""
    parts = PartsConfig(
        drawer_density=1500.0,
        joint_damping=joint_damping,
        joint_friction=joint_friction,
        joint_effort=200.0,
    )
    return TaskConfig(
        name=name,
        horizon=80,
        goal=[0.25],
        object_start=[0.0],
        success_threshold=0.03,
        robot=RobotConfig(start_q=[0.0, 0.41, 0.0, -1.54, 0.0, -0.37, 0.0]),
        grasp=GraspConfig(enabled=True),
        scene=ArticulatedScene(
            category="drawer",
            depth=0.5,
            width=0.5,
            height=0.2,
            pose=Pose(x=1.2075, y=0.0, z=0.35, yaw=0.0),
            joint_limits=(0.0, 0.3),
            parts=parts,
        ),
    )


@register_task("drawer")
def drawer_task() -> TaskConfig:
    """Grasp the handle and pull a heavy drawer open (section 5.3.1, Figure 5.3).

    A 0.5 x 0.5 x 0.2 m drawer unit (Table A.1 ranges) floats fixed-base with its
    handle 0.92 m in front of the robot, 0.45 m high; the drawer starts closed and
    the goal is 0.25 m of its 0.3 m travel. The drawer is a loaded kitchen drawer
    (1500 kg/m^3, about 14 kg) on stiff runners: breakaway force
    `HEAVY_DRAWER_FRICTION` = 100 N and damping `HEAVY_DRAWER_DAMPING` = 300 N s/m. The
    planned demo pulls at 0.25 m/s, which needs 175 N, more than the grasp transmits
    (150 N): the handle slips out and the drawer stops about half open (Fig. 5.3b); a
    pull about 1.25x slower succeeds. `drawer_light` is the light drawer for comparison.
    """
    return _drawer("drawer", HEAVY_DRAWER_DAMPING, HEAVY_DRAWER_FRICTION)


@register_task("microwave")
def microwave_task() -> TaskConfig:
    """Push an open microwave door shut (section 5.3.1, Figure 5.5).

    A 0.4 x 0.6 x 0.35 m microwave (Table A.1 ranges), hinge on its -y edge, stands
    1.25 m ahead and 0.5 m to the left of the robot. Open (1.4 rad) its handle is
    0.67 m from the robot's axis and within reach; closed it is 1.16 m away, beyond
    the iiwa's reach, so the robot must push the door fast enough for it to swing shut.
    No grasp: the robot acts through contact. Horizon 80 steps (4 s): a planned demo
    follows the door to the edge of the robot's reach (about 1 rad of the door's swing,
    with large wrist motions at the end), which takes 64 steps at the joint speed limits.
    """
    parts = PartsConfig(joint_damping=0.3, joint_friction=0.05)
    return TaskConfig(
        name="microwave",
        horizon=80,
        goal=[0.0],
        object_start=[1.4],
        success_threshold=0.1,
        robot=RobotConfig(start_q=[-0.81, 0.82, 0.51, -1.38, 1.03, 1.77, 0.02]),
        grasp=GraspConfig(enabled=False),
        scene=ArticulatedScene(
            category="microwave",
            depth=0.4,
            width=0.6,
            height=0.35,
            chirality=1,
            pose=Pose(x=1.25, y=0.5, z=0.25, yaw=0.0),
            joint_limits=(0.0, math.pi / 2),
            parts=parts,
        ),
    )


@register_task("tball")
def tball_task() -> TaskConfig:
    """Hit a ball off a tee (section 5.3.1): the object state is the ball's y
    displacement from its start. No grasp: the robot strikes.

    A 7 cm ball (60 g) rests on a 0.3 m tee 0.6 m ahead of the robot; it rolls to a stop
    on the ground (rolling friction). Goal: 0.75 m along +y, success within 0.2 m. The
    thesis gives no distance; this one sits between what the planned demo achieves (a
    push from rest, 0.23-0.34 m) and what the iiwa's fastest swing along the demo's path
    achieves (about 1 m, joint speed limits saturated): success needs policy search to
    learn a faster swing, and stays within the robot's reach (docs/bootstrap.md).
    """
    return TaskConfig(
        name="tball",
        horizon=60,
        goal=[0.75],
        object_start=[0.0],
        success_threshold=0.2,
        robot=RobotConfig(start_q=[-0.89, 1.23, 0.66, -0.9, 0.77, 1.89, 0.09]),
        grasp=GraspConfig(enabled=False),
        scene=TBallScene(),
    )


@register_task("drawer_light")
def drawer_light_task() -> TaskConfig:
    """The drawer task with a light-running drawer (the `drawer` task before issue 23):
    the same 14 kg drawer with damping 20 N s/m and breakaway force 15 N, which the
    planned demo opens at the planned speed (10/10 demos succeed)."""
    return _drawer("drawer_light", 20.0, 15.0)
