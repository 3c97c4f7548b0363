"""Task configurations of Chapter 6 (section 6.4.1): trajectory following (`traj`),
door opening (`door`) and block pushing (`push`), with their own registry: Chapter 5
owns `task` names (`artic.sim.tasks`); these register with `@register_rmp_task` and
`conf/common/rmp_task/<name>.yaml` mirrors each default.

World frame as in Chapter 5: the iiwa's base at the origin, +x ahead, +z up. The table
is the plane z = 0 on which the robot's base, the cabinet and the block stand (the arm
is mounted at table height, as robosuite's arms at their table's edge). Every reward
constant below is ours (the thesis gives Eq. 6.6's form only): docs/rmp.md.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from artic.named import Registry
from artic.sim.tasks import RobotConfig

Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]
RmpTaskName = Literal["traj", "door", "push"]


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class Box3(_Frozen):
    """An axis-aligned box: centre (3,) and half extents (3,), m."""

    centre: Vector3 = Field(description="centre, m")
    half_extents: Vector3 = Field(description="half extents along x, y, z, m")

    @model_validator(mode="after")
    def _positive(self) -> Box3:
        if any(h < 0 for h in self.half_extents):
            raise ValueError("half_extents must be >= 0")
        return self


class ObstacleConfig(_Frozen):
    """Evaluation obstacles (section 6.5.2): spheres drawn uniformly in `volume`, clear
    of the task's protected points by `clearance` and of each other."""

    count: int = Field(2, ge=0, description="spheres per episode")
    radius: float = Field(0.05, gt=0, description="sphere radius, m")
    volume: Box3 = Field(description="where sphere centres are drawn")
    clearance: float = Field(
        0.05, ge=0, description="free gap between a sphere and protected points / the arm, m"
    )
    draws: int = Field(1000, ge=1, description="draws before placement is declared impossible")


class ControlPointConfig(_Frozen):
    """Control points of the collision RMPs (section 6.3.1): the centre of mass and the
    URDF frame origin of each listed link (PyBullet indices; 1-6 are lbr_iiwa_link_2-7),
    each a ball of `radius` around the point."""

    links: list[int] = Field(default_factory=lambda: [1, 2, 3, 4, 5, 6], description="links")
    radius: float = Field(0.08, gt=0, description="radius of the link around a point, m")


class TrajScene(_Frozen):
    """Four via points drawn in a box, to be passed in order."""

    kind: Literal["traj"] = Field(default="traj", description="scene type")
    box: Box3 = Field(description="volume the via points are drawn in")
    n_points: int = Field(4, ge=1, description="via points per episode")
    min_separation: float = Field(0.1, ge=0, description="least distance between via points, m")
    reach_distance: float = Field(0.05, gt=0, description="a via point is checked within this, m")
    shaping: float = Field(1.0, ge=0, description="w of w (1 - tanh(10 d_next)) per step")
    bonus: float = Field(50.0, ge=0, description="reward once per via point checked")


class DoorScene(_Frozen):
    """An `artic.objects` cabinet (one full-front door) on the table, the door grasped."""

    kind: Literal["door"] = Field(default="door", description="scene type")
    depth: float = Field(0.35, gt=0, description="cabinet extent along x, m")
    width: float = Field(0.4, gt=0, description="cabinet extent along y (= door width), m")
    height: float = Field(0.5, gt=0, description="cabinet height, m")
    x: float = Field(1.15, description="cabinet centre x, m (front face at x - depth/2)")
    y: float = Field(0.0, description="cabinet centre y, m")
    z: float = Field(0.15, ge=0, description="cabinet base height above the table, m")
    chirality: Literal[-1, 1] = Field(1, description="+1: hinge on the -y edge")
    door_limit: float = Field(1.6, gt=0, description="door opening range, rad")
    goal_angle: float = Field(1.0, gt=0, description="angle of full reward and success, rad")
    reward_scale: float = Field(1.0, ge=0, description="reward per step at goal_angle")
    joint_damping: float = Field(0.5, ge=0, description="door hinge damping")
    joint_friction: float = Field(0.2, ge=0, description="door hinge friction, N m")


class PushScene(_Frozen):
    """A cube pushed to a goal on the table (Eq. 6.6)."""

    kind: Literal["push"] = Field(default="push", description="scene type")
    block_size: float = Field(0.05, gt=0, description="cube edge, m")
    block_mass: float = Field(0.2, gt=0, description="cube mass, kg")
    block_friction: float = Field(0.5, ge=0, description="lateral friction of cube and table")
    block_start: Box3 = Field(description="cube centre drawn here at reset (z ignored)")
    goal: Box3 = Field(description="goal drawn here at reset (z ignored)")
    r_h2c: float = Field(0.5, ge=0, description="Eq. 6.6: largest hand-to-cube reward")
    r_c2g: float = Field(2.0, ge=0, description="Eq. 6.6: largest cube-to-goal reward")
    success_distance: float = Field(0.03, gt=0, description="success: cube within this of goal, m")


