"""`artic compose` (thesis section 7.4; issue 21 part 8): its config, the skills read back
from train-cip and grasp-candidates folders, and one trial with true and perceived
models. The scene and the sequence are `artic.planning.compose`.

A trial draws the scene (`planning.compose.layout`, from (seed, trial)) and runs the
sequence once with the true models and, with `perceive`, once more in the same scene with
the models the Chapter 3 network sees (`perceived_placement`); each run is one row per
skill of `TRIAL_COLUMNS`.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from artic.artifacts.manifest import read_stage_config, verify_file
from artic.config.schemas import StageConfig, Strict
from artic.errors import InputError
from artic.kinematics import Estimator
from artic.learning.cip_train import SETTINGS, Setting, TrainCipConfig, start_margin
from artic.planning.compose import (
    ComposeEnv,
    MotionConfig,
    Placement,
    Skill,
    check_compatible,
    frame_errors,
    layout,
    perceived_placement,
    rot_about_base,
    run_sequence,
)
from artic.render.noise import SensorNoiseConfig
from artic.sim.cip_tasks import CipTaskName

if TYPE_CHECKING:
    from artic.kinematics.predict import Predictor

TASKS: tuple[CipTaskName, ...] = ("door", "drawer", "slide", "lever")
ModelsUsed = Literal["true", "perceived"]
TRIAL_COLUMNS = ("trial", "models", "skill", "task", "handle_error_cm", "yaw_error_deg", "grasp",
                 "plan_checks", "tracking_error_rad", "steps", "success", "end")  # fmt: skip
SUCCESS = TRIAL_COLUMNS.index("success")
COMPOSE_COLUMNS = ("models", "trials", "first_skill_success", "sequence_success")


class PerceptionConfig(Strict):
    """The Chapter 3 network's view of each object (`perceive`)."""

    mdn: dict[str, str | None] = Field(
        default_factory=dict,
        description="per category (cabinet, drawer): a model.pt; missing or null: the "
        "model store's choice, as `artic predict` makes it",
    )
    refine: bool = Field(True, description="the geometric refinement of `artic predict`")
    estimator: Estimator = Field("most-likely", description="the MDN's estimator")
    noise: SensorNoiseConfig = Field(
        default_factory=SensorNoiseConfig, description="the depth sensor model of the view"
    )


class ComposeConfig(StageConfig):
    """The config of `artic compose` (conf/compose/config.yaml)."""

    skills: list[CipTaskName] = Field(min_length=1, description="tasks, in the order chained")
    bearings_deg: list[float] = Field(
        description="each skill's object turned about the base by this, deg (its side)"
    )
    setting: Setting = Field("cip_bc", description="whose policies (a grasp setting)")
    policy_seed: int = Field(0, ge=0, description="which seed's policy of the setting")
    policies: dict[str, str | None] = Field(description="train-cip output folder per task")
    grasps: dict[str, str | None] = Field(description="grasp-candidates output folder per task")
    trials: int = Field(50, ge=1, description="sequences (issue 21: 50)")
    perceive: bool = Field(False, description="also run every trial on perceived models")
    perception: PerceptionConfig = Field(default_factory=PerceptionConfig)
    motion: MotionConfig = Field(default_factory=MotionConfig)

    @field_validator("setting")
    @classmethod
    def _grasp_setting(cls, value: Setting) -> Setting:
        if SETTINGS[value].grasp == "home":
            grasping = ", ".join(s for s, v in SETTINGS.items() if v.grasp != "home")
            raise ValueError(f"setting {value} starts at home; compose chains the settings "
                             f"that start at a grasp ({grasping})")  # fmt: skip
        return value

    @model_validator(mode="after")
    def _consistent(self) -> ComposeConfig:
        if len(set(self.skills)) != len(self.skills):
            raise ValueError("skills: a task appears twice")
        if len(self.bearings_deg) != len(self.skills):
            raise ValueError(f"bearings_deg: {len(self.bearings_deg)} values for "
                             f"{len(self.skills)} skills")  # fmt: skip
        for field in ("policies", "grasps"):
            for task in self.skills:
                if getattr(self, field).get(task) is None:
                    raise ValueError(f"{field}.{task}: no folder for skill {task}")
        return self

    def input_paths(self) -> dict[str, Path]:
        """`<task>` (train-cip) and `<task>_grasps` (grasp-candidates) of each skill."""
        paths: dict[str, Path] = {}
        for task in self.skills:
            paths[task] = Path(str(self.policies[task]))
            paths[f"{task}_grasps"] = Path(str(self.grasps[task]))
        return paths


