"""plan-demos end to end through the CLI on the tiny preset (drawer task)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from artic.artifacts.formats import read_npz
from artic.artifacts.hashing import sha256_file
from artic.artifacts.manifest import read_manifest
from artic.config.compose import models_dir
from cli_runner import run_cli

DEMO_ARRAYS = {"t", "q_robot", "qd_robot", "q_object", "ee_pose"}
RECORD_KEYS = {"index", "file", "status", "reason", "steps", "q_robot_start", "q_object_start"}


@pytest.fixture(scope="module")
def tiny_demos(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("demos") / "drawer"
    code, _, err = run_cli("plan-demos", "debug=tiny", "task=drawer", f"out={out}")
    assert code == 0, err
    return out


def test_writes_the_demos_format(tiny_demos: Path) -> None:
    from artic.sim.tasks import get_task
    from artic.sim.world import TaskWorld

    info = json.loads((tiny_demos / "demos.json").read_text())
    assert info["task"] == "drawer" and info["n_requested"] == 2 and info["n_joints"] == 7
    assert info["control_dt"] == 0.05 and info["planner"] == "rrtconnect"
    assert info["kinematic_model"] == {"source": "true"}
    assert [d["index"] for d in info["demos"]] == [0, 1]
    with TaskWorld.create(get_task("drawer")) as world:
        low, high = world.robot_limits()
        vmax = world.velocity_limits()
    assert info["horizon"] == 80 and info["goal"] == [0.25] and info["dof_object"] == 1
    timings = json.loads((tiny_demos / "timings.json").read_text())
    assert [d["index"] for d in timings["demos"]] == [0, 1]
    assert all(d["planning_time_s"] > 0 for d in timings["demos"])
    assert timings["median_planning_time_s"] > 0
    for record in info["demos"]:
        assert set(record) >= RECORD_KEYS and "planning_time_s" not in record
        assert record["status"] == "ok" and record["reason"] == ""
        assert 0 <= record["grasp_step"] < record["steps"] and record["reached_fraction"] == 1.0
        data = read_npz(tiny_demos / record["file"])
        assert set(data) == DEMO_ARRAYS
        steps = record["steps"]
        assert data["t"].shape == (steps,) and data["t"].dtype == np.float64
        np.testing.assert_allclose(np.diff(data["t"]), 0.05)
        assert data["q_robot"].shape == (steps, 7) and data["qd_robot"].shape == (steps, 7)
        assert data["q_object"].shape == (steps, 1) and data["ee_pose"].shape == (steps, 4, 4)
        assert np.all(data["q_robot"] >= low - 1e-9) and np.all(data["q_robot"] <= high + 1e-9)
        assert np.all(np.abs(data["qd_robot"]) <= vmax + 1e-9)
        np.testing.assert_allclose(data["q_object"][0], [0.0])
        np.testing.assert_allclose(data["q_object"][-1], [0.25], atol=1e-4)
        # forward differences: integrating the commanded velocities reproduces the path
        np.testing.assert_allclose(
            data["q_robot"][:-1] + 0.05 * data["qd_robot"][:-1], data["q_robot"][1:], atol=1e-9
        )
        rotations = data["ee_pose"][:, :3, :3]
        identity = np.broadcast_to(np.eye(3), rotations.shape)
        np.testing.assert_allclose(rotations @ rotations.transpose(0, 2, 1), identity, atol=1e-6)
        # executed in the simulator: the achieved object configuration is recorded
        executed = record["executed"]
        assert len(executed["q_object"]) == 1 and executed["goal_error"] >= 0


def test_manifest_records_the_model_source(tiny_demos: Path) -> None:
    manifest = read_manifest(tiny_demos)
    assert manifest.stage == "plan-demos" and manifest.status == "complete"
    assert manifest.config["model"]["source"] == "true"
    assert manifest.stats["kinematic model"] == "true" and manifest.stats["demos planned"] == 2
    assert set(manifest.outputs) == {"demo_000.npz", "demo_001.npz", "demos.json", "timings.json"}


def test_same_seed_gives_the_same_bytes(tiny_demos: Path, tmp_path: Path) -> None:
    # everything but timings.json (wall-clock planning times) is deterministic
    out = tmp_path / "again"
    code, _, err = run_cli("plan-demos", "debug=tiny", "task=drawer", f"out={out}")
    assert code == 0, err
    for name in ("demos.json", "demo_000.npz", "demo_001.npz"):
        assert (out / name).read_bytes() == (tiny_demos / name).read_bytes(), name
    assert (out / "timings.json").exists()


@pytest.mark.parametrize("task", ["tball", "microwave"])
def test_contact_tasks_plan_clean_demos_within_the_horizon(task: str, tmp_path: Path) -> None:
    from artic.sim.tasks import get_task

    out = tmp_path / task
    code, _, err = run_cli(
        "plan-demos", "debug=tiny", f"task={task}", f"out={out}", "demos.count=1"
    )
    assert code == 0, err
    record = json.loads((out / "demos.json").read_text())["demos"][0]
    cfg = get_task(task)
    assert record["status"] == "ok" and record["steps"] <= cfg.horizon
    executed = record["executed"]
    # the arm follows its plan (it does not jam on the tee or the microwave)
    assert executed["max_tracking_error_rad"] < 0.05
    moved = executed["q_object"][0] - cfg.object_start[0]
    if task == "tball":
        assert moved > 0.1  # the ball was hit along +y
    else:
        assert moved < -0.5  # the door was pushed most of the way towards shut


def test_shards_merge_into_the_same_demos(tiny_demos: Path, tmp_path: Path) -> None:
    out = tmp_path / "drawer"
    common = ("plan-demos", "debug=tiny", "task=drawer", f"out={out}", "shard.count=2")
    code, _, err = run_cli(*common, "shard.index=1")
    assert code == 0, err
    assert not (out / "demos.json").exists()  # one of two shards: not published yet
    code, _, err = run_cli(*common, "shard.index=0")
    assert code == 0, err
    for name in ("demo_000.npz", "demo_001.npz", "demos.json"):
        assert (out / name).read_bytes() == (tiny_demos / name).read_bytes()


def test_noisy_model_is_recorded(tmp_path: Path) -> None:
    out = tmp_path / "noisy"
    code, _, err = run_cli(
        "plan-demos",
        "debug=tiny",
        "task=drawer",
        f"out={out}",
        "demos.count=1",
        "model.source=noisy",
        "model.direction_std_rad=0.02",
        "execute.enabled=false",
    )
    assert code == 0, err
    model = json.loads((out / "demos.json").read_text())["kinematic_model"]
    assert model["source"] == "noisy" and model["direction_std_rad"] == 0.02
    assert len(model["direction_error_rad"]) == 1 and 0 < model["direction_error_rad"][0] < 0.2
    assert read_manifest(out).stats["kinematic model"] == "noisy"


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("task=nosuchtask", "task"),
        ("demos.count=-1", "demos.count"),
        ("task.goal=[0.9]", "task drawer: goal"),
    ],
)
def test_bad_input_exits_2_with_one_line(override: str, message: str, tmp_path: Path) -> None:
    out = tmp_path / "bad"
    code, _, err = run_cli("plan-demos", "debug=tiny", "task=drawer", override, f"out={out}")
    assert code == 2, err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_a_goal_no_demo_reaches_is_bad_input(tmp_path: Path) -> None:
    # the microwave's closed door is out of the iiwa's reach: demanding the whole motion fails
    code, _, err = run_cli(
        "plan-demos",
        "debug=tiny",
        "task=microwave",
        f"out={tmp_path / 'mw'}",
        "demos.count=1",
        "grasp.min_reach_fraction=1.0",
        "execute.enabled=false",
    )
    assert code == 2, err
    assert "task microwave: no demo could be planned to the goal" in err and "IK" in err
    assert not (tmp_path / "mw").exists()


# -- model.source=predicted: the Chapter 3 MDN's estimate from a rendered view ----------


@pytest.fixture(scope="session")
def tiny_drawer_mdn(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny drawer MDN made by the real stages (its estimates are poor)."""
    root = tmp_path_factory.mktemp("drawer_mdn")
    steps = [
        ("generate-dataset", "debug=tiny", "category=drawer", f"out={root / 'objects'}"),
        ("render-depth", "debug=tiny", f"dataset={root / 'objects'}", f"out={root / 'depth'}"),
        ("train-mdn", "debug=tiny", "category=drawer", f"depth={root / 'depth'}",
         f"out={root / 'mdn'}"),
    ]  # fmt: skip
    for step in steps:
        code, _, err = run_cli(*step)
        assert code == 0, err
    return root / "mdn"


