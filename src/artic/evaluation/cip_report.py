"""Chapter 7's figures as pure functions (thesis section 7.4, issue 21): the success table
of Fig. 7.3 and 7.4 from train-cip's learning curves, the episodes to 80% success, the
targets of the reproduction and `table.md`; Fig. 7.3 and 7.4 drawn with matplotlib (Agg).

Statistics over seeds: the mean, and the standard error = sample standard deviation
(ddof 1) / sqrt(n), 0 for a single seed. The 4-task mean (task `mean`, only when all
four tasks are present): per seed index, the mean over the tasks of that run's value
(run i of every task has the same seed), then the mean and standard error over seeds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

TASKS = ("door", "drawer", "slide", "lever")
SETTINGS = ("e2e", "head", "safety", "mv", "cip", "cip_bc", "e2e_bc")
LABELS = {"e2e": "E2E", "head": "Head", "safety": "Safety", "mv": "MV", "cip": "CIP",
          "cip_bc": "CIP+BC", "e2e_bc": "E2E+BC"}  # fmt: skip
SUCCESS_COLUMNS = ["scale", "task", "setting", "episode", "success_best_mean",
                   "success_best_se", "violation_rate"]  # fmt: skip
MEAN = "mean"
#: the level of "episodes to 80%"
LEVEL = 0.8
#: order targets: a tie within this many (fraction) points counts as met
TIE = 0.1
TABLE_EPISODES = (50, 120, 500)


def mean_se(values: Sequence[float]) -> tuple[float, float]:
    """Mean and standard error (sample s.d. / sqrt(n); 0 for one value) of `values`."""
    a = np.asarray(values, dtype=np.float64)
    if not len(a):
        return math.nan, 0.0
    se = float(a.std(ddof=1) / math.sqrt(len(a))) if len(a) > 1 else 0.0
    return float(a.mean()), se


def _ordered(keys: Sequence[str], order: Sequence[str]) -> list[str]:
    return [k for k in order if k in keys] + sorted(k for k in set(keys) if k not in order)


def success_rows(
    scales: dict[str, str], curves: dict[str, Sequence[Sequence[str]]]
) -> list[list[Any]]:
    """`SUCCESS_COLUMNS` rows from each task's train-cip `learning_curve.csv` rows (no
    header: setting, seed, episode, success, success_best, violation_rate, ...) and its
    scale (the experiment preset); the 4-task mean's rows when all four tasks are in."""
    # (task, setting, episode) -> seed -> (success_best, violation_rate)
    points: dict[tuple[str, str, int], dict[int, tuple[float, float]]] = {}
    for task, curve in curves.items():
        for r in curve:
            key = (task, r[0], int(r[2]))
            points.setdefault(key, {})[int(r[1])] = (float(r[4]), float(r[5]))
    rows: list[list[Any]] = []
    tasks = _ordered(list(curves), TASKS)
    settings = _ordered([k[1] for k in points], SETTINGS)
    for task in tasks:
        for setting in settings:
            for e in sorted(k[2] for k in points if k[:2] == (task, setting)):
                seeds = points[(task, setting, e)]
                m, se = mean_se([v[0] for v in seeds.values()])
                rows.append([scales[task], task, setting, e, m, se,
                             mean_se([v[1] for v in seeds.values()])[0]])  # fmt: skip
    if not all(t in curves for t in TASKS):
        return rows
    scale = "/".join(sorted({scales[t] for t in TASKS}))
    for setting in settings:
        episodes = [sorted(k[2] for k in points if k[:2] == (t, setting)) for t in TASKS]
        for e in sorted(set(episodes[0]).intersection(*episodes[1:])):
            by_task = [points[(t, setting, e)] for t in TASKS]
            common = sorted(set(by_task[0]).intersection(*by_task[1:]))
            if not common:
                continue
            success = [float(np.mean([b[s][0] for b in by_task])) for s in common]
            violation = [float(np.mean([b[s][1] for b in by_task])) for s in common]
            m, se = mean_se(success)
            rows.append([scale, MEAN, setting, e, m, se, mean_se(violation)[0]])
    return rows


def value_at(rows: Sequence[Sequence[Any]], task: str, setting: str, episode: int,
             column: int = 4) -> float | None:  # fmt: skip
    """`column` of the row (task, setting, episode); None when there is none."""
    for r in rows:
        if r[1] == task and r[2] == setting and int(r[3]) == episode:
            return float(r[column])
    return None


