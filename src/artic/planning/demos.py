"""Algorithm 2 (InitialMPDemos, thesis Chapter 5): motion-planned demonstrations.

  T_O    <- MotionPlanner(C_O, q_O*)          plan_path in the object's configuration space
  g      <- EstimateGrasp(C_O, f_O)           grasp.estimate_grasp from the handle (or ball)
  eepath <- GraspPath(T_O, C_O, f_O, g)       grasp.grasp_path: f_O along T_O composed with g
  T_R    <- MotionPlanner(C_R, eepath, f_R^-1)  IK along eepath, seeded by the previous
            solution, after a collision-free plan_path in C_R from the start to the
            pre-grasp configuration and a straight approach to the grasp

The robot is seen only through functions (`RobotFunctions`: IK, collision check,
forward kinematics, limits), so nothing here knows about the simulator. Demonstration i
perturbs the start state, the object plan and the grasp with Gaussian noise drawn from
its own generator, so demos can be planned in any order, or on different machines.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from artic.config.schemas import Strict
from artic.objects.model import ArticulatedObject
from artic.planning.grasp import (
    Grasp,
    estimate_grasp,
    grasp_path,
    interpolate_poses,
    pregrasp_pose,
)
from artic.planning.ompl_adapter import PlanResult, plan_path
from artic.planning.trajectory import Timed, time_parameterize

Array = NDArray[np.float64]


class PlannerSettings(Strict):
    """OMPL settings of both MotionPlanner calls of Algorithm 2."""

    name: Literal["rrtconnect", "rrtstar"] = Field("rrtconnect", description="OMPL planner")
    time_budget_s: float = Field(1.0, gt=0, description="wall-time limit of each plan, s")
    max_checks: int | None = Field(
        None, gt=0, description="also stop after this many validity checks (rrtstar)"
    )
    object_resolution: float = Field(
        0.005, gt=0, description="spacing of the object plan T_O, m or rad"
    )
    robot_resolution: float = Field(
        0.05, gt=0, description="collision-check spacing of the robot's approach plan, rad"
    )
    simplify: bool = Field(True, description="shortcut the plans (OMPL PathSimplifier)")


class GraspSettings(Strict):
    """EstimateGrasp, GraspPath and the IK along the end-effector path."""

    kind: Literal["auto", "handle", "push"] = Field(
        "auto", description="auto: handle for a handle link, push otherwise (t-ball)"
    )
    standoff_m: float = Field(
        0.0, description="handle: tool point this far in front of the bar's centre, m"
    )
    push_standoff_m: float = Field(
        -0.05,
        description="push: tool point this far behind the part's surface, m; negative puts "
        "it inside, so that the hand's physical end touches (artic's iiwa: the flange is "
        "0.055 m behind the tool point)",
    )
    push_pitch_rad: float = Field(
        0.5,
        ge=0,
        lt=1.5,
        description="push: tilt of the tool's approach axis below the push direction, rad "
        "(the arm comes from above-behind, clear of what the pushed part rests on)",
    )
    push_lift_m: float = Field(
        0.03,
        description="push: tool point this far above the contact point in the tool's end "
        "face (along the tool x axis), m: strike with the lower rim of the hand",
    )
    pregrasp_m: float = Field(0.08, ge=0, description="pre-grasp distance back from the grasp, m")
    ee_step_m: float = Field(0.01, gt=0, description="spacing of the straight approach, m")
    max_joint_jump_rad: float = Field(
        0.3, gt=0, description="largest joint change between IK waypoints (else IK failed)"
    )
    min_reach_fraction: float = Field(
        0.1,
        ge=0,
        le=1,
        description="a demo whose IK stops earlier than this fraction of the object's motion "
        "fails; later, it is kept, truncated (the robot's reach ends the plan)",
    )


class TimingSettings(Strict):
    """Time-parameterisation of the robot path at the task's control period."""

    velocity_scale: float = Field(
        0.5, gt=0, le=1, description="fraction of the robot's joint speed limits used"
    )
    object_max_velocity: float = Field(
        0.25, gt=0, description="largest object speed along the plan, m/s or rad/s"
    )
    smoothing_s: float = Field(0.05, ge=0, description="Gaussian smoothing of positions, s")
    hold_s: float = Field(0.25, ge=0, description="standing still at the end, s")
    fit_horizon: bool = Field(
        True,
        description="speed a demo longer than the task's horizon up to fit it (at most to "
        "the robot's full joint speed limits)",
    )


