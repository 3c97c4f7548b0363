"""`artic evaluate bootstrap`: Figure 5.2 for one task, bootstrapped against random init.

Reads the two policy-search folders of a task (`bootstrap=`, `random=`; both must be of
the same task config) and writes (docs/formats.md, "evaluate-bootstrap"): `curves.csv`
and `curves.png` (the normalised return over seeds per update, Figure 5.2), the final
policies' evaluation `episodes.csv` and `success.csv`, `report.md` (the table and the
verdicts), `summary.csv` (one row per init, `artic.learning.bootstrap_summary`),
`fig5_3.png` (Figure 5.3, `figure.enabled`) and `video_<init>.gif` (`video.enabled`).

Chunks: one per (init, seed) pair, each rolling out that seed's share of the episodes
(the chunk of seed 0 also films the video).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from artic.artifacts.chunk_parts import take_csv_rows
from artic.artifacts.formats import write_csv
from artic.cli.stage_runner import Plan, Stage
from artic.evaluation import bootstrap_report as report
from artic.evaluation.bootstrap_report import EPISODE_COLUMNS, INITS, SUMMARY_COLUMNS
from artic.evaluation.plots import bootstrap_curves
from artic.learning import bootstrap_summary as summary
from artic.learning.search import algorithm_of
from artic.learning.search_output import (
    EvaluateBootstrapConfig,
    SearchOutput,
    bootstrap_verdict,
    curve_stats,
    film_episode,
    open_runs,
    touch_share,
)


def _chunks(runs: dict[str, SearchOutput]) -> list[tuple[str, int]]:
    return [(init, i) for init in INITS for i in range(runs[init].cfg.seeds)]


def _plan(cfg: EvaluateBootstrapConfig, inputs: dict[str, Path]) -> Plan:
    runs = open_runs(cfg.task.name, inputs)
    chunks = _chunks(runs)
    return Plan([len(cfg.episodes_of(runs[i].cfg.seeds, s)) for i, s in chunks], "episodes")


def evaluate_chunk(
    cfg: EvaluateBootstrapConfig, inputs: dict[str, Path], chunk: int, tmp: Path
) -> int:
    """Roll out the final policy of one (init, seed) for its share of the episodes."""
    from artic.learning.rollout import rollout
    from artic.sim.envs import ArticTaskEnv

    runs = open_runs(cfg.task.name, inputs)
    init, seed = _chunks(runs)[chunk]
    run = runs[init]
    act = run.final_actor(seed)
    episodes = cfg.episodes_of(run.cfg.seeds, seed)
    starts = cfg.episode_starts()
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
    if cfg.video.enabled and seed == 0:
        _, gif = film_episode(run.cfg.task, act, int(starts[0]), cfg.video)
        (tmp / f"video_{init}.gif").write_bytes(gif)
    return len(rows)


def _finalize(
    cfg: EvaluateBootstrapConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    runs = open_runs(cfg.task.name, inputs)
    curves = {init: runs[init].curve() for init in INITS}
    stats = {init: curve_stats(curves[init]) for init in INITS}
    write_csv(work / "curves.csv", summary.CURVES_COLUMNS, summary.curve_rows(curves, stats))
    algorithm = algorithm_of(runs["bootstrap"].cfg)
    title = f"{cfg.task.name}: {algorithm}, mean and s.e. over seeds"
    bootstrap_curves(work / "curves.png", stats, title)
    episodes = take_csv_rows(sorted((work / "episodes").glob("*.csv")))
    (work / "episodes").rmdir()
    episodes.sort(key=lambda r: (INITS.index(r[0]), int(r[2])))
    write_csv(work / "episodes.csv", EPISODE_COLUMNS, episodes)
    success = report.success_table(episodes)
    table = [[i, n, w, w / n, m] for i, (n, w, m) in success.items()]
    write_csv(work / "success.csv", report.SUCCESS_COLUMNS, table)
    verdict = bootstrap_verdict(stats, cfg.reach_fraction, cfg.reach_within)
    b, r = runs["bootstrap"], runs["random"]
    text = report.bootstrap_report(
        cfg.task.name, algorithm, (b.cfg.seeds, r.cfg.seeds), b.cfg.rollouts, stats, success,
        verdict, (cfg.reach_fraction, cfg.reach_within), (b.folder, r.folder),
        {init: touch_share(curves[init]) for init in INITS},
    )  # fmt: skip
    (work / "report.md").write_text(text)
    write_csv(work / "summary.csv", SUMMARY_COLUMNS, summary.summary_rows(runs, curves, success))
    if cfg.figure.enabled:
        summary.figure_5_3(cfg, runs, work / "fig5_3.png")
    videos = {"videos": ", ".join(f"video_{i}.gif" for i in INITS)} if cfg.video.enabled else {}
    return {
        "task": cfg.task.name,
        "bootstrap final": round(float(stats["bootstrap"][-1, 2]), 4),
        "random final": round(float(stats["random"][-1, 2]), 4),
        "bootstrap success": round(success["bootstrap"][1] / success["bootstrap"][0], 3),
        "random success": round(success["random"][1] / success["random"][0], 3),
        "beats random at every update": str(verdict["beats_every_update"]),
        "reaches 90% by update": str(verdict["reach_update"]),
        **videos,
    }


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
