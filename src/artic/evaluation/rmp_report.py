"""Chapter 6's figures as pure functions: Table 6.1 (obstacle episodes), the training
curves of Fig. 6.2 with the percent decrease of their integrals, and the targets of the
reproduction (issue 20), with the thesis' numbers beside ours; Fig. 6.2 and Fig. 6.4
drawn with matplotlib (Agg)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

CONTROLLERS = ("vices", "rmp_vices")
TABLE_COLUMNS = ["task", "controller", "reward_mean", "reward_std", "collisions",
                 "joint_limit_events", "episodes"]  # fmt: skip
EPISODE_COLUMNS = ["task", "controller", "seed", "episode", "reset_seed", "return", "steps",
                   "collision", "joint_limit", "success", "force"]  # fmt: skip
#: Table 6.1 of the thesis: (reward mean, reward s.d., collisions, joint-limit events)
#: per task and controller, 100 episodes each, Kinova Jaco 2 in robosuite
THESIS_TABLE = {
    ("traj", "vices"): (7864.0, 11670.0, 56, 44),
    ("door", "vices"): (1703.0, 1948.0, 61, 36),
    ("push", "vices"): (1755.0, 2256.0, 93, 0),
    ("traj", "rmp_vices"): (6847.0, 3723.0, 25, 22),
    ("door", "rmp_vices"): (1051.0, 696.0, 5, 11),
    ("push", "rmp_vices"): (1740.0, 854.0, 19, 0),
}
#: Fig. 6.2's percent decrease of the integrated (collision, joint-limit) curves
THESIS_DECREASE = {"traj": (math.nan, 90.5), "door": (39.8, 90.7), "push": (54.6, 93.2)}
#: issue 20's targets: largest collision ratio; reward ratio at least this
COLLISION_RATIO = 0.45
REWARD_RATIO = {"traj": 0.8, "door": 0.6, "push": 0.8}


def table_rows(episodes: Sequence[Sequence[Any]], tasks: Sequence[str]) -> list[list[Any]]:
    """Table 6.1 rows (`TABLE_COLUMNS`) from episode rows (`EPISODE_COLUMNS`)."""
    rows = []
    for task in tasks:
        for controller in CONTROLLERS:
            mine = [e for e in episodes if e[0] == task and e[1] == controller]
            if not mine:
                continue
            returns = np.array([float(e[5]) for e in mine])
            rows.append([task, controller, float(returns.mean()), float(returns.std()),
                         sum(int(e[7]) for e in mine), sum(int(e[8]) for e in mine),
                         len(mine)])  # fmt: skip
    return rows


def curve_stats(
    curve: Sequence[Sequence[str]], controller: str, column: int
) -> NDArray[np.float64]:
    """(epochs, 3) [epoch, mean, standard error over seeds] of a learning-curve column
    (train-rmp's `learning_curve.csv` rows without the header) for one controller."""
    mine = [r for r in curve if r[0] == controller]
    epochs = sorted({int(r[2]) for r in mine})
    out = []
    for e in epochs:
        values = np.array([float(r[column]) for r in mine if int(r[2]) == e])
        values = values[np.isfinite(values)]
        mean = float(values.mean()) if len(values) else math.nan
        sem = float(values.std(ddof=1) / np.sqrt(len(values))) if len(values) > 1 else 0.0
        out.append([e, mean, sem])
    return np.array(out, dtype=np.float64).reshape(-1, 3)


def percent_decrease(vices: NDArray[np.float64], rmp: NDArray[np.float64]) -> float:
    """100 (1 - integral(rmp) / integral(vices)) of two mean curves over epochs (the
    trapezoid rule); nan when VICES' integral is 0 (the thesis' "N/A")."""
    a = (
        float(np.trapezoid(vices[:, 1], vices[:, 0]))
        if len(vices) > 1
        else float(vices[:, 1].sum())
    )
    b = float(np.trapezoid(rmp[:, 1], rmp[:, 0])) if len(rmp) > 1 else float(rmp[:, 1].sum())
    return 100.0 * (1.0 - b / a) if a > 0 else math.nan


def verdict(
    table: Sequence[Sequence[Any]],
    decreases: dict[str, tuple[float, float]],
    medians: dict[tuple[str, str], float] | None = None,
) -> list[str]:
    """One line per target of issue 20 that the numbers allow to check: PASS or FAIL
    (n/a where a controller had no event to compare). `medians`: the median collision
    force (N) of each (task, controller) over the obstacle episodes (Fig. 6.4)."""
    medians = medians or {}
    by = {(r[0], r[1]): r for r in table}
    lines = []
    for task in sorted({r[0] for r in table}):
        if (task, "vices") not in by or (task, "rmp_vices") not in by:
            continue
        v, r = by[(task, "vices")], by[(task, "rmp_vices")]
        ok = r[4] <= COLLISION_RATIO * v[4] if v[4] else r[4] == 0
        lines.append(f"- {task}: collisions {r[4]} <= {COLLISION_RATIO} x {v[4]}: "
                     f"{'PASS' if ok else 'FAIL'}")  # fmt: skip
        ok = r[5] <= 0.5 * v[5] if v[5] >= 10 else r[5] <= v[5]
        lines.append(f"- {task}: joint-limit events {r[5]} vs {v[5]} (at most 0.5x from 10, "
                     f"never more): {'PASS' if ok else 'FAIL'}")  # fmt: skip
        ratio = REWARD_RATIO.get(task, 0.8)
        ok = r[2] >= ratio * v[2] if v[2] > 0 else r[2] >= v[2]
        lines.append(f"- {task}: mean reward {r[2]:.1f} >= {ratio} x {v[2]:.1f}: "
                     f"{'PASS' if ok else 'FAIL'}")  # fmt: skip
        collisions, joints = decreases.get(task, (math.nan, math.nan))
        lines.append(f"- {task}: integrated joint-limit events down {_num(joints)}% (>= 50%): "
                     f"{_mark(joints >= 50.0, joints)}")  # fmt: skip
        if task in ("door", "push"):
            lines.append(f"- {task}: integrated collisions down ({_num(collisions)}%): "
                         f"{_mark(collisions > 0, collisions)}")  # fmt: skip
        force_v = medians.get((task, "vices"), math.nan)
        force_r = medians.get((task, "rmp_vices"), math.nan)
        mark = (
            ("PASS" if force_r <= force_v else "FAIL")
            if math.isfinite(force_r) and math.isfinite(force_v)
            else "n/a (a controller without collisions)"
        )
        lines.append(f"- {task}: median collision force {_num(force_r)} N <= "
                     f"{_num(force_v)} N: {mark}")  # fmt: skip
    return lines


def _mark(ok: bool, value: float) -> str:
    """PASS / FAIL, or n/a when VICES had no event to decrease from."""
    return "n/a (no VICES events)" if not math.isfinite(value) else ("PASS" if ok else "FAIL")


def _num(x: float) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:.1f}"


