"""policy-search and evaluate-bootstrap end to end through the CLI on the tiny preset.

Inputs are made here: a plan-demos folder of smooth joint-space demos from the task's
start configuration (written with the real manifest model), and the real fit-dmp stage
run on it.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from artic.artifacts.formats import write_json, write_npz
from artic.artifacts.manifest import (
    MANIFEST,
)
from artic.sim.tasks import get_task
from cli_runner import run_cli
from fake_outputs import write_manifest

DT = 0.05


def _demo(task: str, k: int, n_joints: int, steps: int = 12) -> dict[str, np.ndarray]:
    cfg = get_task(task)
    t = np.arange(steps) * DT
    s = t / t[-1]
    shape = 10 * s**3 - 15 * s**4 + 6 * s**5
    start = np.array(cfg.robot.start_q)[:n_joints]
    goal = start + np.linspace(0.3, -0.3, n_joints) + 0.01 * k
    q = start + (goal - start) * shape[:, None]
    q_object = cfg.object_start[0] + (cfg.goal[0] - cfg.object_start[0]) * shape
    qd = np.gradient(q, t, axis=0)
    pose = np.tile(np.eye(4), (steps, 1, 1))
    return {"t": t, "q_robot": q, "qd_robot": qd, "q_object": q_object[:, None], "ee_pose": pose}


def write_plan_demos(folder: Path, task: str, n_joints: int = 7, n_ok: int = 2) -> Path:
    folder.mkdir(parents=True)
    entries = []
    for k in range(n_ok):
        write_npz(folder / f"demo_{k:03d}.npz", _demo(task, k, n_joints))
        entries.append({"index": k, "file": f"demo_{k:03d}.npz", "status": "ok", "reason": "",
                        "planning_time_s": 0.1, "steps": 12})  # fmt: skip
    write_json(folder / "demos.json", {
        "task": task, "n_requested": n_ok, "control_dt": DT, "n_joints": n_joints,
        "kinematic_model": {"source": "true"}, "planner": "RRTConnect", "demos": entries,
    })  # fmt: skip
    config = {"task": {"name": task}, "out": str(folder), "model": {"source": "true"},
              "execute": {"gain": 5.0}}  # fmt: skip
    write_manifest(folder, "plan-demos", config)
    return folder


def fit_dmp(demos: Path, out: Path, task: str) -> Path:
    code, _, err = run_cli("fit-dmp", "debug=tiny", f"task={task}", f"demos={demos}", f"out={out}")
    assert code == 0, err
    return out


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("ch5")
    drawer = write_plan_demos(root / "demos" / "drawer", "drawer")
    microwave = write_plan_demos(root / "demos" / "microwave", "microwave")
    six = write_plan_demos(root / "demos" / "six", "drawer", n_joints=6)
    return {
        "drawer_demos": drawer,
        "microwave_demos": microwave,
        "drawer_dmp": fit_dmp(drawer, root / "dmp" / "drawer", "drawer"),
        "microwave_dmp": fit_dmp(microwave, root / "dmp" / "microwave", "microwave"),
        "six_dmp": fit_dmp(six, root / "dmp" / "six", "drawer"),
    }


def search(out: Path, *args: str) -> tuple[int, str, str]:
    return run_cli("policy-search", "debug=tiny", f"out={out}", *args)


def read_curve(folder: Path) -> list[dict[str, str]]:
    with (folder / "learning_curve.csv").open(newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def drawer_runs(inputs, tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("policy")
    runs = {}
    for init in ("bootstrap", "random"):
        out = root / init
        code, _, err = search(out, "task=drawer", f"init={init}", f"dmp={inputs['drawer_dmp']}")
        assert code == 0, err
        runs[init] = out
    return runs


def test_pi2cma_writes_curve_final_dmps_and_summary(drawer_runs):
    out = drawer_runs["bootstrap"]
    rows = read_curve(out)
    assert [(r["seed"], r["update"], r["rollouts"]) for r in rows] == [
        (str(s), str(u), str(3 * u)) for s in range(2) for u in range(3)
    ]
    for r in rows:
        assert float(r["mean_return"]) < 0 and 0 <= float(r["success_rate"]) <= 1
        # the normalised return is 1 - R / R_idle with R_idle < 0
        assert float(r["normalised_return"]) <= 1
        # the share of the update's exploration rollouts touching the drawer; none at 0
        touch = float(r["touch_rate"])
        assert np.isnan(touch) if r["update"] == "0" else touch in (0, 1 / 3, 2 / 3, 1)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["algorithm"] == "pi2cma" and summary["init"] == "bootstrap"
    assert summary["final_policies"] == ["seeds/seed_000/dmp.json", "seeds/seed_001/dmp.json"]
    final = json.loads((out / "seeds/seed_000/dmp.json").read_text())
    other = json.loads((out / "seeds/seed_001/dmp.json").read_text())
    assert final["task"] == "drawer" and np.array(final["weights"]).shape == (7, 10)
    assert final["weights"] != other["weights"], "each seed searched on its own"
    manifest = json.loads((out / MANIFEST).read_text())
    assert set(manifest["inputs"]) == {"dmp"}
    assert "learning_curve.csv" in manifest["outputs"] and "timings.csv" in manifest["outputs"]


def test_random_init_uses_no_input_and_starts_at_the_robot_start(drawer_runs):
    out = drawer_runs["random"]
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["inputs"] == {}
    summary = json.loads((out / "summary.json").read_text())
    assert "weights ~ N(0" in summary["random_init"]
    first = [r for r in read_curve(out) if r["update"] == "0"]
    # a random DMP from the start configuration barely moves the drawer: close to idle
    assert all(abs(float(r["normalised_return"])) < 0.2 for r in first)


def test_policy_search_is_deterministic(inputs, drawer_runs, tmp_path):
    out = tmp_path / "again"
    code, _, err = search(out, "task=drawer", f"dmp={inputs['drawer_dmp']}")
    assert code == 0, err
    a, b = drawer_runs["bootstrap"], out
    for name in ("learning_curve.csv", "seeds/seed_000/dmp.json", "seeds/seed_001/dmp.json"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    code, _, err = search(
        tmp_path / "other", "task=drawer", f"dmp={inputs['drawer_dmp']}", "seed=1"
    )
    assert code == 0, err
    assert (tmp_path / "other/learning_curve.csv").read_bytes() != (
        a / "learning_curve.csv"
    ).read_bytes()


def test_interrupted_search_resumes_from_the_last_update(
    inputs, drawer_runs, tmp_path, monkeypatch
):
    from artic.learning.search import Evaluator

    calls: list[int] = []
    original = Evaluator.row

    def interrupt_third(self, *args, **kwargs):
        calls.append(args[1])
        if len(calls) == 3:  # seed 0, update 2: updates 0 and 1 are checkpointed
            raise KeyboardInterrupt
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Evaluator, "row", interrupt_third)
    out = tmp_path / "resumed"
    args = ("task=drawer", f"dmp={inputs['drawer_dmp']}")
    code, _, err = search(out, *args)
    assert code == 130 and "resume" in err and not out.exists()
    calls.clear()
    monkeypatch.setattr(Evaluator, "row", original)
    seen: list[int] = []

    def record(self, *a, **k):
        seen.append(a[1])
        return original(self, *a, **k)

    monkeypatch.setattr(Evaluator, "row", record)
    code, _, err = search(out, *args)
    assert code == 0, err
    assert seen[:1] == [2], "seed 0 continued at update 2"
    ref = drawer_runs["bootstrap"]
    for name in ("learning_curve.csv", "seeds/seed_000/dmp.json"):
        assert (out / name).read_bytes() == (ref / name).read_bytes(), "resumed = uninterrupted"


def test_dapg_from_demos_and_npg_from_random_on_the_microwave(inputs, tmp_path):
    runs = {}
    for init in ("bootstrap", "random"):
        out = tmp_path / init
        code, _, err = search(out, "task=microwave", f"init={init}",
                              f"demos={inputs['microwave_demos']}")  # fmt: skip
        assert code == 0, err
        summary = json.loads((out / "summary.json").read_text())
        assert summary["algorithm"] == "dapg" and summary["policy"] == "gaussian_mlp"
        saved = torch.load(out / "seeds/seed_000/policy.pt", weights_only=True)
        assert saved["hparams"]["hidden"] == [32, 32] and saved["hparams"]["obs_dim"] == 8
        runs[init] = saved
    # behaviour cloning standardised the inputs with the demos' statistics; random did not
    assert not torch.equal(runs["bootstrap"]["state_dict"]["obs_shift"], torch.zeros(8))
    assert torch.equal(runs["random"]["state_dict"]["obs_shift"], torch.zeros(8))
    # the same run with two torch threads (the default is one): the same bytes
    again = tmp_path / "again"
    code, _, err = search(
        again, "task=microwave", f"demos={inputs['microwave_demos']}", "runtime.threads=2"
    )
    assert code == 0, err
    assert (again / "learning_curve.csv").read_bytes() == (
        tmp_path / "bootstrap/learning_curve.csv"
    ).read_bytes()
    b = torch.load(again / "seeds/seed_001/policy.pt", weights_only=True)["state_dict"]
    a = torch.load(tmp_path / "bootstrap/seeds/seed_001/policy.pt", weights_only=True)["state_dict"]
    assert all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("task=drawer", "dmp={microwave_dmp}"), "holds DMPs of task 'microwave'"),
        (("task=drawer", "dmp={six_dmp}"), "has 6 joints"),
        (("task=drawer", "dmp={drawer_demos}"), "expected a 'fit-dmp' output"),
        (("task=microwave", "demos={drawer_demos}"), "holds demos of task 'drawer'"),
        (("task=drawer", "dmp=/no/such/folder"), "no such folder"),
        (("task=drawer", "init=scratch"), "init"),
        (("task=drawer", "rollouts=1"), "rollouts"),
    ],
)
def test_bad_input_exits_2_with_one_line(inputs, tmp_path, args, message):
    filled = [a.format(**{k: str(v) for k, v in inputs.items()}) for a in args]
    code, _, err = search(tmp_path / "out", *filled)
    assert code == 2, err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_evaluate_bootstrap_writes_curves_success_and_report(drawer_runs, tmp_path):
    out = tmp_path / "report"
    code, _, err = run_cli("evaluate", "bootstrap", "debug=tiny", "task=drawer",
                           f"bootstrap={drawer_runs['bootstrap']}",
                           f"random={drawer_runs['random']}", f"out={out}")  # fmt: skip
    assert code == 0, err
    for name in ("curves.csv", "curves.png", "episodes.csv", "success.csv", "report.md",
                 "summary.csv", "fig5_3.png"):  # fmt: skip
        assert (out / name).is_file(), name
    with (out / "curves.csv").open(newline="") as f:
        curves = list(csv.DictReader(f))
    assert [(c["init"], c["update"]) for c in curves] == [
        (i, str(u)) for i in ("bootstrap", "random") for u in range(3)
    ]
    boot = [r for r in read_curve(drawer_runs["bootstrap"]) if r["update"] == "2"]
    expected = np.mean([float(r["normalised_return"]) for r in boot])
    assert float(curves[2]["mean"]) == pytest.approx(expected)
    assert float(curves[2]["touch_rate"]) == pytest.approx(
        np.mean([float(r["touch_rate"]) for r in boot])
    )
    with (out / "success.csv").open(newline="") as f:
        success = list(csv.DictReader(f))
    assert [s["episodes"] for s in success] == ["4", "4"]
    # summary.csv: the columns, one row per init, what the curves and files say
    with (out / "summary.csv").open(newline="") as f:
        reader = csv.DictReader(f)
        summary = list(reader)
    assert reader.fieldnames == ["task", "init", "baseline", "model_source", "demo_success",
                                 "success_update_10", "final_success", "return_update_0",
                                 "return_update_50"]  # fmt: skip
    b, r = summary
    assert (b["task"], b["init"], b["baseline"], b["model_source"]) == (
        "drawer",
        "bootstrap",
        "",
        "true",
    )
    assert (r["init"], r["baseline"], r["model_source"], r["demo_success"]) == (
        "random",
        "exploring",
        "",
        "",
    )
    # the tiny runs have 2 updates: no update 10 or 50
    assert b["success_update_10"] == b["return_update_50"] == ""
    assert float(b["return_update_0"]) == pytest.approx(float(curves[0]["mean"]), abs=1e-4)
    assert float(b["final_success"]) == float(success[0]["success_rate"])
    report = (out / "report.md").read_text()
    assert "beats random at every update" in report and "| 2 |" in report
    # the inputs swapped: refused
    bad = f"out={tmp_path / 'bad'}"
    code, _, err = run_cli("evaluate", "bootstrap", "debug=tiny", "task=drawer",
                           f"bootstrap={drawer_runs['random']}",
                           f"random={drawer_runs['bootstrap']}", bad)  # fmt: skip
    assert code == 2 and "init=random" in err
    code, _, err = run_cli("evaluate", "bootstrap", "debug=tiny", "task=microwave",
                           f"bootstrap={drawer_runs['bootstrap']}",
                           f"random={drawer_runs['random']}", bad)  # fmt: skip
    assert code == 2 and "expected 'microwave'" in err


def test_interrupted_dapg_resumes_to_the_same_policy(inputs, tmp_path, monkeypatch):
    from artic.learning.search import Evaluator

    args = ("task=microwave", f"demos={inputs['microwave_demos']}", "seeds=1")
    code, _, err = search(tmp_path / "ref", *args)
    assert code == 0, err
    original = Evaluator.row
    calls: list[int] = []

    def interrupt_third(self, *a, **k):
        calls.append(a[1])
        if len(calls) == 3:
            raise KeyboardInterrupt
        return original(self, *a, **k)

    monkeypatch.setattr(Evaluator, "row", interrupt_third)
    code, _, err = search(tmp_path / "resumed", *args)
    assert code == 130, err
    monkeypatch.setattr(Evaluator, "row", original)
    code, _, err = search(tmp_path / "resumed", *args)
    assert code == 0, err
    ref, out = tmp_path / "ref", tmp_path / "resumed"
    assert (out / "learning_curve.csv").read_bytes() == (ref / "learning_curve.csv").read_bytes()
    a = torch.load(ref / "seeds/seed_000/policy.pt", weights_only=True)["state_dict"]
    b = torch.load(out / "seeds/seed_000/policy.pt", weights_only=True)["state_dict"]
    assert all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("task", ["drawer", "microwave", "tball"])
def test_cpu_experiment_is_the_default_and_paper_has_twenty_seeds(task):
    from artic.cli.policy_search import PolicySearchConfig
    from artic.config.compose import compose, validate

    default = compose("policy_search", [f"task={task}"])
    assert compose("policy_search", [f"task={task}", "experiment=cpu"]) == default
    paper = validate(
        PolicySearchConfig, compose("policy_search", [f"task={task}", "experiment=paper"])
    )
    assert (paper.seeds, paper.updates, paper.rollouts) == (20, 50, 20)
    cfg = validate(PolicySearchConfig, default)
    # the schema's defaults are the yaml's (the Figure 5.2 CPU configuration)
    assert (cfg.rollouts, cfg.mlp_policy.npg.step_size) == (20, 0.1)
    fields = PolicySearchConfig.model_fields
    assert fields["rollouts"].default == cfg.rollouts
