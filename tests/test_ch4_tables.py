"""scripts/ch4_tables.py: evaluate-hierarchy summaries -> docs/results/ch4/tables.csv rows."""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path
from types import ModuleType

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "ch4_tables.py"
SUMMARY = ["kind", "segmentation", "scans", "map", "tree_f1"]


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("ch4_tables", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _summary(folder: Path, kinds: list[str], value: float) -> Path:
    """An evaluate-hierarchy folder's summary.csv (the only file the script reads)."""
    folder.mkdir()
    with (folder / "summary.csv").open("w", newline="") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(SUMMARY)
        for kind in kinds:
            for seg in ("gt", "pred"):
                writer.writerow([kind, seg, 6, value / 100, value])
    return folder


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def test_a_run_replaces_only_the_pairs_its_folders_hold(tmp_path: Path) -> None:
    ch4_tables = _script()
    out = tmp_path / "tables.csv"
    withheld = _summary(tmp_path / "withheld", ["clean", "noisy"], 90.0)
    turned = _summary(tmp_path / "withheld_yaw", ["noisy"], 85.0)
    ch4_tables.main(["--category", "lamp", "--withheld", str(withheld),
                     "--withheld-yaw", str(turned), "--out", str(out)])  # fmt: skip
    first = _rows(out)
    assert list(first[0]) == ch4_tables.COLUMNS
    assert [(r["data"], r["scans"], r["parts"]) for r in first] == [
        ("withheld", s, p) for s in ("clean", "noisy", "noisy_yaw")
        for p in ("ground_truth", "predicted")
    ]  # fmt: skip
    assert {r["map50"] for r in first if r["parts"] == "ground_truth"} == {""}
    assert first[5]["map50"] == "0.850" and first[5]["tree_f1"] == "85.00"
    # the independent rows join; the withheld ones stay; another category's are kept
    independent = _summary(tmp_path / "independent", ["clean", "noisy"], 70.0)
    ch4_tables.main(["--category", "lamp", "--independent", str(independent), "--out", str(out)])
    again = _summary(tmp_path / "withheld_yaw_again", ["noisy"], 86.0)
    ch4_tables.main(["--category", "office_chair", "--withheld-yaw", str(again), "--out", str(out)])
    ch4_tables.main(["--category", "lamp", "--withheld-yaw", str(again), "--out", str(out)])
    rows = _rows(out)
    lamp = [r for r in rows if r["category"] == "lamp"]
    assert [r["data"] for r in lamp] == ["withheld"] * 6 + ["independent"] * 4
    assert lamp[:4] == first[:4] and lamp[5]["tree_f1"] == "86.00"
    assert [r["category"] for r in rows] == ["lamp"] * 10 + ["office_chair"] * 2
