"""Figure 5.2's tables and report (`artic evaluate bootstrap`) from plain data: the
success table of the final policies' evaluation episodes and `report.md`'s text."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

INITS = ("bootstrap", "random")
EPISODE_COLUMNS = ["init", "seed", "episode", "reset_seed", "return", "success"]
SUCCESS_COLUMNS = ["init", "episodes", "successes", "success_rate", "mean_return"]
#: summary.csv (docs/results/ch5/summary.csv is these rows of every report)
SUMMARY_COLUMNS = ["task", "init", "baseline", "model_source", "demo_success",
                   "success_update_10", "final_success", "return_update_0",
                   "return_update_50"]  # fmt: skip


def _cell(value: float | str | None) -> str:
    """A summary.csv cell: "" for missing, floats to 4 decimals."""
    if value is None:
        return ""
    return f"{value:.4f}" if isinstance(value, float) else str(value)


def summary_row(
    task: str,
    init: str,
    baseline: str | None,
    model_source: str | None,
    demo_success: float | None,
    curve_means: dict[str, float | None],
    final_success: float,
) -> list[str]:
    """One `SUMMARY_COLUMNS` row. `curve_means`: the mean over seeds of the learning
    curve's `success_rate` at update 10 and `normalised_return` at updates 0 and 50, keyed
    `success_update_10`, `return_update_0`, `return_update_50` (None: not reached by
    every seed); None for a column that does not apply (a bootstrapped run's baseline, a
    random run's model and demos) is left empty."""
    return [_cell(v) for v in (
        task, init, baseline, model_source, demo_success, curve_means["success_update_10"],
        final_success, curve_means["return_update_0"], curve_means["return_update_50"],
    )]  # fmt: skip


def success_table(episodes: list[list[str]]) -> dict[str, tuple[int, int, float]]:
    """Per init: (episodes, successes, mean return) of `EPISODE_COLUMNS` rows."""
    success: dict[str, tuple[int, int, float]] = {}
    for init in INITS:
        mine = [r for r in episodes if r[0] == init]
        wins = sum(int(r[5]) for r in mine)
        success[init] = (len(mine), wins, float(np.mean([float(r[4]) for r in mine])))
    return success


def bootstrap_report(
    task: str,
    algorithm: str,
    seeds: tuple[int, int],
    rollouts: int,
    stats: dict[str, np.ndarray],
    success: dict[str, tuple[int, int, float]],
    verdict: dict[str, Any],
    reach: tuple[float, int],
    folders: tuple[Path, Path],
    touch: dict[str, float | None],
) -> str:
    """report.md: the curves' table (`curve_stats` rows of each init), the success table,
    the verdicts (`bootstrap_verdict`); `seeds`, `folders`: (bootstrap, random);
    `reach`: (fraction, within); `touch`: per init, the share of exploration rollouts of
    updates 1-10 that touched the object (None: not recorded)."""
    reach_fraction, reach_within = reach
    lines = [
        f"# Bootstrapped vs random initialisation: {task} (Figure 5.2)",
        "",
        f"Algorithm: {algorithm}; seeds: {seeds[0]} bootstrap, {seeds[1]} random; "
        f"{rollouts} rollouts per update. Normalised return = 1 - R / R_idle (R_idle: the "
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
    at = verdict["reach_update"]
    lines += [
        "",
        f"- Bootstrapped beats random at every update (mean over seeds): **{beats}**",
        f"- Bootstrapped reaches {reach_fraction:.0%} of its final normalised return at "
        f"update **{at if at is not None else 'never (final <= 0)'}** (target: within "
        f"{reach_within}): **{'yes' if verdict['reach_ok'] else 'no'}**",
        "- Exploration rollouts of updates 1-10 that touch the object (grasp it or move "
        "it): "
        + ", ".join(f"{init} {'-' if v is None else f'{v:.0%}'}" for init, v in touch.items()),
        f"- Inputs: `{folders[0]}`, `{folders[1]}`",
        "",
    ]
    return "\n".join(lines)
