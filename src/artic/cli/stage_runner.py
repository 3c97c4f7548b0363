"""Run one stage under the stage contract of DESIGN.md.

compose config -> validate -> skip if up to date -> do the missing chunks of this shard
(in parallel worker processes) -> when all chunks are done: summary files, manifest,
atomic publish. A `Stage` supplies only what is specific to it.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import threading
import time
import traceback
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, TypeVar

from artic.artifacts.formats import write_json
from artic.artifacts.hashing import sha256_json
from artic.artifacts.manifest import (
    LOG,
    MANIFEST,
    InputRecord,
    Manifest,
    list_outputs,
    now_iso,
    outputs_hash,
    package_versions,
    read_manifest,
    verify_outputs,
)
from artic.artifacts.workdir import WorkDir, chunks_of_shard, shards_of_chunks
from artic.cli.progress import progress
from artic.config.compose import compose, validate
from artic.config.schemas import NON_OUTPUT_KEYS, StageConfig
from artic.errors import InputError, Interrupted

log = logging.getLogger("artic")

C = TypeVar("C", bound=StageConfig)

#: chunk function: (config, input folders, chunk index, empty folder to write into) -> items done
ChunkFn = Callable[[Any, dict[str, Path], int, Path], int]


class InternalError(Exception):
    """An unexpected failure; the traceback is in `log_path`."""

    exit_code = 1

    def __init__(self, message: str, log_path: Path | None) -> None:
        super().__init__(message)
        self.log_path = log_path


@dataclass(frozen=True)
class Plan:
    """How a stage's work splits: `items[c]` samples in chunk c, counted in `unit`."""

    items: list[int]
    unit: str

    @property
    def n_chunks(self) -> int:
        return len(self.items)


@dataclass(frozen=True)
class Stage(Generic[C]):
    """What a subcommand tells the runner. `inputs` maps input names to the stage each
    must come from; `input_paths` reads them off the config; `chunk` must be a
    module-level function (it runs in worker processes).

    A module of `artic.cli` defining `STAGE = Stage(...)` registers the stage
    (`cli/registry.py`), and its command is generated from these fields: `help` (the
    command's help, first paragraph listed by `artic --help`), `command` (the words
    after `artic`, default the name; "evaluate mdn" is a subcommand of `evaluate`),
    `task_option` (`--task NAME`, shorthand for `task=NAME`), `preset` (overrides the
    stage always composes with, e.g. render-scan's `render=scan`) and `alias` (another
    command line that runs this stage, with a log line saying so: "render-depth
    render=scan"). The registry reads these from the source without importing the
    module, so they must be literals."""

    name: str
    conf: str
    schema: type[C]
    plan: Callable[[C, dict[str, Path]], Plan]
    chunk: ChunkFn
    finalize: Callable[[C, dict[str, Path], Path], dict[str, float | int | str]]
    inputs: dict[str, str] = field(default_factory=dict)
    input_paths: Callable[[C], dict[str, Path]] = lambda cfg: {}
    help: str = ""
    command: str = ""
    task_option: bool = False
    preset: tuple[str, ...] = ()
    alias: str = ""


@dataclass(frozen=True)
class Result:
    status: str  # "complete", "skipped", "partial"
    out: Path
    manifest: Manifest | None = None
    message: str = ""


def resolved_config(stage: Stage[Any], overrides: list[str]) -> dict[str, Any]:
    return compose(stage.conf, with_preset(stage, overrides))


def with_preset(stage: Stage[Any], overrides: list[str]) -> list[str]:
    """`overrides` with the stage's `preset` in front (a preset given again is taken
    once; the same key with another value is bad input)."""
    given = {o.partition("=")[0].lstrip("+~"): o for o in overrides if "=" in o}
    extra = []
    for preset in stage.preset:
        key = preset.partition("=")[0]
        if key not in given:
            extra.append(preset)
        elif given[key] != preset:
            raise InputError(f"{given[key]}: {stage.name} always runs with {preset}")
    return [*extra, *overrides]


def config_hash_of(stage: str, config: dict[str, Any], input_keys: Iterable[str]) -> str:
    """The config hash of a stage output: the resolved config without the keys that do
    not change the outputs (`NON_OUTPUT_KEYS` and the paths of the stage's inputs)."""
    skip = set(NON_OUTPUT_KEYS) | set(input_keys)
    return sha256_json(
        {"stage": stage, "config": {k: v for k, v in config.items() if k not in skip}}
    )


