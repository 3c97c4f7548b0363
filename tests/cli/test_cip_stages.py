"""The Chapter 7 stages on the tiny preset (grasp-candidates -> cip-demos -> train-cip on
the drawer): the task YAMLs mirror the registry, outputs, same command same bytes, an
interrupted train-cip resumes to the uninterrupted bytes, bad input exits 2."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from artic.artifacts.formats import read_npz
from artic.artifacts.manifest import read_manifest
from artic.learning.cip_train import CURVE_COLUMNS, DEMO_ARRAYS, SETTING_NAMES
from cli_runner import run_cli

TASKS = ["door", "drawer", "slide", "lever"]


class Chain:
    """The tiny chain's three output folders."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.grasps = root / "grasps"
        self.demos = root / "demos"
        self.policy = root / "policy"

    def train(self, out: Path, *args: str) -> tuple[int, str, str]:
        return run_cli("train-cip", "--task", "drawer", "debug=tiny",
                       f"initiation_set={self.grasps}", f"demos={self.demos}", f"out={out}",
                       *args)  # fmt: skip


@pytest.fixture(scope="module")
def chain(tmp_path_factory: pytest.TempPathFactory) -> Chain:
    chain = Chain(tmp_path_factory.mktemp("cip"))
    code, _, err = run_cli("grasp-candidates", "--task", "drawer", "debug=tiny",
                           f"out={chain.grasps}")  # fmt: skip
    assert code == 0, err
    code, _, err = run_cli("cip-demos", "--task", "drawer", "debug=tiny",
                           f"initiation_set={chain.grasps}", f"out={chain.demos}")  # fmt: skip
    assert code == 0, err
    code, _, err = chain.train(chain.policy)
    assert code == 0, err
    return chain


@pytest.mark.parametrize("task", TASKS)
def test_task_yaml_mirrors_the_registry(task):
    from artic.config.compose import compose, validate
    from artic.learning.cip_train import TrainCipConfig
    from artic.planning.cip_demos import CipDemosConfig, GraspCandidatesStageConfig
    from artic.sim.cip_tasks import get_cip_task

    expected = get_cip_task(task)
    grasps = validate(GraspCandidatesStageConfig, compose("grasp_candidates", [f"task={task}"]))
    demos = validate(CipDemosConfig, compose("cip_demos", [f"task={task}"]))
    train = validate(TrainCipConfig, compose("train_cip", [f"task={task}"]))
    assert grasps.task == expected and demos.task == expected
    assert train.task == expected.model_copy(update={"horizon": 150})  # experiment=cpu


def test_the_stage_yamls_hold_the_library_defaults():
    from artic.config.compose import compose, validate
    from artic.learning.cip_train import CipTrainConfig, HeadConfig, TrainCipConfig
    from artic.planning.cip_demos import CipDemosConfig, GraspCandidatesStageConfig
    from artic.planning.cip_expert import ExpertConfig
    from artic.planning.cip_grasps import GraspCandidatesConfig

    grasps = validate(GraspCandidatesStageConfig, compose("grasp_candidates", []))
    assert grasps.candidates == GraspCandidatesConfig() and grasps.grasps == 100
    demos = validate(CipDemosConfig, compose("cip_demos", []))
    assert demos.expert == ExpertConfig() and demos.demos == 10
    train = validate(TrainCipConfig, compose("train_cip", []))
    assert train.train == CipTrainConfig() and tuple(train.settings) == SETTING_NAMES
    assert train.head == HeadConfig() and train.head.execute == "teleport"


def test_cpu_experiment_is_the_default_and_paper_is_the_thesis_scale():
    from artic.config.compose import compose, validate
    from artic.learning.cip_train import TrainCipConfig

    default = validate(TrainCipConfig, compose("train_cip", ["task=lever"]))
    cpu = validate(TrainCipConfig, compose("train_cip", ["task=lever", "experiment=cpu"]))
    paper = validate(TrainCipConfig, compose("train_cip", ["task=lever", "experiment=paper"]))
    assert default == cpu
    t = cpu.train
    assert (cpu.seeds, t.episodes, cpu.task.horizon, t.eval_rollouts) == (1, 120, 150, 5)
    t = paper.train
    assert (paper.seeds, t.episodes, paper.task.horizon, t.eval_rollouts) == (10, 500, 250, 20)
    assert len(cpu.settings) * cpu.seeds == 7 and paper.task.name == "lever"


