"""Several processes on one output at once: shard jobs of a cluster run started together
on a fresh output folder with a duplicate run of the whole command (real processes).
The work area's file locks (`artifacts/workdir.py`) make this safe: the config hash is
written once, under `<out>.lock`, by whichever process comes first; no process deletes
or rewrites another's chunks; the last to finish publishes once."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_stages import tree_bytes

GEN = ["generate-dataset", "debug=tiny", "category=microwave"]  # 3 chunks
#: 6 chunks of one object, so that each of 4 shards has work
GEN_6 = [*GEN, "dataset.chunk_size=1"]
SHARDS = 4


def _start(out: Path, *extra: str, gen: list[str] = GEN) -> subprocess.Popen[bytes]:
    args = [sys.executable, "-m", "artic", "-q", *gen, f"out={out}", *extra]
    return subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


@pytest.fixture(scope="module")
def six_chunks(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """The data files of GEN_6 run alone."""
    out = tmp_path_factory.mktemp("six") / "objects"
    _, err = (job := _start(out, gen=GEN_6)).communicate(timeout=180)
    assert job.returncode == 0, err.decode()
    return tree_bytes(out)


def _trial(folder: Path, reference: dict[str, bytes]) -> None:
    out = folder / "objects"
    jobs = [
        _start(out, f"shard.index={i}", f"shard.count={SHARDS}", gen=GEN_6) for i in range(SHARDS)
    ]
    jobs.append(_start(out, gen=GEN_6))  # the same command again, without shard.*
    for job in jobs:
        _, err = job.communicate(timeout=180)
        assert job.returncode == 0, err.decode()
    assert tree_bytes(out) == reference
    assert sorted(p.name for p in folder.iterdir()) == ["objects", "objects.lock"], (
        "no .partial or .old.* left"
    )


@pytest.mark.parametrize("trial", range(20))
def test_four_shards_and_a_duplicate_run_at_once(tmp_path, six_chunks, trial):
    """20 trials of N = 4 shards started at once on a fresh folder (issue 22; one test
    each, so they spread over the test workers), each bounded in time by the jobs'
    timeout: zero failures, the bytes of a single run."""
    _trial(tmp_path, six_chunks)


def test_the_same_command_twice_at_once(tmp_path, tiny_objects):
    out = tmp_path / "objects"
    jobs = [_start(out, "runtime.workers=2") for _ in range(2)]
    for job in jobs:
        _, err = job.communicate(timeout=180)
        assert job.returncode == 0, err.decode()
    assert tree_bytes(out) == tree_bytes(tiny_objects)
    assert not out.with_name("objects.partial").exists()
    assert not [p for p in tmp_path.iterdir() if ".old." in p.name]
    assert os.listdir(out)  # published once, complete
