"""What the stage runner promises, in-process and fast: bad input is refused before
anything is created, --force runs resume, shards name the missing shards, and a
hand-edited input manifest is refused."""

from __future__ import annotations

import dataclasses
import json
import shutil
import signal
from collections.abc import Callable
from functools import partial
from pathlib import Path

import pytest
from test_stages import tree_bytes

from artic.artifacts import workers
from artic.cli import stage_runner
from artic.cli.registry import load_stage
from artic.errors import InputError
from cli_runner import run_cli

GEN = ["generate-dataset", "debug=tiny", "category=microwave"]

# every stage subcommand, with placeholder inputs (out= is checked before they are read)
STAGE_ARGS = [
    ["generate-dataset"],
    ["render-depth", "dataset=/nonexistent"],
    ["render-depth", "render=scan", "dataset=/nonexistent"],
    ["train-mdn", "depth=/nonexistent"],
    ["evaluate", "mdn", "model=/nonexistent", "depth=/nonexistent", "objects=/nonexistent"],
    ["plan-demos"],
    ["fit-dmp", "demos=/nonexistent"],
    ["policy-search", "dmp=/nonexistent", "demos=/nonexistent"],
    ["evaluate", "bootstrap", "bootstrap=/nonexistent", "random=/nonexistent"],
    ["train-segmenter", "scans=/nonexistent"],
    ["train-hierarchy", "scans=/nonexistent"],
    ["evaluate", "hierarchy", "scans=/x", "segmenter=/x", "labeller=/x"],
]


@pytest.mark.parametrize("args", STAGE_ARGS, ids=lambda a: "-".join(a[:2]))
def test_out_naming_a_file_exits_2_and_touches_nothing(tmp_path, args):
    target = tmp_path / "results.txt"
    target.write_text("the user's file")
    code, _, err = run_cli(*args, "debug=tiny", f"out={target}")
    assert code == 2, err
    assert "is a file, not a folder" in err and len(err.strip().splitlines()) == 1
    assert target.read_text() == "the user's file"
    assert [p.name for p in tmp_path.iterdir()] == ["results.txt"], "nothing created"


def test_bad_input_found_by_the_plan_creates_nothing(tmp_path):
    def bad_plan(cfg, inputs):
        raise InputError("dataset: bad input found while planning")

    stage = dataclasses.replace(load_stage("generate-dataset"), plan=bad_plan)
    with pytest.raises(InputError, match="while planning"):
        stage_runner.run_stage(stage, ["debug=tiny", f"out={tmp_path / 'o'}"])
    assert list(tmp_path.iterdir()) == []


def test_bad_input_found_in_a_chunk_leaves_no_work_area(tmp_path, monkeypatch):
    def bad_chunk(fn, cfg, inputs, chunk, out_dir):
        raise InputError("dataset: a file found bad by the chunk")

    monkeypatch.setattr(workers, "_run_chunk", bad_chunk)
    out = tmp_path / "o"
    code, _, err = run_cli(*GEN, f"out={out}")
    assert code == 2 and "found bad by the chunk" in err
    assert list(tmp_path.iterdir()) == [], "no work area, no lock file"


def test_pipeline_with_a_bad_override_in_stage_2_runs_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.yaml").write_text(
        "stages:\n"
        "  objects: {cmd: generate-dataset, overrides: [debug=tiny, out=a], outs: [a]}\n"
        "  depth: {cmd: render-depth, overrides: [debug=tiny, dataset=a, out=b,"
        " render.configurationz=3], deps: [a], outs: [b]}\n"
    )
    code, _, err = run_cli("pipeline", str(tmp_path / "p.yaml"))
    assert code == 2, err
    assert "stage depth" in err and "configurationz" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.yaml"], "stage 1 did not run"


def test_a_shard_names_the_shards_still_missing(tmp_path):
    out = tmp_path / "o"
    code, text, err = run_cli(*GEN, f"out={out}", "shard.index=1", "shard.count=3")
    assert code == 0, err
    said = " ".join(text.split())
    assert "shard.index=1 (shard.count=3) finished" in said, said
    assert "shard.index 0, 2 still to run" in said
    code, text, _ = run_cli(*GEN, f"out={out}", "shard.index=0", "shard.count=3")
    assert "shard.index 2 still to run" in " ".join(text.split())


def _raise_ctrl_c() -> None:
    raise KeyboardInterrupt


def _interrupt_on_second_chunk(
    monkeypatch,
    calls: list[int],
    armed: list[bool],
    interrupt: Callable[[], object] = _raise_ctrl_c,
) -> None:
    """Record the chunks started in `calls`; while `armed[0]`, call `interrupt()` as the
    second starts (the chunk runs on if it does not raise)."""
    original = workers._run_chunk

    def run(fn, cfg, inputs, chunk, out_dir):
        calls.append(chunk)
        if armed[0] and len(calls) == 2:
            interrupt()
        return original(fn, cfg, inputs, chunk, out_dir)

    monkeypatch.setattr(workers, "_run_chunk", run)