def test_grasp_candidates_writes_the_initiation_set_and_its_counts(chain):
    from artic.planning.cip_grasps import InitiationSet

    initiation_set = InitiationSet.from_json((chain.grasps / "initiation_set.json").read_text())
    stats = read_manifest(chain.grasps).stats
    assert initiation_set.task == "drawer" and stats["sampled"] == 20
    assert stats["holding"] == len(initiation_set.grasps) >= 1
    assert stats["reachable"] >= stats["collision_free"] >= stats["holding"]


def test_cip_demos_writes_every_episode_and_which_succeeded(chain):
    arrays = read_npz(chain.demos / "demos.npz", DEMO_ARRAYS)
    summary = json.loads((chain.demos / "summary.json").read_text())
    assert len(arrays["success"]) == summary["demos"] + summary["home_demos"] == 4
    assert arrays["from_home"].tolist() == [False, False, True, True]
    assert summary["succeeded"] == int(arrays["success"][:2].sum()) >= 1
    assert summary["succeeded_from_home"] == int(arrays["success"][2:].sum()) >= 1
    n = len(arrays["actions"])
    assert arrays["obs"].shape == arrays["next_obs"].shape == (n, 30)
    assert arrays["actions"].shape == (n, 13) and np.abs(arrays["actions"]).max() <= 1.0
    steps = [e["steps"] for e in summary["episodes"]]
    assert np.bincount(arrays["episode"], minlength=4).tolist() == steps
    home = np.isin(arrays["episode"], [2, 3])  # a reach from home, then the expert
    assert arrays["obs"][home][0, 23] > 0.05 > arrays["obs"][~home][0, 23]  # the opening
    assert read_manifest(chain.demos).inputs["initiation_set"].stage == "grasp-candidates"


def test_train_cip_writes_the_curve_policies_and_summary(chain):
    lines = (chain.policy / "learning_curve.csv").read_text().splitlines()
    assert lines[0] == ",".join(CURVE_COLUMNS)
    assert len(lines) == 1 + 7 * 2  # seven settings x one seed x two evaluations
    assert [ln.split(",")[:3] for ln in lines[1:3]] == [["e2e", "0", "2"], ["e2e", "0", "4"]]
    assert {ln.split(",")[0] for ln in lines[1:]} == set(SETTING_NAMES)
    for setting in SETTING_NAMES:
        record = torch.load(chain.policy / f"policies/{setting}/seed_000/policy.pt",
                            weights_only=True)  # fmt: skip
        assert (record["task"], record["setting"], record["seed"]) == ("drawer", setting, 0)
        assert record["state_dict"] and all(k.startswith("mu.") for k in record["state_dict"])
        home = setting in ("e2e", "e2e_bc")  # the head's state: UCB1's counts over I_c
        assert record["starts"] == {} if home else sum(record["starts"]["bandit"]["pulls"]) > 0
    summary = json.loads((chain.policy / "summary.json").read_text())
    assert set(summary["final"]) == set(SETTING_NAMES)
    manifest = read_manifest(chain.policy)
    assert set(manifest.inputs) == {"initiation_set", "demos"}
    assert manifest.choices["experiment"] == "cpu" and manifest.choices["debug"] == "tiny"


def test_same_command_same_bytes(chain, tmp_path):
    code, _, err = chain.train(tmp_path / "again")
    assert code == 0, err
    for name in ("learning_curve.csv", "policies/cip_bc/seed_000/policy.pt"):
        assert (tmp_path / "again" / name).read_bytes() == (chain.policy / name).read_bytes()


def test_interrupted_training_resumes_to_the_uninterrupted_bytes(chain, tmp_path, monkeypatch):
    import artic.learning.cip_train as cip_train

    original = cip_train.curve_row
    calls: list[tuple[str, int]] = []

    def interrupt(setting: str, seed: int, episode: int, *args: Any, **kwargs: Any) -> Any:
        calls.append((setting, episode))
        if (setting, episode) == ("cip_bc", 4):  # its first block is checkpointed
            raise KeyboardInterrupt
        return original(setting, seed, episode, *args, **kwargs)

    monkeypatch.setattr(cip_train, "curve_row", interrupt)
    out = tmp_path / "resumed"
    code, _, err = chain.train(out)
    assert code == 130 and "resume" in err and not out.exists()
    calls.clear()
    monkeypatch.setattr(cip_train, "curve_row", lambda s, *a, **k: calls.append((s, a[1]))
                        or original(s, *a, **k))  # fmt: skip
    code, _, err = chain.train(out)
    assert code == 0, err
    assert calls == [("cip_bc", 4), ("e2e_bc", 2), ("e2e_bc", 4)], "resumed at cip_bc's block 2"
    assert (out / "learning_curve.csv").read_bytes() == (
        chain.policy / "learning_curve.csv"
    ).read_bytes()
    for setting in ("cip_bc", "e2e_bc"):
        path = f"policies/{setting}/seed_000/policy.pt"
        a = torch.load(chain.policy / path, weights_only=True)["state_dict"]
        b = torch.load(out / path, weights_only=True)["state_dict"]
        assert all(torch.equal(a[k], b[k]) for k in a)


