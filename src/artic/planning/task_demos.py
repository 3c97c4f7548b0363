"""Algorithm 2 on a simulated Chapter 5 task: the config of `artic plan-demos`, the
kinematic model the demos are planned with (`planning_model`), the world's robot as the
functions the planner takes (`robot_functions`), planning one demo (`plan_one`) and
executing it in the simulator by joint-velocity tracking (`execute`,
`artic.control.tracking`). Demo i is drawn from a generator seeded by (seed, i).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import Field, model_validator

from artic.artifacts.demo_dataset import demo_name
from artic.config.schemas import StageConfig, Strict
from artic.planning.demos import (
    DemoProblem,
    GraspSettings,
    NoiseSettings,
    PlannerSettings,
    TimingSettings,
    perturbed_problem,
    plan_demo,
)
from artic.planning.models import ModelConfig
from artic.sim.tasks import ArticulatedScene, TaskConfig, TBallScene

if TYPE_CHECKING:
    from artic.artifacts.model_store import ModelChoice
    from artic.objects.model import ArticulatedObject
    from artic.planning.demos import Demo, RobotFunctions
    from artic.sim.world import TaskWorld


class DemosConfig(Strict):
    """How many demonstrations, and how many per chunk (the resume/shard unit)."""

    count: int = Field(10, gt=0, description="demonstrations to plan (thesis: 10)")
    per_chunk: int = Field(1, gt=0, description="demonstrations per chunk")


class ExecuteConfig(Strict):
    """Execute each demo in the simulator (joint-velocity tracking) and record the result."""

    enabled: bool = Field(True, description="run the demo in the simulator")
    gain: float = Field(5.0, ge=0, description="qd_cmd = qd_plan[k] + gain (q_plan[k] - q), 1/s")
    extra_steps: int = Field(10, ge=0, description="steps of holding still after the demo")


class PlanDemosConfig(StageConfig):
    task: TaskConfig
    demos: DemosConfig
    model: ModelConfig
    planner: PlannerSettings
    grasp: GraspSettings
    timing: TimingSettings
    noise: NoiseSettings
    execute: ExecuteConfig

    @model_validator(mode="after")
    def _goal_in_range(self) -> PlanDemosConfig:
        scene = self.task.scene
        low, high = scene.travel if isinstance(scene, TBallScene) else scene.joint_limits
        for name, value in (("goal", self.task.goal), ("object_start", self.task.object_start)):
            if any(not low <= v <= high for v in value):
                raise ValueError(
                    f"task {self.task.name}: {name} {value} is outside the object's range "
                    f"[{low}, {high}]"
                )
        if self.model.source == "predicted" and not isinstance(scene, ArticulatedScene):
            raise ValueError(
                f"model.source: 'predicted' needs an object with a Chapter 3 MDN category "
                f"(drawer, microwave); task {self.task.name} has none"
            )
        return self


def mdn_choice(cfg: PlanDemosConfig) -> ModelChoice:
    """The MDN the `predicted` model comes from, chosen as `artic predict` chooses
    (`artifacts.model_store.choose_model`): `model.mdn` (a model.pt, or a train-mdn
    output folder: its model.pt); else `<artifacts_root>/models/mdn/<category>` unless it
    is a debug model; else the shipped model of the category."""
    from artic.artifacts.model_store import MODEL_FILE, choose_model

    scene = cfg.task.scene
    assert isinstance(scene, ArticulatedScene)
    given = Path(cfg.model.mdn) if cfg.model.mdn is not None else None
    if given is not None and given.is_dir():
        given = given / MODEL_FILE
    root = Path(cfg.artifacts_root) / "models"
    return choose_model("mdn", scene.category, given, "model.mdn", root=root)


def mdn_input(cfg: PlanDemosConfig) -> dict[str, Path]:
    """plan-demos' stage inputs: {"mdn": the train-mdn output folder holding the chosen
    MDN (`mdn_choice`; its manifest beside it)} for the `predicted` source; nothing for
    the others, nor for a shipped model (its bytes are checked against its model card
    instead, and demos.json records its sha256)."""
    from artic.artifacts.manifest import MANIFEST

    if cfg.model.source != "predicted":
        return {}
    folder = mdn_choice(cfg).path.parent
    return {"mdn": folder} if (folder / MANIFEST).is_file() else {}


def planning_model(
    cfg: ModelConfig, seed: int, world: TaskWorld, mdn: Path | None = None
) -> tuple[ArticulatedObject, dict[str, Any]]:
    """The kinematic model to plan with (one for all demos: the robot estimates the object
    once) and its record for demos.json (`artic.planning.models`); `mdn`: the MDN's
    model.pt for the `predicted` source (`mdn_choice`)."""
    from artic.planning.models import noisy_model, predicted_model

    true = world.kinematic_model()
    if cfg.source == "true":
        return true, {"source": cfg.source}
    if cfg.source == "noisy":
        return noisy_model(cfg, seed, true)
    if mdn is None:
        raise ValueError("model.source predicted needs the MDN's model file")
    from artic.artifacts.hashing import sha256_file
    from artic.kinematics.predict import Predictor

    scene = world.cfg.scene
    assert isinstance(scene, ArticulatedScene)
    predictor = Predictor.load(mdn, scene.category)
    start = np.asarray(world.cfg.object_start, dtype=np.float64)
    model, record = predicted_model(cfg, seed, true, scene.spec(), start, scene.category, predictor)
    return model, {"source": "predicted", "mdn": str(mdn), "mdn_sha256": sha256_file(mdn),
                   **record}  # fmt: skip


def robot_functions(world: TaskWorld) -> RobotFunctions:
    """The world's robot as the functions Algorithm 2 takes."""
    from artic.planning.demos import RobotFunctions

    limits = world.robot_limits()
    return RobotFunctions(
        ik=world.ik,
        in_collision=world.in_collision,
        ee_pose=world.ee_pose,
        low=np.asarray(limits.low, dtype=np.float64),
        high=np.asarray(limits.high, dtype=np.float64),
        max_velocity=np.asarray(world.velocity_limits(), dtype=np.float64),
    )


