"""A finished policy-search output folder (`artic policy-search`, docs/formats.md) read
back: its validated config, its learning curve and each seed's final policy as an
`ActionFn`; and the config (`EvaluateBootstrapConfig`), the two runs (`open_runs`) and
the statistics over seeds (`curve_stats`, `bootstrap_verdict`) of Figure 5.2, and the
optional video of a final policy (`VideoConfig`, `film_episode`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from pydantic import Field

from artic.artifacts.formats import read_csv, read_json
from artic.artifacts.manifest import (
    input_folder,
    read_manifest,
    read_stage_config,
    verify_file,
)
from artic.config.schemas import StageConfig, Strict
from artic.errors import InputError
from artic.evaluation.bootstrap_report import INITS
from artic.learning.search import CURVE, CURVE_COLUMNS, PolicySearchConfig, algorithm_of, seed_dir
from artic.sim.camera import CameraConfig
from artic.sim.tasks import TaskConfig

if TYPE_CHECKING:
    from artic.learning.rollout import ActionFn, Trajectory


class TaskName(Strict):
    """The task config group (`conf/common/task`); only its name is used: the policies
    are rolled out in the task config their policy-search run used."""

    model_config = Strict.model_config | {"extra": "ignore"}
    name: str = Field(description="task name: drawer, microwave, tball")


class VideoConfig(Strict):
    """The animated GIF of each init's final policy (seed 0's, evaluation episode 0)."""

    enabled: bool = Field(False, description="write video_<init>.gif (off: no rendering)")
    frame_every: int = Field(
        2, ge=1, description="keep every n-th control step's frame (2: 10 frames/s at 20 Hz)"
    )
    camera: CameraConfig = Field(default_factory=CameraConfig, description="view and size")


class FigureConfig(Strict):
    """Figure 5.3: frames of three episodes from one start (evaluation episode 0)."""

    enabled: bool = Field(True, description="write fig5_3.png (about 1 s of rendering)")
    frames: int = Field(5, ge=2, le=12, description="frames per episode, evenly spaced")


class EvaluateBootstrapConfig(StageConfig):
    """`artic evaluate bootstrap` (Figure 5.2): the two policy-search runs of a task."""

    task: TaskName
    bootstrap: str = Field(description="policy-search output with init=bootstrap")
    random: str = Field(description="policy-search output with init=random")
    episodes: int = Field(100, gt=0, description="evaluation rollouts per init")
    reach_fraction: float = Field(0.9, gt=0, le=1, description="fraction of the final return")
    reach_within: int = Field(50, ge=0, description="updates to reach it within (target)")
    video: VideoConfig = Field(default_factory=VideoConfig, description="video of the policy")
    figure: FigureConfig = Field(default_factory=FigureConfig, description="Figure 5.3")

    def episode_starts(self) -> list[int]:
        """The reset seed of each evaluation episode j, drawn from (seed, 7)."""
        return [
            int(v) for v in np.random.SeedSequence([self.seed, 7]).generate_state(self.episodes)
        ]

    def episodes_of(self, n_seeds: int, seed: int) -> list[int]:
        """The evaluation episodes seed `seed` of a run of `n_seeds` seeds rolls out."""
        return [j for j in range(self.episodes) if j % n_seeds == seed]


@dataclass(frozen=True)
class SearchOutput:
    """A finished policy-search folder: its validated config and manifest."""

    folder: Path
    cfg: PolicySearchConfig
    manifest: Any

    @classmethod
    def open(cls, folder: Path) -> SearchOutput:
        cfg, manifest = read_stage_config(folder, "policy-search", PolicySearchConfig)
        verify_file(folder, manifest, CURVE)
        return cls(folder, cfg, manifest)

    def curve(self) -> np.ndarray:
        """(rows, 8) learning_curve.csv as floats (columns `CURVE_COLUMNS`)."""
        rows = read_csv(self.folder / CURVE)
        if not rows or rows[0] != CURVE_COLUMNS:
            raise InputError(f"{self.folder / CURVE}: expected the columns {CURVE_COLUMNS}")
        return np.array([[float(v) for v in r] for r in rows[1:]], dtype=np.float64).reshape(
            -1, len(CURVE_COLUMNS)
        )

    def initial_actor(self, index: int) -> Any:
        """The `ActionFn` of a random run's initial policy of seed `index` (update 0,
        mean action): the random DMP (`artic.learning.search.random_dmp`) or the random
        Gaussian MLP, both rebuilt from the run's config and seed."""
        from artic.learning.search import N_JOINTS, random_dmp, run_seed

        if self.cfg.init != "random":
            raise InputError(f"{self.folder}: only a random run's initial policy is rebuilt")
        task, seed = self.cfg.task, run_seed(self.cfg.seed, index)
        if algorithm_of(self.cfg) == "pi2cma":
            from artic.learning.rollout import dmp_actor

            p = self.cfg.pi2cma_policy
            return dmp_actor(random_dmp(self.cfg, seed), p.basis, task.control_dt,
                             task.horizon, p.k_p)  # fmt: skip
        import torch

        from artic.learning.rollout import gaussian_actor
        from artic.policies.gaussian_mlp import GaussianMLPPolicy

        m, obs_dim = self.cfg.mlp_policy, N_JOINTS + len(task.goal)
        policy = GaussianMLPPolicy(
            obs_dim,
            N_JOINTS,
            tuple(m.hidden),
            m.init_log_std,
            m.min_log_std,
            generator=torch.Generator().manual_seed(seed),
        )
        return gaussian_actor(policy)

    def final_actor(self, index: int) -> Any:
        """The `ActionFn` of seed `index`'s final policy (mean action, no exploration)."""
        task = self.cfg.task
        if algorithm_of(self.cfg) == "pi2cma":
            from artic.learning.rollout import dmp_actor
            from artic.policies.dmp import DMPFile

            path = verify_file(self.folder, self.manifest, f"{seed_dir(index)}/dmp.json")
            dmp = DMPFile.from_json_dict(read_json(path))
            k_p = self.cfg.pi2cma_policy.k_p
            return dmp_actor(dmp.params, dmp.cfg, task.control_dt, task.horizon, k_p)
        from artic.artifacts.model_file import load_torch_file
        from artic.learning.rollout import gaussian_actor
        from artic.policies.gaussian_mlp import GaussianMLPPolicy

        path = verify_file(self.folder, self.manifest, f"{seed_dir(index)}/policy.pt")
        saved = load_torch_file(path, "policy file")  # weights_only: tensors and plain data
        try:
            h = saved["hparams"]
            policy = GaussianMLPPolicy(h["obs_dim"], h["act_dim"], tuple(h["hidden"]),
                                       min_log_std=h["min_log_std"])  # fmt: skip
            policy.load_state_dict(saved["state_dict"])
        except (KeyError, TypeError, ValueError, RuntimeError) as err:
            raise InputError(f"{path}: policy does not load ({type(err).__name__})") from None
        return gaussian_actor(policy)


