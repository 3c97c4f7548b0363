"""`artic evaluate rmp` (thesis section 6.5.2, Table 6.1): its config, the train-rmp
folders read back (`RmpRun`), the best seed of each controller and the obstacle
episodes of a final policy.

Best seed: the highest mean of `return_mean` over a run's last `best_of_last` epochs
(ties: the lower seed). Episode j of task t is reset from the seed (seed, t, j) for both
controllers, so they meet the same spheres, via points, blocks and goals. Actions are
the policy's mean (no exploration noise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, field_validator

from artic.artifacts.formats import read_csv
from artic.artifacts.manifest import read_stage_config, verify_file
from artic.config.schemas import StageConfig
from artic.errors import InputError
from artic.learning.rmp_train import CURVE, FORCES, TrainRmpConfig, load_policy, make_env
from artic.sim.rmp_tasks import RmpTaskName

TASKS: tuple[RmpTaskName, ...] = ("traj", "door", "push")
CONTROLLERS = ("vices", "rmp_vices")


class EvaluateRmpConfig(StageConfig):
    """The config of `artic evaluate rmp` (conf/evaluate_rmp/config.yaml)."""

    tasks: list[RmpTaskName] = Field(
        default_factory=lambda: list(TASKS), description="tasks of the table (rows)"
    )
    policies: dict[str, str] = Field(description="train-rmp output folder of each task")
    episodes: int = Field(100, gt=0, description="obstacle episodes per task and controller")
    best_of_last: int = Field(3, ge=1, description="epochs the best seed is ranked over")

    @field_validator("tasks")
    @classmethod
    def _distinct(cls, value: list[str]) -> list[str]:
        if not value or len(set(value)) != len(value):
            raise ValueError("tasks: one or more distinct names of traj, door, push")
        return value

    def chunks(self) -> list[tuple[str, str]]:
        """(task, controller) of each chunk."""
        return [(t, c) for t in self.tasks for c in CONTROLLERS]

    def input_paths(self) -> dict[str, Path]:
        missing = [t for t in self.tasks if t not in self.policies]
        if missing:
            raise InputError(f"config field policies: no folder for task {missing[0]}")
        return {t: Path(self.policies[t]) for t in self.tasks}


@dataclass(frozen=True)
class RmpRun:
    """A finished train-rmp folder: its validated config and learning curve."""

    folder: Path
    cfg: TrainRmpConfig
    curve: list[list[str]]

    @classmethod
    def open(cls, folder: Path, task: str) -> RmpRun:
        """The run in `folder`, checked to be of `task` under both controllers."""
        cfg, manifest = read_stage_config(folder, "train-rmp", TrainRmpConfig)
        if cfg.task.name != task:
            raise InputError(f"policies.{task}: {folder} holds task '{cfg.task.name}'")
        if sorted(cfg.controllers) != sorted(CONTROLLERS):
            raise InputError(
                f"policies.{task}: {folder} trained {cfg.controllers}, expected both vices "
                "and rmp_vices"
            )
        verify_file(folder, manifest, FORCES)
        curve = read_csv(verify_file(folder, manifest, CURVE))[1:]
        return cls(folder, cfg, curve)

    def forces(self) -> list[list[str]]:
        """The training collision forces (`forces.csv` rows, no header)."""
        return read_csv(self.folder / FORCES)[1:]

    def best_seed(self, controller: str, last: int) -> int:
        """The seed with the highest mean return over the last `last` epochs."""
        best, score = 0, -math.inf
        for seed in range(self.cfg.seeds):
            rows = [r for r in self.curve if r[0] == controller and int(r[1]) == seed]
            values = [float(r[5]) for r in rows[-last:]]
            finite = [v for v in values if math.isfinite(v)]
            mean = float(np.mean(finite)) if finite else -math.inf
            if mean > score:
                best, score = seed, mean
        return best

    def policy(self, controller: str, seed: int, env: Any) -> Any:
        """The final SB3 policy of (controller, seed) on `env`."""
        from artic.artifacts.model_file import load_torch_file

        path = self.folder / f"policies/{controller}/seed_{seed:03d}/policy.pt"
        if not path.is_file():
            raise InputError(f"{path}: no such file")
        record = load_torch_file(path, "policy file")
        if record.get("controller") != controller or record.get("task") != self.cfg.task.name:
            raise InputError(f"{path}: a policy of {record.get('task')}/{record.get('controller')}")
        return load_policy(record, self.cfg, env)


def reset_seed(seed: int, task: str, episode: int) -> int:
    """The reset seed of evaluation episode `episode` of `task` (both controllers)."""
    return int(np.random.SeedSequence([seed, TASKS.index(task), episode, 9]).generate_state(1)[0])


def check_obstacles(run: RmpRun, base_seed: int) -> None:
    """Place the spheres of the first evaluation episode (InputError naming
    `task.obstacles` when they cannot be placed clear): bad input found before any
    episode runs."""
    env = make_env(run.cfg, "vices", obstacles=True)
    try:
        env.reset(seed=reset_seed(base_seed, run.cfg.task.name, 0))
    except InputError as err:
        raise InputError(f"{run.folder}: {err}") from None
    finally:
        env.close()


def obstacle_episodes(run: RmpRun, controller: str, seed: int, base_seed: int,
                      episodes: int) -> list[list[Any]]:  # fmt: skip
    """Roll the final policy of (controller, seed) out in `episodes` obstacle episodes:
    rows of `artic.evaluation.rmp_report.EPISODE_COLUMNS` (force: the largest collision
    force of the episode, N, nan without a collision)."""
    import torch

    torch.set_num_threads(1)
    task = run.cfg.task.name
    env = make_env(run.cfg, controller, obstacles=True)  # type: ignore[arg-type]
    rows: list[list[Any]] = []
    try:
        policy = run.policy(controller, seed, env)
        for j in range(episodes):
            s = reset_seed(base_seed, task, j)
            obs, _ = env.reset(seed=s)
            total, steps, force = 0.0, 0, math.nan
            info: dict[str, Any] = {}
            while True:
                action, _ = policy.predict(obs, deterministic=True)
                obs, reward, terminated, truncated, info = env.step(action)
                total += float(reward)
                steps += 1
                if info["collision"]:
                    force = float(info["contact_force"])
                if terminated or truncated:
                    break
            rows.append([task, controller, seed, j, s, total, steps, int(info["collision"]),
                         int(info["joint_limit"]), int(info["success"]), force])  # fmt: skip
    finally:
        env.close()
    return rows
