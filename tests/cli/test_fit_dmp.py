"""fit-dmp end to end through the CLI, on a small plan-demos folder written here."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from artic.artifacts.formats import write_json, write_npz
from artic.artifacts.manifest import (
    read_manifest,
)
from artic.errors import InputError
from artic.policies.dmp import read_dmp, rollout_dmp
from cli_runner import run_cli
from fake_outputs import write_manifest

DT = 0.05
START = np.array([0.0, 0.5, 0.0, -1.5, 0.0, 1.0, 0.0])
GOAL = np.array([0.4, 0.8, -0.2, -1.0, 0.3, 1.2, 0.5])


def demo_arrays(k: int, n_joints: int = 7, steps: int = 41) -> dict[str, np.ndarray]:
    """A smooth joint-space demo (min-jerk with a bump), perturbed per demo k."""
    t = np.arange(steps) * DT
    s = t / t[-1]
    shape = 10 * s**3 - 15 * s**4 + 6 * s**5
    bump = np.sin(np.pi * s) ** 2
    start, goal = START[:n_joints] + 0.02 * k, GOAL[:n_joints] - 0.01 * k
    q = start + (goal - start) * shape[:, None] + 0.1 * bump[:, None] * np.cos(np.arange(n_joints))
    return {
        "t": t,
        "q_robot": q,
        "qd_robot": np.gradient(q, t, axis=0),
        "q_object": (0.25 * shape)[:, None],
        "ee_pose": np.tile(np.eye(4), (steps, 1, 1)),
    }


def write_plan_demos(
    folder: Path,
    task: str = "drawer",
    n_ok: int = 3,
    n_failed: int = 1,
    bad: dict[int, dict[str, np.ndarray]] | None = None,
    stage: str = "plan-demos",
) -> Path:
    """A plan-demos output folder (format of docs/formats.md, Chapter 5) with a manifest
    written by the real manifest model, so the stage runner accepts it."""
    folder.mkdir(parents=True)
    entries = []
    for k in range(n_ok + n_failed):
        if k < n_ok:
            name = f"demo_{k:03d}.npz"
            arrays = (bad or {}).get(k) or demo_arrays(k)
            write_npz(folder / name, arrays)
            steps = len(arrays["t"])
            entries.append(
                {"index": k, "file": name, "status": "ok", "reason": "", "planning_time_s": 0.1,
                 "steps": steps}
            )  # fmt: skip
        else:
            entries.append(
                {"index": k, "file": None, "status": "failed", "reason": "no IK solution",
                 "planning_time_s": 0.2, "steps": 0}
            )  # fmt: skip
    index = {
        "task": task,
        "n_requested": n_ok + n_failed,
        "control_dt": DT,
        "n_joints": 7,
        "kinematic_model": {"source": "true"},
        "planner": "RRTConnect",
        "demos": entries,
    }
    write_json(folder / "demos.json", index)
    write_manifest(folder, stage, {"task": {"name": task}, "out": str(folder)})
    return folder


@pytest.fixture()
def demos(tmp_path: Path) -> Path:
    return write_plan_demos(tmp_path / "demos" / "drawer")


def fit(demos: Path, out: Path, *extra: str) -> tuple[int, str, str]:
    return run_cli("fit-dmp", "debug=tiny", "task=drawer", f"demos={demos}", f"out={out}", *extra)


def read_fit_csv(out: Path) -> list[dict[str, str]]:
    with (out / "fit.csv").open(newline="") as f:
        return list(csv.DictReader(f))


def test_fit_dmp_writes_dmp_fit_table_and_manifest(demos, tmp_path):
    out = tmp_path / "dmp"
    code, _, err = fit(demos, out)
    assert code == 0, err
    info = json.loads((out / "dmp.json").read_text())
    contract = {"task", "n_joints", "n_basis", "alpha_z", "beta_z", "alpha_x", "tau", "dt",
                "y0", "goal", "weights"}  # fmt: skip
    assert contract <= set(info)
    assert info["task"] == "drawer" and info["n_joints"] == 7 and info["n_basis"] == 10
    assert info["dt"] == DT and info["beta_z"] == info["alpha_z"] / 4
    assert np.array(info["weights"]).shape == (7, 10)
    assert info["demos_used"] == ["demo_000.npz", "demo_001.npz", "demo_002.npz"]
    # y0, goal and tau: the means over the three demos
    assert np.allclose(info["y0"], START + 0.02) and np.allclose(info["goal"], GOAL - 0.01)
    assert info["tau"] == pytest.approx(2.0)
    rows = read_fit_csv(out)
    assert len(rows) == 3 * 7 and {r["file"] for r in rows} == set(info["demos_used"])
    middle = [r for r in rows if r["file"] == "demo_001.npz"]  # the mean of the three
    span = np.array([float(r["range"]) for r in middle])
    assert (np.array([float(r["rms"]) for r in middle]) < 0.03 * span).all()
    # the written DMP differs from the outer demos by their spread (2 cm starts)
    assert (np.array([float(r["rms"]) for r in rows]) < 0.03).all()
    manifest = read_manifest(out)
    assert manifest.stage == "fit-dmp" and manifest.inputs["demos"].stage == "plan-demos"
    assert set(manifest.outputs) == {"dmp.json", "fit.csv"}
    assert manifest.stats["demos used"] == 3
    rms = np.array([float(r["rms"]) for r in rows])
    rel = rms / np.array([float(r["range"]) for r in rows])
    assert manifest.stats["max RMS (mrad)"] == round(1000 * rms.max(), 2)
    assert manifest.stats["max RMS / range (%)"] == round(100 * rel.max(), 3)


def test_read_dmp_rolls_out_the_written_dmps(demos, tmp_path):
    out = tmp_path / "dmp"
    assert fit(demos, out)[0] == 0
    loaded = read_dmp(out)
    assert loaded.task == "drawer" and loaded.dt == DT and loaded.cfg.n_basis == 10
    traj = rollout_dmp(loaded.params, loaded.cfg, loaded.dt, 41)
    q = demo_arrays(1)["q_robot"]  # the middle demo is the mean demo
    assert np.abs(traj.y - q).max() < 0.02
    with pytest.raises(InputError, match="expected a 'fit-dmp' output"):
        read_dmp(demos)


def test_fit_dmp_is_deterministic_and_skips_when_up_to_date(demos, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert fit(demos, a)[0] == 0 and fit(demos, b)[0] == 0
    for name in ("dmp.json", "fit.csv"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    code, stdout, err = fit(demos, a)
    assert code == 0 and "skipped" in stdout + err


def test_max_demos_task_option_and_plot(demos, tmp_path):
    out = tmp_path / "one"
    code, _, err = run_cli(
        "fit-dmp", "--task", "drawer", "debug=tiny", f"demos={demos}", f"out={out}",
        "max_demos=1", "plot=true",
    )  # fmt: skip
    assert code == 0, err
    info = json.loads((out / "dmp.json").read_text())
    assert info["demos_used"] == ["demo_000.npz"] and np.allclose(info["y0"], START)
    rows = read_fit_csv(out)
    assert len(rows) == 7 and all(r["rms"] == r["rms_own"] for r in rows)
    span = np.array([float(r["range"]) for r in rows])
    assert (np.array([float(r["rms"]) for r in rows]) < 0.03 * span).all()
    assert (out / "fit.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_demos_of_another_task_are_refused(tmp_path):
    demos = write_plan_demos(tmp_path / "tball", task="tball")
    code, _, err = fit(demos, tmp_path / "out")
    assert code == 2 and "task 'tball'" in err and "expected 'drawer'" in err
    assert not (tmp_path / "out").exists()


def test_no_successful_demos_is_an_input_error(tmp_path):
    demos = write_plan_demos(tmp_path / "failed", n_ok=0, n_failed=3)
    code, _, err = fit(demos, tmp_path / "out")
    assert code == 2 and "no successful demos" in err


def test_a_demo_with_the_wrong_joint_count_is_named(tmp_path):
    demos = write_plan_demos(tmp_path / "six", bad={1: demo_arrays(1, n_joints=6)})
    code, _, err = fit(demos, tmp_path / "out")
    assert code == 2 and "demo_001.npz" in err and "7) joints" in err


def test_a_demo_with_nan_is_named(tmp_path):
    arrays = demo_arrays(2)
    arrays["q_robot"][5, 3] = np.nan
    demos = write_plan_demos(tmp_path / "nan", bad={2: arrays})
    code, _, err = fit(demos, tmp_path / "out")
    assert code == 2 and "demo_002.npz" in err and "finite" in err


def test_a_folder_of_another_stage_is_refused(tmp_path):
    demos = write_plan_demos(tmp_path / "other", stage="render-depth")
    code, _, err = fit(demos, tmp_path / "out")
    assert code == 2 and "expected a 'plan-demos' output" in err
    code, _, err = fit(tmp_path / "missing", tmp_path / "out")
    assert code == 2 and "no such folder" in err


def test_cfg_prints_the_resolved_config():
    code, stdout, err = run_cli("fit-dmp", "task=tball", "--cfg")
    assert code == 0, err
    assert "demos: artifacts/demos/tball" in stdout and "out: artifacts/dmp/tball" in stdout