def run_stage(stage: Stage[C], overrides: list[str], force: bool = False) -> Result:
    """Run `stage` with Hydra `overrides`; see the module docstring.

    Everything that can be checked is checked before anything is created: the config,
    `out`, the inputs (manifests and their integrity) and the plan. The rest runs with
    the work area's lock held only around state changes (see `artifacts.workdir`)."""
    raw = resolved_config(stage, overrides)
    cfg = validate(stage.schema, raw)
    out = Path(cfg.out)
    check_out(out)
    inputs = _read_inputs(stage, cfg)
    paths = {k: Path(r.path) for k, r in inputs.items()}
    plan = stage.plan(cfg, paths)
    # an input is identified by its content hash, not by where it lies
    config_hash = config_hash_of(stage.name, raw, stage.inputs)
    input_hashes = {k: r.content_hash for k, r in inputs.items()}
    key = sha256_json({"config": config_hash, "inputs": input_hashes})
    shard, shards = cfg.shard.index, cfg.shard.count

    work = WorkDir(out)
    with work.locked():
        # an output is up to date unless a work area of the same key is pending (an
        # interrupted --force, which is then resumed)
        if not force and work.stored_key() != key:
            previous = _up_to_date(out, config_hash, input_hashes)
            if previous is not None:
                return Result("skipped", out, previous, "up to date")
        already = work.prepare(key, force=force, shared=shards > 1)
    handler = log_to(work.path / LOG)
    started, t0 = now_iso(), time.perf_counter()
    restore = _terminate_as_interrupt()
    try:
        if already:
            log.info("%s: resuming, %d of %d chunks already done", out, already, plan.n_chunks)
        mine = chunks_of_shard(plan.n_chunks, shard, shards)
        while True:
            with work.locked():
                if not work.is_mine(key):
                    return _gone(out, config_hash, input_hashes)
                finished = work.finished()
                todo = [c for c in mine if c not in finished]
                if not todo:
                    missing = sorted(set(range(plan.n_chunks)) - finished)
                    if missing:
                        names = ", ".join(
                            f"{s + 1}/{shards}" for s in shards_of_chunks(missing, shards)
                        )
                        msg = (
                            f"shard {shard + 1}/{shards} finished; {len(finished)} of "
                            f"{plan.n_chunks} chunks done; shards {names} still to run (or "
                            "the command without shard.*) to finish"
                        )
                        return Result("partial", out, None, msg)
                    stats = stage.finalize(cfg, paths, work.path)
                    stop_log(handler)
                    manifest = publish(
                        work,
                        ManifestHead(stage.name, raw, config_hash, cfg.seed, inputs),
                        stats,
                        started,
                        t0,
                    )
                    return Result("complete", out, manifest)
                claimed = work.claim(todo)
            if claimed:
                _execute(stage, cfg, paths, plan, claimed, work, key)
            else:
                time.sleep(_POLL_S)  # another process is doing the rest of our chunks
    except InputError:
        with work.locked():
            if work.created:
                work.remove_if_unused(key)
        raise
    except Interrupted:
        raise
    except KeyboardInterrupt as err:
        term = isinstance(err, Terminated)
        raise Interrupted(
            f"{'terminated' if term else 'interrupted'}: {len(work.finished())} chunks of "
            f"{out} are kept; run the same command again to resume",
            exit_code=143 if term else 130,
        ) from None
    except Exception as err:
        log.error("internal error in %s:\n%s", stage.name, traceback.format_exc())
        raise InternalError(f"{stage.name}: {type(err).__name__}: {err}", work.path / LOG) from err
    finally:
        restore()
        work.leave()
        stop_log(handler)


#: seconds between looks at chunks other processes are doing
_POLL_S = 0.2


def check_out(out: Path) -> None:
    """`out` must be a folder or not exist yet, under folders: InputError otherwise."""
    for p in (out, *out.parents):
        if p.exists():
            if not p.is_dir():
                if p == out:
                    raise InputError(f"out: {out} is a file, not a folder")
                raise InputError(f"out: cannot write to {out} ({p} is a file)")
            return


def _up_to_date(out: Path, config_hash: str, input_hashes: dict[str, str]) -> Manifest | None:
    """The manifest of `out` when it is up to date (every file checked), else None."""
    if not (out / MANIFEST).is_file():
        return None
    previous = read_manifest(out)
    same_inputs = {k: r.content_hash for k, r in previous.inputs.items()} == input_hashes
    if previous.config_hash != config_hash or not same_inputs:
        return None
    verify_outputs(out, previous)
    return previous


def _gone(out: Path, config_hash: str, input_hashes: dict[str, str]) -> Result:
    """Our work area was published (or replaced) by another process."""
    previous = _up_to_date(out, config_hash, input_hashes)
    if previous is None:
        raise InputError(f"out: {out} was replaced by another run with another config meanwhile")
    return Result("skipped", out, previous, "up to date (finished by another process)")


