"""`artic evaluate bootstrap`: Figure 5.2 for one task, bootstrapped against random init.

Reads the two policy-search folders of a task (`bootstrap=`, `random=`; both must be of
the same task config) and writes:
- `curves.csv`: per init and update, the mean and standard error over seeds of the
  normalised return 1 - R / R_idle (see `artic.learning.search`), and the rollouts done;
- `curves.png`: those curves, mean with a standard-error band (Figure 5.2's style);
- `episodes.csv`: `episodes` evaluation rollouts of each init's final policies (mean
  action, no exploration), episode j run by seed j mod seeds, from reset seeds drawn
  from (seed, j): init, seed, episode, reset_seed, return, success;
- `success.csv`: per init, episodes, successes, success rate, mean return;
- `report.md`: the table, whether the bootstrapped mean beats the random one at every
  update, and the first update at which the bootstrapped curve reaches 90% of its final
  value (target: within 50 updates).

Chunks: one per (init, seed) pair, each rolling out that seed's share of the episodes.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field

from artic.artifacts.formats import write_csv
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import StageConfig, Strict
from artic.errors import InputError
from artic.learning.search import algorithm_of
from artic.learning.search_output import SearchOutput, bootstrap_verdict, curve_stats

INITS = ("bootstrap", "random")
EPISODE_COLUMNS = ["init", "seed", "episode", "reset_seed", "return", "success"]


class TaskName(Strict):
    """The task config group (`conf/common/task`); only its name is used: the policies
    are rolled out in the task config their policy-search run used."""

    model_config = Strict.model_config | {"extra": "ignore"}
    name: str = Field(description="task name: drawer, microwave, tball")


class EvaluateBootstrapConfig(StageConfig):
    task: TaskName
    bootstrap: str = Field(description="policy-search output with init=bootstrap")
    random: str = Field(description="policy-search output with init=random")
    episodes: int = Field(100, gt=0, description="evaluation rollouts per init")
    reach_fraction: float = Field(0.9, gt=0, le=1, description="fraction of the final return")
    reach_within: int = Field(50, ge=0, description="updates to reach it within (target)")


def _open_inputs(cfg: EvaluateBootstrapConfig, inputs: dict[str, Path]) -> dict[str, SearchOutput]:
    runs = {init: SearchOutput.open(inputs[init]) for init in INITS}
    for init, run in runs.items():
        if run.cfg.init != init:
            raise InputError(f"{init}: {run.folder} was run with init={run.cfg.init}")
        if run.cfg.task.name != cfg.task.name:
            raise InputError(
                f"{init}: {run.folder} is of task '{run.cfg.task.name}', expected '{cfg.task.name}'"
            )
    if runs["bootstrap"].cfg.task != runs["random"].cfg.task:
        raise InputError("random: its task config differs from the bootstrap run's")
    return runs


def _chunks(runs: dict[str, SearchOutput]) -> list[tuple[str, int]]:
    return [(init, i) for init in INITS for i in range(runs[init].cfg.seeds)]


def _episodes_of(cfg: EvaluateBootstrapConfig, n_seeds: int, seed: int) -> list[int]:
    return [j for j in range(cfg.episodes) if j % n_seeds == seed]


def _plan(cfg: EvaluateBootstrapConfig, inputs: dict[str, Path]) -> Plan:
    runs = _open_inputs(cfg, inputs)
    chunks = _chunks(runs)
    return Plan([len(_episodes_of(cfg, runs[i].cfg.seeds, s)) for i, s in chunks], "episodes")


def evaluate_chunk(
    cfg: EvaluateBootstrapConfig, inputs: dict[str, Path], chunk: int, tmp: Path
) -> int:
    """Roll out the final policy of one (init, seed) for its share of the episodes."""
    from artic.learning.rollout import rollout
    from artic.sim.envs import ArticTaskEnv

    runs = _open_inputs(cfg, inputs)
    init, seed = _chunks(runs)[chunk]
    run = runs[init]
    act = run.final_actor(seed)
    episodes = _episodes_of(cfg, run.cfg.seeds, seed)
    starts = np.random.SeedSequence([cfg.seed, 7]).generate_state(cfg.episodes)
    rows: list[list[Any]] = []
    env = ArticTaskEnv(run.cfg.task, seed=None)
    try:
        for j in episodes:
            traj = rollout(env, act, int(starts[j]))
            rows.append([init, seed, j, int(starts[j]), traj.total_return, int(traj.success)])
    finally:
        env.close()
    (tmp / "episodes").mkdir()
    write_csv(tmp / "episodes" / f"{init}_{seed:03d}.csv", EPISODE_COLUMNS, rows)
    return len(rows)


def _plot(path: Path, stats: dict[str, np.ndarray], title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.0, 3.6))
    names = {"bootstrap": "ours (motion-planner bootstrap)", "random": "random init"}
    for init, colour in zip(INITS, ("C0", "C3"), strict=True):
        s = stats[init]
        ax.plot(s[:, 0], s[:, 2], color=colour, lw=1.8, label=names[init])
        ax.fill_between(s[:, 0], s[:, 2] - s[:, 3], s[:, 2] + s[:, 3], color=colour, alpha=0.25)
    ax.set_xlabel("policy update")
    ax.set_ylabel("normalised return")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=100, metadata={"Software": None})
    plt.close(fig)


def _read_episodes(work: Path) -> list[list[str]]:
    rows: list[list[str]] = []
    for path in sorted((work / "episodes").glob("*.csv")):
        with path.open(newline="") as f:
            rows.extend(list(csv.reader(f))[1:])
        path.unlink()
    (work / "episodes").rmdir()
    return sorted(rows, key=lambda r: (INITS.index(r[0]), int(r[2])))


def _finalize(
    cfg: EvaluateBootstrapConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    runs = _open_inputs(cfg, inputs)
    stats = {init: curve_stats(runs[init].curve()) for init in INITS}
    curve_rows = [[init, int(u), int(r), m, s] for init in INITS for u, r, m, s in stats[init]]
    write_csv(work / "curves.csv", ["init", "update", "rollouts", "mean", "sem"], curve_rows)
    algorithm = algorithm_of(runs["bootstrap"].cfg)
    title = f"{cfg.task.name}: {algorithm}, mean and s.e. over seeds"
    _plot(work / "curves.png", stats, title)
    episodes = _read_episodes(work)
    write_csv(work / "episodes.csv", EPISODE_COLUMNS, episodes)
    success: dict[str, tuple[int, int, float]] = {}
    for init in INITS:
        mine = [r for r in episodes if r[0] == init]
        wins = sum(int(r[5]) for r in mine)
        success[init] = (len(mine), wins, float(np.mean([float(r[4]) for r in mine])))
    columns = ["init", "episodes", "successes", "success_rate", "mean_return"]
    table = [[i, n, w, w / n, m] for i, (n, w, m) in success.items()]
    write_csv(work / "success.csv", columns, table)
    verdict = bootstrap_verdict(stats, cfg.reach_fraction, cfg.reach_within)
    _report(work / "report.md", cfg, runs, stats, success, verdict)
    return {
        "task": cfg.task.name,
        "bootstrap final": round(float(stats["bootstrap"][-1, 2]), 4),
        "random final": round(float(stats["random"][-1, 2]), 4),
        "bootstrap success": round(success["bootstrap"][1] / success["bootstrap"][0], 3),
        "random success": round(success["random"][1] / success["random"][0], 3),
        "beats random at every update": str(verdict["beats_every_update"]),
        "reaches 90% by update": str(verdict["reach_update"]),
    }


def _report(path: Path, cfg: EvaluateBootstrapConfig, runs: dict[str, SearchOutput],
            stats: dict[str, np.ndarray], success: dict[str, tuple[int, int, float]],
            verdict: dict[str, Any]) -> None:  # fmt: skip
    b, r = runs["bootstrap"].cfg, runs["random"].cfg
    lines = [
        f"# Bootstrapped vs random initialisation: {cfg.task.name} (Figure 5.2)",
        "",
        f"Algorithm: {algorithm_of(b)}; seeds: {b.seeds} bootstrap, {r.seeds} random; "
        f"{b.rollouts} rollouts per update. Normalised return = 1 - R / R_idle (R_idle: the "
        "robot keeping still from the same starts); mean and standard error over seeds.",
        "",
        "![curves](curves.png)",
        "",
        "| update | bootstrap mean | bootstrap s.e. | random mean | random s.e. |",
        "|---:|---:|---:|---:|---:|",
    ]
    rm = {row[0]: row for row in stats["random"]}
    for u, _, m, s in stats["bootstrap"]:
        rr = rm.get(u)
        tail = f"{rr[2]:.3f} | {rr[3]:.3f}" if rr is not None else "- | -"
        lines.append(f"| {int(u)} | {m:.3f} | {s:.3f} | {tail} |")
    lines += [
        "",
        "| final policies | episodes | success rate | mean return |",
        "|---|---:|---:|---:|",
    ]
    for init, (n, w, mean) in success.items():
        lines.append(f"| {init} | {n} | {w / n:.2f} | {mean:.2f} |")
    beats = (
        "yes" if verdict["beats_every_update"] else f"no (not at updates {verdict['behind_at']})"
    )
    reach = verdict["reach_update"]
    lines += [
        "",
        f"- Bootstrapped beats random at every update (mean over seeds): **{beats}**",
        f"- Bootstrapped reaches {cfg.reach_fraction:.0%} of its final normalised return at "
        f"update **{reach if reach is not None else 'never (final <= 0)'}** (target: within "
        f"{cfg.reach_within}): **{'yes' if verdict['reach_ok'] else 'no'}**",
        f"- Inputs: `{runs['bootstrap'].folder}`, `{runs['random'].folder}`",
        "",
    ]
    path.write_text("\n".join(lines))


STAGE: Stage[EvaluateBootstrapConfig] = Stage(
    name="evaluate-bootstrap",
    command="evaluate bootstrap",
    help=(
        "Figure 5.2: bootstrapped vs random initialisation over seeds, and success rates.\n\n"
        "Example: artic evaluate bootstrap --task drawer"
    ),
    task_option=True,
    conf="evaluate_bootstrap",
    schema=EvaluateBootstrapConfig,
    plan=_plan,
    chunk=evaluate_chunk,
    finalize=_finalize,
    inputs={"bootstrap": "policy-search", "random": "policy-search"},
    input_paths=lambda cfg: {"bootstrap": Path(cfg.bootstrap), "random": Path(cfg.random)},
)