class NoiseSettings(Strict):
    """Perturbations that make N different demos (section 5.3.1)."""

    start_robot_rad: float = Field(0.02, ge=0, description="std of the robot start, rad")
    start_object: float = Field(0.0, ge=0, description="std of the object start, m or rad")
    plan: float = Field(
        0.01, ge=0, description="std of the smooth perturbation of T_O's interior, m or rad"
    )
    grasp_m: float = Field(0.005, ge=0, description="std of the grasp position, m")
    nominal_first: bool = Field(True, description="demo 0 is the unperturbed plan")


@dataclass(frozen=True)
class RobotFunctions:
    """What Algorithm 2 needs of the robot, as functions (no simulator here).

    ik(pose (4, 4), seed (n,)) -> (n,) | None; in_collision(q_robot (n,), q_object
    (dof,)) -> bool; ee_pose(q_robot (n,)) -> (4, 4) world pose of the tool frame (tool
    +z = approach direction); low, high: (n,) joint limits, rad; max_velocity: (n,) rad/s.
    """

    ik: Callable[[Array, Array], Array | None]
    in_collision: Callable[[Array, Array], bool]
    ee_pose: Callable[[Array], Array]
    low: Array
    high: Array
    max_velocity: Array


@dataclass(frozen=True)
class DemoProblem:
    """One task's planning problem: the object's kinematic model (the estimate planned
    with), the link to grasp (index into `model.links`), start states q_R (n,) and q_O
    (dof,), goal q_O* (dof,), control period dt (s), and the number of steps a demo
    should fit in (the task's horizon; None: any)."""

    model: ArticulatedObject
    link: int
    q_robot_start: Array
    q_object_start: Array
    q_object_goal: Array
    dt: float
    max_steps: int | None = None


@dataclass(frozen=True)
class Demo:
    """A planned demonstration sampled every dt: t (T,) s; q_robot (T, n) rad; qd_robot
    (T, n) rad/s (forward differences, the velocity to command at each step); q_object
    (T, dof) the object's configuration along the plan; ee_pose (T, 4, 4) world tool
    poses. grasp_step: first step of the grasp path. reached_fraction: share of the
    object's planned motion the robot's IK could follow (1 = the whole plan)."""

    t: Array
    q_robot: Array
    qd_robot: Array
    q_object: Array
    ee_pose: Array
    grasp_step: int
    reached_fraction: float


@dataclass(frozen=True)
class DemoOutcome:
    """A demo, or why there is none. status "ok" | "failed"; reason: "" or one line."""

    demo: Demo | None
    status: Literal["ok", "failed"]
    reason: str
    planning_time_s: float


def joint_limits(model: ArticulatedObject) -> tuple[Array, Array]:
    """(low (dof,), high (dof,)) of the object's movable joints."""
    limits = np.array([j.limits for j in model.movable_joints], dtype=np.float64)
    return limits[:, 0], limits[:, 1]


def smooth_perturbation(
    path: Array, std: float, rng: np.random.Generator, low: Array, high: Array
) -> Array:
    """path (K, dof) + sum_k a_k sin(k pi s), k = 1, 2, a_k ~ N(0, std^2) per DoF,
    s in [0, 1] the path parameter: zero at both ends, smooth, clipped to [low, high]."""
    s = np.linspace(0.0, 1.0, len(path))[:, None]
    a = rng.normal(0.0, std, (2, path.shape[1]))
    bump = a[0] * np.sin(np.pi * s) + a[1] * np.sin(2.0 * np.pi * s)
    return np.clip(path + bump, low, high)


def perturbed_problem(
    problem: DemoProblem,
    noise: NoiseSettings,
    robot: RobotFunctions,
    rng: np.random.Generator,
) -> DemoProblem:
    """The problem with Gaussian noise on the robot's and the object's start state."""
    low, high = joint_limits(problem.model)
    q_r = problem.q_robot_start + rng.normal(0.0, noise.start_robot_rad, robot.low.shape)
    q_o = problem.q_object_start + rng.normal(0.0, noise.start_object, low.shape)
    return DemoProblem(
        model=problem.model,
        link=problem.link,
        q_robot_start=np.clip(q_r, robot.low, robot.high),
        q_object_start=np.clip(q_o, low, high),
        q_object_goal=problem.q_object_goal,
        dt=problem.dt,
        max_steps=problem.max_steps,
    )


