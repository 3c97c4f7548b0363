"""`artic plan-demos`: motion-planned demonstrations of a Chapter 5 task (Algorithm 2).

The task's world (`artic.sim.world.TaskWorld`, built once per process) lends the robot's
inverse kinematics, collision check and forward kinematics as functions to
`artic.planning.demos.plan_demo`, which plans on a kinematic model of the object: the
world's true one, a noisy copy, or the one the Chapter 3 MDN (`model.mdn`, a stage
input) predicts from a rendered depth view (`model.source`). Demo i is drawn from a generator
seeded by (seed, i); chunks hold `demos.per_chunk` demos, so any sharding writes the same
demo files. Each planned demo is then executed in the simulator by joint-velocity
tracking (`execute`), and the object configuration it achieves is recorded: the plan is
kinematic, so it may not move a heavy drawer all the way (thesis Fig. 5.3b).

Outputs are the same bytes for the same seed and config, whatever the sharding, except
`timings.json`: the wall-clock planning time of each demo lives there, not in demos.json.
"""

from __future__ import annotations

import functools
import json
import math
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import Field, model_validator

from artic.artifacts.formats import write_json, write_npz
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import StageConfig, Strict
from artic.errors import InputError
from artic.kinematics import Estimator
from artic.planning.demos import GraspSettings, NoiseSettings, PlannerSettings, TimingSettings
from artic.render.noise import SensorNoiseConfig
from artic.sim.tasks import ArticulatedScene, TaskConfig, TBallScene

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from artic.objects.model import ArticulatedObject
    from artic.objects.spec import CategoryConfig, PoseRanges
    from artic.planning.demos import Demo, RobotFunctions
    from artic.sim.world import TaskWorld

