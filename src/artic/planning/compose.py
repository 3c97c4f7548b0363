"""Composition of CIPs (thesis section 7.4; issue 21 part 8): learnt skills chained by
planning, with no further learning.

The scene (`layout`): each skill's object as its task draws it (jittered about its
nominal pose), then turned about the robot base's vertical axis (joint 1's) by the
skill's bearing, so the objects stand side by side at the distances they were trained
at. Turning a scene about that axis is a symmetry of the arm: joint 1 turned by the same
angle gives the same arm relative to the object. So a skill's observation, already in
its object's frame (`CipEnv`), reads joint 1 from the object's bearing (the direction of
its frame's origin seen from the base), and the skill meets the scene it was trained in.

One sequence (`run_sequence`), for each skill in order:
- head: the skill's best grasp under I_c (the highest success rate of its training
  run's bandit, ties: the lower index; the next one when no IK solution is collision
  free), moved with the object's frame as the robot knows it (true or perceived), IK
  warm-started from the grasp's stored solutions turned by the bearing, an OMPL
  RRTConnect plan to it from where the arm stands in the planning scene (the objects as
  the robot knows them, their joints where the simulator's sensors put them),
  time-parameterised and tracked with computed torque, the hand open;
- Gamma: the gripper closes;
- pi_c: the skill's policy (deterministic) until beta_c, B or the horizon;
- tail: the gripper opens and the tool retreats `retreat_m` along its approach; the next
  skill's head plans on from where the tail ended.
A skill is attempted whatever the previous one did; the sequence succeeds when every
skill reaches its beta_c.

Perceived models (`perceived_placement`): the object seen in one depth image by the
Chapter 3 network of its category (`planning/perception.py`, as `plan-demos`' predicted
source), and the skill's object frame anchored at the perceived handle: the frame in
which the handle stands where it stands on the task's object. The grasps, the policy's
frame and the planning scene then come from the estimate; the simulator still supplies
q_O (the object's joint sensed, as in training).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from artic.control.osc import vices_command
from artic.errors import InputError
from artic.learning.cip_train import HeadMotion
from artic.objects.model import ArticulatedObject
from artic.planning.cip_grasps import InitiationSet, in_collision, robot_ik, solution_order
from artic.planning.cip_head import plan_head, timed_path
from artic.sim.cip_envs import CipEnv, draw_object_pose, task_object
from artic.sim.cip_tasks import CipTaskConfig
from artic.sim.scene import load_articulated

if TYPE_CHECKING:
    from artic.kinematics.predict import Predictor
    from artic.planning.models import ModelConfig

F64 = NDArray[np.float64]
Actor = Callable[[NDArray[np.float32]], NDArray[np.float32]]
HANDLE = "handle_0"


def rot_about_base(angle: float) -> F64:
    """(4, 4) rotation by `angle` rad about the world's z axis through the robot base."""
    c, s = np.cos(angle), np.sin(angle)
    turn = np.eye(4)
    turn[:2, :2] = [[c, -s], [s, c]]
    return turn


def bearing(frame: F64) -> float:
    """The direction (rad, about world z) of `frame`'s origin seen from the robot base."""
    return float(np.arctan2(frame[1, 3], frame[0, 3]))


class Placement(NamedTuple):
    """One skill's object: `model` as it stands (world), `frame` (4, 4) the skill's
    object frame (the pose the policy's observations and actions are expressed in)."""

    task: CipTaskConfig
    model: ArticulatedObject
    frame: F64


def layout(
    tasks: Sequence[CipTaskConfig], bearings: Sequence[float], rng: np.random.Generator
) -> list[Placement]:
    """The true scene: each task's object drawn as its episodes draw it
    (`draw_object_pose`) and turned about the base by its bearing (rad)."""
    placements = []
    for task, angle in zip(tasks, bearings, strict=True):
        frame = rot_about_base(angle) @ draw_object_pose(task, rng)
        placements.append(Placement(task, task_object(task, frame), frame))
    return placements


