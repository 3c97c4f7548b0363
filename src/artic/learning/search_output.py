"""A finished policy-search output folder (`artic policy-search`, docs/formats.md) read
back: its validated config, its learning curve and each seed's final policy as an
`ActionFn`; and the config (`EvaluateBootstrapConfig`), the two runs (`open_runs`) and
the statistics over seeds (`curve_stats`, `bootstrap_verdict`) of Figure 5.2, and the
optional video of a final policy (`VideoConfig`, `film_episode`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from pydantic import Field

from artic.artifacts.formats import read_csv, read_json
from artic.artifacts.manifest import read_stage_config, verify_file
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


class EvaluateBootstrapConfig(StageConfig):
    """`artic evaluate bootstrap` (Figure 5.2): the two policy-search runs of a task."""

    task: TaskName
    bootstrap: str = Field(description="policy-search output with init=bootstrap")
    random: str = Field(description="policy-search output with init=random")
    episodes: int = Field(100, gt=0, description="evaluation rollouts per init")
    reach_fraction: float = Field(0.9, gt=0, le=1, description="fraction of the final return")
    reach_within: int = Field(50, ge=0, description="updates to reach it within (target)")
    video: VideoConfig = Field(default_factory=VideoConfig, description="video of the policy")

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
        """(rows, 7) learning_curve.csv as floats (columns `CURVE_COLUMNS`)."""
        rows = read_csv(self.folder / CURVE)
        if not rows or rows[0] != CURVE_COLUMNS:
            raise InputError(f"{self.folder / CURVE}: expected the columns {CURVE_COLUMNS}")
        return np.array([[float(v) for v in r] for r in rows[1:]], dtype=np.float64).reshape(
            -1, len(CURVE_COLUMNS)
        )

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
    seconds = table[table[:, 1] > 0, 7]
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
    for a learning_curve table (rows, 7); updates that not every seed reached are left out."""
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
    from artic.learning.rollout import rollout
    from artic.sim.camera import encode_gif
    from artic.sim.envs import ArticTaskEnv

    env = _Filmed(
        ArticTaskEnv(task, seed=None, render_mode="rgb_array", camera=video.camera),
        video.frame_every,
    )
    try:
        traj = rollout(env, act, reset_seed)
    finally:
        env.close()
    return traj, encode_gif(env.frames, fps=1.0 / (task.control_dt * video.frame_every))


class _Filmed(gym.Wrapper[Any, Any, Any, Any]):
    """Keeps `render()` frames of the last episode: after the reset, after every
    `every`-th step and after the step that ends it (only those are rendered)."""

    def __init__(self, env: gym.Env[Any, Any], every: int) -> None:
        super().__init__(env)
        self.every, self._steps = every, 0
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
        if self._steps % self.every == 0 or out[2] or out[3]:
            self._keep()
        return out
