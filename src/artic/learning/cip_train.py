"""Learning a CIP's contact policy (thesis section 7.3, Algorithm 3) under the seven
settings of the ablation, with TD3 (+ Q-filtered BC: `learning/td3_bc.py`).

A run is one (setting, seed): episodes of `CipEnv`, each started by the setting's head
(`Starts`: home for E2E; a grasp of the initiation set, reached by IK, for the others;
the grasp chooser hears each episode's success, Algorithm 3 line 14), trained in blocks
of `eval_every` episodes; after each block the policy is evaluated on `eval_rollouts`
deterministic episodes and the run's state is handed to `save` (networks, optimisers,
buffers, generators, the chooser's state and the rows so far), so a resumed run gives
the uninterrupted run's bytes. Every block starts from a fresh reset: episode k of run
`seed` is reset with `episode_seed(seed, k)`, evaluation rollout j after block b with
`episode_seed(seed, -(b * rollouts + j) - 1)`.

The stage `artic train-cip` (`cli/train_cip.py`) runs (setting, seed) pairs of
`TrainCipConfig`; its inputs are read back here (`read_demonstrations`: the successful
episodes of a cip-demos folder) and in `planning/cip_demos.py` (the initiation set).

| setting | start | IK of the grasp | envelope sigma | B: lost contact | demonstrations |
|---|---|---|---|---|---|
| e2e | home, open hand | - | no | no | no |
| head | a random grasp | the first solution ("naive IK") | no | yes | no |
| safety | a random grasp | the first solution | yes | yes | no |
| mv | a random grasp | the best-scored of its solutions | yes | yes | no |
| cip | UCB1's grasp | the best-scored | yes | yes | no |
| cip_bc | UCB1's grasp | the best-scored | yes | yes | yes |
| e2e_bc | home, open hand | - | no | no | yes |
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal, NamedTuple, Protocol

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray
from pydantic import Field, field_validator, model_validator

from artic.artifacts.formats import read_npz
from artic.artifacts.manifest import Manifest, read_manifest, verify_file
from artic.config.schemas import Strict, TrainingStageConfig
from artic.errors import InputError
from artic.learning.td3_settings import Demonstrations, Td3Config
from artic.sim.cip_envs import CipEnv
from artic.sim.cip_tasks import CipObject, CipTaskConfig

Setting = Literal["e2e", "head", "safety", "mv", "cip", "cip_bc", "e2e_bc"]
SETTING_NAMES: tuple[Setting, ...] = ("e2e", "head", "safety", "mv", "cip", "cip_bc", "e2e_bc")
CURVE_COLUMNS = ["setting", "seed", "episode", "success", "success_best", "violation_rate",
                 "violation_rate_train", "return_mean"]  # fmt: skip
CURVE = "learning_curve.csv"
DEMOS_NPZ = "demos.npz"
DEMO_ARRAYS = ("obs", "actions", "rewards", "next_obs", "dones", "episode", "success",
               "from_home")  # fmt: skip
"""The arrays of cip-demos' demos.npz: every recorded transition (N rows: obs (N, 30),
actions (N, 13), rewards (N,), next_obs (N, 30), dones (N,) 1 where the episode
terminated, episode (N,) its episode's index), success (E,) of each episode and
from_home (E,): started at home (E2E+BC's), not at a CIP start (CIP+BC's)."""


class SettingSpec(NamedTuple):
    """What a setting adds (module docstring's table)."""

    grasp: Literal["home", "random", "ucb"]
    ik: Literal["naive", "best"]
    safety: bool
    contact_termination: bool
    demos: bool


SETTINGS: dict[Setting, SettingSpec] = {
    "e2e": SettingSpec("home", "naive", False, False, False),
    "head": SettingSpec("random", "naive", False, True, False),
    "safety": SettingSpec("random", "naive", True, True, False),
    "mv": SettingSpec("random", "best", True, True, False),
    "cip": SettingSpec("ucb", "best", True, True, False),
    "cip_bc": SettingSpec("ucb", "best", True, True, True),
    "e2e_bc": SettingSpec("home", "naive", False, False, True),
}


def episode_seed(seed: int, episode: int) -> int:
    """The environment's reset seed of episode `episode` of run `seed` (negative
    episodes: evaluation rollouts)."""
    entropy = [seed, episode + 2**31, 11]
    return int(np.random.SeedSequence(entropy).generate_state(1)[0] % (2**31 - 1))


class Starts(Protocol):
    """A setting's head: where an episode starts, and what it learns from the outcome."""

    def choose(self, env: CipEnv, seed: int, explore: bool) -> dict[str, Any] | None:
        """`reset` options for the episode reset with `seed` (`env.draw_pose(seed)` is
        its object pose); None: home. `explore` false: evaluation (no exploration)."""
        ...

    def report(self, success: bool) -> None:
        """The outcome of the last training episode chosen with `explore`."""
        ...

    def state(self) -> dict[str, Any]:
        """JSON-able state (checkpoints)."""
        ...

    def load(self, state: dict[str, Any]) -> None:
        """Restore `state`."""
        ...


class HomeStarts:
    """E2E: every episode starts at home with the hand open; nothing to learn."""

    def choose(self, env: CipEnv, seed: int, explore: bool) -> dict[str, Any] | None:
        return None

    def report(self, success: bool) -> None:
        return None

    def state(self) -> dict[str, Any]:
        return {}

    def load(self, state: dict[str, Any]) -> None:
        return None


class EpisodeRecord(NamedTuple):
    """One finished episode: its return, beta_c, and whether B's joint limit ended it."""

    ret: float
    success: bool
    violation: bool


class CipEpisodes(gym.Wrapper[NDArray[np.float32], NDArray[np.float32], Any, Any]):
    """`CipEnv` whose every reset is episode k's: seeded `episode_seed(seed, k)` and
    started by `starts`; finished episodes are recorded in `finished` and their success
    reported to `starts` (with `explore`)."""

    def __init__(self, env: CipEnv, starts: Starts, seed: int, explore: bool = True) -> None:
        super().__init__(env)
        self.cip: CipEnv = env
        self.starts, self.seed, self.explore = starts, seed, explore
        self.episode = 0
        self.finished: list[EpisodeRecord] = []
        self._return = 0.0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        reset_seed = episode_seed(self.seed, self.episode)
        chosen = self.starts.choose(self.cip, reset_seed, self.explore)
        self.episode += 1
        self._return = 0.0
        return self.cip.reset(seed=reset_seed, options=chosen)

    def step(
        self, action: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], Any, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.cip.step(action)
        self._return += float(reward)
        if terminated or truncated:
            record = EpisodeRecord(self._return, bool(info["success"]), bool(info["joint_limit"]))
            self.finished.append(record)
            if self.explore:
                self.starts.report(record.success)
        return obs, reward, terminated, truncated, info


def start_margin(task: CipTaskConfig, setting: Setting) -> float:
    """The least distance (rad) of every joint to its limits at the start of a setting's
    episode: B's threshold, or sigma1 under the envelope. A start inside sigma1 would
    begin in the envelope's null-space mode, and the hand closing on the handle can press
    a joint on past B's threshold before the first action (measured: 2 of 8 random-action
    episodes of the drawer from the Safety setting's starts; docs/cip.md)."""
    return task.safety.sigma1 if SETTINGS[setting].safety else task.safety.limit_threshold


def make_env(task: CipTaskConfig, setting: Setting) -> CipEnv:
    """The setting's environment: the envelope and B's lost-contact rule as it says."""
    spec = SETTINGS[setting]
    return CipEnv(task, safety=spec.safety, contact_termination=spec.contact_termination)


def evaluate_policy(
    predict: Callable[[NDArray[np.float32]], NDArray[np.float32]],
    env: CipEnv,
    starts: Starts,
    seeds: list[int],
) -> list[EpisodeRecord]:
    """Deterministic rollouts of `predict` from `starts` (no exploration), one per seed."""
    records = []
    for s in seeds:
        obs, _ = env.reset(seed=s, options=starts.choose(env, s, explore=False))
        ret, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, info = env.step(predict(obs))
            ret += float(reward)
            done = bool(terminated or truncated)
        records.append(EpisodeRecord(ret, bool(info["success"]), bool(info["joint_limit"])))
    return records


class CurveRow(NamedTuple):
    """One evaluation point of a run (`CURVE_COLUMNS`)."""

    setting: str
    seed: int
    episode: int
    success: float
    success_best: float
    violation_rate: float
    violation_rate_train: float
    return_mean: float


def curve_row(
    setting: str,
    seed: int,
    episode: int,
    evaluation: list[EpisodeRecord],
    training: list[EpisodeRecord],
    best: float,
) -> CurveRow:
    """The row after `episode` training episodes: the evaluation's success rate and its
    best to date (`best`: the previous rows' best), its joint-limit violation rate, the
    violation rate of the block's training episodes, and the evaluation's mean return."""
    success = float(np.mean([r.success for r in evaluation]))
    return CurveRow(
        setting, seed, episode, success, max(best, success),
        float(np.mean([r.violation for r in evaluation])),
        float(np.mean([r.violation for r in training])) if training else 0.0,
        float(np.mean([r.ret for r in evaluation])),
    )  # fmt: skip


class HeadMotion(Strict):
    """A head's motion: an OMPL RRTConnect plan to the grasp's IK solution, from home
    (train-cip) or where the arm stands (compose), time-parameterised and tracked by
    computed torque with the hand open (`planning/cip_head.py`)."""

    speed: float = Field(1.0, gt=0, description="largest joint speed of a tracked plan, rad/s")
    k_p: float = Field(400.0, gt=0, description="computed-torque stiffness, 1/s^2 (k_d 2 sqrt)")
    settle_s: float = Field(0.3, ge=0, description="hold at a plan's end, s")
    plan_time_s: float = Field(
        60.0, gt=0, description="RRTConnect's wall-time budget per head, s (a safety net)"
    )
    plan_checks: int = Field(
        100_000,
        ge=1,
        description="RRTConnect stops after this many validity checks: a "
        "machine-independent limit, so a run gives the same plans on any CPU",
    )
    resolution: float = Field(0.02, gt=0, description="motion check spacing, rad")
    clearance_m: float = Field(
        0.002, ge=0, description="least distance of the open hand and arm to the objects, m"
    )


class HeadConfig(HeadMotion):
    """How a grasp setting's episode reaches its start (Algorithm 3 lines 6-10):
    `teleport` resets the arm at the IK solution (the plan's end); `track` plans from
    home in the episode's scene and tracks the plan (`HeadMotion`) before Gamma."""

    execute: Literal["teleport", "track"] = Field(
        "teleport", description="teleport | track: how the head reaches the grasp"
    )


class CipTrainConfig(Strict):
    """One run's schedule (issue 21: cpu 120 episodes, 5 rollouts; paper 500, 20)."""

    episodes: int = Field(120, ge=1, description="training episodes per run (thesis: 500)")
    eval_every: int = Field(10, ge=1, description="episodes between evaluations (thesis: 10)")
    eval_rollouts: int = Field(5, ge=1, description="deterministic rollouts per evaluation")
    td3: Td3Config = Field(default_factory=Td3Config, description="the learner")

    @model_validator(mode="after")
    def _whole_blocks(self) -> CipTrainConfig:
        if self.episodes % self.eval_every:
            raise ValueError("episodes: not a multiple of eval_every")
        return self


class _StopAfterEpisodes:
    """An SB3 callback ending `learn` once `n` episodes have finished."""

    def __new__(cls, n: int) -> Any:
        from stable_baselines3.common.callbacks import BaseCallback

        class Stop(BaseCallback):
            def __init__(self) -> None:
                super().__init__()
                self.count = 0

            def _on_step(self) -> bool:
                self.count += int(np.sum(self.locals["dones"]))
                return self.count < n

        return Stop()


def train_run(
    task: CipTaskConfig,
    setting: Setting,
    seed: int,
    cfg: CipTrainConfig,
    starts: Starts,
    demos: Demonstrations | None = None,
    state: dict[str, Any] | None = None,
    save: Callable[[dict[str, Any]], None] | None = None,
) -> list[CurveRow]:
    """Run (`setting`, `seed`) of Algorithm 3 (module docstring): TD3 on `task` started
    by `starts`, with `demos` for the BC settings; resumes from `state` (a `save`d one);
    returns the run's evaluation rows."""
    import torch

    from artic.learning import td3_bc

    spec = SETTINGS[setting]
    if spec.demos and demos is None:
        raise InputError(f"demos: setting {setting} learns from demonstrations; none given")
    torch.set_num_threads(cfg.td3.threads)
    env = CipEpisodes(make_env(task, setting), starts, seed)
    evaluation_env = make_env(task, setting)
    try:
        model = td3_bc.td3_model(cfg.td3, env, seed)
        if spec.demos and demos is not None:
            td3_bc.load_demonstrations(model, demos)
        rows: list[CurveRow] = []
        if state is not None:
            td3_bc.restore(model, state["td3"])
            starts.load(state["starts"])
            env.episode = int(state["episode"])
            rows = [CurveRow(*row) for row in state["rows"]]
        best = max((row.success_best for row in rows), default=0.0)
        n = cfg.eval_rollouts
        for block in range(len(rows), cfg.episodes // cfg.eval_every):
            env.finished = []
            model._last_obs = None  # every block starts with a fresh reset
            model.learn(10**9, callback=_StopAfterEpisodes(cfg.eval_every),
                        reset_num_timesteps=False)  # fmt: skip
            seeds = [episode_seed(seed, -(block * n + j) - 1) for j in range(n)]
            evaluation = evaluate_policy(
                lambda obs: model.predict(obs, deterministic=True)[0], evaluation_env,
                starts, seeds,
            )  # fmt: skip
            row = curve_row(setting, seed, (block + 1) * cfg.eval_every, evaluation,
                            env.finished, best)  # fmt: skip
            rows.append(row)
            best = row.success_best
            if save is not None:
                save({"td3": td3_bc.checkpoint(model, block + 1), "starts": starts.state(),
                      "episode": env.episode, "rows": [list(r) for r in rows]})  # fmt: skip
        return rows
    finally:
        env.close()
        evaluation_env.close()


# -- the train-cip stage ------------------------------------------------------------------


class TrainCipConfig(TrainingStageConfig):
    """The config of `artic train-cip` (conf/train_cip/config.yaml): runs (setting, seed),
    setting-major, each `train_run` with the setting's head and, under the BC settings,
    the successful demonstrations of a cip-demos folder."""

    task: CipTaskConfig
    settings: list[Setting] = Field(
        default_factory=lambda: list(SETTING_NAMES), description="settings trained (section 7.3)"
    )
    seeds: int = Field(1, gt=0, description="independent runs per setting (thesis: 10)")
    train: CipTrainConfig = Field(default_factory=CipTrainConfig, description="one run")
    head: HeadConfig = Field(
        default_factory=HeadConfig, description="the grasp settings' head (teleport | track)"
    )
    initiation_set: str | None = Field(
        None, description="a grasp-candidates output folder of the task (the grasp settings)"
    )
    demos: str | None = Field(None, description="a cip-demos output folder of the task (BC)")

    @field_validator("settings")
    @classmethod
    def _distinct(cls, value: list[str]) -> list[str]:
        if not value or len(set(value)) != len(value):
            raise ValueError(f"settings: one or more distinct names of {', '.join(SETTINGS)}")
        return value

    def run_of(self, chunk: int) -> tuple[Setting, int]:
        """(setting, seed index) of chunk `chunk`: setting-major."""
        return self.settings[chunk // self.seeds], chunk % self.seeds

    def input_paths(self) -> dict[str, Path]:
        """The inputs the settings read: the initiation set if one starts at a grasp, the
        demonstrations if one learns from them; InputError naming the field when it is
        needed and null."""
        needs = {
            "initiation_set": [s for s in self.settings if SETTINGS[s].grasp != "home"],
            "demos": [s for s in self.settings if SETTINGS[s].demos],
        }
        paths: dict[str, Path] = {}
        for field, settings in needs.items():
            folder = getattr(self, field)
            if settings and folder is None:
                raise InputError(f"config field {field}: null, but setting "
                                 f"{', '.join(settings)} needs it")  # fmt: skip
            if settings:
                paths[field] = Path(folder)
        return paths


def run_seed(base: int, index: int) -> int:
    """TD3's seed of run `index`, the same under every setting: run i of each setting
    meets the same episode seeds, hence the same object poses (paired runs)."""
    return int(np.random.SeedSequence([base, index, 21]).generate_state(1)[0] % (2**31 - 1))


def check_input_task(name: str, folder: Path, manifest: Manifest, task: CipTaskConfig) -> None:
    """InputError naming input `name` when the stage output `folder` (its `manifest`) was
    made for another task: another name, or another object (geometry, pose, jitter)."""
    theirs = manifest.config.get("task")
    theirs = theirs if isinstance(theirs, dict) else {}
    if theirs.get("name") != task.name:
        raise InputError(
            f"{name}: {folder} holds task '{theirs.get('name')}', expected '{task.name}'"
        )
    try:
        same = CipObject.model_validate(theirs.get("object")) == task.object
    except ValueError:
        same = False
    if not same:
        raise InputError(f"{name}: {folder} was made with another task.object than this config's")


def read_demonstrations(folder: Path, task: CipTaskConfig, from_home: bool) -> Demonstrations:
    """The transitions of the successful episodes in the cip-demos output `folder` (made
    for `task`) that started at home (`from_home`: E2E+BC's) or at a CIP start (CIP+BC's);
    InputError naming the folder when it holds none."""
    manifest = read_manifest(folder, expected_stage="cip-demos")
    check_input_task("demos", folder, manifest, task)
    arrays = read_npz(verify_file(folder, manifest, DEMOS_NPZ), DEMO_ARRAYS)
    success, episode = arrays["success"].astype(bool), arrays["episode"].astype(np.int64)
    if len(episode) and (episode.min() < 0 or episode.max() >= len(success)):
        raise InputError(f"{folder / DEMOS_NPZ}: episode: indices outside 0-{len(success) - 1}")
    if arrays["from_home"].shape != success.shape:
        raise InputError(f"{folder / DEMOS_NPZ}: from_home: one value per episode expected")
    kind = arrays["from_home"].astype(bool) == from_home
    keep = (success & kind)[episode]
    if not keep.any():
        start = "from home" if from_home else "from a CIP start"
        raise InputError(f"demos: {folder} holds no successful demonstration {start} "
                         f"(0 of {int(kind.sum())})")  # fmt: skip
    return Demonstrations(*(arrays[k][keep] for k in DEMO_ARRAYS[:5]))


def policy_record(cfg: TrainCipConfig, chunk: int, state: dict[str, Any]) -> dict[str, Any]:
    """The `policy.pt` payload of a run from its last checkpoint `state` (`train_run`'s
    save): the actor pi_c's weights (TD3's `actor.*` without the prefix: they load into
    `td3_model(...).actor`; no critics, no targets), the head's learnt state (`starts`:
    the UCB1 counts over I_c under the grasp settings, which `compose` reads to take the
    best grasp; {} for the settings that start at home) and plain data naming its task,
    setting, seed and learner."""
    setting, index = cfg.run_of(chunk)
    actor = {key.removeprefix("actor."): value for key, value in state["td3"]["policy"].items()
             if key.startswith("actor.")}  # fmt: skip
    return {"task": cfg.task.name, "setting": setting, "seed": index,
            "td3": cfg.train.td3.model_dump(), "starts": state["starts"],
            "state_dict": actor}  # fmt: skip


def run_summary(
    cfg: TrainCipConfig, rows: list[list[str]]
) -> tuple[dict[str, Any], dict[str, float | int | str]]:
    """summary.json and the manifest's stats of a finished train-cip folder, from
    learning_curve.csv's rows (strings): per setting, the means over its seeds of the
    last evaluation's best-to-date success (Fig. 7.3's last point) and violation rate."""
    final: dict[str, dict[str, float]] = {}
    stats: dict[str, float | int | str] = {"task": cfg.task.name}
    for setting in cfg.settings:
        last = [r for r in rows if r[0] == setting and int(r[2]) == cfg.train.episodes]
        success = float(np.mean([float(r[4]) for r in last]))
        violations = float(np.mean([float(r[5]) for r in last]))
        final[setting] = {"success_best": success, "violation_rate": violations}
        stats[setting] = f"success {success:.2f} (best to date), violations {violations:.2f}"
    summary = {"task": cfg.task.name, "settings": cfg.settings, "seeds": cfg.seeds,
               "train": cfg.train.model_dump(exclude={"td3"}), "final": final}  # fmt: skip
    return summary, stats