def plan_one(
    cfg: PlanDemosConfig, world: TaskWorld, model: ArticulatedObject, index: int
) -> tuple[Demo | None, dict[str, Any]]:
    """Plan demo `index` (Algorithm 2) and, if it succeeded, execute it; returns the demo
    and its record: the demos.json fields plus `planning_time_s` (wall clock, s), which
    the stage moves to timings.json. `model`: the kinematic model to plan with."""

    robot = robot_functions(world)
    nominal = DemoProblem(
        model=model,
        link=world.grasp_target_link,
        q_robot_start=np.asarray(cfg.task.robot.start_q, dtype=np.float64),
        q_object_start=np.asarray(cfg.task.object_start, dtype=np.float64),
        q_object_goal=np.asarray(cfg.task.goal, dtype=np.float64),
        dt=world.dt,
        max_steps=world.horizon,
    )
    rng = np.random.default_rng([cfg.seed, index])
    unperturbed = index == 0 and cfg.noise.nominal_first
    problem = nominal if unperturbed else perturbed_problem(nominal, cfg.noise, robot, rng)
    noise = None if unperturbed else cfg.noise
    outcome = plan_demo(problem, robot, cfg.planner, cfg.grasp, cfg.timing, noise, rng)
    record: dict[str, Any] = {
        "index": index,
        "file": None,
        "status": outcome.status,
        "reason": outcome.reason,
        "planning_time_s": round(outcome.planning_time_s, 4),
        "steps": 0,
        "q_robot_start": problem.q_robot_start.tolist(),
        "q_object_start": problem.q_object_start.tolist(),
    }
    demo = outcome.demo
    if demo is not None:
        record.update(
            file=demo_name(index),
            steps=len(demo.t),
            grasp_step=demo.grasp_step,
            reached_fraction=round(demo.reached_fraction, 4),
        )
        if cfg.execute.enabled:
            record["executed"] = execute(world, demo, cfg)
    return demo, record


