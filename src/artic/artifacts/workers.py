"""Doing a stage's chunks, inline or in worker processes, into its work area
(`artifacts.workdir.WorkDir`): used by the stage runner (`cli/stage_runner`).

Workers are spawned processes, one thread each; they die with the runner that started
them (the kernel's parent-death signal, and a watcher thread), and a worker whose runner
has died does not commit its chunk. In the runner, SIGTERM is handled like Ctrl-C
(`Interrupts`): the workers are stopped, finished chunks are kept.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any

from artic.artifacts.workdir import WorkDir

#: chunk function: (config, input folders, chunk index, empty folder to write into) -> items done
ChunkFn = Callable[[Any, dict[str, Path], int, Path], int]


def available_cpus() -> int:
    """CPUs this process may use: the affinity mask, capped by a cgroup v2 CPU quota."""
    n = len(os.sched_getaffinity(0))
    try:
        quota, period = Path("/sys/fs/cgroup/cpu.max").read_text().split()
        if quota != "max":
            n = min(n, max(1, int(int(quota) / int(period))))
    except (OSError, ValueError):
        pass
    return max(1, n)


class Terminated(KeyboardInterrupt):
    """SIGTERM, handled like Ctrl-C."""


class Interrupts:
    """Ctrl-C and SIGTERM in the runner's main thread while a stage runs (from `start()`
    to `stop()`): raised where they land (SIGTERM as `Terminated`) and remembered.

    Python prints and drops an exception raised in a finalizer (an object's `__del__`, a
    weakref callback: a file lock's, for one); a Ctrl-C that lands there would be lost
    and the run would go on to publish. `check()` raises a signal received again; the
    runner calls it between chunks and before publishing. A SIGINT that is ignored when
    the stage starts (a background job of a non-interactive shell) stays ignored; in a
    thread other than the main one nothing is installed (signals reach the main one)."""

    def __init__(self) -> None:
        self.received: int | None = None
        self._previous: dict[int, Any] = {}

    def _handler(self, signum: int, frame: Any) -> None:
        self.received = signum
        self.check()

    def check(self) -> None:
        """Raise the signal received since the stage started, if any."""
        if self.received == signal.SIGTERM:
            raise Terminated
        if self.received is not None:
            raise KeyboardInterrupt

    def start(self) -> Interrupts:
        """Install the handlers; returns self."""
        if threading.current_thread() is threading.main_thread():
            for signum in (signal.SIGINT, signal.SIGTERM):
                current = signal.getsignal(signum)
                if signum == signal.SIGINT and current is not signal.default_int_handler:
                    continue  # ignored, or someone else's handler
                self._previous[signum] = signal.signal(signum, self._handler)
        return self

    def stop(self) -> None:
        """Put back the handlers that were there before `start()`."""
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
        self._previous.clear()


#: in a worker process: the pid of the runner that started it (None in the runner)
_PARENT: int | None = None


def _run_chunk(fn: ChunkFn, cfg: Any, inputs: dict[str, Path], chunk: int, out: Path) -> int:
    """Worker entry: write chunk `chunk` into a private folder, then commit it (not if
    the runner that started this worker has died)."""
    work = WorkDir(out)
    tmp = work.chunk_tmp(chunk)
    items = fn(cfg, inputs, chunk, tmp)
    if not work.commit_chunk(chunk, tmp, parent=_PARENT):
        os._exit(1)  # orphaned: the runner died; nobody waits for this worker
    return items


def _worker_init(parent: int) -> None:
    """Worker setup: one thread (parallelism comes from the processes), Ctrl-C left to
    the runner, and death with the runner: the kernel kills the worker when the runner
    dies (Linux `PR_SET_PDEATHSIG`), and a watcher thread does elsewhere."""
    global _PARENT
    _PARENT = parent
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:
        os._exit(1)  # the runner died before this worker started

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.2)
        os._exit(1)

    threading.Thread(target=watch, name="artic-parent-watch", daemon=True).start()


def run_chunks(
    fn: ChunkFn,
    cfg: Any,
    inputs: dict[str, Path],
    todo: list[int],
    work: WorkDir,
    workers: int,
    advance: Callable[[int], None],
    check: Callable[[], None],
) -> None:
    """Do the chunks `todo` (claimed by this process) with `fn`, inline (`workers` <= 1)
    or in `workers` worker processes; each claim is released once its chunk is done,
    and `advance(items)` is told the items the chunk did. `check()` is called before a
    chunk is started (`Interrupts.check`: it raises an interruption received)."""
    if workers <= 1:
        for c in todo:
            check()
            advance(_run_chunk(fn, cfg, inputs, c, work.out))
            work.release_claim(c)
        return
    ctx = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(
        workers, mp_context=ctx, initializer=_worker_init, initargs=(os.getpid(),)
    )
    pending: dict[Future[int], int] = {}
    queue = list(todo)
    try:
        while queue or pending:
            # only as many chunks as workers are handed out, so that on Ctrl-C or
            # SIGTERM no queued chunk is left to finish
            check()
            while queue and len(pending) < workers:
                c = queue.pop(0)
                pending[pool.submit(_run_chunk, fn, cfg, inputs, c, work.out)] = c
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                c = pending.pop(fut)
                advance(fut.result())
                work.release_claim(c)
    except BaseException:
        _stop(pool, pending)
        raise
    pool.shutdown(wait=True)


def _stop(pool: ProcessPoolExecutor, pending: dict[Future[int], int]) -> None:
    """Stop the workers now: cancel what has not started, end what runs (its chunk is
    not committed; finished chunks are kept)."""
    for fut in pending:
        fut.cancel()
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for p in procs:
        if p.is_alive():
            p.terminate()
    deadline = time.monotonic() + 5
    for p in procs:
        p.join(max(0.0, deadline - time.monotonic()))
        if p.is_alive():
            p.kill()
            p.join(1)
    # with its workers gone, the pool's manager thread ends at once; waiting for it here
    # keeps it from writing to its closed wake-up pipe while the interpreter exits (an
    # "OSError: Bad file descriptor" traceback after the one-line message, Python < 3.14)
    pool.shutdown(wait=True, cancel_futures=True)