PREDICTED = ("plan-demos", "debug=tiny", "task=drawer", "model.source=predicted")


def test_predicted_model_is_planned_on_and_recorded(tiny_drawer_mdn: Path, tmp_path: Path) -> None:
    out = tmp_path / "predicted"
    code, _, err = run_cli(*PREDICTED, f"model.mdn={tiny_drawer_mdn}", f"out={out}")
    # a poor estimate may fail every demo: that is a result (with reasons), not an error
    assert code == 0, err
    info = json.loads((out / "demos.json").read_text())
    model = info["kinematic_model"]
    assert model["source"] == "predicted" and model["mdn"] == str(tiny_drawer_mdn / "model.pt")
    assert model["mdn_sha256"] == sha256_file(tiny_drawer_mdn / "model.pt")
    assert isinstance(model["refinement"]["refined"], bool) and model["refinement"]["status"]
    assert model["category"] == "drawer" and model["estimator"] == "most-likely"
    assert model["configuration_error_unit"] == "cm" and model["valid_pixels"] > 500
    pose = model["object_pose_in_camera"]
    assert pose["x"] == pytest.approx(1.5) and -0.8 <= pose["z"] <= 0.0
    for key in ("axis_position_error_cm", "axis_direction_error_deg", "configuration_error"):
        assert len(model[key]) == 1 and 0 <= model[key][0] < 1e3, key
    # the recorded errors are those of the recorded labels
    p, t = model["predicted"], model["true"]
    origin = [p[f"j0_origin_{a}"] - t[f"j0_origin_{a}"] for a in "xyz"]
    assert model["axis_position_error_cm"][0] == pytest.approx(
        100 * np.linalg.norm(origin), abs=1e-3
    )
    assert model["configuration_error"][0] == pytest.approx(
        100 * abs(p["j0_q"] - t["j0_q"]), abs=1e-3
    )
    assert t["pose_x"] == pytest.approx(1.5) and t["j0_q"] == 0.0
    for record in info["demos"]:
        assert record["status"] in ("ok", "failed")
        assert (record["status"] == "ok") == (record["reason"] == "")
        assert (record["file"] is None) == (record["status"] == "failed")
    manifest = read_manifest(out)
    assert manifest.inputs["mdn"].content_hash == read_manifest(tiny_drawer_mdn).content_hash
    assert manifest.inputs["mdn"].stage == "train-mdn"
    assert manifest.stats["kinematic model"] == "predicted"
    assert manifest.stats["axis position error (cm)"] == pytest.approx(
        model["axis_position_error_cm"][0], abs=1e-3
    )
    ok = sum(r["status"] == "ok" for r in info["demos"])
    assert manifest.stats["demos planned"] == ok
    # the view's sensor noise is seeded: the same run gives the same bytes
    again = tmp_path / "again"
    code, _, err = run_cli(*PREDICTED, f"model.mdn={tiny_drawer_mdn}", f"out={again}")
    assert code == 0, err
    assert (again / "demos.json").read_bytes() == (out / "demos.json").read_bytes()
    # another seed, another noisy view, another estimate
    other = tmp_path / "seed1"
    code, _, err = run_cli(*PREDICTED, f"model.mdn={tiny_drawer_mdn}", f"out={other}", "seed=1")
    assert code == 0, err
    model1 = json.loads((other / "demos.json").read_text())["kinematic_model"]
    assert model1["true"] == model["true"] and model1["predicted"] != model["predicted"]