def open_runs(task: str, folders: dict[str, Path]) -> dict[str, SearchOutput]:
    """The policy-search runs of each init (`INITS`), checked to be of that init, of task
    `task` and of one task config."""
    runs = {init: SearchOutput.open(folders[init]) for init in INITS}
    for init, run in runs.items():
        if run.cfg.init != init:
            raise InputError(f"{init}: {run.folder} was run with init={run.cfg.init}")
        if run.cfg.task.name != task:
            raise InputError(
                f"{init}: {run.folder} is of task '{run.cfg.task.name}', expected '{task}'"
            )
    if runs["bootstrap"].cfg.task != runs["random"].cfg.task:
        raise InputError("random: its task config differs from the bootstrap run's")
    return runs


def run_summary(
    cfg: PolicySearchConfig, inputs: dict[str, str], table: np.ndarray
) -> tuple[dict[str, Any], dict[str, float | int | str]]:
    """summary.json of a policy-search run and its statistics, from its learning curve
    rows (`CURVE_COLUMNS` + seconds, as floats): its settings, the normalised return (mean
    and standard error over seeds) at update 0 and at the last, the final success rate."""
    dmp = algorithm_of(cfg) == "pi2cma"
    last = table[table[:, 1] == cfg.updates]
    first = table[table[:, 1] == 0]
    seconds = table[table[:, 1] > 0, len(CURVE_COLUMNS)]
    summary = {
        "task": cfg.task.name,
        "init": cfg.init,
        "algorithm": algorithm_of(cfg),
        "policy": "dmp" if dmp else "gaussian_mlp",
        "seeds": cfg.seeds,
        "updates": cfg.updates,
        "rollouts_per_update": cfg.rollouts,
        "eval_rollouts": cfg.eval_rollouts,
        "initial_normalised_return": _mean_sem(first[:, 4]),
        "final_normalised_return": _mean_sem(last[:, 4]),
        "final_success_rate": float(last[:, 5].mean()),
        "normalised_return": "1 - R / R_idle; R: return of the mean policy from fixed starts, "
        "R_idle: return of a robot that keeps still from the same starts",
        "random_init": (
            _random_dmp_description(cfg)
            if dmp
            else "MLP: PyTorch default init, output layer x0.01 (mean action ~ 0)"
        ),
        "inputs": inputs,
        "final_policies": [
            f"{seed_dir(i)}/{'dmp.json' if dmp else 'policy.pt'}" for i in range(cfg.seeds)
        ],
    }
    return summary, {
        "task": cfg.task.name,
        "init": cfg.init,
        "algorithm": algorithm_of(cfg),
        "seeds": cfg.seeds,
        "final normalised return": round(float(last[:, 4].mean()), 4),
        "final success rate": round(float(last[:, 5].mean()), 3),
        "s per update": round(float(seconds.mean()), 3) if len(seconds) else 0.0,
    }


