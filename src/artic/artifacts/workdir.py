"""The work area of one stage output: resumable, shardable, published atomically.

Work for output folder `out` happens in the sibling `out.partial/`. The stage's work is
split into numbered chunks (a fixed number of samples each); a chunk writes its files
into a private temporary folder in the final layout, and only when it is complete are
they moved into `out.partial/` and a marker written. An interrupted run therefore keeps
every finished chunk and redoes at most the chunks that were in flight; parallel shard
jobs (`shard.index`/`shard.count`) share the same work area without conflict because
each owns different chunks. When every chunk is done, the stage writes its summary
files and `manifest.json`, and `out.partial/` is renamed to `out`, replacing the
previous output only at that moment.

The config hash is stored in `out.partial/.state/config_hash`; a work area left by a run with
another config is discarded, never mixed.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from artic.errors import InputError

# bookkeeping, all under one hidden folder that is never part of the outputs
_STATE = ".state"
_MARKERS = f"{_STATE}/chunks"
_TMP = f"{_STATE}/tmp"
_HASH = f"{_STATE}/config_hash"


class WorkDir:
    """Manage `out.partial/` for an output folder `out`."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.path = out.with_name(out.name + ".partial")

    def prepare(self, config_hash: str, fresh: bool = False) -> int:
        """Create (or reuse) the work area for `config_hash`; returns the number of chunks
        already finished. `fresh` discards any previous work."""
        try:
            if self.path.exists() and (fresh or self._stored_hash() != config_hash):
                shutil.rmtree(self.path)
            (self.path / _MARKERS).mkdir(parents=True, exist_ok=True)
            (self.path / _TMP).mkdir(parents=True, exist_ok=True)
            (self.path / _HASH).write_text(config_hash + "\n")
        except OSError as err:
            raise InputError(f"out: cannot write to {self.out} ({err.strerror})") from None
        return len(self.finished())

    def _stored_hash(self) -> str | None:
        p = self.path / _HASH
        return p.read_text().strip() if p.is_file() else None

    def finished(self) -> set[int]:
        """Indices of the chunks that are complete."""
        markers = self.path / _MARKERS
        if not markers.is_dir():
            return set()
        return {int(p.name) for p in markers.iterdir() if p.name.isdigit()}

    def chunk_tmp(self, chunk: int) -> Path:
        """An empty private folder for chunk `chunk` to write its files into."""
        tmp = self.path / _TMP / f"{chunk:06d}.{os.getpid()}"
        if tmp.exists():
            shutil.rmtree(tmp)
        tmp.mkdir(parents=True)
        return tmp

    def resume_dir(self, name: str) -> Path:
        """A folder that survives interruptions (not cleared between runs of the same
        config, never part of the outputs): for a long chunk's own checkpoints."""
        path = self.path / _STATE / "resume" / name
        path.mkdir(parents=True, exist_ok=True)
        return path

    def commit_chunk(self, chunk: int, tmp: Path) -> None:
        """Move the files of a completed chunk into place, then mark it done."""
        for src in sorted(p for p in tmp.rglob("*") if p.is_file()):
            dst = self.path / src.relative_to(tmp)
            dst.parent.mkdir(parents=True, exist_ok=True)
            os.replace(src, dst)
        shutil.rmtree(tmp)
        (self.path / _MARKERS / str(chunk)).touch()

    def publish(self) -> None:
        """Remove the bookkeeping and rename the work area to the output folder."""
        shutil.rmtree(self.path / _STATE, ignore_errors=True)
        old = self.out.with_name(self.out.name + f".old.{os.getpid()}")
        if self.out.exists():
            os.replace(self.out, old)
        os.replace(self.path, self.out)
        if old.exists():
            shutil.rmtree(old)


def chunks_of_shard(n_chunks: int, shard_index: int, shard_count: int) -> list[int]:
    """The chunks shard `shard_index` of `shard_count` is responsible for (round robin)."""
    return [c for c in range(n_chunks) if c % shard_count == shard_index]