def test_without_a_local_mdn_the_shipped_one_is_used(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Perception in the loop as a user runs it: no MDN trained here, the shipped drawer
    model estimates the drawer (refined), the demos are planned on its estimate."""
    monkeypatch.delenv("ARTIC_MODELS")
    shipped = models_dir() / "mdn" / "drawer" / "model.pt"
    out = tmp_path / "shipped"
    code, _, err = run_cli(*PREDICTED, f"artifacts_root={tmp_path / 'nowhere'}", f"out={out}")
    assert code == 0, err
    model = json.loads((out / "demos.json").read_text())["kinematic_model"]
    assert Path(model["mdn"]).resolve() == shipped.resolve()
    assert model["mdn_sha256"] == sha256_file(shipped)
    assert "mdn" not in read_manifest(out).inputs  # a shipped model is no stage output
    # the shipped model reads the simulated drawer within a few centimetres
    assert model["axis_position_error_cm"][0] < 10 and model["axis_direction_error_deg"][0] < 10


def test_predicted_model_file_missing_is_bad_input(tmp_path: Path) -> None:
    out = tmp_path / "bad"
    code, _, err = run_cli(*PREDICTED, f"model.mdn={tmp_path / 'nowhere.pt'}", f"out={out}")
    assert code == 2, err
    assert "model.mdn" in err and str(tmp_path / "nowhere.pt") in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_an_mdn_of_another_category_is_bad_input(tiny_depth: Path, tmp_path: Path) -> None:
    mdn = tmp_path / "microwave_mdn"
    code, _, err = run_cli(
        "train-mdn", "debug=tiny", "category=microwave", f"depth={tiny_depth}", f"out={mdn}"
    )
    assert code == 0, err
    out = tmp_path / "bad"
    code, _, err = run_cli(*PREDICTED, f"model.mdn={mdn}", f"out={out}")
    assert code == 2, err
    assert "a model of category microwave, not drawer" in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_a_view_the_mdn_was_not_trained_on_is_bad_input(
    tiny_drawer_mdn: Path, tmp_path: Path
) -> None:
    out = tmp_path / "bad"
    code, _, err = run_cli(
        *PREDICTED, f"model.mdn={tiny_drawer_mdn}", "model.camera.position=[0.7,0.0,0.75]",
        f"out={out}",
    )  # fmt: skip
    assert code == 2, err
    assert "model.camera" in err and "object x in the camera frame 0.5" in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_predicted_is_refused_for_the_tball(tmp_path: Path) -> None:
    out = tmp_path / "bad"
    code, _, err = run_cli("plan-demos", "debug=tiny", "task=tball", "model.source=predicted",
                           f"out={out}")  # fmt: skip
    assert code == 2, err
    assert "model.source" in err and "task tball has none" in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()