def grasp_kind(model: ArticulatedObject, link: int, kind: str) -> Literal["handle", "push"]:
    """The grasp kind for `link`: "auto" means handle for a "handle" link, push otherwise."""
    if kind == "auto":
        return "handle" if model.links[link].role == "handle" else "push"
    return "handle" if kind == "handle" else "push"


class _Failed(Exception):
    """A demo could not be planned; the message is its one-line reason."""


def plan_demo(
    problem: DemoProblem,
    robot: RobotFunctions,
    planner: PlannerSettings,
    grasp_cfg: GraspSettings,
    timing: TimingSettings,
    noise: NoiseSettings | None,
    rng: np.random.Generator,
) -> DemoOutcome:
    """Algorithm 2 for one demonstration (see the module docstring).

    noise: perturb the object plan and the grasp (None: the nominal plan); the start
    state is perturbed by the caller (`perturbed_problem`). rng: the demo's own
    generator; OMPL's seeds are drawn from it too. Never raises for a plan that fails:
    the outcome says why.
    """
    t0 = time.perf_counter()
    try:
        demo = _plan(problem, robot, planner, grasp_cfg, timing, noise, rng)
    except _Failed as failure:
        return DemoOutcome(None, "failed", str(failure), time.perf_counter() - t0)
    return DemoOutcome(demo, "ok", "", time.perf_counter() - t0)


def _plan(
    problem: DemoProblem,
    robot: RobotFunctions,
    planner: PlannerSettings,
    grasp_cfg: GraspSettings,
    timing: TimingSettings,
    noise: NoiseSettings | None,
    rng: np.random.Generator,
) -> Demo:
    model, q_o0, goal = problem.model, problem.q_object_start, problem.q_object_goal
    low, high = joint_limits(model)
    seeds = rng.integers(0, 2**31 - 1, size=2)
    # 1. MotionPlanner in C_O
    object_plan = _motion_plan(
        low, high, q_o0, goal, lambda q: True, planner, int(seeds[0]), planner.object_resolution
    )
    if not object_plan.solved:
        raise _Failed(f"object plan: {object_plan.status}")
    path_o = object_plan.path
    if noise is not None and noise.plan > 0:
        path_o = smooth_perturbation(path_o, noise.plan, rng, low, high)
    # 2. EstimateGrasp
    kind = grasp_kind(model, problem.link, grasp_cfg.kind)
    direction = float(np.sign(np.sum(goal - q_o0)) or 1.0)
    standoff = grasp_cfg.standoff_m if kind == "handle" else grasp_cfg.push_standoff_m
    push = (grasp_cfg.push_pitch_rad, grasp_cfg.push_lift_m) if kind == "push" else (0.0, 0.0)
    grasp = estimate_grasp(model, problem.link, q_o0, kind, standoff, direction, *push)
    if noise is not None and noise.grasp_m > 0:
        offset = grasp.offset.copy()
        offset[:3, 3] += rng.normal(0.0, noise.grasp_m, 3)
        grasp = Grasp(grasp.link, offset, grasp.kind, grasp.approach)
    # 3. GraspPath
    ee_path = grasp_path(model, grasp, path_o)
    # 4. robot: pre-grasp IK, collision-free approach in C_R, straight approach, IK path
    pre = pregrasp_pose(ee_path[0], grasp_cfg.pregrasp_m)
    q_pre = robot.ik(pre, problem.q_robot_start)
    if q_pre is None:
        raise _Failed("IK: no solution for the pre-grasp pose")
    if robot.in_collision(q_pre, q_o0):
        raise _Failed("pre-grasp configuration in collision")
    approach = _motion_plan(
        robot.low,
        robot.high,
        problem.q_robot_start,
        q_pre,
        lambda q: not robot.in_collision(q, q_o0),
        planner,
        int(seeds[1]),
        planner.robot_resolution,
    )
    if not approach.solved:
        raise _Failed(f"robot approach plan: {approach.status}")
    approach_poses = interpolate_poses(pre, ee_path[0], grasp_cfg.ee_step_m)[1:]
    straight = _ik_chain(robot, approach_poses, q_pre, grasp_cfg.max_joint_jump_rad)
    if len(straight) < len(approach_poses):
        raise _Failed("IK: the straight approach to the grasp is not reachable")
    along = _ik_chain(robot, ee_path[1:], straight[-1], grasp_cfg.max_joint_jump_rad)
    reached = _reached_fraction(path_o[: len(along) + 1], q_o0, goal)
    if reached < grasp_cfg.min_reach_fraction:
        raise _Failed(
            f"IK: the grasp path is reachable for {reached:.0%} of the object's motion "
            f"(min_reach_fraction {grasp_cfg.min_reach_fraction:.0%})"
        )
    # combine: object at rest during the approach, then along T_O
    n = len(q_pre)
    q_path = np.concatenate([approach.path, np.array(straight), np.reshape(along, (-1, n))])
    n_still = len(approach.path) + len(straight)
    o_path = np.concatenate([np.repeat(q_o0[None], n_still, axis=0), path_o[1 : len(along) + 1]])
    timed = _timed(q_path, o_path, problem, robot, timing)
    moving = np.flatnonzero(np.any(np.abs(timed.extra - q_o0) > 1e-9, axis=1))
    grasp_step = int(moving[0]) - 1 if len(moving) else len(timed.t) - 1
    ee = np.stack([robot.ee_pose(q) for q in timed.q])
    return Demo(timed.t, timed.q, timed.qd, timed.extra, ee, max(grasp_step, 0), reached)


