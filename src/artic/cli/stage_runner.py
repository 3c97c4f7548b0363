"""Run one stage under the stage contract of DESIGN.md.

compose config -> validate -> skip if up to date -> do the missing chunks of this shard
(in parallel worker processes) -> when all chunks are done: summary files, manifest,
atomic publish. A `Stage` supplies only what is specific to it.

What is not orchestration lives in `artifacts/`: the output writer (config hash,
manifest, log copy, atomic publish: `artifacts/output.py`, shared with
`artifacts/scan_outputs.OutputFolder`) and the worker processes (`artifacts/workers.py`).
"""

from __future__ import annotations

import logging
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from artic.artifacts.manifest import LOG, InputRecord, Manifest, now_iso, read_manifest
from artic.artifacts.model_store import shipped_input
from artic.artifacts.output import (
    ManifestHead,
    check_integrity,
    check_out,
    config_hash_of,
    log_to,
    publish,
    stop_log,
    up_to_date,
)
from artic.artifacts.workdir import WorkDir, chunks_of_shard, key_of, shards_of_chunks
from artic.artifacts.workers import Interrupts, Terminated, available_cpus, run_chunks
from artic.cli.registry import stage_entries
from artic.cli.stage import C, Plan, Stage
from artic.config.compose import Composed, compose, compose_with_choices, validate
from artic.errors import InputError, Interrupted
from artic.progress import progress

__all__ = ["InternalError", "Plan", "Result", "Stage", "resolved_config", "run_stage"]

log = logging.getLogger("artic")


class InternalError(Exception):
    """An unexpected failure; the traceback is in `log_path`."""

    exit_code = 1

    def __init__(self, message: str, log_path: Path | None) -> None:
        super().__init__(message)
        self.log_path = log_path


@dataclass(frozen=True)
class Result:
    status: str  # "complete", "skipped", "partial"
    out: Path
    manifest: Manifest | None = None
    message: str = ""


def resolved_config(stage: Stage[Any], overrides: list[str]) -> dict[str, Any]:
    return compose(stage.conf, with_preset(stage, overrides))


def composed_config(stage: Stage[Any], overrides: list[str]) -> Composed:
    """The resolved config and the config-group options (debug, experiment, ...) it came
    from; the manifest records both."""
    return compose_with_choices(stage.conf, with_preset(stage, overrides))


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


def run_stage(stage: Stage[C], overrides: list[str], force: bool = False) -> Result:
    """Run `stage` with Hydra `overrides`; see the module docstring.

    Everything that can be checked is checked before anything is created: the config,
    `out`, the inputs (manifests and their integrity) and the plan. The rest runs with
    the work area's lock held only around state changes (see `artifacts.workdir`)."""
    composed = composed_config(stage, overrides)
    raw = composed.config
    cfg = validate(stage.schema, raw)
    out = Path(cfg.out)
    check_out(out)
    inputs = _read_inputs(stage, cfg)
    paths = {k: Path(r.path) for k, r in inputs.items()}
    plan = stage.plan(cfg, paths)
    if stage.one_chunk and plan.n_chunks != 1:
        raise RuntimeError(f"{stage.name}: declared one_chunk, planned {plan.n_chunks} chunks")
    # an input is identified by its content hash, not by where it lies
    config_hash = config_hash_of(stage.name, raw, stage.inputs)
    input_hashes = {k: r.content_hash for k, r in inputs.items()}
    key = key_of(config_hash, input_hashes)
    shard, shards = cfg.shard.index, cfg.shard.count

    work = WorkDir(out)
    with work.locked():
        # an output is up to date unless a work area of the same key is pending (an
        # interrupted --force, which is then resumed)
        if not force and work.stored_key() != key:
            previous = up_to_date(out, config_hash, input_hashes)
            if previous is not None:
                return Result("skipped", out, previous, "up to date")
        already = work.prepare(key, force=force, shared=shards > 1)
    handler = log_to(work.path / LOG)
    started, t0 = now_iso(), time.perf_counter()
    interrupts = Interrupts().start()
    try:
        if already:
            log.info("%s: resuming, %d of %d chunks already done", out, already, plan.n_chunks)
        mine = chunks_of_shard(plan.n_chunks, shard, shards)
        while True:
            interrupts.check()
            with work.locked():
                if not work.is_mine(key):
                    return _gone(out, config_hash, input_hashes)
                finished = work.finished()
                todo = [c for c in mine if c not in finished]
                if not todo:
                    missing = sorted(set(range(plan.n_chunks)) - finished)
                    if missing:
                        names = ", ".join(str(s) for s in shards_of_chunks(missing, shards))
                        msg = (
                            f"shard.index={shard} (shard.count={shards}) finished; "
                            f"{len(finished)} of {plan.n_chunks} chunks done; shard.index "
                            f"{names} still to run (or the command without shard.*) to finish"
                        )
                        return Result("partial", out, None, msg)
                    stats = stage.finalize(cfg, paths, work.path)
                    interrupts.check()  # one lost in a finalizer (`Interrupts`)
                    stop_log(handler)
                    manifest = publish(
                        work,
                        ManifestHead(
                            stage.name, raw, config_hash, cfg.seed, inputs, composed.choices
                        ),
                        stats,
                        started,
                        t0,
                    )
                    return Result("complete", out, manifest)
                claimed = work.claim(todo)
            if claimed:
                _execute(stage, cfg, paths, plan, claimed, work, interrupts.check)
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
        interrupts.stop()
        work.leave()
        stop_log(handler)


#: seconds between looks at chunks other processes are doing
_POLL_S = 0.2


def _gone(out: Path, config_hash: str, input_hashes: dict[str, str]) -> Result:
    """Our work area was published (or replaced) by another process."""
    previous = up_to_date(out, config_hash, input_hashes)
    if previous is None:
        raise InputError(f"out: {out} was replaced by another run with another config meanwhile")
    return Result("skipped", out, previous, "up to date (finished by another process)")


def _read_inputs(stage: Stage[C], cfg: C) -> dict[str, InputRecord]:
    records: dict[str, InputRecord] = {}
    for name, path in stage.input_paths(cfg).items():
        if (shipped := shipped_input(path, stage.inputs[name])) is not None:
            records[name] = shipped  # a shipped model, checked against its card
            continue
        try:
            manifest = read_manifest(path, expected_stage=stage.inputs[name])
            entry = stage_entries().get(manifest.stage)
            check_integrity(path, manifest, None if entry is None else entry.inputs)
        except InputError as err:
            raise InputError(f"{name}: {err}") from None
        records[name] = InputRecord(
            path=str(path), stage=manifest.stage, content_hash=manifest.content_hash
        )
    return records


def _execute(
    stage: Stage[C],
    cfg: C,
    inputs: dict[str, Path],
    plan: Plan,
    todo: list[int],
    work: WorkDir,
    check: Callable[[], None],
) -> None:
    """Do the chunks `todo` (claimed by this process), inline or in worker processes
    (`artifacts.workers.run_chunks`); each claim is released once its chunk is done, and
    `check()` (`Interrupts.check`) is called before each chunk starts."""
    if not todo:
        return
    workers = min(cfg.runtime.workers or available_cpus(), len(todo))
    total = sum(plan.items[c] for c in todo)
    with progress(stage.name, total, plan.unit) as advance:
        run_chunks(stage.chunk, cfg, inputs, todo, work, workers, advance, check)