def policy_path(cfg: ComposeConfig) -> str:
    """The policy file of `cfg.setting` and `cfg.policy_seed` in a train-cip folder."""
    return f"policies/{cfg.setting}/seed_{cfg.policy_seed:03d}/policy.pt"


class SkillFiles:
    """A skill's files checked: the train-cip run (its task and the policy's file, hashed)
    and the initiation set whose grasps its bandit counted."""

    def __init__(self, cfg: ComposeConfig, task: str, inputs: dict[str, Path]) -> None:
        from artic.planning.cip_demos import read_initiation_set

        folder = inputs[task]
        run, manifest = read_stage_config(folder, "train-cip", TrainCipConfig)
        if run.task.name != task:
            raise InputError(f"policies.{task}: {folder} holds task '{run.task.name}'")
        if cfg.setting not in run.settings or cfg.policy_seed >= run.seeds:
            raise InputError(f"policies.{task}: {folder} has no policy of setting "
                             f"{cfg.setting}, seed {cfg.policy_seed}")  # fmt: skip
        self.task, self.run, self.setting = run.task, run, cfg.setting
        self.policy = verify_file(folder, manifest, policy_path(cfg))
        #: the policy's sha256 as its train-cip manifest lists it (the file checked equal)
        self.sha256 = manifest.outputs[policy_path(cfg)].sha256
        self.initiation_set = read_initiation_set(inputs[f"{task}_grasps"], run.task)

    def load(self, env: ComposeEnv) -> Skill:
        """The skill: the actor pi_c (TD3's, deterministic) and the initiation set with the
        run's bandit; InputError naming the policy file when it holds no bandit or one of
        another initiation set."""
        import torch

        from artic.learning.bandits import UCB1
        from artic.learning.td3_bc import td3_model

        record = torch.load(self.policy, weights_only=True)
        starts = record.get("starts") or {}
        if "bandit" not in starts:
            raise InputError(f"{self.policy}: no head state (made by an older train-cip: "
                             f"train it again)")  # fmt: skip
        bandit = UCB1.from_dict(starts["bandit"], f"{self.policy}: starts.bandit")
        if bandit.n_arms != len(self.initiation_set.grasps):
            raise InputError(f"{self.policy}: its bandit has {bandit.n_arms} grasps, the "
                             f"initiation set {len(self.initiation_set.grasps)}")  # fmt: skip
        torch.set_num_threads(1)
        model = td3_model(self.run.train.td3, env, 0)
        model.actor.load_state_dict(record["state_dict"])
        model.actor.set_training_mode(False)

        def actor(obs: Any) -> Any:
            return model.predict(obs, deterministic=True)[0]

        self.initiation_set.bandit = bandit
        return Skill(self.task, actor, self.initiation_set, start_margin(self.task, self.setting))


def trial_seed(seed: int, trial: int) -> int:
    return int(np.random.SeedSequence([seed, trial, 7]).generate_state(1)[0] % (2**31 - 1))


def run_trial(cfg: ComposeConfig, inputs: dict[str, Path], trial: int) -> list[list[Any]]:
    """Trial `trial`: the scene from (seed, trial), the sequence with the true models and,
    with `perceive`, with the perceived ones; rows of `TRIAL_COLUMNS`."""
    files = [SkillFiles(cfg, task, inputs) for task in cfg.skills]
    tasks = [f.task for f in files]
    check_compatible(tasks)
    bearings = [float(np.radians(b)) for b in cfg.bearings_deg]
    seed = trial_seed(cfg.seed, trial)
    true = layout(tasks, bearings, np.random.default_rng(seed))
    runs: list[tuple[ModelsUsed, list[Placement]]] = [("true", true)]
    if cfg.perceive:
        runs.append(("perceived", _perceived(cfg, true, bearings, seed)))
    setting = SETTINGS[cfg.setting]
    rows: list[list[Any]] = []
    skills: list[Skill] = []
    for models, known in runs:
        sim = ComposeEnv(true, setting.safety, setting.contact_termination)
        plan_env = ComposeEnv(known, setting.safety, setting.contact_termination)
        try:
            skills = skills or [f.load(sim) for f in files]  # the same for every run
            outcomes = run_sequence(skills, sim, plan_env, [p.frame for p in known],
                                    cfg.motion, seed)  # fmt: skip
        finally:
            sim.close()
            plan_env.close()
        for k, o in enumerate(outcomes):
            handle, yaw = frame_errors(true[k], known[k])
            rows.append([trial, models, k, o.task, round(handle, 4), round(yaw, 4), o.grasp,
                         o.plan_checks,
                         round(o.tracking_error, 6), o.steps, int(o.success), o.end])  # fmt: skip
    return rows


