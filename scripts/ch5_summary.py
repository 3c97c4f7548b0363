"""Collect `artic evaluate bootstrap` reports into docs/results/ch5/summary.csv (issue 23).

    python scripts/ch5_summary.py R/drawer R/drawer_centred R/drawer_noisy ... \
        --out docs/results/ch5/summary.csv

Each argument is an evaluate-bootstrap output folder; its `summary.csv` has one row per
init in the columns below (`artic.evaluation.bootstrap_report.SUMMARY_COLUMNS`: task,
init, baseline, model_source, demo_success, success_update_10, final_success,
return_update_0, return_update_50). A row that two reports share (the same bootstrapped
run evaluated against two random baselines) is written once; two different rows for the
same (task, init, baseline, model_source) are an error. Rows are sorted by task, init
(bootstrap first), model source (true, noisy, predicted) and baseline (exploring first).
With `--plot PNG`, the bootstrapped curves of every report, one panel per task, one line
per kinematic model source (the random ones in grey), side by side.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from artic.evaluation.bootstrap_report import INITS, SUMMARY_COLUMNS

SOURCES = ["true", "noisy", "predicted", ""]
BASELINES = ["", "exploring", "centred"]


def collect(reports: list[Path]) -> list[dict[str, str]]:
    """The distinct summary rows of `reports`, sorted (see the module docstring)."""
    rows: dict[tuple[str, ...], dict[str, str]] = {}
    for folder in reports:
        with (folder / "summary.csv").open(newline="") as f:
            reader = csv.DictReader(f)
            if reader.fieldnames != SUMMARY_COLUMNS:
                raise SystemExit(f"{folder / 'summary.csv'}: columns {reader.fieldnames}")
            for row in reader:
                key = (row["task"], row["init"], row["baseline"], row["model_source"])
                if key in rows and rows[key] != row:
                    raise SystemExit(f"{folder}: a second, different row for {key}")
                rows[key] = row
    return sorted(rows.values(), key=lambda r: (
        r["task"], INITS.index(r["init"]), SOURCES.index(r["model_source"]),
        BASELINES.index(r["baseline"]),
    ))  # fmt: skip


def plot(reports: list[Path], path: Path) -> None:
    """One panel per task: each report's curves.csv, bootstrapped per model source, random
    per baseline (grey), mean normalised return over seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lines: dict[str, dict[str, list[tuple[int, float]]]] = {}
    for folder in reports:
        with (folder / "summary.csv").open(newline="") as f:
            rows = {r["init"]: r for r in csv.DictReader(f)}
        with (folder / "curves.csv").open(newline="") as f:
            curves = list(csv.DictReader(f))
        for init, row in rows.items():
            name = (f"bootstrapped, {row['model_source']} model" if init == "bootstrap"
                    else f"random, {row['baseline'] or 'MLP'}")  # fmt: skip
            points = [(int(c["update"]), float(c["mean"])) for c in curves if c["init"] == init]
            lines.setdefault(row["task"], {})[name] = points
    tasks = sorted(lines)
    fig, axes = plt.subplots(1, len(tasks), figsize=(4.6 * len(tasks), 3.6), squeeze=False)
    for ax, task in zip(axes[0], tasks, strict=True):
        for name, points in sorted(lines[task].items()):
            u, m = zip(*points, strict=True)
            grey = name.startswith("random")
            colour = next((f"C{i}" for i, m in enumerate(SOURCES[:3]) if f", {m} " in name), "0.6")
            style = {"color": "0.6", "lw": 1.2} if grey else {"color": colour, "lw": 1.8}
            ax.plot(u, m, label=name, ls="--" if "centred" in name else "-", **style)
        ax.set_title(task, fontsize=10)
        ax.set_xlabel("policy update")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    axes[0, 0].set_ylabel("normalised return (mean over seeds)")
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=100, metadata={"Software": None})
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reports", nargs="+", type=Path, help="evaluate-bootstrap outputs")
    parser.add_argument("--out", type=Path, required=True, help="summary.csv to write")
    parser.add_argument("--plot", type=Path, help="also draw every report's curves here")
    args = parser.parse_args()
    rows = collect(args.reports)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    sys.stderr.write(f"{args.out}: {len(rows)} rows\n")
    if args.plot is not None:
        plot(args.reports, args.plot)


if __name__ == "__main__":
    main()