def test_a_tracked_head_trains_and_repeats_its_bytes(chain, tmp_path):
    """head.execute=track through the stage: the CIP run's episodes start from home
    along a plan (other starts than the teleporting run's, so another curve), and the
    same command gives the same bytes."""
    runs = [tmp_path / "track", tmp_path / "again"]
    for out in runs:
        code, _, err = chain.train(out, "settings=[cip]", "head.execute=track")
        assert code == 0, err
    curves = [(out / "learning_curve.csv").read_bytes() for out in runs]
    assert curves[0] == curves[1]
    teleport = (chain.policy / "learning_curve.csv").read_text().splitlines()
    tracked = curves[0].decode().splitlines()
    assert tracked[1:] != [row for row in teleport if row.startswith("cip,")]


def _bad_cases(chain: Chain) -> dict[str, tuple[list[str], str]]:
    door = ["train-cip", "--task", "door", "debug=tiny"]
    drawer = ["train-cip", "--task", "drawer", "debug=tiny"]
    return {
        "unknown task": (["train-cip", "--task", "sofa"], "task/sofa"),
        "Chapter 5 task": (["train-cip", "--task", "microwave"], "task.name"),
        "unknown setting": ([*drawer, "settings=[e3e]"], "settings.0"),
        "repeated setting": ([*drawer, "settings=[cip,cip]"], "settings"),
        "episodes not whole blocks": ([*drawer, "train.episodes=5"], "episodes"),
        "unknown head": ([*drawer, "head.execute=fly"], "head.execute"),
        "demos null": ([*drawer, "settings=[e2e_bc]", "demos=null"], "demos"),
        "initiation set null": ([*drawer, "settings=[mv]", "initiation_set=null"],
                                "initiation_set"),
        "missing demos": ([*drawer, "settings=[cip_bc]", f"initiation_set={chain.grasps}",
                           f"demos={chain.root / 'absent'}"], "absent"),
        "initiation set of another task": (
            [*door, "settings=[cip]", f"initiation_set={chain.grasps}"], "holds task 'drawer'"),
        "demos of another task": ([*door, "settings=[e2e_bc]", f"demos={chain.demos}"],
                                  "holds task 'drawer'"),
        "another object": ([*drawer, "settings=[cip]", "task.object.x=1.0",
                            f"initiation_set={chain.grasps}"], "task.object"),
        "demos as initiation set": (["cip-demos", "--task", "drawer",
                                     f"initiation_set={chain.demos}"], "grasp-candidates"),
        "no grasp left": (["grasp-candidates", "--task", "drawer", "grasps=3",
                           "candidates.clearance_m=1.0"], "no grasp left after filtering"),
    }  # fmt: skip


@pytest.mark.parametrize("name", list(_bad_cases(Chain(Path("."))).keys()))
def test_bad_input_exits_2_with_one_line(chain, tmp_path, name):
    args, fragment = _bad_cases(chain)[name]
    code, _, err = run_cli(*args, f"out={tmp_path / 'bad'}")
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, (name, err)
    assert len(lines) == 1 and fragment in lines[0], (name, err)
    assert not (tmp_path / "bad").exists() and not (tmp_path / "bad.partial").exists()


def test_e2e_bc_needs_demonstrations_from_home(chain, tmp_path):
    demos = tmp_path / "demos"
    code, _, err = run_cli("cip-demos", "--task", "drawer", "debug=tiny", "home_demos=0",
                           f"initiation_set={chain.grasps}", f"out={demos}")  # fmt: skip
    assert code == 0, err
    code, _, err = run_cli("train-cip", "--task", "drawer", "debug=tiny", "settings=[e2e_bc]",
                           f"initiation_set={chain.grasps}", f"demos={demos}",
                           f"out={tmp_path / 'policy'}")  # fmt: skip
    assert code == 2 and "no successful demonstration from home (0 of 0)" in err, err
    assert not (tmp_path / "policy").exists()