def episodes_to(rows: Sequence[Sequence[Any]], task: str, setting: str,
                level: float = LEVEL) -> int | None:  # fmt: skip
    """The first evaluation point where success_best_mean >= `level`; None if never."""
    hits = [int(r[3]) for r in rows if r[1] == task and r[2] == setting and float(r[4]) >= level]
    return min(hits) if hits else None


def last_episode(rows: Sequence[Sequence[Any]]) -> int:
    """The last evaluation point common to every (task, setting) of `rows` (0: none)."""
    ends: dict[tuple[str, str], int] = {}
    for r in rows:
        ends[(r[1], r[2])] = max(ends.get((r[1], r[2]), 0), int(r[3]))
    return min(ends.values(), default=0)


def _mark(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def _pct(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{100 * x:.0f}%"


def _mean_target(rows: Sequence[Sequence[Any]], setting: str, episode: int, level: float,
                 text: str, every: float | None = None) -> str:  # fmt: skip
    """`text`: the 4-task mean of `setting` >= `level` at `episode` (and every task >=
    `every`)."""
    mean = value_at(rows, MEAN, setting, episode)
    if mean is None:
        return f"- {text}: n/a (needs all four tasks at episode {episode})"
    ok, parts = mean >= level, [f"mean {_pct(mean)}"]
    if every is not None:
        tasks = [(t, value_at(rows, t, setting, episode)) for t in TASKS]
        ok = ok and all(v is not None and v >= every for _, v in tasks)
        parts += [f"{t} {_pct(v)}" for t, v in tasks]
    return f"- {text}: {', '.join(parts)}: {_mark(ok)}"


def _every_task_at_most(rows: Sequence[Sequence[Any]], setting: str, episode: int,
                        level: float, text: str) -> str:  # fmt: skip
    found = [(t, value_at(rows, t, setting, episode)) for t in TASKS]
    tasks = [(t, v) for t, v in found if v is not None]
    if not tasks:
        return f"- {text}: n/a (no {LABELS[setting]} run at episode {episode})"
    ok = all(v <= level for _, v in tasks)
    return f"- {text}: {', '.join(f'{t} {_pct(v)}' for t, v in tasks)}: {_mark(ok)}"


def order_targets(rows: Sequence[Sequence[Any]], episode: int) -> list[str]:
    """The order on the 4-task mean at `episode`: CIP+BC >= CIP >= MV >= Head, Safety
    within 10 points of Head, CIP+BC > E2E+BC; a shortfall within `TIE` counts as met."""
    pairs = [("cip_bc", "cip", ">="), ("cip", "mv", ">="), ("mv", "head", ">="),
             ("safety", "head", "within 10 points of"), ("cip_bc", "e2e_bc", ">")]  # fmt: skip
    lines = []
    for a, b, op in pairs:
        va, vb = value_at(rows, MEAN, a, episode), value_at(rows, MEAN, b, episode)
        text = f"- 4-task mean at episode {episode}: {LABELS[a]} {op} {LABELS[b]}"
        if va is None or vb is None:
            lines.append(f"{text}: n/a (needs both settings on all four tasks)")
            continue
        within = op.startswith("within")
        ok = abs(va - vb) <= TIE if within else va >= vb - TIE
        tie = "" if within else ", ties within 10 points met"
        lines.append(f"{text} ({_pct(va)} vs {_pct(vb)}{tie}): {_mark(ok)}")
    return lines


def _mean_violation(rows: Sequence[Sequence[Any]], setting: str, until: int) -> float | None:
    values = [float(r[6]) for r in rows if r[1] == MEAN and r[2] == setting and int(r[3]) <= until]
    return float(np.mean(values)) if values else None


def targets(rows: Sequence[Sequence[Any]]) -> list[str]:
    """One line per target of issue 21, PASS or FAIL, or n/a when the runs cannot tell
    (a task missing, or the runs end before the target's episode). CPU targets by
    episode 120, paper ones by 500 (only when the runs reach 500)."""
    end = last_episode(rows)
    lines = ["CPU scale (issue 21):", ""]
    if end < 120:
        lines.append(f"- by episode 120: n/a (the runs end at episode {end})")
    else:
        lines += [
            _mean_target(rows, "cip_bc", 120, 0.8,
                         "CIP+BC >= 80% mean and >= 70% every task by episode 120", 0.7),
            _mean_target(rows, "cip", 120, 0.6, "CIP >= 60% mean by episode 120"),
        ]  # fmt: skip
    if end:
        text = f"E2E <= 10% every task (last episode, {end})"
        lines.append(_every_task_at_most(rows, "e2e", end, 0.1, text))
        lines += order_targets(rows, end)
    lines += ["", "Paper scale (thesis, 10 seeds x 500 episodes):", ""]
    if end < 500:
        return [*lines, f"- by episode 500: n/a (the runs end at episode {end})"]
    lines += [
        _mean_target(rows, "cip", 500, 0.8, "CIP >= 80% mean by episode 500"),
        _mean_target(rows, "cip_bc", 50, 0.8, "CIP+BC >= 80% mean by episode 50"),
        _every_task_at_most(rows, "e2e", 500, 0.1, "E2E <= 10% every task (episode 500)"),
    ]
    safety, head = _mean_violation(rows, "safety", 500), _mean_violation(rows, "head", 500)
    text = "Safety's violation rate <= 0.5 x Head's (4-task mean over evaluations to 500)"
    if safety is None or head is None:
        return [*lines, f"- {text}: n/a (needs both settings on all four tasks)"]
    ok = safety <= 0.5 * head
    return [*lines, f"- {text}: {safety:.3f} vs {head:.3f}: {_mark(ok)}"]


def report_markdown(rows: Sequence[Sequence[Any]], sources: dict[str, str]) -> str:
    """`table.md`: best-to-date success at episodes 50, 120, 500 (those present) and
    the last, episodes to 80%, the targets and the inputs."""
    tasks = _ordered(list({r[1] for r in rows}), (*TASKS, MEAN))
    settings = _ordered(list({r[2] for r in rows}), SETTINGS)
    present = {int(r[3]) for r in rows}
    end = last_episode(rows)
    episodes = [e for e in TABLE_EPISODES if e in present and e <= end]
    episodes += [end] if end and end not in episodes else []
    head = f"| setting | {' | '.join(tasks)} |"
    rule = "|---" * (len(tasks) + 1) + "|"
    lines = ["# Chapter 7: Fig. 7.3 and 7.4 (artic evaluate cip)", "",
             "Best-to-date success of the deterministic evaluations, mean +- s.e. over "
             "seeds (`success.csv`).", ""]  # fmt: skip
    for e in episodes:
        lines += [f"Best-to-date success at episode {e}:", "", head, rule]
        for s in settings:
            cells = []
            for t in tasks:
                m, se = value_at(rows, t, s, e), value_at(rows, t, s, e, 5)
                cells.append("-" if m is None else f"{_pct(m)} +- {_pct(se)}")
            lines.append(f"| {LABELS.get(s, s)} | {' | '.join(cells)} |")
        lines.append("")
    lines += ["Episodes to 80% (first evaluation with best-to-date mean >= 80%; - never):",
              "", head, rule]  # fmt: skip
    for s in settings:
        cells = [str(episodes_to(rows, t, s) or "-") for t in tasks]
        lines.append(f"| {LABELS.get(s, s)} | {' | '.join(cells)} |")
    lines += ["", "Targets:", "", *targets(rows), "", "Inputs:", ""]
    lines += [f"- {task}: {path}" for task, path in sources.items()]
    return "\n".join(lines) + "\n"


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def curve_figure(path: Path, rows: Sequence[Sequence[Any]], column: int, label: str) -> None:
    """Fig. 7.3 (`column` 4: best-to-date success, mean +- s.e. shaded) or Fig. 7.4
    (`column` 6: violation rate): one panel per task (and the mean), one line per
    setting, against training episodes."""
    plt = _pyplot()
    tasks = _ordered(list({r[1] for r in rows}), (*TASKS, MEAN))
    settings = _ordered(list({r[2] for r in rows}), SETTINGS)
    n = max(len(tasks), 1)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 3.2), squeeze=False)
    for ax, task in zip(axes[0], tasks, strict=False):
        for s in settings:
            mine = sorted((int(r[3]), float(r[column]), float(r[5])) for r in rows
                          if r[1] == task and r[2] == s)  # fmt: skip
            if not mine:
                continue
            a = np.array(mine)
            ax.plot(a[:, 0], a[:, 1], label=LABELS.get(s, s))
            if column == 4:
                ax.fill_between(a[:, 0], a[:, 1] - a[:, 2], a[:, 1] + a[:, 2], alpha=0.2)
        ax.set_title(task)
        ax.set_xlabel("training episode")
        ax.set_ylabel(label)
        ax.set_ylim(-0.05, 1.05)
    if tasks:
        axes[0][0].legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)
