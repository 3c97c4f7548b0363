"""`artic evaluate cip`: the pure statistics and targets of `evaluation/cip_report.py` on
hand-made rows, then the stage end to end on a tiny train-cip folder (drawer) and its bad
inputs (exit 2, one line)."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest

from artic.artifacts.formats import read_csv
from artic.artifacts.manifest import read_manifest
from artic.evaluation import cip_report as report
from cli_runner import run_cli

COLUMNS = ["scale", "task", "setting", "episode", "success_best_mean", "success_best_se",
           "violation_rate"]  # fmt: skip


def curve(setting: str, seed: int, best: list[float], violation: float = 0.0) -> list[list[str]]:
    """learning_curve.csv rows (no header) of one run evaluated every 10 episodes."""
    return [[setting, str(seed), str(10 * (i + 1)), str(b), str(b), str(violation), "0", "0"]
            for i, b in enumerate(best)]  # fmt: skip


def rows_of(values: dict[str, float], episodes: tuple[int, ...] = (120,),
            violation: dict[str, float] | None = None) -> list[list[object]]:  # fmt: skip
    """success.csv rows: every task and the mean at `episodes` with each setting's value."""
    violation = violation or {}
    tasks = (*report.TASKS, "mean")
    return [["cpu", t, s, e, v, 0.0, violation.get(s, 0.0)]
            for t in tasks for s, v in values.items() for e in episodes]  # fmt: skip


def test_mean_and_standard_error():
    assert report.mean_se([0.2, 0.4, 0.6]) == pytest.approx((0.4, 0.2 / math.sqrt(3)))
    assert report.mean_se([0.7]) == (0.7, 0.0)  # one seed: s.e. 0


def test_rows_hold_mean_se_and_stay_monotone():
    curves = {"door": curve("cip", 0, [0.0, 0.4, 0.4, 1.0], 0.5)
              + curve("cip", 1, [0.2, 0.2, 0.6, 0.6], 0.1)}  # fmt: skip
    rows = report.success_rows({"door": "paper"}, curves)
    assert [r[3] for r in rows] == [10, 20, 30, 40]
    means = [r[4] for r in rows]
    assert means == pytest.approx([0.1, 0.3, 0.5, 0.8])
    assert all(a <= b for a, b in itertools.pairwise(means))
    assert rows[0][:3] == ["paper", "door", "cip"]
    assert rows[0][5] == pytest.approx(report.mean_se([0.0, 0.2])[1])
    assert rows[0][6] == pytest.approx(0.3)
    assert not any(r[1] == "mean" for r in rows)  # one task: no 4-task mean


def test_the_four_task_mean_is_over_seeds_of_task_means():
    curves = {t: curve("cip", 0, [0.0, v]) + curve("cip", 1, [0.0, 1.0])
              for t, v in zip(report.TASKS, [0.2, 0.4, 0.6, 0.8], strict=True)}  # fmt: skip
    rows = report.success_rows(dict.fromkeys(report.TASKS, "cpu"), curves)
    mean = [r for r in rows if r[1] == "mean" and r[3] == 20]
    assert len(mean) == 1 and mean[0][0] == "cpu"
    assert mean[0][4] == pytest.approx(0.75) and mean[0][5] == pytest.approx(0.25)


def test_episodes_to_80_percent():
    rows = report.success_rows({"door": "cpu"}, {"door": curve("cip", 0, [0.2, 0.8, 1.0])})
    assert report.episodes_to(rows, "door", "cip") == 20
    assert report.episodes_to(rows, "door", "cip", level=1.1) is None


def _line(lines: list[str], fragment: str) -> str:
    (line,) = [ln for ln in lines if fragment in ln]
    return line


GOOD = {"e2e": 0.0, "head": 0.3, "safety": 0.35, "mv": 0.4, "cip": 0.7, "cip_bc": 0.9,
        "e2e_bc": 0.1}  # fmt: skip


@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        ({"cip_bc": 0.75}, "CIP+BC >= 80% mean"),
        ({"cip": 0.5}, "CIP >= 60% mean"),
        ({"e2e": 0.2}, "E2E <= 10% every task"),
        ({"cip": 0.4, "mv": 0.6}, "CIP >= MV"),
        ({"safety": 0.5}, "Safety within 10 points of Head"),
        ({"e2e_bc": 1.0, "cip_bc": 0.85}, "CIP+BC > E2E+BC"),
    ],
)
def test_each_cpu_target_passes_and_fails(change, fragment):
    good = report.targets(rows_of(GOOD))
    assert _line(good, fragment).endswith("PASS")
    assert _line(report.targets(rows_of({**GOOD, **change})), fragment).endswith("FAIL")


