"""`artic evaluate rmp` on tiny train-rmp folders: Table 6.1, the figures, bad input."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from cli_runner import run_cli

TINY = ("debug=tiny", "task.horizon=8", "ppo.steps_per_epoch=32", "ppo.train_iters=2")


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("rmp")
    runs = {}
    for name, args in {
        "push": ("task=push",),
        "traj_vices_only": ("task=traj", "controllers=[vices]"),
        "push_crowded": ("task=push", "epochs=1", "task.obstacles.volume.half_extents=[0,0,0]"),
    }.items():
        runs[name] = root / name
        code, _, err = run_cli("train-rmp", *TINY, *args, f"out={runs[name]}")
        assert code == 0, err
    return runs


def evaluate(out: Path, *args: str) -> tuple[int, str, str]:
    return run_cli("evaluate", "rmp", "debug=tiny", f"out={out}", *args)


def test_writes_table_6_1_and_the_figures(trained, tmp_path):
    out = tmp_path / "report"
    code, _, err = evaluate(out, "tasks=[push]", f"policies.push={trained['push']}")
    assert code == 0, err
    with (out / "table_6_1.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["controller"] for r in rows] == ["vices", "rmp_vices"]
    assert list(rows[0]) == ["task", "controller", "reward_mean", "reward_std", "collisions",
                             "joint_limit_events", "episodes"]  # fmt: skip
    assert all(r["task"] == "push" and r["episodes"] == "3" for r in rows)
    for name in ("table_6_1.md", "fig_6_2.png", "fig_6_4.png", "curves.csv", "episodes.csv"):
        assert (out / name).stat().st_size > 0
    text = (out / "table_6_1.md").read_text()
    assert "1755" in text and "Targets" in text  # the thesis' VICES push reward beside ours
    # both controllers met the same obstacle layouts (same reset seeds)
    with (out / "episodes.csv").open() as f:
        episodes = list(csv.DictReader(f))
    seeds = {c: [e["reset_seed"] for e in episodes if e["controller"] == c]
             for c in ("vices", "rmp_vices")}  # fmt: skip
    assert seeds["vices"] == seeds["rmp_vices"]
    again = tmp_path / "again"
    assert evaluate(again, "tasks=[push]", f"policies.push={trained['push']}")[0] == 0
    for name in ("table_6_1.csv", "episodes.csv", "curves.csv"):
        assert (again / name).read_bytes() == (out / name).read_bytes()


def test_a_policy_folder_of_another_task_or_controllers_is_refused(trained, tmp_path):
    code, _, err = evaluate(tmp_path / "a", "tasks=[door]", f"policies.door={trained['push']}")
    assert code == 2 and "holds task 'push'" in err and len(err.strip().splitlines()) == 1
    code, _, err = evaluate(
        tmp_path / "b", "tasks=[traj]", f"policies.traj={trained['traj_vices_only']}"
    )
    assert code == 2 and "expected both vices and rmp_vices" in err
    code, _, err = evaluate(tmp_path / "c", "tasks=[push]", f"policies.push={tmp_path / 'none'}")
    assert code == 2 and "no such folder" in err
    # spheres that cannot be placed clear (two in one point): refused before any episode
    code, _, err = evaluate(
        tmp_path / "d", "tasks=[push]", f"policies.push={trained['push_crowded']}"
    )
    assert code == 2 and "task.obstacles" in err and "1000 draws" in err
    assert len(err.strip().splitlines()) == 1
    assert not any((tmp_path / n).exists() for n in "abcd")
