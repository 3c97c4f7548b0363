"""Collect `artic evaluate mdn` reports into docs/results/ch3/table_3_1.csv (issue 19).

    python scripts/ch3_table.py R/cabinet R/cabinet_grid R/drawer B/drawer ... \
        --out docs/results/ch3/table_3_1.csv

Each argument is an evaluate-mdn output folder or a bench/independent_mdn_objects.py
output folder (below). An evaluate-mdn folder's rows, in the issue's columns
(`COLUMNS`): the category (the report's category name), the data (`continuous` or
`thesis_grid`: the `render.sampling` of the depth folder the report evaluated, read from
that folder's manifest), the estimator (Mean -> mean, NN -> nn, ICP -> icp, Ours ->
network, Ours + refinement -> refined; "Ours (densest)" is not a column of Table 3.1),
the mean errors (configuration in deg, the drawer's in cm) and, for the network and the
refined estimate, the coverage of their 90% intervals over all predicted columns
(`calibration.csv`, `calibration_refined.csv`; none for a report without the latter).
Rows already in `--out` for other (category, data) pairs are kept; a report replaces the
rows of its own pair.

A bench/independent_mdn_objects.py folder (its `objects.jsonl` tells it apart) gives one
row of data `independent`: the estimator its summary names (network with `--no-refine`,
else refined), the means over its errors.csv's images (both hinge sides; the rotation in
the thesis' metric as `kinematic_errors` computes it; the hinge side wrong on the share
of images not `hinge_side_right`), no coverage (the bench forms no intervals). It
replaces that one (category, independent, estimator) row. Rows are sorted by category,
data and estimator.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from artic.artifacts.manifest import input_folder, read_manifest

COLUMNS = [
    "category", "data", "estimator", "axis_position_cm", "configuration",
    "rotation_thesis_deg", "yaw_deg", "hinge_side_wrong_pct", "coverage_90_pct",
]  # fmt: skip
ESTIMATORS = {"Mean": "mean", "NN": "nn", "ICP": "icp", "Ours": "network",
              "Ours + refinement": "refined"}  # fmt: skip
ORDER = ["mean", "nn", "icp", "network", "refined"]
CATEGORIES = ["cabinet", "drawer", "microwave", "toaster", "cabinet2", "refrigerator"]
DATA = ["continuous", "thesis_grid", "independent"]


def report_rows(folder: Path) -> list[dict[str, str]]:
    """The Table 3.1 rows of one evaluate-mdn or bench output folder (module docstring)."""
    if (folder / "objects.jsonl").is_file():
        return [bench_row(folder)]
    manifest = read_manifest(folder, expected_stage="evaluate-mdn")
    category = str(manifest.config["category"]["name"])
    depth = read_manifest(input_folder(folder, manifest, "depth"), expected_stage="render-depth")
    data = str(depth.config["render"].get("sampling", "continuous"))
    coverage = {"network": _coverage(folder / "calibration.csv"),
                "refined": _coverage(folder / "calibration_refined.csv")}  # fmt: skip
    rows = []
    with (folder / "summary.csv").open(newline="") as f:
        for r in csv.DictReader(f):
            if r["method"] not in ESTIMATORS:
                continue
            estimator = ESTIMATORS[r["method"]]
            rows.append({
                "category": category, "data": data, "estimator": estimator,
                "axis_position_cm": _round(r["position_cm_mean"]),
                "configuration": _round(r["configuration_mean"]),
                "rotation_thesis_deg": _round(r["rotation_thesis_deg_mean"]),
                "yaw_deg": _round(r["rotation_deg_mean"]),
                "hinge_side_wrong_pct": _round(r["hinge_side_wrong_pct_mean"]),
                "coverage_90_pct": (
                    f"{100 * coverage[estimator][0.9]:.1f}" if 0.9 in coverage.get(estimator, {})
                    else ""
                ),
            })  # fmt: skip
    return rows


def bench_row(folder: Path) -> dict[str, str]:
    """The `independent` row of one bench/independent_mdn_objects.py output folder."""
    with (folder / "summary.csv").open(newline="") as f:
        summary = list(csv.DictReader(f))
    with (folder / "errors.csv").open(newline="") as f:
        errors = list(csv.DictReader(f))
    if not summary or not errors:
        raise SystemExit(f"{folder}: an empty bench output")

    def mean(column: str) -> str:
        return f"{sum(float(r[column]) for r in errors) / len(errors):.2f}"

    wrong = 100.0 * sum(r["hinge_side_right"] == "0" for r in errors) / len(errors)
    return {
        "category": summary[0]["category"], "data": "independent",
        "estimator": ESTIMATORS[summary[0]["estimator"]],
        "axis_position_cm": mean("axis_position_cm"),
        "configuration": mean("configuration_deg"),
        "rotation_thesis_deg": mean("rotation_thesis_deg"),
        "yaw_deg": mean("yaw_deg"), "hinge_side_wrong_pct": f"{wrong:.2f}",
        "coverage_90_pct": "",
    }  # fmt: skip


def _coverage(path: Path) -> dict[float, float]:
    """nominal level -> coverage over all predicted columns, of a calibration csv (none
    when the file is absent: a report from before the refined intervals)."""
    if not path.exists():
        return {}
    with path.open(newline="") as f:
        return {float(r["nominal"]): float(r["all predicted columns"]) for r in csv.DictReader(f)}


def _round(value: str) -> str:
    return f"{float(value):.2f}"


def _key(row: dict[str, str]) -> tuple[int, int, int]:
    return (
        CATEGORIES.index(row["category"]) if row["category"] in CATEGORIES else len(CATEGORIES),
        DATA.index(row["data"]),
        ORDER.index(row["estimator"]),
    )


def merge(existing: list[dict[str, str]], reports: list[Path]) -> list[dict[str, str]]:
    """`existing` rows with each report's (category, data) pair replaced by its rows (a
    bench folder's: its one (category, data, estimator) row)."""
    new: list[dict[str, str]] = []
    for folder in reports:
        new += report_rows(folder)
    cells = {(r["category"], r["data"], r["estimator"]) for r in new}
    if len(cells) != len(new):
        raise SystemExit("two reports evaluate the same category on the same data")
    pairs = {(r["category"], r["data"]) for r in new if r["data"] != "independent"}

    def replaced(r: dict[str, str]) -> bool:
        return (r["category"], r["data"]) in pairs or (
            r["category"], r["data"], r["estimator"]) in cells  # fmt: skip

    kept = [r for r in existing if not replaced(r)]
    return sorted(kept + new, key=_key)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "reports", type=Path, nargs="+",
        help="evaluate-mdn or bench/independent_mdn_objects.py output folders",
    )  # fmt: skip
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    existing: list[dict[str, str]] = []
    if args.out.is_file():
        with args.out.open(newline="") as f:
            reader = csv.DictReader(f)
            if reader.fieldnames != COLUMNS:
                raise SystemExit(f"{args.out}: columns {reader.fieldnames}, not {COLUMNS}")
            existing = list(reader)
    rows = merge(existing, args.reports)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp")
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(args.out)
    sys.stdout.write(f"{args.out}: {len(rows)} rows\n")


if __name__ == "__main__":
    main()
