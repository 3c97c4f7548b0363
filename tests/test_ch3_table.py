"""scripts/ch3_table.py: evaluate-mdn reports -> docs/results/ch3/table_3_1.csv rows."""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import pytest

from cli_runner import run_cli

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "ch3_table.py"


def _script():
    spec = importlib.util.spec_from_file_location("ch3_table", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_rows_in_the_issues_columns_merged_by_category_and_data(tiny_model, tiny_depth, tmp_path):
    ch3_table = _script()
    report = tmp_path / "report"
    code, _, err = run_cli(
        "evaluate", "mdn", "debug=tiny", "category=microwave", f"model={tiny_model}",
        f"depth={tiny_depth}", f"out={report}", "evaluate.icp_images=2",
    )  # fmt: skip
    assert code == 0, err
    out = tmp_path / "table.csv"
    kept = dict.fromkeys(ch3_table.COLUMNS, "1.00")
    kept.update(category="cabinet", data="thesis_grid", estimator="network")
    stale = {**kept, "category": "microwave", "data": "continuous", "estimator": "nn"}
    with out.open("w", newline="") as f:
        writer = csv.DictWriter(f, ch3_table.COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows([stale, kept])
    ch3_table.main([str(report), "--out", str(out)])
    with out.open(newline="") as f:
        reader = csv.DictReader(f)
        assert reader.fieldnames == ch3_table.COLUMNS
        rows = list(reader)
    # the report replaces its own (category, data) rows, keeps the others, sorted
    assert rows[0] == kept
    mine = rows[1:]
    assert [r["estimator"] for r in mine] == ["mean", "nn", "icp", "network", "refined"]
    assert {(r["category"], r["data"]) for r in mine} == {("microwave", "continuous")}
    summary = {r["method"]: r for r in csv.DictReader((report / "summary.csv").open())}
    network = next(r for r in mine if r["estimator"] == "network")
    assert float(network["axis_position_cm"]) == pytest.approx(
        float(summary["Ours"]["position_cm_mean"]), abs=0.005
    )
    assert 0.0 <= float(network["coverage_90_pct"]) <= 100.0
    assert all(r["coverage_90_pct"] == "" for r in mine if r["estimator"] != "network")
    # the same report twice is refused: two answers for one cell
    with pytest.raises(SystemExit, match="same category"):
        ch3_table.main([str(report), str(report), "--out", str(out)])


def _bench_folder(path: Path, estimator: str, axis: list[float], right: list[int]) -> Path:
    """A bench/independent_mdn_objects.py output folder with these images' errors."""
    path.mkdir()
    (path / "objects.jsonl").write_text('{"category": "cabinet"}\n')
    (path / "summary.csv").write_text(
        "category,sides,sizes,placement,estimator,images\n"
        f"cabinet,both,table_a1,frame,{estimator},{len(axis)}\n"
    )
    lines = ["image,axis_position_cm,yaw_deg,configuration_deg,rotation_thesis_deg,"
             "hinge_side_right"]  # fmt: skip
    rows = enumerate(zip(axis, right, strict=True))
    lines += [f"{i},{a},1.0,{2 * a},0.5,{r}" for i, (a, r) in rows]
    (path / "errors.csv").write_text("\n".join(lines) + "\n")
    return path


def test_a_bench_folder_gives_its_one_independent_row(tmp_path):
    """A second-generator bench folder: one `independent` row of its estimator, the means
    over its images, the hinge side wrong on the share not right, no coverage; it
    replaces that cell only (the other estimator's independent row and every other row
    stay)."""
    ch3_table = _script()
    out = tmp_path / "table.csv"
    other = dict.fromkeys(ch3_table.COLUMNS, "9.00")
    other.update(category="cabinet", data="independent", estimator="network")
    stale = {**other, "estimator": "refined"}
    continuous = {**other, "data": "continuous"}
    with out.open("w", newline="") as f:
        writer = csv.DictWriter(f, ch3_table.COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows([continuous, other, stale])
    bench = _bench_folder(tmp_path / "bench", "Ours + refinement", [1.0, 2.0, 6.0], [1, 1, 0])
    ch3_table.main([str(bench), "--out", str(out)])
    with out.open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows[:2] == [continuous, other]
    assert rows[2] == {
        "category": "cabinet", "data": "independent", "estimator": "refined",
        "axis_position_cm": "3.00", "configuration": "6.00", "rotation_thesis_deg": "0.50",
        "yaw_deg": "1.00", "hinge_side_wrong_pct": "33.33", "coverage_90_pct": "",
    }  # fmt: skip
    assert len(rows) == 3