def handle_frame(model: ArticulatedObject) -> F64:
    """(4, 4) the handle link's pose (world) with the object closed."""
    return model.link_poses(np.zeros(model.dof))[model.link_index(HANDLE)]


def anchored_frame(task: CipTaskConfig, model: ArticulatedObject) -> F64:
    """The object frame in which `model`'s handle stands where it stands on `task`'s
    object at its own frame (the identity): handle(model) handle(task's object)^-1."""
    return handle_frame(model) @ np.linalg.inv(handle_frame(task_object(task, np.eye(4))))


def frame_errors(true: Placement, known: Placement) -> tuple[float, float]:
    """How far the robot's knowledge `known` of an object is from `true`: the handle's
    position error (closed, cm) and the object frame's yaw error (deg)."""
    handle = float(
        np.linalg.norm(handle_frame(known.model)[:3, 3] - handle_frame(true.model)[:3, 3])
    )
    relative = np.linalg.inv(true.frame) @ known.frame
    yaw = float(np.degrees(abs(np.arctan2(relative[1, 0], relative[0, 0]))))
    return 100.0 * handle, yaw


def perceived_placement(
    true: Placement,
    nominal: F64,
    predictor: Predictor,
    cfg: ModelConfig,
    seed: int,
) -> tuple[Placement, dict[str, Any]]:
    """The object of `true` as the Chapter 3 network of its category sees it in one depth
    image (sensor noise from `seed`), from the level camera centred on the skill's
    nominal pose `nominal` (4, 4; the layout's, without the jitter): the predicted model
    (world) and the frame anchored at its handle (`anchored_frame`); and the perception's
    record (errors, refinement)."""
    from artic.geometry.transforms import yaw_of
    from artic.planning.models import CameraConfig, category_config, predicted_model
    from artic.planning.perception import centred_camera
    from artic.sim.cip_envs import task_spec

    category = true.task.object.category
    camera = centred_camera(nominal, category_config(category).pose)
    view = CameraConfig(position=[float(v) for v in camera[:3, 3]], yaw=yaw_of(camera[:3, :3]))
    spec = task_spec(true.task, true.frame)
    model, record = predicted_model(
        cfg.model_copy(update={"camera": view}), seed, true.model, spec, np.zeros(1),
        category, predictor,
    )  # fmt: skip
    return Placement(true.task, model, anchored_frame(true.task, model)), record


