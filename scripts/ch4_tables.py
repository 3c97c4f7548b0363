"""Collect `artic evaluate hierarchy` outputs into docs/results/ch4/tables.csv (issue 18).

    python scripts/ch4_tables.py --category storage_furniture \
        --withheld R/withheld --withheld-yaw R/withheld_yaw \
        --independent R/independent --independent-yaw R/independent_yaw \
        --out docs/results/ch4/tables.csv

Each argument is an evaluate-hierarchy output folder (its summary.csv); the `*-yaw` ones
were run with `evaluate.yaw=random`, whose noisy rows become scans `noisy_yaw`. Columns
(other tools read them): category, data (withheld | independent), scans (clean | noisy |
noisy_yaw), parts (ground_truth | predicted), map50 (the segmenter's mAP@0.5, on the
predicted-parts rows; empty where it does not apply), tree_f1. Rows of an existing file
are kept but those of this category's (data, scans) pairs the given folders hold, which
they replace; rows in the order category, data, scans, parts.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

COLUMNS = ["category", "data", "scans", "parts", "map50", "tree_f1"]
PARTS = {"gt": "ground_truth", "pred": "predicted"}
DATA = ("withheld", "independent")
SCANS = ("clean", "noisy", "noisy_yaw")


def rows_of(folder: Path, category: str, data: str, turned: bool) -> list[dict[str, str]]:
    """The tables.csv rows of one evaluate-hierarchy output folder."""
    with (folder / "summary.csv").open() as f:
        summary = list(csv.DictReader(f))
    rows = []
    for r in summary:
        scans = "noisy_yaw" if turned and r["kind"] == "noisy" else r["kind"]
        if turned and r["kind"] != "noisy":
            continue
        parts = PARTS[r["segmentation"]]
        rows.append({
            "category": category, "data": data, "scans": scans, "parts": parts,
            "map50": f"{float(r['map']):.3f}" if parts == "predicted" else "",
            "tree_f1": f"{float(r['tree_f1']):.2f}",
        })  # fmt: skip
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--category", required=True)
    for name in ("withheld", "withheld-yaw", "independent", "independent-yaw"):
        parser.add_argument(f"--{name}", type=Path)
    parser.add_argument("--out", type=Path, default=Path("docs/results/ch4/tables.csv"))
    args = parser.parse_args(argv)
    new: list[dict[str, str]] = []
    for data in DATA:
        for turned in (False, True):
            folder = getattr(args, data + ("_yaw" if turned else ""))
            if folder is not None:
                new += rows_of(folder, args.category, data, turned)
    replaced = {(r["category"], r["data"], r["scans"]) for r in new}
    rows: list[dict[str, str]] = []
    if args.out.is_file():
        with args.out.open() as f:
            rows = [r for r in csv.DictReader(f)
                    if (r["category"], r["data"], r["scans"]) not in replaced]  # fmt: skip
    rows = sorted(rows + new, key=lambda r: (r["category"], DATA.index(r["data"]),
                                            SCANS.index(r["scans"]), r["parts"]))  # fmt: skip
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    print(f"{len(rows)} rows -> {args.out}")  # noqa: T201


if __name__ == "__main__":
    main()
