import os

import pytest

from artic.artifacts.workdir import WorkDir, chunks_of_shard, write_atomic
from artic.errors import InputError


def test_chunks_of_shards_partition_the_work():
    n = 17
    parts = [chunks_of_shard(n, i, 4) for i in range(4)]
    assert sorted(c for p in parts for c in p) == list(range(n))
    assert chunks_of_shard(n, 0, 1) == list(range(n))


def _commit(work, chunk, text):
    tmp = work.chunk_tmp(chunk)
    (tmp / "sub").mkdir()
    (tmp / "sub" / f"{chunk}.txt").write_text(text)
    work.commit_chunk(chunk, tmp)


def test_resume_keeps_finished_chunks_and_publish_replaces(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("previous good output")
    work = WorkDir(out)
    assert work.prepare("h1") == 0
    _commit(work, 0, "zero")
    # an interrupted chunk leaves only a temporary folder behind
    work.chunk_tmp(1)
    work.leave()
    # same config: the finished chunk is kept
    assert WorkDir(out).prepare("h1") == 1
    assert (out / "old.txt").exists(), "previous output untouched while work is pending"
    _commit(work, 1, "one")
    assert work.finished() == {0, 1}
    work.publish()
    assert not work.path.exists()
    assert sorted(p.name for p in out.rglob("*.txt")) == ["0.txt", "1.txt"]
    assert not (out / "old.txt").exists()


def test_other_config_discards_partial_work(tmp_path):
    work = WorkDir(tmp_path / "out")
    work.prepare("h1")
    _commit(work, 0, "zero")
    work.leave()  # its run ended
    other = WorkDir(tmp_path / "out")
    assert other.prepare("h2") == 0 and other.created
    _commit(other, 0, "zero")
    other.leave()
    assert WorkDir(tmp_path / "out").prepare("h2", fresh=True) == 0


def test_a_work_area_in_use_by_a_live_run_is_never_discarded(tmp_path):
    running = WorkDir(tmp_path / "out")
    running.prepare("h1")
    _commit(running, 0, "zero")
    # another config (a second WorkDir stands for a second process: its own locks)
    with pytest.raises(InputError, match="in use by another run"):
        WorkDir(tmp_path / "out").prepare("h2")
    # --force of the same config joins it instead of discarding the live run's chunks
    assert WorkDir(tmp_path / "out").prepare("h1", force=True) == 1
    running.leave()
    assert WorkDir(tmp_path / "out").prepare("h2") == 0, "a dead run's area is discarded"


def test_a_folder_whose_state_cannot_be_read_is_never_deleted(tmp_path):
    partial = tmp_path / "out.partial"
    (partial / ".state").mkdir(parents=True)  # config_hash missing (or being written)
    (partial / "data.txt").write_text("someone's data")
    with pytest.raises(InputError, match="no readable work state"):
        WorkDir(tmp_path / "out").prepare("h1")
    assert (partial / "data.txt").read_text() == "someone's data"
    # an empty skeleton (a run killed while creating it) holds nothing and is replaced
    (partial / "data.txt").unlink()
    assert WorkDir(tmp_path / "out").prepare("h1") == 0


def test_force_resumes_its_own_work_area_but_not_an_older_one(tmp_path):
    old = WorkDir(tmp_path / "out")
    old.prepare("h1")
    _commit(old, 0, "zero")
    old.leave()
    forced = WorkDir(tmp_path / "out")
    assert forced.prepare("h1", force=True) == 0, "--force discards chunks made before it"
    _commit(forced, 1, "one")
    forced.leave()  # interrupted
    assert WorkDir(tmp_path / "out").prepare("h1", force=True) == 1, "--force again resumes"
    # shard jobs never discard the shared area, even with --force
    assert WorkDir(tmp_path / "out").prepare("h1", force=True, shared=True) == 1


def test_commit_is_idempotent_and_claims_are_exclusive(tmp_path):
    a, b = WorkDir(tmp_path / "out"), WorkDir(tmp_path / "out")
    a.prepare("h1")
    b.prepare("h1")
    assert a.claim([0, 1]) == [0, 1]
    assert b.claim([0, 1, 2]) == [2], "chunks claimed by a live run are not done twice"
    a.release_claim(1)
    assert b.claim([1]) == [1]
    _commit(a, 0, "zero")
    _commit(b, 0, "zero")  # the same chunk done twice (a duplicate run): no error
    assert a.finished() == {0}
    assert (a.path / "sub" / "0.txt").read_text() == "zero"
    # once the area is published, a late commit is dropped (no work area is re-created)
    tmp = b.chunk_tmp(2)
    (tmp / "late.txt").write_text("late")
    a.publish()
    assert not b.commit_chunk(2, tmp, key="h1")
    assert not b.path.exists() and not (tmp_path / "out" / "late.txt").exists()


def test_commit_after_the_parent_died_is_refused(tmp_path):
    work = WorkDir(tmp_path / "out")
    work.prepare("h1")
    tmp = work.chunk_tmp(0)
    (tmp / "x.txt").write_text("x")
    assert not work.commit_chunk(0, tmp, parent=os.getppid() + 1)
    assert work.finished() == set() and not (work.path / "x.txt").exists()


def test_state_files_are_written_atomically(tmp_path, monkeypatch):
    path = tmp_path / "state"
    write_atomic(path, "old\n")

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError):
        write_atomic(path, "new\n")
    assert path.read_text() == "old\n", "a failed write leaves the previous content"
    assert [p.name for p in tmp_path.iterdir()] == ["state"], "no temporary file left"


def test_unwritable_output_is_an_input_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(InputError, match="out: cannot write"):
        WorkDir(blocker / "out").prepare("h")