DEMOS_JSON = "demos.json"
TIMINGS_JSON = "timings.json"  # wall-clock planning times: the one output that varies by run
RECORDS = "records"  # per-demo JSON records, merged into demos.json by finalize
MODEL_STREAM = 1_000_003  # generator stream of the noisy model: (seed, MODEL_STREAM)
PERCEPTION_STREAM = 1_000_033  # generator stream of the predicted model's sensor noise
MDN_KIND = "kinematics-mdn"  # model-file kind written by train-mdn


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

    source: Literal["true", "noisy", "predicted"] = Field(
        "true",
        description="true: the world's model; noisy: it with Gaussian axis errors; "
        "predicted: the MDN's estimate from a rendered depth view (drawer, microwave)",
    )
    direction_std_rad: float = Field(0.05, ge=0, description="noisy: axis direction std, rad")
    origin_std_m: float = Field(0.01, ge=0, description="noisy: axis origin std per axis, m")
    mdn: str | None = Field(
        None,
        description="predicted: a train-mdn output folder of the task's object category; "
        "null: <artifacts_root>/models/mdn/<category>",
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


def mdn_folder(cfg: PlanDemosConfig) -> Path:
    """The train-mdn output the `predicted` model comes from."""
    if cfg.model.mdn is not None:
        return Path(cfg.model.mdn)
    scene = cfg.task.scene
    assert isinstance(scene, ArticulatedScene)
    return Path(cfg.artifacts_root) / "models" / "mdn" / scene.category


def _input_paths(cfg: PlanDemosConfig) -> dict[str, Path]:
    return {"mdn": mdn_folder(cfg)} if cfg.model.source == "predicted" else {}


@functools.lru_cache(maxsize=1)
def _world(task_json: str) -> TaskWorld:
    """One world per process (chunks reuse it; `reset` restores its initial state)."""
    from artic.sim.world import TaskWorld

    # rng None: the task's nominal object geometry (no geometry_jitter draw)
    return TaskWorld.create(TaskConfig.model_validate_json(task_json), None)


def planning_model(
    cfg: ModelConfig, seed: int, world: TaskWorld, mdn: Path | None = None
) -> tuple[ArticulatedObject, dict[str, Any]]:
    """The kinematic model to plan with (one for all demos: the robot estimates the object
    once) and its record for demos.json; the noisy model is drawn from (seed,
    MODEL_STREAM), the predicted one's sensor noise from (seed, PERCEPTION_STREAM)."""
    from artic.planning.models import perturb_model

    true = world.kinematic_model()
    record: dict[str, Any] = {"source": cfg.source}
    if cfg.source == "true":
        return true, record
    if cfg.source == "predicted":
        if mdn is None:
            raise ValueError("model.source predicted needs the MDN folder")
        return predicted_model(cfg, seed, world, mdn)
    rng = np.random.default_rng([seed, MODEL_STREAM])
    noisy = perturb_model(true, cfg.direction_std_rad, cfg.origin_std_m, rng)
    record.update(
        direction_std_rad=cfg.direction_std_rad,
        origin_std_m=cfg.origin_std_m,
        direction_error_rad=noisy.direction_error_rad,
        origin_error_m=noisy.origin_error_m,
    )
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
    cfg: ModelConfig, seed: int, world: TaskWorld, mdn: Path
) -> tuple[ArticulatedObject, dict[str, Any]]:
    """The model the MDN in `mdn` estimates from a rendered view of the world's object
    (`artic.planning.perception.perceive`) and its demos.json record."""
    from artic.artifacts.manifest import read_manifest, verify_file
    from artic.artifacts.model_file import load_model_file
    from artic.geometry.transforms import yaw_of
    from artic.kinematics.predict import Predictor
    from artic.planning.perception import perceive, pose_in_camera, summary, view_problems

    scene = world.cfg.scene
    assert isinstance(scene, ArticulatedScene)
    category = scene.category
    path = verify_file(mdn, read_manifest(mdn, expected_stage="train-mdn"), "model.pt")
    predictor = Predictor.from_payload(load_model_file(path, MDN_KIND, category))
    classes = category_config(category)
    true = world.kinematic_model()
    spec = scene.spec()
    camera = camera_pose(cfg.camera, true.base_pose, classes.pose)
    pose = pose_in_camera(true.base_pose, camera)
    problems = view_problems(pose, classes.pose, spec, predictor.camera)
    if problems:
        raise InputError(
            f"model.camera: the {category} MDN was not trained on this view: " + "; ".join(problems)
        )
    start = np.asarray(world.cfg.object_start, dtype=np.float64)
    rng = np.random.default_rng([seed, PERCEPTION_STREAM])
    seen = perceive(
        true, spec, start, camera, predictor, cfg.noise, rng, cfg.estimator,
        classes.geometry, classes.chirality,
    )  # fmt: skip
    record: dict[str, Any] = {
        "source": "predicted",
        "mdn": str(mdn),
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


def demo_name(index: int) -> str:
    return f"demo_{index:03d}.npz"


def _indices(cfg: PlanDemosConfig, chunk: int) -> range:
    size = cfg.demos.per_chunk
    return range(chunk * size, min((chunk + 1) * size, cfg.demos.count))


def _plan(cfg: PlanDemosConfig, inputs: dict[str, Path]) -> Plan:
    if cfg.model.source == "predicted":
        _cached_model(cfg)  # bad input (model, camera) fails here, before any chunk
    size, n = cfg.demos.per_chunk, cfg.demos.count
    return Plan([min(size, n - c * size) for c in range(math.ceil(n / size))], "demos")


def plan_one(
    cfg: PlanDemosConfig, world: TaskWorld, index: int
) -> tuple[Demo | None, dict[str, Any]]:
    """Plan demo `index` (Algorithm 2) and, if it succeeded, execute it; returns the demo
    and its record: the demos.json fields plus `planning_time_s` (wall clock, s), which
    `_finalize` moves to timings.json."""
    from artic.planning.demos import DemoProblem, perturbed_problem, plan_demo

    model, _ = _cached_model(cfg)
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


@functools.lru_cache(maxsize=1)
def _model(
    task_json: str, model_json: str, seed: int, mdn: str | None
) -> tuple[ArticulatedObject, dict[str, Any]]:
    """The planning model of a config, drawn (or predicted) once per process."""
    cfg = ModelConfig.model_validate_json(model_json)
    return planning_model(cfg, seed, _world(task_json), Path(mdn) if mdn else None)


def _cached_model(cfg: PlanDemosConfig) -> tuple[ArticulatedObject, dict[str, Any]]:
    mdn = str(mdn_folder(cfg)) if cfg.model.source == "predicted" else None
    return _model(cfg.task.model_dump_json(), cfg.model.model_dump_json(), cfg.seed, mdn)


def execute(world: TaskWorld, demo: Demo, cfg: PlanDemosConfig) -> dict[str, Any]:
    """Run `demo` in the simulator from its start: command qd_plan[k] + gain (q_plan[k] -
    q) at each step, then hold still for `extra_steps`. Returns the achieved object
    configuration, its error to the goal and whether the task's success threshold holds."""
    goal = np.asarray(cfg.task.goal, dtype=np.float64)
    world.reset(demo.q_robot[0], demo.q_object[0])
    gain = cfg.execute.gain
    steps = len(demo.t) + cfg.execute.extra_steps
    tracking = 0.0
    for k in range(steps):
        target = demo.q_robot[min(k, len(demo.t) - 1)]
        feed = demo.qd_robot[k] if k < len(demo.t) else np.zeros_like(target)
        q = world.robot_q()
        tracking = max(tracking, float(np.max(np.abs(target - q))))
        world.apply_action(feed + gain * (target - q))
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


def plan_chunk(cfg: PlanDemosConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Plan the demos of chunk `chunk`: `demo_###.npz` for each that succeeded and a
    record for each into tmp."""
    world = _world(cfg.task.model_dump_json())
    (tmp / RECORDS).mkdir()
    done = 0
    for index in _indices(cfg, chunk):
        demo, record = plan_one(cfg, world, index)
        if demo is not None:
            write_npz(
                tmp / demo_name(index),
                {
                    "t": demo.t,
                    "q_robot": demo.q_robot,
                    "qd_robot": demo.qd_robot,
                    "q_object": demo.q_object,
                    "ee_pose": demo.ee_pose,
                },
            )
        write_json(tmp / RECORDS / f"demo_{index:03d}.json", record)
        done += 1
    return done


def _finalize(
    cfg: PlanDemosConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    records = [
        json.loads((work / RECORDS / f"demo_{i:03d}.json").read_text())
        for i in range(cfg.demos.count)
    ]
    # wall-clock times vary from run to run: they go to timings.json, demos.json stays
    # deterministic
    times = [r.pop("planning_time_s") for r in records]
    ok = [r for r in records if r["status"] == "ok"]
    # a perceived model may be too wrong to plan on: that is a result, not bad input
    if not ok and cfg.model.source != "predicted":
        reasons = sorted({r["reason"] for r in records})
        raise InputError(
            f"task {cfg.task.name}: no demo could be planned to the goal q_O* = "
            f"{cfg.task.goal} ({'; '.join(reasons)})"
        )
    from artic.sim.world import TaskWorld

    # the true model's record needs no world; a noisy one is drawn from it (cached)
    model_record: dict[str, Any] = (
        {"source": "true"} if cfg.model.source == "true" else _cached_model(cfg)[1]
    )
    write_json(
        work / DEMOS_JSON,
        {
            "task": cfg.task.name,
            "n_requested": cfg.demos.count,
            "control_dt": cfg.task.control_dt,
            "horizon": cfg.task.horizon,
            "goal": list(cfg.task.goal),
            "n_joints": TaskWorld.n_robot,
            "dof_object": len(cfg.task.goal),
            "kinematic_model": model_record,
            "planner": cfg.planner.name,
            "demos": records,
        },
    )
    write_json(
        work / TIMINGS_JSON,
        {
            "task": cfg.task.name,
            "median_planning_time_s": round(float(np.median(times)), 4),
            "demos": [
                {"index": r["index"], "status": r["status"], "planning_time_s": t}
                for r, t in zip(records, times, strict=True)
            ],
        },
    )
    shutil.rmtree(work / RECORDS)
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


STAGE: Stage[PlanDemosConfig] = Stage(
    name="plan-demos",
    conf="plan_demos",
    schema=PlanDemosConfig,
    plan=_plan,
    chunk=plan_chunk,
    finalize=_finalize,
    inputs={"mdn": "train-mdn"},
    input_paths=_input_paths,
)