def _motion_plan(
    low: Array,
    high: Array,
    start: Array,
    goal: Array,
    is_valid: Callable[[Array], bool],
    planner: PlannerSettings,
    seed: int,
    resolution: float,
) -> PlanResult:
    """MotionPlanner of Algorithm 2 with the stage's OMPL settings."""
    return plan_path(
        low,
        high,
        start,
        goal,
        is_valid,
        planner=planner.name,
        time_budget_s=planner.time_budget_s,
        seed=seed,
        resolution=resolution,
        simplify=planner.simplify,
        max_checks=planner.max_checks,
    )


def _timed(
    q_path: Array,
    o_path: Array,
    problem: DemoProblem,
    robot: RobotFunctions,
    timing: TimingSettings,
) -> Timed:
    """Time-parameterise at `timing`'s speeds; if that takes more than the problem's
    `max_steps` and `timing.fit_horizon`, speed the motion up to fit, at most to the
    robot's full joint speed limits."""
    vmax = robot.max_velocity * timing.velocity_scale
    omax = np.full(o_path.shape[1], timing.object_max_velocity)

    def timed(factor: float) -> Timed:
        return time_parameterize(
            q_path,
            problem.dt,
            np.minimum(vmax * factor, robot.max_velocity),
            extra=o_path,
            extra_max_velocity=omax * factor,
            smoothing_s=timing.smoothing_s,
            hold_s=timing.hold_s,
        )

    out = timed(1.0)
    limit = problem.max_steps
    if limit is None or not timing.fit_horizon or len(out.t) <= limit:
        return out
    # the steps that do not shrink: lead-in, hold, the last one (a path with no motion)
    still = len(
        time_parameterize(
            q_path[:1], problem.dt, vmax, o_path[:1], omax, timing.smoothing_s, timing.hold_s
        ).t
    )
    moving, allowed = len(out.t) - still, limit - still
    if allowed <= 0:
        return out
    return timed(moving / allowed * (1.0 + 1e-9))


def _ik_chain(robot: RobotFunctions, poses: Array, seed: Array, max_jump: float) -> list[Array]:
    """IK along `poses` (M, 4, 4), each seeded by the previous solution; stops at the
    first pose without a solution or with a joint jump above `max_jump` rad."""
    out: list[Array] = []
    previous = seed
    for pose in poses:
        q = robot.ik(pose, previous)
        if q is None or float(np.max(np.abs(q - previous))) > max_jump:
            break
        out.append(q)
        previous = q
    return out


def _reached_fraction(path: Array, start: Array, goal: Array) -> float:
    """How far along start -> goal the last configuration of `path` (K, dof) got, 0..1."""
    total = float(np.linalg.norm(goal - start))
    if total == 0.0:
        return 1.0
    return float(np.clip(np.dot(path[-1] - start, goal - start) / total**2, 0.0, 1.0))
