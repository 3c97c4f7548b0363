"""Issue 20's verdicts in `artic evaluate rmp`'s table_6_1.md (`evaluation/rmp_report.py`)."""

from __future__ import annotations

import math

from artic.evaluation.rmp_report import verdict

# task, controller, reward mean, reward s.d., collisions, joint-limit events, episodes
TABLE = [
    ["door", "vices", 100.0, 10.0, 30, 20, 100],
    ["door", "rmp_vices", 70.0, 5.0, 10, 5, 100],
    ["traj", "vices", 10.0, 1.0, 40, 5, 100],
    ["traj", "rmp_vices", 7.0, 1.0, 20, 6, 100],
]


def _line(lines: list[str], start: str) -> str:
    [line] = [ln for ln in lines if ln.startswith(start)]
    return line


def test_each_target_passes_or_fails_on_its_own_threshold():
    lines = verdict(TABLE, {"door": (40.0, 60.0), "traj": (math.nan, 49.0)})
    assert _line(lines, "- door: collisions").endswith("PASS")  # 10 <= 0.45 x 30
    assert _line(lines, "- door: joint-limit").endswith("PASS")  # 5 <= 0.5 x 20
    assert _line(lines, "- door: mean reward").endswith("PASS")  # 70 >= 0.6 x 100
    assert _line(lines, "- door: integrated joint-limit").endswith("PASS")
    assert _line(lines, "- door: integrated collisions").endswith("PASS")
    assert _line(lines, "- traj: collisions").endswith("FAIL")  # 20 > 0.45 x 40
    assert _line(lines, "- traj: joint-limit").endswith("FAIL")  # under 10: never more
    assert _line(lines, "- traj: mean reward").endswith("FAIL")  # 7 < 0.8 x 10
    assert _line(lines, "- traj: integrated joint-limit").endswith("FAIL")  # 49 < 50


def test_median_collision_force_is_a_verdict_when_both_controllers_collide():
    medians = {("door", "vices"): 40.0, ("door", "rmp_vices"): 20.0,
               ("traj", "vices"): 10.0, ("traj", "rmp_vices"): 12.0}  # fmt: skip
    lines = verdict(TABLE, {}, medians)
    assert _line(lines, "- door: median collision force").endswith("PASS")
    assert _line(lines, "- traj: median collision force").endswith("FAIL")
    lines = verdict(TABLE, {}, {("door", "vices"): 40.0, ("door", "rmp_vices"): math.nan})
    assert "n/a" in _line(lines, "- door: median collision force")
