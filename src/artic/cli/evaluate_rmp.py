"""`artic evaluate rmp`: Table 6.1, Fig. 6.2 and Fig. 6.4 (thesis section 6.5) from the
train-rmp folders of the tasks (`policies.<task>=`). The config, the runs read back and
the episodes are `artic.learning.rmp_evaluate`; the table, the decreases and the plots
are `artic.evaluation.rmp_report`.

Chunks: one per (task, controller), each rolling out the best seed's final policy in
`episodes` episodes with two random spheres. Outputs: `episodes.csv`, `table_6_1.csv`
(task, controller, reward_mean, reward_std, collisions, joint_limit_events, episodes),
`table_6_1.md` (with the thesis' numbers, Fig. 6.2's decreases, Fig. 6.4's medians and
the targets), `curves.csv` (Fig. 6.2's mean and s.e. over seeds per epoch),
`fig_6_2.png`, `fig_6_4.png`.
"""

from __future__ import annotations

from pathlib import Path

from artic.artifacts.chunk_parts import take_csv_rows
from artic.artifacts.formats import write_csv
from artic.cli.stage_runner import Plan, Stage
from artic.evaluation import rmp_report as report
from artic.learning.rmp_evaluate import EvaluateRmpConfig, RmpRun


def _runs(cfg: EvaluateRmpConfig, inputs: dict[str, Path]) -> dict[str, RmpRun]:
    return {task: RmpRun.open(inputs[task], task) for task in cfg.tasks}


def _plan(cfg: EvaluateRmpConfig, inputs: dict[str, Path]) -> Plan:
    from artic.learning.rmp_evaluate import check_obstacles

    for run in _runs(cfg, inputs).values():
        check_obstacles(run, cfg.seed)
    return Plan([cfg.episodes] * len(cfg.chunks()), "episodes")


def evaluate_chunk(cfg: EvaluateRmpConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """The obstacle episodes of one (task, controller)."""
    from artic.learning.rmp_evaluate import obstacle_episodes

    task, controller = cfg.chunks()[chunk]
    run = RmpRun.open(inputs[task], task)
    seed = run.best_seed(controller, cfg.best_of_last)
    rows = obstacle_episodes(run, controller, seed, cfg.seed, cfg.episodes)
    (tmp / "episodes").mkdir()
    write_csv(tmp / "episodes" / f"{chunk:03d}.csv", report.EPISODE_COLUMNS, rows)
    return len(rows)


def _finalize(
    cfg: EvaluateRmpConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    runs = _runs(cfg, inputs)
    parts = [work / "episodes" / f"{c:03d}.csv" for c in range(len(cfg.chunks()))]
    episodes = take_csv_rows(parts)
    (work / "episodes").rmdir()
    write_csv(work / "episodes.csv", report.EPISODE_COLUMNS, episodes)
    curves = {t: run.curve for t, run in runs.items()}
    out = report.summarise(cfg.tasks, curves, {t: r.forces() for t, r in runs.items()}, episodes)
    write_csv(work / "table_6_1.csv", report.TABLE_COLUMNS, out.table)
    write_csv(work / "curves.csv", ["task", "controller", "curve", "epoch", "mean", "sem"],
              out.curve_rows)  # fmt: skip
    report.training_curves(work / "fig_6_2.png", out.curves)
    report.force_histograms(work / "fig_6_4.png", out.forces)
    best = {(t, c): runs[t].best_seed(c, cfg.best_of_last) for t, c in cfg.chunks()}
    sources: dict[str, str] = {t: str(inputs[t]) for t in cfg.tasks}
    text = report.report_markdown(out.table, out.decreases, out.medians, sources, best)
    (work / "table_6_1.md").write_text(text)
    return {f"{r[0]} {r[1]}": f"reward {r[2]:.1f}, {r[4]} collisions, {r[5]} joint limits"
            for r in out.table}  # fmt: skip


STAGE: Stage[EvaluateRmpConfig] = Stage(
    name="evaluate-rmp",
    command="evaluate rmp",
    help=(
        "Table 6.1, Fig. 6.2, Fig. 6.4: VICES vs RMP-VICES with random obstacles.\n\n"
        "Example: artic evaluate rmp"
    ),
    conf="evaluate_rmp",
    schema=EvaluateRmpConfig,
    plan=_plan,
    chunk=evaluate_chunk,
    finalize=_finalize,
    inputs={"traj": "train-rmp", "door": "train-rmp", "push": "train-rmp"},
    input_paths=lambda cfg: cfg.input_paths(),
)