def perception_models(cfg: ComposeConfig, categories: list[str]) -> dict[str, Path]:
    """The Chapter 3 model file of each category, chosen as `artic predict` chooses
    (`perception.mdn.<category>`, else the local model, else the shipped one); InputError
    naming the field when a category has none."""
    from artic.artifacts.model_store import choose_model

    root = Path(cfg.artifacts_root) / "models"
    models = {}
    for category in categories:
        given = cfg.perception.mdn.get(category)
        models[category] = choose_model("mdn", category, Path(given) if given else None,
                                        f"perception.mdn.{category}", root=root).path  # fmt: skip
    return models


@functools.lru_cache(maxsize=8)
def _predictor(path: Path, category: str) -> Predictor:
    """The MDN at `path`, loaded once per process (every trial of a chunk's worker)."""
    from artic.kinematics.predict import Predictor

    return Predictor.load(path, category)


def _perceived(
    cfg: ComposeConfig, true: list[Placement], bearings: list[float], seed: int
) -> list[Placement]:
    from artic.planning.models import ModelConfig
    from artic.sim.cip_envs import yaw_pose

    view = ModelConfig(source="predicted", refine=cfg.perception.refine,
                       estimator=cfg.perception.estimator, noise=cfg.perception.noise)  # fmt: skip
    mdns = perception_models(cfg, [p.task.object.category for p in true])
    known = []
    for k, (placement, angle) in enumerate(zip(true, bearings, strict=True)):
        category = placement.task.object.category
        predictor = _predictor(mdns[category], category)
        o = placement.task.object
        nominal = rot_about_base(angle) @ yaw_pose(o.x, o.y, o.z, 0.0)
        seen, _ = perceived_placement(placement, nominal, predictor, view, seed * 31 + k)
        known.append(seen)
    return known


def per_skill(rows: list[list[str]]) -> list[dict[str, Any]]:
    """Per models used and skill, from the trials' rows (strings): its success rate, how
    its contact phases ended, and the median handle and yaw errors of the robot's models."""
    column = {name: i for i, name in enumerate(TRIAL_COLUMNS)}
    out = []
    for models in ("true", "perceived"):
        for task in dict.fromkeys(r[3] for r in rows if r[1] == models):
            mine = [r for r in rows if r[1] == models and r[3] == task]
            ends: dict[str, int] = {}
            for r in mine:
                ends[r[column["end"]]] = ends.get(r[column["end"]], 0) + 1
            out.append({
                "models": models, "task": task, "trials": len(mine),
                "success": round(float(np.mean([int(r[SUCCESS]) for r in mine])), 4),
                "ends": dict(sorted(ends.items())),
                "handle_error_cm_median": round(float(np.median(
                    [float(r[column["handle_error_cm"]]) for r in mine])), 3),
                "yaw_error_deg_median": round(float(np.median(
                    [float(r[column["yaw_error_deg"]]) for r in mine])), 3),
            })  # fmt: skip
    return out


def compose_rows(rows: list[list[str]]) -> list[list[Any]]:
    """compose.csv's rows from the trials' rows (strings): per models used, trials,
    the first skill's success rate and the whole sequence's."""
    out: list[list[Any]] = []
    for models in ("true", "perceived"):
        mine = [r for r in rows if r[1] == models]
        if not mine:
            continue
        trials = sorted({int(r[0]) for r in mine})
        first = [int(r[SUCCESS]) for r in mine if int(r[2]) == 0]
        whole = [all(int(r[SUCCESS]) for r in mine if int(r[0]) == t) for t in trials]
        out.append([models, len(trials), round(float(np.mean(first)), 4),
                    round(float(np.mean(whole)), 4)])  # fmt: skip
    return out
