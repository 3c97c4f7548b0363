"""PPO under VICES and RMP-VICES (thesis section 6.4): the config of `artic train-rmp`
and one run (controller, seed) of it, with stable-baselines3's PPO.

The thesis trains with SpinningUp's PPO "as in VICES"; SB3's PPO is set to match it
(`ppo_model`, docs/rmp.md for the mapping): an MLP (64, 64) with tanh for the policy and
a separate one for the value function, one epoch = `steps_per_epoch` environment steps
taken as ONE batch, `train_iters` gradient steps over it stopped early once the
approximate KL exceeds 1.5 `target_kl` (SB3's and SpinningUp's rule alike), GAE(gamma,
lambda), clip 0.2, Adam at `lr`, advantages normalised, no entropy bonus, no gradient
clipping, PyTorch's default initialisation and log std -0.5 (SpinningUp's).

Epochs are independent of history except through the networks and the optimiser, as in
SpinningUp (which cuts the last episode of an epoch and resets): epoch k of run `seed`
reseeds torch's and numpy's global generators (SB3 samples actions and shuffles batches
with them) and the environment from (seed, k), so a run resumed from the checkpoint of
epoch k (networks, optimiser state and counters: `RunState`) takes exactly the steps of
an uninterrupted one. A run touches no files: it returns its rows and hands each
epoch's checkpoint to the caller's `save`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import Field, field_validator

from artic.config.schemas import Strict, TrainingStageConfig
from artic.control.osc import VicesConfig
from artic.control.rmp import RmpConfig
from artic.sim.rmp_tasks import RmpTaskConfig

if TYPE_CHECKING:
    from stable_baselines3 import PPO

log = logging.getLogger("artic")

ControllerName = Literal["vices", "rmp_vices"]
CURVE = "learning_curve.csv"
FORCES = "forces.csv"
TIMING = "timings.csv"
CURVE_COLUMNS = ["controller", "seed", "epoch", "steps", "episodes", "return_mean",
                 "return_std", "collisions", "joint_limit_events", "force_median"]  # fmt: skip
FORCE_COLUMNS = ["controller", "seed", "epoch", "force"]
Checkpoint = dict[str, Any]


class PPOConfig(Strict):
    """PPO as SpinningUp's, as in VICES (section 6.4); docs/rmp.md maps it onto SB3."""

    hidden: list[int] = Field(default_factory=lambda: [64, 64], description="MLP widths (tanh)")
    steps_per_epoch: int = Field(4096, ge=2, description="environment steps per epoch (batch)")
    train_iters: int = Field(80, ge=1, description="gradient steps per epoch (SB3 n_epochs)")
    target_kl: float = Field(0.01, gt=0, description="stop an epoch's steps at KL > 1.5 this")
    gamma: float = Field(0.99, gt=0, le=1, description="discount")
    gae_lambda: float = Field(0.97, ge=0, le=1, description="GAE lambda")
    clip: float = Field(0.2, gt=0, description="PPO clip ratio")
    lr: float = Field(3e-4, gt=0, description="Adam step size (policy and value)")
    vf_coef: float = Field(0.5, ge=0, description="value loss weight in SB3's joint loss")
    init_log_std: float = Field(-0.5, description="initial log std of the Gaussian policy")
    threads: int = Field(1, ge=1, description="torch threads per run (part of the result)")


