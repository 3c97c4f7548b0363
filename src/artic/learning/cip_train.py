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
from typing import Any, Literal, NamedTuple, Protocol

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from artic.config.schemas import Strict
from artic.errors import InputError
from artic.learning.td3_settings import Demonstrations, Td3Config
from artic.sim.cip_envs import CipEnv
from artic.sim.cip_tasks import CipTaskConfig

Setting = Literal["e2e", "head", "safety", "mv", "cip", "cip_bc", "e2e_bc"]
SETTING_NAMES: tuple[Setting, ...] = ("e2e", "head", "safety", "mv", "cip", "cip_bc", "e2e_bc")
CURVE_COLUMNS = ["setting", "seed", "episode", "success", "success_best", "violation_rate",
                 "violation_rate_train", "return_mean"]  # fmt: skip


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