def execute(world: TaskWorld, demo: Demo, cfg: PlanDemosConfig) -> dict[str, Any]:
    """Run `demo` in the simulator from its start, tracking it in joint velocities
    (`artic.control.tracking.JointTracker`, gain `execute.gain`), then hold still for
    `extra_steps`. Returns the achieved object configuration, its error to the goal and
    whether the task's success threshold holds."""
    from artic.control.tracking import JointTracker

    goal = np.asarray(cfg.task.goal, dtype=np.float64)
    world.reset(demo.q_robot[0], demo.q_object[0])
    tracker = JointTracker(demo.q_robot, demo.qd_robot, cfg.execute.gain)
    steps = len(demo.t) + cfg.execute.extra_steps
    tracking = 0.0
    for k in range(steps):
        q = world.robot_q()
        tracking = max(tracking, float(np.max(np.abs(tracker.reference(k)[0] - q))))
        world.apply_action(tracker.action(k, q))
        world.step()
    achieved = world.object_q()
    error = float(np.linalg.norm(achieved - goal))
    return {
        "q_object": [round(float(v), 6) for v in achieved],
        "goal_error": round(error, 6),
        "success": bool(error <= cfg.task.success_threshold),
        "max_tracking_error_rad": round(tracking, 6),
        "steps": steps,
    }


def demos_index(
    cfg: PlanDemosConfig, records: list[dict[str, Any]], model: dict[str, Any], n_joints: int
) -> dict[str, Any]:
    """demos.json (docs/formats.md, Chapter 5): the task, the kinematic model's record and
    every demo's record (deterministic: the planning times are in `timings_record`)."""
    return {
        "task": cfg.task.name,
        "n_requested": cfg.demos.count,
        "control_dt": cfg.task.control_dt,
        "horizon": cfg.task.horizon,
        "goal": list(cfg.task.goal),
        "n_joints": n_joints,
        "dof_object": len(cfg.task.goal),
        "kinematic_model": model,
        "planner": cfg.planner.name,
        "demos": records,
    }


def timings_record(
    cfg: PlanDemosConfig, records: list[dict[str, Any]], times: list[float]
) -> dict[str, Any]:
    """timings.json: the wall-clock planning time of each demo, and their median."""
    return {
        "task": cfg.task.name,
        "median_planning_time_s": round(float(np.median(times)), 4),
        "demos": [
            {"index": r["index"], "status": r["status"], "planning_time_s": t}
            for r, t in zip(records, times, strict=True)
        ],
    }


def demo_stats(
    cfg: PlanDemosConfig,
    records: list[dict[str, Any]],
    times: list[float],
    model_record: dict[str, Any],
) -> dict[str, float | int | str]:
    """plan-demos' run statistics from its demo records (`plan_one`), their planning
    times and the kinematic model's record."""
    ok = [r for r in records if r["status"] == "ok"]
    stats: dict[str, float | int | str] = {
        "task": cfg.task.name,
        "kinematic model": cfg.model.source,
        "demos planned": len(ok),
        "demos failed": len(records) - len(ok),
        "median planning time (s)": float(np.median(times)),
        "median steps": int(np.median([r["steps"] for r in ok])) if ok else 0,
    }
    if cfg.model.source == "predicted":
        unit = model_record["configuration_error_unit"]
        stats["MDN"] = model_record["mdn"]
        for key, name in (
            ("axis_position_error_cm", "axis position error (cm)"),
            ("axis_direction_error_deg", "axis direction error (deg)"),
            ("configuration_error", f"configuration error ({unit})"),
        ):
            stats[name] = round(float(np.mean(model_record[key])), 4)
    executed = [r["executed"] for r in ok if "executed" in r]
    if executed:
        stats["executed successes"] = sum(e["success"] for e in executed)
        stats["median executed goal error"] = float(np.median([e["goal_error"] for e in executed]))
    return stats