class TrainRmpConfig(TrainingStageConfig):
    """The config of `artic train-rmp` (conf/train_rmp/config.yaml)."""

    task: RmpTaskConfig
    controllers: list[ControllerName] = Field(
        default=["vices", "rmp_vices"], description="controllers to train under"
    )
    seeds: int = Field(2, gt=0, description="independent runs per controller (thesis: 10)")
    epochs: int = Field(20, ge=1, description="PPO epochs per run (thesis: 367)")
    ppo: PPOConfig = Field(default_factory=PPOConfig)
    vices: VicesConfig = Field(default_factory=VicesConfig)
    rmp: RmpConfig = Field(default_factory=RmpConfig)

    @field_validator("controllers")
    @classmethod
    def _distinct(cls, value: list[str]) -> list[str]:
        if not value or len(set(value)) != len(value):
            raise ValueError("controllers: one or more distinct names of vices, rmp_vices")
        return value

    def run_of(self, chunk: int) -> tuple[ControllerName, int]:
        """(controller, seed index) of chunk `chunk`: controller-major."""
        return self.controllers[chunk // self.seeds], chunk % self.seeds


def run_seed(base: int, controller: str, index: int) -> int:
    """The seed of run `index`: the same for every controller (paired runs)."""
    return int(np.random.SeedSequence([base, index]).generate_state(1)[0] % (2**31 - 1))


def epoch_seed(seed: int, epoch: int) -> int:
    """The seed of epoch `epoch` of run `seed` (torch, numpy and the environment)."""
    return int(np.random.SeedSequence([seed, epoch, 6]).generate_state(1)[0] % (2**31 - 1))


def make_env(cfg: TrainRmpConfig, controller: ControllerName, obstacles: bool = False) -> Any:
    """The environment of a run (`artic.sim.rmp_envs.RmpEnv`)."""
    from artic.sim.rmp_envs import RmpEnv

    return RmpEnv(cfg.task, controller, obstacles=obstacles, vices=cfg.vices, rmp=cfg.rmp)


def ppo_model(cfg: PPOConfig, env: Any, seed: int) -> PPO:
    """SB3's PPO set as SpinningUp's (module docstring), on `env` (one environment)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import Logger

    model = PPO(
        "MlpPolicy",
        env,
        learning_rate=cfg.lr,
        n_steps=cfg.steps_per_epoch,
        batch_size=cfg.steps_per_epoch,
        n_epochs=cfg.train_iters,
        gamma=cfg.gamma,
        gae_lambda=cfg.gae_lambda,
        clip_range=cfg.clip,
        normalize_advantage=True,
        ent_coef=0.0,
        vf_coef=cfg.vf_coef,
        max_grad_norm=1e10,  # SpinningUp does not clip gradients
        target_kl=cfg.target_kl,
        policy_kwargs={
            "net_arch": {"pi": list(cfg.hidden), "vf": list(cfg.hidden)},
            "activation_fn": torch.nn.Tanh,
            "ortho_init": False,
            "log_std_init": cfg.init_log_std,
        },
        seed=seed,
        device="cpu",
        verbose=0,
    )
    # artic writes its own per-epoch rows; SB3's default logger would make an empty
    # SB3-<time> folder in the system's temporary folder at every learn() call
    model.set_logger(Logger(None, []))
    return model


class EpochStats:
    """Per-epoch counts from the steps' infos: completed episodes' returns, collision
    and joint-limit events, and each collision's contact force (N)."""

    def __init__(self) -> None:
        self.returns: list[float] = []
        self.collisions = 0
        self.joint_limits = 0
        self.forces: list[float] = []
        self._running = 0.0

    def add(self, reward: float, done: bool, info: dict[str, Any]) -> None:
        self._running += reward
        if info.get("collision"):
            self.collisions += 1
            self.forces.append(float(info.get("contact_force", 0.0)))
        if info.get("joint_limit"):
            self.joint_limits += 1
        if done:
            self.returns.append(self._running)
            self._running = 0.0


def _callback(stats: EpochStats) -> Any:
    from stable_baselines3.common.callbacks import BaseCallback

    class Record(BaseCallback):
        def _on_step(self) -> bool:
            rewards, dones, infos = (
                self.locals["rewards"],
                self.locals["dones"],
                self.locals["infos"],
            )
            for r, d, info in zip(rewards, dones, infos, strict=True):
                stats.add(float(r), bool(d), info)
            return True

    return Record()


def train_run(
    cfg: TrainRmpConfig,
    chunk: int,
    state: Checkpoint | None,
    save: Callable[[Checkpoint], None],
) -> tuple[list[list[Any]], list[list[Any]], Any]:
    """Run chunk `chunk` (controller, seed) for `cfg.epochs` epochs: (curve rows
    (`CURVE_COLUMNS` + seconds), force rows (`FORCE_COLUMNS`), the final policy (SB3
    `ActorCriticPolicy`)). `state`: a checkpoint to resume from (None: start afresh);
    `save` gets one after every epoch (tensors and plain data)."""
    import torch
    from stable_baselines3.common.vec_env import DummyVecEnv

    controller, index = cfg.run_of(chunk)
    seed = run_seed(cfg.seed, controller, index)
    torch.set_num_threads(cfg.ppo.threads)
    vec = DummyVecEnv([lambda: make_env(cfg, controller)])
    try:
        model = ppo_model(cfg.ppo, vec, seed)
        rows: list[list[Any]] = []
        forces: list[list[Any]] = []
        if state is not None:
            model.policy.load_state_dict(state["policy"])
            model.policy.optimizer.load_state_dict(state["optimizer"])
            model.num_timesteps = int(state["num_timesteps"])
            model._n_updates = int(state["n_updates"])
            rows, forces = state["rows"], state["forces"]
        for epoch in range(len(rows), cfg.epochs):
            t0 = time.perf_counter()
            s = epoch_seed(seed, epoch)
            torch.manual_seed(s)
            np.random.seed(s % (2**32))
            vec.seed(s)
            model._last_obs = None  # learn() then resets the env (seeded above)
            stats = EpochStats()
            model.learn(cfg.ppo.steps_per_epoch, callback=_callback(stats),
                        reset_num_timesteps=False)  # fmt: skip
            seconds = time.perf_counter() - t0
            returns = np.asarray(stats.returns)
            mean = float(returns.mean()) if len(returns) else float("nan")
            std = float(returns.std()) if len(returns) else float("nan")
            median = float(np.median(stats.forces)) if stats.forces else float("nan")
            rows.append([controller, index, epoch, int(model.num_timesteps), len(returns), mean,
                         std, stats.collisions, stats.joint_limits, median, seconds])  # fmt: skip
            forces.extend([controller, index, epoch, f] for f in stats.forces)
            log.info("%s seed %d epoch %d: return %.2f, %d collisions, %d joint limits (%.1f s)",
                     controller, index, epoch, mean, stats.collisions, stats.joint_limits,
                     seconds)  # fmt: skip
            save({"policy": model.policy.state_dict(),
                  "optimizer": model.policy.optimizer.state_dict(),
                  "num_timesteps": int(model.num_timesteps), "n_updates": int(model._n_updates),
                  "rows": rows, "forces": forces})  # fmt: skip
        return rows, forces, model.policy
    finally:
        vec.close()


def policy_record(cfg: TrainRmpConfig, chunk: int, policy: Any) -> dict[str, Any]:
    """The `policy.pt` payload of a run: the policy's weights and plain data naming its
    task, controller and network (read back by `load_policy`)."""
    controller, index = cfg.run_of(chunk)
    return {"task": cfg.task.name, "controller": controller, "seed": index,
            "hidden": list(cfg.ppo.hidden), "state_dict": policy.state_dict()}  # fmt: skip


def load_policy(record: dict[str, Any], cfg: TrainRmpConfig, env: Any) -> Any:
    """The SB3 policy of a `policy_record` on `env` (its spaces)."""
    model = ppo_model(cfg.ppo.model_copy(update={"hidden": record["hidden"]}), env, seed=0)
    model.policy.load_state_dict(record["state_dict"])
    model.policy.set_training_mode(False)
    return model.policy