def test_interrupted_force_run_resumes_with_or_without_force(tmp_path, tiny_objects, monkeypatch):
    out = tmp_path / "o"
    shutil.copytree(tiny_objects, out)  # an up-to-date output
    calls: list[int] = []
    armed = [True]
    _interrupt_on_second_chunk(monkeypatch, calls, armed)
    assert run_cli(*GEN, f"out={out}", "--force")[0] == 130
    assert out.with_name("o.partial").is_dir()
    # the same --force command resumes: chunk 0 (made by this --force) is kept
    calls.clear()
    assert run_cli(*GEN, f"out={out}", "--force")[0] == 130
    assert calls == [1, 2], "chunk 0 is not redone; chunk 1 is kept, 2 interrupted"
    # without --force the pending --force work is finished, not reported up to date
    calls.clear()
    armed[0] = False
    code, text, err = run_cli(*GEN, f"out={out}")
    assert code == 0, err
    assert "up to date" not in " ".join(text.split())
    assert calls == [2]
    assert not out.with_name("o.partial").exists()
    assert tree_bytes(out) == tree_bytes(tiny_objects)
    # and --force on a completed output starts afresh
    calls.clear()
    assert run_cli(*GEN, f"out={out}", "--force")[0] == 0
    assert calls == [0, 1, 2]


def test_force_does_not_reuse_chunks_of_an_earlier_run(tmp_path, monkeypatch):
    out = tmp_path / "o"
    calls: list[int] = []
    armed = [True]
    _interrupt_on_second_chunk(monkeypatch, calls, armed)
    assert run_cli(*GEN, f"out={out}")[0] == 130  # a plain run leaves chunk 0
    calls.clear()
    armed[0] = False
    assert run_cli(*GEN, f"out={out}", "--force")[0] == 0
    assert calls == [0, 1, 2]


def _edit_manifest(folder: Path, edit) -> None:
    path = folder / "manifest.json"
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda m: m["config"]["category"].update(name="drawer"), "config does not match"),
        (lambda m: m["config"].update(seed=7), "config does not match"),
        (lambda m: m.update(content_hash="0" * 64), "content_hash does not match"),
    ],
)
def test_a_hand_edited_input_manifest_is_refused(tmp_path, tiny_objects, edit, message):
    objects = tmp_path / "objects"
    shutil.copytree(tiny_objects, objects)
    _edit_manifest(objects, edit)
    out = tmp_path / "d"
    code, _, err = run_cli("render-depth", "debug=tiny", f"dataset={objects}", f"out={out}")
    assert code == 2, err
    assert f"{objects / 'manifest.json'}: {message}" in err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists() and not out.with_name("d.partial").exists()


class _SignalsInItsFinalizer:
    """An object whose finalizer receives `signum` (as a file lock's `__del__` may while
    Ctrl-C is pressed): Python prints the exception raised there and drops it."""

    def __init__(self, signum: int) -> None:
        self.signum = signum

    def __del__(self) -> None:
        signal.raise_signal(self.signum)
        for _ in range(1000):  # the handler runs at the next instructions, still in here
            pass


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.parametrize(
    ("signum", "exit_code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["int", "term"]
)
def test_a_signal_lost_in_a_finalizer_still_stops_the_run(
    tmp_path, tiny_objects, monkeypatch, signum, exit_code
):
    out = tmp_path / "o"
    calls: list[int] = []
    armed = [True]
    # the object is dropped at once: its __del__ runs as the second chunk starts
    _interrupt_on_second_chunk(monkeypatch, calls, armed, lambda: _SignalsInItsFinalizer(signum))
    assert run_cli(*GEN, f"out={out}")[0] == exit_code
    assert calls == [0, 1], "the chunk that was running finished; no other was started"
    assert not out.exists() and out.with_name("o.partial").is_dir()
    calls.clear()
    armed[0] = False
    code, _, err = run_cli(*GEN, f"out={out}")
    assert code == 0, err
    assert calls == [2]
    assert tree_bytes(out) == tree_bytes(tiny_objects)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler, "handlers put back"


def test_an_ignored_ctrl_c_stays_ignored(tmp_path, monkeypatch):
    # a background job of a non-interactive shell: SIGINT ignored when the stage starts
    _interrupt_on_second_chunk(monkeypatch, [], [True], partial(signal.raise_signal, signal.SIGINT))
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        code, _, err = run_cli(*GEN, f"out={tmp_path / 'o'}")
    finally:
        signal.signal(signal.SIGINT, previous)
    assert code == 0, err
    assert (tmp_path / "o" / "manifest.json").is_file()
