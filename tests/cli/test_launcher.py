"""`artic pipeline NAME launcher=local|slurm` (cli/launcher.py): submitit's local executor
gives the bytes of launcher=inline, with a sharded stage's shards at once; a killed shard
is all a resubmission runs; the sbatch scripts of ch3_paper, checked with a fake `sbatch`;
bad launcher input exits 2 with one line and submits nothing; ch7's at paper scale before its
inputs exist."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_stages import tree_bytes

from artic.artifacts.job_records import JOBS_JSON, read_jobs
from artic.config.launcher import split_launcher_args
from cli_runner import run_cli

# objects as 4 shards at once (6 chunks of one object), then a stage reading them
SHARDED = """
stages:
  objects:
    cmd: generate-dataset
    overrides: [debug=tiny, category=microwave, dataset.chunk_size=1, out=out/objects]
    outs: [out/objects]
    resources: {shards: 4}
  depth:
    cmd: render-depth
    overrides: [debug=tiny, dataset=out/objects, out=out/depth]
    deps: [out/objects]
    outs: [out/depth]
"""
OUTS = ("out/objects", "out/depth")


def _pipeline(folder: Path, text: str = SHARDED) -> str:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "p.yaml"
    path.write_text(text)
    return str(path)


@pytest.fixture(scope="module")
def inline_run(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, bytes]]:
    """The data files of the pipeline run with launcher=inline."""
    folder = tmp_path_factory.mktemp("inline")
    cwd = Path.cwd()
    os.chdir(folder)
    try:
        code, _, err = run_cli("pipeline", _pipeline(folder))
    finally:
        os.chdir(cwd)
    assert code == 0, err
    return {out: tree_bytes(folder / out) for out in OUTS}


def _jobs(folder: Path, out: str) -> list[tuple[str, int]]:
    """(role, shard) of the jobs of the last submission of `out`."""
    record = read_jobs(folder / out)
    return [(j["role"], j["shard"]) for j in record["submissions"][-1]["jobs"]]


def test_local_launcher_gives_the_bytes_of_inline(tmp_path, monkeypatch, inline_run):
    """Each job a separate process (submitit's local executor), the 4 shards at once."""
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli("pipeline", _pipeline(tmp_path), "launcher=local")
    assert code == 0, err
    for out in OUTS:
        assert tree_bytes(tmp_path / out) == inline_run[out], out
    assert _jobs(tmp_path, "out/objects") == [
        ("shard", 0),
        ("shard", 1),
        ("shard", 2),
        ("shard", 3),
        ("publish", 0),
    ]
    assert _jobs(tmp_path, "out/depth") == [("stage", 0)]
    logs = sorted(p.name for p in (tmp_path / "out/objects.jobs").glob("*_log.err"))
    assert len(logs) == 5  # each job's stderr beside the stage's work folder
    # up to date: a second launch submits nothing
    code, _, err = run_cli("pipeline", _pipeline(tmp_path), "launcher=local")
    assert code == 0 and "nothing submitted" in err
    code, out, err = run_cli("pipeline", _pipeline(tmp_path), "--status")
    assert code == 0, err
    assert out.count(" done ") == 2


def _launch(folder: Path) -> subprocess.Popen[bytes]:
    args = [sys.executable, "-m", "artic", "pipeline", "p.yaml", "launcher=local"]
    return subprocess.Popen(args, cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _job_of_shard(folder: Path, shard: int, proc: subprocess.Popen[bytes]) -> str:
    """The id of shard `shard`'s job of out/objects, as soon as the launcher records it
    (the launch failing or hanging first fails the test)."""
    end = time.monotonic() + 300
    while True:
        record = read_jobs(folder / "out/objects")
        for job in (record.get("submissions") or [{}])[-1].get("jobs", []):
            if job["role"] == "shard" and job["shard"] == shard:
                return str(job["id"])
        assert proc.poll() is None, proc.communicate()[1].decode()
        assert time.monotonic() < end, "the launcher never recorded the job"
        time.sleep(0.01)


def test_a_killed_shard_is_all_a_resubmission_runs(tmp_path, inline_run):
    """SIGTERM (what scancel sends) to shard.index=1's job as soon as it is submitted: the
    publish job names the shard, --status shows it and the job's last log lines, and the
    next launch runs that shard alone, to the bytes of launcher=inline."""
    _pipeline(tmp_path)
    proc = _launch(tmp_path)
    os.kill(int(_job_of_shard(tmp_path, 1, proc)), signal.SIGTERM)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 1, err.decode()
    message = err.decode().strip().splitlines()[-1]
    assert "shard.index 1 (shard.count=4) did not finish" in message and "objects.jobs" in message
    assert not (tmp_path / "out/objects").exists() and not (tmp_path / "out/depth").exists()

    code, out, err2 = _status(tmp_path)
    assert code == 0, err2
    row = next(line for line in out.splitlines() if line.startswith("│ objects"))
    assert "failed" in row and "missing shard.index 1" in " ".join(out.split())
    assert "waiting" in out  # depth: its input is not made
    assert "did not finish" in out  # the publish job's last log lines

    proc = _launch(tmp_path)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err.decode()
    assert _jobs(tmp_path, "out/objects") == [("shard", 1), ("publish", 0)]
    assert len(read_jobs(tmp_path / "out/objects")["submissions"]) == 2
    for out_dir in OUTS:
        assert tree_bytes(tmp_path / out_dir) == inline_run[out_dir], out_dir


def _status(folder: Path) -> tuple[int, str, str]:
    args = [sys.executable, "-m", "artic", "pipeline", "p.yaml", "--status"]
    env = {**os.environ, "COLUMNS": "200"}
    done = subprocess.run(args, cwd=folder, capture_output=True, text=True, env=env, timeout=300)
    return done.returncode, done.stdout, done.stderr


# -- SLURM without a cluster: a fake sbatch that records its scripts ---------------------

FAKE_SBATCH = """#!/bin/sh
n=$(( $(cat "$FAKE_SLURM/count" 2>/dev/null || echo 100) + 1 ))
echo $n > "$FAKE_SLURM/count"
cp "$1" "$FAKE_SLURM/$n.sh"
echo "Submitted batch job $n"
"""


@pytest.fixture
def fake_slurm(tmp_path, monkeypatch) -> Path:
    """`sbatch` (records each script as <job id>.sh and prints the id) and `srun` on PATH."""
    bin_dir, record = tmp_path / "bin", tmp_path / "slurm"
    bin_dir.mkdir()
    record.mkdir()
    (bin_dir / "sbatch").write_text(FAKE_SBATCH)
    (bin_dir / "srun").write_text("#!/bin/sh\nexit 0\n")
    for tool in ("sbatch", "srun"):
        (bin_dir / tool).chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.setenv("FAKE_SLURM", str(record))
    return record


def _scripts(record: Path) -> dict[str, dict[str, str]]:
    """job id -> {sbatch option: value} of every recorded script."""
    scripts = {}
    for path in record.glob("*.sh"):
        options = dict(re.findall(r"^#SBATCH --([\w-]+)=(.*)$", path.read_text(), re.MULTILINE))
        scripts[path.stem] = options
    return scripts


def test_ch3_paper_sbatch_scripts(tmp_path, monkeypatch, fake_slurm):
    """One submission: per category the objects job, depth as an array of 8 plus its
    publish job (afterany the array), training on a GPU after the depth's publish job,
    the evaluation after training and depth; scripts and job ids beside the outputs."""
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli("pipeline", "ch3_paper", "launcher=slurm", "launcher.partition=gpu")
    assert code == 0, err
    scripts = _scripts(fake_slurm)
    by_name: dict[str, list[tuple[str, dict[str, str]]]] = {}
    for job_id, options in scripts.items():
        by_name.setdefault(options["job-name"].removeprefix("artic-"), []).append((job_id, options))
    categories = ("cabinet", "drawer", "microwave", "toaster", "cabinet2", "refrigerator")
    assert len(scripts) == 5 * len(categories)
    for c in categories:
        ((objects_id, objects),) = by_name[f"objects-{c}"]
        (array_id, array), (publish_id, publish) = sorted(by_name[f"depth-{c}"])
        ((train_id, train),) = by_name[f"train-{c}"]
        ((_, evaluate),) = by_name[f"evaluate-{c}"]
        assert "dependency" not in objects and "array" not in objects
        assert array["array"] == "0-7%8" and array["dependency"] == f"afterok:{objects_id}"
        assert publish["dependency"] == f"afterany:{array_id}" and "array" not in publish
        assert train["gpus-per-node"] == "1" and train["time"] == "1440"
        assert train["dependency"] == f"afterok:{publish_id}"
        assert sorted(evaluate["dependency"].removeprefix("afterok:").split(":")) == sorted(
            [publish_id, train_id]
        )
        assert evaluate["gpus-per-node"] == "0" and evaluate["cpus-per-task"] == "8"
        assert {s["partition"] for _, s in by_name[f"depth-{c}"]} == {"gpu"}
        jobs = read_jobs(tmp_path / f"artifacts/paper/depth/{c}")["submissions"][-1]["jobs"]
        assert [j["id"] for j in jobs] == [f"{array_id}_{i}" for i in range(8)] + [publish_id]


def test_ch7_paper_sbatch_scripts(tmp_path, monkeypatch, fake_slurm):
    """Chapter 7 at paper scale, submitted before any input exists: train-cip's and
    compose's `shards: chunks` come from the config alone (7 settings x 10 seeds, 50
    trials), each stage after the jobs that make its inputs."""
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli("pipeline", "ch7", "experiment=paper", "launcher=slurm")
    assert code == 0, err
    by_name: dict[str, list[tuple[str, dict[str, str]]]] = {}
    for job_id, options in _scripts(fake_slurm).items():
        by_name.setdefault(options["job-name"].removeprefix("artic-"), []).append((job_id, options))
    tasks = ("door", "drawer", "slide", "lever")
    assert sum(len(jobs) for jobs in by_name.values()) == 4 * len(tasks) + 1 + 2
    published = {}
    for t in tasks:
        ((grasps_id, grasps),) = by_name[f"grasps-{t}"]
        ((demos_id, demos),) = by_name[f"demos-{t}"]
        (array_id, array), (publish_id, publish) = sorted(by_name[f"train-{t}"])
        assert "dependency" not in grasps and demos["dependency"] == f"afterok:{grasps_id}"
        assert array["array"] == "0-69%64" and array["cpus-per-task"] == "1"
        assert sorted(array["dependency"].removeprefix("afterok:").split(":")) == sorted(
            [grasps_id, demos_id]
        )
        assert publish["dependency"] == f"afterany:{array_id}"
        published[t] = (grasps_id, publish_id)
    ((_, evaluate),) = by_name["evaluate"]
    assert sorted(evaluate["dependency"].removeprefix("afterok:").split(":")) == sorted(
        p for _, p in published.values()
    )
    (compose_id, compose), (_, compose_publish) = sorted(by_name["compose"])
    assert compose["array"] == "0-49%50"
    assert sorted(compose["dependency"].removeprefix("afterok:").split(":")) == sorted(
        [*published["door"], *published["drawer"]]
    )
    assert compose_publish["dependency"] == f"afterany:{compose_id}"


def test_submitted_stages_are_not_submitted_again_while_up_to_date(
    tmp_path, monkeypatch, fake_slurm, inline_run
):
    """A second submission after the outputs exist submits nothing (a stage up to date is
    not a job)."""
    monkeypatch.chdir(tmp_path)
    assert run_cli("pipeline", _pipeline(tmp_path))[0] == 0  # inline: both up to date
    code, _, err = run_cli("pipeline", _pipeline(tmp_path), "launcher=slurm")
    assert code == 0 and "nothing submitted" in err
    assert not list(fake_slurm.glob("*.sh"))


def test_a_stage_after_a_remade_output_is_submitted_too(tmp_path, monkeypatch, fake_slurm):
    """depth is up to date for the objects on disk, but the launch makes the objects
    again (another seed): depth is submitted after them, all its shards."""
    monkeypatch.chdir(tmp_path)
    assert run_cli("pipeline", _pipeline(tmp_path))[0] == 0  # inline: both up to date
    reseeded = SHARDED.replace("dataset.chunk_size=1,", "dataset.chunk_size=1, seed=1,")
    code, _, err = run_cli("pipeline", _pipeline(tmp_path, reseeded), "launcher=slurm")
    assert code == 0, err
    objects = read_jobs(tmp_path / "out/objects")["submissions"][-1]["jobs"]
    assert [j["shard"] for j in objects] == [0, 1, 2, 3, 0]
    (depth,) = read_jobs(tmp_path / "out/depth")["submissions"][-1]["jobs"]
    assert _scripts(fake_slurm)[depth["id"]]["dependency"] == f"afterok:{objects[-1]['id']}"


TRAIN_SHARDED = """
stages:
  train:
    cmd: train-mdn
    overrides: [debug=tiny, category=microwave, depth=nowhere, out=out/model]
    outs: [out/model]
    resources: {shards: 4}
"""


@pytest.mark.parametrize(
    ("args", "text", "message"),
    [
        (["launcher=pbs"], SHARDED, "launcher=pbs: unknown launcher (known: inline, local, slurm)"),
        (["launcher=slurm", "launcher.bogus=1"], SHARDED, "launcher.bogus: Extra inputs"),
        (["launcher=slurm", "launcher.timeout_min=soon"], SHARDED, "launcher.defaults.timeout_min"),
        (["launcher=slurm", "launcher.slurm.nodez=2"], SHARDED, "Unknown argument 'nodez'"),
        (["launcher=slurm"], TRAIN_SHARDED, "has no shard support"),
        (["launcher=slurm"], SHARDED.replace("shards: 4", "shards: 0"), "resources.shards"),
        (["launcher=local"], TRAIN_SHARDED, "has no shard support"),
    ],
)
def test_bad_launcher_input_exits_2_and_submits_nothing(
    tmp_path, monkeypatch, fake_slurm, args, text, message
):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli("pipeline", _pipeline(tmp_path, text), *args)
    assert code == 2, err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not list(fake_slurm.iterdir())  # no sbatch ran
    assert not list((tmp_path / "out").glob("*.jobs")) if (tmp_path / "out").exists() else True


def test_slurm_without_sbatch_exits_2(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    code, _, err = run_cli("pipeline", _pipeline(tmp_path), "launcher=slurm")
    assert code == 2 and "`sbatch` is not on PATH" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_launcher_arguments_are_split_from_pipeline_variables():
    assert split_launcher_args(["task=tball", "launcher=slurm", "launcher.partition=gpu"]) == (
        "slurm",
        {"partition": "gpu"},
        ["task=tball"],
    )
    assert split_launcher_args([]) == ("inline", {}, [])


def test_job_records_are_json(tmp_path, monkeypatch, fake_slurm):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli("pipeline", _pipeline(tmp_path), "launcher=slurm")
    assert code == 0, err
    record = json.loads((tmp_path / "out/objects.jobs" / JOBS_JSON).read_text())
    (submission,) = record["submissions"]
    assert submission["launcher"] == "slurm"
    assert [j["role"] for j in submission["jobs"]] == ["shard"] * 4 + ["publish"]
    # depth waits for the objects' publish job
    depth = read_jobs(tmp_path / "out/depth")["submissions"][0]["jobs"][0]["id"]
    assert _scripts(fake_slurm)[depth]["dependency"] == f"afterok:{submission['jobs'][-1]['id']}"


def test_smoke_pipeline_local_gives_the_bytes_of_inline(tmp_path, monkeypatch):
    """Every stage of the smoke pipeline as a separate process (issue 22's target): the
    same data files as launcher=inline, except the wall-clock timings files."""
    for folder, args in (("inline", ()), ("local", ("launcher=local",))):
        (tmp_path / folder).mkdir()
        monkeypatch.chdir(tmp_path / folder)
        code, _, err = run_cli("pipeline", "smoke", *args)
        assert code == 0, err
    inline = tmp_path / "inline"
    outs = sorted(p.parent.relative_to(inline) for p in inline.rglob("manifest.json"))
    assert len(outs) >= 17
    for out in outs:
        expected, got = (
            {k: v for k, v in tree_bytes(tmp_path / side / out).items() if "timings" not in k}
            for side in ("inline", "local")
        )
        assert got == expected, out


# -- the launcher config, the status words, shard support (no jobs) -----------------------


def test_resources_precedence_defaults_hints_then_stage_patterns():
    from artic.config.launcher import Resources, load_launcher

    launcher = load_launcher(
        "slurm",
        {
            "timeout_min": "30",  # a resource field sets the default
            "stages.train-*.gpus_per_node": "2",
            "stages.train-cabinet.timeout_min": "900",
        },
    )
    hints = Resources(shards=8, gpus_per_node=1, mem_gb=64)
    plain = launcher.resources("objects-cabinet")
    assert (plain.timeout_min, plain.shards, plain.gpus_per_node) == (30, 1, 0)
    depth = launcher.resources("depth-cabinet", hints)
    assert (depth.shards, depth.gpus_per_node, depth.mem_gb, depth.timeout_min) == (8, 1, 64, 30)
    train = launcher.resources("train-cabinet", hints)
    assert (train.gpus_per_node, train.timeout_min, train.mem_gb) == (2, 900, 64)
    assert launcher.resources("train-drawer", hints).timeout_min == 30


def test_every_shipped_launcher_config_loads():
    from artic.config.launcher import LAUNCHERS, load_launcher

    assert [load_launcher(name).name for name in LAUNCHERS] == list(LAUNCHERS)


def _state(state, role="shard", shard=0, shards=4):
    from artic.artifacts.job_records import JobState

    return JobState(f"{shard}", role, shard, shards, state, Path("/nowhere"))


@pytest.mark.parametrize(
    ("progress", "jobs", "word", "detail"),
    [
        (("done", [], 6), [_state("COMPLETED")], "done", ""),
        (
            ("partial", [1], 6),
            [_state("RUNNING"), _state("PENDING", shard=1)],
            "running",
            "jobs 0, 1",
        ),
        (("none", [0, 1], 6), [_state("PENDING"), _state("PENDING", shard=1)], "pending", ""),
        (
            ("partial", [1], 6),
            [_state("COMPLETED"), _state("FAILED", shard=1)],
            "failed",
            "missing shard.index 1 (shard.count=4)",
        ),
        (("partial", [1], 6), [_state("CANCELLED", shard=1)], "failed", "cancelled"),
        (("none", [0], 6), [_state("UNKNOWN")], "submitted", "state unknown"),
        (("partial", [3], 6), [], "missing", "4/6 chunks"),
        (("waiting", None, None), [], "waiting", "inputs not made"),
        (("none", [0], 6), [], "not started", ""),
    ],
)
def test_status_words(progress, jobs, word, detail):
    from artic.artifacts.job_records import describe
    from artic.artifacts.workdir import Progress

    state, missing, n_chunks = progress
    got = describe(Progress(Path("out"), state, missing, 4, n_chunks), jobs)
    assert got[0] == word and detail in got[1]


def test_stages_of_one_chunk_say_so():
    """`Stage.one_chunk` (no shard support) is declared by the training stages and single
    evaluations; the runner checks the declaration against every plan it makes."""
    from artic.cli.registry import load_stage, stage_entries

    single = {n for n in stage_entries() if load_stage(n).one_chunk}
    assert {"train-mdn", "train-segmenter", "train-hierarchy", "evaluate-mdn"} <= single
    assert not single & {"generate-dataset", "render-depth", "policy-search", "plan-demos"}
