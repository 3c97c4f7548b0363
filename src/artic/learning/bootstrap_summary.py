"""`artic evaluate bootstrap`'s curves.csv and summary.csv rows and Figure 5.3 (issue
23), from the two policy-search runs of a task (`artic.learning.search_output`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from artic.evaluation.bootstrap_report import INITS, summary_row
from artic.evaluation.plots import frame_strips
from artic.learning.search import algorithm_of
from artic.learning.search_output import (
    EvaluateBootstrapConfig,
    SearchOutput,
    curve_mean,
    demo_provenance,
    figure_frames,
)

CURVES_COLUMNS = ["init", "update", "rollouts", "mean", "sem", "touch_rate"]


def curve_rows(curves: dict[str, np.ndarray], stats: dict[str, np.ndarray]) -> list[list[object]]:
    """curves.csv's rows (`CURVES_COLUMNS`): each init's `curve_stats` rows and the mean
    over seeds of the update's `touch_rate` (nan at update 0)."""
    return [[init, int(u), int(r), m, s, curve_mean(curves[init], int(u), "touch_rate")]
            for init in INITS for u, r, m, s in stats[init]]  # fmt: skip


def summary_rows(
    runs: dict[str, SearchOutput],
    curves: dict[str, np.ndarray],
    success: dict[str, tuple[int, int, float]],
) -> list[list[str]]:
    """summary.csv's rows (`SUMMARY_COLUMNS`), one per init, from the runs, their
    learning curves and the final policies' `success_table`."""
    rows = []
    for init in INITS:
        run, curve = runs[init], curves[init]
        source, demos = demo_provenance(run)
        dmp = algorithm_of(run.cfg) == "pi2cma"
        baseline = run.cfg.baseline if init == "random" and dmp else None
        means = {
            "success_update_10": curve_mean(curve, 10, "success_rate"),
            "return_update_0": curve_mean(curve, 0, "normalised_return"),
            "return_update_50": curve_mean(curve, 50, "normalised_return"),
        }
        n, wins, _ = success[init]
        rows.append(summary_row(run.cfg.task.name, init, baseline, source, demos, means, wins / n))
    return rows


def figure_5_3(cfg: EvaluateBootstrapConfig, runs: dict[str, SearchOutput], path: Path) -> None:
    """fig5_3.png: `figure_frames` from the start of evaluation episode 0 (the reset seed
    `artic evaluate bootstrap` draws for it), each row captioned with its outcome."""
    start = cfg.episode_starts()[0]
    task = runs["bootstrap"].cfg.task
    rows = []
    for label, frames, traj in figure_frames(runs, start, cfg.figure.frames, cfg.video.camera):
        q = ", ".join(f"{v:.2f}" for v in traj.observations[-1, 7:])
        outcome = "success" if traj.success else "failure"
        rows.append((label, frames, f"object at {q} (goal {task.goal[0]:g}): {outcome}"))
    seconds = task.horizon * task.control_dt
    frame_strips(path, rows, f"{task.name}: frames over the {seconds:g} s episode (Figure 5.3)")
