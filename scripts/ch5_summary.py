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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reports", nargs="+", type=Path, help="evaluate-bootstrap outputs")
    parser.add_argument("--out", type=Path, required=True, help="summary.csv to write")
    args = parser.parse_args()
    rows = collect(args.reports)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    sys.stderr.write(f"{args.out}: {len(rows)} rows\n")


if __name__ == "__main__":
    main()
