"""`artic train-rmp` on the tiny preset: outputs, determinism, exact resume, bad input."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from cli_runner import run_cli

TINY = ("debug=tiny", "task.horizon=8", "ppo.steps_per_epoch=32", "ppo.train_iters=2")


def train(out: Path, *args: str) -> tuple[int, str, str]:
    return run_cli("train-rmp", *TINY, f"out={out}", *args)


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("train_rmp") / "push"
    code, _, err = train(out, "--task", "push", "epochs=3")
    assert code == 0, err
    return out


def test_writes_curve_forces_policies_and_summary(reference):
    lines = (reference / "learning_curve.csv").read_text().splitlines()
    assert lines[0].startswith("controller,seed,epoch,steps,episodes,return_mean")
    assert len(lines) == 1 + 2 * 3  # two controllers x one seed x three epochs
    assert {ln.split(",")[0] for ln in lines[1:]} == {"vices", "rmp_vices"}
    assert lines[-1].split(",")[3] == str(3 * 32)  # steps so far
    for controller in ("vices", "rmp_vices"):
        record = torch.load(reference / f"policies/{controller}/seed_000/policy.pt",
                            weights_only=True)  # fmt: skip
        assert record["task"] == "push" and record["controller"] == controller
    assert (reference / "forces.csv").read_text().startswith("controller,seed,epoch,force")
    assert (reference / "manifest.json").is_file()


def test_training_leaves_nothing_in_the_temporary_folder(tmp_path, monkeypatch):
    """SB3's default logger makes an SB3-<time> folder in the system's temporary folder at
    every learn() call; artic sets its own (it writes its own rows)."""
    import tempfile

    scratch = tmp_path / "system_tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    code, _, err = train(tmp_path / "out", "--task", "push", "epochs=2")
    assert code == 0, err
    assert not list(scratch.glob("SB3-*"))


def test_same_config_same_bytes(reference, tmp_path):
    code, _, err = train(tmp_path / "again", "--task", "push", "epochs=3")
    assert code == 0, err
    for name in ("learning_curve.csv", "forces.csv", "policies/rmp_vices/seed_000/policy.pt"):
        assert (tmp_path / "again" / name).read_bytes() == (reference / name).read_bytes()


def test_interrupted_training_resumes_to_the_uninterrupted_bytes(reference, tmp_path, monkeypatch):
    import artic.learning.rmp_train as rmp_train

    original = rmp_train.epoch_seed
    calls: list[int] = []

    def interrupt_third(seed: int, epoch: int) -> int:
        calls.append(epoch)
        if len(calls) == 3:  # vices, epoch 2: epochs 0 and 1 are checkpointed
            raise KeyboardInterrupt
        return original(seed, epoch)

    monkeypatch.setattr(rmp_train, "epoch_seed", interrupt_third)
    out = tmp_path / "resumed"
    code, _, err = train(out, "--task", "push", "epochs=3")
    assert code == 130 and "resume" in err and not out.exists()
    calls.clear()
    monkeypatch.setattr(rmp_train, "epoch_seed", lambda s, e: calls.append(e) or original(s, e))
    code, _, err = train(out, "--task", "push", "epochs=3")
    assert code == 0, err
    assert calls[:1] == [2], "the first run continued at epoch 2"
    for name in ("learning_curve.csv", "forces.csv"):
        assert (out / name).read_bytes() == (reference / name).read_bytes()
    for controller in ("vices", "rmp_vices"):
        a = torch.load(reference / f"policies/{controller}/seed_000/policy.pt", weights_only=True)
        b = torch.load(out / f"policies/{controller}/seed_000/policy.pt", weights_only=True)
        assert all(torch.equal(a["state_dict"][k], b["state_dict"][k]) for k in a["state_dict"])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--task", "drawer"), "task.name"),
        (("--task", "sofa"), "task/sofa"),
        (("controllers=[osc]",), "controllers"),
        (("vices.kp_min=400",), "kp_min"),
        (("task.obstacles.radius=0",), "task.obstacles.radius"),
        (("runtime.threads=2",), "runtime"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path, args, message):
    code, _, err = train(tmp_path / "bad", *args)
    assert code == 2, err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "bad").exists()


@pytest.mark.parametrize("task", ["traj", "door", "push"])
def test_cpu_experiment_is_the_default_and_paper_is_the_thesis_scale(task):
    from artic.config.compose import compose, validate
    from artic.learning.rmp_train import TrainRmpConfig

    default = validate(TrainRmpConfig, compose("train_rmp", [f"task={task}"]))
    cpu = validate(TrainRmpConfig, compose("train_rmp", [f"task={task}", "experiment=cpu"]))
    paper = validate(TrainRmpConfig, compose("train_rmp", [f"task={task}", "experiment=paper"]))
    assert default == cpu
    assert (cpu.seeds, cpu.epochs, cpu.task.horizon) == (2, 20, 256)
    assert (paper.seeds, paper.epochs, paper.task.horizon) == (10, 367, 1024)
    assert paper.epochs * paper.ppo.steps_per_epoch == 1_503_232
    assert cpu.task.name == task


@pytest.mark.parametrize("task", ["traj", "door", "push"])
def test_task_yaml_mirrors_the_registry(task):
    from artic.config.compose import compose, validate
    from artic.learning.rmp_train import TrainRmpConfig
    from artic.sim.rmp_tasks import get_rmp_task

    cfg = validate(TrainRmpConfig, compose("train_rmp", [f"task={task}"]))
    assert cfg.task == get_rmp_task(task).model_copy(update={"horizon": 256})
