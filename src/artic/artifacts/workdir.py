"""The work area of one stage output: resumable, shardable, safe against other processes,
published atomically.

Work for output folder `out` happens in the sibling `out.partial/`. The stage's work is
split into numbered chunks (a fixed number of samples each); a chunk writes its files
into a private temporary folder in the final layout, and only when it is complete are
they moved into `out.partial/` and a marker written. An interrupted run therefore keeps
every finished chunk and redoes at most the chunks that were in flight. When every chunk
is done, the stage writes its summary files and `manifest.json`, and `out.partial/` is
renamed to `out`, replacing the previous output only at that moment.

Several processes may work on the same output at once (shard jobs of a cluster run, the
same command started twice). They coordinate through file locks (`filelock`):

- `<out>.lock` (beside `out`, never inside the folder that gets renamed) guards every
  change of the work area's state: preparing or discarding it, committing a chunk,
  publishing. It is held only for these short critical sections.
- `.state/runs/<id>.lock` is held by each process working in the area for as long as it
  does: a work area with a live run in it is never discarded.
- `.state/claims/<chunk>.lock` is held by the process doing that chunk, so two processes
  never do the same chunk at once; the claim of a killed process is free again.

The key (config hash and input hashes) is stored in `.state/config_hash`, written
atomically; a work area of another key with no live run is discarded, never mixed, and
a folder whose state cannot be read is never deleted.
"""

from __future__ import annotations

import os
import secrets
import shutil
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from filelock import FileLock, Timeout

from artic.errors import InputError

# bookkeeping, all under one hidden folder that is never part of the outputs
_STATE = ".state"
_MARKERS = f"{_STATE}/chunks"
_TMP = f"{_STATE}/tmp"
_HASH = f"{_STATE}/config_hash"
_FORCED = f"{_STATE}/forced"
_RUNS = f"{_STATE}/runs"
_CLAIMS = f"{_STATE}/claims"


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write `data` (text or bytes) to `path` so that a reader sees the old content or the
    new, never a partial file (a unique temporary file renamed over it)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        with tmp.open("wb" if isinstance(data, bytes) else "w") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