class ComposeEnv(CipEnv):
    """`CipEnv` over several objects (`placements`), one of them active at a time
    (`activate`): the simulated scene of a sequence, or, built from the models the
    robot knows, its planning scene (`set_object_joints`, `in_collision`)."""

    def __init__(
        self,
        placements: Sequence[Placement],
        safety: bool = True,
        contact_termination: bool = True,
    ) -> None:
        if not placements:
            raise ValueError("placements: at least one object")
        self.placements = list(placements)
        self.active = 0
        self.objects: list[int] = []
        super().__init__(placements[0].task, safety, contact_termination)

    def _draw(self, rng: np.random.Generator) -> F64:
        return self.placements[self.active].frame

    def _build(self) -> None:
        self._load_arm()
        self.objects = [load_articulated(self.client, p.model) for p in self.placements]
        self.model = self.placements[self.active].model
        self.object = self.objects[self.active]

    def activate(self, index: int, frame: F64 | None = None) -> None:
        """Make skill `index` the active one: its task (beta_c, B, horizon), its object
        (q_O, tactile), and `frame` (default: its placement's) as the object frame of
        observations and actions, joint 1 read from that frame's bearing."""
        placement = self.placements[index]
        self.active, self.task = index, placement.task
        self._safety_cfg = self.task.safety.model_copy(update={"enabled": self.safety})
        self.model, self.object = placement.model, self.objects[index]
        self.object_pose = placement.frame if frame is None else np.asarray(frame)
        self.joint_offset = np.zeros_like(self.joint_offset)
        self.joint_offset[0] = bearing(self.object_pose)

    def object_joints(self) -> list[float]:
        """q_O of every object (its one joint), rad or m."""
        return [float(self.client.getJointState(o, 0)[0]) for o in self.objects]

    def set_object_joints(self, values: Sequence[float]) -> None:
        """Place every object's joint at `values` (kinematic: a planning scene's)."""
        for body, value in zip(self.objects, values, strict=True):
            self.client.resetJointState(body, 0, float(value))

    def joints(self) -> F64:
        """q (7,) of the arm, rad."""
        return self._joints()[0]

    def track(self, waypoints: F64, speed: float, k_p: float, settle_s: float) -> float:
        """Follow the joint path `waypoints` (K, 7) at most `speed` rad/s per joint
        (`time_parameterize`, smoothed, then `settle_s` s held at its end) with
        computed torque (gains k_p, 2 sqrt(k_p)); returns the largest joint error at the
        end, rad."""
        timed = timed_path(waypoints, self.task.physics_dt, speed, settle_s)
        self.follow(timed.q, timed.qd, k_p)
        return float(np.abs(self.joints() - waypoints[-1]).max())

    def hold(self, seconds: float, displacement: F64 | None = None) -> None:
        """VICES (mid-range stiffness) holding the tool's orientation for `seconds`,
        its point at the current one plus `displacement` (3,) m (world, at most the
        action's 0.05 m)."""
        state = self.arm_state()
        action = np.zeros(12)
        if displacement is not None:
            action[:3] = np.asarray(displacement) / self.task.vices.position_scale
        command = vices_command(action, state.ee_position, state.ee_rotation, self.task.vices)
        for _ in range(round(seconds / self.task.physics_dt)):
            self._substep(command)

    def release_and_retreat(self, retreat_m: float, release_s: float, retreat_s: float) -> None:
        """The tail's first part: open the hand while VICES holds the tool, then move the
        tool `retreat_m` back along its approach in steps of at most 0.05 m."""
        self.gripper.command(close=False)
        self.hold(release_s)
        steps = max(1, int(np.ceil(retreat_m / self.task.vices.position_scale - 1e-9)))
        approach = self.robot.tool_pose()[:3, 2]
        for _ in range(steps):
            self.hold(retreat_s / steps, -approach * retreat_m / steps)


def grasp_order(initiation_set: InitiationSet) -> list[int]:
    """The grasps, best first: success rate of the training run's bandit (descending;
    ties: the lower index)."""
    rates = initiation_set.bandit.success_rates()
    return [int(i) for i in np.argsort(-rates, kind="stable")]


class HeadGoal(NamedTuple):
    """The head's target: grasp index (-1: none reachable), q (7,) or None."""

    grasp: int
    q: F64 | None


def head_goal(
    initiation_set: InitiationSet,
    frame: F64,
    plan_env: ComposeEnv,
    clearance: float,
    grasps_tried: int,
    margin: float,
) -> HeadGoal:
    """The first of the `grasps_tried` best grasps (`grasp_order`) with a collision-free
    IK solution in the planning scene at the object frame `frame` (4, 4), warm-started
    from its stored solutions (best score first) turned by the change of bearing, every
    joint at least `margin` rad from its limits."""
    ik = robot_ik(plan_env.robot, margin)
    turn = bearing(frame) - bearing(initiation_set.object_pose)
    obstacles = tuple(plan_env.objects)
    for grasp in grasp_order(initiation_set)[:grasps_tried]:
        target = frame @ initiation_set.grasps[grasp]
        for k in solution_order(initiation_set, grasp, "cip"):
            seed = initiation_set.solutions[grasp][k].copy()
            seed[0] += turn
            q = ik(target, seed)
            if q is not None and not in_collision(plan_env, q, clearance, obstacles):
                return HeadGoal(grasp, q)
    return HeadGoal(-1, None)


class Skill(NamedTuple):
    """A learnt skill: its task, policy pi_c, initiation set (with the training run's
    bandit) and the least joint-limit distance of its starts, rad (its setting's:
    `learning.cip_train.start_margin`)."""

    task: CipTaskConfig
    actor: Actor
    initiation_set: InitiationSet
    margin: float