def test_every_task_target_and_order_ties():
    rows = [r for r in rows_of(GOOD) if not (r[1] == "lever" and r[2] == "cip_bc")]
    rows.append(["cpu", "lever", "cip_bc", 120, 0.6, 0.0, 0.0])  # lever below 70%
    assert _line(report.targets(rows), "CIP+BC >= 80% mean").endswith("FAIL")
    tie = report.targets(rows_of({**GOOD, "mv": 0.75}))  # CIP 70% vs MV 75%: within 10
    assert _line(tie, "CIP >= MV").endswith("PASS")


@pytest.mark.parametrize(
    ("change", "violation", "fragment"),
    [
        ({"cip": 0.7}, {}, "CIP >= 80% mean by episode 500"),
        ({"cip_bc": 0.5}, {}, "CIP+BC >= 80% mean by episode 50"),
        ({"e2e": 0.3}, {}, "E2E <= 10% every task (episode 500)"),
        ({}, {"safety": 0.3, "head": 0.4}, "Safety's violation rate"),
    ],
)
def test_each_paper_target_passes_and_fails(change, violation, fragment):
    paper = {**GOOD, "cip": 0.85, "cip_bc": 0.9}
    good = report.targets(rows_of(paper, (50, 120, 500), {"safety": 0.1, "head": 0.4}))
    assert _line(good, fragment).endswith("PASS")
    bad = rows_of({**paper, **change}, (50, 120, 500), {"safety": 0.1, "head": 0.4, **violation})
    assert _line(report.targets(bad), fragment).endswith("FAIL")


def test_targets_beyond_the_runs_are_not_applicable():
    lines = report.targets(rows_of(GOOD, (10, 20)))
    assert _line(lines, "by episode 120").endswith("(the runs end at episode 20)")
    assert _line(lines, "by episode 500").startswith("- by episode 500: n/a")


def test_markdown_lists_the_episodes_and_episodes_to_80():
    text = report.report_markdown(rows_of(GOOD, (50, 120)), {"door": "x"})
    assert "at episode 50:" in text and "at episode 120:" in text and "episode 500" in text
    assert "| CIP+BC | 50 | 50 | 50 | 50 | 50 |" in text


@pytest.fixture(scope="module")
def train_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("cip")
    code, _, err = run_cli("grasp-candidates", "--task", "drawer", "debug=tiny",
                           f"out={root / 'grasps'}")  # fmt: skip
    assert code == 0, err
    code, _, err = run_cli("cip-demos", "--task", "drawer", "debug=tiny",
                           f"initiation_set={root / 'grasps'}",
                           f"out={root / 'demos'}")  # fmt: skip
    assert code == 0, err
    code, _, err = run_cli("train-cip", "--task", "drawer", "debug=tiny",
                           f"initiation_set={root / 'grasps'}", f"demos={root / 'demos'}",
                           f"out={root / 'policy'}", "settings=[head,cip_bc]")  # fmt: skip
    assert code == 0, err
    return root


def evaluate(tmp: Path, *runs: str) -> tuple[int, str, str]:
    nulls = [f"runs.{t}=null" for t in report.TASKS]
    return run_cli("evaluate", "cip", "debug=tiny", *nulls, *runs, f"out={tmp}")


def test_stage_writes_success_table_and_figures(train_folder, tmp_path):
    code, _, err = evaluate(tmp_path / "out", f"runs.drawer={train_folder / 'policy'}")
    assert code == 0, err
    out = tmp_path / "out"
    rows = read_csv(out / "success.csv")
    assert rows[0] == COLUMNS
    assert {(r[0], r[1], r[2]) for r in rows[1:]} == {("cpu", "drawer", "head"),
                                                      ("cpu", "drawer", "cip_bc")}  # fmt: skip
    assert sorted({int(r[3]) for r in rows[1:]}) == [2, 4]
    text = (out / "table.md").read_text()
    assert "Best-to-date success at episode 4" in text and "n/a" in text
    assert (out / "fig_7_3.png").stat().st_size > 0 and (out / "fig_7_4.png").stat().st_size > 0
    assert read_manifest(out).stage == "evaluate-cip"


@pytest.mark.parametrize(
    ("which", "fragment"),
    [
        ("grasps", "expected a 'train-cip' output"),
        ("door", "holds task 'drawer'"),
        ("none", "every task is null"),
    ],
)
def test_bad_input_exits_2_with_one_line(train_folder, tmp_path, which, fragment):
    runs = {"grasps": [f"runs.drawer={train_folder / 'grasps'}"],
            "door": [f"runs.door={train_folder / 'policy'}"], "none": []}[which]  # fmt: skip
    code, _, err = evaluate(tmp_path / "bad", *runs)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, err
    assert len(lines) == 1 and fragment in lines[0], err