class RmpTaskConfig(_Frozen):
    """One Chapter 6 task: every number the simulation uses."""

    name: RmpTaskName = Field(description="task name (registry key)")
    control_dt: float = Field(0.05, gt=0, description="action period, s (20 Hz)")
    substeps: int = Field(12, ge=1, description="physics steps per action (240 Hz physics)")
    horizon: int = Field(256, ge=1, description="actions per episode")
    gravity: float = Field(-9.81, description="gravity along z, m/s^2")
    robot: RobotConfig = Field(default_factory=RobotConfig, description="the KUKA iiwa")
    joint_limit_margin: float = Field(
        0.1, ge=0, description="a joint this close to a limit ends the episode, rad"
    )
    penalty: float = Field(10.0, ge=0, description="reward lost at a collision or limit event")
    control_points: ControlPointConfig = Field(default_factory=ControlPointConfig)
    obstacles: ObstacleConfig = Field(description="evaluation obstacles")
    scene: TrajScene | DoorScene | PushScene = Field(discriminator="kind")

    @property
    def physics_dt(self) -> float:
        return self.control_dt / self.substeps

    @model_validator(mode="after")
    def _scene_is_the_task(self) -> RmpTaskConfig:
        if self.scene.kind != self.name:
            raise ValueError(f"scene.kind {self.scene.kind!r} is not the task {self.name!r}")
        return self


RmpTaskFactory = Callable[[], RmpTaskConfig]
RMP_TASKS: Registry[RmpTaskFactory] = Registry("task", "RMP task", "RMP tasks")
"""Registered Chapter 6 task factories by name; fill it with `@register_rmp_task`."""
#: decorator: register a factory returning the default `RmpTaskConfig` of a name
register_rmp_task = RMP_TASKS.register


def get_rmp_task(name: str) -> RmpTaskConfig:
    """The default config of Chapter 6 task `name`; InputError listing the known ones."""
    return RMP_TASKS.lookup(name)()


_DOWN_START = [0.0, 0.6, 0.0, -1.3, 0.0, 1.2, 0.0]  # tool at (0.62, 0, 0.40), z down
_PUSH_START = [-0.255, 1.16, 0.0, -1.18, 0.0, 0.8, 0.0]  # tool at (0.65, -0.17, 0.07), z down


@register_rmp_task("traj")
def traj_task() -> RmpTaskConfig:
    """Trajectory following (VICES' domain): four via points in a box ahead of the robot;
    obstacles drawn in the same box (section 6.4.1)."""
    box = Box3(centre=[0.55, 0.0, 0.45], half_extents=[0.15, 0.25, 0.15])
    return RmpTaskConfig(
        name="traj",
        robot=RobotConfig(start_q=_DOWN_START, start_noise=0.02),
        obstacles=ObstacleConfig(volume=box),
        scene=TrajScene(box=box),
    )


@register_rmp_task("door")
def door_task() -> RmpTaskConfig:
    """Door opening: a cabinet ahead of the robot, its door handle grasped at the start
    (Chapter 5's grasp model), far enough that the grasp's path to the goal angle keeps
    every joint clear of its limits (`RmpEnv.grasp_path`, docs/rmp.md); obstacles in a box
    the arm sweeps along that path, clear of the door's swing (section 6.4.1)."""
    return RmpTaskConfig(
        name="door",
        robot=RobotConfig(start_q=_DOWN_START, start_noise=0.0),
        obstacles=ObstacleConfig(
            volume=Box3(centre=[0.35, -0.15, 0.5], half_extents=[0.15, 0.2, 0.2])
        ),
        scene=DoorScene(),
    )


@register_rmp_task("push")
def push_task() -> RmpTaskConfig:
    """Block pushing: a 5 cm cube to a goal on the table (Eq. 6.6); obstacles in a box
    above the pushing area (section 6.4.1)."""
    return RmpTaskConfig(
        name="push",
        robot=RobotConfig(start_q=_PUSH_START, start_noise=0.02),
        obstacles=ObstacleConfig(
            volume=Box3(centre=[0.6, 0.0, 0.3], half_extents=[0.15, 0.25, 0.1])
        ),
        scene=PushScene(
            block_start=Box3(centre=[0.65, -0.1, 0.0], half_extents=[0.04, 0.03, 0.0]),
            goal=Box3(centre=[0.65, 0.15, 0.0], half_extents=[0.05, 0.05, 0.0]),
        ),
    )