class MotionConfig(HeadMotion):
    """The constants of heads and tails (`compose`'s `motion`): a head's plan and
    tracking (`HeadMotion`, shared with train-cip's `head`), the grasps tried, the tail."""

    grasps_tried: int = Field(3, ge=1, description="best grasps tried for a reachable one")
    release_s: float = Field(0.5, gt=0, description="the hand opening, s")
    retreat_m: float = Field(0.1, ge=0, description="tail: retreat along the approach, m")
    retreat_s: float = Field(1.0, gt=0, description="tail: the retreat's duration, s")


class SkillOutcome(NamedTuple):
    """One skill of a sequence. end: success | joint_limit | contact_lost | horizon |
    no_grasp | no_plan. plan_checks: the head's validity checks (OMPL; 0 without a
    goal). head_start, tail_end: (7,) where its head's plan started and its tail ended
    (rad)."""

    task: str
    grasp: int
    plan_checks: int
    tracking_error: float
    steps: int
    success: bool
    end: str
    head_start: F64
    tail_end: F64


def run_sequence(
    skills: Sequence[Skill],
    sim: ComposeEnv,
    plan_env: ComposeEnv,
    frames: Sequence[F64],
    cfg: MotionConfig,
    seed: int,
) -> list[SkillOutcome]:
    """One sequence (module docstring) in `sim` (its placements: the true scene), the
    heads planned in `plan_env` (the scene as the robot knows it) with the skills'
    object frames `frames` (the same knowledge); OMPL seeded from `seed`."""
    sim.activate(0)
    sim.reset()
    outcomes: list[SkillOutcome] = []
    for index, (skill, frame) in enumerate(zip(skills, frames, strict=True)):
        start = sim.joints()
        plan_env.set_object_joints(sim.object_joints())
        goal = head_goal(skill.initiation_set, frame, plan_env, cfg.clearance_m,
                         cfg.grasps_tried, skill.margin)  # fmt: skip
        checks, error, steps, success, end = 0, float("nan"), 0, False, "no_grasp"
        if goal.q is not None:
            plan = plan_head(plan_env, start, goal.q, cfg, seed * 101 + index, plan_env.objects)
            checks, end = plan.validity_checks, "no_plan"
            if plan.solved:
                error = sim.track(plan.path, cfg.speed, cfg.k_p, cfg.settle_s)
                sim.activate(index, frame)
                steps, success, end = _contact_phase(sim, skill.actor)
        if goal.q is not None and end != "no_plan":
            sim.release_and_retreat(cfg.retreat_m, cfg.release_s, cfg.retreat_s)
        outcomes.append(SkillOutcome(skill.task.name, goal.grasp, checks, error, steps, success,
                                     end, start, sim.joints()))  # fmt: skip
    return outcomes


def _contact_phase(sim: ComposeEnv, actor: Actor) -> tuple[int, bool, str]:
    """Gamma, then pi_c until beta_c, B or the horizon: (actions, success, end)."""
    obs = sim.grasp_here()
    info: dict[str, Any] = {}
    step, done = 0, False
    while not done:
        obs, _, terminated, truncated, info = sim.step(actor(obs))
        step, done = step + 1, terminated or truncated
    if info.get("success"):
        return step, True, "success"
    for key in ("joint_limit", "contact_lost"):
        if info.get(key):
            return step, False, key
    return step, False, "horizon"


def check_compatible(tasks: Sequence[CipTaskConfig]) -> None:
    """InputError unless the skills' tasks share one robot, gripper, action space,
    envelope and physics (they run in one scene)."""
    fields = ("control_dt", "substeps", "gravity", "robot", "gripper", "vices", "safety")
    first = tasks[0]
    for task in tasks[1:]:
        for name in fields:
            if getattr(task, name) != getattr(first, name):
                raise InputError(f"skills: {first.name} and {task.name} were trained with "
                                 f"different task.{name}; they cannot share a scene")  # fmt: skip