def report_markdown(table: Sequence[Sequence[Any]], decreases: dict[str, tuple[float, float]],
                    medians: dict[tuple[str, str], float], sources: dict[str, str],
                    best: dict[tuple[str, str], int]) -> str:  # fmt: skip
    """`table_6_1.md`: Table 6.1 with the thesis beside, Fig. 6.2's decreases, the
    median collision forces of Fig. 6.4 and the targets."""
    lines = ["# Chapter 6: Table 6.1, Fig. 6.2, Fig. 6.4 (artic evaluate rmp)", "",
             "Episodes with two random spheres (r = 5 cm); the best seed of each task and "
             "controller (highest mean return over its last epochs).", "",
             "| task | controller | seed | reward (artic) | coll. | jnt lim. | episodes "
             "| reward (thesis) | coll. | jnt lim. |",
             "|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in table:
        t = THESIS_TABLE.get((r[0], r[1]), (math.nan, math.nan, 0, 0))
        lines.append(f"| {r[0]} | {r[1]} | {best.get((r[0], r[1]), '')} | {r[2]:.1f} +- "
                     f"{r[3]:.1f} | {r[4]} | {r[5]} | {r[6]} | {t[0]:.0f} +- {t[1]:.0f} | "
                     f"{t[2]} | {t[3]} |")  # fmt: skip
    lines += ["", "Fig. 6.2: decrease of the integrated mean training curves, RMP-VICES vs "
              "VICES (percent; thesis beside).", "",
              "| task | collisions (artic) | joint limits (artic) | collisions (thesis) | "
              "joint limits (thesis) |", "|---|---|---|---|---|"]  # fmt: skip
    for task, (c, j) in decreases.items():
        tc, tj = THESIS_DECREASE.get(task, (math.nan, math.nan))
        lines.append(f"| {task} | {_num(c)} | {_num(j)} | {_num(tc)} | {_num(tj)} |")
    lines += [
        "",
        "Fig. 6.4: median collision force (N), evaluation episodes.",
        "",
        "| task | VICES | RMP-VICES |",
        "|---|---|---|",
    ]
    for task in decreases:
        med_v = medians.get((task, "vices"), math.nan)
        med_r = medians.get((task, "rmp_vices"), math.nan)
        lines.append(f"| {task} | {_num(med_v)} | {_num(med_r)} |")
    lines += ["", "Targets (issue 20):", "", *verdict(table, decreases, medians), "", "Inputs:", ""]
    lines += [f"- {task}: {path}" for task, path in sources.items()]
    return "\n".join(lines) + "\n"


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


LABELS = {"vices": "VICES", "rmp_vices": "RMP-VICES"}
CURVES = (("return_mean", 5, "average return"), ("collisions", 7, "collisions"),
          ("joint_limit_events", 8, "joint-limit events"))  # fmt: skip


def training_curves(
    path: Path, curves: dict[str, dict[tuple[str, int], NDArray[np.float64]]]
) -> None:
    """Fig. 6.2: per task (rows) return, collisions and joint-limit events per epoch
    (columns), mean and standard error over seeds for each controller."""
    plt = _pyplot()
    tasks = list(curves)
    fig, axes = plt.subplots(len(tasks), 3, figsize=(12, 3.2 * len(tasks)), squeeze=False)
    for i, task in enumerate(tasks):
        for j, (_, column, label) in enumerate(CURVES):
            ax = axes[i][j]
            for controller in CONTROLLERS:
                s = curves[task].get((controller, column))
                if s is None or not len(s):
                    continue
                ax.plot(s[:, 0], s[:, 1], label=LABELS[controller])
                ax.fill_between(s[:, 0], s[:, 1] - s[:, 2], s[:, 1] + s[:, 2], alpha=0.25)
            ax.set_title(f"{task}: {label}")
            ax.set_xlabel("epoch")
            if i == 0 and j == 0:
                ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)


