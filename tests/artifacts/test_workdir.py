import pytest

from artic.artifacts.workdir import WorkDir, chunks_of_shard
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
    assert WorkDir(tmp_path / "out").prepare("h2") == 0
    assert WorkDir(tmp_path / "out").prepare("h2", fresh=True) == 0


def test_unwritable_output_is_an_input_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(InputError, match="out: cannot write"):
        WorkDir(blocker / "out").prepare("h")