def _random_dmp_description(cfg: PolicySearchConfig) -> str:
    """How `artic.learning.search.random_dmp` draws the random DMP of `cfg.baseline`."""
    if cfg.baseline == "centred":
        return (
            "DMP (baseline centred): y0 = goal = robot start, weights ~ N(0, random_weight_std^2)"
        )
    return (
        "DMP (baseline exploring): y0 = robot start, goal = IK of a tool point uniform in "
        "explore_half_extent around the handle / ball, weights ~ N(0, explore_weight_std^2)"
    )


def _mean_sem(x: np.ndarray) -> dict[str, float]:
    sem = float(x.std(ddof=1) / np.sqrt(len(x))) if len(x) > 1 else 0.0
    return {"mean": float(x.mean()), "sem": sem}


def curve_stats(curve: np.ndarray) -> np.ndarray:
    """(updates, 4) rows [update, rollouts, mean, sem] of the normalised return over seeds
    for a learning_curve table (rows, 8); updates that not every seed reached are left out."""
    seeds = np.unique(curve[:, 0])
    out = []
    for u in np.unique(curve[:, 1]):
        at = curve[curve[:, 1] == u]
        if len(at) != len(seeds):
            continue
        x = at[:, 4]
        sem = x.std(ddof=1) / np.sqrt(len(x)) if len(x) > 1 else 0.0
        out.append([u, at[0, 2], x.mean(), sem])
    return np.array(out, dtype=np.float64).reshape(-1, 4)


def curve_mean(curve: np.ndarray, update: int, column: str) -> float | None:
    """Mean over seeds of `column` (of `CURVE_COLUMNS`) at `update`, or None when not
    every seed of the curve reached that update."""
    at = curve[curve[:, 1] == update]
    if len(at) == 0 or len(at) != len(np.unique(curve[:, 0])):
        return None
    return float(at[:, CURVE_COLUMNS.index(column)].mean())


def touch_share(curve: np.ndarray, first: int = 1, last: int = 10) -> float | None:
    """Share of the exploration rollouts of updates `first`..`last` that touched the
    object (mean of `touch_rate` over seeds and updates; every update has the same number
    of rollouts), or None when none of those updates is recorded."""
    at = curve[(curve[:, 1] >= first) & (curve[:, 1] <= last)]
    values = at[:, CURVE_COLUMNS.index("touch_rate")]
    return float(values.mean()) if len(values) else None


def demos_folder(run: SearchOutput) -> Path:
    """The plan-demos output a bootstrapped run descends from (through fit-dmp for DMP
    policies), as its manifests record it (`input_folder`: a relative path is taken
    from the folder the run was started in)."""
    name = "dmp" if "dmp" in run.manifest.inputs else "demos"
    parent = input_folder(run.folder, run.manifest, name)
    manifest = read_manifest(parent)
    return input_folder(parent, manifest, "demos") if manifest.stage == "fit-dmp" else parent


def demo_provenance(run: SearchOutput) -> tuple[str | None, float | None]:
    """(the kinematic model source, the share of demos that succeeded when executed) of
    the plan-demos output a bootstrapped run descends from (`demos_folder`); (None, None)
    for a random run. A demo that was not planned counts as a failure; the share is None
    when plan-demos did not execute its demos."""
    if run.cfg.init == "random":
        return None, None
    folder = demos_folder(run)
    manifest = read_manifest(folder, expected_stage="plan-demos")
    source = manifest.config.get("model", {}).get("source")
    if source is None:
        raise InputError(f"{folder}: its manifest's config has no model.source")
    if "executed successes" not in manifest.stats:
        return str(source), None
    total = int(manifest.stats["demos planned"]) + int(manifest.stats["demos failed"])
    return str(source), int(manifest.stats["executed successes"]) / max(total, 1)


def bootstrap_verdict(
    stats: dict[str, np.ndarray], reach_fraction: float, reach_within: int
) -> dict[str, Any]:
    """Figure 5.2's two verdicts from the `curve_stats` of each init: whether the
    bootstrapped mean beats the random one at every common update (and where it does
    not), and the first update at which it reaches `reach_fraction` of its final value
    (None if that is <= 0), and whether that is within `reach_within` updates."""
    b, r = stats["bootstrap"], stats["random"]
    common = sorted(set(b[:, 0]) & set(r[:, 0]))
    bm = dict(zip(b[:, 0], b[:, 2], strict=True))
    rm = dict(zip(r[:, 0], r[:, 2], strict=True))
    behind = [int(u) for u in common if not bm[u] > rm[u]]
    final = float(b[-1, 2])
    reached = [int(u) for u, m in zip(b[:, 0], b[:, 2], strict=True) if m >= reach_fraction * final]
    reach = reached[0] if final > 0 and reached else None
    return {
        "beats_every_update": not behind and bool(common),
        "behind_at": behind,
        "reach_update": reach,
        "reach_ok": reach is not None and reach <= reach_within,
    }


