"""Ctrl-C, SIGTERM and SIGKILL of a real `artic` process, then the same command again."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_stages import tree_bytes

from cli_runner import run_cli


def _finished(markers: Path) -> set[str]:
    """The chunks marked finished (a marker is named by its chunk number; the folder may
    also hold a marker's temporary file while it is written)."""
    return {p.name for p in markers.iterdir() if p.name.isdigit()} if markers.is_dir() else set()


def _artic(*args: str) -> list[str]:
    return [sys.executable, "-m", "artic", "-q", *args]


def test_sigint_then_rerun_resumes_to_identical_dataset(tmp_path, tiny_objects):
    def command(out: Path) -> list[str]:
        return _artic(
            "render-depth",
            "debug=tiny",
            f"dataset={tiny_objects}",
            f"out={out}",
            "render.configurations=48",
            "render.objects_per_shard=1",
            "render.backend=pybullet",
        )

    out = tmp_path / "depth"
    args = command(out)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=_default_sigint
    )
    markers = out.with_name("depth.partial") / ".state" / "chunks"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        if _finished(markers):
            break
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err.decode()
    assert b"resume" in err
    assert not out.exists(), "nothing published by an interrupted run"
    done = len(_finished(markers))
    assert 1 <= done < 6
    rerun = subprocess.run(args, env=env, capture_output=True, timeout=120)
    assert rerun.returncode == 0, rerun.stderr.decode()
    # same bytes as an uninterrupted run of the same config (shard size differs from the
    # tiny_depth fixture, so compare against a fresh uninterrupted run)
    ref = tmp_path / "ref"
    ok = subprocess.run(command(ref), env=env, capture_output=True, timeout=120)
    assert ok.returncode == 0, ok.stderr.decode()
    assert tree_bytes(out) == tree_bytes(ref)
    assert Path(out / "manifest.json").is_file()


# -- SIGINT, SIGTERM and SIGKILL of the main process with 2 workers ---------------------

GEN = ["generate-dataset", "debug=tiny", "category=microwave", "dataset.objects=30"]
GEN += ["dataset.chunk_size=1", "runtime.workers=2"]


def _default_sigint() -> None:
    # a process started from a non-interactive shell inherits SIGINT ignored
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _descendants(pid: int) -> set[int]:
    """Every process below `pid` (from /proc, no psutil)."""
    found: set[int] = set()
    todo = [pid]
    while todo:
        p = todo.pop()
        for children in Path(f"/proc/{p}/task").glob("*/children"):
            try:
                kids = {int(c) for c in children.read_text().split()}
            except OSError:
                continue
            todo.extend(kids - found)
            found |= kids
    return found


def _running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")  # a zombie has exited


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    out = tmp_path_factory.mktemp("ref") / "objects"
    code, _, err = run_cli(*GEN, f"out={out}")
    assert code == 0, err
    return tree_bytes(out)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_killed_main_process_leaves_no_worker_and_resumes_to_identical_bytes(
    tmp_path, reference, sig
):
    out = tmp_path / "objects"
    args = _artic(*GEN, f"out={out}")
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    log = (tmp_path / "stderr.txt").open("w+b")  # a file: orphans holding a pipe can't hang us
    proc = subprocess.Popen(
        args, env=env, stdout=subprocess.DEVNULL, stderr=log, preexec_fn=_default_sigint
    )
    markers = out.with_name("objects.partial") / ".state" / "chunks"
    workers: set[int] = set()
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline and proc.poll() is None:
        workers |= _descendants(proc.pid)
        if len(_finished(markers)) >= 2 and len(workers) >= 2:
            break
        time.sleep(0.01)
    assert len(workers) >= 2, "the run has its 2 worker processes"
    t0 = time.monotonic()
    proc.send_signal(sig)
    proc.wait(timeout=30)
    assert time.monotonic() - t0 < 10, "prompt exit"
    log.seek(0)
    err = log.read()
    log.close()
    (tmp_path / "stderr.txt").unlink()
    if sig == signal.SIGKILL:
        assert proc.returncode == -signal.SIGKILL
    else:  # handled alike; the exit code says which: 130 Ctrl-C, 143 SIGTERM
        assert proc.returncode == (130 if sig == signal.SIGINT else 143), err.decode()
        assert b"resume" in err and b"Traceback" not in err
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_running(p) for p in workers):
        time.sleep(0.05)
    assert not [p for p in workers if _running(p)], "no process outlives the main one"
    done = len(_finished(markers))
    time.sleep(1)
    assert len(_finished(markers)) == done, "no chunk committed after the main died"
    assert done < 30, "queued chunks were not all finished before exiting"
    assert not out.exists()
    rerun = subprocess.run(args, env=env, capture_output=True, timeout=180)
    assert rerun.returncode == 0, rerun.stderr.decode()
    assert tree_bytes(out) == reference
    assert sorted(p.name for p in tmp_path.iterdir()) in (
        ["objects"],
        ["objects", "objects.lock"],
    ), "no .partial or .old.* left"
