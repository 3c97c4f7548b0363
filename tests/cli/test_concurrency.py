"""Several processes on one output at once: shard jobs of a cluster run started together
with a duplicate run of the whole command (real processes)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_stages import tree_bytes

GEN = ["generate-dataset", "debug=tiny", "category=microwave"]  # 3 chunks


def _start(out: Path, *extra: str) -> subprocess.Popen[bytes]:
    args = [sys.executable, "-m", "artic", "-q", *GEN, f"out={out}", *extra]
    return subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def _trial(folder: Path, reference: dict[str, bytes]) -> None:
    out = folder / "objects"
    jobs = [_start(out, f"shard.index={i}", "shard.count=3") for i in range(3)]
    jobs.append(_start(out))  # the same command again, without shard.*
    for job in jobs:
        _, err = job.communicate(timeout=180)
        assert job.returncode == 0, err.decode()
    assert tree_bytes(out) == reference
    assert sorted(p.name for p in folder.iterdir()) == ["objects", "objects.lock"], (
        "no .partial or .old.* left"
    )


@pytest.mark.parametrize("trial", range(20))
def test_three_shards_and_a_duplicate_run_at_once(tmp_path, tiny_objects, trial):
    """20 trials (one test each, so they spread over the test workers), each bounded in
    time by the jobs' timeout."""
    _trial(tmp_path, tree_bytes(tiny_objects))


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