class Terminated(KeyboardInterrupt):
    """SIGTERM, handled like Ctrl-C."""


def _terminate_as_interrupt() -> Callable[[], None]:
    """Turn SIGTERM into `Terminated` in the main thread; returns the undo."""
    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def handler(signum: int, frame: Any) -> None:
        raise Terminated

    previous = signal.signal(signal.SIGTERM, handler)

    def restore() -> None:
        signal.signal(signal.SIGTERM, previous)

    return restore


def _read_inputs(stage: Stage[C], cfg: C) -> dict[str, InputRecord]:
    records: dict[str, InputRecord] = {}
    for name, path in stage.input_paths(cfg).items():
        try:
            manifest = read_manifest(path, expected_stage=stage.inputs[name])
            _check_integrity(path, manifest)
        except InputError as err:
            raise InputError(f"{name}: {err}") from None
        records[name] = InputRecord(
            path=str(path), stage=manifest.stage, content_hash=manifest.content_hash
        )
    return records


def _check_integrity(folder: Path, manifest: Manifest) -> None:
    """A manifest edited by hand is refused: its config must give its config hash (as
    the stage that wrote it computes it) and its outputs listing its content hash."""
    from artic.cli.registry import load_stage, stage_entries

    where = folder / MANIFEST
    if outputs_hash(manifest.outputs) != manifest.content_hash:
        raise InputError(
            f"{where}: content_hash does not match the listed outputs (edited by hand?); "
            "rerun the stage that made it with --force"
        )
    if manifest.stage not in stage_entries():
        return
    keys = set(load_stage(manifest.stage).inputs)
    # outputs made before 2026-11-26 included the input paths in the hash
    accepted = {config_hash_of(manifest.stage, manifest.config, k) for k in (keys, set())}
    if manifest.config_hash not in accepted:
        raise InputError(
            f"{where}: config does not match config_hash (edited by hand?); "
            "rerun the stage that made it with --force"
        )


# -- writing an output folder: shared by run_stage and segment / build-hierarchy /
# infer-hierarchy (cli/hierarchy_output.OutputFolder)


def log_to(path: Path) -> logging.Handler:
    """Copy the log (every level, with tracebacks) into `path`, the folder's artic.log."""
    handler = logging.FileHandler(path)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    logging.getLogger().addHandler(handler)
    return handler


def stop_log(handler: logging.Handler) -> None:
    """Stop copying the log into the folder (idempotent)."""
    logging.getLogger().removeHandler(handler)
    handler.close()


@dataclass(frozen=True)
class ManifestHead:
    """What a manifest says about how an output was made: the stage (or command), its
    resolved config and config hash, the seed and the inputs."""

    stage: str
    config: dict[str, Any]
    config_hash: str
    seed: int
    inputs: dict[str, InputRecord]


def publish(
    work: WorkDir, head: ManifestHead, stats: dict[str, float | int | str], started: str, t0: float
) -> Manifest:
    """Write `manifest.json` (every file of the work area, its content hash, the
    versions, the times) into the work area, then rename it to the output folder, under
    the work area's lock. `started`/`t0`: `now_iso()` / `time.perf_counter()` at the
    start of the run."""
    with work.locked():
        outputs = list_outputs(work.path)
        manifest = Manifest(
            stage=head.stage,
            config=head.config,
            config_hash=head.config_hash,
            seed=head.seed,
            inputs=head.inputs,
            outputs=outputs,
            content_hash=outputs_hash(outputs),
            versions=package_versions(),
            started_at=started,
            finished_at=now_iso(),
            wall_time_s=round(time.perf_counter() - t0, 3),
            stats=stats,
        )
        write_json(work.path / MANIFEST, manifest.model_dump(mode="json"))
        work.publish()
    return manifest


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


def _execute(
    stage: Stage[C],
    cfg: C,
    inputs: dict[str, Path],
    plan: Plan,
    todo: list[int],
    work: WorkDir,
    key: str,
) -> None:
    """Do the chunks `todo` (claimed by this process), inline or in worker processes;
    each claim is released once its chunk is done."""
    if not todo:
        return
    workers = min(cfg.runtime.workers or available_cpus(), len(todo))
    total = sum(plan.items[c] for c in todo)
    with progress(stage.name, total, plan.unit) as advance:
        if workers <= 1:
            for c in todo:
                advance(_run_chunk(stage.chunk, cfg, inputs, c, work.out))
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
                while queue and len(pending) < workers:
                    c = queue.pop(0)
                    pending[pool.submit(_run_chunk, stage.chunk, cfg, inputs, c, work.out)] = c
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
    pool.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + 5
    for p in procs:
        p.join(max(0.0, deadline - time.monotonic()))
        if p.is_alive():
            p.kill()
            p.join(1)