class WorkDir:
    """Manage `out.partial/` for an output folder `out`."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.path = out.with_name(out.name + ".partial")
        self.lock_path = out.with_name(out.name + ".lock")
        self._run: FileLock | None = None
        self._claims: dict[int, FileLock] = {}
        self.created = False
        self._lock = FileLock(self.lock_path)
        self._depth = 0
        self._lock_created: bool | None = None  # whether this object made `<out>.lock`

    # -- the lock around state changes -------------------------------------------------

    @contextmanager
    def locked(self) -> Iterator[None]:
        """Hold `<out>.lock` (waiting for it) for a critical section; reentrant."""
        if self._depth == 0:
            if self._lock_created is None:
                self._lock_created = not self.lock_path.exists()
            try:
                self._lock.acquire()
            except OSError as err:
                raise InputError(f"out: cannot write to {self.out} ({err.strerror})") from None
        self._depth += 1
        try:
            yield
        finally:
            self._depth -= 1
            if self._depth == 0:
                self._lock.release()

    # -- state (call under `locked()`) -------------------------------------------------

    def stored_key(self) -> str | None:
        """The key of the work area, or None when there is none (or it is unreadable)."""
        try:
            return (self.path / _HASH).read_text().strip() or None
        except OSError:
            return None

    def is_mine(self, key: str) -> bool:
        """Whether the work area exists and is the one for `key` (not published or
        replaced by another process)."""
        return self.stored_key() == key

    def prepare(
        self, key: str, fresh: bool = False, force: bool = False, shared: bool = False
    ) -> int:
        """Create, reuse or discard the work area for `key` and join it as a run; returns
        the number of chunks already finished, and sets `created`.
        `fresh` discards any previous work of a dead run.

        A work area of another key is discarded unless a live run works in it (then an
        InputError). With `force` (and not `shared`, i.e. not a shard job), a work area
        of this key is discarded unless it was itself started by a `--force` or a live run
        works in it (then it is joined): a rerun of an interrupted `--force` resumes."""
        with self.locked():
            return self._prepare(key, fresh, force, shared)

    def _prepare(self, key: str, fresh: bool, force: bool, shared: bool) -> int:
        try:
            if self.path.exists() or self.path.is_symlink():
                if not self.path.is_dir():
                    raise InputError(f"out: {self.path} exists and is not a folder; remove it")
                stored = self.stored_key()
                if stored is None:
                    if any(p.is_file() for p in self.path.rglob("*")):
                        raise InputError(
                            f"out: {self.path} exists but holds no readable work state "
                            f"({_HASH}); it was not left by artic, remove it"
                        )
                    shutil.rmtree(self.path)  # an empty skeleton: nothing to lose
                elif stored != key or fresh:
                    if self.others_active():
                        raise InputError(
                            f"out: {self.path} is in use by another run; "
                            "wait for it to finish or choose another out="
                        )
                    shutil.rmtree(self.path)
                elif (
                    force
                    and not shared
                    and not (self.path / _FORCED).is_file()
                    and not self.others_active()
                ):
                    shutil.rmtree(self.path)
            created = not self.path.exists()
            for sub in (_MARKERS, _TMP, _RUNS, _CLAIMS):
                (self.path / sub).mkdir(parents=True, exist_ok=True)
            if created:
                write_atomic(self.path / _HASH, key + "\n")
                if force:
                    write_atomic(self.path / _FORCED, "")
        except OSError as err:
            raise InputError(f"out: cannot write to {self.out} ({err.strerror})") from None
        self._join()
        self.created = created
        return len(self.finished())

    def _join(self) -> None:
        run = FileLock(self.path / _RUNS / f"{os.getpid()}-{secrets.token_hex(4)}.lock")
        run.acquire()
        self._run = run

    def leave(self) -> None:
        """Stop being a run of this work area (release the run and claim locks)."""
        for c in list(self._claims):
            self.release_claim(c)
        if self._run is not None:
            self._run.release()
            Path(self._run.lock_file).unlink(missing_ok=True)
            self._run = None

    def others_active(self) -> bool:
        """Whether a live process other than this one works in the area (stale run
        files of dead processes are removed)."""
        mine = Path(self._run.lock_file).name if self._run is not None else None
        runs = self.path / _RUNS
        active = False
        for path in sorted(runs.glob("*.lock")) if runs.is_dir() else []:
            if path.name == mine:
                continue
            probe = FileLock(path)
            try:
                probe.acquire(timeout=0)
            except Timeout:
                active = True
                continue
            probe.release()
            path.unlink(missing_ok=True)
        return active

    def claim(self, chunks: list[int]) -> list[int]:
        """Claim the chunks no live process is doing; returns those claimed. Call under
        `locked()`, after checking `is_mine`."""
        claimed = []
        for c in chunks:
            lock = FileLock(self.path / _CLAIMS / f"{c}.lock")
            try:
                lock.acquire(timeout=0)
            except Timeout:
                continue
            self._claims[c] = lock
            claimed.append(c)
        return claimed

    def release_claim(self, chunk: int) -> None:
        lock = self._claims.pop(chunk, None)
        if lock is not None:
            lock.release()

    def remove_if_unused(self, key: str) -> None:
        """Remove the work area if it is ours, holds no finished chunk and no other run
        works in it (after bad input found once the area was created), and `<out>.lock`
        if this run made it. Call under `locked()`."""
        if self.is_mine(key) and not self.finished() and not self.others_active():
            self.leave()
            shutil.rmtree(self.path, ignore_errors=True)
            if self._lock_created:
                # no debris either; a run that would wait on this lock meanwhile is one
                # of the same bad command, which fails the same way
                self.lock_path.unlink(missing_ok=True)

    def finished(self) -> set[int]:
        """Indices of the chunks that are complete."""
        markers = self.path / _MARKERS
        if not markers.is_dir():
            return set()
        return {int(p.name) for p in markers.iterdir() if p.name.isdigit()}

    # -- chunks (any process) ---------------------------------------------------------

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

    def commit_chunk(
        self, chunk: int, tmp: Path, key: str | None = None, parent: int | None = None
    ) -> bool:
        """Move the files of a completed chunk into place, then mark it done; returns
        whether it was committed. Not committed (the files are dropped) when the work area
        is no longer the one for `key` (published or replaced by another process) or, in a
        worker, when its parent process `parent` has died. Idempotent: committing a chunk
        already marked done leaves the area as it is."""
        with self.locked():
            alive = parent is None or os.getppid() == parent
            if not alive or (key is not None and not self.is_mine(key)):
                shutil.rmtree(tmp, ignore_errors=True)
                return False
            marker = self.path / _MARKERS / str(chunk)
            if not marker.exists():
                for src in sorted(p for p in tmp.rglob("*") if p.is_file()):
                    dst = self.path / src.relative_to(tmp)
                    dst.parent.mkdir(parents=True, exist_ok=True)
                    os.replace(src, dst)
                write_atomic(marker, "")
            shutil.rmtree(tmp, ignore_errors=True)
            return True

    def publish(self) -> None:
        """Remove the bookkeeping and rename the work area to the output folder. Call
        under `locked()` after checking `is_mine`: only one process publishes."""
        with self.locked():
            self._publish()

    def _publish(self) -> None:
        self.leave()
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


def shards_of_chunks(chunks: set[int] | list[int], shard_count: int) -> list[int]:
    """The (0-based) shards responsible for `chunks`, sorted."""
    return sorted({c % shard_count for c in chunks})


def shard_names(shards: Sequence[int], shard_count: int) -> str:
    """Shards as the user gave them: "shard.index 1, 3 (shard.count=4)"."""
    return f"shard.index {', '.join(str(s) for s in shards)} (shard.count={shard_count})"


@dataclass
class Progress:
    """How far a stage output `out` is: `state` is "done" (published, of this config and
    these inputs), "partial" (a work area of this key with `chunks_done` of `n_chunks`
    chunks), "none" (nothing of this key yet) or "waiting" (its inputs are not made).
    `missing`: the 0-based shards with chunks left (None when the chunk count is not
    known)."""

    out: Path
    state: str
    missing: list[int] | None = None
    chunks_done: int = 0
    n_chunks: int | None = None


def progress_of(
    out: Path,
    config_hash: str,
    input_hashes: dict[str, str],
    n_chunks: int | None,
    shard_count: int,
) -> Progress:
    """The progress of output `out` for a config and inputs (`key_of` them), read only:
    no lock taken, nothing written (a status may be stale by the time it is read)."""
    from artic.artifacts.manifest import MANIFEST, read_manifest

    work = WorkDir(out)
    pending = work.stored_key() == key_of(config_hash, input_hashes)
    if not pending and (out / MANIFEST).is_file():
        previous = read_manifest(out)
        same_inputs = {k: r.content_hash for k, r in previous.inputs.items()} == input_hashes
        if previous.config_hash == config_hash and same_inputs:
            return Progress(out, "done", [])
    if not pending:
        every = list(range(shard_count))
        if n_chunks is not None:
            every = shards_of_chunks(list(range(n_chunks)), shard_count)
        return Progress(out, "none", every, 0, n_chunks)
    finished = work.finished()
    if n_chunks is None:
        return Progress(out, "partial", None, len(finished))
    missing = shards_of_chunks(sorted(set(range(n_chunks)) - finished), shard_count)
    return Progress(out, "partial", missing, len(finished), n_chunks)


def key_of(config_hash: str, input_hashes: dict[str, str]) -> str:
    """The key of a work area: its config hash and its inputs' content hashes (as the
    stage runner stores it in `.state/config_hash`)."""
    from artic.artifacts.hashing import sha256_json

    return sha256_json({"config": config_hash, "inputs": input_hashes})