def force_histograms(path: Path, forces: dict[str, dict[str, list[float]]]) -> None:
    """Fig. 6.4: histograms of collision forces (N) per panel (training of each task,
    then the obstacle episodes of each task), both controllers overlaid."""
    plt = _pyplot()
    panels = list(forces)
    fig, axes = plt.subplots(1, max(len(panels), 1), figsize=(3.6 * max(len(panels), 1), 3),
                             squeeze=False)  # fmt: skip
    for ax, panel in zip(axes[0], panels, strict=False):
        values = [v for vs in forces[panel].values() for v in vs if math.isfinite(v)]
        top = max(values) if values else 1.0
        bins = np.linspace(0.0, max(top, 1e-6), 20)
        for controller in CONTROLLERS:
            data = [v for v in forces[panel].get(controller, []) if math.isfinite(v)]
            ax.hist(data, bins=bins, alpha=0.5, label=f"{LABELS[controller]} ({len(data)})")
        ax.set_title(panel)
        ax.set_xlabel("collision force, N")
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)


class RmpReport(NamedTuple):
    """Everything `artic evaluate rmp` writes besides the episodes: Table 6.1 rows, Fig.
    6.2's per-epoch statistics (`curves[task][(controller, column)]`, (epochs, 3)) and
    their rows, the integrated decreases (collisions, joint limits) per task, the
    collision forces of Fig. 6.4's panels and the median obstacle-episode forces."""

    table: list[list[Any]]
    curves: dict[str, dict[tuple[str, int], NDArray[np.float64]]]
    curve_rows: list[list[Any]]
    decreases: dict[str, tuple[float, float]]
    forces: dict[str, dict[str, list[float]]]
    medians: dict[tuple[str, str], float]


def summarise(
    tasks: Sequence[str],
    training_curves: dict[str, list[list[str]]],
    training_forces: dict[str, list[list[str]]],
    episodes: Sequence[Sequence[Any]],
) -> RmpReport:
    """The report of `tasks` from each task's train-rmp `learning_curve.csv` and
    `forces.csv` rows (no header) and the obstacle episodes (`EPISODE_COLUMNS` rows)."""
    curves: dict[str, dict[tuple[str, int], NDArray[np.float64]]] = {}
    rows: list[list[Any]] = []
    decreases: dict[str, tuple[float, float]] = {}
    forces: dict[str, dict[str, list[float]]] = {}
    medians: dict[tuple[str, str], float] = {}
    for task in tasks:
        by: dict[tuple[str, int], NDArray[np.float64]] = {}
        for name, column, _ in CURVES:
            for controller in CONTROLLERS:
                stats = curve_stats(training_curves[task], controller, column)
                by[(controller, column)] = stats
                rows += [[task, controller, name, int(e), m, s] for e, m, s in stats]
        curves[task] = by
        decreases[task] = (
            percent_decrease(by[("vices", 7)], by[("rmp_vices", 7)]),
            percent_decrease(by[("vices", 8)], by[("rmp_vices", 8)]),
        )
        train = training_forces[task]
        forces[f"{task}: training"] = {
            c: [float(r[3]) for r in train if r[0] == c] for c in CONTROLLERS
        }
    for task in tasks:
        panel: dict[str, list[float]] = {}
        for controller in CONTROLLERS:
            values = [float(e[10]) for e in episodes if e[0] == task and e[1] == controller]
            panel[controller] = [v for v in values if math.isfinite(v)]
            medians[(task, controller)] = (
                float(np.median(panel[controller])) if panel[controller] else math.nan
            )
        forces[f"{task}: obstacles"] = panel
    return RmpReport(table_rows(episodes, tasks), curves, rows, decreases, forces, medians)
