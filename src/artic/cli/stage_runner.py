"""Run one stage under the stage contract of DESIGN.md.

compose config -> validate -> skip if up to date -> do the missing chunks of this shard
(in parallel worker processes) -> when all chunks are done: summary files, manifest,
atomic publish. A `Stage` supplies only what is specific to it.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import time
import traceback
from collections.abc import Callable
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
from artic.artifacts.workdir import WorkDir, chunks_of_shard
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
    module-level function (it runs in worker processes)."""

    name: str
    conf: str
    schema: type[C]
    plan: Callable[[C, dict[str, Path]], Plan]
    chunk: ChunkFn
    finalize: Callable[[C, dict[str, Path], Path], dict[str, float | int | str]]
    inputs: dict[str, str] = field(default_factory=dict)
    input_paths: Callable[[C], dict[str, Path]] = lambda cfg: {}


@dataclass(frozen=True)
class Result:
    status: str  # "complete", "skipped", "partial"
    out: Path
    manifest: Manifest | None = None
    message: str = ""


def resolved_config(stage: Stage[Any], overrides: list[str]) -> dict[str, Any]:
    return compose(stage.conf, overrides)


def run_stage(stage: Stage[C], overrides: list[str], force: bool = False) -> Result:
    """Run `stage` with Hydra `overrides`; see the module docstring."""
    raw = resolved_config(stage, overrides)
    cfg = validate(stage.schema, raw)
    out = Path(cfg.out)
    inputs = _read_inputs(stage, cfg)
    # an input is identified by its content hash, not by where it lies
    skip = set(NON_OUTPUT_KEYS) | set(stage.inputs)
    output_config = {k: v for k, v in raw.items() if k not in skip}
    config_hash = sha256_json({"stage": stage.name, "config": output_config})
    input_hashes = {k: r.content_hash for k, r in inputs.items()}

    if not force and (out / MANIFEST).is_file():
        previous = read_manifest(out)
        same_inputs = {k: r.content_hash for k, r in previous.inputs.items()} == input_hashes
        if previous.config_hash == config_hash and same_inputs:
            verify_outputs(out, previous)
            return Result("skipped", out, previous, "up to date")

    work = WorkDir(out)
    key = sha256_json({"config": config_hash, "inputs": input_hashes})
    fresh = force and cfg.shard.count == 1
    already = work.prepare(key, fresh=fresh)
    handler = _log_to(work.path / LOG)
    started, t0 = now_iso(), time.perf_counter()
    try:
        paths = {k: Path(r.path) for k, r in inputs.items()}
        plan = stage.plan(cfg, paths)
        todo = [
            c
            for c in chunks_of_shard(plan.n_chunks, cfg.shard.index, cfg.shard.count)
            if c not in work.finished()
        ]
        if already:
            log.info("%s: resuming, %d of %d chunks already done", out, already, plan.n_chunks)
        _execute(stage, cfg, paths, plan, todo, work)
        done = len(work.finished())
        if done < plan.n_chunks:
            msg = (
                f"shard {cfg.shard.index + 1}/{cfg.shard.count} finished; {done} of "
                f"{plan.n_chunks} chunks done; run the remaining shards, or the command "
                "without shard.*, to finish"
            )
            return Result("partial", out, None, msg)
        stats = stage.finalize(cfg, paths, work.path)
        outputs = list_outputs(work.path)
        wall = time.perf_counter() - t0
        manifest = Manifest(
            stage=stage.name,
            config=raw,
            config_hash=config_hash,
            seed=cfg.seed,
            inputs=inputs,
            outputs=outputs,
            content_hash=outputs_hash(outputs),
            versions=package_versions(),
            started_at=started,
            finished_at=now_iso(),
            wall_time_s=round(wall, 3),
            stats=stats,
        )
        write_json(work.path / MANIFEST, manifest.model_dump(mode="json"))
        logging.getLogger().removeHandler(handler)
        handler.close()
        work.publish()
        return Result("complete", out, manifest)
    except (InputError, Interrupted):
        raise
    except KeyboardInterrupt:
        raise Interrupted(
            f"interrupted: {len(work.finished())} chunks of {out} are kept; "
            "run the same command again to resume"
        ) from None
    except Exception as err:
        log.error("internal error in %s:\n%s", stage.name, traceback.format_exc())
        raise InternalError(f"{stage.name}: {type(err).__name__}: {err}", work.path / LOG) from err
    finally:
        logging.getLogger().removeHandler(handler)
        handler.close()


def _read_inputs(stage: Stage[C], cfg: C) -> dict[str, InputRecord]:
    records: dict[str, InputRecord] = {}
    for name, path in stage.input_paths(cfg).items():
        try:
            manifest = read_manifest(path, expected_stage=stage.inputs[name])
        except InputError as err:
            raise InputError(f"{name}: {err}") from None
        records[name] = InputRecord(
            path=str(path), stage=manifest.stage, content_hash=manifest.content_hash
        )
    return records


def _log_to(path: Path) -> logging.Handler:
    handler = logging.FileHandler(path)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    logging.getLogger().addHandler(handler)
    return handler


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


def _run_chunk(fn: ChunkFn, cfg: Any, inputs: dict[str, Path], chunk: int, out: Path) -> int:
    """Worker entry: write chunk `chunk` into a private folder, then commit it."""
    work = WorkDir(out)
    tmp = work.chunk_tmp(chunk)
    items = fn(cfg, inputs, chunk, tmp)
    work.commit_chunk(chunk, tmp)
    return items


def _worker_init() -> None:
    # One thread per worker process: parallelism comes from the processes.
    os.environ.setdefault("OMP_NUM_THREADS", "1")


def _execute(
    stage: Stage[C], cfg: C, inputs: dict[str, Path], plan: Plan, todo: list[int], work: WorkDir
) -> None:
    if not todo:
        return
    workers = min(cfg.runtime.workers or available_cpus(), len(todo))
    total = sum(plan.items[c] for c in todo)
    with progress(stage.name, total, plan.unit) as advance:
        if workers <= 1:
            for c in todo:
                advance(_run_chunk(stage.chunk, cfg, inputs, c, work.out))
            return
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=ctx, initializer=_worker_init) as pool:
            pending: set[Future[int]] = set()
            queue = list(todo)
            try:
                while queue or pending:
                    while queue and len(pending) < 2 * workers:
                        c = queue.pop(0)
                        pending.add(pool.submit(_run_chunk, stage.chunk, cfg, inputs, c, work.out))
                    finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                    for fut in finished:
                        advance(fut.result())
            except BaseException:
                for fut in pending:
                    fut.cancel()
                pool.shutdown(wait=True, cancel_futures=True)
                raise