def film_episode(
    task: TaskConfig, act: ActionFn, reset_seed: int, video: VideoConfig
) -> tuple[Trajectory, bytes]:
    """One episode of `act` from `reset(seed=reset_seed)`, the same as
    `artic.learning.rollout.rollout` gives, and its animated GIF: the frames after the
    reset and after every `frame_every`-th step and the last one (`artic.sim.camera`,
    deterministic), shown at the control rate / `frame_every`."""
    from artic.sim.camera import encode_gif

    every = video.frame_every
    traj, frames = film_steps(task, act, reset_seed, lambda k: k % every == 0, video.camera)
    return traj, encode_gif(frames, fps=1.0 / (task.control_dt * every))


def film_steps(
    task: TaskConfig,
    act: ActionFn,
    reset_seed: int,
    keep: Callable[[int], bool],
    camera: CameraConfig,
) -> tuple[Trajectory, list[np.ndarray]]:
    """One episode of `act` from `reset(seed=reset_seed)` and the frames after the steps
    `k` (0: the reset) for which `keep(k)`, and after the last step (only those are
    rendered; the episode is the same as unfilmed)."""
    from artic.learning.rollout import rollout
    from artic.sim.envs import ArticTaskEnv

    env = _Filmed(ArticTaskEnv(task, seed=None, render_mode="rgb_array", camera=camera), keep)
    try:
        traj = rollout(env, act, reset_seed)
    finally:
        env.close()
    return traj, env.frames


class _Filmed(gym.Wrapper[Any, Any, Any, Any]):
    """Keeps `render()` frames of the last episode: after the reset, after every step
    `k` with `keep(k)` and after the step that ends it (only those are rendered)."""

    def __init__(self, env: gym.Env[Any, Any], keep: Callable[[int], bool]) -> None:
        super().__init__(env)
        self.keep, self._steps = keep, 0
        self.frames: list[np.ndarray] = []

    def _keep(self) -> None:
        self.frames.append(np.asarray(self.env.render(), dtype=np.uint8))

    def reset(self, **kwargs: Any) -> Any:
        out = self.env.reset(**kwargs)
        self.frames, self._steps = [], 0
        self._keep()
        return out

    def step(self, action: Any) -> Any:
        out = self.env.step(action)
        self._steps += 1
        if self.keep(self._steps) or out[2] or out[3]:
            self._keep()
        return out


def demo_actor(folder: Path, task: TaskConfig) -> ActionFn:
    """The `ActionFn` that replays a plan-demos output's first demo as plan-demos executes
    it: its joint positions and velocities tracked with the stage's `execute.gain`
    (`artic.control.tracking.JointTracker`)."""
    from artic.artifacts.demo_dataset import load_demos
    from artic.artifacts.formats import read_npz
    from artic.control.tracking import JointTracker

    demo = load_demos(folder, task.name, max_demos=1).demos[0]
    manifest = read_manifest(folder, expected_stage="plan-demos")
    qd = read_npz(verify_file(folder, manifest, demo.file))["qd_robot"].astype(np.float64)
    return JointTracker(demo.q, qd, float(manifest.config["execute"]["gain"]))


def figure_frames(
    runs: dict[str, SearchOutput], reset_seed: int, frames: int, camera: CameraConfig
) -> list[tuple[str, list[np.ndarray], Trajectory]]:
    """Figure 5.3's rows, each (label, `frames` frames evenly spaced over the episode,
    the episode), from the start of `reset_seed`: (a) the random run's initial policy
    (seed 0), what learning from scratch starts with; (b) the first planned demo replayed
    as plan-demos executes it; (c) the bootstrapped run's final policy (seed 0)."""
    task = runs["bootstrap"].cfg.task
    at = {round(i * task.horizon / (frames - 1)) for i in range(frames)}
    rows = []
    for label, act in (
        ("(a) random initial policy", runs["random"].initial_actor(0)),
        ("(b) planned demo, executed", demo_actor(demos_folder(runs["bootstrap"]), task)),
        ("(c) bootstrapped, learnt", runs["bootstrap"].final_actor(0)),
    ):
        traj, kept = film_steps(task, act, reset_seed, lambda k: k in at, camera)
        rows.append((label, kept, traj))
    return rows
