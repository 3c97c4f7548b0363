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
